//! The fractal inverse problem for one block: the least-squares control values of a model
//! (thesis II.3, with the subdivision rules fixed: free weights never paid for their bits, see
//! docs/decisions.md). Inside the image a precomputed projection of the block's pixels; at its
//! edges the normal equations from [`Tabulator`]'s exact derivatives. The analysis fits every
//! model a node supports here; the fits are then quantised ([`super::quantise`]).
//!
//! Above [`super::synthesis`]; below [`super::quantise`].

use super::ids::ModelId;
use super::plane::Plane;
use super::synthesis::Tabulator;
use decoder_core::internal::model::ModelType;
use decoder_core::Node;
use nalgebra::{DMatrix, DVector};

/// Largest number of samples used to fit one block: bigger blocks are fitted on a regular
/// sub-lattice of their pixels (the closed-loop distortion still counts every pixel).
pub const MAX_FIT_SAMPLES: u32 = 32 * 32;
/// Largest block fitted by a [`Projection`] (its build tabulates the patch at every pixel: 42 MB
/// for the 9x9 model at 256 x 256); larger blocks are fitted on a lattice.
const MAX_PROJECTION_LOG2: u8 = 8;
/// Damped Gauss-Newton steps tried per fit at the image's edges ([`least_squares`]).
pub const MAX_ITERATIONS: usize = 5;

/// Fitted real-valued parameters of one model on one block. Every node's fits are alive at
/// once between the fitting and the coarse pass, so they hold no more than they need (see
/// docs/decisions.md).
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// Model type.
    pub model: ModelId,
    /// Control values, grey levels, row-major.
    pub control: Box<[f64]>,
    /// For a projection fit whose least-squares control values clamping changed: those
    /// unclamped values ([`Fit::exact`]).
    unclamped: Option<Box<[f64]>>,
    /// For an exact least-squares fit over every pixel of an interior block (a projection,
    /// see [`gram`]): its squared error (before clamping the control values). Then the error
    /// of any other control values `c` is this plus `(c - exact)^T G (c - exact)`, with `G`
    /// the projection's Gram matrix ([`Fit::error_of`]), without rendering anything.
    pub residual: Option<f64>,
}

impl Fit {
    /// For a projection fit ([`Fit::residual`] is known): the unclamped least-squares control
    /// values, the centre of [`Fit::error_of`]'s quadratic form.
    pub fn exact(&self) -> &[f64] {
        self.unclamped.as_deref().unwrap_or(&self.control)
    }

    /// Squared error over the block's pixels of the patch with control values `control` (grey
    /// levels), by the quadratic form of an exact fit; `None` when this fit is not one (a block
    /// at the image's edge).
    pub fn error_of(&self, log2: u8, control: &[f64]) -> Option<f64> {
        let residual = self.residual?;
        let projection = Projection::of(self.model, log2);
        let n = projection.gram.nrows();
        let mut d = [0.0f64; decoder_core::internal::model::MAX_CONTROL];
        for (k, dk) in d.iter_mut().enumerate().take(n) {
            *dk = control[k] - self.exact()[k];
        }
        Some(residual + projection.quadratic_form(&d[..n]))
    }
}

/// The Gram matrix `G` of model `model`'s default-weight patch on interior blocks of side
/// `2^log2` (grey levels): the squared error of control values `c` is an exact fit's residual
/// plus `(c - exact)^T G (c - exact)` ([`Fit::error_of`]). `None` where there is no projection.
pub fn gram(model: ModelId, log2: u8) -> Option<&'static DMatrix<f64>> {
    (log2 <= MAX_PROJECTION_LOG2).then(|| &Projection::of(model, log2).gram)
}

/// The samples of a block the fit looks at: in-image pixels on a lattice of stride `stride`.
struct Lattice {
    size: u32,
    x0: u32,
    y0: u32,
    stride: u32,
    width: u32,
    height: u32,
}

impl Lattice {
    fn new(plane: &Plane, node: &Node) -> Self {
        let stride = Self::stride_of(node.size());
        Lattice {
            size: node.size(),
            x0: node.x,
            y0: node.y,
            stride,
            width: plane.width,
            height: plane.height,
        }
    }

