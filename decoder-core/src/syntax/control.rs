//! Control-value coding: the control quantisers' steps, the 2-D DCT of a control grid ("grid
//! transform") with its coding order and steps, the pixel-grid layout. What the syntax reads is
//! turned into control values here.

use crate::format::{load, store};
#[cfg(doc)]
use crate::model::ModelType;
#[cfg(doc)]
use crate::model::MODELS;
use crate::model::{MAX_CONTROL, MAX_GRID};

/// Largest number of band levels of a control grid (a side of 9: 9, 5, 3, 2, 1).
pub const MAX_GRID_LEVELS: usize = 4;

/// The sides of the nested squares that group a control grid's coefficients into band levels
/// (frequencies rising with the row and column), from the grid's side down to 1, and the
/// number of levels: `n, ceil(n/2), ...`.
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

/// The band level of position `(r, c)` of a control grid of side `side`: 0 for the highest
/// frequencies, up to the number of levels for the grid's mean at `(0, 0)`.
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

/// Where the detail coefficients of band level at most 1, and of level 0 (the finest), begin
/// in the coding order of a coded grid of side `side` ([`transform_order`], which runs from the
/// coarsest level to the finest): positions past the low band's first, so that the details
/// are coded in runs of one level class each.
pub fn fine_starts(side: usize) -> [usize; 2] {
    let k = usize::from(GRID_SLOTS[side.min(MAX_GRID)]);
    let [medium, fine] = FINE_STARTS.get(k).copied().unwrap_or_default();
    [usize::from(medium), usize::from(fine)]
}

/// [`fine_starts`] of every coded grid side.
const FINE_STARTS: [[u8; 2]; GRID_SIDES.len()] = {
    let mut out = [[0u8; 2]; GRID_SIDES.len()];
    let mut k = 0;
    while k < GRID_SIDES.len() {
        let side = GRID_SIDES[k];
        let scan = transform_scan(side);
        let n = side * side;
        let mut starts = [n as u8; 2];
        // Backwards, so that each start ends at the first position of its levels.
        let mut j = n;
        while j > 1 {
            j -= 1;
            let i = scan[j] as usize;
            let level = band_level_of(side, i / side, i % side);
            if level <= 1 {
                starts[0] = j as u8;
            }
            if level == 0 {
                starts[1] = j as u8;
            }
        }
        out[k] = starts;
        k += 1;
    }
    out
};

/// [`band_levels`] of every coded grid side.
const BAND_LEVELS: [u8; GRID_TABLE_LEN] = per_side_table(GridTable::BandLevels);

/// The coding order of a control grid of side `side` under the grid transform: the mean `(0,
/// 0)` first, then for each band level from the lowest frequencies to the highest its
/// positions, in raster order. Entries are row-major grid indices; entries
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

/// The cosines of the inverse DCT in 1/4096, one row per frequency: `round(4096 sqrt(2) cos(pi
/// (2t + 1) k / 2n))` for frequency `k > 0` at point `t` of a line of `n` points, 4096 for `k =
/// 0` (so that coefficient 0 is the mean of a line and every other basis line has a mean
/// square of one). Rows 0 to 7 are those of `n = 8` (also `n = 4` and 2: every second and
/// fourth row), rows 8 to 16 those of `n = 9` (also `n = 3`: every third), rows 17 to 21
/// those of `n = 5`; points past `n` are 0. Each row is symmetric (even `k`) or antisymmetric
/// (odd `k`) about its middle, exactly.
const COSINES: [[i16; MAX_GRID]; 22] = [
    [4096, 4096, 4096, 4096, 4096, 4096, 4096, 4096, 0],
    [5681, 4816, 3218, 1130, -1130, -3218, -4816, -5681, 0],
    [5352, 2217, -2217, -5352, -5352, -2217, 2217, 5352, 0],
    [4816, -1130, -5681, -3218, 3218, 5681, 1130, -4816, 0],
    [4096, -4096, -4096, 4096, 4096, -4096, -4096, 4096, 0],
    [3218, -5681, 1130, 4816, -4816, -1130, 5681, -3218, 0],
    [2217, -5352, 5352, -2217, -2217, 5352, -5352, 2217, 0],
    [1130, -3218, 4816, -5681, 5681, -4816, 3218, -1130, 0],
    [4096, 4096, 4096, 4096, 4096, 4096, 4096, 4096, 4096],
    [5705, 5017, 3723, 1981, 0, -1981, -3723, -5017, -5705],
    [5443, 2896, -1006, -4437, -5793, -4437, -1006, 2896, 5443],
    [5017, 0, -5017, -5017, 0, 5017, 5017, 0, -5017],
    [4437, -2896, -5443, 1006, 5793, 1006, -5443, -2896, 4437],
    [3723, -5017, -1981, 5705, 0, -5705, 1981, 5017, -3723],
    [2896, -5793, 2896, 2896, -5793, 2896, 2896, -5793, 2896],
    [1981, -5017, 5705, -3723, 0, 3723, -5705, 5017, -1981],
    [1006, -2896, 4437, -5443, 5793, -5443, 4437, -2896, 1006],
    [4096, 4096, 4096, 4096, 4096, 0, 0, 0, 0],
    [5509, 3405, 0, -3405, -5509, 0, 0, 0, 0],
    [4686, -1790, -5793, -1790, 4686, 0, 0, 0, 0],
    [3405, -5509, 0, 5509, -3405, 0, 0, 0, 0],
    [1790, -4686, 5793, -4686, 1790, 0, 0, 0, 0],
];

