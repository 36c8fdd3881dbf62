//! Quantisation of fitted parameters into syntax elements: uniform quantisers for control values
//! (one step per 'cquant'), uniform and Lloyd-Max quantisers for weights (thesis III.3.4).

use super::fit::Fit;
use decoder_core::bitstream::{
    dequantise_control, intra_prediction, Codebook, LeafSyntax, MAX_CODEBOOK,
};
use decoder_core::model::{
    for_each_free_tap, WeightClass, WeightQuantiser, CONTROL_STEPS, MAX_CONTROL, MODELS,
    SAMPLE_MAX, SAMPLE_MIN, SAMPLE_ONE, WEIGHT_LIMIT, WEIGHT_ONE, WEIGHT_QUANTISER_KINDS,
};

/// Quantises `fit` with control quantiser `cq` and weight quantiser `wq`; also returns the
/// control values the decoder will reconstruct (sample units, row-major), which the DPCM
/// computes anyway.
pub fn quantise(
    fit: &Fit,
    cq: u8,
    wq: u8,
    codebooks: &[Codebook; 2],
) -> (LeafSyntax, [i16; MAX_CONTROL]) {
    let model = MODELS[usize::from(fit.model)];
    let mut leaf = LeafSyntax {
        model: fit.model,
        cquant: cq,
        wquant: wq,
        ..LeafSyntax::default()
    };
    // DPCM within the leaf, against the values the decoder will reconstruct.
    let step = CONTROL_STEPS[usize::from(cq)];
    let side = model.grid();
    let mut values = [0i16; MAX_CONTROL];
    for (i, &c) in fit.control.iter().enumerate().take(side * side) {
        let target =
            (c * f64::from(SAMPLE_ONE)).clamp(f64::from(SAMPLE_MIN), f64::from(SAMPLE_MAX));
        let base = if i == 0 {
            0
        } else {
            intra_prediction(&values, side, i / side, i % side)
        };
        // Indices stay far inside i16: |target - base| < 2^14 and the step is at least 24.
        let index = deadzone_round((target - f64::from(base)) / f64::from(step));
        leaf.control[i] = index as i16;
        values[i] = dequantise_control(base, step, index);
    }
    let kind = WEIGHT_QUANTISER_KINDS[usize::from(wq)];
    if kind == WeightQuantiser::Default {
        // The default weights: every index stays zero.
        return (leaf, values);
    }
    let mut i = 0;
    for_each_free_tap(model, |slot| {
        let dev = fit.weights.get(i).copied().unwrap_or(0.0) * f64::from(WEIGHT_ONE);
        // Both kinds give small indices (at most 2 * WEIGHT_LIMIT / step, or a codebook size).
        leaf.weights[i] = match kind {
            WeightQuantiser::Default => 0,
            WeightQuantiser::Uniform(step) => {
                let lim = 2 * WEIGHT_LIMIT / step;
                ((dev / f64::from(step)).round() as i32).clamp(-lim, lim) as i16
            }
            WeightQuantiser::Codebook => {
                let book = &codebooks[slot.class() as usize];
                (nearest_level(book, dev) - book.center()) as i16
            }
        };
        i += 1;
    });
    (leaf, values)
}

/// Rounding offset of the control quantisers: values are rounded towards zero unless they are
/// at least this far past a step, so that small residuals cost nothing (a dead zone).
const ROUNDING_OFFSET: f64 = 0.35;

fn deadzone_round(v: f64) -> i32 {
    // The truncating cast floors the non-negative magnitude (no libm call).
    let magnitude = (v.abs() + ROUNDING_OFFSET) as i32;
    if v < 0.0 {
        -magnitude
    } else {
        magnitude
    }
}

fn nearest_level(book: &Codebook, v: f64) -> i32 {
    let mut best = 0;
    for i in 0..usize::from(book.len) {
        if (f64::from(book.levels[i]) - v).abs() < (f64::from(book.levels[best]) - v).abs() {
            best = i;
        }
    }
    best as i32
}

/// Designs a Lloyd-Max codebook of `levels` levels (at most [`MAX_CODEBOOK`]) for the weight
/// deviations `samples` (weight units, 1.0 = one). Returns an empty codebook when there is too
/// little data.
pub fn lloyd_max(samples: &mut [f64], levels: usize) -> Codebook {
    let levels = levels.clamp(2, MAX_CODEBOOK);
    if samples.len() < levels * 4 {
        return Codebook::EMPTY;
    }
    samples.sort_by(f64::total_cmp);
    let scale = f64::from(WEIGHT_ONE);
    // Start at the quantiles, then alternate centroids and midpoints (Lloyd's method I).
    let mut q: Vec<f64> = (0..levels)
        .map(|i| samples[(2 * i + 1) * samples.len() / (2 * levels)] * scale)
        .collect();
    for _ in 0..50 {
        let mut sum = vec![0.0; levels];
        let mut count = vec![0usize; levels];
        let mut j = 0;
        for &s in samples.iter() {
            let v = s * scale;
            while j + 1 < levels && v > 0.5 * (q[j] + q[j + 1]) {
                j += 1;
            }
            sum[j] += v;
            count[j] += 1;
        }
        for i in 0..levels {
            if count[i] > 0 {
                q[i] = sum[i] / count[i] as f64;
            }
        }
    }
    let mut book = Codebook::EMPTY;
    let mut last = i32::MIN;
    for v in q {
        let l = (v.round() as i32).clamp(-WEIGHT_LIMIT, WEIGHT_LIMIT);
        if l > last {
            book.levels[usize::from(book.len)] = l as i16;
            book.len += 1;
            last = l;
        }
    }
    if book.len < 2 {
        return Codebook::EMPTY;
    }
    book
}

/// The weight class of every free weight of model `model`, in coding order.
pub fn weight_classes(model: u8) -> Vec<WeightClass> {
    let mut v = Vec::new();
    for_each_free_tap(MODELS[usize::from(model)], |slot| v.push(slot.class()));
    v
}