    /// The stride of a block of side `size`: the smallest power of two that leaves at most
    /// [`MAX_FIT_SAMPLES`] samples.
    fn stride_of(size: u32) -> u32 {
        let mut stride = 1;
        while (size / stride) * (size / stride) > MAX_FIT_SAMPLES {
            stride *= 2;
        }
        stride
    }

    /// Whether every lattice sample of the block is in the image.
    fn is_interior(&self) -> bool {
        u64::from(self.x0) + u64::from(self.size) <= u64::from(self.width)
            && u64::from(self.y0) + u64::from(self.size) <= u64::from(self.height)
    }

    /// Whether the block's sample at offset `(dx, dy)` is on the lattice and in the image. The
    /// row and column just past the block (where the patch's last control values sit) belong to
    /// the neighbours and are not fitted: fitting them too lost quality (see docs/decisions.md).
    fn wants(&self, dx: u32, dy: u32) -> bool {
        dx < self.size
            && dy < self.size
            && dx.is_multiple_of(self.stride)
            && dy.is_multiple_of(self.stride)
            && self.x0 + dx < self.width
            && self.y0 + dy < self.height
    }
}

/// The least-squares control values of model `model_id` on `node`. The patch is linear in its
/// control values, so this is exact: inside the image one precomputed projection of the
/// block's samples (see [`gram`]), at the image's edges one Gauss-Newton step.
pub fn fit_default(plane: &Plane, node: &Node, model_id: ModelId) -> Fit {
    let model = model_id.model();
    let lattice = Lattice::new(plane, node);
    let (exact, residual) = if lattice.is_interior() && node.log2 <= MAX_PROJECTION_LOG2 {
        let (c, residual) = Projection::of(model_id, node.log2).apply(plane, node);
        (c, Some(residual))
    } else {
        let mut c = initial_control(plane, node, model);
        least_squares(plane, node, model_id, &lattice, &mut c);
        (c, None)
    };
    let mut control = exact.clone();
    clamp_control(&mut control);
    let unclamped = (residual.is_some() && control != exact).then(|| exact.into());
    Fit {
        model: model_id,
        control: control.into(),
        unclamped,
        residual,
    }
}

/// The least-squares projection of an interior block's pixels onto the control values of a
/// model. With `B` the matrix whose row `k` is the patch's derivative
/// with respect to the control values at pixel `offsets[k]` (the patch is linear in them, so
/// that is also its value for unit control values), `gram = B^T B` and
/// `pinv = (B^T B)^-1 B^T`. Every pixel of the block counts, whatever its size. One per model
/// and block size, built on first use.
struct Projection {
    solver: Solver,
    gram: DMatrix<f64>,
    /// `U` with `G = U^T U` (the transposed Cholesky factor), its upper triangle packed by
    /// rows; `None` when `G` is singular.
    factor: Option<Vec<f64>>,
}

/// The pixel offsets of a block of side `2^log2` and the derivatives there of model `model`'s
/// patch with respect to its control values (column `p` for the pixel at `offsets[p]`).
fn derivatives(model: ModelId, log2: u8) -> (Vec<(u32, u32)>, DMatrix<f64>) {
    let model = model.model();
    let nc = model.control_count();
    let size = 1u32 << log2;
    let mut offsets = Vec::with_capacity((size * size) as usize);
    let mut rows: Vec<f64> = Vec::with_capacity((size * size) as usize * nc);
    let mut tab = Tabulator::new(model, true);
    tab.run(
        &vec![0.0; nc],
        log2,
        &|dx, dy| dx < size && dy < size,
        &|dx, dy, _| dx < size && dy < size,
        &mut |dx, dy, s| {
            offsets.push((dx, dy));
            rows.extend_from_slice(&s[1..1 + nc]);
        },
    );
    let bt = DMatrix::from_column_slice(nc, offsets.len(), &rows);
    (offsets, bt)
}

/// How a [`Projection`] turns a block's pixels into its control values.
enum Solver {
    /// Control value `k` is row `k` of `pinv` dotted with the pixels at `offsets`.
    Matrix {
        offsets: Vec<(u32, u32)>,
        pinv: DMatrix<f64>,
    },
    /// A tensor-product patch (`B = B_1 ⊗ B_1`, checked when built): then
    /// `pinv = P ⊗ P` with `P = (B_1^T B_1)^-1 B_1^T`, applied along the block's rows and
    /// then down its columns. `axis` holds `P` row-major (`side` rows of the block's size):
    /// a few kilobytes where the matrix takes megabytes, and a fraction of its work.
    Separable { axis: Vec<f64>, side: usize },
}