/// Where the cosine rows of a line of `n` points start in [`COSINES`], and how many rows apart
/// its frequencies are (`None` for another length).
fn cosine_rows(n: usize) -> Option<(usize, usize)> {
    match n {
        2 => Some((0, 4)),
        3 => Some((8, 3)),
        4 => Some((0, 2)),
        5 => Some((17, 1)),
        8 => Some((0, 1)),
        9 => Some((8, 1)),
        _ => None,
    }
}

/// The inverse DCT of the `n` coefficients of `g` at `start`, `start + stride`, ... (`n` from 2
/// to 9): point `t` becomes `(2048 + sum_k X_k C_n(k, t)) >> 12`, saturated to `i16` (at most 9
/// products of a 16-bit value and a cosine below 2^13, and the rounding, fit 32 bits). The
/// sums over even and odd frequencies are made for the first half of the points only, the
/// second half's being their difference (the rows' symmetry); zero coefficients are skipped,
/// and a line without any is left as it is (all zero: what the sums give). Whether the line
/// had a coefficient that is not zero.
fn inverse_dct_line(g: &mut [i16; MAX_CONTROL], start: usize, stride: usize, n: usize) -> bool {
    let Some((first_row, every)) = cosine_rows(n) else {
        return false;
    };
    if start + (n - 1) * stride >= MAX_CONTROL {
        return false;
    }
    let half = n.div_ceil(2);
    // Per point of the first half: the sums over even and over odd frequencies (one array,
    // cleared at once).
    let mut sums = [0i32; 2 * HALF_LINE];
    let (even, odd) = sums.split_at_mut(HALF_LINE);
    let mut any = false;
    let mut row = first_row;
    for k in 0..n {
        let x = i32::from(load(g, start + k * stride));
        if x != 0 {
            any = true;
            let Some(cosines) = COSINES.get(row) else {
                return false;
            };
            let sums = if k % 2 == 0 { &mut *even } else { &mut *odd };
            match half {
                1 => accumulate::<1>(sums, x, cosines),
                2 => accumulate::<2>(sums, x, cosines),
                3 => accumulate::<3>(sums, x, cosines),
                4 => accumulate::<4>(sums, x, cosines),
                _ => accumulate::<5>(sums, x, cosines),
            }
        }
        row += every;
    }
    if !any {
        return false;
    }
    for (t, (&e, &o)) in even.iter().zip(odd.iter()).enumerate().take(half) {
        let e = e + 2048;
        store(g, start + t * stride, narrow((e + o) >> 12));
        store(g, start + (n - 1 - t) * stride, narrow((e - o) >> 12));
    }
    true
}

/// Points in the first half of the longest line.
const HALF_LINE: usize = MAX_GRID.div_ceil(2);

