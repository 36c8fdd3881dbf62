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

use crate::format::{byte, div_round, med, CODING_TILE, DEFAULT_STRIPE};
use crate::geometry::{Node, Rect};
use crate::model::SAMPLE_ONE;
#[cfg(test)]
use crate::synthesis::Discard;
use crate::synthesis::{Patch, Stop, TileMut, TileOut, TILE};

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
        predict_by_pixels(self, x, y, width)
    }
}

/// [`SamplePrediction::predict`] pixel by pixel, through [`SamplePrediction::beside`].
fn predict_by_pixels<P: SamplePrediction + ?Sized>(
    prediction: &P,
    x: u32,
    y: u32,
    width: u32,
) -> (i32, bool) {
    let (mut sum, mut count, mut sides) = (0u32, 0u32, 0);
    for row in [true, false] {
        let before = count;
        for k in 0..width {
            let (px, py) = if row { (x + k, y) } else { (x, y + k) };
            if let Some(v) = prediction.beside(row, px, py) {
                // Pixels are non-negative sample values.
                sum += v as u32;
                count += 1;
            }
        }
        sides += u32::from(count > before);
    }
    mean_prediction(sum, count, sides == 2)
}

/// The prediction of [`SamplePrediction::predict`] from the `count` known pixels beside a leaf
/// summing to `sum` (sample units), `both` when both edges had one.
#[inline]
fn mean_prediction(sum: u32, count: u32, both: bool) -> (i32, bool) {
    match count {
        0 => (128 * SAMPLE_ONE, false),
        _ => (crate::format::div_floor(sum, count) as i32, both),
    }
}

/// Whether the pixel beside `(x, y)` (above it when `above`, else left of it) has been drawn
/// before the leaf at `(x, y)` in an image of `width x height` pixels coded in stripes of
/// `stripe` pixels: above, unless `(x, y)` is on the image's top row; left, unless it is on a
/// stripe's left edge. The frontier's availability rule, shared by decoders and encoders.
#[inline]
pub fn beside_known(above: bool, x: u32, y: u32, width: u32, height: u32, stripe: u32) -> bool {
    beside_rule(above, (x, y), (width, height), || {
        x.checked_rem(stripe).unwrap_or(0)
    })
}

/// [`beside_known`] with the stripe's column of `x` (`x mod stripe`, 0 for no stripe) made by
/// `column`, only for a pixel to the left.
#[inline(always)]
pub(crate) fn beside_rule(
    above: bool,
    (x, y): (u32, u32),
    (width, height): (u32, u32),
    column: impl FnOnce() -> u32,
) -> bool {
    x < width && y < height && if above { y > 0 } else { column() != 0 }
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
    // min(change / step, 2) by comparisons: no division on a core without a divider.
    let change = (outside - outside_before).unsigned_abs();
    let step = step.max(1) as u32;
    let steps = if change >= step.saturating_mul(2) {
        2
    } else {
        usize::from(change >= step)
    };
    context / 2 + steps
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
    let pixel = |d: u32| edge_pixel(prediction, node, row, d);
    Some((pixel(along)?, pixel(along - spacing)?))
}

/// The pixel next to a leaf's first row (`row == true`) or column, `along` pixels from its
/// corner, if known.
#[inline]
pub fn edge_pixel<P: SamplePrediction + ?Sized>(
    prediction: &P,
    node: &Node,
    row: bool,
    along: u32,
) -> Option<i32> {
    let (x, y) = if row {
        (node.x + along, node.y)
    } else {
        (node.x, node.y + along)
    };
    prediction.beside(row, x, y)
}

/// A stripe width, a whole number of coding tiles, whose remainders are made by a multiply
/// and shifts rather than a division (a Cortex-M0 has no divide instruction); coordinates are
/// below 2^16. One word: the tile count in the low [`TILE_COUNT_BITS`] bits, above them
/// `ceil(2^RECIPROCAL_BITS / tiles)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct StripeWidth(u32);

/// Precision of [`StripeWidth`]'s reciprocal: exact for quotients of numbers below
/// `MAX_TILES` by divisors up to `MAX_TILES` (`tests::stripe_remainders_are_exact`).
const RECIPROCAL_BITS: u32 = 18;
/// The most coding tiles in a stripe: as wide as the widest image.
const MAX_TILES: u32 = 512;
/// Bits of [`StripeWidth`] that hold the tile count.
const TILE_COUNT_BITS: u32 = 10;

impl StripeWidth {
    /// A stripe of `pixels`, if that is a whole number of coding tiles, at most [`MAX_TILES`].
    pub(crate) const fn new(pixels: u32) -> Option<StripeWidth> {
        let tiles = pixels / CODING_TILE;
        if !pixels.is_multiple_of(CODING_TILE) || tiles == 0 || tiles > MAX_TILES {
            return None;
        }
        let reciprocal = crate::format::divide((1u32 << RECIPROCAL_BITS) + tiles - 1, tiles);
        Some(StripeWidth(reciprocal << TILE_COUNT_BITS | tiles))
    }