impl Solver {
    /// The separable solver of the tabulated patch derivatives `bt` (column `p` for the pixel
    /// at `offsets[p]`, in a block of side `size`), if the patch is a tensor product of one
    /// curve scheme whose first row's weights sum to one.
    fn separable(bt: &DMatrix<f64>, offsets: &[(u32, u32)], size: usize) -> Option<Solver> {
        let nc = bt.nrows();
        let side = (1..=nc).find(|s| s * s == nc)?;
        let mut at = vec![usize::MAX; size * size];
        for (p, &(dx, dy)) in offsets.iter().enumerate() {
            at[dy as usize * size + dx as usize] = p;
        }
        if at.contains(&usize::MAX) {
            return None;
        }
        // The curve's basis: the first row of pixels, its control values summed by column.
        let mut b = DMatrix::<f64>::zeros(size, side);
        for d in 0..size {
            for j in 0..side {
                b[(d, j)] = (0..side).map(|i| bt[(i * side + j, at[d])]).sum();
            }
        }
        let tensor = (0..size * size).all(|p| {
            let (dx, dy) = (p % size, p / size);
            (0..nc).all(|k| {
                let (i, j) = (k / side, k % side);
                (bt[(k, at[p])] - b[(dy, i)] * b[(dx, j)]).abs() <= 1e-12
            })
        });
        if !tensor {
            return None;
        }
        let p = (b.transpose() * &b).cholesky()?.inverse() * b.transpose();
        let axis = (0..side)
            .flat_map(|j| (0..size).map(move |d| (j, d)))
            .map(|(j, d)| p[(j, d)])
            .collect();
        Some(Solver::Separable { axis, side })
    }

    /// The control values of the pixels of the interior block `node`, with the sum of the
    /// pixels' squares.
    fn apply(&self, plane: &Plane, node: &Node) -> (DVector<f64>, f64) {
        match self {
            Solver::Matrix { offsets, pinv } => {
                let y = DVector::from_iterator(
                    offsets.len(),
                    offsets
                        .iter()
                        .map(|&(dx, dy)| plane.value(node.x + dx, node.y + dy)),
                );
                (pinv * &y, y.norm_squared())
            }
            Solver::Separable { axis, side } => {
                let size = node.size() as usize;
                let mut squares = 0.0;
                let mut row = vec![0.0; size];
                // Along each row: rows[dy][j] = sum over dx of pixel(dx, dy) P[j][dx].
                let mut rows = vec![0.0; size * side];
                for (dy, out) in rows.chunks_exact_mut(*side).enumerate() {
                    let y = node.y as usize + dy;
                    plane.row_values(node.x, y as u32, &mut row);
                    for r in &row {
                        squares += r * r;
                    }
                    for (o, p) in out.iter_mut().zip(axis.chunks_exact(size)) {
                        *o = p.iter().zip(&row).map(|(a, b)| a * b).sum();
                    }
                }
                // Down each column: c[i][j] = sum over dy of P[i][dy] rows[dy][j].
                let mut control = vec![0.0; side * side];
                for (out, p) in control.chunks_exact_mut(*side).zip(axis.chunks_exact(size)) {
                    for (&a, r) in p.iter().zip(rows.chunks_exact(*side)) {
                        for (o, &v) in out.iter_mut().zip(r) {
                            *o += a * v;
                        }
                    }
                }
                (DVector::from_vec(control), squares)
            }
        }
    }
}

/// Builds, in parallel, the projections of every model usable at the block sizes
/// `log2s` (otherwise each is built by the first block that needs it, while the others wait).
pub fn prepare_projections(log2s: impl Iterator<Item = u8>) {
    use rayon::prelude::*;
    let mut pairs = Vec::new();
    for log2 in log2s.filter(|&l| l <= MAX_PROJECTION_LOG2) {
        pairs.extend(ModelId::for_block(log2).map(|m| (m, log2)));
    }
    // Largest first: they take longest.
    pairs.sort_by_key(|&(m, l)| std::cmp::Reverse((l, m)));
    pairs.par_iter().for_each(|&(m, l)| {
        Projection::of(m, l);
    });
}

