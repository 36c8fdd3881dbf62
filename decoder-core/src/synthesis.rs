//! Patch synthesis: exact tabulation of a projected-IFS patch by recursive subdivision, in
//! integer arithmetic that is bit-exact on every platform.
//!
//! Values are samples in 1/16 grey level ([`SAMPLE_ONE`]); weights are in 1/4096
//! ([`WEIGHT_ONE`]). Every new point is `(sum(tap * value) + 2048) >> 12` (arithmetic shift),
//! clamped to `[SAMPLE_MIN, SAMPLE_MAX]`. The sum of tap magnitudes of a rule ([`Rules`]) is at
//! most `6144`, and `6144 * 8192 < 2^31`, so the accumulation never overflows an `i32`.
//!
//! The subdivision refines the control grid level by level: each level's points are the last
//! one's refined by `N` along the rows (the line rule of each phase on the four points around
//! an interval, mirrored at the ends of its block of `m` intervals: the child grids of the
//! subdivision side by side), then across them (the same rule on four refined rows). A leaf
//! is drawn in strips of a tile's width, each from top to bottom: a level's rows are made
//! only as the level below needs them, and each level keeps its last four rows (refined
//! along the row, over the strip's columns and the taps around them), so memory is four
//! short rows a level, independent of the leaf's size ([`Pipeline`]).
//!
//! A patch can also be drawn at a [`Scale`] other than the coded size: smaller by stopping the
//! subdivision earlier (pixel `(X, Y)` of a decode at `1/2^k` is pixel `(X 2^k, Y 2^k)` of the
//! full decode, exactly), larger by letting it go on below the pixel (pixel `(X, Y)` of a decode
//! at `2^k` is the patch's point at `(X / 2^k, Y / 2^k)`).

use crate::format::SampleRange;
use crate::format::MAX_LEAF_LOG2;
use crate::geometry::{Node, Rect};
use crate::model::{ModelType, MAX_CONTROL, SAMPLE_BITS, SAMPLE_MAX, SAMPLE_MIN};
#[cfg(doc)]
use crate::model::{Rules, SAMPLE_ONE, WEIGHT_ONE};

/// Side of the tiles handed to a [`PixelSink`].
pub const TILE: usize = 8;

/// Refinement levels from a leaf's control grid to its pixels at the coded size, at most: a
/// leaf of the largest size with one interval and two transforms (the bilinear model) has one
/// per halving of its 128 px.
const LEVELS: usize = MAX_LEAF_LOG2 as usize;

/// The same for decodes at up to four times the coded size ([`Scale::Quadruple`]).
const LEVELS_LARGE: usize = LEVELS + 2;

/// What a rendering makes: 8-bit pixels, or the pixels and their samples (1/16 grey level,
/// before rounding), which a 16-bit stream's values are made from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Depth {
    /// Pixels only (an 8-bit stream).
    #[default]
    Pixels,
    /// Pixels and their samples (a 16-bit stream).
    Samples,
}

/// The output size of a decode relative to the coded image. Smaller decodes stop the
/// subdivision earlier: pixel `(X, Y)` of a decode at `1/2^k` is pixel `(X 2^k, Y 2^k)` of the
/// full decode (so a leaf smaller than `2^k` pixels draws its top-left control value if that
/// pixel is one of those, else nothing). Larger decodes continue the subdivision below the
/// pixel: pixel `(X, Y)` of a decode at `2^k` is the patch's value at `(X / 2^k, Y / 2^k)` (the
/// fractal detail of the patches at half or quarter pixels). An image of `w x h` pixels decodes
/// to `ceil(w s) x ceil(h s)` ([`Scale::apply`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Scale {
    /// One eighth of the coded size.
    Eighth,
    /// One quarter.
    Quarter,
    /// One half.
    Half,
    /// The coded size.
    #[default]
    One,
    /// Twice the coded size.
    Double,
    /// Four times the coded size.
    Quadruple,
}

impl Scale {
    /// Every scale, smallest first.
    pub const ALL: [Scale; 6] = [
        Scale::Eighth,
        Scale::Quarter,
        Scale::Half,
        Scale::One,
        Scale::Double,
        Scale::Quadruple,
    ];

    /// The scale as a power of two: -3 for [`Scale::Eighth`] up to 2 for [`Scale::Quadruple`].
    pub const fn log2(self) -> i32 {
        match self {
            Scale::Eighth => -3,
            Scale::Quarter => -2,
            Scale::Half => -1,
            Scale::One => 0,
            Scale::Double => 1,
            Scale::Quadruple => 2,
        }
    }

    /// The scale `2^log2`, if there is one.
    pub const fn from_log2(log2: i32) -> Option<Scale> {
        match log2 {
            -3 => Some(Scale::Eighth),
            -2 => Some(Scale::Quarter),
            -1 => Some(Scale::Half),
            0 => Some(Scale::One),
            1 => Some(Scale::Double),
            2 => Some(Scale::Quadruple),
            _ => None,
        }
    }

    /// A length of the coded image at this scale, rounded up: `ceil(length * s)`.
    pub const fn apply(self, length: u32) -> u32 {
        let k = self.log2();
        if k >= 0 {
            length << k
        } else {
            let k = -k as u32;
            (length >> k) + (length & ((1 << k) - 1) != 0) as u32
        }
    }
}

/// A rectangle of decoded pixels, handed to a [`PixelSink`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct Tile<'a> {
    /// Where the pixels go, in image coordinates (at most [`TILE`] x [`TILE`]).
    pub area: Rect,
    /// Row-major pixels: 8-bit luma (`channels == 1`, `area.w * area.h` values) or RGB
    /// triples (`channels == 3`, `3 * area.w * area.h` values: a colour stream).
    pub pixels: &'a [u8],
    /// Values per pixel: 1 (gray) or 3 (RGB).
    pub channels: u8,
    /// A 16-bit stream's values for the same pixels, in the data's units (its header's
    /// [`SampleRange`](crate::SampleRange)); empty for an 8-bit stream, whose `pixels` are the
    /// data. A 16-bit stream's `pixels` are its values mapped onto grey by that range.
    pub values: &'a [u16],
}

/// Receives decoded pixels, one [`Tile`] at a time, in the order the decoder makes them. A sink
/// that fails (a display bus error, a full disk) returns its error, and decoding stops there.
pub trait PixelSink {
    /// Why the sink can fail ([`core::convert::Infallible`] when it cannot).
    type Error;

    /// Takes the pixels of one tile.
    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Self::Error>;
}

impl<S: PixelSink + ?Sized> PixelSink for &mut S {
    type Error = S::Error;

    #[inline]
    fn tile(&mut self, tile: Tile<'_>) -> Result<(), S::Error> {
        (**self).tile(tile)
    }
}

/// A sink refused a tile: synthesis stops. The sink's own error is kept by [`Catch`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stop;

/// Where synthesis delivers tiles, as a trait object: one copy of the synthesis serves every
/// sink (the caller's, the prediction frontier's), which matters more on a microcontroller's
/// flash than a call per tile does.
pub trait TileOut {
    /// Takes one tile; [`Stop`] ends the synthesis.
    fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop>;

    /// Takes one tile of a 16-bit stream with its pixels' `samples` (1/16 grey level, before
    /// their rounding; laid out as the pixels). An output that does not carry samples on
    /// takes the pixels alone.
    fn put_samples(&mut self, tile: TileMut<'_>, samples: &mut [i16]) -> Result<(), Stop> {
        let _ = samples;
        self.put(tile)
    }

    /// What the output wants made: pixels, or pixels and their samples (for a 16-bit
    /// stream's sink). An output that passes tiles on asks the one it passes them to.
    fn depth(&self) -> Depth {
        Depth::Pixels
    }
}

/// A tile on its way through the decoder's own outputs ([`TileOut`]): a [`Tile`] whose pixels
/// are scratch, so that an output that corrects or cuts them does it in place, without a
/// buffer of its own.
#[derive(Debug)]
pub struct TileMut<'a> {
    /// Where the pixels go, as [`Tile::area`].
    pub area: Rect,
    /// Row-major pixels, as [`Tile::pixels`].
    pub pixels: &'a mut [u8],
    /// Values per pixel: 1 (gray) or 3 (RGB).
    pub channels: u8,
}

