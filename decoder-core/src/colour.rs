//! Colour: the YCbCr planes of a three-channel stream, and their conversion to RGB as pixels
//! are drawn.
//!
//! A colour stream codes luma (`Y`) exactly as a grayscale stream codes its one plane, and two
//! chroma planes (`Cb`, `Cr`) at half the width and height (4:2:0). The quadtree cut is shared:
//! every luma leaf of side `S` at `(x, y)` is followed in the stream by the two chroma leaves of
//! side `max(S / 2, 1)` at `(x / 2, y / 2)` of their planes, unless a split node above it coded
//! the chroma of its whole subtree (a flag after its split flag, then its own chroma leaves,
//! which cover every leaf of the subtree: chroma may be coarser than the cut, never finer). A
//! chroma leaf is a grid of control
//! values (coded like a luma leaf's: DPCM or the grid transform, predicted from the chroma
//! pixels beside it) that is interpolated **bilinearly**, so that any of its pixels can be made
//! on its own, in the order luma is drawn, with no buffer: the decoder keeps no more than the
//! leaf's two grids and a chroma frontier (the last chroma row of each column pair of a stripe
//! and the last chroma column of each row pair of a band).
//!
//! Chroma is **upsampled** as it is drawn, not repeated over 2 x 2 luma pixels: output pixel
//! `(x, y)` of a leaf takes the leaf's bilinear chroma surface at the pixel's own centre,
//! `(x / 2 - 1/4, y / 2 - 1/4)` in chroma pixels (JFIF's centred siting); across the leaf's
//! top and left edges, a quarter pixel before the surface, the chroma beside the leaf (which
//! the chroma frontier holds) is mixed in, on both sides of the edge. The pixel is converted to
//! RGB with the integer BT.601 full-range conversion of [`ycbcr_to_rgb`].

use crate::format::{byte, CODING_TILE, DEFAULT_STRIPE};
use crate::geometry::{Node, Rect};
use crate::model::{MAX_CONTROL, SAMPLE_BITS, SAMPLE_ONE};
use crate::prediction::{beside_rule, SamplePrediction, StripeWidth};
use crate::synthesis::{Scale, Stop, TileMut, TileOut, TILE};

/// RGB of a YCbCr pixel (BT.601 full range, as JFIF), in 16-bit fixed point with rounding:
/// `R = Y + (91881 Cr' + 32768) >> 16`, `G = Y + (-22554 Cb' - 46802 Cr' + 32768) >> 16`,
/// `B = Y + (116130 Cb' + 32768) >> 16`, with `Cb' = Cb - 128`, `Cr' = Cr - 128`, `>>` flooring,
/// each clamped to `0..=255`.
#[inline]
pub fn ycbcr_to_rgb(y: u8, cb: u8, cr: u8) -> [u8; 3] {
    let y = i32::from(y);
    let cb = i32::from(cb) - 128;
    let cr = i32::from(cr) - 128;
    let r = y + ((91881 * cr + 32768) >> 16);
    let g = y + ((-22554 * cb - 46802 * cr + 32768) >> 16);
    let b = y + ((116130 * cb + 32768) >> 16);
    [byte(r), byte(g), byte(b)]
}

/// YCbCr of an RGB pixel (BT.601 full range, as JFIF), the conversion the reference encoder
/// uses: `Y = (19595 R + 38470 G + 7471 B + 32768) >> 16`,
/// `Cb = 128 + (-11059 R - 21709 G + 32768 B + 32768) >> 16`,
/// `Cr = 128 + (32768 R - 27439 G - 5329 B + 32768) >> 16`, each clamped to `0..=255`.
#[inline]
pub fn rgb_to_ycbcr(r: u8, g: u8, b: u8) -> [u8; 3] {
    let (r, g, b) = (i32::from(r), i32::from(g), i32::from(b));
    let y = (19595 * r + 38470 * g + 7471 * b + 32768) >> 16;
    let cb = 128 + ((-11059 * r - 21709 * g + 32768 * b + 32768) >> 16);
    let cr = 128 + ((32768 * r - 27439 * g - 5329 * b + 32768) >> 16);
    [
        y.clamp(0, 255) as u8,
        cb.clamp(0, 255) as u8,
        cr.clamp(0, 255) as u8,
    ]
}

/// The luma of an RGB pixel ([`rgb_to_ycbcr`]'s `Y`): a colour stream drawn on a gray display.
#[inline]
pub fn rgb_to_luma(r: u8, g: u8, b: u8) -> u8 {
    rgb_to_ycbcr(r, g, b)[0]
}

/// The chroma models: grid intervals `g` (the control grid has `g + 1` values a side) and the
/// index in [`crate::model::MODELS`] of the luma model with that grid, whose control coding
/// (grid side, transform tables) a chroma leaf shares.
pub const CHROMA_GRIDS: [(u8, u8); 4] = [(1, 0), (2, 1), (4, 2), (8, 3)];

/// How many chroma models a chroma leaf of side `2^log2` may use: those with `g <= 2^log2`
/// (the first ones of [`CHROMA_GRIDS`]).
#[inline]
pub fn chroma_models(log2: u8) -> usize {
    (usize::from(log2) + 1).min(CHROMA_GRIDS.len())
}

/// The chroma node of luma leaf `node`: half its position, half its side (at least one pixel).
#[inline]
pub fn chroma_node(node: &Node) -> Node {
    Node {
        x: node.x / 2,
        y: node.y / 2,
        log2: node.log2.saturating_sub(1),
    }
}

