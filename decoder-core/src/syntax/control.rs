//! Control-value coding: the control quantisers' steps, the reversible 5/3 wavelet of a
//! control grid ("grid transform") with its coding order and per-band steps, the pixel-grid
//! layout. What the syntax reads is turned into control values here.

use crate::format::{load, store};
#[cfg(doc)]
use crate::model::ModelType;
#[cfg(doc)]
use crate::model::MODELS;
use crate::model::{MAX_CONTROL, MAX_GRID};

/// Largest number of transform levels of a control grid (a side of 9: 9, 5, 3, 2, 1).
pub const MAX_GRID_LEVELS: usize = 4;

/// The sides of a control grid's low band after each transform level, from the grid's side
/// down to 1, and the number of levels: `n, ceil(n/2), ...`.
pub const fn grid_sizes(side: usize) -> ([usize; MAX_GRID_LEVELS + 1], usize) {
    let mut sizes = [1usize; MAX_GRID_LEVELS + 1];
    sizes[0] = side;
    let mut k = 0;
    while sizes[k] > 1 && k < MAX_GRID_LEVELS {
        sizes[k + 1] = sizes[k].div_ceil(2);
        k += 1;
    }
    (sizes, k)
}

/// Row and column of the row-major index `i` of a grid of side `side` (at most [`MAX_GRID`]):
/// `(i / side, i % side)` by a multiply and a shift (no division, which a Cortex-M0 lacks):
/// `i * ceil(1024 / side) >> 10` is `i / side` exactly for every index of such a grid.
#[inline]
pub fn grid_position(i: usize, side: usize) -> (usize, usize) {
    const RECIPROCALS: [u16; MAX_GRID + 1] = {
        let mut out = [0u16; MAX_GRID + 1];
        let mut s = 1;
        while s <= MAX_GRID {
            out[s] = 1024u32.div_ceil(s as u32) as u16;
            s += 1;
        }
        out
    };
    let Some(&reciprocal) = RECIPROCALS.get(side) else {
        return (0, 0);
    };
    let r = (i * usize::from(reciprocal)) >> 10;
    (r, i.wrapping_sub(r * side))
}

/// The transform level of position `(r, c)` of a control grid of side `side`: 0 for the
/// finest detail band, up to the number of levels for the single low-band value at `(0, 0)`.
/// A table lookup for the coded grid sides.
pub const fn band_level(side: usize, r: usize, c: usize) -> usize {
    if r < side && c < side && side <= MAX_GRID && GRID_SIDES[GRID_SLOTS[side] as usize] == side {
        let at = GRID_OFFSETS[GRID_SLOTS[side] as usize] as usize + r * side + c;
        return BAND_LEVELS[at] as usize;
    }
    band_level_of(side, r, c)
}

/// [`band_level`], computed.
const fn band_level_of(side: usize, r: usize, c: usize) -> usize {
    let (sizes, levels) = grid_sizes(side);
    let mut k = 0;
    while k < levels {
        if r >= sizes[k + 1] || c >= sizes[k + 1] {
            return k;
        }
        k += 1;
    }
    levels
}

/// The band level of every position of a grid of side `side` ([`band_level_of`]).
const fn band_levels(side: usize) -> [u8; MAX_CONTROL] {
    let mut out = [0u8; MAX_CONTROL];
    let mut i = 0;
    while i < side * side {
        out[i] = band_level_of(side, i / side, i % side) as u8;
        i += 1;
    }
    out
}

/// [`band_level`] of every position of a coded grid of side `side`, row-major.
pub fn band_level_table(side: usize) -> &'static [u8] {
    grid_entries(&BAND_LEVELS, side)
}

/// [`band_levels`] of every coded grid side.
const BAND_LEVELS: [u8; GRID_TABLE_LEN] = per_side_table(GridTable::BandLevels);

/// The coding order of a control grid of side `side` under the grid transform: the low-band
/// value `(0, 0)` first, then for each level from the coarsest to the finest the positions that
/// become detail at that level, in raster order. Entries are row-major grid indices; entries
/// past `side * side` are unused.
const fn transform_scan(side: usize) -> [u8; MAX_CONTROL] {
    let mut out = [0u8; MAX_CONTROL];
    let mut n = 0;
    let (_, levels) = grid_sizes(side);
    let mut k = levels + 1;
    while k > 0 {
        k -= 1;
        let mut i = 0;
        while i < side * side {
            if band_level_of(side, i / side, i % side) == k {
                out[n] = i as u8;
                n += 1;
            }
            i += 1;
        }
    }
    out
}

