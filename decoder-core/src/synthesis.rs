//! Patch synthesis: exact tabulation of a projected-IFS patch by recursive subdivision, in
//! integer arithmetic that is bit-exact on every platform.
//!
//! Values are samples in 1/16 grey level ([`SAMPLE_ONE`]); weights are in 1/4096
//! ([`WEIGHT_ONE`]). Every new point is `(sum(tap * value) + 2048) >> 12` (arithmetic shift),
//! clamped to `[SAMPLE_MIN, SAMPLE_MAX]`. With free taps bounded by [`WEIGHT_LIMIT`] the sum of
//! tap magnitudes of a rule is at most `3 * 8192 + 28672 = 53248`, and `53248 * 8192 < 2^31`, so
//! the accumulation never overflows an `i32`.
//!
//! Evaluation is depth-first: a control grid is refined one sub-grid at a time and each sub-grid
//! is refined recursively, so memory is one small grid per level (at most
//! [`ARENA_LEN`] values), independent of the block size. The last level is not stored: pixels are
//! computed directly from the parent grid and handed to the [`PixelSink`] in tiles of at most
//! [`TILE`] x [`TILE`].

use crate::format::MAX_LEAF_LOG2;
use crate::geometry::{Node, Rect};
use crate::model::{
    tap_point, ModelType, Weights, MAX_CONTROL, MAX_GRID, MODELS, SAMPLE_BITS, SAMPLE_MAX,
    SAMPLE_MIN, WEIGHT_BITS,
};
#[cfg(doc)]
use crate::model::{SAMPLE_ONE, WEIGHT_LIMIT, WEIGHT_ONE};

/// Side of the tiles handed to a [`PixelSink`].
pub const TILE: usize = 8;
/// Values of the per-level grid stack below a patch's control grid: the most that any model
/// needs at the largest leaf (9x9 grids on two levels for the 9x9/4x4 model).
pub const ARENA_LEN: usize = arena_len();

/// The stored grids below the control grid when `model` tabulates a leaf of side `2^log2`, in
/// values: one grid per subdivision level whose points are more than `N` pixels apart (the
/// last level goes straight to pixels).
const fn stored_values(model: ModelType, log2: u8) -> usize {
    let n = model.transforms as u32;
    let mut sp = (1u32 << log2) / model.intervals as u32;
    let mut levels = 0;
    while sp > n {
        sp /= n;
        levels += 1;
    }
    levels * model.control_count()
}