/// Adds `x` times the first `H` cosines of a row to `sums` (a loop of known length, unrolled).
#[inline(never)]
fn accumulate<const H: usize>(sums: &mut [i32], x: i32, cosines: &[i16; MAX_GRID]) {
    for (sum, &c) in sums.iter_mut().zip(cosines).take(H) {
        *sum += x * i32::from(c);
    }
}

/// `v` saturated to the `i16` range.
#[inline]
fn narrow(v: i32) -> i16 {
    // One unsigned compare for the values in range, as they nearly always are.
    if (v.wrapping_sub(i32::from(i16::MIN)) as u32) <= u32::from(u16::MAX) {
        v as i16
    } else if v < 0 {
        i16::MIN
    } else {
        i16::MAX
    }
}

/// Inverse transform of a control grid of side `side` (2 to 9, row-major): the 2-D inverse
/// DCT, every column (`inverse_dct_line`), then every row. Works in place on 16-bit values
/// (saturating), so that a decoder needs no wider copy of the grid; a grid without any
/// coefficient is left as it is.
pub fn inverse_grid_transform(g: &mut [i16; MAX_CONTROL], side: usize) {
    let mut any = false;
    for j in 0..side {
        any |= inverse_dct_line(g, j, side, side);
    }
    if any {
        for j in 0..side {
            inverse_dct_line(g, j * side, 1, side);
        }
    }
}

/// Fixed-point scale of grid multipliers: a multiplier `b` scales a step by `b / 64`.
pub const MULTIPLIER_ONE: i32 = 64;

/// The step multiplier of the coefficients of a control grid of side `side`, in units of
/// [`MULTIPLIER_ONE`]: `64 / side`, rounded. A unit coefficient makes control values of a mean
/// square of one (coefficient 0 a constant grid, every other a basis grid of mean square one),
/// `side^2` of them, so every coefficient adds the same error to the control values per step,
/// and a step of `s` in the coefficients adds what a step of `s` in each value would.
pub fn grid_multiplier(side: usize) -> i32 {
    // A table rather than a division (a library call on a Cortex-M0).
    const MULTIPLIERS: [u8; MAX_GRID + 1] = {
        let mut out = [0u8; MAX_GRID + 1];
        let mut n = 1;
        while n <= MAX_GRID {
            out[n] = ((2 * MULTIPLIER_ONE as usize + n) / (2 * n)) as u8;
            n += 1;
        }
        out
    };
    i32::from(MULTIPLIERS.get(side).copied().unwrap_or(0))
}

/// The quantiser step of the coefficients of a control grid of side `side` for the control
/// step `step`: `max(2, (step * grid_multiplier(side) + 32) >> 6)` (at least 2, so that a
/// grid's indices stay within what an integer codes).
pub fn coefficient_step(side: usize, step: i32) -> i32 {
    ((step * grid_multiplier(side) + MULTIPLIER_ONE / 2) >> 6).max(2)
}

