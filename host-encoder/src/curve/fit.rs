//! Fitting a projected-IFS curve to a sampled curve (thesis II.3): Levenberg–Marquardt on the
//! distance of [`super::distance`] between the curve's tabulation and the data, the control
//! points started on the data at uniform arc length with the smooth (Bézier) rules, fitted
//! first alone, then with the subdivision weights (from two starts, one coarse to fine in the
//! tabulation depth).

use super::distance::{length, resample};
use super::lm::{minimise, LmConfig};
use super::projected::{Point, ProjectedCurve};
use std::fmt;

/// What to fit.
#[derive(Debug, Clone, PartialEq)]
pub struct CurveFitConfig {
    /// Control points, `m + 1` (at least 2).
    pub points: usize,
    /// Subdivision matrices (pieces per level), `N` (at least 2).
    pub maps: usize,
    /// Fit the subdivision weights too (the fractal model); otherwise the smooth Bézier rules
    /// stay and only the control points move.
    pub weights: bool,
    /// Tabulation depth `p`: the curve is compared through its `N^p + 1` tabulated points.
    pub depth: u32,
    /// Resampling count `M` of the distance (`M + 1` points).
    pub resample: usize,
    /// Iteration limit and stopping tolerance of each Levenberg–Marquardt stage.
    pub lm: LmConfig,
}

impl CurveFitConfig {
    /// `points` control points and `maps` matrices, weights fitted, the tabulation at least
    /// as fine as 1024 points and a resampling of 500, as in the thesis's synthetic tests
    /// (Table 1).
    pub fn new(points: usize, maps: usize) -> CurveFitConfig {
        let mut depth = 1;
        while maps.max(2).pow(depth) < 1024 {
            depth += 1;
        }
        CurveFitConfig {
            points,
            maps,
            weights: true,
            depth,
            resample: 500,
            lm: LmConfig::default(),
        }
    }

    /// Free parameters of the model: two coordinates per control point, and with weights
    /// `m` per free column of the matrices (`N m - 1` of them: the first column of `T_0`
    /// and the last of `T_{N-1}` are fixed, each first column of a later matrix is the last
    /// column of the one before, and each column's last weight makes its sum 1).
    pub fn parameter_count(&self) -> usize {
        let m = self.points.saturating_sub(1);
        let weights = if self.weights {
            m.saturating_mul(self.maps.saturating_mul(m).saturating_sub(1))
        } else {
            0
        };
        self.points.saturating_mul(2).saturating_add(weights)
    }
}

/// Why a curve cannot be fitted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CurveFitError {
    /// Fewer than 2 data points, or data of zero length.
    TooFewPoints,
    /// Fewer than 2 control points or 2 matrices.
    BadModel,
    /// More parameters than resampled coordinates to fit them to.
    TooManyParameters {
        /// The model's free parameters.
        parameters: usize,
        /// Coordinates the distance compares (`2 (M + 1)`).
        residuals: usize,
    },
    /// A coordinate is not finite.
    NotFinite,
    /// The tabulation would have more than [`MAX_TABULATION`] points.
    TooDeep,
}

/// The weights are fitted from two starts, the closer kept: at the fit's depth at once, and
/// coarse to fine, first through the tabulation at the first depth with at least this many
/// points, then at each depth after it. Neither start is the better one on every curve of
/// `bench/curves.sh` (`docs/decisions.md`).
const COARSE_POINTS: usize = 81;

/// Most points a fit tabulates (`N^depth + 1`).
pub const MAX_TABULATION: usize = 1 << 22;

impl fmt::Display for CurveFitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CurveFitError::TooFewPoints => write!(f, "a curve needs at least 2 distinct points"),
            CurveFitError::BadModel => {
                write!(
                    f,
                    "a curve model needs at least 2 control points and 2 maps"
                )
            }
            CurveFitError::TooManyParameters {
                parameters,
                residuals,
            } => write!(
                f,
                "{parameters} parameters but only {residuals} resampled coordinates to fit them to"
            ),
            CurveFitError::NotFinite => write!(f, "a coordinate is not a finite number"),
            CurveFitError::TooDeep => write!(
                f,
                "the tabulation would have more than {MAX_TABULATION} points: choose a smaller depth"
            ),
        }
    }
}

impl std::error::Error for CurveFitError {}

/// A fitted curve and how well it fits.
#[derive(Debug, Clone, PartialEq)]
pub struct CurveFit {
    /// The curve, in the data's coordinates.
    pub curve: ProjectedCurve,
    /// The distance `D` to the data (Definition 14), in squared data units.
    pub distance: f64,
    /// Root-mean-square distance between the resampled points, in data units.
    pub rms: f64,
    /// Free parameters of the model.
    pub parameters: usize,
    /// Levenberg–Marquardt iterations, both stages.
    pub iterations: usize,
}