/// Side of the chroma planes of an image `n` pixels wide or high.
#[inline]
pub fn chroma_len(n: u32) -> u32 {
    n.div_ceil(2)
}

/// One chroma plane of a leaf: the grid intervals `g` and the `(g + 1)^2` control values
/// (row-major, sample units; a pixel grid's row and column past the block repeat the last
/// ones).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
// The control values first, word-aligned, as in a luma `Patch`: cleared by the word-aligned
// routine.
#[repr(C, align(4))]
pub struct ChromaPlane {
    /// Control values, row-major, `grid + 1` per row.
    pub control: [i16; MAX_CONTROL],
    /// Grid intervals (1, 2, 4 or 8).
    pub grid: u8,
}

impl ChromaPlane {
    /// A flat mid-grey plane (no colour).
    pub const NEUTRAL: ChromaPlane = ChromaPlane {
        grid: 1,
        control: [128 * SAMPLE_ONE as i16; MAX_CONTROL],
    };

    /// A plane of zeros, for storage a leaf's chroma is coded into before it is read: made by
    /// clearing, where a copy of [`ChromaPlane::NEUTRAL`] pulls a general `memcpy` into the
    /// decoder.
    #[inline(always)]
    pub const fn cleared() -> ChromaPlane {
        ChromaPlane {
            control: [0; MAX_CONTROL],
            grid: 1,
        }
    }
}

/// The two chroma planes of one leaf, at the leaf's chroma node ([`chroma_node`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChromaPatch {
    /// The chroma node (chroma-plane coordinates).
    pub node: Node,
    /// `Cb` then `Cr`.
    pub planes: [ChromaPlane; 2],
}

impl Default for ChromaPatch {
    fn default() -> Self {
        ChromaPatch::EMPTY
    }
}

impl ChromaPatch {
    /// Neutral chroma at the origin.
    pub const EMPTY: ChromaPatch = ChromaPatch {
        node: Node {
            x: 0,
            y: 0,
            log2: 0,
        },
        planes: [ChromaPlane::NEUTRAL; 2],
    };

    /// The 8-bit value of plane `p` at offset `(i, j)` (column, row) inside the leaf: the
    /// bilinear interpolation of the control grid at `(i g / C, j g / C)` (`C` the chroma
    /// leaf's side), rounded like a luma sample (`clamp((v + 8) >> 4, 0, 255)`).
    #[inline]
    pub fn value(&self, p: usize, i: u32, j: u32) -> u8 {
        let plane = &self.planes[p & 1];
        sample(plane, self.node.log2, i, j)
    }

    /// The 8-bit value of plane `p` under the luma pixel at offset `(i, j)` (column, row) from
    /// the leaf's luma corner: the bilinear interpolation of the control grid at the pixel's
    /// centre, `((2i - 1) / 4, (2j - 1) / 4)` chroma pixels (0 for the first row and column),
    /// rounded as [`ChromaPatch::value`].
    #[inline]
    pub fn value_under(&self, p: usize, i: u32, j: u32) -> u8 {
        sample_at(&self.planes[p & 1], self.node.log2, 2, centre(i), centre(j))
    }
}

/// The centre of the luma pixel at offset `v` from a leaf's luma corner, in quarter chroma
/// pixels from the leaf's chroma corner: `2 v - 1`, or 0 for the first (a quarter pixel
/// before the leaf, where its surface starts).
#[inline]
fn centre(v: u32) -> u32 {
    (2 * v).saturating_sub(1)
}

/// [`ChromaPatch::value`] of one plane of a leaf of side `2^log2`.
#[inline]
pub fn sample(plane: &ChromaPlane, log2: u8, i: u32, j: u32) -> u8 {
    sample_at(plane, log2, 0, i, j)
}

/// The bilinear interpolation of `plane`'s grid (a leaf of side `2^log2`) at `(i, j)` in units
/// of `2^-sub` chroma pixels.
#[inline]
fn sample_at(plane: &ChromaPlane, log2: u8, sub: u32, i: u32, j: u32) -> u8 {
    let g = u32::from(plane.grid.max(1));
    let side = g as usize + 1;
    let sh = u32::from(log2).saturating_sub(g.trailing_zeros()) + sub;
    let mask = (1u32 << sh) - 1;
    let (a, f) = ((i >> sh).min(g - 1) as usize, (i & mask) as i32);
    let (b, e) = ((j >> sh).min(g - 1) as usize, (j & mask) as i32);
    let at = |r: usize, c: usize| i32::from(plane.control.get(r * side + c).copied().unwrap_or(0));
    let one = 1i32 << sh;
    let top = (one - f) * at(b, a) + f * at(b, a + 1);
    let bottom = (one - f) * at(b + 1, a) + f * at(b + 1, a + 1);
    let v = (one - e) * top + e * bottom;
    let shift = 2 * sh + SAMPLE_BITS;
    byte((v + (1 << (shift - 1))) >> shift)
}

/// [`sample`] along row `j` of a leaf of side `2^log2`, at its columns `0..out.len()`: the same
/// values, stepped along each grid cell (an encoder measures a leaf's error with it).
pub fn sample_row(plane: &ChromaPlane, log2: u8, j: u32, out: &mut [u8]) {
    let mut row = SurfaceLine::row(plane, log2, 0, j);
    let shift = 2 * row.sh + SAMPLE_BITS;
    let half = 1i32 << (shift - 1);
    if row.sh == 0 {
        // A pixel grid: each pixel is its control value.
        for (p, &v) in out.iter_mut().zip(plane.control.iter().skip(row.first)) {
            *p = byte((i32::from(v) + half) >> shift);
        }
        return;
    }
    let (mut rest, mut i) = (out, 0u32);
    while !rest.is_empty() {
        // The columns left in the grid cell of column `i`.
        let cell_end = ((i >> row.sh) + 1) << row.sh;
        let run = ((cell_end - i) as usize).min(rest.len());
        let (now, tail) = rest.split_at_mut(run);
        // Wrapping: the same integers as `line` at each column.
        let mut v = row.line(i);
        for p in now {
            *p = byte(v.wrapping_add(half) >> shift);
            v = v.wrapping_add(row.slope);
        }
        (rest, i) = (tail, i + run as u32);
    }
}

