//! The chroma planes of a colour stream: the YCbCr planes of an RGB image, what coding a
//! node's chroma costs (which the quadtree's cut weighs with its luma), and the choice of each
//! leaf's chroma syntax while the stream is written.
//!
//! A leaf's two chroma planes are fitted at the leaf's chroma node (half its side) with every
//! chroma model (a bilinear
//! grid of 1, 2, 4 or 8 intervals: the least-squares grid, or the pixels themselves where the
//! grid is as fine as the pixels), quantised with every control step and both control codings
//! (closed-loop DPCM, or the grid transform), reconstructed by decoder-core, and priced with
//! the chroma contexts' current probabilities. The choice minimises `w * 4 * sse + lambda *
//! bits`, `lambda` the luma plan's multiplier and `w` the weight that makes chroma error RGB
//! error (below), 4 the luma pixels a chroma pixel stands for. The analysis prices the same
//! options for every node from the image's own chroma and the contexts every stream starts
//! from ([`leaf_cost`]; for rate targets the coarse steps first and the finer ones only where
//! they pay, as for luma), so that rate control splits where colour, not only luma, pays for
//! it.
//!
//! The luma plane is not the pixels' plain luma: each pixel's is the luma that, with the chroma
//! the decoder will draw there (the 2 x 2 means, upsampled), gives the RGB nearest the pixel's,
//! so that the luma makes up for what 4:2:0 chroma cannot show.
//!
//! Above [`super::quantise`] (its forward grid transform); below the writer.

use super::candidates::{ChromaCost, RatePoint};
use super::plane::{ImagePrediction, Plane};
use super::quantise::forward_grid_transform;
use super::rate::GrowingHull;
use crate::entropy::BitCounter;
use decoder_core::internal::colour::{chroma_len, chroma_node, CHROMA_GRIDS};
use decoder_core::internal::colour::{chroma_models, rgb_to_ycbcr, sample_row, ChromaPlane};
use decoder_core::internal::format::CODING_TILE;
use decoder_core::internal::model::{MAX_CONTROL, SAMPLE_MAX, SAMPLE_MIN, SAMPLE_ONE};
use decoder_core::internal::prediction::SamplePrediction;
use decoder_core::internal::syntax::control::{
    coefficient_step, CONTROL_QUANTISERS, QUANTISERS_BY_STEP,
};
use decoder_core::internal::syntax::{
    chroma_grid, code_chroma, dequantise_control, intra_prediction, reconstruct_chroma,
    ChromaContexts, ControlCoding, LeafSyntax,
};
use decoder_core::Node;
use nalgebra::DMatrix;
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

/// What an error of one level in `Cb` and `Cr` adds to the RGB squared error, relative to one
/// in `Y` (which adds 3, one per channel): BT.601's `(0.344^2 + 1.772^2) / 3` and
/// `(1.402^2 + 0.714^2) / 3`. The encoder's distortion is the RGB squared error.
pub const CHROMA_WEIGHTS: [f64; 2] = [3.258 / 3.0, 2.476 / 3.0];

/// The chroma of an RGB image, and the image itself (for its error).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ColourPlanes {
    /// `Cb` and `Cr`, half the width and height (rounded up): the mean of each 2 x 2 block's
    /// pixels, rounded.
    pub chroma: [Plane; 2],
    /// The RGB image, row-major, 3 bytes a pixel.
    pub rgb: Vec<u8>,
}

impl ColourPlanes {
    /// The luma plane and the chroma planes of an RGB image (`3 * width * height` bytes),
    /// converted by decoder-core's integer BT.601 conversion; each pixel's luma is then the one
    /// whose RGB, with the chroma the decoder draws there, is nearest the pixel's.
    pub fn from_rgb(width: u32, height: u32, rgb: Vec<u8>) -> (Plane, ColourPlanes) {
        let (w, h) = (width as usize, height as usize);
        assert_eq!(rgb.len(), 3 * w * h, "RGB size mismatch");
        let mut y = Vec::with_capacity(w * h);
        let mut full = [vec![0u8; w * h], vec![0u8; w * h]];
        for (i, p) in rgb.chunks_exact(3).enumerate() {
            let [l, cb, cr] = rgb_to_ycbcr(p[0], p[1], p[2]);
            y.push(l);
            full[0][i] = cb;
            full[1][i] = cr;
        }
        let (cw, ch) = (chroma_len(width), chroma_len(height));
        let half = |plane: &[u8]| {
            let mut out = Vec::with_capacity((cw * ch) as usize);
            for cy in 0..ch as usize {
                for cx in 0..cw as usize {
                    let (mut sum, mut n) = (0u32, 0u32);
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (x, yy) = (2 * cx + dx, 2 * cy + dy);
                        if x < w && yy < h {
                            sum += u32::from(plane[yy * w + x]);
                            n += 1;
                        }
                    }
                    out.push(((sum + n / 2) / n) as u8);
                }
            }
            Plane::new(cw, ch, out)
        };
        let chroma = [half(&full[0]), half(&full[1])];
        let luma = luma_under(&chroma, width, &rgb, &y);
        (
            Plane::new(width, height, luma),
            ColourPlanes { chroma, rgb },
        )
    }
}

/// The luma plane the encoder codes: at each pixel, the luma whose RGB, with the chroma
/// `chroma` drawn there as the decoder upsamples it, is nearest the image's pixel (least
/// squares over R, G and B, the conversion's clamping included), ties going to the plain luma
/// `plain`. With 4:2:0 chroma the plain luma is not that: the chroma drawn at a pixel is not
/// the pixel's own, and part of the difference is luma's to make up (docs/decisions.md,
/// "Luma that makes up for the chroma drawn").
fn luma_under(chroma: &[Plane; 2], width: u32, rgb: &[u8], plain: &[u8]) -> Vec<u8> {
    let w = width as usize;
    rgb.chunks_exact(3)
        .zip(plain)
        .enumerate()
        .map(|(i, (pixel, &plain))| {
            let (x, y) = ((i % w) as u32, (i / w) as u32);
            let offsets = rgb_offsets(upsampled(&chroma[0], x, y), upsampled(&chroma[1], x, y));
            nearest_luma([pixel[0], pixel[1], pixel[2]], offsets, plain)
        })
        .collect()
}