const fn arena_len() -> usize {
    let mut max = 0;
    let mut i = 0;
    while i < MODELS.len() {
        let v = stored_values(MODELS[i], MAX_LEAF_LOG2);
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
    /// 8-bit luma, row-major, `area.w * area.h` values.
    pub pixels: &'a [u8],
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
    fn put(&mut self, tile: Tile<'_>) -> Result<(), Stop>;
}

/// Takes every tile and keeps nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Discard;

impl TileOut for Discard {
    fn put(&mut self, _tile: Tile<'_>) -> Result<(), Stop> {
        Ok(())
    }
}

/// A [`PixelSink`] seen as a [`TileOut`]: keeps the sink's first error for [`Catch::finish`].
pub struct Catch<'s, S: PixelSink + ?Sized> {
    sink: &'s mut S,
    error: Option<S::Error>,
}

impl<'s, S: PixelSink + ?Sized> Catch<'s, S> {
    /// Wraps `sink`.
    pub fn new(sink: &'s mut S) -> Self {
        Catch { sink, error: None }
    }

    /// The sink's error if synthesis stopped for it.
    pub fn finish(self, result: Result<(), Stop>) -> Result<(), S::Error> {
        match (result, self.error) {
            (Err(Stop), Some(e)) => Err(e),
            _ => Ok(()),
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
    fn put(&mut self, tile: Tile<'_>) -> Result<(), Stop> {
        self.sink.tile(tile).map_err(|e| {
            self.error = Some(e);
            Stop
        })
    }
}

/// A reconstructed patch: a model type, its control values and its subdivision weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Patch {
    /// The model type.
    pub model: ModelType,
    /// Control values, row-major, `model.grid()` per row, in sample units.
    pub control: [i16; MAX_CONTROL],
    /// The subdivision rules.
    pub weights: Weights,
}

#[inline]
fn round_clamp(acc: i32) -> i32 {
    ((acc + (1 << (WEIGHT_BITS - 1))) >> WEIGHT_BITS).clamp(SAMPLE_MIN, SAMPLE_MAX)
}

/// Converts a sample value to an 8-bit pixel (round to nearest, saturate).
#[inline]
pub fn sample_to_pixel(v: i32) -> u8 {
    ((v + (1 << (SAMPLE_BITS - 1))) >> SAMPLE_BITS).clamp(0, 255) as u8
}

impl Patch {
    /// A flat bilinear patch at zero (a placeholder to reconstruct into).
    pub const EMPTY: Patch = Patch {
        model: crate::model::MODELS[0],
        control: [0; MAX_CONTROL],
        weights: Weights {
            line: [[[0; 4]; 3]; 2],
            cell: [[[0; 4]; 3]; 3],
        },
    };

    /// The refined value at refined coordinates `(q1, q2)` (row, column; `0..=N*m`) of the
    /// control grid `g` (row-major, side `m+1`), point by point as the specification states
    /// it: the reference [`Patch::refine`] is tested against.
    #[cfg(test)]
    fn point(&self, g: &[i16], q1: usize, q2: usize) -> i32 {
        // N is 2 or 4: shifts and masks instead of divisions.
        let shift = self.model.transforms.trailing_zeros();
        let mask = (1usize << shift) - 1;
        let (a1, r1) = (q1 >> shift, q1 & mask);
        let (a2, r2) = (q2 >> shift, q2 & mask);
        match (r1, r2) {
            (0, 0) => i32::from(g[a1 * self.model.grid() + a2]),
            (0, _) => self.line(g, 0, a1, a2, r2),
            (_, 0) => self.line(g, 1, a2, a1, r1),
            _ => {
                // The tensor product: the line rule across the new points of the nearest rows.
                let taps = &self.weights.cell[r1 - 1][r2 - 1];
                let m = self.model.grid() - 1;
                let mut acc = 0i32;
                for (t, &tap) in taps.iter().enumerate() {
                    acc += i32::from(tap) * self.line(g, 0, tap_point(a1, t, m), a2, r2);
                }
                round_clamp(acc)
            }
        }
    }

    /// New point at phase `r` between points `a` and `a+1` of line `fixed` (a row when `dir` is
    /// 0, a column when 1); taps on points `a-1..=a+2`, mirrored at the line's ends.
    #[cfg(test)]
    fn line(&self, g: &[i16], dir: usize, fixed: usize, a: usize, r: usize) -> i32 {
        let side = self.model.grid();
        let m = side - 1;
        let taps = &self.weights.line[dir][r - 1];
        let mut acc = 0i32;
        for (t, &tap) in taps.iter().enumerate() {
            let idx = tap_point(a, t, m);
            let v = if dir == 0 {
                g[fixed * side + idx]
            } else {
                g[idx * side + fixed]
            };
            acc += i32::from(tap) * i32::from(v);
        }
        round_clamp(acc)
    }

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
        let result = self.render_to(node, clip, &mut out);
        out.finish(result)
    }

    /// [`Patch::render`] into a [`TileOut`] trait object.
    #[inline(never)]
    pub fn render_to(&self, node: &Node, clip: Rect, out: &mut dyn TileOut) -> Result<(), Stop> {
        let log2 = node.log2;
        if log2 >= 16 || (1u32 << log2) < u32::from(self.model.intervals) || clip.is_empty() {
            return Ok(());
        }
        let mut arena = [0i16; ARENA_LEN];
        let mut scratch = Scratch::EMPTY;
        let n2 = self.model.control_count();
        let spacing = (1u32 << log2) / u32::from(self.model.intervals);
        let square = Square {
            x: node.x,
            y: node.y,
            sp: spacing,
        };
        self.walk(
            &self.control[..n2],
            &mut arena,
            &square,
            &clip,
            &mut scratch,
            out,
        )
    }

    /// Draws the pixels of grid `g` (its square `at`) inside `clip`: a square that fits an
    /// output tile is filled whole ([`Patch::fill`]) and handed on as one tile; a larger one
    /// is subdivided, each child grid stored at the front of `below` while it is drawn, until
    /// its points are at most `N` pixels apart ([`Patch::emit`]).
    fn walk(
        &self,
        g: &[i16],
        below: &mut [i16],
        at: &Square,
        clip: &Rect,
        scratch: &mut Scratch,
        out: &mut dyn TileOut,
    ) -> Result<(), Stop> {
        let m = u32::from(self.model.intervals);
        let n = u32::from(self.model.transforms);
        let side = self.model.grid();
        let ext = m * at.sp;
        if !clip.overlaps_square(at.x, at.y, ext) {
            return Ok(());
        }
        if ext <= TILE as u32 {
            return self.fill_tile(g, below, at, clip, scratch, out);
        }
        if at.sp <= n {
            return self.emit(g, at, clip, scratch, out);
        }
        let n2 = side * side;
        if below.len() < n2 {
            return Ok(());
        }
        let (child, deeper) = below.split_at_mut(n2);
        for i in 0..n {
            for j in 0..n {
                let child_at = at.child(m, n, i, j);
                if !clip.overlaps_square(child_at.x, child_at.y, ext / n) {
                    continue;
                }
                let window = Window::child(m, i, j);
                self.refine(g, &window, child, side, &mut scratch.h);
                self.walk(child, deeper, &child_at, clip, scratch, out)?;
            }
        }
        Ok(())
    }

    /// Draws a square that fits an output tile: fills its pixels ([`Patch::fill`]) and hands
    /// the part inside `clip` on as one tile.
    #[inline(never)]
    fn fill_tile(
        &self,
        g: &[i16],
        below: &mut [i16],
        at: &Square,
        clip: &Rect,
        scratch: &mut Scratch,
        out: &mut dyn TileOut,
    ) -> Result<(), Stop> {
        let ext = u32::from(self.model.intervals) * at.sp;
        let mut values = [0i16; TILE * TILE];
        self.fill(g, below, at.sp, 0, &mut values, &mut scratch.h);
        let area = Rect {
            x: at.x,
            y: at.y,
            w: ext,
            h: ext,
        }
        .intersect(clip);
        let (dx, dy) = ((area.x - at.x) as usize, (area.y - at.y) as usize);
        let mut k = 0;
        for j in 0..area.h as usize {
            let row = &values[(dy + j) * TILE + dx..(dy + j) * TILE + dx + area.w as usize];
            for &v in row {
                scratch.pixels[k] = sample_to_pixel(i32::from(v));
                k += 1;
            }
        }
        out.put(Tile {
            area,
            pixels: &scratch.pixels[..k],
        })
    }

    /// The pixels of grid `g` (points `sp` pixels apart, `m * sp` at most [`TILE`]) into
    /// `values` from offset `at` (row-major, [`TILE`] per row): refined straight to pixels when
    /// its points are at most `N` apart, else through its child grids (stored at the front of
    /// `below`).
    fn fill(
        &self,
        g: &[i16],
        below: &mut [i16],
        sp: u32,
        at: usize,
        values: &mut [i16; TILE * TILE],
        h: &mut [i16; MAX_GRID * MAX_WINDOW],
    ) {
        let m = u32::from(self.model.intervals);
        let n = u32::from(self.model.transforms);
        let side = self.model.grid();
        if sp <= n {
            let ext = (m * sp) as usize;
            let window = Window {
                q1: 0,
                q2: 0,
                rows: ext,
                cols: ext,
                stride: (n / sp.max(1)) as usize,
            };
            self.refine(g, &window, &mut values[at..], TILE, h);
            return;
        }
        let n2 = side * side;
        if below.len() < n2 {
            return;
        }
        let (child, deeper) = below.split_at_mut(n2);
        let child_ext = (m * sp / n) as usize;
        for i in 0..n {
            for j in 0..n {
                self.refine(g, &Window::child(m, i, j), child, side, h);
                let child_at = at + i as usize * child_ext * TILE + j as usize * child_ext;
                self.fill(child, deeper, sp / n, child_at, values, h);
            }
        }
    }

    /// Emits the `m*sp` square of pixels covered by grid `g` (points at most `N` pixels apart),
    /// each the refined point at stride `N / sp` of `g` ([`Patch::refine`]), tile by tile.
    #[inline(never)]
    fn emit(
        &self,
        g: &[i16],
        at: &Square,
        clip: &Rect,
        scratch: &mut Scratch,
        out: &mut dyn TileOut,
    ) -> Result<(), Stop> {
        let (x, y, sp) = (at.x, at.y, at.sp);
        let ext = u32::from(self.model.intervals) * sp;
        let stride = (u32::from(self.model.transforms) / sp.max(1)) as usize;
        let x_lo = x.max(clip.x);
        let y_lo = y.max(clip.y);
        let x_hi = (u64::from(x) + u64::from(ext)).min(clip.right()) as u32;
        let y_hi = (u64::from(y) + u64::from(ext)).min(clip.bottom()) as u32;
        let mut values = [0i16; TILE * TILE];
        let mut ty = y_lo;
        while ty < y_hi {
            let th = (y_hi - ty).min(TILE as u32);
            let mut tx = x_lo;
            while tx < x_hi {
                let tw = (x_hi - tx).min(TILE as u32);
                let window = Window {
                    q1: (ty - y) as usize * stride,
                    q2: (tx - x) as usize * stride,
                    rows: th as usize,
                    cols: tw as usize,
                    stride,
                };
                self.refine(g, &window, &mut values, tw as usize, &mut scratch.h);
                let k = (tw * th) as usize;
                for (p, &v) in scratch.pixels.iter_mut().zip(&values).take(k) {
                    *p = sample_to_pixel(i32::from(v));
                }
                let area = Rect {
                    x: tx,
                    y: ty,
                    w: tw,
                    h: th,
                };
                out.put(Tile {
                    area,
                    pixels: &scratch.pixels[..k],
                })?;
                tx += tw;
            }
            ty += th;
        }
        Ok(())
    }

    /// The refined points of grid `g` in `window` (see [`Window`]), into `out` row-major,
    /// `out_stride` values per row: each [`Patch::point`], computed separably. First the row
    /// rule gives the window's columns on the old rows its rows need (each row padded with its
    /// mirrored end points, so the taps read four consecutive values), into `h`; then each
    /// point is the old row's value (on an old row), the column rule (on an old column) or the
    /// cell rule (between them) across those: at most four multiply-adds per point. The cell
    /// rule weighs the row rule's rounded points, as [`Patch::point`] does.
    #[inline(never)]
    fn refine(
        &self,
        g: &[i16],
        window: &Window,
        out: &mut [i16],
        out_stride: usize,
        h: &mut [i16; MAX_GRID * MAX_WINDOW],
    ) {
        let m = usize::from(self.model.intervals);
        let side = m + 1;
        let shift = self.model.transforms.trailing_zeros();
        let mask = (1usize << shift) - 1;
        let (rows, cols) = (window.rows.min(MAX_WINDOW), window.cols.min(MAX_WINDOW));
        if rows == 0
            || cols == 0
            || g.len() < side * side
            || out.len() < (rows - 1) * out_stride + cols
        {
            return;
        }
        // Where each column is: the old column before it and its phase.
        let mut col_a = [0u8; MAX_WINDOW];
        let mut col_r = [0u8; MAX_WINDOW];
        for i in 0..cols {
            let q2 = window.q2 + i * window.stride;
            col_a[i] = (q2 >> shift).min(m) as u8;
            col_r[i] = (q2 & mask) as u8;
        }
        // The row rule on the old rows the window needs: a - 1 ..= a + 2 around each row's.
        let q1_last = window.q1 + (rows - 1) * window.stride;
        let k_lo = (window.q1 >> shift).saturating_sub(1);
        let k_hi = ((q1_last >> shift) + 2).min(m);
        let mut padded = [0i16; MAX_GRID + 3];
        for k in k_lo..=k_hi {
            let row = &g[k * side..k * side + side];
            padded[1..=side].copy_from_slice(row);
            padded[0] = row[1.min(m)];
            padded[side + 1] = row[m.saturating_sub(1)];
            let dst = &mut h[(k - k_lo) * MAX_WINDOW..(k - k_lo + 1) * MAX_WINDOW];
            for i in 0..cols {
                let a = usize::from(col_a[i]);
                dst[i] = match col_r[i] {
                    0 => padded[a + 1],
                    r => {
                        let taps = &self.weights.line[0][usize::from(r) - 1];
                        let p = &padded[a..a + 4];
                        rule(taps, [p[0], p[1], p[2], p[3]])
                    }
                };
            }
        }
        // Each point across the old rows.
        for j in 0..rows {
            let q1 = window.q1 + j * window.stride;
            let (a1, r1) = ((q1 >> shift).min(m), q1 & mask);
            let dst = &mut out[j * out_stride..j * out_stride + cols];
            if r1 == 0 {
                let at = (a1 - k_lo) * MAX_WINDOW;
                dst.copy_from_slice(&h[at..at + cols]);
                continue;
            }
            let at = |t: usize| (tap_point(a1, t, m) - k_lo) * MAX_WINDOW;
            let (o0, o1, o2, o3) = (at(0), at(1), at(2), at(3));
            let cell = &self.weights.cell[r1 - 1];
            let sets = [&self.weights.line[1][r1 - 1], &cell[0], &cell[1], &cell[2]];
            for (i, v) in dst.iter_mut().enumerate() {
                let taps = sets[usize::from(col_r[i]) & 3];
                *v = rule(taps, [h[o0 + i], h[o1 + i], h[o2 + i], h[o3 + i]]);
            }
        }
    }
}

/// Where a grid lies in the image: its top-left point and the pixels between its points.
struct Square {
    x: u32,
    y: u32,
    sp: u32,
}

impl Square {
    /// The square of child grid `(i, j)` of a grid with `m` intervals refined by `n`.
    fn child(&self, m: u32, n: u32, i: u32, j: u32) -> Square {
        let csp = self.sp / n;
        Square {
            x: self.x + j * m * csp,
            y: self.y + i * m * csp,
            sp: csp,
        }
    }
}

/// Buffers the synthesis of one patch reuses: the row rule's points for [`Patch::refine`] and
/// an output tile's pixels.
struct Scratch {
    h: [i16; MAX_GRID * MAX_WINDOW],
    pixels: [u8; TILE * TILE],
}

impl Scratch {
    const EMPTY: Scratch = Scratch {
        h: [0; MAX_GRID * MAX_WINDOW],
        pixels: [0; TILE * TILE],
    };
}

/// Largest side of a window of refined points computed at once: a child grid (9) or an output
/// tile (8).
const MAX_WINDOW: usize = if MAX_GRID > TILE { MAX_GRID } else { TILE };

/// A rectangle of refined points of a grid: rows `q1, q1 + stride, ...` (`rows` of them) by
/// columns `q2, q2 + stride, ...` (`cols`), at most [`MAX_WINDOW`] each way.
struct Window {
    q1: usize,
    q2: usize,
    rows: usize,
    cols: usize,
    stride: usize,
}

impl Window {
    /// The points of child grid `(i, j)` of a grid with `m` intervals: its whole grid.
    fn child(m: u32, i: u32, j: u32) -> Window {
        let side = m as usize + 1;
        Window {
            q1: (i * m) as usize,
            q2: (j * m) as usize,
            rows: side,
            cols: side,
            stride: 1,
        }
    }
}

/// A rule's new point: `rc(sum of tap * value)` over its four taps.
#[inline(always)]
fn rule(taps: &[i16; 4], values: [i16; 4]) -> i16 {
    let mut acc = 0i32;
    for (&tap, v) in taps.iter().zip(values) {
        acc += i32::from(tap) * i32::from(v);
    }
    // Clamped to the sample range, which fits in an i16.
    round_clamp(acc) as i16
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::MIN_LEAF_LOG2;
    use crate::model::SAMPLE_ONE;
    use core::convert::Infallible;

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

    /// The separable refinement gives the point-by-point values of the specification, for
    /// every model, window and stride, with random control values and random (also extreme)
    /// weights.
    #[test]
    fn separable_refinement_is_the_specifications_points() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move |range: i32| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % range as u64) as i32
        };
        for model in MODELS {
            for trial in 0..40 {
                let side = model.grid();
                let mut control = [0i16; MAX_CONTROL];
                for v in control.iter_mut().take(side * side) {
                    *v = (next(12288) - 4096) as i16;
                }
                let deviations: [i32; crate::model::MAX_WEIGHTS] = core::array::from_fn(|_| {
                    if trial % 2 == 0 {
                        next(8193) - 4096
                    } else {
                        next(32769) - 16384
                    }
                });
                let patch = Patch {
                    model,
                    control,
                    weights: Weights::from_deviations(model, &deviations),
                };
                let g = &patch.control[..side * side];
                let n = usize::from(model.transforms);
                let full = n * (side - 1) + 1;
                for stride in [1usize, 2, 4] {
                    for _ in 0..8 {
                        let rows = 1 + next(MAX_WINDOW as i32) as usize;
                        let cols = 1 + next(MAX_WINDOW as i32) as usize;
                        let span = |count: usize| (count - 1) * stride;
                        if span(rows) >= full || span(cols) >= full {
                            continue;
                        }
                        let q1 = next((full - span(rows)) as i32) as usize;
                        let q2 = next((full - span(cols)) as i32) as usize;
                        let window = Window {
                            q1,
                            q2,
                            rows,
                            cols,
                            stride,
                        };
                        let mut out = [0i16; MAX_WINDOW * MAX_WINDOW];
                        let mut h = [0i16; MAX_GRID * MAX_WINDOW];
                        patch.refine(g, &window, &mut out, cols, &mut h);
                        for j in 0..rows {
                            for i in 0..cols {
                                let expected = patch.point(g, q1 + j * stride, q2 + i * stride);
                                assert_eq!(
                                    i32::from(out[j * cols + i]),
                                    expected,
                                    "{model:?} window {q1},{q2} {rows}x{cols}/{stride} at {j},{i}"
                                );
                            }
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
            let patch = Patch {
                model,
                control,
                weights: Weights::default_for(model),
            };
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
    /// pixel `(x, y)` is value `(y, x)`, whatever the weights, and the values past the block
    /// draw nothing.
    #[test]
    fn pixel_grids_draw_their_control_values() {
        let mut pixel_grids = 0;
        for model in MODELS {
            let log2 = model.intervals.trailing_zeros() as u8;
            if log2 < MIN_LEAF_LOG2 {
                continue;
            }
            if !model.fits_block(log2) {
                // The 5x5/4x4 model: the 5x5/2x2 model draws the same pixel grid.
                assert_eq!(model, MODELS[3]);
                continue;
            }
            assert!(!model.subdivides(log2), "{model:?}");
            pixel_grids += 1;
            let side = model.grid();
            let mut control = [0i16; MAX_CONTROL];
            for (i, v) in control.iter_mut().take(side * side).enumerate() {
                *v = (SAMPLE_ONE * ((i * 37) % 256) as i32) as i16;
            }
            let mut weights = Weights::default_for(model);
            weights
                .line
                .iter_mut()
                .flatten()
                .flatten()
                .for_each(|t| *t += 500);
            let patch = Patch {
                model,
                control,
                weights,
            };
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
                    weights: Weights::default_for(model),
                };
                let size = 1u32 << log2;
                let mut sink = Count { size, pixels: 0 };
                let Ok(()) = patch.render(&at_origin(log2), Rect::of_size(size, size), &mut sink);
                assert_eq!(sink.pixels, u64::from(size * size), "{model:?} at 2^{log2}");
            }
        }
    }
}
