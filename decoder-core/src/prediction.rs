//! Prediction from earlier leaves: the pixel frontier a decoder keeps, and what the syntax
//! predicts from it (a leaf's first control value, and the first row and column of a DPCM
//! leaf).
//!
//! Control values interpolate the image: a leaf's top row of control values sits on the pixel
//! row just below its upper neighbours, its left column just right of its left neighbours. The
//! decoder therefore remembers, for every column of the current [`FRONTIER`]-pixel tile, the
//! last pixel decoded in it (the bottom row of the leaves above), and for every row the last
//! pixel decoded in that row (the right column of the leaves to the left). In the quadtree's Z
//! order, the pixels above and to the left of a leaf are decoded before it and nothing decoded
//! in between covers them again, so inside a tile these are exactly the neighbours' pixels;
//! across a tile's top or left edge nothing is predicted (the tile's pixels are contiguous in
//! Z order, but its upper and left neighbours tiles are not), which bounds the memory at two
//! rows of [`FRONTIER`] bytes whatever the image size.

use crate::format::{div_round, med, MAX_LEAF_LOG2};
use crate::geometry::{Node, Rect};
use crate::model::SAMPLE_ONE;
use crate::synthesis::{Patch, Stop, Tile, TileOut};

/// Side of the tiles the frontier covers, pixels: prediction does not cross their top and left
/// edges.
pub const FRONTIER: u32 = 128;

// No leaf is larger than a tile: each tile's leaves are consecutive in Z order.
const _: () = assert!(1u32 << MAX_LEAF_LOG2 <= FRONTIER);

/// Where a leaf's predictions come from: the pixels earlier leaves drew next to it.
pub trait SamplePrediction {
    /// The pixel just above `(x, y)` (at `(x, y - 1)`) when `above`, else the one just left of
    /// it (at `(x - 1, y)`), in sample units, if earlier leaves drew it and it is in `(x, y)`'s
    /// tile ([`FRONTIER`]).
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32>;

    /// The pixel just above `(x, y)` ([`SamplePrediction::beside`]).
    fn above(&self, x: u32, y: u32) -> Option<i32> {
        self.beside(true, x, y)
    }

    /// The pixel just left of `(x, y)` ([`SamplePrediction::beside`]).
    fn left(&self, x: u32, y: u32) -> Option<i32> {
        self.beside(false, x, y)
    }

    /// A prediction of the leaf at `(x, y)` from the pixels along its top and left edges over
    /// `width` pixels: their mean (of those known), and whether both edges have a known pixel;
    /// mid-grey when none is. With a width of 1, the mean of the pixels left of and above the
    /// top-left pixel (a DPCM leaf's first value); with the leaf's side, a prediction of the
    /// block's mean (what a grid transform's low band is, rather than its corner).
    fn predict(&self, x: u32, y: u32, width: u32) -> (i32, bool) {
        let (mut sum, mut count, mut sides) = (0u32, 0u32, 0);
        for row in [true, false] {
            let before = count;
            for k in 0..width {
                let (px, py) = if row { (x + k, y) } else { (x, y + k) };
                if let Some(v) = self.beside(row, px, py) {
                    // Pixels are non-negative sample values.
                    sum += v as u32;
                    count += 1;
                }
            }
            sides += u32::from(count > before);
        }
        match count {
            0 => (128 * SAMPLE_ONE, false),
            _ => ((sum / count) as i32, sides == 2),
        }
    }
}

/// Whether position `v` along an axis of an image `len` pixels long has a predecessor in its
/// tile: the frontier's availability rule, shared by decoders and encoders.
#[inline]
pub fn inside_tile(v: u32, len: u32) -> bool {
    !v.is_multiple_of(FRONTIER) && v < len
}

/// The index a DPCM leaf's first-row or first-column control value is coded against, in steps
/// of `step`: the LOCO-I median of the value before it in the leaf (`base`, which the value's
/// index is added to) and the pixels next to the leaf beside it and beside `base` (`outside`,
/// `outside_before`), as an offset from `base`.
#[inline]
pub fn edge_offset(base: i32, outside: i32, outside_before: i32, step: i32) -> i32 {
    div_round(med(base, outside, outside_before) - base, step)
}