impl TileMut<'_> {
    /// The tile as a [`PixelSink`] takes it, with `values` (empty for an 8-bit stream).
    #[inline]
    pub fn tile<'t>(&'t self, values: &'t [u16]) -> Tile<'t> {
        Tile {
            area: self.area,
            pixels: self.pixels,
            channels: self.channels,
            values,
        }
    }
}

/// Takes every tile and keeps nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Discard;

impl TileOut for Discard {
    fn put(&mut self, _tile: TileMut<'_>) -> Result<(), Stop> {
        Ok(())
    }
}

/// A [`PixelSink`] seen as a [`TileOut`]: keeps the sink's first error for [`Catch::finish`],
/// and maps a 16-bit stream's samples onto its values.
pub struct Catch<'s, S: PixelSink + ?Sized> {
    sink: &'s mut S,
    error: Option<S::Error>,
    #[cfg_attr(not(feature = "deep"), allow(dead_code))]
    range: Option<SampleRange>,
}

impl<'s, S: PixelSink + ?Sized> Catch<'s, S> {
    /// Wraps `sink`.
    pub fn new(sink: &'s mut S) -> Self {
        Catch {
            sink,
            error: None,
            range: None,
        }
    }

    /// Wraps `sink`, mapping the samples of tiles that carry them onto `range` (a 16-bit
    /// stream's [`Header::range`](crate::Header::range)).
    pub fn with_range(sink: &'s mut S, range: Option<SampleRange>) -> Self {
        Catch {
            sink,
            error: None,
            range,
        }
    }

    /// The sink's first error, if it failed (and synthesis stopped for it).
    pub fn finish(self) -> Result<(), S::Error> {
        match self.error {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

impl<S: PixelSink + ?Sized> core::fmt::Debug for Catch<'_, S> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Catch")
            .field("failed", &self.error.is_some())
            .finish_non_exhaustive()
    }
}

impl<S: PixelSink + ?Sized> TileOut for Catch<'_, S> {
    #[inline]
    fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop> {
        if self.error.is_some() {
            return Err(Stop);
        }
        self.sink.tile(tile.tile(&[])).map_err(|e| {
            self.error = Some(e);
            Stop
        })
    }

    #[cfg(feature = "deep")]
    fn depth(&self) -> Depth {
        match self.range {
            Some(_) => Depth::Samples,
            None => Depth::Pixels,
        }
    }

    /// With a range (a 16-bit stream's), the sink gets the tile's values too.
    #[cfg(feature = "deep")]
    fn put_samples(&mut self, tile: TileMut<'_>, samples: &mut [i16]) -> Result<(), Stop> {
        let Some(range) = self.range else {
            return self.put(tile);
        };
        if self.error.is_some() {
            return Err(Stop);
        }
        let mut values = [0u16; TILE * TILE];
        let n = to_values(&mut values, samples, range);
        self.sink.tile(tile.tile(&values[..n])).map_err(|e| {
            self.error = Some(e);
            Stop
        })
    }
}

/// `values[i]` = the value of `samples[i]` in `range`; returns how many were made (at most a
/// tile's).
#[cfg(feature = "deep")]
#[inline(never)]
fn to_values(values: &mut [u16; TILE * TILE], samples: &[i16], range: SampleRange) -> usize {
    for (v, &s) in values.iter_mut().zip(samples) {
        *v = range.value(s);
    }
    samples.len().min(TILE * TILE)
}

/// A reconstructed patch: a model type (its subdivision rules are the model's, [`Rules`]) and
/// its control values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
// The control values first, word-aligned: a new patch is cleared by the word-aligned routine
// the decoder uses anyway, not by a second, bytewise one.
#[repr(C, align(4))]
pub struct Patch {
    /// Control values, row-major, `model.grid()` per row, in sample units.
    pub control: [i16; MAX_CONTROL],
    /// The model type.
    pub model: ModelType,
}

impl Default for Patch {
    /// [`Patch::CLEARED`].
    fn default() -> Self {
        Patch::CLEARED
    }
}

/// Converts a sample value to an 8-bit pixel (round to nearest, saturate).
#[inline]
pub fn sample_to_pixel(v: i32) -> u8 {
    crate::format::byte((v + (1 << (SAMPLE_BITS - 1))) >> SAMPLE_BITS)
}

/// How a rule's new point is made from the four values its taps weigh.
trait Rule: Copy {
    /// The new point from the values of the points its taps weigh.
    fn apply(self, a: i16, b: i16, c: i16, d: i16) -> i16;

    /// The new point as an 8-bit pixel: [`sample_to_pixel`] of [`Rule::apply`], in one
    /// rounding (the clamp to the sample range cannot change a pixel).
    fn pixel(self, a: i16, b: i16, c: i16, d: i16) -> u8;
}

/// A line rule of the models ([`Rules`]) with its taps as constants: `(A a + B b + C c + D d)`
/// in units of `2^-SHIFT`, equal to the taps in 1/4096 divided by `2^(12 - SHIFT)`, so that
/// `(sum + 2^(SHIFT-1)) >> SHIFT` is exactly `(sum of tap * value + 2048) >> 12`. Constant
/// small taps compile to shifts and adds (or a multiply by an immediate), with no tap loads:
/// the rules are fixed by the format (`line_rules_are_the_models`).
#[derive(Clone, Copy, Default)]
struct Line<const A: i32, const B: i32, const C: i32, const D: i32, const SHIFT: u32>;

/// The midpoint rule, `(-1, 5, 5, -1) / 8` (phase 1 of 2, phase 2 of 4).
type Half = Line<{ -1 }, 5, 5, { -1 }, 3>;
/// Phase 1 of 4: `(-7, 57, 19, -5) / 64`.
type Quarter = Line<{ -7 }, 57, 19, { -5 }, 6>;
/// Phase 3 of 4: `(-5, 19, 57, -7) / 64`.
type ThreeQuarters = Line<{ -5 }, 19, 57, { -7 }, 6>;

impl<const A: i32, const B: i32, const C: i32, const D: i32, const SHIFT: u32>
    Line<A, B, C, D, SHIFT>
{
    /// The weighted sum of the four values (it cannot overflow: the taps' magnitudes sum to
    /// at most 96 and values fit 16 bits).
    #[inline(always)]
    fn sum(a: i16, b: i16, c: i16, d: i16) -> i32 {
        A * i32::from(a) + B * i32::from(b) + C * i32::from(c) + D * i32::from(d)
    }
}

impl<const A: i32, const B: i32, const C: i32, const D: i32, const SHIFT: u32> Rule
    for Line<A, B, C, D, SHIFT>
{
    #[inline(always)]
    fn apply(self, a: i16, b: i16, c: i16, d: i16) -> i16 {
        clamp_sample((Self::sum(a, b, c, d) + (1 << (SHIFT - 1))) >> SHIFT)
    }

    #[inline(always)]
    fn pixel(self, a: i16, b: i16, c: i16, d: i16) -> u8 {
        // floor((floor((s + 2^(SHIFT-1)) / 2^SHIFT) + 8) / 16)
        //   = floor((s + 2^(SHIFT-1) + 8 * 2^SHIFT) / 2^(SHIFT+4))
        crate::format::byte(
            (Self::sum(a, b, c, d) + (1 << (SHIFT - 1)) + (8 << SHIFT)) >> (SHIFT + 4),
        )
    }
}

/// `v` clamped to the sample range (which fits an `i16`): one unsigned compare when it is in
/// range, as it nearly always is.
#[inline(always)]
fn clamp_sample(v: i32) -> i16 {
    if (v.wrapping_sub(SAMPLE_MIN) as u32) <= (SAMPLE_MAX - SAMPLE_MIN) as u32 {
        v as i16
    } else {
        saturate(v)
    }
}

/// [`clamp_sample`] of a value out of range.
#[cold]
#[inline(never)]
fn saturate(v: i32) -> i16 {
    if v < 0 {
        SAMPLE_MIN as i16
    } else {
        SAMPLE_MAX as i16
    }
}