/// The sides of the coded grids ([`ModelType::coded_side`]): the models' grids (2, 3, 5, 9)
/// and their pixel grids (2, 4, 8), in the order of the per-side tables below.
const GRID_SIDES: [usize; 6] = [2, 3, 4, 5, 8, 9];

/// Where each side's entries start in the per-side tables, which hold `side * side` entries
/// per side, one side after the other; the last entry is their total length (199: bytes keep
/// the table small in flash).
const GRID_OFFSETS: [u8; GRID_SIDES.len() + 1] = grid_offsets();

const fn grid_offsets() -> [u8; GRID_SIDES.len() + 1] {
    let mut out = [0u8; GRID_SIDES.len() + 1];
    let mut k = 0;
    while k < GRID_SIDES.len() {
        out[k + 1] = out[k] + (GRID_SIDES[k] * GRID_SIDES[k]) as u8;
        k += 1;
    }
    out
}

/// Total length of a per-side table.
const GRID_TABLE_LEN: usize = GRID_OFFSETS[GRID_SIDES.len()] as usize;

/// The slot in [`GRID_SIDES`] of each side up to [`MAX_GRID`] (the largest grid's for a side
/// that is not there).
const GRID_SLOTS: [u8; MAX_GRID + 1] = grid_slots();

const fn grid_slots() -> [u8; MAX_GRID + 1] {
    let mut out = [(GRID_SIDES.len() - 1) as u8; MAX_GRID + 1];
    let mut k = 0;
    while k < GRID_SIDES.len() {
        out[GRID_SIDES[k]] = k as u8;
        k += 1;
    }
    out
}

/// The entries of side `side` in a per-side table (the largest grid's for any other side).
fn grid_entries(table: &[u8; GRID_TABLE_LEN], side: usize) -> &[u8] {
    let k = usize::from(GRID_SLOTS[side.min(MAX_GRID)]);
    let (start, end) = (GRID_OFFSETS[k], GRID_OFFSETS[k + 1]);
    table
        .get(usize::from(start)..usize::from(end))
        .unwrap_or_default()
}

/// What a per-side table holds.
#[derive(Clone, Copy)]
enum GridTable {
    /// [`transform_scan`].
    Scans,
    /// [`band_multipliers`].
    BandMultipliers,
    /// [`band_levels`].
    BandLevels,
}

/// A per-side table: the first `side * side` entries of `table` for every side of
/// [`GRID_SIDES`], one after the other.
const fn per_side_table(table: GridTable) -> [u8; GRID_TABLE_LEN] {
    let mut out = [0u8; GRID_TABLE_LEN];
    let mut k = 0;
    while k < GRID_SIDES.len() {
        let entries = match table {
            GridTable::Scans => transform_scan(GRID_SIDES[k]),
            GridTable::BandMultipliers => band_multipliers(GRID_SIDES[k]),
            GridTable::BandLevels => band_levels(GRID_SIDES[k]),
        };
        let mut i = 0;
        while i < GRID_SIDES[k] * GRID_SIDES[k] {
            out[GRID_OFFSETS[k] as usize + i] = entries[i];
            i += 1;
        }
        k += 1;
    }
    out
}

/// [`transform_scan`] of every coded grid side.
const TRANSFORM_SCANS: [u8; GRID_TABLE_LEN] = per_side_table(GridTable::Scans);

/// The coding order of the coefficients of a control grid of side `side` under the grid
/// transform (see [`band_level`]): the row-major indices of its `side * side` positions.
pub fn transform_order(side: usize) -> &'static [u8] {
    grid_entries(&TRANSFORM_SCANS, side)
}

/// Spreads the `m x m` values of a pixel grid (row-major, side `m`: [`ModelType::coded_side`])
/// over the model's control grid of side `m + 1`, in place: the row and column past the block,
/// which draw nothing, repeat the last ones.
pub fn expand_pixel_grid(values: &mut [i16; MAX_CONTROL], m: usize) {
    if m == 0 || m >= MAX_GRID {
        return;
    }
    let side = m + 1;
    // Backwards: every value moves to an index at least as large, past the ones still to move.
    for r in (0..m).rev() {
        for c in (0..m).rev() {
            let v = load(values, r * m + c);
            store(values, r * side + c, v);
        }
        let v = load(values, r * side + m - 1);
        store(values, r * side + m, v);
    }
    for c in 0..side {
        let v = load(values, (m - 1) * side + c);
        store(values, m * side + c, v);
    }
}