/// The zero-flag context of a DPCM first-row or first-column residual whose pixels beside are
/// known: half its neighbourhood context `context` (twice the magnitude of the index before it)
/// plus the change between those pixels, in steps (at most 2).
#[inline]
pub fn edge_context(context: usize, outside: i32, outside_before: i32, step: i32) -> usize {
    context / 2 + ((outside - outside_before).unsigned_abs() / step.max(1) as u32).min(2) as usize
}

/// The pixels next to a leaf's control point `k` of its first row (`row == true`) or column,
/// and next to point `k - 1`: `Some` when both are known and point `k` lies in the leaf
/// (spacing `spacing` pixels).
#[inline]
pub fn edge_pixels<P: SamplePrediction + ?Sized>(
    prediction: &P,
    node: &Node,
    spacing: u32,
    row: bool,
    k: usize,
) -> Option<(i32, i32)> {
    let along = k as u32 * spacing;
    if k == 0 || along >= node.size() {
        return None;
    }
    let pixel = |d: u32| {
        let (x, y) = if row {
            (node.x + d, node.y)
        } else {
            (node.x, node.y + d)
        };
        prediction.beside(row, x, y)
    };
    Some((pixel(along)?, pixel(along - spacing)?))
}

/// The decoder's prediction memory: the last pixel decoded in each column and in each row of
/// the current tile (modulo [`FRONTIER`]), and the image size.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frontier {
    columns: [u8; FRONTIER as usize],
    rows: [u8; FRONTIER as usize],
    width: u32,
    height: u32,
}

impl Default for Frontier {
    fn default() -> Self {
        Frontier::EMPTY
    }
}

impl Frontier {
    /// Nothing decoded, for an empty image (all zero bits, like
    /// the syntax's fresh contexts): [`Frontier::start`] sets the size.
    pub const EMPTY: Frontier = Frontier {
        columns: [0; FRONTIER as usize],
        rows: [0; FRONTIER as usize],
        width: 0,
        height: 0,
    };

    /// Starts a stream of a `width x height` image. The slots keep what they hold: a slot is
    /// only read once a leaf of the stream has written it (the availability rule of
    /// [`SamplePrediction::above`]).
    pub fn start(&mut self, width: u32, height: u32) {
        self.width = width;
        self.height = height;
    }

    /// Remembers the bottom row and the right column of a decoded leaf (as far as they lie in
    /// the image), rendered from its patch.
    #[inline(never)]
    pub fn record(&mut self, node: &Node, patch: &Patch) {
        let s = node.size();
        let image = Rect::of_size(self.width, self.height);
        for row in [true, false] {
            let edge = Rect {
                x: if row { node.x } else { node.x + s - 1 },
                y: if row { node.y + s - 1 } else { node.y },
                w: if row { s } else { 1 },
                h: if row { 1 } else { s },
            };
            // Capturing into nothing cannot stop.
            let _ = patch.render_to(
                node,
                edge.intersect(&image),
                &mut self.capture(node, &mut Discard),
            );
        }
    }

    /// A tile output that hands every tile of the leaf `node` on to `out` and remembers the
    /// pixels of the leaf's bottom row and right column among them: drawing a whole leaf
    /// through it does what [`Frontier::record`] does, without rendering anything twice.
    pub fn capture<'a>(&'a mut self, node: &Node, out: &'a mut dyn TileOut) -> Capture<'a> {
        let last = node.size() - 1;
        Capture {
            frontier: self,
            out,
            right: node.x + last,
            bottom: node.y + last,
        }
    }
}

/// See [`Frontier::capture`].
pub struct Capture<'a> {
    frontier: &'a mut Frontier,
    out: &'a mut dyn TileOut,
    right: u32,
    bottom: u32,
}

impl core::fmt::Debug for Capture<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Capture")
            .field("right", &self.right)
            .field("bottom", &self.bottom)
            .finish_non_exhaustive()
    }
}

impl TileOut for Capture<'_> {
    fn put(&mut self, tile: Tile<'_>) -> Result<(), Stop> {
        let f = &mut *self.frontier;
        let Rect { x, y, w, h } = tile.area;
        let on_right = x + w - 1 == self.right;
        // Most tiles hold neither the leaf's right column nor its bottom row.
        if !on_right && !(y..y + h).contains(&self.bottom) {
            return self.out.put(tile);
        }
        for (j, row) in tile.pixels.chunks(w as usize).enumerate() {
            let py = y + j as u32;
            if let (true, Some(&p)) = (on_right, row.last()) {
                f.rows[(py % FRONTIER) as usize] = p;
            }
            if py == self.bottom {
                for (i, &p) in row.iter().enumerate() {
                    f.columns[((x + i as u32) % FRONTIER) as usize] = p;
                }
            }
        }
        self.out.put(tile)
    }
}

