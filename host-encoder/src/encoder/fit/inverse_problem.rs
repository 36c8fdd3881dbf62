//! The fractal inverse problem for one block (thesis II.4.1): a block synthesised from known
//! model parameters, rounded to 8 bits, is fitted back by the encoder's Levenberg-Marquardt
//! fitter ([`super::fit_block`]); the fitted parameters must reproduce the synthesised
//! (unrounded) block to >= 50 dB.
//!
//! Rounding to integers alone costs about 59 dB (a uniform error of variance 1/12), and a
//! least-squares fit with fewer parameters than samples filters part of that noise, so a fitter
//! that converges reaches 50 dB with margin.
//!
//! Two weight perturbations are used: mild (deviations in +-0.05, where the default weights are
//! already close) and strong (+-0.2, where the default weights with the true control values are
//! well below 50 dB, so only a real fit of the weights passes).
//!
//! Unit tests of the fitter and of [`Tabulator`] (the encoder's internals).

use super::super::ids::ModelId;
use super::super::plane::{psnr as psnr_of_sse, Plane};
use super::super::synthesis::Tabulator;
use super::fit_block;
use decoder_core::internal::model::{ModelType, MODELS};
use decoder_core::{Node, PixelSink, Rect, Tile};
use std::convert::Infallible;

/// A 32-bit linear congruential generator (Numerical Recipes constants): deterministic on
/// every platform (as the integration tests' own).
struct Lcg(u32);

impl Lcg {
    fn new(seed: u32) -> Self {
        Lcg(seed ^ 0x9E37_79B9)
    }

    fn next_u32(&mut self) -> u32 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        self.0
    }

    /// Uniform in `[-1, 1)`.
    fn unit(&mut self) -> f64 {
        f64::from(self.next_u32() >> 8) / f64::from(1u32 << 23) - 1.0
    }
}

/// Records the pixels it is given, how often each was written, and any tile that breaks the
/// [`PixelSink`] contract (a copy of the integration tests' sink, which this crate cannot use).
struct CoverageSink {
    width: u32,
    height: u32,
    counts: Vec<u32>,
    pixels: Vec<u8>,
    violations: Vec<String>,
}

impl CoverageSink {
    fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        CoverageSink {
            width,
            height,
            counts: vec![0; n],
            pixels: vec![0; n],
            violations: Vec::new(),
        }
    }

    /// Pixels written a number of times other than once: `(x, y, count)`, at most `limit`.
    fn not_once(&self, limit: usize) -> Vec<(u32, u32, u32)> {
        self.counts
            .iter()
            .enumerate()
            .filter(|(_, &c)| c != 1)
            .take(limit)
            .map(|(i, &c)| {
                (
                    (i % self.width as usize) as u32,
                    (i / self.width as usize) as u32,
                    c,
                )
            })
            .collect()
    }
}

impl PixelSink for CoverageSink {
    type Error = Infallible;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
        let Rect { x, y, w, h } = tile.area;
        let pixels = tile.pixels;
        let tile = decoder_core::TILE as u32;
        if w == 0 || h == 0 || w > tile || h > tile {
            self.violations
                .push(format!("tile {w}x{h} at ({x}, {y}): bad tile size"));
        }
        if pixels.len() != w as usize * h as usize {
            self.violations.push(format!(
                "tile {w}x{h} at ({x}, {y}): {} pixels",
                pixels.len()
            ));
            return Ok(());
        }
        if u64::from(x) + u64::from(w) > u64::from(self.width)
            || u64::from(y) + u64::from(h) > u64::from(self.height)
        {
            self.violations.push(format!(
                "tile {w}x{h} at ({x}, {y}) outside the {}x{} image",
                self.width, self.height
            ));
            return Ok(());
        }
        let mut k = 0;
        for py in y..y + h {
            for px in x..x + w {
                let i = py as usize * self.width as usize + px as usize;
                self.counts[i] += 1;
                self.pixels[i] = pixels[k];
                k += 1;
            }
        }
        Ok(())
    }
}

/// The PSNR the fitted parameters must reach against the exact synthesised block.
const REQUIRED_DB: f64 = 50.0;
/// Mild weight perturbation: deviations uniform in `[-MILD, MILD]`.
const MILD: f64 = 0.05;
/// Strong weight perturbation.
const STRONG: f64 = 0.2;