/// Weight of [`extrapolation_penalty`]: small against the pixels' errors, large enough for a
/// well-conditioned factor.
const EXTRAPOLATION_WEIGHT: f64 = 1e-4;

/// On a pixel grid (control values one pixel apart, [`ModelType::subdivides`] false) the
/// values on the row and column past the block draw none of its pixels, so the least-squares
/// problem leaves them free. The format does not code them either: the decoder repeats the
/// values before them ([`decoder_core::internal::syntax::control::expand_pixel_grid`]). This quadratic form (to add
/// to the Gram matrix) ties each to the value before it in its row (the last column, the corner
/// included) or column (the last row), so the problem is regular and its solution repeats the
/// block's last pixels as the decoder does.
fn extrapolation_penalty(model: ModelType) -> DMatrix<f64> {
    let m = usize::from(model.intervals);
    let side = m + 1;
    let n = side * side;
    let mut penalty = DMatrix::<f64>::zeros(n, n);
    for r in 0..side {
        for c in 0..side {
            if r < m && c < m {
                continue;
            }
            // Along the row for the last column, else along the column.
            let step = if c == m { 1 } else { side };
            let at = r * side + c;
            let pair = [(at, 1.0), (at - step, -1.0)];
            for &(i, a) in &pair {
                for &(j, b) in &pair {
                    penalty[(i, j)] += EXTRAPOLATION_WEIGHT * a * b;
                }
            }
        }
    }
    penalty
}

impl Projection {
    fn of(model: ModelId, log2: u8) -> &'static Projection {
        use std::sync::OnceLock;
        const SIZES: usize = decoder_core::internal::format::MAX_LEAF_LOG2 as usize + 1;
        static TABLE: [[OnceLock<Projection>; SIZES]; decoder_core::internal::model::MODEL_COUNT] =
            [const { [const { OnceLock::new() }; SIZES] };
                decoder_core::internal::model::MODEL_COUNT];
        TABLE[model.index()][usize::from(log2)].get_or_init(|| Projection::build(model, log2))
    }

    fn build(model: ModelId, log2: u8) -> Projection {
        let (offsets, bt) = derivatives(model, log2);
        let model = model.model();
        let nc = model.control_count();
        let size = 1u32 << log2;
        let mut gram = &bt * bt.transpose();
        if !model.subdivides(log2) {
            gram += extrapolation_penalty(model);
        }
        let separable = model
            .subdivides(log2)
            .then(|| Solver::separable(&bt, &offsets, size as usize))
            .flatten();
        let (solver, factor) = match gram.clone().cholesky() {
            Some(chol) => {
                let l = chol.l();
                let upper = (0..nc).flat_map(|i| (i..nc).map(move |j| (i, j)));
                let factor = upper.map(|(i, j)| l[(j, i)]).collect();
                // G^-1 B^T as one matrix product (fast) rather than a triangular solve per
                // pixel.
                let solver = separable.unwrap_or_else(|| Solver::Matrix {
                    pinv: chol.inverse() * &bt,
                    offsets,
                });
                (solver, Some(factor))
            }
            // Fewer independent pixels than control values: the minimum-norm solution.
            None => {
                let pinv = bt
                    .transpose()
                    .pseudo_inverse(1e-9)
                    .unwrap_or_else(|_| DMatrix::zeros(nc, offsets.len()));
                (Solver::Matrix { offsets, pinv }, None)
            }
        };
        Projection {
            solver,
            gram,
            factor,
        }
    }

    /// `d^T G d`: the squared error that moving the control values by `d` adds.
    fn quadratic_form(&self, d: &[f64]) -> f64 {
        let Some(upper) = &self.factor else {
            return self.quadratic_form_full(d);
        };
        // |U d|^2 with U upper triangular: half the work of the full form.
        let n = d.len();
        let mut at = 0;
        (0..n)
            .map(|i| {
                let row = &upper[at..at + n - i];
                at += n - i;
                let v: f64 = row.iter().zip(&d[i..]).map(|(u, x)| u * x).sum();
                v * v
            })
            .sum()
    }

    /// `d^T G d` from `G` itself (symmetric: the sum over columns j of `d_j (G_j . d)`).
    fn quadratic_form_full(&self, d: &[f64]) -> f64 {
        self.gram
            .as_slice()
            .chunks_exact(d.len())
            .zip(d)
            .map(|(col, &dj)| dj * col.iter().zip(d).map(|(g, x)| g * x).sum::<f64>())
            .sum()
    }

    /// The least-squares control values of the interior block `node` and their squared error.
    fn apply(&self, plane: &Plane, node: &Node) -> (Vec<f64>, f64) {
        let (c, squares) = self.solver.apply(plane, node);
        // |y - Bc|^2 = |y|^2 - c^T G c at the least-squares optimum.
        let residual = (squares - c.dot(&(&self.gram * &c))).max(0.0);
        (c.data.into(), residual)
    }
}

