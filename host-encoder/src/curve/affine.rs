//! Affine IFS on the real line fitted to function data (Guérin & Tosan, "Fractal inverse
//! problem: an analytical approach", §6.1).
//!
//! `N` maps `T_i(x) = a_i x + b_i` act on the values `y`. The address function of the IFS is
//!
//! ```text
//! phi(rho) = b_{rho_1} + a_{rho_1} b_{rho_2} + a_{rho_1} a_{rho_2} b_{rho_3} + ...
//!          = lim B_n,   B_1 = b_{rho_1},  B_{k+1} = B_k + A_k b_{rho_{k+1}},
//!                       A_1 = a_{rho_1},  A_{k+1} = A_k a_{rho_{k+1}}.
//! ```
//!
//! A sample `(x, y)` with `x` in `[0, 1)` is given the address `alpha_1 ... alpha_n 0^omega`,
//! `alpha_1 ... alpha_n` the first `n` digits of the `N`-adic expansion of `x`, and the model
//! value there is
//!
//! ```text
//! psi(alpha_1 ... alpha_n 0^omega) = B_n + A_n phi(0^omega),   phi(0^omega) = b_0 / (1 - a_0),
//! ```
//!
//! `phi(0^omega)` being the fixed point of `T_0`. [`fit_affine`] minimises the paper's
//! `g_n(T) = (1/p) sum_i (psi_i - y_i)^2` over the `a_i, b_i` with the crate's
//! Levenberg–Marquardt solver (`curve::lm`). As the paper remarks, the method is local:
//! the result may be a local minimum, and nothing keeps the fitted maps contractive
//! ([`AffineIfs::is_contractive`] tells).

use crate::curve::lm::{minimise, LmConfig};
use std::fmt;

/// A position closer than this (in units of the digit being read) below a digit boundary is
/// taken to be on it, so that `i / N` written in floating point (`0.29 * 100 = 28.999…`) gets
/// the digit `i`.
const DIGIT_SNAP: f64 = 1e-9;

/// The largest `|a_i|` of the starting maps (see [`fit_affine`]): the start is contractive.
const START_CONTRACTION: f64 = 0.9;

/// One map `x -> a x + b` of the real line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineMap {
    /// The factor (the map is a contraction when `|a| < 1`).
    pub a: f64,
    /// The offset.
    pub b: f64,
}

impl AffineMap {
    /// `a x + b`.
    pub fn apply(&self, x: f64) -> f64 {
        self.a * x + self.b
    }

    /// The fixed point `b / (1 - a)`. `NaN` when `a == 1`: the map is then a translation (no
    /// fixed point, or every point when `b == 0`). It exists, but repels, when `|a| > 1`.
    pub fn fixed_point(&self) -> f64 {
        let denominator = 1.0 - self.a;
        if denominator == 0.0 {
            f64::NAN
        } else {
            self.b / denominator
        }
    }
}

/// An IFS of affine maps of the real line; map `i` is the digit `i` of the addresses.
#[derive(Debug, Clone, PartialEq)]
pub struct AffineIfs {
    /// The maps `T_0 ... T_{N-1}`.
    pub maps: Vec<AffineMap>,
}

impl AffineIfs {
    /// The address function at the first `depth` digits of the `N`-adic expansion of `x`
    /// (`N` the number of maps) followed by `0^omega`: `B_depth + A_depth * phi(0^omega)`,
    /// `phi(0^omega)` the fixed point of `T_0` (`NaN` when `a_0 == 1`). `x` is taken into
    /// `[0, 1)` (clamped).
    pub fn value(&self, x: f64, depth: u32) -> f64 {
        let digits = digits(x, self.maps.len(), depth);
        address_value(&digits, |k| self.maps[k])
    }

    /// [`AffineIfs::value`] at `x = k / count`, `k = 0 .. count`.
    pub fn sample(&self, count: usize, depth: u32) -> Vec<f64> {
        (0..count)
            .map(|k| self.value(k as f64 / count as f64, depth))
            .collect()
    }