/// The chroma decoder's prediction memory, like the luma frontier's without deferred edges:
/// for each chroma column of a stripe the last chroma pixel decoded in it, for each chroma row
/// of a band the last one in that row, both planes interleaved (`Cb`, `Cr`). Holds stripes of
/// up to `STRIPE` luma pixels (`STRIPE` bytes).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChromaFrontier<const STRIPE: usize = DEFAULT_STRIPE> {
    columns: [u8; STRIPE],
    rows: [u8; CODING_TILE as usize],
    /// Chroma plane width.
    width: u32,
    /// Chroma plane height.
    height: u32,
    /// The luma stripe width (a chroma stripe is half as wide).
    stripe: StripeWidth,
}

impl<const STRIPE: usize> Default for ChromaFrontier<STRIPE> {
    fn default() -> Self {
        ChromaFrontier::EMPTY
    }
}

/// Chroma rows of a band.
const CHROMA_BAND: u32 = CODING_TILE / 2;

impl<const STRIPE: usize> ChromaFrontier<STRIPE> {
    /// Nothing decoded.
    pub const EMPTY: ChromaFrontier<STRIPE> = ChromaFrontier {
        columns: [0; STRIPE],
        rows: [0; CODING_TILE as usize],
        width: 0,
        height: 0,
        stripe: StripeWidth::NONE,
    };

    /// Starts a stream of a `width x height` (luma) image in stripes of `stripe` luma pixels;
    /// `false` when the stripe is wider than this frontier holds.
    pub fn start(&mut self, width: u32, height: u32, stripe: u32) -> bool {
        let Some(stripe_width) = StripeWidth::new(stripe) else {
            return false;
        };
        if stripe as usize > STRIPE {
            return false;
        }
        self.width = chroma_len(width);
        self.height = chroma_len(height);
        self.stripe = stripe_width;
        true
    }

    /// The column of chroma pixel column `cx` in its stripe: half the luma column of `2 cx`
    /// (no division: [`StripeWidth`]).
    #[inline]
    fn column(&self, cx: u32) -> u32 {
        self.stripe.column(2 * cx) / 2
    }

    /// Plane `p` (0: `Cb`, 1: `Cr`) as a [`SamplePrediction`] in chroma coordinates.
    pub fn plane(&self, p: usize) -> ChromaPrediction<'_, STRIPE> {
        ChromaPrediction {
            frontier: self,
            plane: p & 1,
        }
    }

    /// The 8-bit value of plane `p` beside chroma pixel `(cx, cy)` (above it when `above`),
    /// whether or not it is known; 128 when out of range.
    #[inline]
    pub fn stored(&self, p: usize, above: bool, cx: u32, cy: u32) -> u8 {
        let slot = if above {
            self.columns.get(2 * self.column(cx) as usize + (p & 1))
        } else {
            self.rows.get(2 * (cy % CHROMA_BAND) as usize + (p & 1))
        };
        slot.copied().unwrap_or(128)
    }

    /// Learns the last row and column of the chroma node `region` (those of its pixels in the
    /// plane), which `patch` covers: a leaf's own chroma, or a subtree's chroma over one of
    /// its leaves; each line stepped along the leaf's surface. Out of line, so that its state
    /// is not on the stack while the walk draws a leaf.
    #[inline(never)]
    pub fn record(&mut self, patch: &ChromaPatch, region: &Node) {
        // The patch's node contains the region: offsets from it are never negative.
        let n = &patch.node;
        let s = region.size();
        let (w, h) = (self.width, self.height);
        let planes = &patch.planes;
        let last_row = region.y + s - 1;
        if last_row < h {
            let j = last_row - n.y;
            let mut lines = [0, 1].map(|p| SurfaceLine::row(&planes[p], n.log2, 0, j));
            for cx in region.x..(region.x + s).min(w) {
                let column = 2 * self.column(cx) as usize;
                for (p, line) in lines.iter_mut().enumerate() {
                    if let Some(slot) = self.columns.get_mut(column + p) {
                        *slot = line.at(cx - n.x);
                    }
                }
            }
        }
        let last_column = region.x + s - 1;
        if last_column < w {
            let i = last_column - n.x;
            let mut lines = [0, 1].map(|p| SurfaceLine::column(&planes[p], n.log2, 0, i));
            for cy in region.y..(region.y + s).min(h) {
                let row = 2 * (cy % CHROMA_BAND) as usize;
                for (p, line) in lines.iter_mut().enumerate() {
                    if let Some(slot) = self.rows.get_mut(row + p) {
                        *slot = line.at(cy - n.y);
                    }
                }
            }
        }
    }
}

/// One chroma plane of a [`ChromaFrontier`], seen as the prediction of chroma leaves.
#[derive(Debug, Clone, Copy)]
pub struct ChromaPrediction<'a, const STRIPE: usize> {
    frontier: &'a ChromaFrontier<STRIPE>,
    plane: usize,
}

