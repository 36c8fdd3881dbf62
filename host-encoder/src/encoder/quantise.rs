//! Quantisation of fitted control values into syntax elements: uniform quantisers, one step per
//! 'cquant' (thesis III.3.4). The analysis quantises every fit with every quantiser; each result is a candidate leaf
//! ([`super::candidates`]).
//!
//! Above [`super::fit`]; below [`super::candidates`].

use super::fit::{gram, Fit};
use super::ids::{leaf_syntax, ControlQuantiserId, ModelId};
use crate::entropy::BitCounter;
use decoder_core::internal::entropy::ZERO_CONTEXTS;
use decoder_core::internal::model::{MAX_CONTROL, MAX_GRID, SAMPLE_MAX, SAMPLE_MIN, SAMPLE_ONE};
use decoder_core::internal::prediction::{
    edge_context, edge_offset, edge_pixels, SamplePrediction,
};
use decoder_core::internal::syntax::control::{
    coefficient_step, expand_pixel_grid, transform_order,
};
use decoder_core::internal::syntax::{
    control_class, control_step, control_value, dequantise_control, intra_prediction,
    transform_control_values, zero_context, Contexts, ControlCoding, LeafSyntax, CONTROL_CLASSES,
    STEP_GROUPS,
};
use decoder_core::Node;
use nalgebra::DMatrix;

/// A fit's control values prepared for quantisation, once for all quantisers: in sample units,
/// and as grid-transform coefficients.
pub struct ControlTargets {
    /// Side of the coded grid ([`decoder_core::internal::model::ModelType::coded_side`]); the values
    /// below are row-major over it.
    side: usize,
    samples: [f64; MAX_CONTROL],
    coefficients: [f64; MAX_CONTROL],
    /// For an exact least-squares fit: what error feedback needs.
    exact: Option<ExactTargets>,
    /// The pixels beside each DPCM first-row (`[0]`) and first-column (`[1]`) value and beside
    /// the one before it, where known ([`edge_pixels`]).
    edges: [[Option<(i32, i32)>; MAX_GRID]; 2],
}

/// The unclamped least-squares control values of an exact fit, as samples and coefficients,
/// with the factors of their error's quadratic form.
struct ExactTargets {
    samples: [f64; MAX_CONTROL],
    coefficients: [f64; MAX_CONTROL],
    feedback: &'static ErrorFeedback,
}

impl ControlTargets {
    /// The targets of `fit`'s control values, on a block of side `2^log2`.
    pub fn of(fit: &Fit, log2: u8) -> Self {
        let model = fit.model.model();
        let (side, grid) = (model.coded_side(log2), model.grid());
        let in_samples = |control: &[f64], clamp: bool| {
            let mut samples = [0.0f64; MAX_CONTROL];
            for (i, g) in samples.iter_mut().enumerate().take(side * side) {
                *g = control[i / side * grid + i % side] * f64::from(SAMPLE_ONE);
                if clamp {
                    *g = g.clamp(f64::from(SAMPLE_MIN), f64::from(SAMPLE_MAX));
                }
            }
            let mut coefficients = samples;
            forward_grid_transform(&mut coefficients, side);
            (samples, coefficients)
        };
        let (samples, coefficients) = in_samples(&fit.control, true);
        let exact = match (fit.residual, ErrorFeedback::of(fit.model, log2)) {
            (Some(_), Some(feedback)) => {
                let (samples, coefficients) = in_samples(fit.exact(), false);
                Some(ExactTargets {
                    samples,
                    coefficients,
                    feedback,
                })
            }
            _ => None,
        };
        ControlTargets {
            side,
            samples,
            coefficients,
            exact,
            edges: [[None; MAX_GRID]; 2],
        }
    }

    /// These targets on the leaf `node` of model `model`, whose DPCM first row and column are
    /// predicted from `prediction`'s pixels.
    pub fn with_edges<P: SamplePrediction>(
        mut self,
        prediction: &P,
        node: &Node,
        model: ModelId,
    ) -> Self {
        let spacing = model.model().spacing(node.log2);
        for (row, edges) in self.edges.iter_mut().enumerate() {
            for (k, e) in edges.iter_mut().enumerate().take(self.side) {
                *e = edge_pixels(prediction, node, spacing, row == 0, k);
            }
        }
        self
    }

    /// The pixels beside DPCM value `(r, c)` and beside the value before it, where known (only
    /// on the first row and column).
    fn beside(&self, r: usize, c: usize) -> Option<(i32, i32)> {
        match (r, c) {
            (0, c) => self.edges[0][c],
            (r, 0) => self.edges[1][r],
            _ => None,
        }
    }

    /// The zero-flag context of DPCM value `(r, c)` where the pixels beside it are known
    /// ([`edge_context`]).
    fn edge_context(
        &self,
        indices: &[i16; MAX_CONTROL],
        r: usize,
        c: usize,
        step: i32,
    ) -> Option<usize> {
        self.beside(r, c)
            .map(|(a, b)| edge_context(zero_context(indices, 1, self.side, r, c), a, b, step))
    }

    /// The index offset DPCM codes value `(r, c)` against, given the value before it
    /// (`base`): nonzero only where the pixels beside it are known.
    fn edge_offset(&self, r: usize, c: usize, base: i32, step: i32) -> i32 {
        self.beside(r, c)
            .map_or(0, |(a, b)| edge_offset(base, a, b, step))
    }
}

/// A factor `V` of a quadratic form `d^T G d` over variables taken in a given order, lower
/// triangular in that order: `d^T G d = sum_k (V_k . d[..=k])^2`. Once the errors of the first
/// `k` variables are made, row `k` alone says which error of variable `k` keeps the form
/// smallest (the later rows can still be zeroed by the later variables).
struct SequentialFactor {
    /// Row `k` holds `k + 1` values, from offset `k (k + 1) / 2`.
    rows: Vec<f64>,
    /// The diagonal of the form, in the same order: each variable's weight in it when no other
    /// variable makes up for its error.
    weights: Vec<f64>,
    /// The form itself, in the same order.
    form: DMatrix<f64>,
    /// The reciprocal of each row's last entry (a multiply, where a division would stall the
    /// sequential quantisation's chain).
    inverse_last: Vec<f64>,
    /// The reciprocal of each diagonal entry of the form.
    inverse_weights: Vec<f64>,
}