/// Control values sampled from the block (nearest in-image pixel): the interpolating scheme's
/// natural starting point.
fn initial_control(plane: &Plane, node: &Node, model: ModelType) -> Vec<f64> {
    let side = model.grid();
    let m = u32::from(model.intervals);
    let sp = node.size() / m;
    let mut c = Vec::with_capacity(side * side);
    for u in 0..side as u32 {
        for v in 0..side as u32 {
            let x = (node.x + v * sp)
                .min(node.x + node.size() - 1)
                .min(plane.width - 1);
            let y = (node.y + u * sp)
                .min(node.y + node.size() - 1)
                .min(plane.height - 1);
            c.push(plane.value(x, y));
        }
    }
    c
}

/// Calls `f(residual, derivatives)` for every lattice sample of `node` in the image, row by
/// row: the patch of `control` at the sample is its derivatives' sum weighted by `control`
/// (the patch is linear in its control values).
fn for_each_residual(
    plane: &Plane,
    node: &Node,
    model: ModelId,
    lattice: &Lattice,
    control: &[f64],
    f: &mut dyn FnMut(f64, &[f64]),
) {
    let derivatives = LatticeDerivatives::of(model, node.log2);
    let stride = lattice.stride as usize;
    for dy in (0..node.size()).step_by(stride) {
        for dx in (0..node.size()).step_by(stride) {
            if !lattice.wants(dx, dy) {
                continue;
            }
            let row = derivatives.at(dx, dy);
            let value: f64 = row.iter().zip(control).map(|(d, c)| d * c).sum();
            f(plane.value(node.x + dx, node.y + dy) - value, row);
        }
    }
}

/// Sum of squared errors of `control` on the lattice.
fn sse(plane: &Plane, node: &Node, model: ModelId, lattice: &Lattice, control: &[f64]) -> f64 {
    let mut total = 0.0;
    for_each_residual(plane, node, model, lattice, control, &mut |e, _| {
        total += e * e
    });
    total
}

/// Normal equations `J^T J`, `J^T r` and the SSE at `control`.
fn normal_equations(
    plane: &Plane,
    node: &Node,
    model_id: ModelId,
    lattice: &Lattice,
    control: &[f64],
) -> (DMatrix<f64>, DVector<f64>, f64) {
    let n = control.len();
    let mut jtj = DMatrix::<f64>::zeros(n, n);
    let mut jtr = DVector::<f64>::zeros(n);
    let mut total = 0.0;
    // Jacobian rows are gathered as the columns of a block (contiguous: a sample's derivative
    // vector is copied whole) and folded in with one matrix product, J^T J += B B^T.
    const BLOCK: usize = 128;
    let mut block = DMatrix::<f64>::zeros(n, BLOCK);
    let mut errors = DVector::<f64>::zeros(BLOCK);
    let mut cols = 0usize;
    let flush = |block: &DMatrix<f64>,
                 errors: &DVector<f64>,
                 cols: &mut usize,
                 jtj: &mut DMatrix<f64>,
                 jtr: &mut DVector<f64>| {
        if *cols == 0 {
            return;
        }
        let used = block.columns(0, *cols);
        jtj.gemm(1.0, &used, &used.transpose(), 1.0);
        jtr.gemv(1.0, &used, &errors.rows(0, *cols), 1.0);
        *cols = 0;
    };
    for_each_residual(plane, node, model_id, lattice, control, &mut |e, row| {
        total += e * e;
        errors[cols] = e;
        block.column_mut(cols).copy_from_slice(row);
        cols += 1;
        if cols == BLOCK {
            flush(&block, &errors, &mut cols, &mut jtj, &mut jtr);
        }
    });
    flush(&block, &errors, &mut cols, &mut jtj, &mut jtr);
    (jtj, jtr, total)
}

