//! Patch synthesis: exact tabulation of a projected-IFS patch by recursive subdivision, in
//! integer arithmetic that is bit-exact on every platform.
//!
//! Values are samples in 1/16 grey level ([`SAMPLE_ONE`]); weights are in 1/4096
//! ([`WEIGHT_ONE`]). Every new point is `(sum(tap * value) + 2048) >> 12` (arithmetic shift),
//! clamped to `[SAMPLE_MIN, SAMPLE_MAX]`. The sum of tap magnitudes of a rule ([`Rules`]) is at
//! most `6144`, and `6144 * 8192 < 2^31`, so the accumulation never overflows an `i32`.
//!
//! Evaluation is depth-first: a control grid is refined one child grid at a time and each child
//! is refined recursively, so memory is one small grid per level (at most [`ARENA_LEN`] values),
//! independent of the block size. A grid whose square fits an output tile ([`TILE`] x [`TILE`]
//! pixels) is refined level by level in one lattice of the tile's points, its child grids side by
//! side, each mirrored at its own ends (a child grid's points depend only on that child grid);
//! a grid whose points are at most `N` pixels apart but whose square is larger than a tile is
//! refined once, one tile's window of points at a time.
//!
//! A patch can also be drawn at a [`Scale`] other than the coded size: smaller by stopping the
//! subdivision earlier (pixel `(X, Y)` of a decode at `1/2^k` is pixel `(X 2^k, Y 2^k)` of the
//! full decode, exactly), larger by letting it go on below the pixel (pixel `(X, Y)` of a decode
//! at `2^k` is the patch's point at `(X / 2^k, Y / 2^k)`).

use crate::format::SampleRange;
use crate::format::MAX_LEAF_LOG2;
use crate::geometry::{Node, Rect};
use crate::model::{ModelType, MAX_CONTROL, MODELS, SAMPLE_BITS, SAMPLE_MAX, SAMPLE_MIN};
#[cfg(doc)]
use crate::model::{Rules, SAMPLE_ONE, WEIGHT_ONE};

/// Side of the tiles handed to a [`PixelSink`].
pub const TILE: usize = 8;

/// Values of the per-level grid stack below a patch's control grid at the coded size: the most
/// that any model needs at the largest leaf (four 5x5 grids for the 5x5/2x2 model).
pub const ARENA_LEN: usize = arena_len(0);

/// The same for decodes at up to four times the coded size ([`Scale::Quadruple`]): two 9x9
/// grids for the 9x9/4x4 model. Only an enlarged decode uses it.
const ARENA_LARGE_LEN: usize = arena_len(2);

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

/// The stored grids below the control grid when `model` tabulates a leaf of side `2^log2`, in
/// values: one grid per subdivision level whose square is larger than a tile and whose points
/// are more than `N` pixels apart (see [`Patch::walk`]).
const fn stored_values(model: ModelType, log2: u32) -> usize {
    let n = model.transforms as u32;
    let m = model.intervals as u32;
    let mut sp = (1u32 << log2) / m;
    let mut levels = 0;
    while m * sp > TILE as u32 && sp > n {
        sp /= n;
        levels += 1;
    }
    levels * model.control_count()
}

