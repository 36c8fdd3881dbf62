//! Affine IFS fitted to function data (Guérin & Tosan, §6.1): the error against the number
//! of maps `N` for the paper's two data sets.
//!
//! ```text
//! cargo run --release -p host-encoder --example affine_ifs
//! ```
//!
//! Prints a markdown table per data set: the cubic `y = 6 (x - 1/2)^3` at 1000 points
//! `x = i / 1000`, and 100 uniform random values in `[0, 1)` at `x = i / 100` (seed 7). The
//! depth of the addresses is the default, the smallest `n` with `N^n >= p`; the minimiser
//! runs with `LmConfig::default()` (at most 300 iterations). "contractive" says whether every
//! fitted `|a_i| < 1`.

use host_encoder::curve::{fit_affine, AffineFit, LmConfig};
use host_encoder::ifs::Rng;

/// The random data set's seed.
const SEED: u64 = 7;

fn abscissae(points: usize) -> Vec<f64> {
    (0..points).map(|i| i as f64 / points as f64).collect()
}

fn table(title: &str, x: &[f64], y: &[f64], counts: &[usize]) {
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let variance = y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / y.len() as f64;
    println!("### {title} ({} points)\n", x.len());
    println!("Variance of y (the MSE of the best constant): {variance:.3e}\n");
    println!("| N | depth n | MSE | RMSE | iterations | contractive | largest abs(a) |");
    println!("|---:|---:|---:|---:|---:|:---:|---:|");
    for &maps in counts {
        let fit: AffineFit =
            fit_affine(x, y, maps, None, &LmConfig::default()).expect("the data sets are valid");
        println!(
            "| {maps} | {} | {:.3e} | {:.3e} | {} | {} | {:.3} |",
            fit.depth,
            fit.mse,
            fit.mse.sqrt(),
            fit.iterations,
            if fit.ifs.is_contractive() {
                "yes"
            } else {
                "no"
            },
            fit.ifs.maps.iter().map(|m| m.a.abs()).fold(0.0, f64::max)
        );
    }
    println!();
}

fn main() {
    let x = abscissae(1000);
    let y: Vec<f64> = x.iter().map(|v| 6.0 * (v - 0.5f64).powi(3)).collect();
    table("Cubic y = 6 (x - 1/2)^3", &x, &y, &[2, 5, 10, 40]);

    let x = abscissae(100);
    let mut rng = Rng::new(SEED);
    let y: Vec<f64> = x.iter().map(|_| rng.unit()).collect();
    table(
        &format!("Random y in [0, 1), seed {SEED}"),
        &x,
        &y,
        &[2, 5, 10, 40, 100],
    );
}