    /// Whether every map is a contraction (`|a_i| < 1`), as the address function of an IFS
    /// wants; a fit may leave it.
    pub fn is_contractive(&self) -> bool {
        self.maps.iter().all(|m| m.a.abs() < 1.0)
    }

    fn from_params(params: &[f64]) -> AffineIfs {
        AffineIfs {
            maps: params
                .chunks_exact(2)
                .map(|p| AffineMap { a: p[0], b: p[1] })
                .collect(),
        }
    }

    fn to_params(&self) -> Vec<f64> {
        self.maps.iter().flat_map(|m| [m.a, m.b]).collect()
    }
}

/// The first `depth` digits of the base-`base` expansion of `x` (clamped into `[0, 1)`),
/// most significant first. Positions just below a digit boundary count as
/// on it (`1e-9` of a digit: `0.29` gives the digit 29 in base 100). `base >= 2`.
pub(crate) fn digits(x: f64, base: usize, depth: u32) -> Vec<usize> {
    let n = base as f64;
    let mut t = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut out = Vec::with_capacity(depth as usize);
    for _ in 0..depth {
        t *= n;
        let mut d = t.floor();
        if t - d > 1.0 - DIGIT_SNAP {
            d += 1.0;
        }
        let d = d.min(n - 1.0);
        out.push(d as usize);
        t = (t - d).max(0.0);
    }
    out
}

/// The smallest `n >= 1` with `maps^n >= points`: every sample can have its own address.
pub(crate) fn default_depth(maps: usize, points: usize) -> u32 {
    let mut depth = 1;
    let mut cells = maps.max(2);
    while cells < points {
        cells = cells.saturating_mul(maps.max(2));
        depth += 1;
    }
    depth
}

/// `B_n + A_n * phi(0^omega)` for the address `digits 0^omega`, `map(k)` giving `T_k`.
fn address_value(digits: &[usize], map: impl Fn(usize) -> AffineMap) -> f64 {
    let tail = map(0).fixed_point();
    let mut b_n = 0.0;
    let mut a_n = 1.0;
    for &d in digits {
        let t = map(d);
        b_n += a_n * t.b;
        a_n *= t.a;
    }
    b_n + a_n * tail
}

/// Why data cannot be fitted.
#[derive(Debug, Clone, PartialEq)]
pub enum AffineError {
    /// No samples.
    Empty,
    /// `x` and `y` differ in length.
    LengthMismatch {
        /// Length of `x`.
        x: usize,
        /// Length of `y`.
        y: usize,
    },
    /// Fewer than two maps.
    TooFewMaps(usize),
    /// A depth of zero (every sample would get the address `0^omega`).
    ZeroDepth,
    /// `x[index]` is not in `[0, 1)`, or `y[index]` is not finite.
    OutOfRange {
        /// The sample.
        index: usize,
    },
    /// `x[index] <= x[index - 1]`: the abscissae must increase strictly.
    Unsorted {
        /// The sample.
        index: usize,
    },
}

impl fmt::Display for AffineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AffineError::Empty => write!(f, "no samples to fit"),
            AffineError::LengthMismatch { x, y } => {
                write!(f, "{x} abscissae but {y} ordinates")
            }
            AffineError::TooFewMaps(n) => write!(f, "{n} maps: an IFS fit needs at least 2"),
            AffineError::ZeroDepth => write!(f, "the address depth must be at least 1"),
            AffineError::OutOfRange { index } => write!(
                f,
                "sample {index}: x must be in [0, 1) and y must be finite"
            ),
            AffineError::Unsorted { index } => {
                write!(f, "sample {index}: x must increase strictly")
            }
        }
    }
}

impl std::error::Error for AffineError {}