/// One inverse lifting step of the reversible 5/3 wavelet (LeGall, as in JPEG 2000's
/// lossless path, with symmetric extension) on the `m` values of `g` at `start`, `start +
/// stride`, ...: low-band values first, then high-band values; replaced by the signal, each
/// value saturated to the `i16` range it is stored in. (The intermediate values are sums of a
/// few 16-bit values, so 32 bits hold them exactly.) `y` is scratch space for the band values.
const fn inverse_line(
    g: &mut [i16; MAX_CONTROL],
    y: &mut [i16; MAX_GRID],
    start: usize,
    stride: usize,
    m: usize,
) {
    if m < 2 || m > MAX_GRID || start + (m - 1) * stride >= MAX_CONTROL {
        return;
    }
    let nl = m.div_ceil(2);
    let nh = m / 2;
    // The band values, read once (the signal is written over them).
    let mut i = 0;
    let mut at = start;
    while i < m {
        store(y, i, load(g, at));
        at += stride;
        i += 1;
    }
    // Even samples: low band minus the update from the neighbouring details (mirrored at the
    // ends: d[-1] = d[0], d[nh] = d[nh - 1]); odd samples: detail plus the prediction from the
    // neighbouring even samples (the one to the right is made first; past the end, the one to
    // the left). The last pair, where the mirrors are, is made after the loop.
    let mut detail = load(y, nl) as i32;
    let mut left = y[0] as i32 - ((detail + 1) >> 1);
    store(g, start, narrow(left));
    let mut at = start + stride;
    i = 0;
    while i + 1 < nh {
        let next = load(y, nl + i + 1) as i32;
        let right = load(y, i + 1) as i32 - ((detail + next + 2) >> 2);
        store(g, at, narrow(detail + ((left + right + 1) >> 1)));
        store(g, at + stride, narrow(right));
        at += 2 * stride;
        left = right;
        detail = next;
        i += 1;
    }
    if 2 * nh < m {
        // An odd line ends on an even sample, whose detail to the right is mirrored.
        let right = load(y, nh) as i32 - ((detail + 1) >> 1);
        store(g, at, narrow(detail + ((left + right + 1) >> 1)));
        store(g, at + stride, narrow(right));
    } else {
        store(g, at, narrow(detail + left));
    }
}

/// `v` saturated to the `i16` range.
const fn narrow(v: i32) -> i16 {
    // One unsigned compare for the values in range, as they nearly always are.
    if (v.wrapping_sub(i16::MIN as i32) as u32) <= u16::MAX as u32 {
        v as i16
    } else if v < 0 {
        i16::MIN
    } else {
        i16::MAX
    }
}

/// Inverse transform of a control grid of side `side` (row-major): the coefficients of every
/// level, coarsest first, are turned back into control values. Level `k` works on the top-left
/// square of side `grid_sizes(side).0[k]`: columns first, then rows. Works in place on 16-bit
/// values (saturating), so that a decoder needs no wider copy of the grid.
pub const fn inverse_grid_transform(g: &mut [i16; MAX_CONTROL], side: usize) {
    let (sizes, levels) = grid_sizes(side);
    // One line's band values at a time (cleared once, not per line).
    let mut y = [0i16; MAX_GRID];
    let mut k = levels;
    while k > 0 {
        k -= 1;
        let m = sizes[k];
        let mut j = 0;
        while j < m {
            inverse_line(g, &mut y, j, side, m);
            j += 1;
        }
        j = 0;
        while j < m {
            inverse_line(g, &mut y, j * side, 1, m);
            j += 1;
        }
    }
}

/// Fixed-point scale of band multipliers: a multiplier `b` scales a step by `b / 64`.
pub const BAND_ONE: i32 = 64;