/// What a tile's rows are made of: 8-bit pixels, or samples (a child grid's, or a 16-bit
/// stream's tile, made pixels by [`Job::put`]). The choice is made once per tile
/// ([`with_rows!`]), so that the loops over rows and pixels are the same as without it.
trait Point: Copy {
    /// The point a sample makes.
    fn of(v: i16) -> Self;

    /// `out[i] = rule(a[i], b[i], c[i], d[i])` for every `i` of `out` (at most a [`Row`]): a
    /// new row from four old rows.
    fn across<R: Rule>(rule: R, out: &mut [Self], from: [&Row; 4]);

    /// `out[i]` = the point of `src[i]` for every `i` of `out`.
    fn take(out: &mut [Self], src: &[i16]);
}

impl Point for u8 {
    #[inline(always)]
    fn of(v: i16) -> u8 {
        sample_to_pixel(i32::from(v))
    }

    #[inline(never)]
    fn across<R: Rule>(rule: R, out: &mut [u8], [a, b, c, d]: [&Row; 4]) {
        for (i, p) in out.iter_mut().enumerate() {
            let i = i % STRIP;
            *p = rule.pixel(a[i], b[i], c[i], d[i]);
        }
    }

    #[inline(always)]
    fn take(out: &mut [u8], src: &[i16]) {
        to_pixels(out, src);
    }
}

impl Point for i16 {
    #[inline(always)]
    fn of(v: i16) -> i16 {
        v
    }

    #[inline(never)]
    fn across<R: Rule>(rule: R, out: &mut [i16], [a, b, c, d]: [&Row; 4]) {
        for (i, v) in out.iter_mut().enumerate() {
            let i = i % STRIP;
            *v = rule.apply(a[i], b[i], c[i], d[i]);
        }
    }

    #[inline(always)]
    fn take(out: &mut [i16], src: &[i16]) {
        copy_short(out, src);
    }
}

/// `out[i] = sample_to_pixel(src[i])` for every `i` of `out`.
#[inline(never)]
fn to_pixels(out: &mut [u8], src: &[i16]) {
    for (p, &v) in out.iter_mut().zip(src) {
        *p = sample_to_pixel(i32::from(v));
    }
}

/// Runs `$body` with `$rows` bound to the buffer the tile being made goes to (its samples
/// for a 16-bit stream, else its pixels), a slice of a [`Point`] type: the choice made once
/// per tile.
macro_rules! with_rows {
    ($job:expr, |$rows:ident| $body:expr) => {{
        #[cfg(feature = "deep")]
        let made = match $job.samples.as_deref_mut() {
            Some(samples) => {
                let $rows: &mut [i16] = samples;
                $body
            }
            None => {
                let $rows: &mut [u8] = &mut $job.pixels;
                $body
            }
        };
        #[cfg(not(feature = "deep"))]
        let made = {
            let $rows: &mut [u8] = &mut $job.pixels;
            $body
        };
        made
    }};
}

/// Copies `src` into `dst` (as much as both hold) one value at a time: for the short rows
/// here a call to `memcpy` costs more than the copy (the compiler fence, which emits nothing,
/// keeps the loop from becoming one).
#[inline(always)]
fn copy_short(dst: &mut [i16], src: &[i16]) {
    for (d, &s) in dst.iter_mut().zip(src) {
        *d = s;
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
    }
}

/// Output columns of a strip of [`Patch::strips`]: a tile's width.
const STRIP: usize = TILE;

/// A row of a strip at one level: at most [`STRIP`] points (a level's points under a strip
/// of `STRIP` pixels, with the taps around them, are never more).
type Row = [i16; STRIP];

/// A level's last four rows: row `i` in slot `i % 4`.
type Ring = [Row; 4];

/// Samples of a [`Ring`].
const RING: usize = 4 * STRIP;

/// A line of a level refined by `2^rho` (a row or a column; blocks of `m` intervals): the
/// interval `k` of its point `j` and `j`'s phase `o` in it (`0`: an old point).
#[inline(always)]
fn interval(j: usize, rho: u32) -> (usize, usize) {
    (j >> rho, j & ((1 << rho) - 1))
}

/// The last point of a line that point `j` of its refinement is made from.
#[inline(always)]
fn last_tap(j: usize, rho: u32, m: usize) -> usize {
    let (k, o) = interval(j, rho);
    if o == 0 {
        k
    } else if k & (m - 1) == m - 1 {
        k + 1
    } else {
        k + 2
    }
}

/// The row at phase `o` (`1 ..`) of interval `k` between the rows of `ring` (a line of rows
/// refined by `2^rho`, in blocks of `m` intervals), into `out`: the line rule of the phase
/// on the rows `k - 1 ..= k + 2`, mirrored at the ends of the block.
#[inline(always)]
fn new_row<P: Point>(out: &mut [P], ring: &Ring, (k, o): (usize, usize), rho: u32, m: usize) {
    let last = m - 1;
    let a = k & last;
    let before = if a == 0 { k + 1 } else { k.wrapping_sub(1) };
    let after = if a == last { k } else { k + 2 };
    let rows = [
        &ring[before % 4],
        &ring[k % 4],
        &ring[(k + 1) % 4],
        &ring[after % 4],
    ];
    if rho == 1 || o == 2 {
        P::across(Half::default(), out, rows)
    } else if o == 1 {
        P::across(Quarter::default(), out, rows)
    } else {
        let [r0, r1, r2, r3] = rows;
        // The phase-3-of-4 rule is the phase-1 rule on the rows in reverse.
        P::across(Quarter::default(), out, [r3, r2, r1, r0])
    }
}

/// Points `lo1 .. lo1 + n` of a line refined by `2^rho` into `out`, from its points `lo0 ..`
/// in `line`: the old points copied, the new ones made by the line rule of their phase from
/// the four points around them, mirrored at the ends of their block of `m` intervals (as
/// [`crate::model::tap_point`]). The points a strip needs are never more than a [`Row`], so
/// an index into one is taken modulo its length (no bounds to check; a mirrored tap's
/// unneeded neighbour may wrap, and is not used).
#[inline(always)]
fn refine_line(
    line: &Row,
    lo0: usize,
    out: &mut Row,
    (lo1, n): (usize, usize),
    rho: u32,
    m: usize,
) {
    if rho == 1 {
        halve_line(line, lo0, out, (lo1, n), m);
    } else {
        quarter_line(line, lo0, out, (lo1, n), m);
    }
}

/// [`refine_line`] by 2: each interval's old point and midpoint; blocks of one interval (the
/// bilinear model) by a loop of their own, the kernel compiled for blocks of two intervals (so
/// that their alternating taps are constants) and once for the longer blocks, whose length `m`
/// (4 or 8) is a variable: a copy for each cost 0.6 KiB of flash for 1% of the instructions.
#[inline(always)]
fn halve_line(line: &Row, lo0: usize, out: &mut Row, points: (usize, usize), m: usize) {
    match m {
        1 => halve_intervals(line, lo0, out, points),
        2 => halve_blocks::<2>(line, lo0, out, points, 2),
        _ => halve_blocks::<4>(line, lo0, out, points, m),
    }
}

/// [`halve_line`] for blocks of one interval (the bilinear model): each interval's old point
/// and midpoint, `(p1 + p2 + 1) >> 1` (the line rule with both taps mirrored), each point of
/// `line` read once.
#[inline(never)]
fn halve_intervals(line: &Row, lo0: usize, out: &mut Row, (lo1, n): (usize, usize)) {
    let at = |k: usize| i32::from(line[k.wrapping_sub(lo0) % STRIP]);
    let mut k = lo1 >> 1;
    let mut p = at(k);
    let mut odd = lo1 & 1 == 1;
    for v in out.iter_mut().take(n) {
        if odd {
            k += 1;
            let q = at(k);
            *v = ((p + q + 1) >> 1) as i16;
            p = q;
        } else {
            *v = p as i16;
        }
        odd = !odd;
    }
}