/// What chroma `(cb, cr)` adds to each of R, G and B before the clamping of decoder-core's
/// conversion (`ycbcr_to_rgb`: `clamp(Y + offset)` per channel).
fn rgb_offsets(cb: u8, cr: u8) -> [i32; 3] {
    let (cb, cr) = (i32::from(cb) - 128, i32::from(cr) - 128);
    [
        (91881 * cr + 32768) >> 16,
        (-22554 * cb - 46802 * cr + 32768) >> 16,
        (116130 * cb + 32768) >> 16,
    ]
}

/// The 8-bit luma `l` that minimises the squared RGB error of `clamp(l + offsets[c])` against
/// `pixel`, ties to `plain`. Each channel's error falls until `l = pixel[c] - offsets[c]` and
/// then rises, so the minimum lies between the smallest and the largest of those.
fn nearest_luma(pixel: [u8; 3], offsets: [i32; 3], plain: u8) -> u8 {
    let wanted = [0, 1, 2].map(|c| i32::from(pixel[c]) - offsets[c]);
    let low = wanted.iter().copied().min().unwrap_or(0).clamp(0, 255);
    let high = wanted.iter().copied().max().unwrap_or(0).clamp(0, 255);
    let error = |l: i32| -> i32 {
        (0..3)
            .map(|c| {
                let d = (l + offsets[c]).clamp(0, 255) - i32::from(pixel[c]);
                d * d
            })
            .sum()
    };
    let plain = i32::from(plain);
    let best = (low..=high)
        .min_by_key(|&l| (error(l), (l - plain).abs()))
        .unwrap_or(plain);
    if error(plain) <= error(best) {
        plain as u8
    } else {
        best as u8
    }
}

/// The chroma the decoder draws under luma pixel `(x, y)` from a whole chroma plane: the
/// bilinear interpolation at the pixel's centre, `(x / 2 - 1/4, y / 2 - 1/4)` chroma pixels
/// (0 for the first row and column; the last chroma row and column extended), rounded.
fn upsampled(plane: &Plane, x: u32, y: u32) -> u8 {
    let (cw, ch) = (plane.width, plane.height);
    // Quarter chroma pixels: the cell and the weight of the next sample in it.
    let cell = |v: u32, n: u32| {
        let q = (2 * v).saturating_sub(1);
        let a = (q >> 2).min(n - 1);
        (a, (a + 1).min(n - 1), q & 3)
    };
    let (a, a1, f) = cell(x, cw);
    let (b, b1, e) = cell(y, ch);
    let at = |c: u32, r: u32| plane.data[(r * cw + c) as usize] as u32;
    let top = (4 - f) * at(a, b) + f * at(a1, b);
    let bottom = (4 - f) * at(a, b1) + f * at(a1, b1);
    (((4 - e) * top + e * bottom + 8) >> 4) as u8
}

/// The chosen syntax of one chroma plane of a leaf and its estimated bits.
#[derive(Debug, Clone, Copy)]
pub struct ChromaChoice {
    /// The syntax to code.
    pub syntax: LeafSyntax,
    /// Its bits under the contexts it was priced with.
    pub bits: f64,
}

/// The least-squares projection of one row (or column) of a chroma leaf of side `2^log2` onto
/// the `g + 1` values of chroma model `model`'s grid of `g` intervals (`g` below the side).
/// The bilinear grid is a tensor product, so a leaf is projected along its rows, then down its
/// columns ([`targets`]): tables of a few kilobytes instead of megabytes.
struct Projector {
    /// `(B^T B)^-1 B^T`, with `B` the pixels' linear weights of the grid values (one row per
    /// pixel).
    p: DMatrix<f64>,
    /// `B^T B`: the squared norm of the surface of grid values `t` is `<G t G, t>`.
    gram: DMatrix<f64>,
}

/// The [`Projector`] of chroma model `model` on a leaf of side `2^log2`.
fn projector(log2: u8, model: usize) -> &'static Projector {
    static CACHE: [[OnceLock<Projector>; 4]; 8] = [const { [const { OnceLock::new() }; 4] }; 8];
    CACHE[usize::from(log2)][model].get_or_init(|| {
        let size = 1usize << log2;
        let g = usize::from(CHROMA_GRIDS[model].0);
        let sp = size / g;
        let side = g + 1;
        let mut b = DMatrix::<f64>::zeros(size, side);
        for i in 0..size {
            let (a, f) = (i / sp, (i % sp) as f64 / sp as f64);
            b[(i, a)] += 1.0 - f;
            b[(i, a + 1)] += f;
        }
        let bt = b.transpose();
        let gram = &bt * &b;
        // Every grid value weighs some pixel (`sp >= 2`), so the Gram matrix is invertible.
        let inv = gram
            .clone()
            .try_inverse()
            .expect("a full-rank bilinear basis");
        Projector { p: inv * bt, gram }
    })
}

/// A lower bound on the squared error of every reconstruction of chroma model `model` at
/// `node` (`pixels` as [`leaf_pixels`] gives them, the node inside the plane), whatever its
/// control values: the least-squares surface's error, less what rounding to whole levels can
/// take away (at most half a level a pixel: by the triangle inequality, the root of the error
/// falls by at most `size / 2`). Zero for the pixel grids, which can be exact.
fn error_floor(pixels: &[f64], node: &Node, model: usize) -> f64 {
    let size = node.size() as usize;
    if usize::from(CHROMA_GRIDS[model].0) >= size {
        return 0.0;
    }
    let Projector { p, gram } = projector(node.log2, model);
    let x = DMatrix::from_row_slice(size, size, pixels);
    let t = p * &x * p.transpose();
    // The surface is the orthogonal projection of the pixels: its error is their norm less
    // its own.
    let residual = x.norm_squared() - (gram * &t * gram).dot(&t);
    let root = residual.max(0.0).sqrt() - 0.5 * size as f64;
    root.max(0.0).powi(2)
}