    /// The width of no stream (before [`Frontier::start`]).
    pub(crate) const NONE: StripeWidth = StripeWidth(0);

    /// `x mod width`, for `x` below 2^16 (`x` for [`StripeWidth::NONE`]). Out of line: it is
    /// called from a few places per leaf, and inlined copies cost more flash than the call
    /// saves time.
    #[inline(never)]
    pub(crate) fn column(self, x: u32) -> u32 {
        let tiles = self.0 & ((1 << TILE_COUNT_BITS) - 1);
        let reciprocal = self.0 >> TILE_COUNT_BITS;
        let tile = (x / CODING_TILE) & (MAX_TILES - 1);
        let quotient = (tile * reciprocal) >> RECIPROCAL_BITS;
        x.wrapping_sub(quotient * tiles * CODING_TILE)
    }
}

/// The side up to which [`Frontier::record`] draws a leaf whole: its four edge strips would
/// tabulate more tiles than the whole leaf (a 16 px leaf is 2 x 2 tiles; its strips cross 8).
pub const RECORD_WHOLE: u32 = 2 * TILE as u32;

/// The decoder's prediction memory: the last pixel decoded in each column of the current
/// stripe and in each row of the current band, for an image of `width x height` coded in
/// stripes of `stripe` pixels; holds stripes of up to `STRIPE` pixels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frontier<const STRIPE: usize = DEFAULT_STRIPE> {
    columns: [u8; STRIPE],
    rows: [u8; CODING_TILE as usize],
    width: u32,
    height: u32,
    stripe: StripeWidth,
    /// The stream's edge-smoothing strength ([`Capture`]).
    deblock: u8,
    /// For each row of a band: whether the pixel `rows` holds is a leaf's bottom-right pixel
    /// that waits with the leaf's bottom row ([`Capture`]).
    corners: [u8; CORNER_BYTES],
}

impl<const STRIPE: usize> Default for Frontier<STRIPE> {
    fn default() -> Self {
        Frontier::EMPTY
    }
}

impl<const STRIPE: usize> Frontier<STRIPE> {
    /// Nothing decoded, for an empty image (all zero bits, like the syntax's contexts before
    /// they start): [`Frontier::start`] sets the size.
    pub const EMPTY: Frontier<STRIPE> = Frontier {
        columns: [0; STRIPE],
        rows: [0; CODING_TILE as usize],
        width: 0,
        height: 0,
        stripe: StripeWidth::NONE,
        deblock: 0,
        corners: [0; CORNER_BYTES],
    };

    /// The widest stripe this frontier holds, pixels.
    pub const CAPACITY: u32 = STRIPE as u32;

    /// Starts a stream of a `width x height` image coded in stripes of `stripe` pixels (a
    /// positive multiple of [`CODING_TILE`]) whose leaf edges are smoothed with strength
    /// `deblock` ([`Capture`]); `false`, and nothing set, when the stripe is not such a
    /// multiple or is wider than this frontier holds. The slots keep what they hold: a slot is
    /// only read once a leaf of the stream has written it ([`beside_known`]).
    pub fn start(&mut self, width: u32, height: u32, stripe: u32, deblock: u8) -> bool {
        let Some(stripe_width) = StripeWidth::new(stripe) else {
            return false;
        };
        if stripe > Self::CAPACITY {
            return false;
        }
        self.width = width;
        self.height = height;
        self.stripe = stripe_width;
        self.deblock = deblock;
        true
    }

    /// [`beside_known`] for this frontier's stream, without a division.
    #[inline]
    fn known(&self, above: bool, x: u32, y: u32) -> bool {
        let size = (self.width, self.height);
        beside_rule(above, (x, y), size, || self.stripe.column(x))
    }

    /// Does for a leaf that is not drawn what drawing it through [`Frontier::capture`] does,
    /// handing `out` the pixels beside the leaf that it draws (see [`Capture`]) and the leaf's
    /// own pixels, for a caller that cuts them away: a leaf of at most [`RECORD_WHOLE`] pixels
    /// a side is drawn whole (all its pixels go to `out`); a larger one has only its edges
    /// rendered from its patch (each pixel once, the first row and column first).
    #[inline(never)]
    pub fn record(&mut self, node: &Node, step: i32, patch: &Patch, out: &mut dyn TileOut) {
        let s = node.size();
        let whole = s <= RECORD_WHOLE;
        // For a leaf drawn whole the leaf, else its first row, its first column below it, its
        // last row right of it and its last column between them; one at a time.
        for part in 0..if whole { 1 } else { 4 } {
            let (x, y, w, h) = match part {
                0 if whole => (node.x, node.y, s, s),
                0 => (node.x, node.y, s, 1),
                1 => (node.x, node.y + 1, 1, s - 1),
                2 => (node.x + 1, node.y + s - 1, s - 1, 1),
                _ => (node.x + s - 1, node.y + 1, 1, s.saturating_sub(2)),
            };
            // Inside the image (an empty part draws nothing).
            let (w, h) = (
                w.min(self.width.saturating_sub(x)),
                h.min(self.height.saturating_sub(y)),
            );
            // A stop is the caller's to report: its own out stops it again.
            let _ = patch.render_to(
                node,
                Rect { x, y, w, h },
                &mut self.capture(node, step, out),
            );
        }
    }