/// [`halve_line`] for blocks of `m` intervals (`M` when it is 2; `M` is 4 for every longer
/// block): whole blocks (or four intervals of a longer block) at a time where the strip holds
/// them, their taps and mirrors fixed; else an interval at a time.
#[inline(never)]
fn halve_blocks<const M: usize>(
    line: &Row,
    lo0: usize,
    out: &mut Row,
    (lo1, n): (usize, usize),
    m: usize,
) {
    let m = if M == 2 { M } else { m.max(M) };
    let at = |k: usize| line[k.wrapping_sub(lo0) % STRIP];
    let half = |p0: i16, p1: i16, p2: i16, p3: i16| Half::default().apply(p0, p1, p2, p3);
    // The midpoint of interval `k`, its taps mirrored at the ends of its block.
    let midpoint = |k: usize| {
        let a = k & (m - 1);
        let (p1, p2) = (at(k), at(k + 1));
        let p0 = if a == 0 { p2 } else { at(k.wrapping_sub(1)) };
        let p3 = if a == m - 1 { p1 } else { at(k + 2) };
        half(p0, p1, p2, p3)
    };
    let n = n.min(STRIP);
    let mut i = 0;
    if lo1 & 1 == 1 && n > 0 {
        out[0] = midpoint(lo1 >> 1);
        i = 1;
    }
    while i < n {
        let b = (lo1 + i) >> 1;
        if M == 2 && b % 2 == 0 && i + 4 <= n {
            // A whole block: points b ..= b + 2 of the line.
            let (v0, v1, v2) = (at(b), at(b + 1), at(b + 2));
            out[i % STRIP] = v0;
            out[(i + 1) % STRIP] = half(v1, v0, v1, v2);
            out[(i + 2) % STRIP] = v1;
            out[(i + 3) % STRIP] = half(v0, v1, v2, v1);
            i += 4;
        } else if M >= 4 && b % 4 == 0 && i + 8 <= n {
            // Four intervals of a block: points b - 1 ..= b + 5, mirrored at the block's ends.
            let (v0, v1, v2, v3, v4) = (at(b), at(b + 1), at(b + 2), at(b + 3), at(b + 4));
            let before = if b & (m - 1) == 0 {
                v1
            } else {
                at(b.wrapping_sub(1))
            };
            let after = if (b + 3) & (m - 1) == m - 1 {
                v3
            } else {
                at(b + 5)
            };
            out[i % STRIP] = v0;
            out[(i + 1) % STRIP] = half(before, v0, v1, v2);
            out[(i + 2) % STRIP] = v1;
            out[(i + 3) % STRIP] = half(v0, v1, v2, v3);
            out[(i + 4) % STRIP] = v2;
            out[(i + 5) % STRIP] = half(v1, v2, v3, v4);
            out[(i + 6) % STRIP] = v3;
            out[(i + 7) % STRIP] = half(v2, v3, v4, after);
            i += 8;
        } else {
            out[i % STRIP] = at(b);
            if i + 1 < n {
                out[(i + 1) % STRIP] = midpoint(b);
            }
            i += 2;
        }
    }
}

/// [`refine_line`] by 4: each interval's old point and its points at a quarter, a half and
/// three quarters (the rules' loop over a whole interval), the points around an interval
/// sliding along the line, one read per interval.
#[inline(never)]
fn quarter_line(line: &Row, lo0: usize, out: &mut Row, (lo1, n): (usize, usize), m: usize) {
    let last = m - 1;
    let at = |j: usize| line[j % STRIP];
    let k = lo1 >> 2;
    let mut a = k & last;
    let mut j = k.wrapping_sub(lo0);
    let (mut w0, mut w1, mut w2) = (at(j.wrapping_sub(1)), at(j), at(j.wrapping_add(1)));
    let mut out = out.iter_mut().take(n);
    let mut o = lo1 & 3;
    loop {
        let w3 = at(j.wrapping_add(2));
        let p0 = if a == 0 { w2 } else { w0 };
        let p3 = if a == last { w1 } else { w3 };
        let points = [
            w1,
            Quarter::apply(Line, p0, w1, w2, p3),
            Half::apply(Line, p0, w1, w2, p3),
            ThreeQuarters::apply(Line, p0, w1, w2, p3),
        ];
        for &p in points.get(o..).unwrap_or(&[]) {
            let Some(v) = out.next() else {
                return;
            };
            *v = p;
        }
        o = 0;
        (w0, w1, w2) = (w1, w2, w3);
        j = j.wrapping_add(1);
        a = (a + 1) & last;
    }
}

/// The rows of one strip of a leaf, made level by level from its control grid as the rows
/// below need them: level `l + 1`'s points are level `l`'s refined by `N` (the last level
/// by `N` or less, down to one pixel apart), each block of `m` intervals of a level refined
/// on its own, mirrored at its ends (the child grids of the subdivision side by side). Each
/// level keeps its last four rows, refined along the row to the next level's columns: a
/// row of the next level is one of them, or the column (and cell) rule across four.
struct Pipeline<'a> {
    /// The control grid, row-major, `m + 1` values a row.
    control: &'a [i16],
    /// Intervals of a block (the model's).
    m: usize,
    /// Refinements from the control grid to the pixels.
    levels: usize,
    /// Per level (`0..=levels`, the last the pixels): `log2` of the refinement to the next
    /// level (`log2 N`, the last one `log2 N` or less).
    rho: [u8; LEVELS_LARGE + 1],
    /// Per level: the first and last columns the strip needs, in the level's points.
    lo: [u16; LEVELS_LARGE + 1],
    hi: [u16; LEVELS_LARGE + 1],
    /// Per level: the next row to make, and the last one wanted.
    next: [u16; LEVELS_LARGE + 1],
    target: [u16; LEVELS_LARGE + 1],
    /// Four rows a level: level `l`'s rows, refined along the row to level `l + 1`'s
    /// columns.
    rings: &'a mut [Ring],
    /// A level's row before it is refined along the row.
    scratch: Row,
}