impl SequentialFactor {
    /// The factor of `g` (symmetric positive definite), or `None` if it is singular.
    fn new(g: &DMatrix<f64>) -> Option<Self> {
        // Reversing the variables turns the usual Cholesky factor (`G = L L^T`, whose transpose
        // has rows over the variables from `k` on) into rows over the variables up to `k`.
        let n = g.nrows();
        let reversed = DMatrix::from_fn(n, n, |i, j| g[(n - 1 - i, n - 1 - j)]);
        let l = reversed.cholesky()?.l();
        let mut rows = Vec::with_capacity(n * (n + 1) / 2);
        for k in 0..n {
            // Row k of V is row n-1-k of L^T (column n-1-k of L), read backwards.
            let col = n - 1 - k;
            rows.extend((0..=k).map(|j| l[(n - 1 - j, col)]));
        }
        let weights: Vec<f64> = (0..n).map(|k| g[(k, k)]).collect();
        let inverse_last = (0..n).map(|k| 1.0 / rows[k * (k + 1) / 2 + k]).collect();
        let inverse_weights = weights.iter().map(|w| 1.0 / w).collect();
        Some(SequentialFactor {
            rows,
            weights,
            form: g.clone(),
            inverse_last,
            inverse_weights,
        })
    }

    /// Row `k` of the factor.
    fn row(&self, k: usize) -> &[f64] {
        &self.rows[k * (k + 1) / 2..][..=k]
    }

    /// Row `k`'s product with the errors `done` of the variables before it: the error of variable
    /// `k` that keeps the form smallest (the later variables free) is minus this over the row's
    /// last entry; once that variable's error `e` is made, the row adds
    /// `(partial + last * e)^2` to the form.
    fn partial(&self, k: usize, done: &[f64]) -> f64 {
        dot(&self.row(k)[..k], done)
    }

    /// `V^T r`: with `r = V e`, the gradient `G e` of (half) the form at `e`.
    fn transposed_product(&self, r: &[f64], out: &mut [f64; MAX_CONTROL]) {
        *out = [0.0; MAX_CONTROL];
        for (k, &rk) in r.iter().enumerate() {
            for (o, &v) in out.iter_mut().zip(self.row(k)) {
                *o += v * rk;
            }
        }
    }
}

/// `a . b` over their common length, in four independent sums: a single running sum is one
/// long chain of dependent additions, which the compiler may not reorder (nor vectorise).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut lanes = [0.0f64; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a4.zip(b4) {
        for l in 0..4 {
            lanes[l] += x[l] * y[l];
        }
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

/// Error feedback for one model and block size: the sequential factors of the squared error over
/// the control values in raster order (DPCM's order) and over the grid-transform coefficients in
/// coding order. Quantising the variables one by one, each towards the value that best makes up
/// for the errors already made, lowers the patch's error at the same rate (the patch error is a
/// quadratic form with strong couplings between neighbouring control values).
struct ErrorFeedback {
    values: SequentialFactor,
    coefficients: SequentialFactor,
}

impl ErrorFeedback {
    fn of(model: ModelId, log2: u8) -> Option<&'static ErrorFeedback> {
        use std::sync::OnceLock;
        const SIZES: usize = decoder_core::internal::format::MAX_LEAF_LOG2 as usize + 1;
        static TABLE: [[OnceLock<Option<ErrorFeedback>>; SIZES];
            decoder_core::internal::model::MODEL_COUNT] = [const { [const { OnceLock::new() }; SIZES] };
            decoder_core::internal::model::MODEL_COUNT];
        TABLE[model.index()][usize::from(log2)]
            .get_or_init(|| ErrorFeedback::build(model, log2))
            .as_ref()
    }

    fn build(model_id: ModelId, log2: u8) -> Option<ErrorFeedback> {
        let model = model_id.model();
        let (side, grid) = (model.coded_side(log2), model.grid());
        let n = side * side;
        // The form over the coded values (on a pixel grid, without the values past the block).
        let full = gram(model_id, log2)?;
        let at = |i: usize| i / side * grid + i % side;
        let g = &DMatrix::from_fn(n, n, |i, j| full[(at(i), at(j))]);
        // The real-valued inverse transform M (column j: the values of coefficient j alone), as
        // the inverse of the forward transform's matrix; the coefficients' form is M^T G M.
        let forward = DMatrix::from_fn(n, n, |i, j| {
            let mut unit = [0.0f64; MAX_CONTROL];
            unit[j] = 1.0;
            forward_grid_transform(&mut unit, side);
            unit[i]
        });
        let inverse = forward.try_inverse()?;
        let gc = inverse.transpose() * g * &inverse;
        let order = transform_order(side);
        let permuted = DMatrix::from_fn(n, n, |i, j| {
            gc[(usize::from(order[i]), usize::from(order[j]))]
        });
        Some(ErrorFeedback {
            values: SequentialFactor::new(g)?,
            coefficients: SequentialFactor::new(&permuted)?,
        })
    }
}

/// A quantised leaf: its syntax, the control values the decoder will reconstruct (sample units,
/// row-major), which both codings compute anyway, and for an exact fit the squared error that
/// quantisation adds to the fit's residual (grey levels squared), which error feedback computes
/// anyway (for the grid transform through its real-valued inverse, which the decoder's integer
/// lifting follows to within its roundings).
pub struct Quantised {
    /// The leaf's syntax elements.
    pub leaf: LeafSyntax,
    /// The error quantisation adds to an exact fit's residual.
    pub added_error: Option<f64>,
}

impl Quantised {
    /// The reconstructed control values on a block of side `2^log2`, row-major over the
    /// model's whole control grid (a pixel grid's values past the block repeating the last
    /// ones, as the decoder's). Made only when asked for: an exact fit's error needs none.
    pub fn control_values(&self, log2: u8) -> [i16; MAX_CONTROL] {
        let leaf = &self.leaf;
        let model = ModelId::new(leaf.model).model();
        let side = model.coded_side(log2);
        let step = control_step(leaf.cquant);
        let mut values = [0i16; MAX_CONTROL];
        match leaf.coding {
            ControlCoding::Dpcm => {
                for (i, &index) in leaf.control.iter().enumerate().take(side * side) {
                    values[i] = control_value(&values, side, i, step, i32::from(index));
                }
            }
            ControlCoding::Transform => {
                transform_control_values(side, step, &leaf.control, &mut values);
            }
        }
        if side == usize::from(model.intervals) {
            expand_pixel_grid(&mut values, side);
        }
        values
    }
}