    /// A tile output for drawing the whole leaf `node` (control step `step`) into `out`, in
    /// synthesis order (a tile holding a pixel of the first row or column before any tile
    /// right of or below it in those rows and columns); see [`Capture`].
    pub fn capture<'a>(
        &'a mut self,
        node: &Node,
        step: i32,
        out: &'a mut dyn TileOut,
    ) -> Capture<'a> {
        let last = node.size() - 1;
        let (w, h, stripe) = (self.width, self.height, self.stripe);
        let (right, bottom) = (node.x + last, node.y + last);
        // Without smoothing nothing waits: a pixel is final as synthesised.
        let smoothing = self.deblock > 0;
        let above_known = smoothing && self.known(true, node.x, node.y);
        let left_known = smoothing && self.known(false, node.x, node.y);
        Capture {
            columns: &mut self.columns,
            rows: &mut self.rows,
            corners: &mut self.corners,
            stripe,
            out,
            left: node.x,
            top: node.y,
            right,
            bottom,
            defer_row: smoothing && bottom + 1 < h,
            defer_column: smoothing && right + 1 < w && stripe.column(right + 1) != 0,
            above_known,
            left_known,
            limit: i32::from(self.deblock) * step,
        }
    }
}

/// Draws a leaf's tiles ([`Frontier::capture`]), keeping the frontier, with **deferred edges
/// and edge smoothing**.
///
/// A leaf's bottom row is not drawn with the leaf when a leaf will come below it (it is not on
/// the image's last row): it waits in the frontier and the leaf below draws it; likewise its
/// right column (its bottom pixel excepted when the row waits) when a leaf will come right of
/// it in the stripe. When a leaf is drawn, the waiting pixels above its first row and left of
/// its first column are smoothed with it and drawn: with the stream's strength `d` and the
/// leaf's control step `s` (1/16 grey level), for each such pair of 8-bit pixels, `q` in the
/// leaf (as synthesised) and `p` beside it, with `D = q - p` and `L = d s`: `c = round(|D| /
/// 3)` when `32 |D| <= L`, `c = floor((4 L - 32 |D| + 144) / 288)` when `L < 32 |D| <= 4 L`
/// (tapering from a third of the step to nothing), else none; with `c` given the sign of `D`,
/// `q -= c` and `p += c`, clamped to `0..=255`. Every pixel is drawn once; the frontier holds
/// the smoothed values, which later leaves are predicted from.
pub struct Capture<'a> {
    columns: &'a mut [u8],
    rows: &'a mut [u8; CODING_TILE as usize],
    corners: &'a mut [u8; CORNER_BYTES],
    stripe: StripeWidth,
    out: &'a mut dyn TileOut,
    left: u32,
    top: u32,
    right: u32,
    bottom: u32,
    /// Whether the leaf's bottom row waits for the leaf below.
    defer_row: bool,
    /// Whether the leaf's right column waits for the leaf right of it.
    defer_column: bool,
    above_known: bool,
    left_known: bool,
    /// `d * s`: a step `D` is smoothed by a third when `32 |D|` is at most this, by less up
    /// to [`TAPER`] times it (0: never).
    limit: i32,
}

/// Bytes of [`Frontier`]'s corner bits: one per row of a band.
const CORNER_BYTES: usize = CODING_TILE as usize / 8;

impl core::fmt::Debug for Capture<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Capture")
            .field("right", &self.right)
            .field("bottom", &self.bottom)
            .finish_non_exhaustive()
    }
}

/// How far past the limit edge smoothing reaches, in limits: a step between one and
/// `TAPER` limits is smoothed less the larger it is ([`Capture`]).
const TAPER: i32 = 4;

/// `floor(x / 3)` for `x < 1024` without a division (the Cortex-M0 has no divider and no
/// 64-bit product, so a constant division is a library call there).
#[inline(always)]
fn third(x: u32) -> u32 {
    (x * 683) >> 11
}

/// `floor(x / 288)` (288 = 96 (TAPER - 1)) for `x < 32768`, without a division.
#[inline(always)]
fn over_span(x: u32) -> u32 {
    (x * 7282) >> 21
}

/// The smoothing of one pixel pair across a leaf edge: `(q, p)` corrected, when `D = q - p`
/// is small enough (see [`Capture`]).
#[cfg(target_os = "none")]
#[inline]
fn smooth(q: u8, p: u8, limit: i32) -> Option<(u8, u8)> {
    let d = i32::from(q) - i32::from(p);
    let size = 32 * d.abs();
    let c = if size <= limit {
        third(d.unsigned_abs() + 1) as i32
    } else if size <= TAPER * limit {
        // From a third of the step at the limit down to nothing at TAPER limits: the
        // numerator lies in 144..3 size + 144 (as L < size), below 24 625.
        const SPAN: i32 = 96 * (TAPER - 1);
        over_span((TAPER * limit - size + SPAN / 2) as u32) as i32
    } else {
        return None;
    };
    let c = if d >= 0 { c } else { -c };
    Some((byte(i32::from(q) - c), byte(i32::from(p) + c)))
}

