//! # host-encoder
//!
//! The encoder of the PIFS format (a quadtree of projected-IFS patches, after E. Guérin's
//! thesis) and the library behind the `pifs` command-line tool.
//!
//! An image is analysed once ([`analyse`]: every model fitted at every quadtree node, every
//! quantiser tried); the [`Analysis`] then encodes any number of targets
//! ([`Analysis::encode`]: a rate, a size or a quality).
//!
//! ```no_run
//! use host_encoder::{analyse, EncoderConfig, Plane, Target};
//! let plane = Plane::new(2, 2, vec![0, 64, 128, 255]);
//! let analysis = analyse(plane, &EncoderConfig::default(), &|_| {}).unwrap();
//! let small = analysis.encode(Target::Bpp(0.25)).unwrap();
//! let good = analysis.encode(Target::Psnr(30.0)).unwrap();
//! # let _ = (small, good);
//! ```
//!
//! [`ifs`] draws iterated function systems the classic ways (the chaos game and the Hutchinson
//! iteration): the Sierpinski triangle and Barnsley's fern, and any decoder patch as the
//! attractor of its projected IFS. Its tests check that decoder-core's integer tabulation of a
//! patch is that attractor, up to the tabulation's roundings (`cargo run --example ifs` draws
//! them).
//!
//! [`curve`] is the thesis's other half for curves: a projected-IFS curve fitted to a polyline
//! or a sampled function by Levenberg–Marquardt on the thesis's arc-length distance
//! ([`curve::fit_curve`]), tabulated at any depth, stored as JSON (`pifs curve`), and the affine
//! IFS of function data of Guérin & Tosan ([`curve::fit_affine`]).
//!
//! ```
//! use host_encoder::curve::{fit_curve, CurveFitConfig, ProjectedCurve};
//! // The points of a cubic Bézier curve are fitted exactly by 4 control points, 2 maps.
//! let data = ProjectedCurve::bezier(vec![[0.0, 0.0], [1.0, 3.0], [3.0, -1.0], [4.0, 1.0]], 2)
//!     .tabulate(10);
//! let fit = fit_curve(&data, &CurveFitConfig::new(4, 2)).unwrap();
//! assert!(fit.rms < 1e-6);
//! let drawn = fit.curve.tabulate(12); // 4097 points
//! # assert_eq!(drawn.len(), 4097);
//! ```
//!
//! [`relief`] draws a heightmap as a hillshaded relief, for a quick look at a decoded terrain.
//!
//! The `pifs` tool is behind the default cargo feature `cli`; a library user writes
//! `host-encoder = { version = "…", default-features = false }` and gets no command-line
//! dependencies (`clap`, `indicatif`, `plotters`).
#![deny(
    missing_docs,
    missing_debug_implementations,
    rustdoc::broken_intra_doc_links
)]

pub mod curve;
mod encoder;
mod entropy;
pub mod ifs;
#[doc(hidden)]
pub mod internal;
pub mod io;
pub mod packets;
pub mod relief;

pub use encoder::{
    analyse, analyse_colour, analyse_colour_in_parts, analyse_in_parts, analysis_steps, psnr,
    Analysis, AnalysisInParts, AnalysisStage, AnalysisSteps, AnalysisTiming, ColourPlanes,
    EncodeError, Encoded, EncoderConfig, Plane, Target, Tune, BOUND_PENALTY, CHROMA_WEIGHTS,
    DEFAULT_STRIPE_TILES, DEFAULT_TRIAL_BPP, FINE_STEPS_BELOW_BPP, FINE_STEP_MARGIN, LOW_RATE_BPP,
    LOW_RATE_MIN_LEAF_LOG2, MIN_TRIAL_BPP, PART_PIXELS, WHOLE_WIDTH,
};