/// Quantises `fit` (whose control values `targets` holds) with control quantiser `cq` and
/// control coding `coding`, its control indices rounded as `rounding` says.
pub fn quantise(
    fit: &Fit,
    targets: &ControlTargets,
    cq: ControlQuantiserId,
    coding: ControlCoding,
    rounding: Rounding,
) -> Quantised {
    let mut leaf = leaf_syntax(fit.model, cq, coding);
    let step = cq.step();
    let side = targets.side;
    let rounding = IndexRounding::new(cq, coding == ControlCoding::Transform, side, rounding);
    let form = match coding {
        ControlCoding::Dpcm => quantise_dpcm(targets, side, step, &rounding, &mut leaf.control),
        ControlCoding::Transform => {
            quantise_coefficients(targets, side, step, &rounding, &mut leaf.control)
        }
    };
    // The forms are over errors in sample units.
    let sample = f64::from(SAMPLE_ONE);
    let added_error = form.map(|f| f / (sample * sample));
    Quantised { leaf, added_error }
}

/// DPCM within the leaf, against the values the decoder will reconstruct: writes the indices.
/// With error feedback, each value aims at what best makes up for the errors of the values
/// before it, rounded by rate and its weight in the patch's error ([`IndexRounding`]); then
/// returns the form of the errors made (sample units).
fn quantise_dpcm(
    targets: &ControlTargets,
    side: usize,
    step: i32,
    rounding: &IndexRounding,
    indices: &mut [i16; MAX_CONTROL],
) -> Option<f64> {
    let n = side * side;
    let mut values = [0i16; MAX_CONTROL];
    let mut errors = [0.0f64; MAX_CONTROL];
    let exact = targets.exact.as_ref();
    let mean_weight = exact.map_or(1.0, |e| {
        e.feedback.values.weights[..n].iter().sum::<f64>() / n as f64
    });
    let mut form = 0.0;
    let inverse_step = 1.0 / f64::from(step);
    for i in 0..n {
        // With error feedback: the row's partial product and last entry.
        let feedback = exact.map(|e| {
            let f = &e.feedback.values;
            (f.partial(i, &errors[..i]), f.row(i)[i])
        });
        let (target, relative_weight) = match (exact, feedback) {
            (Some(e), Some((partial, _))) => (
                (e.samples[i] - partial * e.feedback.values.inverse_last[i])
                    .clamp(f64::from(SAMPLE_MIN), f64::from(SAMPLE_MAX)),
                e.feedback.values.weights[i] / mean_weight,
            ),
            _ => (targets.samples[i], 1.0),
        };
        let (r, c) = (i / side, i % side);
        let base = if i == 0 {
            0
        } else {
            intra_prediction(&values, side, r, c)
        };
        // The residual is coded against an offset on the first row and column.
        let offset = if i == 0 {
            0
        } else {
            targets.edge_offset(r, c, base, step)
        };
        // Indices stay far inside i16: |target - base| < 2^14 and the step is at least 12.
        let context = if i == 0 {
            None
        } else {
            targets.edge_context(indices, r, c, step)
        };
        let index = offset
            + rounding.round(
                indices,
                i,
                (target - f64::from(base)) * inverse_step - f64::from(offset),
                relative_weight,
                context,
            );
        indices[i] = index as i16;
        values[i] = dequantise_control(base, step, index);
        if let (Some(e), Some((partial, last))) = (exact, feedback) {
            errors[i] = f64::from(values[i]) - e.samples[i];
            let r = partial + last * errors[i];
            form += r * r;
        }
    }
    exact.map(|_| form)
}

/// Grid-transform coefficients, each with its band's step, in coding order (with error feedback
/// and rounding by rate and weight as in [`quantise_dpcm`]), then refined
/// ([`CoefficientQuantiser::refine`]). With error feedback, returns the form of the coefficient
/// errors made (sample units).
fn quantise_coefficients(
    targets: &ControlTargets,
    side: usize,
    step: i32,
    rounding: &IndexRounding,
    indices: &mut [i16; MAX_CONTROL],
) -> Option<f64> {
    let order = transform_order(side);
    let n = order.len();
    // Every coefficient of a grid has the same step.
    let q = f64::from(coefficient_step(side, step));
    let inverse_q = 1.0 / q;
    let Some(exact) = &targets.exact else {
        for &i in order {
            let i = usize::from(i);
            // Coefficients are below 2^18 and steps at least 1: indices fit in i16.
            indices[i] =
                rounding.round(indices, i, targets.coefficients[i] * inverse_q, 1.0, None) as i16;
        }
        return None;
    };
    let f = &exact.feedback.coefficients;
    // Each coefficient's weight in the patch's error per step, relative to the leaf's mean.
    let mut relative_weights = [0.0f64; MAX_CONTROL];
    for (k, w) in relative_weights.iter_mut().enumerate().take(n) {
        *w = f.weights[k] * q * q;
    }
    let mean = relative_weights.iter().sum::<f64>() / n as f64;
    relative_weights.iter_mut().for_each(|w| *w /= mean);
    let mut errors = [0.0f64; MAX_CONTROL];
    // The rows' products with the errors: `V e`.
    let mut rows = [0.0f64; MAX_CONTROL];
    for (k, &i) in order.iter().enumerate() {
        let i = usize::from(i);
        let (partial, last) = (f.partial(k, &errors[..k]), f.row(k)[k]);
        let target = exact.coefficients[i] - partial * f.inverse_last[k];
        let index = rounding.round(indices, i, target * inverse_q, relative_weights[k], None);
        indices[i] = index as i16;
        errors[k] = f64::from(index) * q - exact.coefficients[i];
        rows[k] = partial + last * errors[k];
    }
    let mut gradient = [0.0f64; MAX_CONTROL];
    f.transposed_product(&rows[..n], &mut gradient);
    let quantiser = CoefficientQuantiser {
        rounding,
        order,
        step: q,
        inverse_step: inverse_q,
        relative_weights: &relative_weights,
        exact: &exact.coefficients,
        form: &f.form,
        inverse_diagonal: &f.inverse_weights,
    };
    quantiser.refine(&mut errors, &mut gradient, indices);
    // e^T G e, from the gradient kept up to date.
    Some(errors[..n].iter().zip(&gradient).map(|(e, g)| e * g).sum())
}

