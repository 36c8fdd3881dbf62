//! Prediction from earlier leaves: the pixel frontier a decoder keeps, and what the syntax
//! predicts from it (a leaf's first control value, and the first row and column of a DPCM
//! leaf), in the value domain: a leaf whose residuals there are zero continues the pixels its
//! neighbours drew.
//!
//! Control values interpolate the image: a leaf's top row of control values sits on the pixel
//! row just below its upper neighbours, its left column just right of its left neighbours. The
//! decoder therefore remembers, for every column of the current stripe, the last pixel decoded
//! in it (the bottom row of the leaves above), and for every row of the current band the last
//! pixel decoded in that row (the right column of the leaves to the left). Coding tiles
//! ([`CODING_TILE`] pixels) are coded band by band, left to right within a stripe, each in Z
//! order: the pixels above and to the left of a leaf are decoded before it and nothing decoded
//! in between covers them again, so these are exactly the neighbours' pixels, across tile edges
//! too. Only a stripe's left edge (and the image's top) has nothing beside it, which bounds the
//! memory at one byte per column of the stripe and one per row of a band, whatever the image
//! size.

use crate::format::{med, CODING_TILE, DEFAULT_STRIPE};
use crate::geometry::{Node, Rect};
use crate::model::{ModelType, MAX_GRID, SAMPLE_ONE};
use crate::synthesis::{Patch, Stop, Tile, TileOut};

/// Where a leaf's predictions come from: the pixels earlier leaves drew next to it.
pub trait SamplePrediction {
    /// The pixel just above `(x, y)` (at `(x, y - 1)`) when `above`, else the one just left of
    /// it (at `(x - 1, y)`), in sample units, if earlier leaves drew it ([`beside_known`]).
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

/// Whether the pixel beside `(x, y)` (above it when `above`, else left of it) has been drawn
/// before the leaf at `(x, y)` in an image of `width x height` pixels coded in stripes of
/// `stripe` pixels: above, unless `(x, y)` is on the image's top row; left, unless it is on a
/// stripe's left edge. The frontier's availability rule, shared by decoders and encoders.
#[inline]
pub fn beside_known(above: bool, x: u32, y: u32, width: u32, height: u32, stripe: u32) -> bool {
    x < width
        && y < height
        && if above {
            y > 0
        } else {
            stripe > 0 && !x.is_multiple_of(stripe)
        }
}

/// The zero-flag context of a DPCM first-row or first-column residual whose pixels beside are
/// known: half its neighbourhood context `context` (twice the magnitude of the residual before
/// it) plus the change between those pixels, in steps (at most 2).
#[inline]
pub fn edge_context(context: usize, outside: i32, outside_before: i32, step: i32) -> usize {
    context / 2 + ((outside - outside_before).unsigned_abs() / step.max(1) as u32).min(2) as usize
}

/// The value a DPCM leaf's first-row or first-column control value is predicted by when the
/// pixels beside it and beside the value before it are known: the LOCO-I median of the value
/// before it in the leaf (`before`) and those pixels (`outside`, `outside_before`): the
/// neighbours' gradient, continued.
#[inline]
pub fn edge_prediction(before: i32, outside: i32, outside_before: i32) -> i32 {
    med(before, outside, outside_before)
}

/// What a leaf's control values are predicted from besides the leaf's own: the pixels its
/// neighbours drew beside it. Computed once per leaf, after its model and control coding are
/// known, for both the syntax (contexts) and the reconstruction (values).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LeafPrediction {
    /// The prediction of the first coded value, sample units: DPCM's top-left control value
    /// (the mean of the pixels left of and above it), or the grid transform's low band (the
    /// mean of the pixels along the leaf's top and left edges).
    pub first: i32,
    /// Whether pixels of both edges went into `first`.
    pub shared: bool,
    /// DPCM: the pixel beside each control point of the first row (`[0]`) and column (`[1]`)
    /// that lies in the leaf, as 8-bit pixels, where `known` has its bit.
    beside: [[u8; MAX_GRID]; 2],
    known: [u16; 2],
}

impl LeafPrediction {
    /// Nothing beside the leaf: mid-grey.
    pub const NONE: LeafPrediction = LeafPrediction {
        first: 128 * SAMPLE_ONE,
        shared: false,
        beside: [[0; MAX_GRID]; 2],
        known: [0; 2],
    };