/// Integer square root (floor).
const fn isqrt(v: u64) -> u64 {
    let mut lo = 0u64;
    let mut hi = 1u64 << 32;
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if mid * mid <= v {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The step multipliers of the coefficients of a control grid of side `side`, in units of
/// [`BAND_ONE`]: `64 / sqrt(E)`, rounded, with `E` the energy of the control values that a unit
/// coefficient at that position makes (computed with [`inverse_grid_transform`] on an impulse
/// of `2^12`). Every coefficient then adds the same error to the control values per step.
const fn band_multipliers(side: usize) -> [u8; MAX_CONTROL] {
    const UNIT: i16 = 1 << 12;
    let mut out = [0u8; MAX_CONTROL];
    let mut i = 0;
    while i < side * side {
        let mut g = [0i16; MAX_CONTROL];
        g[i] = UNIT;
        inverse_grid_transform(&mut g, side);
        let mut energy = 0u64;
        let mut j = 0;
        while j < side * side {
            energy += (g[j] as i64 * g[j] as i64) as u64;
            j += 1;
        }
        let root = isqrt(energy);
        let scaled = (BAND_ONE as u64 * UNIT as u64 * 2 + root) / (2 * root);
        out[i] = if scaled > 255 { 255 } else { scaled as u8 };
        i += 1;
    }
    out
}

/// [`band_multipliers`] of every coded grid side.
const BAND_MULTIPLIERS: [u8; GRID_TABLE_LEN] = per_side_table(GridTable::BandMultipliers);

/// The quantiser step of coefficient `i` (row-major) of a control grid of side `side` for the
/// control step `step`: `max(1, (step * multiplier + 32) >> 6)`.
pub fn coefficient_step(side: usize, i: usize, step: i32) -> i32 {
    scaled_step(
        step,
        band_multiplier_table(side).get(i).copied().unwrap_or(0),
    )
}

/// The band multipliers of a coded grid of side `side`, row-major (see `band_multipliers`).
pub fn band_multiplier_table(side: usize) -> &'static [u8] {
    grid_entries(&BAND_MULTIPLIERS, side)
}

/// A control step scaled by a band multiplier: `max(1, (step * multiplier + 32) >> 6)`.
#[inline]
pub fn scaled_step(step: i32, multiplier: u8) -> i32 {
    ((step * i32::from(multiplier) + BAND_ONE / 2) >> 6).max(1)
}

/// Number of control-value quantisers (the 'cquant' element, coded on 4 bits).
pub const CONTROL_QUANTISERS: usize = 14;
/// Control step of each control quantiser, in sample units (1/16 grey level).
pub const CONTROL_STEPS: [i32; CONTROL_QUANTISERS] = [
    24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048,
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::MODELS;

    /// `grid_position` divides exactly for every index of every grid side.
    #[test]
    fn grid_positions_are_divisions() {
        for side in 1..=MAX_GRID {
            for i in 0..side * side {
                assert_eq!(grid_position(i, side), (i / side, i % side), "{i} / {side}");
            }
        }
    }

    /// A pixel grid's `m x m` values land at their grid positions, and the row and column past
    /// the block repeat the last ones.
    #[test]
    fn pixel_grid_expands_to_the_control_grid() {
        for m in [2usize, 4, 8] {
            let mut values = [0i16; MAX_CONTROL];
            for (i, v) in values.iter_mut().take(m * m).enumerate() {
                *v = i as i16 + 1;
            }
            expand_pixel_grid(&mut values, m);
            let side = m + 1;
            for r in 0..side {
                for c in 0..side {
                    let (sr, sc) = (r.min(m - 1), c.min(m - 1));
                    assert_eq!(
                        values[r * side + c],
                        (sr * m + sc) as i16 + 1,
                        "m {m}: ({r}, {c})"
                    );
                }
            }
        }
    }

    /// The per-side tables hold every coded grid side: the coding order of each is a
    /// permutation of its positions, low band first.
    #[test]
    fn every_coded_side_has_its_transform_order() {
        for model in MODELS {
            for log2 in 1..=9u8 {
                if !model.fits_block(log2) {
                    continue;
                }
                let side = model.coded_side(log2);
                let order = transform_order(side);
                assert_eq!(order.len(), side * side, "side {side}");
                let mut seen = [false; MAX_CONTROL];
                for &i in order {
                    assert!(!seen[usize::from(i)], "side {side}: {i} twice");
                    seen[usize::from(i)] = true;
                }
                assert_eq!(order[0], 0);
                assert!(coefficient_step(side, side * side - 1, 256) >= 1);
            }
        }
    }
}