/// An affine IFS fitted to function data.
#[derive(Debug, Clone, PartialEq)]
pub struct AffineFit {
    /// The fitted maps.
    pub ifs: AffineIfs,
    /// The mean squared error `g_n(T)` over the samples.
    pub mse: f64,
    /// Levenberg–Marquardt iterations run.
    pub iterations: usize,
    /// The address depth `n` used.
    pub depth: u32,
}

/// Fits an IFS of `maps` affine maps to the samples `(x[i], y[i])` (`x` in `[0, 1)`, strictly
/// increasing), minimising `g_n(T) = (1/p) sum_i (psi(alpha^(i)_1..n 0^omega) - y_i)^2`.
///
/// `depth` is the `n` of the addresses; `None` takes the default (the smallest `n` with
/// `maps^n >= p`, so that evenly spread samples get addresses of their own, and no deeper:
/// deeper digits only multiply the cost).
///
/// The start is a collage fit: `psi(k rho) = T_k(psi(rho))` says that the data on the `k`-th
/// piece `[k/N, (k+1)/N)` is an affine image in `y` of the whole data, so each `(a_k, b_k)`
/// starts as the least-squares line through the points `(f(N x_i - k), y_i)` of that piece,
/// `f` the piecewise-linear interpolation of the data. This is linear, cheap, and lands close
/// to the optimum for smooth data (the fit proper then only corrects the truncation of the
/// addresses). `a_k` is clamped into `[-0.9, 0.9]` so that the start is contractive; a piece
/// with fewer than two points (or a flat `f` there) gets `a_k = 1/N` and the `b_k` that
/// matches the mean. With `N = p` and `x_i = i/p` this start already interpolates exactly
/// (`phi(0^omega) = y_0` and `T_k(y_0) = y_k`).
///
/// Nothing keeps the fit contractive: on rough data (the paper's random values) the
/// minimiser readily takes some `|a_i| > 1`; check [`AffineIfs::is_contractive`].
pub fn fit_affine(
    x: &[f64],
    y: &[f64],
    maps: usize,
    depth: Option<u32>,
    config: &LmConfig,
) -> Result<AffineFit, AffineError> {
    validate(x, y, maps)?;
    let depth = depth.unwrap_or_else(|| default_depth(maps, x.len()));
    if depth == 0 {
        return Err(AffineError::ZeroDepth);
    }
    let addresses: Vec<usize> = x.iter().flat_map(|&v| digits(v, maps, depth)).collect();
    let n = depth as usize;
    let mut params = collage_start(x, y, maps).to_params();
    let report = minimise(
        &mut params,
        |p, r| {
            let map = |k: usize| AffineMap {
                a: p[2 * k],
                b: p[2 * k + 1],
            };
            r.extend(
                addresses
                    .chunks_exact(n)
                    .zip(y)
                    .map(|(address, yi)| address_value(address, map) - yi),
            );
        },
        config,
    );
    Ok(AffineFit {
        ifs: AffineIfs::from_params(&params),
        mse: report.error() / x.len() as f64,
        iterations: report.iterations,
        depth,
    })
}

fn validate(x: &[f64], y: &[f64], maps: usize) -> Result<(), AffineError> {
    if x.len() != y.len() {
        return Err(AffineError::LengthMismatch {
            x: x.len(),
            y: y.len(),
        });
    }
    if x.is_empty() {
        return Err(AffineError::Empty);
    }
    if maps < 2 {
        return Err(AffineError::TooFewMaps(maps));
    }
    for (index, (&xi, &yi)) in x.iter().zip(y).enumerate() {
        if !(0.0..1.0).contains(&xi) || !yi.is_finite() {
            return Err(AffineError::OutOfRange { index });
        }
        if index > 0 && xi <= x[index - 1] {
            return Err(AffineError::Unsorted { index });
        }
    }
    Ok(())
}

/// The piecewise-linear interpolation of the data at `t`, constant beyond its ends.
fn interpolate(x: &[f64], y: &[f64], t: f64) -> f64 {
    let i = x.partition_point(|&v| v <= t);
    if i == 0 {
        return y[0];
    }
    if i == x.len() {
        return y[x.len() - 1];
    }
    let w = (t - x[i - 1]) / (x[i] - x[i - 1]);
    y[i - 1] + w * (y[i] - y[i - 1])
}