/// [`smooth`] without branches (the steps' sizes are not predictable): both corrections made,
/// one kept, none beyond `TAPER` limits (a pair corrected by nothing is the pair unchanged).
#[cfg(not(target_os = "none"))]
#[inline]
fn smooth(q: u8, p: u8, limit: i32) -> Option<(u8, u8)> {
    let d = i32::from(q) - i32::from(p);
    let size = 32 * d.abs();
    const SPAN: i32 = 96 * (TAPER - 1);
    let within = third(d.unsigned_abs() + 1) as i32;
    let tapered = over_span((TAPER * limit - size + SPAN / 2).max(0) as u32) as i32;
    let c = if size <= limit {
        within
    } else if size <= TAPER * limit {
        tapered
    } else {
        0
    };
    let c = if d >= 0 { c } else { -c };
    Some((byte(i32::from(q) - c), byte(i32::from(p) + c)))
}

/// `q` moved by what smoothing moved `q_before` to `q_new` (a pixel smoothed across both
/// edges moves by both corrections).
#[inline]
fn moved(q: u8, q_before: u8, q_new: u8) -> u8 {
    byte(i32::from(q) + i32::from(q_new) - i32::from(q_before))
}

/// `span[..n] = span[by..]` (`n = span.len() - by`, a tile's row but one: at most 7 bytes):
/// byte by byte on a microcontroller (fewer instructions there: 1–1.6% of a decode on the
/// Cortex-M0 and M3, and 332 B less flash on the M0), by two overlapping moves elsewhere
/// (1.5% of a host decode).
#[inline(always)]
fn move_row_back(span: &mut [u8], by: usize) {
    #[cfg(target_os = "none")]
    {
        // Cells: the span read and written through one shared view, without checks.
        let cells = core::cell::Cell::from_mut(span).as_slice_of_cells();
        for (to, from) in cells.iter().zip(cells.get(by..).unwrap_or_default()) {
            to.set(from.get());
        }
    }
    #[cfg(not(target_os = "none"))]
    {
        const _: () = assert!(TILE <= 8);
        match span.len().saturating_sub(by) {
            1 => move_back::<1>(span, by),
            2..4 => move_back::<2>(span, by),
            _ => move_back::<4>(span, by),
        }
    }
}

/// `span[..n] = span[by..]` (`n = span.len() - by`, from `N` to `2 N` bytes) by its two ends.
#[cfg(not(target_os = "none"))]
#[inline(always)]
fn move_back<const N: usize>(span: &mut [u8], by: usize) {
    let n = span.len().saturating_sub(by);
    if let Some(both) = span.get(by..).and_then(crate::format::ends::<N>) {
        if let Some(to) = span.get_mut(..n) {
            crate::format::put_ends(to, both);
        }
    }
}