/// Passes of [`CoefficientQuantiser::refine`] at most: refinement goes on until a pass changes
/// nothing, capped because dead-zone rounding could cycle (see docs/decisions.md).
const MAX_REFINEMENT_PASSES: usize = 8;

/// What refining the quantised coefficients of one leaf needs, in coding order.
struct CoefficientQuantiser<'a> {
    /// How indices are rounded.
    rounding: &'a IndexRounding<'a>,
    order: &'a [u8],
    /// The coefficients' step (one for the grid).
    step: f64,
    /// Its reciprocal.
    inverse_step: f64,
    relative_weights: &'a [f64; MAX_CONTROL],
    /// The exact coefficients, by grid position.
    exact: &'a [f64; MAX_CONTROL],
    /// The patch error's quadratic form over the coefficients in coding order.
    form: &'a DMatrix<f64>,
    /// The reciprocals of the form's diagonal.
    inverse_diagonal: &'a [f64],
}

impl CoefficientQuantiser<'_> {
    /// Coordinate descent on the patch error: each coefficient in turn is quantised again
    /// towards the value that is best given all the others (the sequential pass only knew the
    /// earlier ones), until a pass changes nothing; a pass stops early once it is past the
    /// last change of the pass before without a change of its own (what follows was quantised
    /// again after every change, so it stays). `errors` (coefficient errors in coding
    /// order), their `gradient` `G e` and `indices` are updated together, at the cost of one
    /// column of `G` per change.
    fn refine(
        &self,
        errors: &mut [f64; MAX_CONTROL],
        gradient: &mut [f64; MAX_CONTROL],
        indices: &mut [i16; MAX_CONTROL],
    ) {
        let n = self.order.len();
        let g = self.form.as_slice();
        // Where the last pass made its last change: the coefficients after it were quantised
        // again after every change, so unless this pass changes one before, they stay.
        let mut last_change = n;
        for _ in 0..MAX_REFINEMENT_PASSES {
            let mut changed = None;
            for (k, &i) in self.order.iter().enumerate() {
                if changed.is_none() && k > last_change {
                    return;
                }
                let i = usize::from(i);
                let column = &g[k * n..(k + 1) * n];
                let target = self.exact[i] + errors[k] - gradient[k] * self.inverse_diagonal[k];
                let index = self.rounding.round(
                    indices,
                    i,
                    target * self.inverse_step,
                    self.relative_weights[k],
                    None,
                );
                let error = f64::from(index) * self.step - self.exact[i];
                let delta = error - errors[k];
                if delta != 0.0 {
                    changed = Some(k);
                    indices[i] = index as i16;
                    errors[k] = error;
                    for (d, &c) in gradient.iter_mut().zip(column) {
                        *d += c * delta;
                    }
                }
            }
            match changed {
                Some(k) => last_change = k,
                None => break,
            }
        }
    }
}

/// The forward grid transform of control values (row-major, side `side`), in real arithmetic:
/// the 2-D DCT whose integer inverse is decoder-core's
/// [`decoder_core::internal::syntax::control::inverse_grid_transform`] up to its roundings.
pub fn forward_grid_transform(g: &mut [f64; MAX_CONTROL], side: usize) {
    for j in 0..side {
        forward_line(g, j * side, 1, side);
    }
    for j in 0..side {
        forward_line(g, j, side, side);
    }
}

/// The DCT of `m` values at `start`, `start + stride`, ...: coefficient 0 their mean, coefficient
/// `k` `sqrt(2) / m sum_n x_n cos(pi (2n + 1) k / 2m)` (the inverse of decoder-core's, whose
/// basis lines have a mean square of one).
fn forward_line(g: &mut [f64; MAX_CONTROL], start: usize, stride: usize, m: usize) {
    let Some(basis) = dct_basis().get(m) else {
        return;
    };
    let mut x = [0.0f64; MAX_GRID];
    for (i, v) in x.iter_mut().enumerate().take(m) {
        *v = g[start + i * stride];
    }
    for (k, row) in basis.iter().enumerate().take(m) {
        let sum: f64 = x.iter().zip(row).take(m).map(|(v, c)| v * c).sum();
        g[start + k * stride] = sum;
    }
}

/// For each line length `m` up to [`MAX_GRID`], the forward DCT's weights: row `k`, column `n`,
/// `1 / m` for `k = 0`, else `sqrt(2) / m cos(pi (2n + 1) k / 2m)`.
fn dct_basis() -> &'static [[[f64; MAX_GRID]; MAX_GRID]; MAX_GRID + 1] {
    static BASIS: std::sync::OnceLock<[[[f64; MAX_GRID]; MAX_GRID]; MAX_GRID + 1]> =
        std::sync::OnceLock::new();
    BASIS.get_or_init(|| {
        let mut out = [[[0.0; MAX_GRID]; MAX_GRID]; MAX_GRID + 1];
        for (m, rows) in out.iter_mut().enumerate().skip(1) {
            let n = m as f64;
            for (k, row) in rows.iter_mut().enumerate().take(m) {
                for (i, c) in row.iter_mut().enumerate().take(m) {
                    let angle = std::f64::consts::PI * (2 * i + 1) as f64 * k as f64 / (2.0 * n);
                    *c = match k {
                        0 => 1.0 / n,
                        _ => std::f64::consts::SQRT_2 * angle.cos() / n,
                    };
                }
            }
        }
        out
    })
}

/// The Lagrange multiplier of index rounding: bits are worth this much of a leaf's mean
/// patch error per squared step, close to a uniform quantiser's slope at high rate,
/// `2 ln 2 / 12` (see docs/decisions.md).
pub const ROUNDING_LAMBDA: f64 = 0.12;