    /// The prediction of the leaf `node` coded with `model`, by DPCM or by the grid transform
    /// (`transform`), from the pixels `prediction` knows.
    pub fn of<P: SamplePrediction + ?Sized>(
        prediction: &P,
        node: &Node,
        model: ModelType,
        transform: bool,
    ) -> LeafPrediction {
        let width = if transform { node.size() } else { 1 };
        let (first, shared) = prediction.predict(node.x, node.y, width);
        let mut out = LeafPrediction {
            first,
            shared,
            ..LeafPrediction::NONE
        };
        if transform {
            return out;
        }
        let spacing = model.spacing(node.log2);
        let side = model.coded_side(node.log2).min(MAX_GRID);
        for (row, (beside, known)) in out.beside.iter_mut().zip(&mut out.known).enumerate() {
            for (k, pixel) in beside.iter_mut().enumerate().take(side) {
                let along = k as u32 * spacing;
                if along >= node.size() {
                    break;
                }
                let (x, y) = if row == 0 {
                    (node.x + along, node.y)
                } else {
                    (node.x, node.y + along)
                };
                if let Some(v) = prediction.beside(row == 0, x, y) {
                    // Known pixels are 8-bit values in sample units.
                    *pixel = (v / SAMPLE_ONE).clamp(0, 255) as u8;
                    *known |= 1 << k;
                }
            }
        }
        out
    }

    /// The pixels beside control point `k` of the first row (`row`) or column and beside
    /// point `k - 1`, sample units, when both are known (`k >= 1`).
    #[inline]
    pub fn edge(&self, row: bool, k: usize) -> Option<(i32, i32)> {
        let i = usize::from(!row);
        let known = |k: usize| self.known[i] & (1 << k) != 0;
        if k == 0 || k >= MAX_GRID || !known(k) || !known(k - 1) {
            return None;
        }
        let pixel = |k: usize| i32::from(self.beside[i][k]) * SAMPLE_ONE;
        Some((pixel(k), pixel(k - 1)))
    }
}

/// The decoder's prediction memory: the last pixel decoded in each column of the current
/// stripe and in each row of the current band, for an image of `width x height` coded in
/// stripes of `stripe` pixels; holds stripes of up to `STRIPE` pixels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frontier<const STRIPE: usize = DEFAULT_STRIPE> {
    columns: [u8; STRIPE],
    rows: [u8; CODING_TILE as usize],
    width: u32,
    height: u32,
    stripe: u32,
}

impl<const STRIPE: usize> Default for Frontier<STRIPE> {
    fn default() -> Self {
        Frontier::EMPTY
    }
}

impl<const STRIPE: usize> Frontier<STRIPE> {
    /// Nothing decoded, for an empty image (all zero bits, like the syntax's fresh contexts):
    /// [`Frontier::start`] sets the size.
    pub const EMPTY: Frontier<STRIPE> = Frontier {
        columns: [0; STRIPE],
        rows: [0; CODING_TILE as usize],
        width: 0,
        height: 0,
        stripe: 0,
    };

    /// The widest stripe this frontier holds, pixels.
    pub const CAPACITY: u32 = STRIPE as u32;

    /// Starts a stream of a `width x height` image coded in stripes of `stripe` pixels (a
    /// positive multiple of [`CODING_TILE`]); `false`, and nothing set, when such a stripe is
    /// wider than this frontier holds. The slots keep what they hold: a slot is only read once
    /// a leaf of the stream has written it ([`beside_known`]).
    pub fn start(&mut self, width: u32, height: u32, stripe: u32) -> bool {
        if stripe == 0 || stripe > Self::CAPACITY {
            return false;
        }
        self.width = width;
        self.height = height;
        self.stripe = stripe;
        true
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
            columns: &mut self.columns,
            rows: &mut self.rows,
            stripe: self.stripe.max(1),
            out,
            right: node.x + last,
            bottom: node.y + last,
        }
    }
}