impl<'a> Pipeline<'a> {
    /// An empty pipeline of `patch` (no levels yet: [`Pipeline::set_levels`]).
    #[inline(always)]
    fn new(patch: &'a Patch, rings: &'a mut [Ring]) -> Pipeline<'a> {
        Pipeline {
            control: &patch.control[..patch.model.control_count()],
            m: usize::from(patch.model.intervals),
            levels: 0,
            rho: [0; LEVELS_LARGE + 1],
            lo: [0; LEVELS_LARGE + 1],
            hi: [0; LEVELS_LARGE + 1],
            next: [0; LEVELS_LARGE + 1],
            target: [0; LEVELS_LARGE + 1],
            rings,
            scratch: [0; STRIP],
        }
    }

    /// The levels from control points `sp > 1` pixels apart to the pixels, refined by `N`
    /// (`2^shift_n`) but the last; whether `rings` holds them.
    #[inline(always)]
    fn set_levels(&mut self, shift_n: u32, sp: u32) -> bool {
        let mut d = sp;
        for level_rho in self.rho.iter_mut().take(LEVELS_LARGE) {
            if d <= 1 {
                break;
            }
            let rho = shift_n.min(d.trailing_zeros());
            *level_rho = rho as u8;
            d >>= rho;
            self.levels += 1;
        }
        d <= 1 && self.levels > 0 && self.rings.len() >= self.levels
    }

    /// `log2` of the refinement from level `l` to level `l + 1`.
    #[inline(always)]
    fn rho(&self, l: usize) -> u32 {
        self.rho.get(l).map_or(1, |&rho| u32::from(rho))
    }

    /// Starts a strip: the pixels of columns `x .. x + w` of the leaf (`w <= STRIP`), from
    /// row `y` down.
    fn start(&mut self, x: usize, w: usize, y: usize) {
        let top = self.levels.min(LEVELS_LARGE);
        let (mut lo, mut hi, mut first) = (x, x + w - 1, y);
        self.lo[top] = lo as u16;
        self.hi[top] = hi as u16;
        // Level l's last point: the grid's m, doubled or quadrupled by each level above.
        let mut last = self.m;
        for &rho in &self.rho[..top] {
            last <<= rho;
        }
        for l in (0..top).rev() {
            let rho = u32::from(self.rho[l]);
            last >>= rho;
            lo = (lo >> rho).saturating_sub(1);
            hi = ((hi >> rho) + 2).min(last);
            first = (first >> rho).saturating_sub(1);
            (self.lo[l], self.hi[l], self.next[l]) = (lo as u16, hi as u16, first as u16);
        }
    }

    /// Rows `first .. first + rows` of the strip's pixels into `out`, `cols` a row.
    #[inline(never)]
    fn draw<P: Point>(&mut self, out: &mut [P], first: usize, rows: usize, cols: usize) {
        let l = self.levels.saturating_sub(1).min(LEVELS_LARGE);
        let (rho, m) = (self.rho(l), self.m);
        for r in 0..rows {
            // Rows by offset: cutting `out` into rows would divide by `cols`, a library call
            // on a Cortex-M0.
            let Some(dst) = out.get_mut(r * cols..r * cols + cols) else {
                return;
            };
            let y = first + r;
            let need = last_tap(y, rho, m);
            if usize::from(self.next[l]) <= need {
                self.fill(l, need);
            }
            let Some(ring) = self.rings.get(l) else {
                return;
            };
            match interval(y, rho) {
                (k, 0) => P::take(dst, &ring[k % 4]),
                at => new_row(dst, ring, at, rho, m),
            }
        }
    }

    /// Makes level `top`'s rows up to row `upto`, with the rows of the levels above that they
    /// need, in order (a level's row waits for the rows of the level above it).
    fn fill(&mut self, top: usize, upto: usize) {
        let Some(t) = self.target.get_mut(top) else {
            return;
        };
        *t = upto as u16;
        let mut l = top;
        while let (Some(&next), Some(&target)) = (self.next.get(l), self.target.get(l)) {
            let i = usize::from(next);
            if i > usize::from(target) {
                if l >= top {
                    return;
                }
                l += 1;
                continue;
            }
            if l > 0 {
                let need = last_tap(i, self.rho(l - 1), self.m);
                if usize::from(self.next[l - 1]) <= need {
                    self.target[l - 1] = need as u16;
                    l -= 1;
                    continue;
                }
            }
            self.make(l, i);
            self.next[l] += 1;
        }
    }

    /// Level `l`'s row `i` over the strip's columns, refined along the row into its ring.
    #[inline(never)]
    fn make(&mut self, l: usize, i: usize) {
        let m = self.m;
        let rho = self.rho(l);
        let rho_above = if l > 0 { self.rho(l - 1) } else { 0 };
        let (lo, hi) = (usize::from(self.lo[l]), usize::from(self.hi[l]));
        let (Some(&lo1), Some(&hi1)) = (self.lo.get(l + 1), self.hi.get(l + 1)) else {
            return;
        };
        let lo1 = usize::from(lo1);
        let n = usize::from(hi1) + 1 - lo1;
        let Pipeline {
            control,
            rings,
            scratch,
            ..
        } = self;
        let Some((above, rest)) = rings.split_at_mut_checked(l) else {
            return;
        };
        let Some(ring) = rest.first_mut() else {
            return;
        };
        let out = &mut ring[i % 4];
        let line = match above.last() {
            None => {
                // The control grid's row, the points the strip needs.
                let side = m + 1;
                copy_short(
                    scratch,
                    control.get(i * side + lo..=i * side + hi).unwrap_or(&[]),
                );
                &*scratch
            }
            Some(above) => match interval(i, rho_above) {
                (k, 0) => &above[k % 4],
                at => {
                    let width = (hi + 1 - lo).min(STRIP);
                    new_row(&mut scratch[..width], above, at, rho_above, m);
                    &*scratch
                }
            },
        };
        refine_line(line, lo, out, (lo1, n), rho, m);
    }
}

/// Where a grid lies in the output: its top-left point and the output pixels between its
/// points (at least 1).
#[derive(Debug, Clone, Copy)]
struct Square {
    x: u32,
    y: u32,
    sp: u32,
}

/// What one rendering of a patch draws into: the clip, the tile output, its pixels and, for
/// a 16-bit stream, its samples.
struct Job<'a> {
    clip: Rect,
    out: &'a mut dyn TileOut,
    pixels: [u8; TILE * TILE],
    #[cfg_attr(not(feature = "deep"), allow(dead_code))]
    samples: Option<&'a mut [i16; TILE * TILE]>,
}

impl Job<'_> {
    /// Hands the first `len` pixels (and samples) on as the tile `area`.
    #[inline(always)]
    fn put(&mut self, area: Rect, len: usize) -> Result<(), Stop> {
        let Job {
            out,
            pixels,
            samples,
            ..
        } = self;
        let tile = TileMut {
            area,
            pixels: pixels.get_mut(..len).unwrap_or(&mut []),
            channels: 1,
        };
        #[cfg(feature = "deep")]
        if let Some(samples) = samples.as_deref_mut().and_then(|s| s.get_mut(..len)) {
            to_pixels(tile.pixels, samples);
            return out.put_samples(tile, samples);
        }
        let _ = samples;
        out.put(tile)
    }
}

/// How far apart, in a grid's values, the points [`grid_points`] draws are: from one row to
/// the next and from one column to the next.
#[derive(Clone, Copy)]
struct Spacing {
    row: usize,
    col: usize,
}

/// `rows` rows of `cols` points of grid `g` into `out`, from value `first` on, `spacing`
/// apart: the pixels of a pixel grid, or of a leaf drawn smaller than its points are apart.
#[inline(always)]
fn grid_points<P: Point>(
    out: &mut [P],
    g: &[i16],
    first: usize,
    spacing: Spacing,
    rows: usize,
    cols: usize,
) {
    for j in 0..rows {
        let row = first + j * spacing.row;
        let Some(dst) = out.get_mut(j * cols..j * cols + cols) else {
            return;
        };
        match g.get(row..row + cols).filter(|_| spacing.col == 1) {
            // A pixel grid at its coded size: a row of points is a row of pixels.
            Some(src) => P::take(dst, src),
            None => {
                for (i, p) in dst.iter_mut().enumerate() {
                    *p = P::of(g.get(row + i * spacing.col).copied().unwrap_or(0));
                }
            }
        }
    }
}

impl Patch {
    /// A patch of no model (all zero bits, so that a decoder's state holding one is cleared in
    /// place): it draws nothing, and is a place to reconstruct a leaf into.
    pub const CLEARED: Patch = Patch {
        model: crate::model::ModelType {
            intervals: 0,
            transforms: 0,
        },
        control: [0; MAX_CONTROL],
    };

    /// Renders the pixels of the leaf `node` that fall inside `clip`, tile by tile, into
    /// `sink`, stopping at the sink's first error. The leaf must be at least as wide as the
    /// grid has intervals, and at most as large as a coded leaf can be (128 px, drawn at most
    /// four times larger; otherwise nothing is drawn); a decoded leaf satisfies
    /// [`ModelType::fits_block`].
    pub fn render<S: PixelSink + ?Sized>(
        &self,
        node: &Node,
        clip: Rect,
        sink: &mut S,
    ) -> Result<(), S::Error> {
        let mut out = Catch::new(sink);
        // A stop comes only from the sink, whose error `finish` returns.
        let _ = self.render_to(node, clip, &mut out);
        out.finish()
    }

    /// [`Patch::render`] into a [`TileOut`] trait object.
    #[inline]
    pub fn render_to(&self, node: &Node, clip: Rect, out: &mut dyn TileOut) -> Result<(), Stop> {
        self.render_scaled(node, Scale::One, clip, out)
    }

    /// Renders the leaf `node` at `scale` (see [`Scale`]): the pixels of its square in the
    /// scaled image (`node`'s coordinates times the scale) that fall inside `clip` (scaled
    /// image coordinates), tile by tile; with their samples when `out` asks for them
    /// ([`TileOut::depth`]).
    #[inline]
    pub fn render_scaled(
        &self,
        node: &Node,
        scale: Scale,
        clip: Rect,
        out: &mut dyn TileOut,
    ) -> Result<(), Stop> {
        #[cfg(feature = "deep")]
        if out.depth() == Depth::Samples {
            return self.render_deep(node, scale, clip, out);
        }
        self.render_job(node, scale, clip, out, None)
    }

    /// [`Patch::render_scaled`] with samples (out of line: their buffer is on the stack only
    /// for a 16-bit stream).
    #[cfg(feature = "deep")]
    #[inline(never)]
    fn render_deep(
        &self,
        node: &Node,
        scale: Scale,
        clip: Rect,
        out: &mut dyn TileOut,
    ) -> Result<(), Stop> {
        let mut samples = [0i16; TILE * TILE];
        self.render_job(node, scale, clip, out, Some(&mut samples))
    }