/// Other multipliers each candidate the rate control keeps is also rounded with
/// ([`crate::Analysis`]): a leaf's control steps are a factor of 1.33 to 1.5 apart, and the
/// same step rounded with fewer zeros (or more) fills the gaps between them on the leaf's
/// rate/distortion curve (see docs/decisions.md).
pub const ROUNDING_VARIANTS: [f64; 4] = [0.03, 0.06, 0.25, 0.5];

/// Targets below this many steps become zero without pricing the alternatives: a nonzero
/// index there adds at least 0.2 of its weight in error, which its bits hardly ever repay, and
/// skipping the pricing saves analysis time (see docs/decisions.md).
const SURE_ZERO: f64 = 0.4;

/// How a leaf's control indices are rounded ([`quantise`]): what bits are worth, and what
/// each residual's bits are.
#[derive(Debug, Clone, Copy)]
pub struct Rounding<'a> {
    /// Bits are worth this much of the leaf's mean patch error per squared step
    /// ([`ROUNDING_LAMBDA`], [`ROUNDING_VARIANTS`]).
    pub lambda: f64,
    /// The residuals' bits.
    pub prices: &'a ResidualPrices,
}

impl Rounding<'static> {
    /// Multiplier `lambda`, the residuals priced under the contexts every stream starts from.
    pub fn from_start(lambda: f64) -> Rounding<'static> {
        Rounding {
            lambda,
            prices: ResidualPrices::at_start(),
        }
    }
}

/// How the control indices of one leaf are rounded: each index but the first is the one next
/// to its target (or zero) that costs least in patch error plus bits, priced under some state
/// of the contexts ([`Rounding`]), its own and those of the two indices whose zero-flag
/// contexts it sets (right of and below it). A nonzero index must pay for itself, more so
/// among zero neighbours; large indices round to nearest.
struct IndexRounding<'a> {
    /// Bits by class, zero-flag context and magnitude, in the leaf's step group.
    bits: &'a [PricedClass; CONTROL_CLASSES],
    /// The class of each grid position.
    classes: &'static [u8; MAX_CONTROL],
    /// The row and column of each grid position (a lookup: dividing by the side is among the
    /// slowest instructions of this hot path).
    positions: &'static [(u8, u8); MAX_CONTROL],
    side: usize,
    /// Bits are worth this much of the leaf's mean patch error per squared step.
    lambda: f64,
}

impl IndexRounding<'_> {
    /// The rounding of control quantiser `cq` under the grid transform or DPCM, for a grid of
    /// side `side`, as `rounding` says.
    fn new(
        cq: ControlQuantiserId,
        transform: bool,
        side: usize,
        rounding: Rounding,
    ) -> IndexRounding {
        let grids = GridTables::get();
        IndexRounding {
            bits: &rounding.prices.bits[cq.step_group()],
            classes: &grids.classes[usize::from(transform)][side],
            positions: &grids.positions[side],
            side,
            lambda: rounding.lambda,
        }
    }

    /// The bits of a leaf's indices but the first, as priced here.
    #[cfg(test)]
    fn bits_of(&self, indices: &[i16; MAX_CONTROL]) -> f64 {
        let side = self.side;
        (1..side * side)
            .map(|p| {
                let context = zero_context(indices, 1, side, p / side, p % side);
                self.price(p, context, i32::from(indices[p]))
            })
            .sum()
    }

    /// The bits of index `k` at grid position `p` in zero-flag context `context`.
    fn price(&self, p: usize, context: usize, k: i32) -> f64 {
        let class = &self.bits[usize::from(self.classes[p])][context.min(ZERO_CONTEXTS - 1)];
        let m = k.unsigned_abs() as usize;
        if m < PRICED_MAGNITUDES {
            f64::from(class[m])
        } else {
            // Beyond the table, two bits per doubling (Exp-Golomb).
            let last = PRICED_MAGNITUDES - 1;
            f64::from(class[last]) + 2.0 * (m as f64 / last as f64).log2()
        }
    }

    /// The index at grid position `i` for the target `v` (in steps), whose weight in the patch
    /// error, relative to the leaf's mean, is `relative_weight`, given the other indices (those
    /// not chosen yet are zero).
    #[inline]
    fn round(
        &self,
        indices: &[i16; MAX_CONTROL],
        i: usize,
        v: f64,
        relative_weight: f64,
        context: Option<usize>,
    ) -> i32 {
        if i == 0 {
            // The first index's residual is coded against a prediction from earlier leaves that
            // is not known here: it is rounded to nearest, not through a dead zone (see
            // docs/decisions.md).
            let magnitude = (v.abs() + 0.5) as i32;
            return if v < 0.0 { -magnitude } else { magnitude };
        }
        // Work on the magnitude: the truncating cast floors it (no libm call).
        let magnitude = v.abs();
        let low = magnitude as i32;
        let chosen = if low >= 2 {
            // Zero-flag contexts count magnitudes up to 2: from there on, only the index's
            // own magnitude bits tell its two candidates apart, whatever its context, and only
            // when the larger one takes a longer Exp-Golomb code (suffixes are bypass bits).
            let mut up = relative_weight * (1.0 - 2.0 * (magnitude - f64::from(low)));
            if (low + 1).count_ones() == 1 {
                up += self.lambda * (self.price(i, 0, low + 1) - self.price(i, 0, low));
            }
            if up < 0.0 {
                low + 1
            } else {
                low
            }
        } else if magnitude < SURE_ZERO {
            0
        } else {
            self.round_small(indices, i, magnitude, relative_weight, context)
        };
        if v < 0.0 {
            -chosen
        } else {
            chosen
        }
    }

    /// [`IndexRounding::round`] for a magnitude below 2 steps (and not surely zero): chooses
    /// among zero and the magnitudes either side, pricing the followers' zero flags too.
    #[inline(never)]
    fn round_small(
        &self,
        indices: &[i16; MAX_CONTROL],
        i: usize,
        magnitude: f64,
        relative_weight: f64,
        context: Option<usize>,
    ) -> i32 {
        let side = self.side;
        let (r, c) = self.positions[i];
        let (r, c) = (usize::from(r), usize::from(c));
        let low = magnitude as i32;
        // The first index's residual is taken as one step, as in the zero-flag contexts.
        let neighbour = |p: usize| {
            if p == 0 {
                1
            } else {
                usize::from(indices[p].unsigned_abs().min(2))
            }
        };
        let context = context.unwrap_or_else(|| zero_context(indices, 1, side, r, c));
        // Bits of the index and of its followers (right of and below it, whose zero-flag
        // contexts it sets; on the first row or column it counts twice there), by magnitude.
        let mut bits = [0.0f64; 3];
        for (m, b) in bits.iter_mut().enumerate().take(low as usize + 2) {
            *b = self.price(i, context, m as i32);
            if c + 1 < side {
                let p = i + 1;
                let context = if r > 0 {
                    neighbour(p - side) + m
                } else {
                    2 * m
                };
                *b += self.price(p, context, i32::from(indices[p]));
            }
            if r + 1 < side {
                let p = i + side;
                let context = if c > 0 { neighbour(p - 1) + m } else { 2 * m };
                *b += self.price(p, context, i32::from(indices[p]));
            }
        }
        let cost = |k: i32| {
            let d = magnitude - f64::from(k);
            relative_weight * d * d + self.lambda * bits[k as usize]
        };
        let mut best = (cost(0), 0);
        for k in [low, low + 1] {
            let c = cost(k);
            if c < best.0 {
                best = (c, k);
            }
        }
        best.1
    }
}