impl Capture<'_> {
    /// Keeps the leaf's bottom row and right column, as drawn, in the frontier, from the tile
    /// at `(x, y)`, `w x h`, whose pixels are `buf` (rows by index: cutting `buf` into rows
    /// would divide by `w`, a library call on a Cortex-M0).
    #[inline(always)]
    fn keep_edges(&mut self, x: u32, y: u32, (w, h): (usize, usize), buf: &[u8]) {
        if x + w as u32 - 1 == self.right {
            for j in 0..h {
                let py = y + j as u32;
                let Some(&q) = buf.get(j * w + w - 1) else {
                    break;
                };
                self.rows[(py % CODING_TILE) as usize] = q;
                self.set_corner(py, py == self.bottom && self.defer_row);
            }
        }
        if (y..y + h as u32).contains(&self.bottom) {
            // A byte loop: at most a tile's width, where a `memcpy` call costs more.
            let j = (self.bottom - y) as usize;
            let first = self.stripe.column(x) as usize;
            let (Some(slots), Some(row)) = (
                self.columns.get_mut(first..first + w),
                buf.get(j * w..(j + 1) * w),
            ) else {
                return;
            };
            for (slot, &v) in slots.iter_mut().zip(row) {
                *slot = v;
            }
        }
    }

    /// Whether the frontier's pixel of band row `r` is a leaf's bottom-right pixel that waits
    /// with its row (not with its column).
    fn is_corner(&self, r: u32) -> bool {
        let r = (r % CODING_TILE) as usize;
        self.corners[r / 8] & (1 << (r % 8)) != 0
    }

    fn set_corner(&mut self, r: u32, corner: bool) {
        let r = (r % CODING_TILE) as usize;
        let bit = 1 << (r % 8);
        if corner {
            self.corners[r / 8] |= bit;
        } else {
            self.corners[r / 8] &= !bit;
        }
    }

    /// The tile's part of the first row (`row`, as synthesised) against the waiting pixels
    /// above, which are smoothed, drawn and kept; `row` is smoothed in place.
    fn top_edge(&mut self, x: u32, y: u32, row: &mut [u8]) -> Result<(), Stop> {
        let mut above = [0u8; TILE];
        // A tile lies inside one stripe (stripes are whole coding tiles).
        let first = self.stripe.column(x) as usize;
        for (i, (q, kept)) in row.iter_mut().zip(&mut above).enumerate() {
            let Some(slot) = self.columns.get_mut(first + i) else {
                continue;
            };
            if let Some((q_new, p_new)) = smooth(*q, *slot, self.limit) {
                *q = q_new;
                *slot = p_new;
            }
            *kept = *slot;
        }
        let w = row.len();
        self.out.put(TileMut {
            area: Rect {
                x,
                y: y - 1,
                w: w as u32,
                h: 1,
            },
            pixels: &mut above[..w],
            channels: 1,
        })
    }

    /// The tile's part of the first column (rows `y..y + h`, column 0 of `buf`, `w` wide, as
    /// synthesised but for its first pixel, synthesised as `corner`) against the waiting
    /// pixels left of it, which are smoothed, drawn and kept; a pixel that waits with its row
    /// instead is neither. `buf` is smoothed in place.
    fn left_edge(
        &mut self,
        x: u32,
        y: u32,
        (w, h): (usize, usize),
        buf: &mut [u8],
        corner: u8,
    ) -> Result<(), Stop> {
        let mut beside = [0u8; TILE];
        // The waiting pixels are drawn in runs of rows: a corner pixel (waiting with its row)
        // ends a run.
        let mut start = 0;
        for j in 0..h.min(TILE) {
            let r = y + j as u32;
            if self.is_corner(r) {
                self.put_column(x - 1, (y, start, j), &mut beside)?;
                start = j + 1;
                continue;
            }
            let slot = &mut self.rows[(r % CODING_TILE) as usize];
            let at = j * w;
            let Some(q) = buf.get_mut(at) else {
                break;
            };
            let q_before = if j == 0 { corner } else { *q };
            if let Some((q_new, p_new)) = smooth(q_before, *slot, self.limit) {
                *q = moved(*q, q_before, q_new);
                *slot = p_new;
            }
            beside[j] = *slot;
        }
        self.put_column(x - 1, (y, start, h.min(TILE)), &mut beside)
    }

    /// Draws rows `start..end` of the column `x` of pixels `column` (row 0 at `y`), if any.
    fn put_column(
        &mut self,
        x: u32,
        (y, start, end): (u32, usize, usize),
        column: &mut [u8; TILE],
    ) -> Result<(), Stop> {
        let Some(pixels) = column.get_mut(start..end).filter(|p| !p.is_empty()) else {
            return Ok(());
        };
        self.out.put(TileMut {
            area: Rect {
                x,
                y: y + start as u32,
                w: 1,
                h: pixels.len() as u32,
            },
            pixels,
            channels: 1,
        })
    }

    #[cfg(feature = "smooth-enlarged")]
    /// The pixels waiting beside the leaf above columns `first..` (`above`) or left of rows
    /// `first..` of one coding tile, as many as `run` holds, as the frontier holds them:
    /// before the leaf's tiles there smooth them.
    pub(crate) fn waiting(&self, above: bool, first: u32, run: &mut [u8]) {
        let (slots, at) = if above {
            (&self.columns[..], self.stripe.column(first))
        } else {
            (&self.rows[..], first % CODING_TILE)
        };
        for (p, &slot) in run
            .iter_mut()
            .zip(slots.get(at as usize..).unwrap_or_default())
        {
            *p = slot;
        }
    }
}