fn clamp_control(control: &mut [f64]) {
    for c in control {
        *c = c.clamp(-200.0, 450.0);
    }
}

/// The derivatives of a model's patch with respect to its control values at every sample of
/// a whole block's fitting lattice ([`Lattice`]: its stride depends on the block's size
/// alone), row-major, a control count of values per sample: what a fit at the image's edge
/// needs at the samples inside the image, tabulated once per model and block size (the
/// 9x9 model's at 32 to 128 px, 1024 samples of 81 derivatives, are 0.66 MB each).
struct LatticeDerivatives {
    /// The lattice's stride, pixels.
    stride: u32,
    /// Samples per row of the lattice.
    per_row: usize,
    /// Values per sample.
    controls: usize,
    values: Vec<f64>,
}

impl LatticeDerivatives {
    fn of(model: ModelId, log2: u8) -> &'static LatticeDerivatives {
        use std::sync::OnceLock;
        const SIZES: usize = decoder_core::internal::format::MAX_LEAF_LOG2 as usize + 1;
        static TABLE: [[OnceLock<LatticeDerivatives>; SIZES];
            decoder_core::internal::model::MODEL_COUNT] = [const { [const { OnceLock::new() }; SIZES] };
            decoder_core::internal::model::MODEL_COUNT];
        TABLE[model.index()][usize::from(log2)].get_or_init(|| Self::build(model, log2))
    }

    fn build(model: ModelId, log2: u8) -> LatticeDerivatives {
        let model = model.model();
        let controls = model.control_count();
        let size = 1u32 << log2;
        let stride = Lattice::stride_of(size);
        let per_row = (size / stride) as usize;
        let mut values = vec![0.0; per_row * per_row * controls];
        let on_lattice = |dx: u32, dy: u32| {
            dx < size && dy < size && dx.is_multiple_of(stride) && dy.is_multiple_of(stride)
        };
        let mut tab = Tabulator::new(model, true);
        tab.run(
            &vec![0.0; controls],
            log2,
            &on_lattice,
            &|_, _, _| true,
            &mut |dx, dy, s| {
                let at = ((dy / stride) as usize * per_row + (dx / stride) as usize) * controls;
                values[at..at + controls].copy_from_slice(&s[1..1 + controls]);
            },
        );
        LatticeDerivatives {
            stride,
            per_row,
            controls,
            values,
        }
    }

    /// The derivatives at block offset `(dx, dy)`, a sample of the lattice.
    fn at(&self, dx: u32, dy: u32) -> &[f64] {
        let (x, y) = ((dx / self.stride) as usize, (dy / self.stride) as usize);
        let at = (y * self.per_row + x) * self.controls;
        &self.values[at..at + self.controls]
    }
}

/// Least-squares control values on the lattice, from `control`: the patch is linear in them,
/// so one damped Gauss-Newton step that lowers the error is the optimum (up to clamping); the
/// damping grows while a step fails.
fn least_squares(
    plane: &Plane,
    node: &Node,
    model_id: ModelId,
    lattice: &Lattice,
    control: &mut Vec<f64>,
) {
    let n = control.len();
    let (jtj, jtr, current) = normal_equations(plane, node, model_id, lattice, control);
    let mut mu = 1e-6;
    for _ in 0..MAX_ITERATIONS {
        if current <= 1e-9 {
            break;
        }
        let mut a = jtj.clone();
        for i in 0..n {
            a[(i, i)] += mu * (jtj[(i, i)] + 1e-9) + 1e-12;
        }
        let Some(chol) = a.cholesky() else {
            mu = (mu * 10.0).max(1e-3);
            continue;
        };
        let delta = chol.solve(&jtr);
        if delta.iter().any(|d| !d.is_finite()) {
            mu = (mu * 10.0).max(1e-3);
            continue;
        }
        let mut trial = control.clone();
        for (t, d) in trial.iter_mut().zip(delta.iter()) {
            *t += d;
        }
        clamp_control(&mut trial);
        let trial_sse = sse(plane, node, model_id, lattice, &trial);
        if trial_sse.is_finite() && trial_sse < current {
            *control = trial;
            break;
        }
        mu = (mu * 8.0).max(1e-4);
    }
}