    /// [`Patch::render_scaled`], with a tile's `samples` for a 16-bit stream.
    #[inline(never)]
    fn render_job(
        &self,
        node: &Node,
        scale: Scale,
        clip: Rect,
        out: &mut dyn TileOut,
        samples: Option<&mut [i16; TILE * TILE]>,
    ) -> Result<(), Stop> {
        let m = self.model.intervals;
        let log2 = i32::from(node.log2);
        if log2 >= 16 || m == 0 || (1u32 << log2) < u32::from(m) || clip.is_empty() {
            return Ok(());
        }
        let k = scale.log2();
        let sp_log2 = log2 + k - m.trailing_zeros() as i32;
        let mut job = Job {
            clip,
            out,
            pixels: [0; TILE * TILE],
            samples,
        };
        if sp_log2 < 0 {
            // Control points closer than an output pixel: output pixel (X, Y) is control point
            // (X, Y) times the points per pixel; a leaf smaller than a pixel draws its first
            // point if its corner is one of the output's pixels, else nothing.
            let unit = 1u32 << -k;
            if (node.x | node.y) & (unit - 1) != 0 {
                return Ok(());
            }
            let at = Square {
                x: node.x >> -k,
                y: node.y >> -k,
                sp: 1,
            };
            let side = (node.size() >> -k).max(1);
            let step = ((unit * u32::from(m)) >> node.log2).max(1) as usize;
            let g = &self.control[..self.model.control_count()];
            return self.points(g, &at, side, step, &mut job);
        }
        let (x, y) = if k >= 0 {
            (node.x << k, node.y << k)
        } else {
            (node.x >> -k, node.y >> -k)
        };
        let at = Square {
            x,
            y,
            sp: 1 << sp_log2,
        };
        if at.sp == 1 {
            // A pixel grid: its points are the pixels.
            let g = &self.control[..self.model.control_count()];
            return self.points(g, &at, u32::from(m), 1, &mut job);
        }
        // One level per refinement by N (the last may be by less) from `sp` pixels to one: a
        // level per halving for N = 2, per two halvings (rounded up) for N = 4.
        let shift_n = self.model.transforms_log2().clamp(1, 2);
        match (at.sp.trailing_zeros() + shift_n - 1) >> (shift_n - 1) {
            0..=2 => self.strips_in::<{ 2 * RING }>(at, &mut job),
            3..=4 => self.strips_in::<{ 4 * RING }>(at, &mut job),
            5..=7 => self.strips_in::<{ LEVELS * RING }>(at, &mut job),
            _ => self.strips_in::<{ LEVELS_LARGE * RING }>(at, &mut job),
        }
    }

    /// [`Patch::strips`] with `SAMPLES / (4 STRIP)` levels of rings (out of line, so that the
    /// rows are on the stack only while a leaf is drawn, and only as many as it needs are
    /// cleared; one flat array, so that clearing it is one call).
    #[inline(never)]
    fn strips_in<const SAMPLES: usize>(&self, at: Square, job: &mut Job<'_>) -> Result<(), Stop> {
        let mut samples = [0i16; SAMPLES];
        let (rows, _) = samples.as_chunks_mut::<STRIP>();
        let (rings, _) = rows.as_chunks_mut::<4>();
        self.strips(at, job, rings)
    }

    /// Draws the pixels of the leaf whose control grid is at `at` (points `at.sp > 1` pixels
    /// apart) inside the clip, in strips of [`STRIP`] columns, each from top to bottom a
    /// tile at a time: the strip's rows are made level by level as the rows below need them
    /// ([`Pipeline`]), four rows of each level kept in `rings`.
    #[inline(never)]
    fn strips(&self, at: Square, job: &mut Job<'_>, rings: &mut [Ring]) -> Result<(), Stop> {
        let m = u32::from(self.model.intervals);
        let ext = m * at.sp;
        let square = Rect {
            x: at.x,
            y: at.y,
            w: ext,
            h: ext,
        };
        let area = square.intersect(&job.clip);
        if area.is_empty() {
            return Ok(());
        }
        let mut pipeline = Pipeline::new(self, rings);
        if !pipeline.set_levels(self.model.transforms_log2(), at.sp) {
            return Ok(());
        }
        let (x0, y0) = (area.x - at.x, area.y - at.y);
        let mut tx = 0;
        while tx < area.w {
            let tw = (area.w - tx).min(STRIP as u32);
            pipeline.start((x0 + tx) as usize, tw as usize, y0 as usize);
            let mut ty = 0;
            while ty < area.h {
                let th = (area.h - ty).min(TILE as u32);
                let first = (y0 + ty) as usize;
                let (rows, cols) = (th as usize, tw as usize);
                with_rows!(job, |out| pipeline.draw(out, first, rows, cols));
                let tile = Rect {
                    x: area.x + tx,
                    y: area.y + ty,
                    w: tw,
                    h: th,
                };
                job.put(tile, (tw * th) as usize)?;
                ty += th;
            }
            tx += tw;
        }
        Ok(())
    }