impl TileOut for Capture<'_> {
    #[cfg(feature = "deep")]
    fn depth(&self) -> crate::synthesis::Depth {
        self.out.depth()
    }

    /// A 16-bit stream's tile (a stream not smoothed, so nothing waits): the leaf's bottom row
    /// and right column go to the frontier, and the tile goes on whole with its samples.
    #[cfg(feature = "deep")]
    fn put_samples(&mut self, tile: TileMut<'_>, samples: &mut [i16]) -> Result<(), Stop> {
        let Rect { x, y, w, h } = tile.area;
        if x + w - 1 == self.right || (y..y + h).contains(&self.bottom) {
            let n = (w * h) as usize;
            if let Some(buf) = tile.pixels.get(..n).filter(|_| n > 0 && w as usize <= TILE) {
                self.keep_edges(x, y, (w as usize, h as usize), buf);
            }
        }
        self.out.put_samples(tile, samples)
    }

    fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop> {
        let Rect { x, y, w, h } = tile.area;
        let (wu, hu) = (w as usize, h as usize);
        let n = wu * hu;
        let on_right = x + w - 1 == self.right;
        let on_first = (self.above_known && y == self.top) || (self.left_known && x == self.left);
        // Most tiles hold none of the leaf's edges: drawn as they are.
        if !on_right && !on_first && !(y..y + h).contains(&self.bottom) {
            return self.out.put(tile);
        }
        let (Some(buf), true) = (tile.pixels.get_mut(..n), n > 0 && wu <= TILE && hu <= TILE)
        else {
            return Ok(());
        };
        let corner = buf[0];
        if self.above_known && y == self.top {
            if let Some(row) = buf.get_mut(..wu) {
                self.top_edge(x, y, row)?;
            }
        }
        if self.left_known && x == self.left {
            self.left_edge(x, y, (wu, hu), buf, corner)?;
        }
        self.keep_edges(x, y, (wu, hu), buf);
        // The rest of the tile is drawn now.
        let keep_h = hu - usize::from(self.defer_row && y + h - 1 == self.bottom);
        let keep_w = wu - usize::from(self.defer_column && on_right);
        if keep_h == 0 || keep_w == 0 {
            return Ok(());
        }
        if keep_w < wu {
            // Row `j` moves `j` places left (`keep_w = wu - 1`), never onto a later row's
            // unread pixels (a `copy_within` would bring in a general memmove, over a
            // kilobyte of flash).
            for j in 1..keep_h {
                let Some(span) = buf.get_mut(j * keep_w..j * wu + keep_w) else {
                    break;
                };
                move_row_back(span, j);
            }
        }
        let Some(pixels) = buf.get_mut(..keep_w * keep_h) else {
            return Ok(());
        };
        self.out.put(TileMut {
            area: Rect {
                x,
                y,
                w: keep_w as u32,
                h: keep_h as u32,
            },
            pixels,
            channels: 1,
        })
    }
}