/// Sums for the least-squares line `y = a f + b` through one piece's points.
#[derive(Debug, Clone, Copy, Default)]
struct LineSums {
    count: f64,
    f: f64,
    y: f64,
    ff: f64,
    fy: f64,
}

impl LineSums {
    fn add(&mut self, f: f64, y: f64) {
        self.count += 1.0;
        self.f += f;
        self.y += y;
        self.ff += f * f;
        self.fy += f * y;
    }

    fn line(&self, fallback_a: f64, fallback_b: f64) -> AffineMap {
        if self.count == 0.0 {
            return AffineMap {
                a: fallback_a,
                b: fallback_b,
            };
        }
        let (mf, my) = (self.f / self.count, self.y / self.count);
        let var = self.ff / self.count - mf * mf;
        let cov = self.fy / self.count - mf * my;
        let a = if self.count >= 2.0 && var > 1e-12 * (1.0 + mf * mf) {
            (cov / var).clamp(-START_CONTRACTION, START_CONTRACTION)
        } else {
            fallback_a
        };
        AffineMap { a, b: my - a * mf }
    }
}

/// The collage start described on [`fit_affine`].
fn collage_start(x: &[f64], y: &[f64], maps: usize) -> AffineIfs {
    let n = maps as f64;
    let mut sums = vec![LineSums::default(); maps];
    for (&xi, &yi) in x.iter().zip(y) {
        let k = digits(xi, maps, 1)[0];
        let shifted = (xi * n - k as f64).max(0.0);
        sums[k].add(interpolate(x, y, shifted), yi);
    }
    let a0 = 1.0 / n;
    let y0 = interpolate(x, y, 0.0);
    AffineIfs {
        maps: sums
            .iter()
            .enumerate()
            .map(|(k, s)| s.line(a0, interpolate(x, y, k as f64 / n) - a0 * y0))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ifs::Rng;

    fn cubic(points: usize) -> (Vec<f64>, Vec<f64>) {
        let x: Vec<f64> = (0..points).map(|i| i as f64 / points as f64).collect();
        let y = x.iter().map(|v| 6.0 * (v - 0.5f64).powi(3)).collect();
        (x, y)
    }

    fn random(points: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = Rng::new(seed);
        let x = (0..points).map(|i| i as f64 / points as f64).collect();
        let y = (0..points).map(|_| rng.unit()).collect();
        (x, y)
    }

    fn mse(x: &[f64], y: &[f64], maps: usize) -> f64 {
        fit_affine(x, y, maps, None, &LmConfig::default())
            .unwrap()
            .mse
    }

    #[test]
    fn value_matches_a_hand_computed_two_map_ifs() {
        // T_0(x) = x/2 + 0.2 (fixed point 0.4), T_1(x) = -x/4 + 1.
        let ifs = AffineIfs {
            maps: vec![AffineMap { a: 0.5, b: 0.2 }, AffineMap { a: -0.25, b: 1.0 }],
        };
        // 0.75 = 0.11 in base 2: T_1(T_1(0.4)) = T_1(0.9) = 0.775.
        assert!((ifs.value(0.75, 2) - 0.775).abs() < 1e-15);
        // 0.25 = 0.010: T_0(T_1(T_0(0.4))) = T_0(T_1(0.4)) = T_0(0.9) = 0.65.
        assert!((ifs.value(0.25, 3) - 0.65).abs() < 1e-15);
        // Depth 0 is phi(0^omega) itself.
        assert!((ifs.value(0.6, 0) - 0.4).abs() < 1e-15);
        // 1/3 = 0.(01): the fixed point of T_0 T_1, z = -z/8 + 0.7, z = 0.7 / 1.125.
        assert!((ifs.value(1.0 / 3.0, 60) - 0.7 / 1.125).abs() < 1e-12);
        assert_eq!(ifs.sample(4, 2)[3], ifs.value(0.75, 2));
    }

    #[test]
    fn fixed_point_of_a_translation_is_nan() {
        let ifs = AffineIfs {
            maps: vec![AffineMap { a: 1.0, b: 0.5 }, AffineMap { a: 0.5, b: 0.0 }],
        };
        assert!(ifs.value(0.5, 3).is_nan());
        assert!(!ifs.is_contractive());
    }

    #[test]
    fn digits_snap_floating_point_fractions() {
        // 0.29 * 100 = 28.999999999999996 in floating point.
        assert_eq!(digits(0.29, 100, 1), vec![29]);
        assert_eq!(digits(0.75, 2, 3), vec![1, 1, 0]);
        assert_eq!(digits(0.123, 10, 3), vec![1, 2, 3]);
        assert_eq!(default_depth(2, 1000), 10);
        assert_eq!(default_depth(40, 1000), 2);
        assert_eq!(default_depth(100, 100), 1);
    }

    #[test]
    fn cubic_improves_with_the_number_of_maps() {
        // Measured (1000 points, default depths 10, 5, 3, 2; default LmConfig): MSE
        // 8.97e-3, 1.90e-3, 5.26e-4, 3.46e-5 for N = 2, 5, 10, 40 (the data's variance is
        // 8.0e-2). N = 2 is ~260 times worse than N = 40; assert 100.
        let (x, y) = cubic(1000);
        let errors: Vec<f64> = [2, 5, 10, 40].iter().map(|&n| mse(&x, &y, n)).collect();
        assert!(errors.windows(2).all(|w| w[1] < w[0]), "{errors:?}");
        assert!(errors[0] > 100.0 * errors[3], "{errors:?}");
    }

    #[test]
    fn random_data_improves_and_is_exact_with_one_map_per_sample() {
        // Measured (seed 7, default depths 3, 2, 2, 1): MSE 8.14e-2, 6.10e-2, 2.26e-2, 0 for
        // N = 5, 10, 40, 100, against a variance of 9.06e-2 (the best constant). The fits for
        // N = 5, 10, 40 leave contraction (max |a_i| 20, 286, 2.3).
        let (x, y) = random(100, 7);
        let mean = y.iter().sum::<f64>() / y.len() as f64;
        let variance = y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / y.len() as f64;
        let errors: Vec<f64> = [5, 10, 40, 100].iter().map(|&n| mse(&x, &y, n)).collect();
        assert!(errors.windows(2).all(|w| w[1] < w[0]), "{errors:?}");
        assert!(errors[0] < 0.95 * variance, "{errors:?} {variance}");
        assert!(errors[3] < 1e-20, "{errors:?}");
        let exact = fit_affine(&x, &y, 100, None, &LmConfig::default()).unwrap();
        assert_eq!(exact.depth, 1);
        for (&xi, &yi) in x.iter().zip(&y) {
            assert!((exact.ifs.value(xi, 1) - yi).abs() < 1e-12);
        }
    }

    #[test]
    fn rejects_bad_data() {
        let c = LmConfig::default();
        assert_eq!(fit_affine(&[], &[], 2, None, &c), Err(AffineError::Empty));
        assert_eq!(
            fit_affine(&[0.0, 0.5], &[1.0, 2.0], 1, None, &c),
            Err(AffineError::TooFewMaps(1))
        );
        assert_eq!(
            fit_affine(&[0.5, 0.2], &[1.0, 2.0], 2, None, &c),
            Err(AffineError::Unsorted { index: 1 })
        );
        assert_eq!(
            fit_affine(&[0.0, 1.0], &[1.0, 2.0], 2, None, &c),
            Err(AffineError::OutOfRange { index: 1 })
        );
        assert_eq!(
            fit_affine(&[0.0, 0.5], &[1.0, 2.0], 2, Some(0), &c),
            Err(AffineError::ZeroDepth)
        );
    }
}