/// Magnitudes priced one by one; larger ones by their Exp-Golomb length.
const PRICED_MAGNITUDES: usize = 32;

/// The bits of the residuals of one class by zero-flag context and magnitude (sign included).
/// Single precision keeps all the tables in 13 KiB, in a core's first-level cache.
type PricedClass = [[f32; PRICED_MAGNITUDES]; ZERO_CONTEXTS];

/// The bits of control residuals under one state of the contexts, by step group, class,
/// zero-flag context and magnitude.
#[derive(Debug)]
pub struct ResidualPrices {
    bits: [[PricedClass; CONTROL_CLASSES]; STEP_GROUPS],
}

impl ResidualPrices {
    /// The prices under `contexts`.
    pub fn under(contexts: &Contexts) -> ResidualPrices {
        let mut prices = ResidualPrices {
            bits: [[[[0.0; PRICED_MAGNITUDES]; ZERO_CONTEXTS]; CONTROL_CLASSES]; STEP_GROUPS],
        };
        for (group, classes) in prices.bits.iter_mut().enumerate() {
            for (class, by_context) in classes.iter_mut().enumerate() {
                let residuals = contexts
                    .control_residuals(group, class)
                    .expect("every group and class has contexts");
                for (context, magnitudes) in by_context.iter_mut().enumerate() {
                    for (m, bits) in magnitudes.iter_mut().enumerate() {
                        let mut counter = BitCounter::frozen();
                        let mut v = m as i32;
                        residuals
                            .clone()
                            .code(&mut counter, context, &mut v)
                            .expect("priced magnitudes are codable");
                        *bits = counter.bits() as f32;
                    }
                }
            }
        }
        prices
    }

    /// The prices under the contexts every stream starts from.
    pub fn at_start() -> &'static ResidualPrices {
        use std::sync::OnceLock;
        static START: OnceLock<ResidualPrices> = OnceLock::new();
        START.get_or_init(|| ResidualPrices::under(&Contexts::default()))
    }
}

/// The class and the row and column of every grid position.
struct GridTables {
    /// By DPCM (0) or transform (1) and grid side.
    classes: [[[u8; MAX_CONTROL]; MAX_GRID + 1]; 2],
    /// By grid side: the row and column of each position.
    positions: [[(u8, u8); MAX_CONTROL]; MAX_GRID + 1],
}