/// Fits a projected-IFS curve to the polyline `data`.
pub fn fit_curve(data: &[Point], config: &CurveFitConfig) -> Result<CurveFit, CurveFitError> {
    if data.iter().flatten().any(|v| !v.is_finite()) {
        return Err(CurveFitError::NotFinite);
    }
    if data.len() < 2 || length(data) <= 0.0 {
        return Err(CurveFitError::TooFewPoints);
    }
    if config.points < 2 || config.maps < 2 {
        return Err(CurveFitError::BadModel);
    }
    if config
        .maps
        .checked_pow(config.depth)
        .is_none_or(|n| n >= MAX_TABULATION)
    {
        return Err(CurveFitError::TooDeep);
    }
    let residuals = config.resample.saturating_add(1).saturating_mul(2);
    if config.parameter_count() > residuals {
        return Err(CurveFitError::TooManyParameters {
            parameters: config.parameter_count(),
            residuals,
        });
    }
    // Fit in a frame where the data spans about 1 (numerical derivatives need a scale).
    let frame = Frame::of(data);
    let local: Vec<Point> = data.iter().map(|p| frame.to_local(*p)).collect();
    let target = resample(&local, config.resample);
    let start = resample(&local, config.points - 1);
    let mut curve = ProjectedCurve::bezier(start, config.maps);
    let layout = Layout::new(config.points, config.maps);
    let residual_at = |curve: &ProjectedCurve, depth: u32, r: &mut Vec<f64>| {
        let model = resample(&curve.tabulate(depth), config.resample);
        for (p, q) in model.iter().zip(&target) {
            r.extend([p[0] - q[0], p[1] - q[1]]);
        }
    };
    // Stage 1: the control points with the smooth rules.
    let mut params: Vec<f64> = curve.points.iter().flatten().copied().collect();
    let mut trial = curve.clone();
    let first = minimise(
        &mut params,
        |a, r| {
            layout.set_points(&mut trial, a);
            residual_at(&trial, config.depth, r)
        },
        &config.lm,
    );
    layout.set_points(&mut curve, &params);
    let mut iterations = first.iterations;
    let mut distance = first.error();
    // Stage 2: the weights too, from two starts (the final depth at once, and coarse to
    // fine); the closer fit is kept.
    if config.weights {
        let start = layout.params(&curve);
        let mut coarse = 1;
        while config.maps.pow(coarse) < COARSE_POINTS && coarse < config.depth {
            coarse += 1;
        }
        let mut best: Option<(f64, Vec<f64>)> = None;
        for first in [config.depth, coarse] {
            let mut params = start.clone();
            let mut error = f64::INFINITY;
            for d in first..=config.depth {
                let report = minimise(
                    &mut params,
                    |a, r| {
                        layout.set_all(&mut trial, a);
                        residual_at(&trial, d, r)
                    },
                    &config.lm,
                );
                iterations += report.iterations;
                error = report.error();
            }
            if best.as_ref().is_none_or(|(e, _)| error < *e) {
                best = Some((error, params));
            }
            if coarse == config.depth {
                break;
            }
        }
        let (error, params) = best.expect("one start at least");
        layout.set_all(&mut curve, &params);
        distance = error;
    }
    for p in &mut curve.points {
        *p = frame.to_data(*p);
    }
    let distance = distance * frame.scale * frame.scale;
    Ok(CurveFit {
        curve,
        distance,
        rms: (distance / (config.resample + 1) as f64).sqrt(),
        parameters: config.parameter_count(),
        iterations,
    })
}

/// The data's bounding box mapped to about the unit square (same scale on both axes).
struct Frame {
    origin: Point,
    scale: f64,
}

impl Frame {
    fn of(data: &[Point]) -> Frame {
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for p in data {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let scale = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        Frame {
            origin: lo,
            scale: if scale > 0.0 { scale } else { 1.0 },
        }
    }

    fn to_local(&self, p: Point) -> Point {
        [
            (p[0] - self.origin[0]) / self.scale,
            (p[1] - self.origin[1]) / self.scale,
        ]
    }

    fn to_data(&self, p: Point) -> Point {
        [
            p[0] * self.scale + self.origin[0],
            p[1] * self.scale + self.origin[1],
        ]
    }
}

/// Where the free parameters sit: the control points' coordinates, then the free columns'
/// first `m` weights (the last one completes the column's sum to 1).
struct Layout {
    points: usize,
    /// `(map, column)` of each free column, in parameter order.
    columns: Vec<(usize, usize)>,
}

impl Layout {
    fn new(points: usize, maps: usize) -> Layout {
        let m = points - 1;
        let columns = (0..maps)
            .flat_map(|k| (1..=m).map(move |j| (k, j)))
            .filter(|&(k, j)| !(k == maps - 1 && j == m))
            .collect();
        Layout { points, columns }
    }

    fn params(&self, curve: &ProjectedCurve) -> Vec<f64> {
        let m = self.points - 1;
        let mut out: Vec<f64> = curve.points.iter().flatten().copied().collect();
        for &(k, j) in &self.columns {
            out.extend_from_slice(&curve.maps[k][j][..m]);
        }
        out
    }

