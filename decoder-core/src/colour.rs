//! Colour: the YCbCr planes of a three-channel stream, and their conversion to RGB as pixels
//! are drawn.
//!
//! A colour stream codes luma (`Y`) exactly as a grayscale stream codes its one plane, and two
//! chroma planes (`Cb`, `Cr`) at half the width and height (4:2:0). The quadtree cut is shared:
//! every luma leaf of side `S` at `(x, y)` is followed in the stream by the two chroma leaves of
//! side `max(S / 2, 1)` at `(x / 2, y / 2)` of their planes. A chroma leaf is a grid of control
//! values (coded like a luma leaf's: DPCM or the grid transform, predicted from the chroma
//! pixels beside it) that is interpolated **bilinearly**, so that any of its pixels can be made
//! on its own, in the order luma is drawn, with no buffer: the decoder keeps no more than the
//! leaf's two grids and a chroma frontier (the last chroma row of each column pair of a stripe
//! and the last chroma column of each row pair of a band).
//!
//! Output pixel `(x, y)` takes the chroma pixel `(x / 2, y / 2)` (nearest, as JFIF decoders
//! without upsampling do) and is converted to RGB with the integer BT.601 full-range
//! conversion of [`ycbcr_to_rgb`].

use crate::format::{CODING_TILE, DEFAULT_STRIPE};
use crate::geometry::{Node, Rect};
use crate::model::{MAX_CONTROL, SAMPLE_BITS, SAMPLE_ONE};
use crate::prediction::{beside_known, SamplePrediction};
use crate::synthesis::{Scale, Stop, Tile, TileOut, TILE};

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
    [
        r.clamp(0, 255) as u8,
        g.clamp(0, 255) as u8,
        b.clamp(0, 255) as u8,
    ]
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
pub const CHROMA_GRIDS: [(u8, u8); 4] = [(1, 0), (2, 1), (4, 2), (8, 4)];

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
pub struct ChromaPlane {
    /// Grid intervals (1, 2, 4 or 8).
    pub grid: u8,
    /// Control values, row-major, `grid + 1` per row.
    pub control: [i16; MAX_CONTROL],
}

impl ChromaPlane {
    /// A flat mid-grey plane (no colour).
    pub const NEUTRAL: ChromaPlane = ChromaPlane {
        grid: 1,
        control: [128 * SAMPLE_ONE as i16; MAX_CONTROL],
    };
}

/// The two chroma planes of one leaf, at the leaf's chroma node ([`chroma_node`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChromaPatch {
    /// The chroma node (chroma-plane coordinates).
    pub node: Node,
    /// `Cb` then `Cr`.
    pub planes: [ChromaPlane; 2],
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
}

