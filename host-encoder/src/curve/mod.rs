//! Fractal curves (thesis part II): projected-IFS curves fitted to polylines and sampled
//! functions ([`fit_curve`]), and the affine IFS of function data (Guérin & Tosan, §6.1,
//! [`fit_affine`]).

mod affine;
mod distance;
mod file;
mod fit;
mod lm;
mod projected;

pub use affine::{fit_affine, AffineError, AffineFit, AffineIfs, AffineMap};
pub use distance::{distance, length, resample};
pub use file::{read_csv, read_svg, CurveFile, CurveFileError, FitRecord, CURVE_FORMAT};
pub use fit::{fit_curve, CurveFit, CurveFitConfig, CurveFitError, MAX_TABULATION};
pub use lm::{minimise, LmConfig, LmReport};
pub use projected::{Point, ProjectedCurve};