/// Tabulates `model` with `control` (grey levels) and weight deviations `dev` on a block of side
/// `2^log2`; returns the samples row-major.
fn tabulate(model: ModelType, control: &[f64], dev: &[f64], log2: u8) -> Vec<f64> {
    let size = 1usize << log2;
    let mut out = vec![f64::NAN; size * size];
    let mut tab = Tabulator::new(model, dev, false);
    assert_eq!(tab.sample_len(), 1);
    let side = size as u32;
    // Only the block's own pixels (the tabulator may also offer the row and column it shares
    // with its neighbours).
    tab.run(
        control,
        log2,
        &|dx, dy| dx < side && dy < side,
        &|_, _, _| true,
        &mut |dx, dy, s| {
            out[dy as usize * size + dx as usize] = s[0];
        },
    );
    assert!(
        out.iter().all(|v| v.is_finite()),
        "the tabulator did not emit every sample of the block"
    );
    out
}

/// Known parameters of a test block: a tilted plane with one gentle bump, sampled on the control
/// grid, plus jitter of +-35 grey levels (so that the subdivision weights visibly matter), and
/// weight deviations uniform in `[-amplitude, amplitude]`.
fn parameters(model: ModelType, seed: u32, amplitude: f64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Lcg::new(seed);
    let side = model.grid();
    let m = f64::from(model.intervals);
    let mut control = Vec::with_capacity(side * side);
    for u in 0..side {
        for v in 0..side {
            let (y, x) = (u as f64 / m, v as f64 / m);
            let bump = 30.0 * (-((x - 0.6).powi(2) + (y - 0.4).powi(2)) * 6.0).exp();
            control.push(70.0 + 50.0 * x + 30.0 * y + bump + 35.0 * rng.unit());
        }
    }
    let weights = (0..model.weight_count())
        .map(|_| amplitude * rng.unit())
        .collect();
    (control, weights)
}

fn psnr(a: &[f64], b: &[f64]) -> f64 {
    let sse: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    psnr_of_sse(sse, a.len())
}

/// PSNRs against the exact synthesised block.
struct Outcome {
    /// The fitted parameters.
    fitted: f64,
    /// The rounded 8-bit block the fitter saw (the noise floor).
    rounded: f64,
    /// The true control values with the default weights (how much the weights matter).
    default_weights: f64,
}

/// Synthesises, rounds, fits and measures.
fn round_trip(model_index: u8, log2: u8, seed: u32, amplitude: f64) -> Outcome {
    let model = MODELS[usize::from(model_index)];
    assert!(model.fits_block(log2), "model {model_index} at 2^{log2}");
    let (control, weights) = parameters(model, seed, amplitude);
    let exact = tabulate(model, &control, &weights, log2);
    let (lo, hi) = exact
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    // The block must not need clipping, or the 8-bit plane would not be the model's block.
    assert!(
        lo > 1.0 && hi < 254.0,
        "synthesised block out of range: {lo}..{hi}"
    );
    let size = 1u32 << log2;
    let plane = Plane::new(size, size, exact.iter().map(|v| v.round() as u8).collect());
    let rounded: Vec<f64> = plane.data.iter().map(|&p| f64::from(p)).collect();
    let node = Node { x: 0, y: 0, log2 };
    let fit = fit_block(&plane, &node, ModelId::new(model_index));
    assert_eq!(fit.model, ModelId::new(model_index));
    assert_eq!(fit.control.len(), model.control_count());
    assert_eq!(fit.weights.len(), model.weight_count());
    let fitted = tabulate(model, &fit.control, &fit.weights, log2);
    let default_weights = tabulate(model, &control, &[], log2);
    Outcome {
        fitted: psnr(&fitted, &exact),
        rounded: psnr(&rounded, &exact),
        default_weights: psnr(&default_weights, &exact),
    }
}