/// The chroma leaf's pixels (row-major, side `2^log2`), those past the plane's edge repeating
/// the nearest ones inside.
fn leaf_pixels(plane: &Plane, node: &Node) -> Vec<f64> {
    let s = node.size();
    let mut out = Vec::with_capacity((s * s) as usize);
    for j in 0..s {
        for i in 0..s {
            let x = (node.x + i).min(plane.width - 1);
            let y = (node.y + j).min(plane.height - 1);
            out.push(f64::from(plane.get(x, y)));
        }
    }
    out
}

/// The control targets of chroma model `model` at `node` (sample units, over the coded grid).
fn targets(pixels: &[f64], node: &Node, model: usize) -> Vec<f64> {
    let g = usize::from(CHROMA_GRIDS[model].0);
    let size = node.size() as usize;
    let one = f64::from(SAMPLE_ONE);
    let lo = f64::from(SAMPLE_MIN);
    let hi = f64::from(SAMPLE_MAX);
    if g >= size {
        return pixels.iter().map(|&p| p * one).collect();
    }
    let p = &projector(node.log2, model).p;
    // Rows of `t` are the grid's rows (down the leaf), as the pixels'.
    let t = p * DMatrix::from_row_slice(size, size, pixels) * p.transpose();
    let side = g + 1;
    (0..side * side)
        .map(|k| (t[(k / side, k % side)] * one).clamp(lo, hi))
        .collect()
}

/// Indices of the control targets `t` (coded grid of side `side`) for step `step`: DPCM in
/// closed loop, or (`coefficients`: the targets' grid transform) the transform's
/// coefficients, each rounded to the nearest.
fn quantise(t: &[f64], coefficients: Option<&[f64]>, side: usize, step: i32) -> [i16; MAX_CONTROL] {
    let mut k = [0i16; MAX_CONTROL];
    let limit = 4095.0;
    if let Some(g) = coefficients {
        let q = f64::from(coefficient_step(side, step));
        for (k, &c) in k.iter_mut().zip(g).take(side * side) {
            *k = round_half_away(c / q).clamp(-limit, limit) as i16;
        }
    } else {
        let mut recon = [0i16; MAX_CONTROL];
        // Each index depends on the one before (closed loop): a multiplication by the
        // reciprocal keeps the chain short where a division would stall it.
        let per_step = 1.0 / f64::from(step);
        for i in 0..side * side {
            let (r, c) = (i / side, i % side);
            let base = if i == 0 {
                0
            } else {
                intra_prediction(&recon, side, r, c)
            };
            let index =
                round_half_away((t[i] - f64::from(base)) * per_step).clamp(-limit, limit) as i32;
            k[i] = index as i16;
            recon[i] = dequantise_control(base, step, index);
        }
    }
    k
}

/// `x` rounded to the nearest integer, halves away from zero: [`f64::round`] for `|x| < 2^52`,
/// without its library call (the chroma options' quantisation rounds millions of values).
#[inline]
fn round_half_away(x: f64) -> f64 {
    if x.is_nan() || x.abs() >= 4_503_599_627_370_496.0 {
        return x.round();
    }
    // Truncation and the fraction left are exact below 2^52.
    let whole = x as i64 as f64;
    let fraction = x - whole;
    if fraction >= 0.5 {
        whole + 1.0
    } else if fraction <= -0.5 {
        whole - 1.0
    } else {
        // A zero keeps the sign of `x`, as the library's.
        whole.copysign(x)
    }
}

/// The grid transform of control targets `t` over a coded grid of side `side`.
fn transformed(t: &[f64], side: usize) -> [f64; MAX_CONTROL] {
    let mut g = [0f64; MAX_CONTROL];
    g[..t.len()].copy_from_slice(t);
    forward_grid_transform(&mut g, side);
    g
}

/// The syntax of chroma model `model` (whose targets are `t`, and their grid transform
/// `coefficients` if known) at `node` with the control quantiser of rank `rank` (0 the finest
/// step) and `coding`, and its reconstruction by decoder-core; `None` if it cannot be
/// reconstructed.
fn quantised(
    t: &[f64],
    coefficients: Option<&[f64; MAX_CONTROL]>,
    node: &Node,
    model: u8,
    rank: u8,
    coding: ControlCoding,
) -> Option<(LeafSyntax, ChromaPlane)> {
    let mut syntax = LeafSyntax {
        model,
        cquant: QUANTISERS_BY_STEP[usize::from(rank)],
        coding,
        control: [0; MAX_CONTROL],
    };
    let grid = chroma_grid(&syntax, node.log2);
    let made;
    let coefficients = match (grid.transform, coefficients) {
        (false, _) => None,
        (true, Some(c)) => Some(&c[..]),
        (true, None) => {
            made = transformed(t, grid.side);
            Some(&made[..])
        }
    };
    syntax.control = quantise(t, coefficients, grid.side, grid.step);
    let mut rec = ChromaPlane::NEUTRAL;
    reconstruct_chroma(&syntax, node.log2, &mut rec).ok()?;
    Some((syntax, rec))
}

/// Squared error of a reconstructed chroma plane over the leaf's pixels inside the plane, row
/// by row ([`sample_row`]: exact integers, so the same sum as pixel by pixel).
fn plane_sse(plane: &Plane, node: &Node, rec: &ChromaPlane) -> f64 {
    let s = node.size();
    let (w, h) = (
        s.min(plane.width - node.x) as usize,
        s.min(plane.height - node.y),
    );
    let mut row = [0u8; CODING_TILE as usize];
    let Some(row) = row.get_mut(..w) else {
        return f64::INFINITY;
    };
    let mut sse = 0u64;
    for j in 0..h {
        sample_row(rec, node.log2, j, row);
        let start = (node.y + j) as usize * plane.width as usize + node.x as usize;
        for (&r, &p) in row.iter().zip(&plane.data[start..start + w]) {
            let d = u64::from(r.abs_diff(p));
            sse += d * d;
        }
    }
    sse as f64
}

