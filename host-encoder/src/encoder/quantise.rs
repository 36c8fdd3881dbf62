//! Quantisation of fitted parameters into syntax elements: uniform quantisers for control values
//! (one step per 'cquant'), uniform and Lloyd-Max quantisers for weights (thesis III.3.4).

use super::fit::Fit;
use decoder_core::bitstream::{
    dequantise_control, intra_prediction, transform_control_values, Codebook, ControlCoding,
    LeafSyntax, MAX_CODEBOOK,
};
use decoder_core::model::{
    coefficient_step, for_each_free_tap, grid_sizes, WeightClass, WeightQuantiser, CONTROL_STEPS,
    MAX_CONTROL, MAX_GRID, MODELS, SAMPLE_MAX, SAMPLE_MIN, SAMPLE_ONE, WEIGHT_LIMIT, WEIGHT_ONE,
    WEIGHT_QUANTISER_KINDS,
};

/// A fit's control values prepared for quantisation, once for all quantisers: in sample units,
/// and as grid-transform coefficients.
pub struct ControlTargets {
    samples: [f64; MAX_CONTROL],
    coefficients: [f64; MAX_CONTROL],
}

impl ControlTargets {
    /// The targets of `fit`'s control values.
    pub fn of(fit: &Fit) -> Self {
        let side = MODELS[usize::from(fit.model)].grid();
        let mut samples = [0.0f64; MAX_CONTROL];
        for (g, &c) in samples.iter_mut().zip(&fit.control).take(side * side) {
            *g = (c * f64::from(SAMPLE_ONE)).clamp(f64::from(SAMPLE_MIN), f64::from(SAMPLE_MAX));
        }
        let mut coefficients = samples;
        forward_grid_transform(&mut coefficients, side);
        ControlTargets {
            samples,
            coefficients,
        }
    }
}