fn check(model_index: u8, log2: u8) {
    let model = MODELS[usize::from(model_index)];
    let amplitudes: &[f64] = if model.weight_count() > 0 {
        &[MILD, STRONG]
    } else {
        &[0.0]
    };
    let size = 1u32 << log2;
    for &amplitude in amplitudes {
        for seed in [1, 2] {
            let o = round_trip(model_index, log2, seed, amplitude);
            println!(
                "model {model_index} on {size}x{size}, weights +-{amplitude}, seed {seed}: fit \
                 {:.2} dB; rounding alone {:.2} dB; default weights {:.2} dB",
                o.fitted, o.rounded, o.default_weights
            );
            assert!(
                o.rounded > 55.0 && o.rounded < 62.0,
                "rounding noise {:.2} dB",
                o.rounded
            );
            if amplitude == STRONG {
                assert!(
                    o.default_weights < REQUIRED_DB - 5.0,
                    "model {model_index}, seed {seed}: the strong perturbation is too weak to \
                     test the weight fit (default weights already give {:.2} dB)",
                    o.default_weights
                );
            }
            assert!(
                o.fitted >= REQUIRED_DB,
                "model {model_index} on a {size}x{size} block, weights +-{amplitude}, seed \
                 {seed}: the fit reproduces the synthesised block to only {:.2} dB (need \
                 {REQUIRED_DB} dB; rounding alone is {:.2} dB)",
                o.fitted,
                o.rounded
            );
        }
    }
}

#[test]
fn model_0_bilinear_is_recovered() {
    // No weights: the fit is linear in the control values; a check of the harness itself.
    check(0, 4);
}

#[test]
fn model_1_on_16x16() {
    check(1, 4);
}

#[test]
fn model_1_on_32x32() {
    check(1, 5);
}

#[test]
fn model_2_on_16x16() {
    check(2, 4);
}

#[test]
fn model_2_on_32x32() {
    check(2, 5);
}

#[test]
fn model_3_on_16x16() {
    check(3, 4);
}

#[test]
fn model_3_on_32x32() {
    check(3, 5);
}

#[test]
fn model_4_on_32x32() {
    // At 16x16 the fitter does not fit model 4's weights at all (256 samples < 3 x 126
    // parameters, see `fit_block`): 32x32 is its smallest block with weights.
    check(4, 5);
}

#[test]
fn tabulator_follows_the_integer_synthesis() {
    // The float tabulator is the model the fitter optimises; decoder-core's integer synthesis is
    // what a decoder shows. For parameters on the format's grids (control values in 1/16 grey
    // level, weights in 1/4096) they agree to within the integer rounding.
    use decoder_core::internal::model::{Weights, MAX_CONTROL, SAMPLE_ONE, WEIGHT_ONE};
    use decoder_core::internal::synthesis::Patch;
    for (mi, &model) in MODELS.iter().enumerate() {
        let log2 = 5;
        let (control, weights) = parameters(model, 9 + mi as u32, MILD);
        let control_q: Vec<i16> = control
            .iter()
            .map(|c| (c * f64::from(SAMPLE_ONE)).round() as i16)
            .collect();
        let dev_q: Vec<i32> = weights
            .iter()
            .map(|w| (w * f64::from(WEIGHT_ONE)).round() as i32)
            .collect();
        let control: Vec<f64> = control_q
            .iter()
            .map(|&c| f64::from(c) / f64::from(SAMPLE_ONE))
            .collect();
        let dev: Vec<f64> = dev_q
            .iter()
            .map(|&d| f64::from(d) / f64::from(WEIGHT_ONE))
            .collect();
        let exact = tabulate(model, &control, &dev, log2);
        let mut patch = Patch {
            model,
            control: [0; MAX_CONTROL],
            weights: Weights::from_deviations(model, &dev_q),
        };
        patch.control[..control_q.len()].copy_from_slice(&control_q);
        let size = 1u32 << log2;
        let mut sink = CoverageSink::new(size, size);
        let node = Node { x: 0, y: 0, log2 };
        let Ok(()) = patch.render(&node, Rect::of_size(size, size), &mut sink);
        assert!(
            sink.violations.is_empty(),
            "model {mi}: {:?}",
            sink.violations
        );
        assert_eq!(sink.not_once(3), vec![], "model {mi}");
        let worst = sink
            .pixels
            .iter()
            .zip(&exact)
            .map(|(&p, &e)| (f64::from(p) - e).abs())
            .fold(0.0, f64::max);
        assert!(
            worst <= 1.0,
            "model {mi}: integer and float synthesis differ by {worst} grey levels"
        );
    }
}