/// One way of coding a chroma leaf: its syntax, its weighted error
/// (`CHROMA_WEIGHTS[p] * 4 * sse`, in luma units) and its bits.
struct ChromaOption {
    syntax: LeafSyntax,
    weighted_sse: f64,
    bits: f64,
}

/// The part of a chroma option that depends on the image alone: its control indices (over
/// the coded grid only) and its weighted error. Its bits depend on the write (the contexts
/// and the chroma frontier), so they are priced each time.
struct Reconstructed {
    cquant: u8,
    control: Box<[i16]>,
    weighted_sse: f64,
}

/// One chroma model and control coding: its options from the coarsest step on, as far as a
/// choice has needed them (`None` where decoder-core cannot reconstruct one).
struct Series {
    model: u8,
    coding: ControlCoding,
    steps: Vec<Option<Reconstructed>>,
}

/// The options of one chroma plane at one chroma node, reconstructed when first needed and
/// kept for the next write that codes the same leaf.
struct NodeOptions {
    /// Every chroma model and coding the node allows, in the order they are visited.
    series: Vec<Series>,
    /// The control targets of each model.
    targets: Vec<Vec<f64>>,
    /// Their grid transform, for the models the transform codes.
    coefficients: Vec<Option<[f64; MAX_CONTROL]>>,
}

impl NodeOptions {
    /// No option reconstructed yet, the targets of every model fitted to `plane` at `node`.
    fn new(plane: &Plane, node: &Node) -> Self {
        Self::of_pixels(&leaf_pixels(plane, node), node)
    }

    /// No option reconstructed yet, the targets of every model fitted to `pixels` (the
    /// node's, as [`leaf_pixels`] gives them).
    fn of_pixels(pixels: &[f64], node: &Node) -> Self {
        let mut series = Vec::new();
        for (model, &(g, _)) in CHROMA_GRIDS
            .iter()
            .enumerate()
            .take(chroma_models(node.log2))
        {
            let codings: &[ControlCoding] = if g >= 2 {
                &[ControlCoding::Dpcm, ControlCoding::Transform]
            } else {
                &[ControlCoding::Dpcm]
            };
            for &coding in codings {
                series.push(Series {
                    model: model as u8,
                    coding,
                    steps: Vec::new(),
                });
            }
        }
        let targets: Vec<Vec<f64>> = (0..chroma_models(node.log2))
            .map(|model| targets(pixels, node, model))
            .collect();
        let coefficients = targets
            .iter()
            .enumerate()
            // Targets cover the coded grid: their count is its side squared.
            .map(|(model, t)| (CHROMA_GRIDS[model].0 >= 2).then(|| transformed(t, t.len().isqrt())))
            .collect();
        NodeOptions {
            series,
            targets,
            coefficients,
        }
    }

    /// Bytes this holds (roughly), for the cache's bound.
    fn bytes(&self) -> usize {
        let steps: usize = self
            .series
            .iter()
            .flat_map(|s| &s.steps)
            .map(|r| 40 + r.as_ref().map_or(0, |r| 2 * r.control.len()))
            .sum();
        let targets: usize = self.targets.iter().map(|t| 8 * t.len()).sum::<usize>()
            + self
                .coefficients
                .iter()
                .flatten()
                .map(|c| 8 * c.len())
                .sum::<usize>();
        64 + steps + targets
    }

    /// Option `k` (0 the coarsest step) of series `s`, reconstructed if not yet.
    fn step(
        &mut self,
        plane: &Plane,
        p: usize,
        node: &Node,
        s: usize,
        k: usize,
    ) -> Option<&Reconstructed> {
        while self.series[s].steps.len() <= k {
            let (model, coding) = (self.series[s].model, self.series[s].coding);
            let rank = (CONTROL_QUANTISERS - 1 - self.series[s].steps.len()) as u8;
            let t = &self.targets[usize::from(model)];
            let c = self.coefficients[usize::from(model)].as_ref();
            let option = quantised(t, c, node, model, rank, coding).map(|(syntax, rec)| {
                let side = chroma_grid(&syntax, node.log2).side;
                Reconstructed {
                    cquant: syntax.cquant,
                    control: syntax.control[..side * side].into(),
                    weighted_sse: 4.0 * CHROMA_WEIGHTS[p & 1] * plane_sse(plane, node, &rec),
                }
            });
            self.series[s].steps.push(option);
        }
        self.series[s].steps[k].as_ref()
    }
}

/// Chroma options already reconstructed, by plane and chroma node: a budget's writes code
/// mostly the same leaves again, and only their bits change from one write to the next.
/// Bounded: emptied when it would hold more than [`ChromaCache::LIMIT`] bytes.
#[derive(Default)]
pub struct ChromaCache {
    held: Mutex<Held>,
}

/// What a [`ChromaCache`] holds: options by plane and chroma node, and their bytes.
#[derive(Default)]
struct Held {
    nodes: HashMap<(usize, Node), NodeOptions>,
    bytes: usize,
}

impl ChromaCache {
    /// Bytes of options held before the cache starts afresh.
    const LIMIT: usize = 64 << 20;

    /// The options of plane `p` at `node` (new ones if not held), for [`ChromaCache::put`].
    fn take(&self, plane: &Plane, p: usize, node: &Node) -> NodeOptions {
        let held = {
            let mut held = self.held.lock().unwrap_or_else(|e| e.into_inner());
            let options = held.nodes.remove(&(p, *node));
            if let Some(o) = &options {
                held.bytes -= o.bytes();
            }
            options
        };
        // New options are made outside the lock.
        held.unwrap_or_else(|| NodeOptions::new(plane, node))
    }

    /// Keeps `options` of plane `p` at `node` for the next write.
    fn put(&self, p: usize, node: &Node, options: NodeOptions) {
        let mut held = self.held.lock().unwrap_or_else(|e| e.into_inner());
        let bytes = options.bytes();
        if held.bytes + bytes > Self::LIMIT {
            *held = Held::default();
        }
        held.bytes += bytes;
        held.nodes.insert((p, *node), options);
    }
}