/// Quantises `fit` (whose control values `targets` holds) with control quantiser `cq`, control
/// coding `coding` and weight quantiser `wq`; also returns the control values the decoder will
/// reconstruct (sample units, row-major), which both codings compute anyway.
pub fn quantise(
    fit: &Fit,
    targets: &ControlTargets,
    cq: u8,
    wq: u8,
    coding: ControlCoding,
    codebooks: &[Codebook; 2],
) -> (LeafSyntax, [i16; MAX_CONTROL]) {
    let model = MODELS[usize::from(fit.model)];
    let mut leaf = LeafSyntax {
        model: fit.model,
        cquant: cq,
        wquant: wq,
        coding,
        ..LeafSyntax::default()
    };
    let step = CONTROL_STEPS[usize::from(cq)];
    let side = model.grid();
    let values = match coding {
        ControlCoding::Dpcm => quantise_dpcm(&targets.samples, side, step, &mut leaf.control),
        ControlCoding::Transform => {
            // Each coefficient of the grid transform is quantised with its own step.
            for (i, &v) in targets.coefficients.iter().enumerate().take(side * side) {
                // Coefficients are below 2^18 and steps at least 1: indices fit in i16.
                let index = deadzone_round(v / f64::from(coefficient_step(side, i, step)));
                leaf.control[i] = index as i16;
            }
            let mut values = [0i16; MAX_CONTROL];
            transform_control_values(side, step, &leaf.control, &mut values);
            values
        }
    };
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

/// DPCM within the leaf, against the values the decoder will reconstruct: writes the indices
/// and returns those values.
fn quantise_dpcm(
    grid: &[f64; MAX_CONTROL],
    side: usize,
    step: i32,
    indices: &mut [i16; MAX_CONTROL],
) -> [i16; MAX_CONTROL] {
    let mut values = [0i16; MAX_CONTROL];
    for (i, &target) in grid.iter().enumerate().take(side * side) {
        let base = if i == 0 {
            0
        } else {
            intra_prediction(&values, side, i / side, i % side)
        };
        // Indices stay far inside i16: |target - base| < 2^14 and the step is at least 24.
        let index = deadzone_round((target - f64::from(base)) / f64::from(step));
        indices[i] = index as i16;
        values[i] = dequantise_control(base, step, index);
    }
    values
}

/// The forward grid transform of control values (row-major, side `side`), in real arithmetic:
/// the inverse of decoder-core's integer [`decoder_core::model::inverse_grid_transform`] up to
/// its roundings. Level by level, rows first, then columns, on the shrinking low band.
pub fn forward_grid_transform(g: &mut [f64; MAX_CONTROL], side: usize) {
    let (sizes, levels) = grid_sizes(side);
    for &m in &sizes[..levels] {
        for j in 0..m {
            forward_line(g, j * side, 1, m);
        }
        for j in 0..m {
            forward_line(g, j, side, m);
        }
    }
}

/// One 5/3 lifting step on `m` values at `start`, `start + stride`, ...: low band first.
fn forward_line(g: &mut [f64; MAX_CONTROL], start: usize, stride: usize, m: usize) {
    let (nl, nh) = (m.div_ceil(2), m / 2);
    let mut x = [0.0f64; MAX_GRID];
    for (i, v) in x.iter_mut().enumerate().take(m) {
        *v = g[start + i * stride];
    }
    let mut d = [0.0f64; MAX_GRID];
    for (i, v) in d.iter_mut().enumerate().take(nh) {
        let right = if 2 * i + 2 < m {
            x[2 * i + 2]
        } else {
            x[2 * i]
        };
        *v = x[2 * i + 1] - 0.5 * (x[2 * i] + right);
    }
    for i in 0..nl {
        let update = if nh == 0 {
            0.0
        } else {
            0.25 * (d[i.saturating_sub(1)] + d[i.min(nh - 1)])
        };
        g[start + i * stride] = x[2 * i] + update;
    }
    for (i, v) in d.iter().enumerate().take(nh) {
        g[start + (nl + i) * stride] = *v;
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use decoder_core::model::inverse_grid_transform;

    const SIDES: [usize; 4] = [2, 3, 5, 9];

    /// The encoder's real-valued forward transform and decoder-core's integer inverse agree:
    /// rounded coefficients come back as the original values, up to the lifting's roundings.
    #[test]
    fn forward_transform_inverts_the_decoders_transform() {
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((seed >> 33) % 4096) as f64
        };
        for side in SIDES {
            for _ in 0..50 {
                let original: Vec<f64> = (0..side * side).map(|_| next()).collect();
                let mut real = [0.0; MAX_CONTROL];
                real[..side * side].copy_from_slice(&original);
                forward_grid_transform(&mut real, side);
                let mut g = [0i16; MAX_CONTROL];
                for (v, r) in g.iter_mut().zip(&real) {
                    *v = r.round() as i16;
                }
                inverse_grid_transform(&mut g, side);
                for (i, &o) in original.iter().enumerate() {
                    let d = (f64::from(g[i]) - o).abs();
                    assert!(
                        d <= 4.0,
                        "side {side}, value {i}: {o} came back as {}",
                        g[i]
                    );
                }
            }
        }
    }

    /// Every coefficient's step is scaled so that one step adds the same energy to the control
    /// values, whatever the coefficient's band: `step^2`, within the multipliers' rounding.
    #[test]
    fn band_steps_equalise_the_error_per_step() {
        let step = 1024;
        for side in SIDES {
            for i in 0..side * side {
                let mut indices = [0i16; MAX_CONTROL];
                indices[i] = 1;
                let mut values = [0i16; MAX_CONTROL];
                transform_control_values(side, step, &indices, &mut values);
                let energy: f64 = values[..side * side]
                    .iter()
                    .map(|&v| f64::from(v) * f64::from(v))
                    .sum();
                let ratio = energy / f64::from(step * step);
                assert!(
                    (0.9..=1.1).contains(&ratio),
                    "side {side}, coefficient {i}: energy ratio {ratio}"
                );
            }
        }
    }
}
