//! Projected-IFS curves against the thesis (II.4.1): the error against the number of
//! parameters, smooth rules against fitted weights, and the effect of quantising the
//! parameters (II.4.1.4).
//!
//! ```text
//! cargo run --release -p host-encoder --example curve_study -- [CURVE.csv ...]
//! ```
//!
//! Prints markdown tables: the synthetic cases (a Bézier curve, a rough projected-IFS curve, a
//! midpoint-displacement profile), then each CSV given (`bench/curves.sh` passes real
//! elevation profiles and contour lines), each fitted with fitted weights (4 points and 2
//! maps, 6 and 3, 8 and 2) and with the smooth rules at about the same parameter counts (12,
//! 35 and 54 control points); then the 6-point, 3-map fit of each CSV with every free
//! parameter quantised uniformly to 6–12 bits.

use host_encoder::curve::{fit_curve, read_csv, CurveFit, CurveFitConfig, Point, ProjectedCurve};
use host_encoder::ifs::Rng;

/// The models compared: (control points, maps, fitted weights).
const MODELS: [(usize, usize, bool); 6] = [
    (4, 2, true),
    (12, 2, false),
    (6, 3, true),
    (35, 2, false),
    (8, 2, true),
    (54, 2, false),
];

fn fit(data: &[Point], points: usize, maps: usize, weights: bool) -> CurveFit {
    let config = CurveFitConfig {
        weights,
        ..CurveFitConfig::new(points, maps)
    };
    fit_curve(data, &config).expect("the study's curves fit")
}

fn span(data: &[Point]) -> f64 {
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for p in data {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (hi[0] - lo[0]).max(hi[1] - lo[1])
}

fn study(name: &str, data: &[Point]) {
    println!(
        "### {name} ({} points, extent {:.4})\n",
        data.len(),
        span(data)
    );
    println!("| model | parameters | rms distance | rms / extent | D | iterations |");
    println!("|---|---:|---:|---:|---:|---:|");
    for (points, maps, weights) in MODELS {
        let f = fit(data, points, maps, weights);
        let rules = if weights {
            "fitted weights"
        } else {
            "smooth rules"
        };
        println!(
            "| {points} points, {maps} maps, {rules} | {} | {:.5} | {:.2e} | {:.4e} | {} |",
            f.parameters,
            f.rms,
            f.rms / span(data),
            f.distance,
            f.iterations
        );
    }
    println!();
}

/// A curve with its free parameters quantised uniformly to `bits` bits: the control points'
/// coordinates over their range on each axis, the matrices' free weights over theirs (every weight but a
/// column's last, which keeps the column's sum at 1; the fixed columns `e_0` of `T_0` and
/// `e_m` of `T_{N-1}` are not parameters).
fn quantised(curve: &ProjectedCurve, bits: u32) -> ProjectedCurve {
    let levels = f64::from((1u32 << bits) - 1);
    let grid = |values: &mut dyn Iterator<Item = &mut f64>, lo: f64, hi: f64| {
        for v in values {
            *v = lo + ((*v - lo) / (hi - lo) * levels).round() / levels * (hi - lo);
        }
    };
    let mut out = curve.clone();
    for axis in 0..2 {
        let (lo, hi) = curve.points.iter().fold((f64::MAX, f64::MIN), |(l, h), p| {
            (l.min(p[axis]), h.max(p[axis]))
        });
        grid(&mut out.points.iter_mut().map(|p| &mut p[axis]), lo, hi);
    }
    let (n, last) = (curve.points.len(), curve.maps.len() - 1);
    let free = |k: usize, j: usize| !((k == 0 && j == 0) || (k == last && j == n - 1));
    let weights: Vec<f64> = (0..=last)
        .flat_map(|k| (0..n).filter(move |&j| free(k, j)).map(move |j| (k, j)))
        .flat_map(|(k, j)| curve.maps[k][j][..n - 1].to_vec())
        .collect();
    let (lo, hi) = weights
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
    for k in 0..=last {
        for j in (0..n).filter(|&j| free(k, j)) {
            let column = &mut out.maps[k][j];
            grid(&mut column[..n - 1].iter_mut(), lo, hi);
            column[n - 1] = 1.0 - column[..n - 1].iter().sum::<f64>();
        }
    }
    out
}

fn quantisation(name: &str, data: &[Point]) {
    let config = CurveFitConfig::new(6, 3);
    let f = fit_curve(data, &config).expect("the study's curves fit");
    println!(
        "### Quantised parameters: {name}, 6 points, 3 maps ({} parameters)\n",
        f.parameters
    );
    println!("| bits per parameter | bits in all | rms distance | against unquantised |");
    println!("|---:|---:|---:|---:|");
    for bits in [6, 7, 8, 9, 10, 12] {
        let q = quantised(&f.curve, bits);
        let d = host_encoder::curve::distance(&q.tabulate(config.depth), data, config.resample);
        let rms = (d / (config.resample + 1) as f64).sqrt();
        println!(
            "| {bits} | {} | {rms:.5} | {:.3}x |",
            bits as usize * f.parameters,
            rms / f.rms
        );
    }
    println!("| unquantised | | {:.5} | 1x |\n", f.rms);
}

/// A midpoint-displacement (fractional Brownian) profile of `2^levels + 1` samples over
/// `[0, 1]`, displacement scaled by `2^-hurst` per level.
fn midpoint_profile(levels: u32, hurst: f64, seed: u64) -> Vec<Point> {
    let n = 1usize << levels;
    let mut rng = Rng::new(seed);
    let mut gauss = move || {
        // Box–Muller.
        let (u, v) = (rng.unit().max(1e-12), rng.unit());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let mut h = vec![0.0; n + 1];
    h[n] = 0.3;
    let (mut step, mut amp) = (n, 0.5);
    while step > 1 {
        for i in (0..n).step_by(step) {
            h[i + step / 2] = (h[i] + h[i + step]) / 2.0 + amp * gauss();
        }
        step /= 2;
        amp *= 2f64.powf(-hurst);
    }
    h.iter()
        .enumerate()
        .map(|(i, v)| [i as f64 / n as f64, *v])
        .collect()
}

fn main() {
    let bezier = ProjectedCurve::bezier(vec![[0.0, 0.0], [1.0, 3.0], [3.0, -1.0], [4.0, 1.0]], 2);
    study(
        "Bézier curve (4 points, 2 maps), depth 10",
        &bezier.tabulate(10),
    );
    let mut rough = bezier.clone();
    for (k, map) in rough.maps.iter_mut().enumerate() {
        // Interior columns moved off the smooth scheme, joins kept (T_0 e_3 = T_1 e_0).
        for (j, column) in map
            .iter_mut()
            .enumerate()
            .filter(|(j, _)| *j == 1 || *j == 2)
        {
            let bump = if (j + k) % 2 == 0 { 0.12 } else { -0.12 };
            column[1] += bump;
            column[2] -= bump;
        }
    }
    study(
        "Rough projected-IFS curve (4 points, 2 maps), depth 10",
        &rough.tabulate(10),
    );
    study(
        "Midpoint-displacement profile, H = 0.85, 1025 samples",
        &midpoint_profile(10, 0.85, 1),
    );
    let curves: Vec<(String, Vec<Point>)> = std::env::args()
        .skip(1)
        .map(|path| {
            let text = std::fs::read_to_string(&path).expect("a readable CSV");
            (path, read_csv(&text).expect("a CSV of points"))
        })
        .collect();
    for (path, data) in &curves {
        study(path, data);
    }
    for (path, data) in &curves {
        quantisation(path, data);
    }
}