#[cfg(test)]
mod tests {
    use super::{derivatives, LatticeDerivatives, ModelId, Plane, Projection, Solver};
    use crate::encoder::synthesis::Tabulator;
    use decoder_core::Node;

    /// At every lattice sample of every block size, a patch made from the cached derivatives
    /// (weighted by its control values) is the patch the tabulation makes.
    #[test]
    fn lattice_derivatives_make_the_tabulated_patch() {
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            f64::from(seed >> 8) / f64::from(1u32 << 24) * 300.0 - 50.0
        };
        for log2 in 2..=7u8 {
            let size = 1u32 << log2;
            let stride = super::Lattice::stride_of(size);
            for m in ModelId::for_block(log2) {
                let cached = LatticeDerivatives::of(m, log2);
                let model = m.model();
                let control: Vec<f64> = (0..model.control_count()).map(|_| next()).collect();
                let mut samples = 0;
                Tabulator::new(model, false).run(
                    &control,
                    log2,
                    &|dx, dy| dx < size && dy < size && dx % stride == 0 && dy % stride == 0,
                    &|_, _, _| true,
                    &mut |dx, dy, s| {
                        let row = cached.at(dx, dy);
                        let value: f64 = row.iter().zip(&control).map(|(d, c)| d * c).sum();
                        assert!((value - s[0]).abs() < 1e-9, "{m:?} {log2} ({dx}, {dy})");
                        samples += 1;
                    },
                );
                assert_eq!(samples, (size / stride).pow(2), "{m:?} {log2}");
            }
        }
    }

    /// The factored quadratic form equals the Gram matrix's, for every model and block size
    /// that has a projection.
    #[test]
    fn factored_form_equals_the_gram_form() {
        let mut seed = 99u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            f64::from(seed >> 8) / f64::from(1u32 << 24) - 0.5
        };
        let mut factored = 0;
        for log2 in 1..=6u8 {
            for m in ModelId::for_block(log2) {
                let p = Projection::of(m, log2);
                factored += usize::from(p.factor.is_some());
                let d: Vec<f64> = (0..p.gram.nrows()).map(|_| 40.0 * next()).collect();
                let (a, b) = (p.quadratic_form(&d), p.quadratic_form_full(&d));
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                    "model {m} at {log2}: {a} vs {b}"
                );
            }
        }
        assert!(factored > 10, "only {factored} projections have a factor");
    }

    /// Where the patch is a tensor product, the separable solver gives the control values the
    /// full projection matrix gives, and it is used for every model that subdivides.
    #[test]
    fn separable_projections_equal_the_matrix() {
        let size = 64u32;
        let data = (0..size * size)
            .map(|p| {
                let (x, y) = (f64::from(p % size), f64::from(p / size));
                (128.0 + 60.0 * (x * 0.37).sin() * (y * 0.21).cos() + (p * 7 % 23) as f64) as u8
            })
            .collect();
        let plane = Plane::new(size, size, data);
        let mut separable = 0;
        for log2 in 2..=6u8 {
            for m in ModelId::for_block(log2) {
                let (offsets, bt) = derivatives(m, log2);
                let found = Solver::separable(&bt, &offsets, 1 << log2);
                assert_eq!(
                    found.is_some(),
                    m.model().subdivides(log2),
                    "model {m} at {log2}"
                );
                let Some(found) = found else { continue };
                separable += 1;
                let pinv = (&bt * bt.transpose()).cholesky().unwrap().inverse() * &bt;
                let matrix = Solver::Matrix { offsets, pinv };
                let node = Node { x: 0, y: 0, log2 };
                let (a, sa) = found.apply(&plane, &node);
                let (b, sb) = matrix.apply(&plane, &node);
                assert_eq!(sa, sb);
                for (a, b) in a.iter().zip(&b) {
                    assert!((a - b).abs() <= 1e-9, "model {m} at {log2}: {a} vs {b}");
                }
            }
        }
        assert!(separable > 10, "only {separable} separable projections");
    }
}