impl<const STRIPE: usize> SamplePrediction for ChromaPrediction<'_, STRIPE> {
    #[inline]
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
        let f = self.frontier;
        if !beside_rule(above, (x, y), (f.width, f.height), || f.column(x)) {
            return None;
        }
        Some(i32::from(f.stored(self.plane, above, x, y)) * SAMPLE_ONE)
    }
}

/// A [`TileOut`] that turns luma tiles into RGB tiles: each pixel takes its chroma from the
/// current leaf's [`ChromaPatch`] when it lies in the leaf, else (a pixel of an earlier leaf
/// that waited for this one, just above or left of it) from the chroma frontier, which still
/// holds the earlier leaves' last chroma row and column; either way upsampled (the module's
/// documentation). Tiles come in output coordinates of a decode at `scale`.
pub struct ColourOut<'a, const STRIPE: usize> {
    /// The current leaf's chroma.
    pub patch: &'a ChromaPatch,
    /// The chroma of the leaves before it.
    pub frontier: &'a ChromaFrontier<STRIPE>,
    /// The decode's scale (output pixel to coded pixel).
    pub scale: Scale,
    /// Where the RGB tiles go.
    pub out: &'a mut dyn TileOut,
}

impl<const STRIPE: usize> core::fmt::Debug for ColourOut<'_, STRIPE> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ColourOut")
            .field("node", &self.patch.node)
            .finish_non_exhaustive()
    }
}

impl<const STRIPE: usize> ColourOut<'_, STRIPE> {
    /// The chroma (both planes) under coded luma pixel `(x, y)` of an earlier leaf, drawn with
    /// this one (it waited with the row above the leaf or the column left of it): the chroma
    /// pixel the frontier holds, a quarter of the way to this leaf's chroma pixel beside it
    /// (above the leaf, from `first_row`: the leaf's first chroma row, at chroma pixels).
    fn waiting_chroma(&self, x: u32, y: u32, first_row: &mut [SurfaceLine<'_>; 2]) -> (u8, u8) {
        let (cx, cy) = (x / 2, y / 2);
        let n = &self.patch.node;
        let s = n.size();
        let above = cy < n.y;
        let mut towards = |p: usize| {
            let stored = self.frontier.stored(p, above, cx, cy);
            let next = if above {
                (cx >= n.x && cx - n.x < s).then(|| first_row[p & 1].at(cx - n.x))
            } else {
                (cy >= n.y && cy - n.y < s).then(|| self.patch.value(p, 0, cy - n.y))
            };
            match next {
                Some(next) => quarter(stored, next),
                None => stored,
            }
        };
        (towards(0), towards(1))
    }

    /// Fills `row` with the chroma of the tile row of coded luma row `y` whose pixels are at
    /// coded columns `columns`: pixels of the leaf take its surface
    /// ([`ChromaPatch::value_under`]) with the chroma beside the leaf mixed in a quarter on its
    /// first column and row; waiting pixels of an earlier leaf, [`ColourOut::waiting_chroma`].
    fn chroma_row(&self, y: u32, columns: impl Iterator<Item = u32>, row: &mut [(u8, u8)]) {
        let n = &self.patch.node;
        let (left, top) = (2 * n.x, 2 * n.y);
        let inside = y >= top;
        // In the leaf's rows, its surface under luma row `y`; above them, its first chroma row.
        let (sub, q) = if inside { (2, centre(y - top)) } else { (0, 0) };
        let mut lines = [0, 1].map(|p| SurfaceLine::row(&self.patch.planes[p], n.log2, sub, q));
        let mut last: Option<(u32, (u8, u8))> = None;
        for (slot, x) in row.iter_mut().zip(columns) {
            *slot = match last {
                Some((lx, c)) if lx == x => c,
                _ if inside && x >= left => {
                    let (i, j) = (x - left, y - top);
                    let [cb, cr] = &mut lines;
                    let mut c = (cb.at(centre(i)), cr.at(centre(i)));
                    if i == 0 || j == 0 {
                        c = (
                            self.beside_edges(0, c.0, (x, y), (i, j)),
                            self.beside_edges(1, c.1, (x, y), (i, j)),
                        );
                    }
                    last = Some((x, c));
                    c
                }
                _ => {
                    let c = self.waiting_chroma(x, y, &mut lines);
                    last = Some((x, c));
                    c
                }
            };
        }
    }

    /// The RGB pixels of a coded-size tile `area` (luma `luma`, row-major) that lies in the
    /// leaf: each plane's surface under the tile ([`surface_tile`]) in the green and blue
    /// places of its pixels, the chroma beside the leaf mixed in on the leaf's first column
    /// and row, then the conversion in place (no buffer beside `rgb`).
    #[inline(never)]
    fn convert_inside(&mut self, area: Rect, luma: &[u8]) -> Result<(), Stop> {
        // Zeroed as words (an array of triples would be zeroed byte by byte).
        let mut tile = [0u8; 3 * TILE * TILE];
        let n = &self.patch.node;
        let (i0, j0) = (area.x - 2 * n.x, area.y - 2 * n.y);
        let (w, h) = ((area.w as usize).min(TILE), (area.h as usize).min(TILE));
        let pixels = &mut tile.as_chunks_mut::<3>().0[..w * h];
        for (p, plane) in self.patch.planes.iter().enumerate() {
            surface_tile(plane, n.log2, (i0, j0), (w, h), pixels, 1 + p);
        }
        if i0 == 0 || j0 == 0 {
            for r in 0..h {
                let Some(row) = pixels.get_mut(r * w..(r + 1) * w) else {
                    break;
                };
                let (x, y, j) = (area.x, area.y + r as u32, j0 + r as u32);
                let last = if j == 0 { w } else { usize::from(i0 == 0) };
                for (k, px) in row.iter_mut().take(last).enumerate() {
                    let i = i0 + k as u32;
                    for (p, c) in px[1..].iter_mut().enumerate() {
                        *c = self.beside_edges(p, *c, (x + k as u32, y), (i, j));
                    }
                }
            }
        }
        convert(luma, pixels);
        self.put_rgb(area, &mut tile)
    }

    /// Chroma `c` of plane `p` under luma pixel `(x, y)` (offset `(i, j)` in the leaf) with the
    /// chroma beside the leaf mixed in a quarter on its first column and first row, when known.
    #[inline(never)]
    fn beside_edges(&self, p: usize, c: u8, (x, y): (u32, u32), (i, j): (u32, u32)) -> u8 {
        let n = &self.patch.node;
        let plane = self.frontier.plane(p);
        let mut c = c;
        if i == 0 {
            if let Some(left) = plane.beside(false, n.x, y / 2) {
                c = quarter(c, (left >> SAMPLE_BITS) as u8);
            }
        }
        if j == 0 {
            if let Some(above) = plane.beside(true, x / 2, n.y) {
                c = quarter(c, (above >> SAMPLE_BITS) as u8);
            }
        }
        c
    }
}