impl Clone for ChromaCache {
    /// An empty cache: what it holds is only ever a shortcut.
    fn clone(&self) -> Self {
        ChromaCache::default()
    }
}

impl std::fmt::Debug for ChromaCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let held = self.held.lock().unwrap_or_else(|e| e.into_inner());
        f.debug_struct("ChromaCache")
            .field("nodes", &held.nodes.len())
            .field("bytes", &held.bytes)
            .finish()
    }
}

/// The bits of chroma syntax `syntax` at chroma node `node`, priced with the chroma contexts
/// `contexts` (not adapted) and the chroma frontier `prediction`; `None` if it cannot be coded.
fn option_bits<P: SamplePrediction>(
    syntax: LeafSyntax,
    contexts: &mut ChromaContexts,
    node: &Node,
    prediction: &P,
) -> Option<f64> {
    let mut counter = BitCounter::frozen();
    let mut coded = syntax;
    code_chroma(&mut counter, contexts, node, prediction, &mut coded).ok()?;
    Some(counter.bits())
}

/// Visits the ways of coding plane `p` (0: `Cb`, 1: `Cr`, `plane` its pixels) at chroma node
/// `node`: every chroma model and control coding, each with its control steps from coarse to
/// fine for as long as `visit` returns `true`. Each is reconstructed by decoder-core (or
/// taken from `options`, which keeps them) and priced with the chroma contexts `contexts` and
/// the chroma frontier `prediction`.
fn for_each_option<P: SamplePrediction>(
    plane: &Plane,
    p: usize,
    node: &Node,
    prediction: &P,
    contexts: &ChromaContexts,
    options: &mut NodeOptions,
    visit: &mut dyn FnMut(&ChromaOption) -> bool,
) {
    let mut ctx = contexts.clone();
    for s in 0..options.series.len() {
        let (model, coding) = (options.series[s].model, options.series[s].coding);
        for k in 0..CONTROL_QUANTISERS {
            let Some(r) = options.step(plane, p, node, s, k) else {
                continue;
            };
            let mut syntax = LeafSyntax {
                model,
                cquant: r.cquant,
                coding,
                control: [0; MAX_CONTROL],
            };
            syntax.control[..r.control.len()].copy_from_slice(&r.control);
            let Some(bits) = option_bits(syntax, &mut ctx, node, prediction) else {
                continue;
            };
            let option = ChromaOption {
                syntax,
                weighted_sse: r.weighted_sse,
                bits,
            };
            if !visit(&option) {
                break;
            }
        }
    }
}

/// The chroma syntax of plane `p` (0: `Cb`, 1: `Cr`, `plane` its pixels) at chroma node
/// `node` of least `CHROMA_WEIGHTS[p] * 4 * sse + lambda * bits` (see the module's notes), with
/// the chroma contexts `contexts` and the chroma frontier `prediction` as the decoder will have
/// them.
pub fn choose<P: SamplePrediction>(
    plane: &Plane,
    p: usize,
    node: &Node,
    prediction: &P,
    contexts: &ChromaContexts,
    lambda: f64,
    cache: &ChromaCache,
) -> ChromaChoice {
    let mut best: Option<(f64, ChromaChoice)> = None;
    let (mut previous, mut worse) = (f64::INFINITY, 0);
    let mut series = None;
    let mut options = cache.take(plane, p, node);
    for_each_option(
        plane,
        p,
        node,
        prediction,
        contexts,
        &mut options,
        &mut |o| {
            // A new model or coding starts a new series of steps.
            let key = (o.syntax.model, o.syntax.coding);
            if series != Some(key) {
                series = Some(key);
                (previous, worse) = (f64::INFINITY, 0);
            }
            let j = o.weighted_sse + lambda * o.bits;
            if best.as_ref().is_none_or(|(b, _)| j < *b) {
                let choice = ChromaChoice {
                    syntax: o.syntax,
                    bits: o.bits,
                };
                best = Some((j, choice));
            }
            // From coarse to fine steps: stop once finer steps stop paying.
            if j > previous {
                worse += 1;
            } else {
                worse = 0;
            }
            previous = j;
            worse < 2
        },
    );
    cache.put(p, node, options);
    best.map(|(_, c)| c).unwrap_or(ChromaChoice {
        syntax: LeafSyntax::default(),
        bits: 0.0,
    })
}

/// Which control steps [`leaf_cost`] searches (as the luma chains' passes,
/// [`super::EncoderConfig::fine_steps`]).
#[derive(Debug, Clone, Copy)]
pub enum ChromaSteps {
    /// Every step: an analysis that may serve any target.
    All,
    /// The coarse pass: control quantisers from rank `first` up (0 the finest step).
    Coarse {
        /// The rank of the finest control quantiser searched.
        first: u8,
    },
    /// The fine pass: the quantisers below `first`, each series going on from its step
    /// `first` while a step lowers the error by at least `floor` per bit it adds (a step
    /// that buys less is on the hull only for multipliers below the floor, a finer one
    /// still, less again).
    Fine {
        /// The rank of the finest control quantiser of the coarse pass.
        first: u8,
        /// Error per bit below which a series stops.
        floor: f64,
    },
}

impl ChromaSteps {
    /// The control quantisers a series visits, coarsest first (with [`ChromaSteps::Fine`],
    /// the coarse pass's finest first, to measure the next step against).
    fn quantisers(self) -> std::ops::RangeInclusive<u8> {
        let coarsest = (CONTROL_QUANTISERS - 1) as u8;
        match self {
            ChromaSteps::All => 0..=coarsest,
            ChromaSteps::Coarse { first } => first..=coarsest,
            ChromaSteps::Fine { first, .. } => 0..=first,
        }
    }