/// [`ChromaPatch::value`] of one plane of a leaf of side `2^log2`.
#[inline]
pub fn sample(plane: &ChromaPlane, log2: u8, i: u32, j: u32) -> u8 {
    let g = u32::from(plane.grid.max(1));
    let side = g as usize + 1;
    let sh = u32::from(log2).saturating_sub(g.trailing_zeros());
    let mask = (1u32 << sh) - 1;
    let (a, f) = ((i >> sh).min(g - 1) as usize, (i & mask) as i32);
    let (b, e) = ((j >> sh).min(g - 1) as usize, (j & mask) as i32);
    let at = |r: usize, c: usize| i32::from(plane.control.get(r * side + c).copied().unwrap_or(0));
    let one = 1i32 << sh;
    let top = (one - f) * at(b, a) + f * at(b, a + 1);
    let bottom = (one - f) * at(b + 1, a) + f * at(b + 1, a + 1);
    let v = (one - e) * top + e * bottom;
    let shift = 2 * sh + SAMPLE_BITS;
    ((v + (1 << (shift - 1))) >> shift).clamp(0, 255) as u8
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
    /// Chroma stripe width (half the luma one).
    stripe: u32,
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
        stripe: 0,
    };

    /// Starts a stream of a `width x height` (luma) image in stripes of `stripe` luma pixels;
    /// `false` when the stripe is wider than this frontier holds.
    pub fn start(&mut self, width: u32, height: u32, stripe: u32) -> bool {
        if stripe < 2 || stripe as usize > STRIPE {
            return false;
        }
        self.width = chroma_len(width);
        self.height = chroma_len(height);
        self.stripe = stripe / 2;
        true
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
            self.columns
                .get(2 * (cx % self.stripe.max(1)) as usize + (p & 1))
        } else {
            self.rows.get(2 * (cy % CHROMA_BAND) as usize + (p & 1))
        };
        slot.copied().unwrap_or(128)
    }

    /// Learns a chroma leaf's last row and column (those of its pixels in the plane).
    pub fn record(&mut self, patch: &ChromaPatch) {
        let n = &patch.node;
        let s = n.size();
        let (w, h) = (self.width, self.height);
        let stripe = self.stripe.max(1);
        let last_row = n.y + s - 1;
        if last_row < h {
            for cx in n.x..(n.x + s).min(w) {
                for p in 0..2 {
                    let v = patch.value(p, cx - n.x, s - 1);
                    if let Some(slot) = self.columns.get_mut(2 * (cx % stripe) as usize + p) {
                        *slot = v;
                    }
                }
            }
        }
        let last_column = n.x + s - 1;
        if last_column < w {
            for cy in n.y..(n.y + s).min(h) {
                for p in 0..2 {
                    let v = patch.value(p, s - 1, cy - n.y);
                    if let Some(slot) = self.rows.get_mut(2 * (cy % CHROMA_BAND) as usize + p) {
                        *slot = v;
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
        if !beside_known(above, x, y, f.width, f.height, f.stripe) {
            return None;
        }
        Some(i32::from(f.stored(self.plane, above, x, y)) * SAMPLE_ONE)
    }
}

/// A [`TileOut`] that turns luma tiles into RGB tiles: each pixel takes its chroma from the
/// current leaf's [`ChromaPatch`] when it lies in the leaf, else (a pixel of an earlier leaf
/// that waited for this one, just above or left of it) from the chroma frontier, which still
/// holds the earlier leaves' last chroma row and column. Tiles come in output coordinates of a
/// decode at `scale`.
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
    /// The chroma pixel (both planes) under coded luma pixel `(x, y)`.
    #[inline]
    fn chroma(&self, x: u32, y: u32) -> (u8, u8) {
        let (cx, cy) = (x / 2, y / 2);
        let n = &self.patch.node;
        if cy < n.y {
            (
                self.frontier.stored(0, true, cx, cy),
                self.frontier.stored(1, true, cx, cy),
            )
        } else if cx < n.x {
            (
                self.frontier.stored(0, false, cx, cy),
                self.frontier.stored(1, false, cx, cy),
            )
        } else {
            let (i, j) = (cx - n.x, cy - n.y);
            (self.patch.value(0, i, j), self.patch.value(1, i, j))
        }
    }
}

impl<const STRIPE: usize> TileOut for ColourOut<'_, STRIPE> {
    fn put(&mut self, tile: Tile<'_>) -> Result<(), Stop> {
        let Rect { x, y, w, h } = tile.area;
        let n = (w * h) as usize;
        let mut rgb = [0u8; 3 * TILE * TILE];
        if n > TILE * TILE || w as usize > TILE || tile.pixels.len() < n || tile.channels != 1 {
            return Ok(());
        }
        let k = self.scale.log2();
        let coded = |v: u32| {
            if k >= 0 {
                v >> k
            } else {
                v << (-k)
            }
        };
        // The chroma of a tile row, kept for the next row when it has the same chroma row
        // (two luma rows share one at the coded size).
        let mut row = [(128u8, 128u8); TILE];
        let mut row_of = None;
        let mut at = 0;
        for j in 0..h {
            let cy = coded(y + j);
            if row_of != Some(cy / 2) {
                row_of = Some(cy / 2);
                let mut last: Option<(u32, (u8, u8))> = None;
                for (i, slot) in row.iter_mut().enumerate().take(w as usize) {
                    let cx = coded(x + i as u32);
                    *slot = match last {
                        Some((lx, c)) if lx == cx / 2 => c,
                        _ => {
                            let c = self.chroma(cx, cy);
                            last = Some((cx / 2, c));
                            c
                        }
                    };
                }
            }
            for c in row.iter().take(w as usize) {
                let px = ycbcr_to_rgb(tile.pixels[at], c.0, c.1);
                rgb[3 * at..3 * at + 3].copy_from_slice(&px);
                at += 1;
            }
        }
        self.out.put(Tile {
            area: tile.area,
            pixels: &rgb[..3 * n],
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

    #[test]
    fn the_frontier_keeps_the_last_row_and_column() {
        let mut f = ChromaFrontier::<256>::EMPTY;
        assert!(f.start(20, 20, 128));
        let one = SAMPLE_ONE as i16;
        let mut patch = ChromaPatch::EMPTY;
        patch.node = Node {
            x: 0,
            y: 0,
            log2: 2,
        };
        patch.planes[1].control[..4].copy_from_slice(&[0, 64 * one, 0, 64 * one]);
        f.record(&patch);
        assert_eq!(f.plane(1).above(2, 4), Some(32 * SAMPLE_ONE));
        assert_eq!(f.plane(0).above(2, 4), Some(128 * SAMPLE_ONE));
        assert_eq!(f.plane(1).left(4, 1), Some(48 * SAMPLE_ONE));
        assert_eq!(f.plane(1).left(0, 1), None);
    }
}