const fn arena_len(enlarge_log2: u32) -> usize {
    let mut max = 0;
    let mut i = 0;
    while i < MODELS.len() {
        let v = stored_values(MODELS[i], MAX_LEAF_LOG2 as u32 + enlarge_log2);
        if v > max {
            max = v;
        }
        i += 1;
    }
    max
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
pub struct Patch {
    /// The model type.
    pub model: ModelType,
    /// Control values, row-major, `model.grid()` per row, in sample units.
    pub control: [i16; MAX_CONTROL],
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
#[derive(Clone, Copy)]
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

/// Which line rule makes the new points at phase `r` (`1 ..= N - 1`) of a model of `N`
/// transforms.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Phase {
    /// [`Half`].
    Half,
    /// [`Quarter`].
    Quarter,
    /// [`ThreeQuarters`].
    ThreeQuarters,
}

/// The loops a rule is compiled into ([`with_rule!`]): the phase-3-of-4 rule is the
/// phase-1 rule with its taps in reverse order ([`Phase::orient`]), so it needs none of
/// its own.
#[derive(Clone, Copy)]
enum Kind {
    /// [`Half`].
    Half,
    /// [`Quarter`].
    Quarter,
}

impl Phase {
    /// The loop kind that makes this phase's points.
    #[inline(always)]
    fn kind(self) -> Kind {
        match self {
            Phase::Half => Kind::Half,
            Phase::Quarter | Phase::ThreeQuarters => Kind::Quarter,
        }
    }

    /// The values this phase's rule weighs (`taps`, in its order) in the order its
    /// [`Phase::kind`] takes them: reversed for the phase-3-of-4 rule.
    #[inline(always)]
    fn orient<T>(self, taps: [T; 4]) -> [T; 4] {
        match self {
            Phase::ThreeQuarters => {
                let [a, b, c, d] = taps;
                [d, c, b, a]
            }
            Phase::Half | Phase::Quarter => taps,
        }
    }

    /// The rule at phase `r` of a model whose `N` is `2^shift` (2 or 4).
    #[inline(always)]
    fn of(r: usize, shift: u32) -> Phase {
        match (r << 2) >> shift {
            1 => Phase::Quarter,
            3 => Phase::ThreeQuarters,
            _ => Phase::Half,
        }
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

/// Runs `$body` with `$rule` bound to the [`Rule`] of loop kind `$kind` ([`Kind`]): the body
/// is compiled once per kind, so that its loop has the taps as constants.
macro_rules! with_rule {
    ($kind:expr, |$rule:ident| $body:expr) => {{
        match $kind {
            Kind::Half => {
                let $rule: Half = Line;
                $body
            }
            Kind::Quarter => {
                let $rule: Quarter = Line;
                $body
            }
        }
    }};
}

/// `out[x] = rule(a[x], b[x], c[x], d[x])` for `x = start, start + step, ...` up to `end`
/// (inclusive): a new row of a lattice from four old rows.
#[inline(never)]
fn across<R: Rule>(
    rule: R,
    out: &mut [i16; LATTICE],
    [a, b, c, d]: [&[i16; LATTICE]; 4],
    start: usize,
    end: usize,
    step: usize,
) {
    let end = end.min(TILE);
    let mut x = start;
    while x <= end {
        out[x] = rule.apply(a[x], b[x], c[x], d[x]);
        x += step;
    }
}

/// What a tile's rows are made of: 8-bit pixels, or samples (a child grid's, or a 16-bit
/// stream's tile, made pixels by [`Job::put`]). The choice is made once per tile
/// ([`with_rows!`]), so that the loops over rows and pixels are the same as without it.
trait Point: Copy {
    /// The point a sample makes.
    fn of(v: i16) -> Self;

    /// `out[i] = rule(a[i], b[i], c[i], d[i])` for every `i` of `out` (at most a row of the
    /// lattice): a new row from four old rows.
    fn across<R: Rule>(rule: R, out: &mut [Self], from: [&[i16; LATTICE]; 4]);

    /// `out[i]` = the point of `src[i]` for every `i` of `out`.
    fn take(out: &mut [Self], src: &[i16]);
}

impl Point for u8 {
    #[inline(always)]
    fn of(v: i16) -> u8 {
        sample_to_pixel(i32::from(v))
    }

    #[inline(never)]
    fn across<R: Rule>(rule: R, out: &mut [u8], [a, b, c, d]: [&[i16; LATTICE]; 4]) {
        for ((((p, &a), &b), &c), &d) in out.iter_mut().zip(a).zip(b).zip(c).zip(d) {
            *p = rule.pixel(a, b, c, d);
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
    fn across<R: Rule>(rule: R, out: &mut [i16], [a, b, c, d]: [&[i16; LATTICE]; 4]) {
        for ((((v, &a), &b), &c), &d) in out.iter_mut().zip(a).zip(b).zip(c).zip(d) {
            *v = rule.apply(a, b, c, d);
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

/// `pad` = the old row `row` (`m + 1` points, `m >= 1`) between its mirrored end points:
/// `row[1], row[0], ..., row[m], row[m - 1]`, so that the taps of interval `a` are
/// `pad[a..a + 4]`.
#[inline(always)]
fn fill_pad(pad: &mut [i16; LATTICE + 3], row: &[i16]) {
    copy_short(&mut pad[1..], row);
    let m = row.len().saturating_sub(1);
    pad[0] = row.get(1).copied().unwrap_or(0);
    if let (Some(p), Some(&v)) = (pad.get_mut(m + 2), row.get(m.wrapping_sub(1))) {
        *p = v;
    }
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

/// Row `y` of `lattice` (mutable) and its rows `taps` (which must not include `y`).
#[inline(always)]
fn split_rows(
    lattice: &mut Lattice,
    y: usize,
    taps: [usize; 4],
) -> Option<(&mut [i16; LATTICE], [&[i16; LATTICE]; 4])> {
    let (above, rest) = lattice.split_at_mut(y);
    let (new, below) = rest.split_first_mut()?;
    let pick = |t: usize| {
        if t < y {
            above.get(t)
        } else {
            below.get(t.wrapping_sub(y + 1))
        }
    };
    let [t0, t1, t2, t3] = taps;
    Some((new, [pick(t0)?, pick(t1)?, pick(t2)?, pick(t3)?]))
}

/// `row[x] = rule(row[p0], row[p1], row[p2], row[p3])` in the rows `first, first + step, ...`
/// up to `last` (inclusive) of `lattice`: a new column of old rows.
#[inline(never)]
fn along<R: Rule>(
    rule: R,
    lattice: &mut Lattice,
    x: usize,
    [p0, p1, p2, p3]: [usize; 4],
    first: usize,
    last: usize,
    step: usize,
) {
    let (x, p0, p1, p2, p3) = (
        x.min(TILE),
        p0.min(TILE),
        p1.min(TILE),
        p2.min(TILE),
        p3.min(TILE),
    );
    let mut y = first;
    while y <= last {
        let Some(row) = lattice.get_mut(y) else {
            return;
        };
        row[x] = rule.apply(row[p0], row[p1], row[p2], row[p3]);
        y += step;
    }
}

/// The points of a row refined by 4 (phases 0, 1, 2, 3 of each interval) into `out`, from
/// `taps` (the padded old row from the first interval's first tap on): whole intervals, then
/// the first points of one more.
#[inline(never)]
fn quarters(taps: &[i16], out: &mut [i16]) {
    let mut windows = taps.windows(4);
    let mut chunks = out.chunks_exact_mut(4);
    for (chunk, w) in (&mut chunks).zip(&mut windows) {
        if let ([o0, o1, o2, o3], &[p0, p1, p2, p3]) = (chunk, w) {
            *o0 = p1;
            *o1 = Quarter::apply(Line, p0, p1, p2, p3);
            *o2 = Half::apply(Line, p0, p1, p2, p3);
            *o3 = ThreeQuarters::apply(Line, p0, p1, p2, p3);
        }
    }
    let rest = chunks.into_remainder();
    if let (Some(&[p0, p1, p2, p3]), false) = (windows.next(), rest.is_empty()) {
        let points = [
            p1,
            Quarter::apply(Line, p0, p1, p2, p3),
            Half::apply(Line, p0, p1, p2, p3),
        ];
        copy_short(rest, &points);
    }
}

/// The points of a row refined by 2 (each interval's old point and midpoint) into `out`,
/// from `taps` as [`quarters`].
#[inline(never)]
fn halves(taps: &[i16], out: &mut [i16]) {
    let mut windows = taps.windows(4);
    let mut chunks = out.chunks_exact_mut(2);
    for (chunk, w) in (&mut chunks).zip(&mut windows) {
        if let ([o0, o1], &[p0, p1, p2, p3]) = (chunk, w) {
            *o0 = p1;
            *o1 = Half::apply(Line, p0, p1, p2, p3);
        }
    }
    if let (Some(&[_, p1, _, _]), [o]) = (windows.next(), chunks.into_remainder()) {
        *o = p1;
    }
}

/// Deepest subdivision below a leaf's control grid that the walk stores (a leaf of the
/// largest size drawn four times larger), plus one for the control grid.
const MAX_DEPTH: usize = arena_len_levels(2) + 1;

/// The most grids [`stored_values`] stores for any model at the largest leaf size enlarged
/// `2^enlarge_log2` times.
const fn arena_len_levels(enlarge_log2: u32) -> usize {
    let (mut max, mut i) = (0, 0);
    while i < MODELS.len() {
        let levels = stored_values(MODELS[i], MAX_LEAF_LOG2 as u32 + enlarge_log2)
            / MODELS[i].control_count();
        if levels > max {
            max = levels;
        }
        i += 1;
    }
    max
}

/// Side of the lattice of a tile's points: its pixels and the points on its far edges.
const LATTICE: usize = TILE + 1;

/// The points of a tile (or the row rule's points of a refinement window), by row.
type Lattice = [[i16; LATTICE]; LATTICE];

/// Where a grid lies in the output: its top-left point and the output pixels between its
/// points (at least 1).
#[derive(Debug, Clone, Copy)]
struct Square {
    x: u32,
    y: u32,
    sp: u32,
}

impl Square {
    /// The square of child grid `(i, j)` of a grid with `m` intervals refined by `n`.
    fn child(&self, m: u32, n: u32, i: u32, j: u32) -> Square {
        let sp = self.sp >> n.trailing_zeros();
        Square {
            x: self.x + j * m * sp,
            y: self.y + i * m * sp,
            sp,
        }
    }
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

/// Rows `r0 ..` and columns `c0 ..` of a refined `lattice` into `out` (`rows` rows of `cols`
/// points): the last step of [`Patch::tile`].
#[inline(always)]
fn take_rows<P: Point>(
    out: &mut [P],
    lattice: &Lattice,
    r0: usize,
    c0: usize,
    rows: usize,
    cols: usize,
) {
    for j in 0..rows {
        if let (Some(dst), Some(src)) =
            (out.get_mut(j * cols..j * cols + cols), lattice.get(r0 + j))
        {
            P::take(dst, &src[c0.min(TILE)..]);
        }
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

/// One tile of a strip of [`Patch::emit`]: its rows `first, first + stride, ...` (`rows`
/// of them, in refined points of the grid), `cols` points a row, made from the old rows of
/// the strip's store whose first is old row `k_lo`.
struct Strip {
    first: usize,
    stride: usize,
    k_lo: usize,
    rows: usize,
    cols: usize,
}

impl Patch {
    /// A flat bilinear patch at zero (a placeholder to reconstruct into).
    pub const EMPTY: Patch = Patch {
        model: crate::model::MODELS[0],
        control: [0; MAX_CONTROL],
    };

    /// Renders the pixels of the leaf `node` that fall inside `clip`, tile by tile, into
    /// `sink`, stopping at the sink's first error. The leaf must be at least as wide as the
    /// grid has intervals, and at most 2^15 px (otherwise nothing is drawn); a decoded leaf
    /// satisfies [`ModelType::fits_block`].
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
        let g = &self.control[..self.model.control_count()];
        if at.sp * u32::from(m) > TILE as u32 {
            if k > 0 {
                self.walk_large(at, &mut job)
            } else {
                self.walk_root(at, &mut job)
            }
        } else if at.sp == 1 {
            self.tile(g, &at, &mut job, None)
        } else {
            self.tile_root(g, &at, &mut job)
        }
    }

    /// [`Patch::tile`] with a lattice of its own (out of line, so that the lattice is not on
    /// the stack while a larger leaf is drawn).
    #[inline(never)]
    fn tile_root(&self, g: &[i16], at: &Square, job: &mut Job<'_>) -> Result<(), Stop> {
        let mut lattice: Lattice = [[0; LATTICE]; LATTICE];
        if at.sp <= u32::from(self.model.transforms) {
            return self.emit(g, at, job, &mut lattice);
        }
        self.tile(g, at, job, Some(&mut lattice))
    }

    /// [`Patch::walk`] from the control grid of a leaf larger than a tile, with the arena of
    /// the coded size (out of line, so that a leaf that fits a tile clears neither).
    #[inline(never)]
    fn walk_root(&self, at: Square, job: &mut Job<'_>) -> Result<(), Stop> {
        let mut lattice: Lattice = [[0; LATTICE]; LATTICE];
        let mut arena = [0i16; ARENA_LEN];
        let n2 = self.model.control_count();
        self.walk(&self.control[..n2], &mut arena, at, job, &mut lattice)
    }

    /// [`Patch::walk_root`] with the arena of a decode at up to four times the coded size
    /// (out of line: only enlarged decodes need its extra stack).
    #[inline(never)]
    fn walk_large(&self, at: Square, job: &mut Job<'_>) -> Result<(), Stop> {
        let mut lattice: Lattice = [[0; LATTICE]; LATTICE];
        let mut arena = [0i16; ARENA_LARGE_LEN];
        let n2 = self.model.control_count();
        self.walk(&self.control[..n2], &mut arena, at, job, &mut lattice)
    }

    /// Draws the pixels of grid `root` (its square `at`) inside the clip, depth first without
    /// recursion: a square that fits a tile is refined whole ([`Patch::tile`]); a larger one
    /// whose points are at most `N` pixels apart is refined once, tile by tile
    /// ([`Patch::emit`]); any other is subdivided, the child grid of depth `d` stored in the
    /// `d`-th grid of `arena` while it is drawn (a child grid is drawn before its next sibling
    /// is made). `lattice` is scratch space.
    fn walk(
        &self,
        root: &[i16],
        arena: &mut [i16],
        at: Square,
        job: &mut Job<'_>,
        lattice: &mut Lattice,
    ) -> Result<(), Stop> {
        let m = u32::from(self.model.intervals);
        let n = u32::from(self.model.transforms);
        let shift = self.model.transforms_log2();
        let n2 = self.model.control_count();
        // Per depth: the grid's corner (as an offset from the root's: a leaf drawn at most four
        // times larger is at most 2^9 pixels a side) and the next of its children to visit (N^2:
        // done); its points are `at.sp >> (depth log2 N)` pixels apart.
        let root_at = at;
        let mut corners = [(0u16, 0u16); MAX_DEPTH];
        let mut next = [0u8; MAX_DEPTH];
        let done = (n * n) as u8;
        let mut depth = 0;
        let mut entering = true;
        loop {
            let (dx, dy) = corners[depth];
            let at = Square {
                x: root_at.x + u32::from(dx),
                y: root_at.y + u32::from(dy),
                sp: root_at.sp >> (shift * depth as u32),
            };
            let ext = m * at.sp;
            if entering {
                entering = false;
                let grid = match depth {
                    0 => root,
                    d => arena.get((d - 1) * n2..d * n2).unwrap_or(&[]),
                };
                if !job.clip.overlaps_square(at.x, at.y, ext) {
                    next[depth] = done;
                } else if at.sp <= n {
                    self.emit(grid, &at, job, lattice)?;
                    next[depth] = done;
                } else if ext <= TILE as u32 {
                    self.tile(grid, &at, job, Some(lattice))?;
                    next[depth] = done;
                } else {
                    next[depth] = 0;
                }
            }
            if next[depth] >= done || depth + 1 >= MAX_DEPTH || arena.len() < (depth + 1) * n2 {
                // This grid is done: back to its parent's next child.
                if depth == 0 {
                    return Ok(());
                }
                depth -= 1;
                continue;
            }
            let c = u32::from(next[depth]);
            next[depth] += 1;
            let (i, j) = (c >> shift, c & (n - 1));
            let child_at = at.child(m, n, i, j);
            if !job
                .clip
                .overlaps_square(child_at.x, child_at.y, ext >> shift)
            {
                continue;
            }
            let (parents, children) = arena.split_at_mut(depth * n2);
            let parent = match depth {
                0 => root,
                d => parents.get((d - 1) * n2..).unwrap_or(&[]),
            };
            let Some(child) = children.get_mut(..n2) else {
                return Ok(());
            };
            self.child(parent, i as usize, j as usize, lattice, child);
            depth += 1;
            corners[depth] = (
                (child_at.x - root_at.x) as u16,
                (child_at.y - root_at.y) as u16,
            );
            entering = true;
        }
    }

    /// Draws a square of grid `g` that fits a tile, as one tile: places the grid's points in
    /// `lattice` (the tile's points) and refines them level by level ([`Patch::level`]) down
    /// to one pixel apart, then hands on the part inside the clip. A grid whose points are one
    /// pixel apart is its pixels (no lattice needed).
    #[inline(never)]
    fn tile(
        &self,
        g: &[i16],
        at: &Square,
        job: &mut Job<'_>,
        lattice: Option<&mut Lattice>,
    ) -> Result<(), Stop> {
        let m = usize::from(self.model.intervals);
        let n = usize::from(self.model.transforms);
        let side = m + 1;
        let sp = at.sp as usize;
        let ext = m * sp;
        let square = Rect {
            x: at.x,
            y: at.y,
            w: ext as u32,
            h: ext as u32,
        };
        let area = square.intersect(&job.clip);
        if area.is_empty() || ext > TILE || g.len() < side * side {
            return Ok(());
        }
        let (c0, r0) = ((area.x - at.x) as usize, (area.y - at.y) as usize);
        let (cols, rows) = (area.w as usize, area.h as usize);
        let len = cols * rows;
        let Some(lattice) = lattice.filter(|_| sp > 1) else {
            // A pixel grid: its points are the pixels.
            return self.points(g, at, ext as u32, 1, job);
        };
        for row in 0..side {
            let dst = &mut lattice[(row * sp).min(TILE)];
            for col in 0..side {
                dst[(col * sp).min(TILE)] = g.get(row * side + col).copied().unwrap_or(0);
            }
        }
        let mut d = sp;
        while d > 1 {
            let nd = if d >= n {
                d >> self.model.transforms_log2()
            } else {
                1
            };
            if nd == 1 {
                // The last level: only the pixels inside the clip.
                let (last_row, last_col) = (r0 + rows - 1, c0 + cols - 1);
                self.level(lattice, d, nd, ext, (r0, last_row), (c0, last_col));
            } else {
                self.level(lattice, d, nd, ext, (0, ext), (0, ext));
            }
            d = nd;
        }
        with_rows!(job, |out| take_rows(out, lattice, r0, c0, rows, cols));
        job.put(area, len)
    }

    /// One subdivision level of a tile's lattice: its points `d` apart become points `nd`
    /// apart (`nd = d / N`; or 1 when `d < N`, the points of phases that are multiples of
    /// `N / d`), each child grid (`m` intervals, `m d` pixels) refined on its own, mirrored at
    /// its ends. Only the points in rows `rows` and columns `cols` (inclusive bounds) are
    /// made, with the row rule's points they are made from.
    fn level(
        &self,
        lattice: &mut Lattice,
        d: usize,
        nd: usize,
        ext: usize,
        rows: (usize, usize),
        cols: (usize, usize),
    ) {
        let m = usize::from(self.model.intervals);
        let (shift_n, shift_d) = (self.model.transforms_log2(), d.trailing_zeros());
        let phase = |offset: usize| Phase::of((offset << shift_n) >> shift_d, shift_n);
        let intervals = (ext >> shift_d).min(TILE);
        let last = m - 1;
        // The lattice positions of the taps of interval k: points k - 1 ..= k + 2 of its child
        // grid, mirrored at the child grid's ends.
        let taps_of = |k: usize| {
            let a = k & (m - 1);
            let before = if a == 0 { k + 1 } else { k.wrapping_sub(1) };
            let after = if a == last { k } else { k + 2 };
            [before, k, k + 1, after].map(|t| (t * d).min(TILE))
        };
        let (c_lo, c_hi) = (cols.0, cols.1.min(TILE));
        let (r_lo, r_hi) = (rows.0, rows.1.min(TILE));
        // The row rule on the old rows the needed rows are made from, in place (it writes
        // between the points it reads), one new column at a time.
        let first = ((r_lo >> shift_d).saturating_sub(1)) << shift_d;
        let end = (((r_hi >> shift_d) + 2) << shift_d).min(ext);
        let mut offset = nd;
        while offset < d {
            let phase = phase(offset);
            with_rule!(phase.kind(), |rule| {
                for k in 0..intervals {
                    let x = k * d + offset;
                    if (c_lo..=c_hi).contains(&x) {
                        along(rule, lattice, x, phase.orient(taps_of(k)), first, end, d);
                    }
                }
            });
            offset += nd;
        }
        // The new rows, across the old ones: the column rule on old columns and the cell rule
        // between them are one rule (a tensor product), which makes a whole row.
        let mut offset = nd;
        while offset < d {
            let phase = phase(offset);
            for k in 0..intervals {
                let y = k * d + offset;
                if !(r_lo..=r_hi).contains(&y) {
                    continue;
                }
                if let Some((new, from)) = split_rows(lattice, y, phase.orient(taps_of(k))) {
                    with_rule!(phase.kind(), |rule| across(rule, new, from, c_lo, c_hi, nd));
                }
            }
            offset += nd;
        }
    }

    /// Draws the square of grid `g` (points at most `N` pixels apart, larger than a tile) in
    /// strips of [`TILE`] columns, each cut into tiles: each pixel is the refined point of `g`
    /// at stride `N / sp`. The row rule makes a strip's columns on every old row it needs, once
    /// (into `h`); then each tile row is an old row's or, across four old rows, the column or
    /// cell rule's, made straight into pixels.
    #[inline(never)]
    fn emit(&self, g: &[i16], at: &Square, job: &mut Job<'_>, h: &mut Lattice) -> Result<(), Stop> {
        let m = usize::from(self.model.intervals);
        let side = m + 1;
        let shift = self.model.transforms_log2();
        let (x, y, sp) = (at.x, at.y, at.sp);
        let ext = u32::from(self.model.intervals) * sp;
        let stride = (u32::from(self.model.transforms) >> sp.trailing_zeros()).max(1) as usize;
        let clip = job.clip;
        let x_lo = x.max(clip.x);
        let y_lo = y.max(clip.y);
        let x_hi = (u64::from(x) + u64::from(ext)).min(clip.right()) as u32;
        let y_hi = (u64::from(y) + u64::from(ext)).min(clip.bottom()) as u32;
        if x_lo >= x_hi || y_lo >= y_hi || g.len() < side * side {
            return Ok(());
        }
        // The old rows the strip's rows need: a - 1 ..= a + 2 around each row's.
        let k_lo = (((y_lo - y) as usize * stride) >> shift).saturating_sub(1);
        let k_hi = ((((y_hi - 1 - y) as usize * stride) >> shift) + 2).min(m);
        let mut pad = [0i16; LATTICE + 3];
        let mut tx = x_lo;
        while tx < x_hi {
            let tw = (x_hi - tx).min(TILE as u32);
            let cols = tw as usize;
            let q2 = (tx - x) as usize * stride;
            for (k, dst) in (k_lo..=k_hi).zip(h.iter_mut()) {
                let Some(row) = g.get(k * side..k * side + side) else {
                    return Ok(());
                };
                fill_pad(&mut pad, row);
                self.row_points(&pad, q2, stride, &mut dst[..cols]);
            }
            let mut ty = y_lo;
            while ty < y_hi {
                let th = (y_hi - ty).min(TILE as u32);
                let strip = Strip {
                    first: (ty - y) as usize * stride,
                    stride,
                    k_lo,
                    rows: th as usize,
                    cols,
                };
                with_rows!(job, |out| self.strip_rows(out, h, &strip));
                let area = Rect {
                    x: tx,
                    y: ty,
                    w: tw,
                    h: th,
                };
                job.put(area, (tw * th) as usize)?;
                ty += th;
            }
            tx += tw;
        }
        Ok(())
    }

    /// The rows of one tile of [`Patch::emit`]'s strip into `out` (`strip.cols` points a
    /// row): each an old row of `h` or, across four of them, the column or cell rule's.
    #[inline(always)]
    fn strip_rows<P: Point>(&self, out: &mut [P], h: &Lattice, strip: &Strip) {
        let m = usize::from(self.model.intervals);
        let shift = self.model.transforms_log2();
        let mask = (1usize << shift) - 1;
        let (cols, k_lo) = (strip.cols, strip.k_lo);
        for j in 0..strip.rows {
            let Some(out) = out.get_mut(j * cols..j * cols + cols) else {
                break;
            };
            let q1 = strip.first + j * strip.stride;
            let (a1, r1) = ((q1 >> shift).min(m), q1 & mask);
            if r1 == 0 {
                if let Some(row) = h.get(a1.wrapping_sub(k_lo)) {
                    P::take(out, row);
                }
                continue;
            }
            let at = |t| h.get(crate::model::tap_point(a1, t, m).wrapping_sub(k_lo));
            let (Some(v0), Some(v1), Some(v2), Some(v3)) = (at(0), at(1), at(2), at(3)) else {
                continue;
            };
            self.new_row(out, [v0, v1, v2, v3], r1);
        }
    }

    /// The refined points of a padded old row `pad` (its points `1..=m+1`, mirrored end points
    /// at 0 and `m + 2`) at columns `q2, q2 + stride, ...`, one per entry of `out`.
    fn row_points(&self, pad: &[i16; LATTICE + 3], q2: usize, stride: usize, out: &mut [i16]) {
        let shift = self.model.transforms_log2();
        let mask = (1usize << shift) - 1;
        // An old point first (every strip and child grid starts on one): whole intervals at
        // a time, each from its four taps, the rules' taps constants.
        if q2 & mask == 0 {
            let taps = pad.get(q2 >> shift..).unwrap_or(&[]);
            if shift == 2 && stride == 1 {
                return quarters(taps, out);
            }
            if stride << 1 == mask + 1 {
                return halves(taps, out);
            }
        }
        let mut q = q2;
        for v in out.iter_mut() {
            let Some(&[p0, p1, p2, p3]) = pad.get(q >> shift..(q >> shift) + 4) else {
                return;
            };
            *v = match q & mask {
                0 => p1,
                r => match Phase::of(r, shift) {
                    Phase::Half => Half::apply(Line, p0, p1, p2, p3),
                    Phase::Quarter => Quarter::apply(Line, p0, p1, p2, p3),
                    Phase::ThreeQuarters => ThreeQuarters::apply(Line, p0, p1, p2, p3),
                },
            };
            q += stride;
        }
    }

    /// A new row at row phase `r1` (1 or more) from the old rows `from` (each holding the
    /// columns `q2, q2 + stride, ...`), as pixels or samples: one rule for the whole row (the
    /// column rule and the cell rules are the line rule of phase `r1`).
    #[inline(never)]
    fn new_row<P: Point>(&self, out: &mut [P], from: [&[i16; LATTICE]; 4], r1: usize) {
        let phase = Phase::of(r1, self.model.transforms_log2());
        with_rule!(phase.kind(), |rule| P::across(
            rule,
            out,
            phase.orient(from)
        ));
    }

    /// Child grid `(i, j)` of grid `g` (one subdivision of the whole grid; `out` holds
    /// `(m + 1)^2` values, row-major): the row rule gives its columns on the old rows it needs
    /// (into `h`), then each row is an old row's or the column or cell rule's across four old
    /// rows.
    #[inline(never)]
    fn child(&self, g: &[i16], i: usize, j: usize, h: &mut Lattice, out: &mut [i16]) {
        let m = usize::from(self.model.intervals);
        let side = m + 1;
        let shift = self.model.transforms_log2();
        let mask = (1usize << shift) - 1;
        let (q1, q2) = (i * m, j * m);
        let k_lo = (q1 >> shift).saturating_sub(1);
        let k_hi = (((q1 + m) >> shift) + 2).min(m);
        let mut pad = [0i16; LATTICE + 3];
        for (k, dst) in (k_lo..=k_hi).zip(h.iter_mut()) {
            let Some(row) = g.get(k * side..k * side + side) else {
                return;
            };
            fill_pad(&mut pad, row);
            self.row_points(&pad, q2, 1, &mut dst[..side.min(LATTICE)]);
        }
        for r in 0..side {
            let Some(dst) = out.get_mut(r * side..r * side + side) else {
                break;
            };
            let q = q1 + r;
            let (a1, r1) = ((q >> shift).min(m), q & mask);
            if r1 == 0 {
                if let Some(row) = h.get(a1.wrapping_sub(k_lo)) {
                    copy_short(dst, row);
                }
                continue;
            }
            let at = |t| h.get(crate::model::tap_point(a1, t, m).wrapping_sub(k_lo));
            let (Some(v0), Some(v1), Some(v2), Some(v3)) = (at(0), at(1), at(2), at(3)) else {
                continue;
            };
            self.new_row(dst, [v0, v1, v2, v3], r1);
        }
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
    use crate::model::{default_line_taps, tap_point, SAMPLE_ONE};
    use core::convert::Infallible;
    use std::vec;
    use std::vec::Vec;

    /// The line rules with constant taps are the models' rules: each tap times
    /// `2^(12 - SHIFT)` is the model's tap at that phase, and the sums round alike.
    #[test]
    fn line_rules_are_the_models() {
        fn taps<const A: i32, const B: i32, const C: i32, const D: i32, const S: u32>(
            _: Line<A, B, C, D, S>,
        ) -> [i32; 4] {
            [A, B, C, D].map(|t| t << (12 - S))
        }
        for model in MODELS {
            let n = usize::from(model.transforms);
            let shift = model.transforms_log2();
            for r in 1..n {
                let want = crate::model::Rules::of(model).taps[r - 1].map(i32::from);
                let got = match Phase::of(r, shift) {
                    Phase::Half => {
                        let rule: Half = Line;
                        taps(rule)
                    }
                    Phase::Quarter => {
                        let rule: Quarter = Line;
                        taps(rule)
                    }
                    Phase::ThreeQuarters => {
                        let rule: ThreeQuarters = Line;
                        taps(rule)
                    }
                };
                assert_eq!(got, want, "model {model:?}, phase {r}");
                // The loop its kind compiles makes the same sum from the oriented values.
                let by_kind = with_rule!(Phase::of(r, shift).kind(), |rule| taps(rule));
                assert_eq!(Phase::of(r, shift).orient(by_kind), want, "phase {r}");
                assert_eq!(want, default_line_taps(model.transforms, r));
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

    /// The arena is sized by a formula: every model at every leaf size it may code must still
    /// deliver every pixel (a short arena would silently skip sub-grids).
    #[test]
    fn arena_covers_every_model_and_leaf_size() {
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