    /// What a series does with `point`, its option at control quantiser `cq`, after `last`.
    fn next(self, cq: u8, last: Option<(f64, f64)>, point: (f64, f64)) -> Next {
        match self {
            ChromaSteps::Fine { first, .. } if cq == first => Next::Counted,
            ChromaSteps::Fine { floor, .. } => {
                let stalls = last.is_some_and(|(bits, sse)| {
                    let added = point.0 - bits;
                    added > 0.0 && sse - point.1 < floor * added
                });
                match stalls {
                    true => Next::Last,
                    false => Next::Add,
                }
            }
            ChromaSteps::All | ChromaSteps::Coarse { .. } => Next::Add,
        }
    }
}

/// What a series of control steps does with an option ([`ChromaSteps::next`]).
enum Next {
    /// The coarse pass counted it: only the next step is measured against it.
    Counted,
    /// Onto the hull, and on to the next step.
    Add,
    /// Onto the hull, and the series ends: the step paid too little.
    Last,
}

/// What coding the chroma of the luma node `node` as a leaf costs, estimated from the image's
/// own chroma (its frontier) and the contexts every stream starts from: for each plane, its
/// options on the lower convex hull of (bits, weighted error), the error also times the node's
/// `weight` (as its luma's, [`super::masking::Masking`]), at the control steps `steps` says,
/// merged with the hull of the `earlier` pass.
pub fn leaf_cost(
    colour: &ColourPlanes,
    node: &Node,
    (stripe, weight): (u32, f64),
    steps: ChromaSteps,
    earlier: &ChromaCost,
) -> ChromaCost {
    let cnode = chroma_node(node);
    let mut planes: [Vec<RatePoint>; 2] = Default::default();
    for (p, hull) in planes.iter_mut().enumerate() {
        let plane = &colour.chroma[p];
        if cnode.x < plane.width && cnode.y < plane.height {
            let weights = (4.0 * CHROMA_WEIGHTS[p & 1], weight);
            *hull = plane_hull(plane, &cnode, (stripe, weights), steps, earlier.plane(p));
        }
    }
    ChromaCost::of(planes)
}

/// The hull of one chroma plane's options at chroma node `cnode` ([`leaf_cost`]), from the
/// `earlier` hull on; an error is the plane's squared error times the RGB weight of its
/// level (`CHROMA_WEIGHTS`, times 4 luma pixels), then times the node's masking weight.
///
/// Each series of steps (a chroma model and coding, the richest first) goes from coarse to
/// fine and stops once the hull so far covers the point of its last step's bits at the
/// model's [`error_floor`]: a finer step has more bits (nearly always) and no less error, so
/// it could not be on the hull (the luma chains' rule, `docs/decisions.md`).
fn plane_hull(
    plane: &Plane,
    cnode: &Node,
    (stripe, (rgb, masking)): (u32, (f64, f64)),
    steps: ChromaSteps,
    earlier: &[RatePoint],
) -> Vec<RatePoint> {
    let prediction = ImagePrediction::new(plane, stripe / 2);
    let pixels = leaf_pixels(plane, cnode);
    let options = NodeOptions::of_pixels(&pixels, cnode);
    // The floor counts every pixel of the node: only where all are inside the plane.
    let end = |start: u32| start.checked_add(cnode.size());
    let inside = end(cnode.x).is_some_and(|x| x <= plane.width)
        && end(cnode.y).is_some_and(|y| y <= plane.height);
    let floors: Vec<f64> = (0..options.targets.len())
        .map(|model| match inside {
            true => masking * rgb * error_floor(&pixels, cnode, model),
            false => 0.0,
        })
        .collect();
    let mut hull = GrowingHull::default();
    for o in earlier {
        hull.add((f64::from(o.bits), f64::from(o.sse)));
    }
    let mut ctx = ChromaContexts::default();
    for series in options.series.iter().rev() {
        let model = usize::from(series.model);
        let (t, c) = (
            &options.targets[model],
            options.coefficients[model].as_ref(),
        );
        let mut last = None;
        for cq in steps.quantisers().rev() {
            let Some((syntax, rec)) = quantised(t, c, cnode, series.model, cq, series.coding)
            else {
                continue;
            };
            let Some(bits) = option_bits(syntax, &mut ctx, cnode, &prediction) else {
                continue;
            };
            let point = (bits, masking * (rgb * plane_sse(plane, cnode, &rec)));
            match steps.next(cq, last, point) {
                Next::Counted => {
                    last = Some(point);
                    continue;
                }
                Next::Last => {
                    hull.add(point);
                    break;
                }
                Next::Add => hull.add(point),
            }
            if hull.covers((bits, floors[model])) {
                break;
            }
            last = Some(point);
        }
    }
    hull.vertices()
        .iter()
        .map(|&(bits, sse)| RatePoint {
            bits: bits as f32,
            sse: sse as f32,
        })
        .collect()
}