    fn set_points(&self, curve: &mut ProjectedCurve, params: &[f64]) {
        for (p, c) in curve.points.iter_mut().zip(params.chunks_exact(2)) {
            *p = [c[0], c[1]];
        }
    }

    fn set_all(&self, curve: &mut ProjectedCurve, params: &[f64]) {
        let m = self.points - 1;
        self.set_points(curve, params);
        let weights = &params[2 * self.points..];
        for (&(k, j), w) in self.columns.iter().zip(weights.chunks_exact(m)) {
            let column = &mut curve.maps[k][j];
            column[..m].copy_from_slice(w);
            column[m] = 1.0 - w.iter().sum::<f64>();
            if j == m {
                // The join: the next matrix's first column is this one.
                let shared = column.clone();
                curve.maps[k + 1][0] = shared;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rough curve: 4 control points, 2 maps with weights away from the smooth scheme (by
    /// up to 0.125; with twice these offsets the fit stops in a local minimum, rms 0.0069
    /// against the smooth rules' 0.024: the method is local, as the thesis says).
    fn rough() -> ProjectedCurve {
        let mut curve =
            ProjectedCurve::bezier(vec![[0.0, 0.0], [1.0, 2.0], [2.0, -1.0], [3.0, 0.5]], 2);
        let layout = Layout::new(4, 2);
        let mut params = layout.params(&curve);
        let bumps = [
            0.15, -0.2, 0.1, 0.25, -0.15, 0.05, -0.1, 0.2, 0.1, -0.05, 0.15, -0.2, 0.1, 0.05, -0.1,
        ];
        for (p, b) in params[8..].iter_mut().zip(bumps) {
            *p += b / 2.0;
        }
        layout.set_all(&mut curve, &params);
        curve
    }

    #[test]
    fn the_parameter_count_is_the_thesis_s() {
        // II.4.1.2: 6 points and 3 general matrices, 12 + 70 = 82 parameters.
        assert_eq!(CurveFitConfig::new(6, 3).parameter_count(), 82);
        let layout = Layout::new(6, 3);
        assert_eq!(layout.columns.len() * 5, 70);
    }

    #[test]
    fn setting_the_weights_keeps_the_curve_joined() {
        assert!(rough().is_joined(1e-12));
    }

    #[test]
    fn a_smooth_curve_is_recovered_with_the_smooth_rules() {
        let data = ProjectedCurve::bezier(
            vec![[0.0, 0.0], [10.0, 30.0], [30.0, -10.0], [40.0, 10.0]],
            2,
        )
        .tabulate(10);
        let mut config = CurveFitConfig::new(4, 2);
        config.weights = false;
        let fit = fit_curve(&data, &config).unwrap();
        assert!(fit.rms < 1e-4 * 40.0, "{fit:?}");
    }

    #[test]
    fn a_rough_curve_needs_its_weights() {
        let data = rough().tabulate(10);
        let smooth = fit_curve(
            &data,
            &CurveFitConfig {
                weights: false,
                ..CurveFitConfig::new(4, 2)
            },
        )
        .unwrap();
        let fractal = fit_curve(&data, &CurveFitConfig::new(4, 2)).unwrap();
        // The smooth rules miss by 0.023 (rms, the curve is 3.4 long); the weights recover the
        // curve (up to a change of basis of the control points, thesis II.4.1.1).
        assert!(smooth.rms > 0.01, "{smooth:?}");
        assert!(fractal.rms < 1e-6, "{fractal:?}");
    }

    #[test]
    fn bad_input_is_refused() {
        let config = CurveFitConfig::new(4, 2);
        assert_eq!(
            fit_curve(&[[0.0, 0.0]], &config),
            Err(CurveFitError::TooFewPoints)
        );
        assert_eq!(
            fit_curve(&[[1.0, 1.0], [1.0, 1.0]], &config),
            Err(CurveFitError::TooFewPoints)
        );
        assert_eq!(
            fit_curve(&[[0.0, f64::NAN], [1.0, 1.0]], &config),
            Err(CurveFitError::NotFinite)
        );
        let deep = CurveFitConfig {
            depth: 30,
            ..CurveFitConfig::new(4, 2)
        };
        assert_eq!(
            fit_curve(&[[0.0, 0.0], [1.0, 1.0]], &deep),
            Err(CurveFitError::TooDeep)
        );
        let huge = CurveFitConfig::new(4, usize::MAX);
        assert!(fit_curve(&[[0.0, 0.0], [1.0, 1.0]], &huge).is_err());
        let tiny = CurveFitConfig {
            resample: 10,
            ..CurveFitConfig::new(6, 3)
        };
        assert!(matches!(
            fit_curve(&[[0.0, 0.0], [1.0, 1.0]], &tiny),
            Err(CurveFitError::TooManyParameters { .. })
        ));
    }
}