/// `a` a quarter of the way to `b`: `(3 a + b + 2) >> 2`.
#[inline]
fn quarter(a: u8, b: u8) -> u8 {
    ((3 * u32::from(a) + u32::from(b) + 2) >> 2) as u8
}

/// The RGB pixels of `luma` and the chroma in `rgb` (each pixel's `Cb` and `Cr` in its
/// second and third bytes), converted in place: [`ycbcr_to_rgb`] of each, its `- 128` and
/// rounding folded into one constant per product sum.
#[inline(never)]
fn convert(luma: &[u8], rgb: &mut [[u8; 3]]) {
    const R: i32 = 32768 - 128 * 91881;
    const G: i32 = 32768 + 128 * (22554 + 46802);
    const B: i32 = 32768 - 128 * 116130;
    for (&l, px) in luma.iter().zip(rgb) {
        let (l, b, r) = (i32::from(l), i32::from(px[1]), i32::from(px[2]));
        *px = [
            byte(l + ((91881 * r + R) >> 16)),
            byte(l + ((G - 22554 * b - 46802 * r) >> 16)),
            byte(l + ((116130 * b + B) >> 16)),
        ];
    }
}

/// The values of `plane` (a leaf of side `2^log2` chroma pixels) under the luma pixels of
/// columns `i0..i0 + w` and rows `j0..j0 + h` of the leaf, into byte `p` of the pixels of
/// `out` (row-major, `w` per row): [`ChromaPatch::value_under`] of each, the same integers as
/// [`SurfaceLine`] makes. The columns and the rows fall in runs whose centres share a grid
/// cell ([`cell_run`]); over a run of columns by a run of rows the surface is bilinear, so
/// each row of it is a line stepped by additions, and from one row to the next the line's
/// start and slope step by fixed amounts.
#[inline(never)]
fn surface_tile(
    plane: &ChromaPlane,
    log2: u8,
    (i0, j0): (u32, u32),
    (w, h): (usize, usize),
    out: &mut [[u8; 3]],
    p: usize,
) {
    let p = p.min(2);
    let g = u32::from(plane.grid.max(1));
    let sh = u32::from(log2).saturating_sub(g.trailing_zeros()) + 2;
    let shift = 2 * sh + SAMPLE_BITS;
    let half = 1i32 << (shift - 1);
    let side = g as usize + 1;
    let control = |at: usize| i32::from(plane.control.get(at).copied().unwrap_or(0));
    let mut column = 0;
    while column < w {
        let (cell, len) = cell_run(i0 + column as u32, sh, w - column);
        let a = cell.min(g - 1);
        let f = centre(i0 + column as u32).wrapping_sub(a << sh) as i32;
        let mut row = 0;
        while row < h {
            let (cell, rows) = cell_run(j0 + row as u32, sh, h - row);
            let b = cell.min(g - 1);
            let e = centre(j0 + row as u32).wrapping_sub(b << sh) as i32;
            // The line's start (with the rounding half) and slope on the run's first row,
            // and their changes from one row to the next.
            let upper = b as usize * side + a as usize;
            let (u0, u1) = (control(upper), control(upper + 1));
            let (d0, d1) = (control(upper + side) - u0, control(upper + side + 1) - u1);
            let c0 = (u0 << sh).wrapping_add(e.wrapping_mul(d0));
            let c1 = (u1 << sh).wrapping_add(e.wrapping_mul(d1));
            let mut slope = c1.wrapping_sub(c0);
            let mut v0 = (c0 << sh)
                .wrapping_add(f.wrapping_mul(slope))
                .wrapping_add(half);
            let dslope = 2 * (d1 - d0);
            let dv = ((d0 << sh).wrapping_add(f.wrapping_mul(d1 - d0))).wrapping_mul(2);
            for r in row..row + rows {
                let at = r * w + column;
                let Some(now) = out.get_mut(at..at + len) else {
                    return;
                };
                let (mut v, step) = (v0, slope.wrapping_mul(2));
                for px in now {
                    px[p] = byte(v >> shift);
                    v = v.wrapping_add(step);
                }
                v0 = v0.wrapping_add(dv);
                slope = slope.wrapping_add(dslope);
            }
            row += rows;
        }
        column += len;
    }
}