/// Whether both chroma planes of the luma node `node` are reproduced by a bilinear chroma
/// leaf (one interval, the finest step) within `mse` per luma pixel, weighted as RGB error:
/// a node is settled only if its chroma is as smooth as its luma.
pub fn smooth_within(colour: &ColourPlanes, node: &Node, mse: f64) -> bool {
    let cnode = chroma_node(node);
    colour.chroma.iter().enumerate().all(|(p, plane)| {
        if cnode.x >= plane.width || cnode.y >= plane.height {
            return true;
        }
        let t = targets(&leaf_pixels(plane, &cnode), &cnode, 0);
        let Some((_, rec)) = quantised(&t, None, &cnode, 0, 0, ControlCoding::Dpcm) else {
            return false;
        };
        let inside = |start: u32, len: u32| cnode.size().min(len - start);
        let pixels = f64::from(inside(cnode.x, plane.width) * inside(cnode.y, plane.height));
        4.0 * CHROMA_WEIGHTS[p] * plane_sse(plane, &cnode, &rec) <= mse * 4.0 * pixels
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inlined rounding is the library's, halves and neighbours of halves included.
    #[test]
    fn rounding_halves_away_from_zero_as_the_library_does() {
        let mut seed = 3u64;
        let mut values = vec![
            0.5,
            -0.5,
            1.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            4095.5,
            -0.0,
            1e300,
            f64::MAX,
        ];
        for _ in 0..100_000 {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let x = ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 20_000.0;
            values.extend([x, x.trunc() + 0.5, x.trunc() - 0.5, (x * 2.0).round() / 2.0]);
        }
        for x in values {
            assert_eq!(round_half_away(x).to_bits(), x.round().to_bits(), "{x}");
        }
    }

    #[test]
    fn chroma_planes_are_the_means_of_2x2_blocks() {
        // A 3x1 image: red, red, blue.
        let rgb = vec![255, 0, 0, 255, 0, 0, 0, 0, 255];
        let (y, c) = ColourPlanes::from_rgb(3, 1, rgb);
        assert_eq!((c.chroma[0].width, c.chroma[0].height), (2, 1));
        assert_eq!(c.chroma[0].data, vec![85, 255]);
        assert_eq!(c.chroma[1].data, vec![255, 107]);
        // The first red pixel has its own chroma drawn under it and keeps its plain luma
        // (76); the other two are drawn with a quarter of their neighbour's chroma
        // (`upsampled`), and their luma makes up for some of it.
        assert_eq!(y.data[0], 76);
        assert_ne!(y.data[1], 76);
        assert_ne!(y.data[2], 29);
    }

    /// The conversion's offsets are decoder-core's: `clamp(l + offset)` is its RGB.
    #[test]
    fn rgb_offsets_are_the_conversions() {
        use decoder_core::internal::colour::ycbcr_to_rgb;
        for cb in (0..=255u8).step_by(3) {
            for cr in (0..=255u8).step_by(5) {
                let offsets = rgb_offsets(cb, cr);
                for l in (0..=255u8).step_by(7) {
                    let rgb = ycbcr_to_rgb(l, cb, cr);
                    for c in 0..3 {
                        assert_eq!(
                            (i32::from(l) + offsets[c]).clamp(0, 255),
                            i32::from(rgb[c]),
                            "l {l}, cb {cb}, cr {cr}, channel {c}"
                        );
                    }
                }
            }
        }
    }

    /// `nearest_luma` is the best 8-bit luma for the RGB error, found by trying every one, and
    /// keeps the plain luma when that is as good.
    #[test]
    fn the_nearest_luma_is_the_best_of_all() {
        let mut seed = 0x2545_f491_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        for _ in 0..5000 {
            let pixel = [0, 1, 2].map(|_| (next() % 256) as u8);
            let (cb, cr) = ((next() % 256) as u8, (next() % 256) as u8);
            let plain = (next() % 256) as u8;
            let offsets = rgb_offsets(cb, cr);
            let error = |l: i32| -> i32 {
                (0..3)
                    .map(|c| ((l + offsets[c]).clamp(0, 255) - i32::from(pixel[c])).pow(2))
                    .sum()
            };
            let got = i32::from(nearest_luma(pixel, offsets, plain));
            let best = (0..=255).map(error).min().unwrap_or(0);
            assert_eq!(error(got), best, "{pixel:?} {cb} {cr}");
            if error(i32::from(plain)) == best {
                assert_eq!(got, i32::from(plain));
            }
        }
    }

    /// A gray image has neutral chroma: its luma is the plain luma, its own grey.
    #[test]
    fn a_gray_image_keeps_its_luma() {
        let (w, h) = (9u32, 7u32);
        let grey: Vec<u8> = (0..w * h).map(|k| (k * 37 % 256) as u8).collect();
        let rgb = grey.iter().flat_map(|&v| [v, v, v]).collect();
        let (y, c) = ColourPlanes::from_rgb(w, h, rgb);
        assert_eq!(y.data, grey);
        assert!(c.chroma.iter().all(|p| p.data.iter().all(|&v| v == 128)));
    }

    /// The chroma under a luma pixel is the plane's linear interpolation at the pixel's centre
    /// (`x / 2 - 1/4`), the first pixel at the first sample, the last sample extended.
    #[test]
    fn chroma_is_upsampled_at_the_pixel_centres() {
        // A ramp of 16 per chroma column, constant down.
        let plane = Plane::new(4, 2, vec![100, 116, 132, 148, 100, 116, 132, 148]);
        let drawn: Vec<u8> = (0..8).map(|x| upsampled(&plane, x, 3)).collect();
        // x / 2 - 1/4 chroma pixels: 0 (clamped), 1/4, 3/4, 5/4, ..., 13/4 (clamped to 3).
        assert_eq!(drawn, vec![100, 104, 112, 120, 128, 136, 144, 148]);
    }

    #[test]
    fn the_least_squares_grid_reproduces_a_bilinear_ramp() {
        let node = Node {
            x: 0,
            y: 0,
            log2: 3,
        };
        // A ramp 10 + 4 i across, constant down: model 0's grid reproduces it exactly.
        let pixels: Vec<f64> = (0..64).map(|k| 10.0 + 4.0 * (k % 8) as f64).collect();
        let t = targets(&pixels, &node, 0);
        let one = f64::from(SAMPLE_ONE);
        assert!((t[0] - 10.0 * one).abs() < 0.01, "{t:?}");
        assert!((t[1] - 42.0 * one).abs() < 0.01, "{t:?}");
    }

    /// Projecting along rows and then columns gives the least-squares grid of the whole leaf
    /// (the bilinear grid is a tensor product): checked against the full projection.
    #[test]
    fn separable_targets_are_the_least_squares_grid() {
        let plane = textured_plane();
        for log2 in 2..=5u8 {
            let node = Node { x: 0, y: 0, log2 };
            let size = node.size() as usize;
            let pixels = leaf_pixels(&plane, &node);
            for (model, &(g, _)) in CHROMA_GRIDS.iter().enumerate().take(chroma_models(log2)) {
                let g = usize::from(g);
                if g >= size {
                    continue;
                }
                let (sp, side) = (size / g, g + 1);
                let mut b = DMatrix::<f64>::zeros(size * size, side * side);
                for k in 0..size * size {
                    let (j, i) = (k / size, k % size);
                    let weight = |p: usize| {
                        let f = (p % sp) as f64 / sp as f64;
                        [(p / sp, 1.0 - f), (p / sp + 1, f)]
                    };
                    for (r, wy) in weight(j) {
                        for (c, wx) in weight(i) {
                            b[(k, r * side + c)] += wx * wy;
                        }
                    }
                }
                let x = DMatrix::from_column_slice(size * size, 1, &pixels);
                let full =
                    (b.transpose() * &b).try_inverse().expect("full rank") * b.transpose() * x;
                let t = targets(&pixels, &node, model);
                let one = f64::from(SAMPLE_ONE);
                for (k, (&got, &want)) in t.iter().zip(full.iter()).enumerate() {
                    assert!(
                        (got - want * one).abs() < 1e-6,
                        "log2 {log2}, model {model}, value {k}: {got} against {}",
                        want * one
                    );
                }
            }
        }
    }

    /// A textured plane of side 32 with a choice of multipliers: what the writer's cache
    /// must not change.
    fn textured_plane() -> Plane {
        let data = (0..32u32 * 32)
            .map(|k| {
                let (x, y) = (k % 32, k / 32);
                (128 + ((x * 7 + y * 3) % 23) as i32 - 11 + ((x * y) % 5) as i32 * 6) as u8
            })
            .collect();
        Plane::new(32, 32, data)
    }

    /// A 64 x 64 RGB image with chroma that varies smoothly and with texture.
    fn colour_image() -> ColourPlanes {
        let rgb = (0..64u32 * 64)
            .flat_map(|k| {
                let (x, y) = (k % 64, k / 64);
                let grain = ((x * 7 + y * 3) % 23) as i32 - 11;
                [
                    (60 + 2 * x as i32 + grain) as u8,
                    (90 + y as i32 + ((x * y) % 5) as i32 * 6) as u8,
                    (200 - 2 * y as i32 + grain / 2) as u8,
                ]
            })
            .collect();
        ColourPlanes::from_rgb(64, 64, rgb).1
    }

    /// The chroma costs of the luma node at the origin of side `2^log2`: every step in one
    /// pass, the coarse pass's, and a fine pass of floor `floor` after it.
    fn passes(colour: &ColourPlanes, log2: u8, floor: f64) -> [ChromaCost; 3] {
        let node = Node { x: 0, y: 0, log2 };
        let first = 7;
        let cost =
            |steps, earlier: &ChromaCost| leaf_cost(colour, &node, (128, 1.0), steps, earlier);
        let none = ChromaCost::default();
        let all = cost(ChromaSteps::All, &none);
        let coarse = cost(ChromaSteps::Coarse { first }, &none);
        let fine = cost(ChromaSteps::Fine { first, floor }, &coarse);
        [all, coarse, fine]
    }

    /// The coarse pass, then a fine pass that never finds a step paying too little, find the
    /// hull one pass over every step finds.
    #[test]
    fn coarse_then_fine_steps_find_the_hull_of_every_step() {
        let colour = colour_image();
        for log2 in 2..=6 {
            let [all, coarse, both] = passes(&colour, log2, f64::NEG_INFINITY);
            for p in 0..2 {
                assert!(!all.plane(p).is_empty(), "{log2}");
                assert_eq!(all.plane(p), both.plane(p), "plane {p}, node of {log2}");
                // The coarse hull alone lacks the finest options.
                let least =
                    |c: &ChromaCost| c.plane(p).iter().map(|o| o.sse).fold(f32::MAX, f32::min);
                assert!(least(&coarse) >= least(&all), "plane {p}, node of {log2}");
            }
        }
    }

    /// A fine pass whose floor no step reaches keeps, for the multipliers that want few bits,
    /// the choices of every step.
    #[test]
    fn a_fine_pass_stops_where_steps_stop_paying() {
        let colour = colour_image();
        for log2 in 2..=6 {
            let [all, _, fine] = passes(&colour, log2, f64::INFINITY);
            for lambda in [300.0, 3000.0, 30000.0] {
                let cheapest =
                    |c: &ChromaCost| -> Vec<RatePoint> { c.cheapest(lambda).copied().collect() };
                assert_eq!(
                    cheapest(&fine),
                    cheapest(&all),
                    "node of {log2}, lambda {lambda}"
                );
            }
        }
    }

    #[test]
    fn the_cache_changes_no_choice() {
        let plane = textured_plane();
        let prediction = ImagePrediction::new(&plane, 256);
        let cache = ChromaCache::default();
        let mut adapted = ChromaContexts::default();
        for (i, node) in [(0, 0, 4), (16, 0, 4), (0, 16, 3), (8, 24, 3), (0, 0, 5)]
            .into_iter()
            .map(|(x, y, log2)| Node { x, y, log2 })
            .enumerate()
        {
            // Fine and coarse multipliers visit different steps; contexts that have adapted
            // price the same options differently.
            for lambda in [0.5, 40.0, 3000.0] {
                for p in 0..2 {
                    let cold = choose(
                        &plane,
                        p,
                        &node,
                        &prediction,
                        &adapted,
                        lambda,
                        &ChromaCache::default(),
                    );
                    let warm = choose(&plane, p, &node, &prediction, &adapted, lambda, &cache);
                    assert_eq!(
                        cold.syntax, warm.syntax,
                        "node {i}, lambda {lambda}, plane {p}"
                    );
                    assert_eq!(cold.bits.to_bits(), warm.bits.to_bits());
                }
            }
            let mut coded = choose(&plane, 0, &node, &prediction, &adapted, 40.0, &cache).syntax;
            let mut counter = BitCounter::default();
            code_chroma(&mut counter, &mut adapted, &node, &prediction, &mut coded).expect("codes");
        }
        let held = cache.held.lock().expect("lock");
        assert_eq!(held.nodes.len(), 10, "every plane of every node is kept");
        let bytes: usize = held.nodes.values().map(NodeOptions::bytes).sum();
        assert_eq!(held.bytes, bytes);
    }
}