impl GridTables {
    fn get() -> &'static GridTables {
        use std::sync::OnceLock;
        static GRIDS: OnceLock<Box<GridTables>> = OnceLock::new();
        GRIDS.get_or_init(GridTables::build)
    }

    fn build() -> Box<GridTables> {
        let mut costs = Box::new(GridTables {
            classes: [[[0; MAX_CONTROL]; MAX_GRID + 1]; 2],
            positions: [[(0, 0); MAX_CONTROL]; MAX_GRID + 1],
        });
        for (side, positions) in costs.positions.iter_mut().enumerate().skip(1) {
            for (i, position) in positions.iter_mut().enumerate().take(side * side) {
                *position = ((i / side) as u8, (i % side) as u8);
            }
        }
        for (transform, sides) in costs.classes.iter_mut().enumerate() {
            for (side, classes) in sides.iter_mut().enumerate().skip(1) {
                for (i, class) in classes.iter_mut().enumerate().take(side * side) {
                    *class = control_class(transform == 1, side, i / side, i % side) as u8;
                }
            }
        }
        costs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use decoder_core::internal::syntax::control::inverse_grid_transform;
    use nalgebra::DVector;

    const SIDES: [usize; 4] = [2, 3, 5, 9];

    /// The real inverse DCT of a grid of side `side` (row-major), with exact cosines.
    fn real_inverse(coefficients: &[f64], side: usize) -> Vec<f64> {
        let basis = |k: usize, n: usize| match k {
            0 => 1.0,
            _ => {
                let angle = std::f64::consts::PI * (2 * n + 1) as f64 * k as f64;
                std::f64::consts::SQRT_2 * (angle / (2 * side) as f64).cos()
            }
        };
        let mut out = vec![0.0; side * side];
        for (i, o) in out.iter_mut().enumerate() {
            let (r, c) = (i / side, i % side);
            for (j, x) in coefficients.iter().enumerate() {
                *o += x * basis(j / side, r) * basis(j % side, c);
            }
        }
        out
    }

    /// The encoder's forward transform is the inverse of the real DCT that decoder-core's
    /// integer transform computes, and decoder-core's transform is that real inverse to within
    /// its roundings: a column pass off by at most `1/2 + sum |X| / 8192` (the rounding, and
    /// each cosine within half a unit of 1/4096), the row pass by that again for its own
    /// inputs, plus the column errors times the row's cosines.
    #[test]
    fn forward_transform_inverts_the_decoders_transform() {
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 33) % 4096
        };
        for side in [2, 3, 4, 5, 8, 9] {
            for _ in 0..50 {
                let original: Vec<f64> = (0..side * side).map(|_| next() as f64).collect();
                let mut real = [0.0; MAX_CONTROL];
                real[..side * side].copy_from_slice(&original);
                forward_grid_transform(&mut real, side);
                let back = real_inverse(&real[..side * side], side);
                for (b, o) in back.iter().zip(&original) {
                    assert!((b - o).abs() < 1e-6, "side {side}: {o} came back as {b}");
                }
                // Integer coefficients as a stream makes them: a low band and sparse details.
                let mut g = [0i16; MAX_CONTROL];
                for (i, v) in g.iter_mut().enumerate().take(side * side) {
                    let x = next() as i16 - 2048;
                    *v = match i {
                        0 => x + 2048,
                        _ if next() % 3 == 0 => x / 4,
                        _ => 0,
                    };
                }
                let exact = real_inverse(
                    &g[..side * side]
                        .iter()
                        .map(|&v| f64::from(v))
                        .collect::<Vec<_>>(),
                    side,
                );
                let column_error: Vec<f64> = (0..side)
                    .map(|c| {
                        let sum: f64 = (0..side).map(|r| f64::from(g[r * side + c]).abs()).sum();
                        0.5 + sum / 8192.0
                    })
                    .collect();
                let mut integer = g;
                inverse_grid_transform(&mut integer, side);
                for (i, &e) in exact.iter().enumerate() {
                    let (r, c0) = (i / side, i % side);
                    // The columns' outputs on row r, as the row pass sees them.
                    let columns = real_inverse_columns(&g, side, r);
                    let bound = 0.5
                        + columns.iter().map(|v| v.abs() + 1.0).sum::<f64>() / 8192.0
                        + (0..side)
                            .map(|c| {
                                column_error[c]
                                    * if c == 0 {
                                        1.0
                                    } else {
                                        std::f64::consts::SQRT_2
                                    }
                            })
                            .sum::<f64>();
                    let d = (f64::from(integer[i]) - e).abs();
                    assert!(
                        d <= bound,
                        "side {side}, ({r}, {c0}): {} against {e}, bound {bound}",
                        integer[i]
                    );
                }
            }
        }
    }

    /// Row `r` of the real inverse DCT's column pass of `g` (side `side`): what the row pass
    /// transforms.
    fn real_inverse_columns(g: &[i16; MAX_CONTROL], side: usize, r: usize) -> Vec<f64> {
        (0..side)
            .map(|c| {
                (0..side)
                    .map(|k| {
                        let b = match k {
                            0 => 1.0,
                            _ => {
                                let angle = std::f64::consts::PI * (2 * r + 1) as f64 * k as f64;
                                std::f64::consts::SQRT_2 * (angle / (2 * side) as f64).cos()
                            }
                        };
                        f64::from(g[k * side + c]) * b
                    })
                    .sum()
            })
            .collect()
    }

    /// A pseudo-random symmetric positive definite matrix (`A^T A + I`).
    fn random_form(n: usize, seed: u64) -> DMatrix<f64> {
        let mut seed = seed;
        let a = DMatrix::from_fn(n, n, |_, _| {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((seed >> 33) as f64 / f64::from(1u32 << 31)) - 0.5
        });
        a.transpose() * a + DMatrix::identity(n, n)
    }

    /// The sequential factor reproduces the form, and its compensation is the error of the next
    /// variable that minimises the form when the later variables are free: the conditional
    /// minimiser `-(G_RR^-1 G_RF d_F)_0`, solved directly.
    #[test]
    fn sequential_factor_gives_the_conditional_minimiser() {
        let n = 9;
        let g = random_form(n, 3);
        let f = SequentialFactor::new(&g).expect("positive definite");
        let d: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin() * 3.0).collect();
        let form =
            (DVector::from_vec(d.clone()).transpose() * &g * DVector::from_vec(d.clone()))[(0, 0)];
        let factored: f64 = (0..n)
            .map(|k| {
                let row = &f.rows[k * (k + 1) / 2..][..=k];
                let v: f64 = row.iter().zip(&d).map(|(a, b)| a * b).sum();
                v * v
            })
            .sum();
        assert!(
            (form - factored).abs() <= 1e-9 * form,
            "{form} vs {factored}"
        );
        for k in 1..n {
            let free = g.view((k, k), (n - k, n - k)).into_owned();
            let coupling = g.view((k, 0), (n - k, k)).into_owned();
            let rhs = -(coupling * DVector::from_column_slice(&d[..k]));
            let best = free.cholesky().expect("positive definite").solve(&rhs);
            let c = -f.partial(k, &d[..k]) / f.row(k)[k];
            assert!(
                (c - best[0]).abs() <= 1e-9 * best[0].abs().max(1.0),
                "variable {k}"
            );
        }
        for k in 0..n {
            assert_eq!(f.weights[k], g[(k, k)]);
        }
    }

    /// On the bundled sample image, error feedback with weighted rounding and refinement
    /// lowers the error that quantising the 9x9 model's grid transform adds to its exact fits
    /// (summed over blocks and mid-range steps) by more than a tenth, for at most a thousandth
    /// more bits (as the rounding prices them), against rounding each coefficient on its own
    /// with equal weights (the margins measured are in docs/decisions.md).
    #[test]
    fn error_feedback_lowers_the_added_error() {
        use super::super::fit::fit_default;
        use decoder_core::Node;
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../samples/kodim23.png");
        let plane = crate::io::load_luma(std::path::Path::new(path)).expect("the bundled sample");
        let (model, log2) = (ModelId::new(3), 4u8);
        let side = model.model().grid();
        let n = side * side;
        let (mut with, mut without) = ((0.0, 0.0), (0.0, 0.0));
        for by in (0..plane.height >> log2).step_by(2) {
            for bx in (0..plane.width >> log2).step_by(2) {
                let node = Node {
                    x: bx << log2,
                    y: by << log2,
                    log2,
                };
                let fit = fit_default(&plane, &node, model);
                let targets = ControlTargets::of(&fit, log2);
                let mut plain = ControlTargets::of(&fit, log2);
                plain.exact = None;
                for step in [192, 384, 768] {
                    let added = |t: &ControlTargets, sum: &mut (f64, f64)| {
                        let mut indices = [0i16; MAX_CONTROL];
                        let cq = ControlQuantiserId::all().find(|cq| cq.step() == step);
                        let cq = cq.unwrap();
                        let rounding = IndexRounding::new(
                            cq,
                            true,
                            side,
                            Rounding::from_start(ROUNDING_LAMBDA),
                        );
                        quantise_coefficients(t, side, step, &rounding, &mut indices);
                        let mut values = [0i16; MAX_CONTROL];
                        transform_control_values(side, step, &indices, &mut values);
                        let control: Vec<f64> = values[..n]
                            .iter()
                            .map(|&v| f64::from(v) / f64::from(SAMPLE_ONE))
                            .collect();
                        let error = fit.error_of(log2, &control).expect("an exact fit");
                        sum.0 += error - fit.residual.expect("an exact fit");
                        sum.1 += rounding.bits_of(&indices);
                    };
                    added(&targets, &mut with);
                    added(&plain, &mut without);
                }
            }
        }
        // Format 20's DCT: 12% less error for 0.07% more bits (the 5/3 wavelet's: 19% less for
        // 1.5% fewer). A tenth of the error is worth far more than a thousandth of the bits.
        assert!(
            with.0 < 0.9 * without.0 && with.1 <= 1.001 * without.1,
            "added error {} with feedback, {} without; bits {} and {}",
            with.0,
            without.0,
            with.1,
            without.1
        );
    }

    /// On the bundled sample image, DPCM pixel grids of 8 px quantised and coded against the
    /// pixels beside them (the image's own, as the analysis takes them) take fewer bits than
    /// without them, for no more error (the margins measured are in docs/decisions.md).
    #[test]
    fn dpcm_edges_are_coded_against_the_pixels_beside_them() {
        use super::super::fit::fit_default;
        use super::super::plane::ImagePrediction;
        use decoder_core::internal::prediction::SamplePrediction;
        use decoder_core::internal::syntax::code_leaf;
        struct Alone;
        impl SamplePrediction for Alone {
            fn beside(&self, _above: bool, _x: u32, _y: u32) -> Option<i32> {
                None
            }
        }
        /// Adds a leaf's bits (from the contexts a stream starts with) and added error.
        fn tally<P: SamplePrediction>(
            fit: &Fit,
            node: &Node,
            prediction: &P,
            sum: &mut (f64, f64),
        ) {
            let (model, cq) = (fit.model, ControlQuantiserId::new(6));
            let targets = ControlTargets::of(fit, node.log2).with_edges(prediction, node, model);
            let q = quantise(
                fit,
                &targets,
                cq,
                ControlCoding::Dpcm,
                Rounding::from_start(ROUNDING_LAMBDA),
            );
            let mut counter = BitCounter::frozen();
            let mut leaf = q.leaf;
            code_leaf(
                &mut counter,
                &mut Contexts::default(),
                node,
                prediction,
                &mut leaf,
            )
            .expect("a valid leaf");
            sum.0 += counter.bits();
            sum.1 += q.added_error.expect("an exact fit");
        }
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../samples/kodim23.png");
        let plane = crate::io::load_luma(std::path::Path::new(path)).expect("the bundled sample");
        let image = ImagePrediction::new(&plane, 128);
        let (model, log2) = (ModelId::new(3), 3u8);
        let (mut with, mut without) = ((0.0, 0.0), (0.0, 0.0));
        for by in 1..plane.height >> log2 {
            for bx in 1..plane.width >> log2 {
                let node = Node {
                    x: bx << log2,
                    y: by << log2,
                    log2,
                };
                let fit = fit_default(&plane, &node, model);
                tally(&fit, &node, &image, &mut with);
                tally(&fit, &node, &Alone, &mut without);
            }
        }
        assert!(
            with.0 < 0.95 * without.0 && with.1 < 1.02 * without.1,
            "bits {} with the pixels beside, {} without; added error {} and {}",
            with.0,
            without.0,
            with.1,
            without.1
        );
    }

    /// A nonzero index must pay for its bits: among zero neighbours (where a nonzero index and
    /// the contexts it sets cost most) a target of 0.65 step rounds to zero, among large
    /// neighbours to one, whatever its sign; under either coding.
    #[test]
    fn rounding_prices_nonzero_indices_by_their_neighbours() {
        let side = 3;
        for transform in [false, true] {
            let rounding = IndexRounding::new(
                ControlQuantiserId::new(11),
                transform,
                side,
                Rounding::from_start(ROUNDING_LAMBDA),
            );
            let mut indices = [0i16; MAX_CONTROL];
            assert_eq!(rounding.round(&indices, 4, 0.65, 1.0, None), 0);
            assert_eq!(rounding.round(&indices, 4, -0.65, 1.0, None), 0);
            indices[3] = 5;
            indices[1] = -4;
            indices[5] = 2;
            indices[7] = 3;
            assert_eq!(rounding.round(&indices, 4, 0.65, 1.0, None), 1);
            assert_eq!(rounding.round(&indices, 4, -0.65, 1.0, None), -1);
            // A value that weighs much in the patch error is kept among zeros too.
            let quiet = [0i16; MAX_CONTROL];
            assert_eq!(rounding.round(&quiet, 4, 0.65, 20.0, None), 1);
        }
    }

    /// Magnitudes of the same Exp-Golomb length cost the same bits: between them the rounding
    /// is to nearest.
    #[test]
    fn large_indices_round_to_nearest() {
        let rounding = IndexRounding::new(
            ControlQuantiserId::new(11),
            true,
            5,
            Rounding::from_start(ROUNDING_LAMBDA),
        );
        let indices = [0i16; MAX_CONTROL];
        assert_eq!(rounding.round(&indices, 12, 5.45, 1.0, None), 5);
        assert_eq!(rounding.round(&indices, 12, 5.55, 1.0, None), 6);
        assert_eq!(rounding.round(&indices, 12, -5.55, 1.0, None), -6);
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
