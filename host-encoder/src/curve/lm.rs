//! Levenberg–Marquardt least squares with a forward-difference Jacobian (thesis II.3.5): the
//! curve fits and the affine IFS of function data both minimise a sum of squared residuals
//! of a model polynomial in its parameters.

use nalgebra::{DMatrix, DVector};

/// When a minimisation stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmConfig {
    /// Iterations at most (each one Jacobian and as many trial steps as it takes).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the sum of squares by less than this fraction of it.
    pub tolerance: f64,
}

impl Default for LmConfig {
    fn default() -> Self {
        LmConfig {
            max_iterations: 300,
            tolerance: 1e-10,
        }
    }
}

/// What a minimisation did.
#[derive(Debug, Clone, PartialEq)]
pub struct LmReport {
    /// Iterations run (Jacobians evaluated).
    pub iterations: usize,
    /// The sum of squared residuals after each iteration, the starting one first.
    pub history: Vec<f64>,
}

impl LmReport {
    /// The final sum of squared residuals.
    pub fn error(&self) -> f64 {
        self.history.last().copied().unwrap_or(f64::NAN)
    }
}

/// Minimises `sum r_i(a)^2` over `params` (updated in place), `residuals(a, r)` writing the
/// residuals into `r` (cleared first; always the same count). Starts in the basin of the
/// solution, as the thesis assumes: the method is local.
pub fn minimise(
    params: &mut [f64],
    mut residuals: impl FnMut(&[f64], &mut Vec<f64>),
    config: &LmConfig,
) -> LmReport {
    let n = params.len();
    let mut r = Vec::new();
    let mut eval = |a: &[f64], r: &mut Vec<f64>| -> f64 {
        r.clear();
        residuals(a, r);
        r.iter().map(|v| v * v).sum()
    };
    let mut error = eval(params, &mut r);
    let mut history = vec![error];
    let mut damping = 1e-3;
    let mut shifted = params.to_vec();
    let mut trial = Vec::new();
    let mut iterations = 0;
    while iterations < config.max_iterations && error > 0.0 {
        iterations += 1;
        let m = r.len();
        let mut jacobian = DMatrix::zeros(m, n);
        for j in 0..n {
            let h = 1e-7 * params[j].abs().max(1.0);
            shifted.copy_from_slice(params);
            shifted[j] += h;
            eval(&shifted, &mut trial);
            for (i, (t, v)) in trial.iter().zip(&r).enumerate() {
                jacobian[(i, j)] = (t - v) / h;
            }
        }
        let jt = jacobian.transpose();
        let normal = &jt * &jacobian;
        let gradient = &jt * DVector::from_column_slice(&r);
        let mut improved = false;
        while damping < 1e12 {
            let mut a = normal.clone();
            for k in 0..n {
                a[(k, k)] += damping * normal[(k, k)].max(1e-12);
            }
            let Some(step) = a.lu().solve(&gradient) else {
                damping *= 10.0;
                continue;
            };
            for (s, (p, d)) in shifted.iter_mut().zip(params.iter().zip(step.iter())) {
                *s = p - d;
            }
            let e = eval(&shifted, &mut trial);
            if e.is_finite() && e < error {
                params.copy_from_slice(&shifted);
                std::mem::swap(&mut r, &mut trial);
                let gain = (error - e) / error;
                error = e;
                damping = (damping / 10.0).max(1e-12);
                improved = gain >= config.tolerance;
                break;
            }
            damping *= 10.0;
        }
        history.push(error);
        if !improved {
            break;
        }
    }
    LmReport {
        iterations,
        history,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential_decay_exactly() {
        // y = 3 exp(-0.5 x) + 1 sampled without noise; start far from it.
        let xs: Vec<f64> = (0..40).map(|i| i as f64 * 0.25).collect();
        let ys: Vec<f64> = xs.iter().map(|x| 3.0 * (-0.5 * x).exp() + 1.0).collect();
        let mut a = [1.0, -0.1, 0.0];
        let report = minimise(
            &mut a,
            |a, r| {
                r.extend(
                    xs.iter()
                        .zip(&ys)
                        .map(|(x, y)| a[0] * (a[1] * x).exp() + a[2] - y),
                )
            },
            &LmConfig::default(),
        );
        assert!(report.error() < 1e-16, "{report:?}");
        for (got, want) in a.iter().zip([3.0, -0.5, 1.0]) {
            assert!((got - want).abs() < 1e-6, "{a:?}");
        }
        assert!(report.history.windows(2).all(|w| w[1] <= w[0]));
    }
}