impl<const STRIPE: usize> SamplePrediction for Frontier<STRIPE> {
    #[inline]
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
        if !self.known(above, x, y) {
            return None;
        }
        let slot = if above {
            self.columns.get(self.stripe.column(x) as usize)
        } else {
            self.rows.get((y % CODING_TILE) as usize)
        };
        slot.map(|&p| i32::from(p) * SAMPLE_ONE)
    }

    /// The mean pixel by pixel, summed over runs of slots: a leaf lies inside one coding tile,
    /// so the pixels above it are consecutive columns of one stripe and those left of it
    /// consecutive rows of one band (runs end at the tile's edge, which no leaf crosses).
    fn predict(&self, x: u32, y: u32, width: u32) -> (i32, bool) {
        // Known pixels above: in columns inside the image, unless on its top row; left: in
        // rows inside the image, unless on a stripe's left edge.
        let run = |start: u32, end: u32| {
            let in_tile = CODING_TILE - start % CODING_TILE;
            width.min(end.saturating_sub(start)).min(in_tile) as usize
        };
        let column = self.stripe.column(x) as usize;
        let above = if y > 0 && y < self.height {
            run(x, self.width)
        } else {
            0
        };
        let left = if column != 0 && x < self.width {
            run(y, self.height)
        } else {
            0
        };
        let row = (y % CODING_TILE) as usize;
        let above = self.columns.get(column..column + above).unwrap_or_default();
        let left = self.rows.get(row..row + left).unwrap_or_default();
        let sum = |run: &[u8]| run.iter().map(|&p| u32::from(p)).sum::<u32>();
        let total = (sum(above) + sum(left)) * SAMPLE_ONE as u32;
        let count = (above.len() + left.len()) as u32;
        mean_prediction(total, count, !above.is_empty() && !left.is_empty())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deferred column's removal moves each row of up to seven pixels back by its index.
    #[test]
    fn rows_move_back_whole() {
        for n in 1..TILE {
            for by in 1..TILE {
                let mut span: [u8; 2 * TILE] = core::array::from_fn(|i| i as u8 + 1);
                let mut want = span;
                want.copy_within(by..by + n, 0);
                move_row_back(&mut span[..by + n], by);
                assert_eq!(span[..n], want[..n], "{n} pixels back by {by}");
            }
        }
    }

    /// The reciprocal remainder is the remainder for every stripe of whole coding tiles and
    /// every coordinate below 2^16; other widths are refused.
    #[test]
    fn stripe_remainders_are_exact() {
        for tiles in 1..=MAX_TILES {
            let pixels = tiles * CODING_TILE;
            let stripe = StripeWidth::new(pixels).unwrap();
            for x in 0..1u32 << 16 {
                assert_eq!(stripe.column(x), x % pixels, "{tiles} tiles, {x}");
            }
        }
        for pixels in [0, 1, 100, 129, (MAX_TILES + 1) * CODING_TILE] {
            assert_eq!(StripeWidth::new(pixels), None, "{pixels}");
        }
        assert_eq!(StripeWidth::NONE.column(5), 5);
    }
    use crate::model::MODELS;

    /// A bilinear patch with corner values `v` (sample units).
    fn bilinear(v: [i16; 4]) -> Patch {
        let mut control = [0; crate::model::MAX_CONTROL];
        control[..4].copy_from_slice(&v);
        Patch {
            model: MODELS[0],
            control,
        }
    }

    fn node(x: u32, y: u32, log2: u8) -> Node {
        Node { x, y, log2 }
    }

    #[test]
    fn a_leaf_predicts_from_the_pixels_its_neighbours_drew() {
        let mut frontier = Frontier::<256>::EMPTY;
        assert!(
            !frontier.start(300, 200, 384, 0),
            "a stripe wider than the frontier"
        );
        assert!(frontier.start(300, 200, 128, 0));
        let one = SAMPLE_ONE as i16;
        // A 4 px ramp from 0 to 64 grey levels across, at (0, 0): its right column is 48 (the
        // pixel one step short of the corner value 64), its bottom row 0, 16, 32, 48.
        frontier.record(
            &node(0, 0, 2),
            24,
            &bilinear([0, 64 * one, 0, 64 * one]),
            &mut Discard,
        );
        let ramp = |k: i32| 16 * k * SAMPLE_ONE;
        assert_eq!(frontier.above(2, 4), Some(ramp(2)));
        assert_eq!(frontier.left(4, 3), Some(ramp(3)));
        // Leaves at (4, 0) and (0, 4), in Z order, draw the pixels the one at (4, 4) is
        // predicted from.
        frontier.record(&node(4, 0, 2), 24, &bilinear([100 * one; 4]), &mut Discard);
        assert_eq!(frontier.left(8, 1), Some(100 * SAMPLE_ONE));
        assert_eq!(frontier.predict(0, 4, 1), (0, false));
        // A grid transform's low band: the mean along the top edge (the left one is the
        // stripe's edge).
        assert_eq!(frontier.predict(0, 4, 4), (ramp(3) / 2, false));
        frontier.record(&node(0, 4, 2), 24, &bilinear([40 * one; 4]), &mut Discard);
        assert_eq!(frontier.predict(4, 4, 1), (70 * SAMPLE_ONE, true));
        assert_eq!(frontier.predict(4, 4, 4), (70 * SAMPLE_ONE, true));
        // Nothing above the image's top, left of a stripe's edge, or outside the image.
        assert_eq!(frontier.above(2, 0), None);
        assert_eq!(frontier.left(128, 2), None);
        assert_eq!(frontier.left(0, 2), None);
        assert_eq!(frontier.above(300, 4), None);
        // Across a coding tile's top edge (a band's), the previous band's pixels.
        frontier.record(&node(0, 124, 2), 24, &bilinear([77 * one; 4]), &mut Discard);
        assert_eq!(frontier.above(1, 128), Some(77 * SAMPLE_ONE));
        assert_eq!(
            Frontier::<128>::EMPTY.predict(0, 0, 1),
            (128 * SAMPLE_ONE, false)
        );
    }

    /// The frontier's mean over runs of slots is the mean pixel by pixel, for every position
    /// and width inside a coding tile (as every leaf is), at the image's and the stripes' edges
    /// and past them.
    #[test]
    fn run_means_are_the_pixel_means() {
        for (width, height, stripe) in [(300, 200, 128), (256, 130, 256), (77, 45, 128)] {
            let mut frontier = Frontier::<256>::EMPTY;
            assert!(frontier.start(width, height, stripe, 0));
            // Slots of every value, none equal to its neighbour's.
            for (i, slot) in frontier.columns.iter_mut().enumerate() {
                *slot = (i * 37 % 251) as u8;
            }
            for (i, slot) in frontier.rows.iter_mut().enumerate() {
                *slot = (i * 91 % 253) as u8;
            }
            // Leaf corners (multiples of 4) and other positions.
            let some = |v: &u32| v.is_multiple_of(4) || v % 7 == 3;
            for y in (0..height + 2).filter(some) {
                for x in (0..width + 2).filter(some) {
                    for w in [0, 1, 2, 4, 8, 16, 32, 64, 128] {
                        if x % CODING_TILE + w > CODING_TILE || y % CODING_TILE + w > CODING_TILE {
                            continue;
                        }
                        assert_eq!(
                            frontier.predict(x, y, w),
                            predict_by_pixels(&frontier, x, y, w),
                            "{width}x{height} in stripes of {stripe}: ({x}, {y}), width {w}"
                        );
                    }
                }
            }
        }
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

    /// Edge smoothing: a step across a leaf's top edge within the limit moves both pixels a
    /// third of the way; one up to four limits by less; a larger one is left alone; the
    /// corrected pixel above is remembered and drawn again.
    #[test]
    fn small_steps_across_an_edge_are_smoothed() {
        struct Collect(std::vec::Vec<(Rect, std::vec::Vec<u8>)>);
        impl TileOut for Collect {
            fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop> {
                self.0.push((tile.area, tile.pixels.to_vec()));
                Ok(())
            }
        }
        extern crate std;
        let one = SAMPLE_ONE as i16;
        // A flat leaf of grey `value` (step 64) drawn through the frontier: what it hands out.
        let draw = |frontier: &mut Frontier<128>, leaf: Node, value: i16| {
            let mut out = Collect(std::vec::Vec::new());
            bilinear([value * one; 4])
                .render_to(
                    &leaf,
                    leaf.rect(),
                    &mut frontier.capture(&leaf, 64, &mut out),
                )
                .unwrap();
            out
        };
        // Strength 4 with a step of 64 (4 grey levels): steps up to 4 * 64 / 32 = 8 grey by a
        // third, up to 32 grey by less.
        let mut frontier = Frontier::<128>::EMPTY;
        assert!(frontier.start(16, 16, 128, 4));
        frontier.record(&node(0, 0, 2), 64, &bilinear([100 * one; 4]), &mut Discard);
        frontier.record(&node(4, 0, 2), 64, &bilinear([100 * one; 4]), &mut Discard);
        // Below the first: 106 (a step of 6, smoothed by 2 each side); below the second: 120
        // (a step of 20: (4 * 256 - 640 + 144) / 288 = 1 each side).
        let out = draw(&mut frontier, node(0, 4, 2), 106);
        let above = out
            .0
            .iter()
            .find(|(a, _)| a.y == 3)
            .expect("the row above, again");
        assert_eq!(above.1, std::vec![102; 4]);
        // The leaf's right column waits for the leaf right of it: three pixels a row now.
        let first_row = out.0.iter().find(|(a, _)| a.y == 4).expect("the leaf");
        assert_eq!(first_row.0.w, 3);
        assert_eq!(first_row.1[..3], [104; 3]);
        // The frontier now holds the leaf's own bottom row.
        assert_eq!(frontier.above(1, 8), Some(106 * SAMPLE_ONE));
        let out = draw(&mut frontier, node(4, 4, 2), 120);
        let tile = out
            .0
            .iter()
            .find(|(a, _)| a.y == 4 && a.x == 4)
            .expect("the leaf");
        // Its corner also meets the 106 left of it (a step of 14: 2 each side).
        assert_eq!(tile.1[..3], [117, 119, 119], "a step of 20 is softened");
        // Past four limits (32 grey levels) a step is an edge, not a seam.
        assert_eq!(smoothed(140, 107, 256), (140, 107));
        assert_eq!(smoothed(139, 107, 256), (139, 107));
        assert_eq!(smoothed(107, 140, 256), (107, 140));
        // The taper starts where the third ends: a step of 9 moves by 3 either way.
        assert_eq!(smoothed(109, 100, 256), (106, 103));
        assert_eq!(smoothed(100, 109, 256), (103, 106));
        assert_eq!(smoothed(108, 100, 256), (105, 103));
    }

    /// The pair `(q, p)` after smoothing (`smooth` may say "unchanged" by `None`).
    fn smoothed(q: u8, p: u8, limit: i32) -> (u8, u8) {
        smooth(q, p, limit).unwrap_or((q, p))
    }

    /// The division-free smoothing is the specification's formula, with its divisions, for
    /// every pixel pair and every strength times every step a stream can give.
    #[test]
    fn smoothing_without_division_is_the_formula() {
        let reference = |q: u8, p: u8, limit: i32| {
            let d = i32::from(q) - i32::from(p);
            let size = 32 * d.abs();
            let c = if size <= limit {
                (d.abs() + 1) / 3
            } else if size <= 4 * limit {
                (4 * limit - size + 144) / 288
            } else {
                return None;
            };
            let c = if d >= 0 { c } else { -c };
            Some((
                (i32::from(q) - c).clamp(0, 255) as u8,
                (i32::from(p) + c).clamp(0, 255) as u8,
            ))
        };
        let reference = |q, p, limit| reference(q, p, limit).unwrap_or((q, p));
        // Strengths up to 16 times steps up to 2048 (multiples of 8): every step size at
        // each limit, from pairs at both ends of the range; every pair at a few limits.
        for limit in (0..=16 * 2048).step_by(8) {
            for d in 0..=255u8 {
                for (q, p) in [(d, 0), (0, d), (255, 255 - d), (255 - d, 255)] {
                    assert_eq!(
                        smoothed(q, p, limit),
                        reference(q, p, limit),
                        "{q} {p} {limit}"
                    );
                }
            }
        }
        for limit in [0, 24, 256, 1000, 4096, 32768] {
            for q in 0..=255u8 {
                for p in 0..=255u8 {
                    assert_eq!(
                        smoothed(q, p, limit),
                        reference(q, p, limit),
                        "{q} {p} {limit}"
                    );
                }
            }
        }
        assert!((0..32768).all(|x| over_span(x) == x / 288));
        assert!((0..1024).all(|x| third(x) == x / 3));
    }

    /// The edge context's step count is `min(change / step, 2)`.
    #[test]
    fn edge_context_counts_steps_without_division() {
        for step in [-3, 0, 1, 2, 3, 7, 16, 100, 4096] {
            for change in 0..20_000 {
                let steps = (change as u32 / step.max(1) as u32).min(2) as usize;
                assert_eq!(
                    edge_context(5, change, 0, step),
                    2 + steps,
                    "{change} {step}"
                );
                assert_eq!(
                    edge_context(5, 0, change, step),
                    2 + steps,
                    "{change} {step}"
                );
            }
        }
    }
}