/// The run of luma columns (or rows) from offset `i` in a leaf whose centres ([`centre`]) lie
/// in one grid cell of `2^sh` units: that cell and the run's length, at most `left`. The
/// centres step by 2 units, but for offset 0's, clamped to the leaf's edge: a run of its own.
#[inline(always)]
fn cell_run(i: u32, sh: u32, left: usize) -> (u32, usize) {
    let q = centre(i);
    let cell = q >> sh;
    let len = if i == 0 {
        1
    } else {
        (((cell + 1) << sh) - q).div_ceil(2) as usize
    };
    (cell, len.min(left))
}

/// One chroma plane's surface along one line of a leaf, a row or a column, stepped along it:
/// the grid's interpolation across the line at the two grid points around the current
/// position is kept until the line leaves that cell (the same integers as [`sample_at`],
/// summed in another order).
struct SurfaceLine<'a> {
    control: &'a [i16; MAX_CONTROL],
    /// The index of the first grid value of the grid line before the line (grid row `b` for a
    /// row, grid column `b` for a column), and the index steps along the line and to the next
    /// grid line.
    first: usize,
    along: usize,
    across: usize,
    g: u32,
    /// Fraction bits of a position within a grid cell.
    sh: u32,
    /// The line's weight between its two grid lines (`e`).
    e: i32,
    /// The grid point whose interpolations the cell's segment holds (`u32::MAX`: none yet).
    a: u32,
    /// The line across that cell: `one * c0 + f * (c1 - c0)` for the interpolations `c0` and
    /// `c1` at its two grid points.
    base: i32,
    slope: i32,
}

impl<'a> SurfaceLine<'a> {
    /// The surface of `plane` (a leaf of side `2^log2` chroma pixels) along row `q`, positions
    /// in units of `2^-sub` chroma pixels ([`sample_at`]).
    fn row(plane: &'a ChromaPlane, log2: u8, sub: u32, q: u32) -> Self {
        Self::new(plane, log2, sub, q, true)
    }

    /// The same along column `q`.
    fn column(plane: &'a ChromaPlane, log2: u8, sub: u32, q: u32) -> Self {
        Self::new(plane, log2, sub, q, false)
    }

    fn new(plane: &'a ChromaPlane, log2: u8, sub: u32, q: u32, row: bool) -> Self {
        let g = u32::from(plane.grid.max(1));
        let sh = u32::from(log2).saturating_sub(g.trailing_zeros()) + sub;
        let side = g as usize + 1;
        let (along, across) = if row { (1, side) } else { (side, 1) };
        SurfaceLine {
            control: &plane.control,
            first: (q >> sh).min(g - 1) as usize * across,
            along,
            across,
            g,
            sh,
            e: (q & ((1 << sh) - 1)) as i32,
            a: u32::MAX,
            base: 0,
            slope: 0,
        }
    }

    /// The grid's interpolation across the line at grid point `c` along it, `2^sh` times the
    /// value: `(one - e) * near + e * far`.
    #[inline]
    fn grid(&self, c: usize) -> i32 {
        let at = self.first + c * self.along;
        let value = |at: usize| i32::from(self.control.get(at).copied().unwrap_or(0));
        let (near, far) = (value(at), value(at + self.across));
        (near << self.sh) + self.e * (far - near)
    }

    /// The 8-bit value at position `q` along the line. Out of line: a few copies of it would
    /// cost more flash than the calls cost time.
    #[inline(never)]
    fn at(&mut self, q: u32) -> u8 {
        let v = self.line(q);
        let shift = 2 * self.sh + SAMPLE_BITS;
        byte((v + (1 << (shift - 1))) >> shift)
    }

    /// The line at position `q` (`2 sh + SAMPLE_BITS` fraction bits), the cell's segment made
    /// first when `q` is in another cell than the last.
    #[inline]
    fn line(&mut self, q: u32) -> i32 {
        let a = (q >> self.sh).min(self.g - 1);
        let f = (q & ((1 << self.sh) - 1)) as i32;
        if a != self.a {
            self.a = a;
            let c0 = self.grid(a as usize);
            self.base = c0 << self.sh;
            self.slope = self.grid(a as usize + 1) - c0;
        }
        self.base + f * self.slope
    }
}

impl<const STRIPE: usize> TileOut for ColourOut<'_, STRIPE> {
    /// Converts `tile` (luma) to RGB and puts it out; the two ways of converting are out of
    /// line, so that the RGB tile and either's state are on the stack only while used.
    fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop> {
        let Rect { x, y, w, h } = tile.area;
        let n = (w * h) as usize;
        if n > TILE * TILE || w as usize > TILE || tile.pixels.len() < n || tile.channels != 1 {
            return Ok(());
        }
        let node = &self.patch.node;
        if self.scale.log2() == 0 && x >= 2 * node.x && y >= 2 * node.y {
            self.convert_inside(tile.area, tile.pixels)
        } else {
            self.convert_rows(tile.area, tile.pixels)
        }
    }
}