/// Number of control-value quantisers (the 'cquant' element, coded on 4 bits).
pub const CONTROL_QUANTISERS: usize = 16;
/// Control step of each control quantiser ('cquant' value), in sample units (1/16 grey level):
/// version 20's fourteen steps, then the two finer ones version 21 gave its unused values.
pub const CONTROL_STEPS: [i32; CONTROL_QUANTISERS] = [
    24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048, 16, 12,
];
/// The control quantisers ('cquant' values) from the finest step to the coarsest.
pub const QUANTISERS_BY_STEP: [u8; CONTROL_QUANTISERS] =
    [15, 14, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13];

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

    /// The inverse DCT of a line is the specification's sum, `(2048 + sum_k X_k C_n(k, t)) >>
    /// 12` saturated, for every line length, coefficients small, large and saturating, sparse
    /// and dense; and the cosine rows are symmetric or antisymmetric about their middle, which
    /// the half-line sums rely on.
    #[test]
    fn the_inverse_dct_is_the_sum_of_its_definition() {
        let mut seed = 11u32;
        let mut next = move || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed >> 8
        };
        for n in [2usize, 3, 4, 5, 8, 9] {
            let (first, every) = cosine_rows(n).unwrap();
            let c = |k: usize, t: usize| i32::from(COSINES[first + k * every][t]);
            for k in 0..n {
                for t in 0..n {
                    let mirrored = if k % 2 == 0 { c(k, t) } else { -c(k, t) };
                    assert_eq!(c(k, n - 1 - t), mirrored, "n {n}, k {k}, t {t}");
                }
            }
            for trial in 0..2000 {
                let mut g = [0i16; MAX_CONTROL];
                let scale = [16, 1 << 10, 1 << 15][trial % 3];
                for v in g.iter_mut().take(n) {
                    if next() % 3 == 0 {
                        *v = ((next() % (2 * scale)) as i32 - scale as i32).clamp(-32768, 32767)
                            as i16;
                    }
                }
                let mut expected = [0i16; MAX_GRID];
                for (t, e) in expected.iter_mut().enumerate().take(n) {
                    let sum: i32 = (0..n).map(|k| i32::from(g[k]) * c(k, t)).sum();
                    *e = ((2048 + sum) >> 12).clamp(-32768, 32767) as i16;
                }
                let had = g[..n].iter().any(|&v| v != 0);
                assert_eq!(inverse_dct_line(&mut g, 0, 1, n), had);
                assert_eq!(&g[..n], &expected[..n], "n {n}");
            }
        }
    }

    /// Every coefficient of a grid adds the same error per step: a unit coefficient anywhere
    /// makes control values whose energy gives the side's multiplier (`64 / sqrt(E)` in units
    /// of the coefficient), within the cosines' rounding.
    #[test]
    fn every_coefficient_has_the_grids_multiplier() {
        const UNIT: i16 = 1 << 12;
        for side in GRID_SIDES {
            for i in 0..side * side {
                let mut g = [0i16; MAX_CONTROL];
                g[i] = UNIT;
                inverse_grid_transform(&mut g, side);
                let energy: f64 = g.iter().map(|&v| f64::from(v).powi(2)).sum();
                let multiplier = f64::from(MULTIPLIER_ONE) * f64::from(UNIT) / energy.sqrt();
                assert_eq!(
                    multiplier.round() as i32,
                    grid_multiplier(side),
                    "{side}: {i}"
                );
            }
        }
    }

    /// Control values anywhere in the sample range make coefficients (but the mean) whose
    /// indices, at every grid side's finest coefficient step, an integer codes (below
    /// `2^MAX_PREFIX`): `|X_kl| <= a_k a_l (SAMPLE_MAX - SAMPLE_MIN) / 2`, with `a_k` the mean
    /// magnitude of cosine row `k` (a coefficient other than the mean ignores a constant).
    #[test]
    fn the_finest_step_keeps_indices_codable() {
        use crate::entropy::MAX_PREFIX;
        use crate::model::{SAMPLE_MAX, SAMPLE_MIN};
        for side in GRID_SIDES {
            let (first, every) = cosine_rows(side).unwrap();
            let mean_magnitude = |k: usize| {
                let row = &COSINES[first + k * every][..side];
                row.iter().map(|&c| f64::from(c).abs()).sum::<f64>() / (4096.0 * side as f64)
            };
            let largest = (0..side * side)
                .skip(1)
                .map(|i| mean_magnitude(i / side) * mean_magnitude(i % side))
                .fold(0.0, f64::max);
            let half_range = f64::from(SAMPLE_MAX - SAMPLE_MIN) / 2.0;
            let q = coefficient_step(side, CONTROL_STEPS[usize::from(QUANTISERS_BY_STEP[0])]);
            let index = largest * half_range / f64::from(q);
            assert!(index < f64::from(1 << MAX_PREFIX), "side {side}: {index}");
        }
    }

    /// The quantisers by step are every quantiser once, their steps rising.
    #[test]
    fn quantisers_by_step_rise() {
        let steps = QUANTISERS_BY_STEP.map(|cq| CONTROL_STEPS[usize::from(cq)]);
        assert!(steps.windows(2).all(|w| w[0] < w[1]), "{steps:?}");
        let mut seen = QUANTISERS_BY_STEP;
        seen.sort_unstable();
        assert!(seen.iter().enumerate().all(|(i, &cq)| usize::from(cq) == i));
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
            }
        }
    }
}