/// Takes every tile and keeps nothing.
struct Discard;

impl TileOut for Discard {
    fn put(&mut self, _tile: Tile<'_>) -> Result<(), Stop> {
        Ok(())
    }
}

impl SamplePrediction for Frontier {
    #[inline]
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
        // Along the edge and across it, with the image's size that way.
        let (slots, along, across, length, breadth) = if above {
            (&self.columns, x, y, self.width, self.height)
        } else {
            (&self.rows, y, x, self.height, self.width)
        };
        (inside_tile(across, breadth) && along < length)
            .then(|| i32::from(slots[(along % FRONTIER) as usize]) * SAMPLE_ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Weights, MODELS};

    /// A bilinear patch with corner values `v` (sample units).
    fn bilinear(v: [i16; 4]) -> Patch {
        let mut control = [0; crate::model::MAX_CONTROL];
        control[..4].copy_from_slice(&v);
        Patch {
            model: MODELS[0],
            control,
            weights: Weights::default_for(MODELS[0]),
        }
    }

    #[test]
    fn a_leaf_predicts_from_the_pixels_its_neighbours_drew() {
        let mut frontier = Frontier::EMPTY;
        frontier.start(64, 64);
        let one = SAMPLE_ONE as i16;
        // A 4 px ramp from 0 to 64 grey levels across, at (0, 0): its right column is 48 (the
        // pixel one step short of the corner value 64), its bottom row 0, 16, 32, 48.
        frontier.record(
            &Node {
                x: 0,
                y: 0,
                log2: 2,
            },
            &bilinear([0, 64 * one, 0, 64 * one]),
        );
        let ramp = |k: i32| 16 * k * SAMPLE_ONE;
        assert_eq!(frontier.above(2, 4), Some(ramp(2)));
        assert_eq!(frontier.left(4, 3), Some(ramp(3)));
        // Leaves at (4, 0) and (0, 4), in Z order, draw the pixels the one at (4, 4) is
        // predicted from.
        frontier.record(
            &Node {
                x: 4,
                y: 0,
                log2: 2,
            },
            &bilinear([100 * one; 4]),
        );
        assert_eq!(frontier.left(8, 1), Some(100 * SAMPLE_ONE));
        assert_eq!(frontier.predict(0, 4, 1), (0, false));
        // A grid transform's low band: the mean along the top edge (the left one is a tile's).
        assert_eq!(frontier.predict(0, 4, 4), (ramp(3) / 2, false));
        frontier.record(
            &Node {
                x: 0,
                y: 4,
                log2: 2,
            },
            &bilinear([40 * one; 4]),
        );
        assert_eq!(frontier.predict(4, 4, 1), (70 * SAMPLE_ONE, true));
        assert_eq!(frontier.predict(4, 4, 4), (70 * SAMPLE_ONE, true));
        // Nothing across a tile's edges or outside the image.
        assert_eq!(frontier.above(2, 0), None);
        assert_eq!(frontier.above(2, FRONTIER), None);
        assert_eq!(frontier.left(FRONTIER, 2), None);
        assert_eq!(frontier.above(64, 4), None);
        assert_eq!(Frontier::EMPTY.predict(0, 0, 1), (128 * SAMPLE_ONE, false));
    }

    #[test]
    fn edges_follow_the_neighbours_gradient() {
        // Flat neighbours: predict the value before.
        assert_eq!(edge_offset(160, 800, 800, 16), 0);
        // A vertical edge in the row above (between the two pixels) continues into the leaf:
        // the median is the pixel above.
        assert_eq!(edge_offset(160, 800, 160, 16), 40);
        // A horizontal edge (flat pixels above, far from the value before): keep the value
        // before.
        assert_eq!(edge_offset(800, 160, 160, 16), 0);
        // A smooth gradient: the value before plus the change along the row above.
        assert_eq!(edge_offset(160, 800, 480, 16), 20);
        // The context: half the neighbourhood's, plus the change beside in steps (at most 2).
        assert_eq!(edge_context(4, 800, 800, 16), 2);
        assert_eq!(edge_context(2, 800, 784, 16), 2);
        assert_eq!(edge_context(0, 800, 160, 16), 2);
    }
}