impl<const STRIPE: usize> ColourOut<'_, STRIPE> {
    /// The RGB pixels of tile `area` (output coordinates, luma `luma`), row by row: the
    /// chroma of each tile row ([`ColourOut::chroma_row`]), then the conversion. For tiles
    /// of a scaled decode and tiles holding pixels of earlier leaves.
    #[inline(never)]
    fn convert_rows(&mut self, area: Rect, luma: &[u8]) -> Result<(), Stop> {
        let Rect { x, y, w, h } = area;
        let mut tile = [0u8; 3 * TILE * TILE];
        let rgb = tile.as_chunks_mut::<3>().0;
        let k = self.scale.log2();
        let coded = |v: u32| {
            if k >= 0 {
                v >> k
            } else {
                v << (-k)
            }
        };
        // The chroma of a tile row, kept for the next row when it is the same coded row (an
        // enlarged decode repeats coded pixels).
        let mut row = [(128u8, 128u8); TILE];
        let mut row_of = None;
        let mut at = 0;
        for j in 0..h {
            let cy = coded(y + j);
            if row_of != Some(cy) {
                row_of = Some(cy);
                let columns = (0..w).map(|i| coded(x + i));
                let Some(row) = row.get_mut(..w as usize) else {
                    return Ok(());
                };
                self.chroma_row(cy, columns, row);
            }
            for c in row.iter().take(w as usize) {
                let (Some(&l), Some(px)) = (luma.get(at), rgb.get_mut(at)) else {
                    return Ok(());
                };
                *px = ycbcr_to_rgb(l, c.0, c.1);
                at += 1;
            }
        }
        self.put_rgb(area, &mut tile)
    }

    /// Puts out the RGB tile `area`, its pixels at the start of `rgb`.
    fn put_rgb(&mut self, area: Rect, rgb: &mut [u8; 3 * TILE * TILE]) -> Result<(), Stop> {
        let n = ((area.w * area.h) as usize).min(TILE * TILE);
        self.out.put(TileMut {
            area,
            pixels: &mut rgb[..3 * n],
            channels: 3,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversion_round_trips_within_a_level_or_two() {
        let mut worst = 0;
        for r in (0..=255u8).step_by(5) {
            for g in (0..=255u8).step_by(5) {
                for b in (0..=255u8).step_by(5) {
                    let [y, cb, cr] = rgb_to_ycbcr(r, g, b);
                    let back = ycbcr_to_rgb(y, cb, cr);
                    for (a, c) in back.iter().zip([r, g, b]) {
                        worst = worst.max((i32::from(*a) - i32::from(c)).abs());
                    }
                }
            }
        }
        assert!(worst <= 2, "worst round-trip error {worst}");
        // Grays stay gray and neutral.
        for v in 0..=255u8 {
            assert_eq!(rgb_to_ycbcr(v, v, v), [v, 128, 128]);
            assert_eq!(ycbcr_to_rgb(v, 128, 128), [v, v, v]);
        }
        // JFIF's primaries.
        assert_eq!(rgb_to_ycbcr(255, 0, 0), [76, 85, 255]);
        assert_eq!(rgb_to_ycbcr(0, 0, 255), [29, 255, 107]);
    }

    #[test]
    fn a_converted_tile_is_the_conversion_of_its_pixels() {
        let luma: [u8; 256] = core::array::from_fn(|k| (k * 5 % 256) as u8);
        for cb in 0..=255u8 {
            let mut rgb: [[u8; 3]; 256] = core::array::from_fn(|k| [0, cb, k as u8]);
            convert(&luma, &mut rgb);
            for (k, px) in rgb.iter().enumerate() {
                assert_eq!(
                    *px,
                    ycbcr_to_rgb(luma[k], cb, k as u8),
                    "cb {cb}, pixel {k}"
                );
            }
        }
    }

    #[test]
    fn bilinear_chroma_interpolates_its_grid() {
        let one = SAMPLE_ONE as i16;
        let mut plane = ChromaPlane {
            grid: 1,
            control: [0; MAX_CONTROL],
        };
        plane.control[..4].copy_from_slice(&[0, 64 * one, 0, 64 * one]);
        // A 4 px ramp: 0, 16, 32, 48 across, constant down.
        for j in 0..4 {
            for i in 0..4 {
                assert_eq!(sample(&plane, 2, i, j), (16 * i) as u8);
            }
        }
        // A pixel grid (g = C) draws its values.
        let mut grid = ChromaPlane {
            grid: 2,
            control: [0; MAX_CONTROL],
        };
        for (k, v) in grid.control[..9].iter_mut().enumerate() {
            *v = (10 * k as i16) * one;
        }
        assert_eq!(sample(&grid, 1, 1, 1), 40);
        assert_eq!(sample(&grid, 1, 0, 1), 30);
    }

    /// A 4 x 4 chroma leaf at `(at, at)` whose plane `p` is a ramp of 16 levels per pixel
    /// across (0, 16, 32, 48), the other plane neutral.
    fn ramp_leaf(at: u32, p: usize) -> ChromaPatch {
        let one = SAMPLE_ONE as i16;
        let mut patch = ChromaPatch::EMPTY;
        patch.node = Node {
            x: at,
            y: at,
            log2: 2,
        };
        patch.planes[p].control[..4].copy_from_slice(&[0, 64 * one, 0, 64 * one]);
        patch
    }

    /// Under luma pixels, chroma is the surface at each pixel's centre: a ramp of 16 levels
    /// per chroma pixel gives 8 per luma pixel, from the leaf's edge value on its first column.
    #[test]
    fn chroma_is_upsampled_inside_a_leaf() {
        let patch = ramp_leaf(2, 0);
        let row: [u8; 8] = core::array::from_fn(|i| patch.value_under(0, i as u32, 5));
        assert_eq!(row, [0, 4, 12, 20, 28, 36, 44, 52]);
        // Constant down the leaf, the first row included.
        assert_eq!(patch.value_under(0, 3, 0), row[3]);
        assert_eq!(patch.value_under(1, 3, 3), 128);
    }

    /// A row made by [`sample_row`] is [`sample`] at each of its pixels, on every grid and leaf
    /// size.
    #[test]
    fn a_sampled_row_is_the_surface() {
        let mut seed = 5u32;
        for log2 in 0..=6u8 {
            for (g, _) in CHROMA_GRIDS {
                if u32::from(g) > 1 << log2 {
                    continue;
                }
                let mut plane = ChromaPlane {
                    grid: g,
                    control: [0; MAX_CONTROL],
                };
                for v in plane.control.iter_mut() {
                    seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    *v = (seed >> 20) as i16;
                }
                let side = 1u32 << log2;
                let mut row = [0u8; 64];
                for j in 0..side {
                    sample_row(&plane, log2, j, &mut row[..side as usize]);
                    for i in 0..side {
                        assert_eq!(
                            row[i as usize],
                            sample(&plane, log2, i, j),
                            "grid {g}, 2^{log2}, ({i}, {j})"
                        );
                    }
                }
            }
        }
    }

    /// The row-stepped surface of the drawing is [`ChromaPatch::value_under`], bit for bit, on
    /// every grid and leaf size, with control values over the whole sample range.
    #[test]
    fn the_stepped_surface_is_the_surface() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for (k, &(g, _)) in CHROMA_GRIDS.iter().enumerate() {
            for log2 in (k as u8)..=6 {
                let mut patch = ChromaPatch::EMPTY;
                patch.node.log2 = log2;
                patch.planes[0].grid = g;
                for v in patch.planes[0].control.iter_mut() {
                    let span = (crate::model::SAMPLE_MAX - crate::model::SAMPLE_MIN) as u64;
                    *v = (crate::model::SAMPLE_MIN + (next() % (span + 1)) as i32) as i16;
                }
                let side = 2 << log2;
                for j in 0..side {
                    let mut row = SurfaceLine::row(&patch.planes[0], log2, 2, centre(j));
                    for i in 0..side {
                        assert_eq!(
                            row.at(centre(i)),
                            patch.value_under(0, i, j),
                            "g {g} log2 {log2}"
                        );
                    }
                }
                // Made a tile at a time from any column and row, as a decode does.
                let t = crate::synthesis::TILE as u32;
                let corners = [0, 1, 2, 3, side / 2 - 1, side.saturating_sub(3)];
                for (i0, j0) in corners.iter().flat_map(|&i| corners.map(|j| (i, j))) {
                    let (i0, j0) = (i0.min(side - 1), j0.min(side - 1));
                    let w = (side - i0).min(t);
                    let h = (side - j0).min(t);
                    let mut out = [[0u8; 3]; crate::synthesis::TILE * crate::synthesis::TILE];
                    let n = (w * h) as usize;
                    // Into the third byte of each pixel, as a colour tile holds `Cr`.
                    surface_tile(
                        &patch.planes[0],
                        log2,
                        (i0, j0),
                        (w as usize, h as usize),
                        &mut out[..n],
                        2,
                    );
                    for (k, px) in out[..n].iter().enumerate() {
                        let (i, j) = (i0 + k as u32 % w, j0 + k as u32 / w);
                        let v = patch.value_under(0, i, j);
                        assert_eq!(*px, [0, 0, v], "g {g} log2 {log2} ({i}, {j})");
                    }
                }
                for j in 0..side / 2 {
                    let mut row = SurfaceLine::row(&patch.planes[0], log2, 0, j);
                    let mut column = SurfaceLine::column(&patch.planes[0], log2, 0, j);
                    for i in 0..side / 2 {
                        assert_eq!(row.at(i), patch.value(0, i, j), "g {g} log2 {log2}");
                        assert_eq!(column.at(i), patch.value(0, j, i), "g {g} log2 {log2}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_frontier_keeps_the_last_row_and_column() {
        let mut f = ChromaFrontier::<256>::EMPTY;
        assert!(f.start(20, 20, 128));
        let leaf = ramp_leaf(0, 1);
        f.record(&leaf, &leaf.node);
        assert_eq!(f.plane(1).above(2, 4), Some(32 * SAMPLE_ONE));
        assert_eq!(f.plane(0).above(2, 4), Some(128 * SAMPLE_ONE));
        assert_eq!(f.plane(1).left(4, 1), Some(48 * SAMPLE_ONE));
        assert_eq!(f.plane(1).left(0, 1), None);
    }

    /// A subtree's chroma over one of its leaves: the frontier learns the leaf's last row and
    /// column with the subtree patch's values there.
    #[test]
    fn the_frontier_learns_a_leaf_from_its_subtree_patch() {
        let one = SAMPLE_ONE as i16;
        let mut patch = ChromaPatch::EMPTY;
        patch.node = Node {
            x: 0,
            y: 0,
            log2: 3,
        };
        // 8 levels per chroma pixel across.
        patch.planes[1].control[..4].copy_from_slice(&[0, 64 * one, 0, 64 * one]);
        let mut f = ChromaFrontier::<256>::EMPTY;
        assert!(f.start(20, 20, 128));
        let leaf = Node {
            x: 4,
            y: 4,
            log2: 2,
        };
        f.record(&patch, &leaf);
        assert_eq!(f.plane(1).above(5, 8), Some(40 * SAMPLE_ONE));
        assert_eq!(f.plane(1).left(8, 5), Some(56 * SAMPLE_ONE));
        assert_eq!(f.plane(0).left(8, 5), Some(128 * SAMPLE_ONE));
    }
}