    /// Draws grid `g`'s points as pixels, `step` points apart: the square of `side` pixels at
    /// `at` (a pixel grid, or a leaf drawn smaller than its control points are apart).
    #[inline(never)]
    fn points(
        &self,
        g: &[i16],
        at: &Square,
        side: u32,
        step: usize,
        job: &mut Job<'_>,
    ) -> Result<(), Stop> {
        let grid = self.model.grid();
        let square = Rect {
            x: at.x,
            y: at.y,
            w: side,
            h: side,
        };
        let area = square.intersect(&job.clip);
        if area.is_empty() || side as usize > TILE {
            return Ok(());
        }
        let (c0, r0) = ((area.x - at.x) as usize, (area.y - at.y) as usize);
        let (cols, rows) = (area.w as usize, area.h as usize);
        let first = r0 * step * grid + c0 * step;
        let spacing = Spacing {
            row: step * grid,
            col: step,
        };
        with_rows!(job, |out| grid_points(out, g, first, spacing, rows, cols));
        job.put(area, cols * rows)
    }
}
#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::format::MIN_LEAF_LOG2;
    use crate::model::{default_line_taps, tap_point, MODELS, SAMPLE_ONE};
    use core::convert::Infallible;
    use std::vec;
    use std::vec::Vec;

    /// The line rules with constant taps are the models' rules: each tap times
    /// `2^(12 - SHIFT)` is the model's tap at that phase, and the sums round alike. Phase `o`
    /// of a refinement by `2^rho` is phase `o N / 2^rho` of the model's `N` (a last level
    /// refined by less than `N` takes the phases that fall on its points).
    #[test]
    fn line_rules_are_the_models() {
        fn taps<const A: i32, const B: i32, const C: i32, const D: i32, const S: u32>(
            _: Line<A, B, C, D, S>,
        ) -> [i32; 4] {
            [A, B, C, D].map(|t| t << (12 - S))
        }
        let half = taps(Half::default());
        let quarter = taps(Quarter::default());
        let three_quarters = taps(ThreeQuarters::default());
        // The phase-3-of-4 rule is the phase-1 rule reversed (`new_row` uses it so).
        let mut reversed = quarter;
        reversed.reverse();
        assert_eq!(three_quarters, reversed);
        for model in MODELS {
            let n = usize::from(model.transforms);
            let rules = crate::model::Rules::of(model);
            for rho in 1..=model.transforms_log2() {
                for o in 1..1usize << rho {
                    let r = (o * n) >> rho;
                    let want = rules.taps[r - 1].map(i32::from);
                    let got = match (rho, o) {
                        (1, _) | (_, 2) => half,
                        (_, 1) => quarter,
                        _ => three_quarters,
                    };
                    assert_eq!(got, want, "model {model:?}, phase {o} of {}", 1 << rho);
                    assert_eq!(want, default_line_taps(model.transforms, r));
                }
            }
        }
    }

    /// Counts the pixels a render delivers and checks each lies in its leaf.
    struct Count {
        size: u32,
        pixels: u64,
    }

    impl PixelSink for Count {
        type Error = Infallible;

        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
            let Rect { x, y, w, h } = tile.area;
            assert!(x + w <= self.size && y + h <= self.size);
            assert_eq!(tile.pixels.len() as u32, w * h);
            self.pixels += u64::from(w * h);
            Ok(())
        }
    }

    /// Collects a rendered block of side `size` at the origin.
    struct Block {
        size: usize,
        pixels: [u8; 64],
    }

    impl PixelSink for Block {
        type Error = Infallible;

        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
            let Rect { x, y, w, h } = tile.area;
            for r in 0..h as usize {
                for c in 0..w as usize {
                    self.pixels[(y as usize + r) * self.size + x as usize + c] =
                        tile.pixels[r * w as usize + c];
                }
            }
            Ok(())
        }
    }

    /// Collects every tile into an image of `width x height`, counting how often each pixel
    /// is drawn and checking the sink contract (tiles of at most TILE x TILE inside `clip`).
    struct Image {
        width: usize,
        pixels: Vec<u8>,
        drawn: Vec<u8>,
        clip: Rect,
    }

    impl Image {
        fn new(width: usize, height: usize, clip: Rect) -> Image {
            Image {
                width,
                pixels: vec![0; width * height],
                drawn: vec![0; width * height],
                clip,
            }
        }
    }

    impl PixelSink for Image {
        type Error = Infallible;

        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
            let Rect { x, y, w, h } = tile.area;
            assert!(w as usize <= TILE && h as usize <= TILE && w > 0 && h > 0);
            assert!(
                self.clip.contains(&tile.area),
                "{:?} outside {:?}",
                tile.area,
                self.clip
            );
            assert_eq!(tile.pixels.len() as u32, w * h);
            for r in 0..h as usize {
                for c in 0..w as usize {
                    let k = (y as usize + r) * self.width + x as usize + c;
                    self.pixels[k] = tile.pixels[r * w as usize + c];
                    self.drawn[k] += 1;
                }
            }
            Ok(())
        }
    }

    /// A small xorshift generator.
    struct Rng(u64);

    impl Rng {
        fn below(&mut self, range: u32) -> u32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 % u64::from(range)) as u32
        }
    }

    /// A patch of `model` with random control values: over grey levels -256..512 when `wild`
    /// is false, over the whole sample range (so that rules saturate) when it is true.
    fn random_patch(rng: &mut Rng, model: ModelType, wild: bool) -> Patch {
        let mut control = [0i16; MAX_CONTROL];
        for v in control.iter_mut().take(model.control_count()) {
            *v = if wild {
                (rng.below((SAMPLE_MAX - SAMPLE_MIN + 1) as u32) as i32 + SAMPLE_MIN) as i16
            } else {
                (rng.below(12288) as i32 - 4096) as i16
            };
        }
        Patch { model, control }
    }

    /// The refined value at refined coordinates `(q1, q2)` (row, column; `0..=N*m`) of the
    /// control grid `g` (row-major, side `m+1`), point by point as the specification states
    /// it.
    fn point(patch: &Patch, g: &[i16], q1: usize, q2: usize) -> i32 {
        let shift = patch.model.transforms.trailing_zeros();
        let mask = (1usize << shift) - 1;
        let (a1, r1) = (q1 >> shift, q1 & mask);
        let (a2, r2) = (q2 >> shift, q2 & mask);
        match (r1, r2) {
            (0, 0) => i32::from(g[a1 * patch.model.grid() + a2]),
            (0, _) => line(patch, g, 0, a1, a2, r2),
            (_, 0) => line(patch, g, 1, a2, a1, r1),
            _ => {
                // The tensor product: the line rule across the new points of the nearest rows.
                let taps = default_line_taps(patch.model.transforms, r1);
                let m = patch.model.grid() - 1;
                let mut acc = 0i32;
                for (t, &tap) in taps.iter().enumerate() {
                    acc += tap * line(patch, g, 0, tap_point(a1, t, m), a2, r2);
                }
                ((acc + 2048) >> 12).clamp(SAMPLE_MIN, SAMPLE_MAX)
            }
        }
    }

    /// New point at phase `r` between points `a` and `a+1` of line `fixed` (a row when `dir` is
    /// 0, a column when 1); taps on points `a-1..=a+2`, mirrored at the line's ends.
    fn line(patch: &Patch, g: &[i16], dir: usize, fixed: usize, a: usize, r: usize) -> i32 {
        let side = patch.model.grid();
        let m = side - 1;
        let taps = default_line_taps(patch.model.transforms, r);
        let mut acc = 0i32;
        for (t, &tap) in taps.iter().enumerate() {
            let idx = tap_point(a, t, m);
            let v = if dir == 0 {
                g[fixed * side + idx]
            } else {
                g[idx * side + fixed]
            };
            acc += tap * i32::from(v);
        }
        ((acc + 2048) >> 12).clamp(SAMPLE_MIN, SAMPLE_MAX)
    }

    /// The patch's value at `(p1, p2) / 2^den` (row, column, in intervals of the control grid),
    /// straight from the specification: subdivide the grid, keep the child grid that holds the
    /// point (its points by [`point`]), until the point is a grid point.
    fn reference(patch: &Patch, mut p1: u64, mut p2: u64, den: u32) -> i32 {
        let m = u64::from(patch.model.intervals);
        let n = u64::from(patch.model.transforms);
        let side = patch.model.grid();
        let mut g: Vec<i16> = patch.control[..side * side].to_vec();
        let one = 1u64 << den;
        loop {
            if p1.is_multiple_of(one) && p2.is_multiple_of(one) {
                return i32::from(g[(p1 / one) as usize * side + (p2 / one) as usize]);
            }
            p1 *= n;
            p2 *= n;
            let i = ((p1 / one) / m).min(n - 1);
            let j = ((p2 / one) / m).min(n - 1);
            p1 -= i * m * one;
            p2 -= j * m * one;
            let mut child = vec![0i16; side * side];
            for r in 0..side {
                for c in 0..side {
                    let q1 = (i * m) as usize + r;
                    let q2 = (j * m) as usize + c;
                    child[r * side + c] = point(patch, &g, q1, q2) as i16;
                }
            }
            g = child;
        }
    }

    /// The leaf at `(x, y)` of side `2^log2` drawn at `scale` inside `clip` (scaled image
    /// coordinates), into an image of the scaled leaf's bottom-right corner's size.
    fn draw(patch: &Patch, node: &Node, scale: Scale, clip: Rect) -> (Image, usize) {
        let side = scale.apply(node.x.max(node.y) + node.size()) as usize;
        let mut image = Image::new(side, side, clip);
        let mut out = Catch::new(&mut image);
        let _ = patch.render_scaled(node, scale, clip, &mut out);
        let Ok(()) = out.finish();
        (image, side)
    }

    /// Every model at every leaf size it may code, drawn at every scale with random control
    /// values (also extreme ones), gives the specification's values: each pixel
    /// once, each the point the subdivision defines (a pixel of a decode at `s` is the patch's
    /// point at the pixel's position divided by `s`).
    #[test]
    fn every_pixel_is_the_specifications_point_at_every_scale() {
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let mut checked = 0u64;
        for model in MODELS {
            for log2 in MIN_LEAF_LOG2..=MAX_LEAF_LOG2 {
                if !model.fits_block(log2) {
                    continue;
                }
                for trial in 0..3 {
                    let patch = random_patch(&mut rng, model, trial == 2);
                    // At an offset, so that a leaf is not always at the origin.
                    let size = 1u32 << log2;
                    let node = Node {
                        x: size * (1 + rng.below(3)),
                        y: size * rng.below(3),
                        log2,
                    };
                    for scale in Scale::ALL {
                        let (image, width) = draw(&patch, &node, scale, Rect::EVERYTHING);
                        let k = scale.log2();
                        // The leaf's pixels at this scale.
                        let (x0, y0) = (scale.apply(node.x), scale.apply(node.y));
                        let (x1, y1) = (scale.apply(node.x + size), scale.apply(node.y + size));
                        let m = u64::from(model.intervals);
                        // Pixel (x0 + i) is at i / 2^k pixels of the leaf: i * m / (size * 2^k)
                        // control intervals.
                        let den = log2 as i32 + k.max(0);
                        for y in 0..image.pixels.len() / width {
                            for x in 0..width {
                                let drawn = image.drawn[y * width + x];
                                let inside = (x0..x1).contains(&(x as u32))
                                    && (y0..y1).contains(&(y as u32));
                                assert_eq!(
                                    drawn,
                                    u8::from(inside),
                                    "{model:?} 2^{log2} {scale:?} at ({x}, {y})"
                                );
                                if !inside {
                                    continue;
                                }
                                // Pixels sampled: all of small outputs, a fixed share of large.
                                if (x1 - x0) * (y1 - y0) > 4096 && rng.below(16) != 0 {
                                    continue;
                                }
                                let (i, j) = ((x as u32 - x0) as u64, (y as u32 - y0) as u64);
                                let (i, j) = if k < 0 { (i << -k, j << -k) } else { (i, j) };
                                let value = reference(&patch, j * m, i * m, den as u32);
                                assert_eq!(
                                    image.pixels[y * width + x],
                                    sample_to_pixel(value),
                                    "{model:?} 2^{log2} {scale:?} trial {trial} at ({x}, {y})"
                                );
                                checked += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 100_000, "{checked}");
    }

    /// A decode cut to a clip draws exactly the full decode's pixels inside the clip, each
    /// once, in tiles inside the clip (at every scale).
    #[test]
    fn clipped_rendering_is_the_full_rendering_cut() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for model in MODELS {
            for log2 in MIN_LEAF_LOG2..=MAX_LEAF_LOG2 {
                if !model.fits_block(log2) {
                    continue;
                }
                let patch = random_patch(&mut rng, model, false);
                let node = Node { x: 0, y: 0, log2 };
                for scale in Scale::ALL {
                    let (full, width) = draw(&patch, &node, scale, Rect::EVERYTHING);
                    let side = width as u32;
                    for _ in 0..12 {
                        let thin = rng.below(4) == 0;
                        let clip = Rect {
                            x: rng.below(side),
                            y: rng.below(side),
                            w: 1 + rng.below(side),
                            h: 1 + rng.below(if thin { 2 } else { side }),
                        };
                        let (cut, _) = draw(&patch, &node, scale, clip);
                        for k in 0..full.pixels.len() {
                            let (x, y) = ((k % width) as u32, (k / width) as u32);
                            let pixel = Rect { x, y, w: 1, h: 1 };
                            let want = u8::from(clip.contains(&pixel));
                            assert_eq!(cut.drawn[k], want, "{model:?} 2^{log2} {scale:?} {clip:?}");
                            if want == 1 {
                                assert_eq!(cut.pixels[k], full.pixels[k]);
                            }
                        }
                    }
                }
            }
        }
    }

    /// A decode at `1/2^k` is the full decode's pixels at multiples of `2^k`, and one at `2^k`
    /// has the full decode's pixels at multiples of `2^k`.
    #[test]
    fn scaled_renderings_agree_with_the_full_one() {
        let mut rng = Rng(0x1234_5678_9abc_def1);
        for model in MODELS {
            for log2 in MIN_LEAF_LOG2..=6 {
                if !model.fits_block(log2) {
                    continue;
                }
                let patch = random_patch(&mut rng, model, true);
                let node = Node {
                    x: 64,
                    y: 128,
                    log2,
                };
                let (full, width) = draw(&patch, &node, Scale::One, Rect::EVERYTHING);
                for scale in Scale::ALL {
                    let (scaled, w) = draw(&patch, &node, scale, Rect::EVERYTHING);
                    let k = scale.log2();
                    for (i, (&p, &drawn)) in scaled.pixels.iter().zip(&scaled.drawn).enumerate() {
                        if drawn == 0 {
                            continue;
                        }
                        let (x, y) = (i % w, i / w);
                        let (fx, fy, exact) = if k >= 0 {
                            (x >> k, y >> k, x % (1 << k) == 0 && y % (1 << k) == 0)
                        } else {
                            (x << -k, y << -k, true)
                        };
                        if exact {
                            assert_eq!(p, full.pixels[fy * width + fx], "{model:?} {scale:?}");
                        }
                    }
                }
            }
        }
    }

    /// The leaf of side `2^log2` at the origin.
    fn at_origin(log2: u8) -> Node {
        Node { x: 0, y: 0, log2 }
    }

    /// The default scheme is the tensor product of its line rules, so a control grid that is a
    /// sum of a function of the column and a function of the row gives such a sum everywhere:
    /// `P(x, y) - P(x, 0) - P(0, y) + P(0, 0)` vanishes up to the roundings (a blend of the
    /// cell's four sides does not: see docs/decisions.md).
    #[test]
    fn default_scheme_keeps_sums_of_row_and_column_functions() {
        for model in [MODELS[1], MODELS[2], MODELS[3]] {
            let side = model.grid();
            let m = side - 1;
            let mut control = [0i16; MAX_CONTROL];
            for r in 0..side {
                for c in 0..side {
                    // Curved along both axes, 90 grey levels each way, clear of the pixel
                    // range's ends (the side lobes overshoot).
                    let f = |i: usize| 90 * (i * i) as i32 / (m * m) as i32;
                    control[r * side + c] = (SAMPLE_ONE * (40 + f(c) + f(r))) as i16;
                }
            }
            let patch = Patch { model, control };
            let mut block = Block {
                size: 8,
                pixels: [0; 64],
            };
            let Ok(()) = patch.render(&at_origin(3), Rect::of_size(8, 8), &mut block);
            let p = |x: usize, y: usize| i32::from(block.pixels[y * 8 + x]);
            for y in 0..8 {
                for x in 0..8 {
                    let mixed = p(x, y) - p(x, 0) - p(0, y) + p(0, 0);
                    assert!(mixed.abs() <= 2, "{model:?} at ({x}, {y}): {mixed}");
                }
            }
        }
    }

    /// On a pixel grid (control points one pixel apart) the patch draws its control values:
    /// pixel `(x, y)` is value `(y, x)`, and the values past the block draw nothing.
    #[test]
    fn pixel_grids_draw_their_control_values() {
        let mut pixel_grids = 0;
        for model in MODELS {
            let log2 = model.intervals.trailing_zeros() as u8;
            if log2 < MIN_LEAF_LOG2 {
                continue;
            }
            assert!(model.fits_block(log2), "{model:?}");
            assert!(!model.subdivides(log2), "{model:?}");
            pixel_grids += 1;
            let side = model.grid();
            let mut control = [0i16; MAX_CONTROL];
            for (i, v) in control.iter_mut().take(side * side).enumerate() {
                *v = (SAMPLE_ONE * ((i * 37) % 256) as i32) as i16;
            }
            let patch = Patch { model, control };
            let size = side - 1;
            let mut block = Block {
                size,
                pixels: [0; 64],
            };
            let Ok(()) = patch.render(&at_origin(log2), Rect::of_size(8, 8), &mut block);
            for y in 0..size {
                for x in 0..size {
                    let expected = ((y * side + x) * 37 % 256) as u8;
                    assert_eq!(
                        block.pixels[y * size + x],
                        expected,
                        "{model:?} at ({x}, {y})"
                    );
                }
            }
        }
        // 3x3 at 2 px, 5x5 at 4 px, 9x9 at 8 px (not the bilinear model: leaves are >= 2 px).
        assert_eq!(pixel_grids, 3);
    }

    /// The rings are sized by the levels a leaf needs: every model at every leaf size it may
    /// code delivers every pixel (too few rings would draw nothing).
    #[test]
    fn rings_cover_every_model_and_leaf_size() {
        for model in MODELS {
            for log2 in MIN_LEAF_LOG2..=MAX_LEAF_LOG2 {
                if !model.fits_block(log2) {
                    continue;
                }
                let patch = Patch {
                    model,
                    control: [100; MAX_CONTROL],
                };
                let size = 1u32 << log2;
                let mut sink = Count { size, pixels: 0 };
                let Ok(()) = patch.render(&at_origin(log2), Rect::of_size(size, size), &mut sink);
                assert_eq!(sink.pixels, u64::from(size * size), "{model:?} at 2^{log2}");
            }
        }
    }
}