/// See [`Frontier::capture`].
pub struct Capture<'a> {
    columns: &'a mut [u8],
    rows: &'a mut [u8],
    stripe: u32,
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
        let Rect { x, y, w, .. } = tile.area;
        let on_right = x + w - 1 == self.right;
        for (j, row) in tile.pixels.chunks(w as usize).enumerate() {
            let py = y + j as u32;
            if let (true, Some(&p), Some(slot)) = (
                on_right,
                row.last(),
                self.rows.get_mut((py % CODING_TILE) as usize),
            ) {
                *slot = p;
            }
            if py == self.bottom {
                for (i, &p) in row.iter().enumerate() {
                    let column = ((x + i as u32) % self.stripe) as usize;
                    if let Some(slot) = self.columns.get_mut(column) {
                        *slot = p;
                    }
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

impl<const STRIPE: usize> SamplePrediction for Frontier<STRIPE> {
    #[inline]
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
        if !beside_known(above, x, y, self.width, self.height, self.stripe) {
            return None;
        }
        let slot = if above {
            self.columns.get((x % self.stripe) as usize)
        } else {
            self.rows.get((y % CODING_TILE) as usize)
        };
        slot.map(|&p| i32::from(p) * SAMPLE_ONE)
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

    fn node(x: u32, y: u32, log2: u8) -> Node {
        Node { x, y, log2 }
    }

    #[test]
    fn a_leaf_predicts_from_the_pixels_its_neighbours_drew() {
        let mut frontier = Frontier::<256>::EMPTY;
        assert!(!frontier.start(300, 200, 384), "a stripe wider than the frontier");
        assert!(frontier.start(300, 200, 128));
        let one = SAMPLE_ONE as i16;
        // A 4 px ramp from 0 to 64 grey levels across, at (0, 0): its right column is 48 (the
        // pixel one step short of the corner value 64), its bottom row 0, 16, 32, 48.
        frontier.record(&node(0, 0, 2), &bilinear([0, 64 * one, 0, 64 * one]));
        let ramp = |k: i32| 16 * k * SAMPLE_ONE;
        assert_eq!(frontier.above(2, 4), Some(ramp(2)));
        assert_eq!(frontier.left(4, 3), Some(ramp(3)));
        // Leaves at (4, 0) and (0, 4), in Z order, draw the pixels the one at (4, 4) is
        // predicted from.
        frontier.record(&node(4, 0, 2), &bilinear([100 * one; 4]));
        assert_eq!(frontier.left(8, 1), Some(100 * SAMPLE_ONE));
        assert_eq!(frontier.predict(0, 4, 1), (0, false));
        // A grid transform's low band: the mean along the top edge (the left one is the
        // stripe's edge).
        assert_eq!(frontier.predict(0, 4, 4), (ramp(3) / 2, false));
        frontier.record(&node(0, 4, 2), &bilinear([40 * one; 4]));
        assert_eq!(frontier.predict(4, 4, 1), (70 * SAMPLE_ONE, true));
        assert_eq!(frontier.predict(4, 4, 4), (70 * SAMPLE_ONE, true));
        // Nothing above the image's top, left of a stripe's edge, or outside the image.
        assert_eq!(frontier.above(2, 0), None);
        assert_eq!(frontier.left(128, 2), None);
        assert_eq!(frontier.left(0, 2), None);
        assert_eq!(frontier.above(300, 4), None);
        // Across a coding tile's top edge (a band's), the previous band's pixels.
        frontier.record(&node(0, 124, 2), &bilinear([77 * one; 4]));
        assert_eq!(frontier.above(1, 128), Some(77 * SAMPLE_ONE));
        assert_eq!(Frontier::<128>::EMPTY.predict(0, 0, 1), (128 * SAMPLE_ONE, false));
    }

    #[test]
    fn edges_follow_the_neighbours_gradient() {
        // Flat neighbours: predict the value before.
        assert_eq!(edge_prediction(160, 800, 800), 160);
        // A vertical edge in the row above (between the two pixels) continues into the leaf:
        // the median is the pixel above.
        assert_eq!(edge_prediction(160, 800, 160), 800);
        // A horizontal edge (flat pixels above, far from the value before): keep the value
        // before.
        assert_eq!(edge_prediction(800, 160, 160), 800);
        // A smooth gradient: the value before plus the change along the row above.
        assert_eq!(edge_prediction(160, 800, 480), 480);
        // The context: half the neighbourhood's, plus the change beside in steps (at most 2).
        assert_eq!(edge_context(4, 800, 800, 16), 2);
        assert_eq!(edge_context(2, 800, 784, 16), 2);
        assert_eq!(edge_context(0, 800, 160, 16), 2);
    }

    /// A leaf's prediction holds the pixels beside its first row and column at its control
    /// points, and the first value's mean.
    #[test]
    fn leaf_prediction_reads_the_pixels_at_the_control_points() {
        let mut frontier = Frontier::<128>::EMPTY;
        assert!(frontier.start(64, 64, 128));
        let one = SAMPLE_ONE as i16;
        frontier.record(&node(0, 0, 3), &bilinear([0, 80 * one, 0, 80 * one]));
        frontier.record(&node(8, 0, 3), &bilinear([90 * one; 4]));
        frontier.record(&node(0, 8, 3), &bilinear([30 * one; 4]));
        // A 5x5 grid on 8 px at (8, 8): points 2 px apart; above it the flat 90, left the
        // flat 30.
        let p = LeafPrediction::of(&frontier, &node(8, 8, 3), MODELS[2], false);
        assert_eq!(p.first, 60 * SAMPLE_ONE);
        assert!(p.shared);
        assert_eq!(p.edge(true, 1), Some((90 * SAMPLE_ONE, 90 * SAMPLE_ONE)));
        assert_eq!(p.edge(false, 3), Some((30 * SAMPLE_ONE, 30 * SAMPLE_ONE)));
        assert_eq!(p.edge(true, 4), None, "point 4 lies past the block");
        assert_eq!(p.edge(true, 0), None);
        let t = LeafPrediction::of(&frontier, &node(8, 8, 3), MODELS[2], true);
        assert_eq!(t.edge(true, 1), None);
    }
}
