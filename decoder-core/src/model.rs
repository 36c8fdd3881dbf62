//! The patch models: projected IFS given in subdivision-scheme form, and their quantisers.
//!
//! A model type is a control grid of `(m+1) x (m+1)` values and `N x N` subdivision transforms.
//! One subdivision step maps a control grid onto the `(N*m+1) x (N*m+1)` grid of its `N x N`
//! sub-grids; each sub-grid is again a control grid, subdivided with the same transforms
//! (thesis II.1.4.2: exact tabulation by recursive subdivision). The transforms are given as
//! *rules* (thesis II.2.1.3): the subdivided grid keeps the old points (interpolating scheme),
//! a new point on an old grid line is a barycentric combination of the four nearest points of
//! that line (mirrored at the line's ends: [`tap_point`]), and a new point inside an old cell
//! is a barycentric combination of the new points at its column phase on the four nearest old
//! rows (the line rule again, across the rows: a tensor product).
//! Rules depend on the phase `r = q mod N` of the new point only, so every transform matrix is
//! barycentric, a sub-grid's border depends only on that border (the raccord condition holds by
//! construction), and a breadth-first and a depth-first evaluation give identical values.

/// Fixed-point scale of weights: a weight `w` is stored as `w * 4096`.
pub const WEIGHT_ONE: i32 = 1 << WEIGHT_BITS;
/// Fractional bits of weights.
pub const WEIGHT_BITS: u32 = 12;
/// Largest magnitude of a free (coded) weight, `2.0`.
pub const WEIGHT_LIMIT: i32 = 2 * WEIGHT_ONE;
/// Fixed-point scale of samples: a grey level `g` is stored as `g * 16`.
pub const SAMPLE_ONE: i32 = 1 << SAMPLE_BITS;
/// Fractional bits of samples.
pub const SAMPLE_BITS: u32 = 4;
/// Smallest representable sample value (grey level -256).
pub const SAMPLE_MIN: i32 = -256 * SAMPLE_ONE;
/// Largest representable sample value (grey level 511.9375).
pub const SAMPLE_MAX: i32 = 512 * SAMPLE_ONE - 1;

/// Largest control grid side (`m + 1`).
pub const MAX_GRID: usize = 9;
/// Largest number of control values of a model.
pub const MAX_CONTROL: usize = MAX_GRID * MAX_GRID;
/// Largest number of free weights of a model.
pub const MAX_WEIGHTS: usize = 45;
/// Number of model types.
pub const MODEL_COUNT: usize = 5;

/// A model type: `(m+1)^2` control values and `N^2` subdivision transforms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelType {
    /// Intervals of the control grid per side (`m`).
    pub intervals: u8,
    /// Transforms per side (`N`, 2 or 4).
    pub transforms: u8,
}

/// The model types, indexed by the 'model' syntax element.
///
/// Type 0 is the degenerate bilinear patch (2x2 control values, fixed weights); types 1-4 are the
/// thesis's four (III.2.2).
pub const MODELS: [ModelType; MODEL_COUNT] = [
    ModelType {
        intervals: 1,
        transforms: 2,
    },
    ModelType {
        intervals: 2,
        transforms: 2,
    },
    ModelType {
        intervals: 4,
        transforms: 2,
    },
    ModelType {
        intervals: 4,
        transforms: 4,
    },
    ModelType {
        intervals: 8,
        transforms: 4,
    },
];

impl ModelType {
    /// Side of the control grid, `m + 1`.
    pub const fn grid(self) -> usize {
        self.intervals as usize + 1
    }

    /// Number of control values.
    pub const fn control_count(self) -> usize {
        self.grid() * self.grid()
    }

    /// Number of free line weights (both directions, all phases).
    pub const fn line_weight_count(self) -> usize {
        if self.intervals < 2 {
            0
        } else {
            2 * (self.transforms as usize - 1) * 3
        }
    }

    /// Number of free cell weights (all phase pairs).
    pub const fn cell_weight_count(self) -> usize {
        if self.intervals < 2 {
            0
        } else {
            let p = self.transforms as usize - 1;
            p * p * 3
        }
    }

    /// Number of free weights.
    pub const fn weight_count(self) -> usize {
        self.line_weight_count() + self.cell_weight_count()
    }

    /// Whether leaves of this model choose their control coding (the 'transform' flag): all
    /// but the bilinear model, whose four values the transform does not help.
    pub const fn has_coding_choice(self) -> bool {
        self.intervals >= 2
    }

    /// Whether this model may code a block of side `2^log2`: its control points must be at
    /// least one pixel apart. At one pixel apart (a *pixel grid*: the control values are the
    /// block's pixels and nothing is subdivided, see [`ModelType::coded_side`]) only the first
    /// model with that grid side may, as the others would draw the same patch.
    pub const fn fits_block(self, log2: u8) -> bool {
        if log2 >= 16 {
            return false;
        }
        let size = 1u32 << log2;
        let m = self.intervals as u32;
        size >= 2 * m || (size == m && self.is_first_of_its_grid())
    }

    /// Whether a leaf of side `2^log2` subdivides this model's control grid at least once
    /// (its control points are at least two pixels apart): only then do its weights shape
    /// the patch (and get coded).
    pub const fn subdivides(self, log2: u8) -> bool {
        log2 < 16 && (1u32 << log2) >= 2 * self.intervals as u32
    }

    /// Pixels between neighbouring control points on a leaf of side `2^log2` (which this
    /// model fits, [`ModelType::fits_block`]).
    pub const fn spacing(self, log2: u8) -> u32 {
        let size = if log2 < 16 { 1u32 << log2 } else { 1 << 15 };
        size / self.intervals as u32
    }

    /// Side of the grid of control values a leaf of side `2^log2` codes: the whole control
    /// grid (`m + 1`) where it subdivides; on a pixel grid only the block's own `m x m` pixels
    /// (the row and column past the block, which draw nothing, repeat the last ones:
    /// [`expand_pixel_grid`]).
    pub const fn coded_side(self, log2: u8) -> usize {
        if self.subdivides(log2) {
            self.grid()
        } else {
            self.intervals as usize
        }
    }

    /// Whether no model before this one in [`MODELS`] has the same control grid.
    const fn is_first_of_its_grid(self) -> bool {
        let mut i = 0;
        while i < MODEL_COUNT {
            if MODELS[i].intervals == self.intervals {
                return MODELS[i].transforms == self.transforms;
            }
            i += 1;
        }
        false
    }
}

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

/// The transform level of position `(r, c)` of a control grid of side `side`: 0 for the
/// finest detail band, up to the number of levels for the single low-band value at `(0, 0)`.
pub const fn band_level(side: usize, r: usize, c: usize) -> usize {
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
            if band_level(side, i / side, i % side) == k {
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
    &table[usize::from(GRID_OFFSETS[k])..usize::from(GRID_OFFSETS[k + 1])]
}

/// What a per-side table holds.
#[derive(Clone, Copy)]
enum GridTable {
    /// [`transform_scan`].
    Scans,
    /// [`band_multipliers`].
    BandMultipliers,
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
            values[r * side + c] = values[r * m + c];
        }
        values[r * side + m] = values[r * side + m - 1];
    }
    for c in 0..side {
        values[m * side + c] = values[(m - 1) * side + c];
    }
}

/// Row-major order: the coding order of DPCM control values.
pub const RASTER_ORDER: [u8; MAX_CONTROL] = raster_order();

const fn raster_order() -> [u8; MAX_CONTROL] {
    let mut out = [0u8; MAX_CONTROL];
    let mut i = 0;
    while i < MAX_CONTROL {
        out[i] = i as u8;
        i += 1;
    }
    out
}

/// One inverse lifting step of the reversible 5/3 wavelet (LeGall, as in JPEG 2000's
/// lossless path, with symmetric extension) on the `m` values of `g` at `start`, `start +
/// stride`, ...: low-band values first, then high-band values; replaced by the signal, each
/// value saturated to the `i16` range it is stored in.
const fn inverse_line(g: &mut [i16; MAX_CONTROL], start: usize, stride: usize, m: usize) {
    let nl = m.div_ceil(2);
    let nh = m / 2;
    let mut y = [0i32; MAX_GRID];
    let mut i = 0;
    while i < m {
        y[i] = g[start + i * stride] as i32;
        i += 1;
    }
    let mut x = [0i32; MAX_GRID];
    // Even samples: low band minus the update from the neighbouring details.
    i = 0;
    while i < nl {
        let (left, right) = if nh == 0 {
            (0, 0)
        } else {
            let l = if i == 0 { 0 } else { i - 1 };
            let r = if i < nh { i } else { nh - 1 };
            (y[nl + l], y[nl + r])
        };
        x[2 * i] = y[i].saturating_sub(left.saturating_add(right).saturating_add(2) >> 2);
        i += 1;
    }
    // Odd samples: detail plus the prediction from the neighbouring even samples.
    i = 0;
    while i < nh {
        let right = if 2 * i + 2 < m {
            x[2 * i + 2]
        } else {
            x[2 * i]
        };
        x[2 * i + 1] =
            y[nl + i].saturating_add(x[2 * i].saturating_add(right).saturating_add(1) >> 1);
        i += 1;
    }
    i = 0;
    while i < m {
        let v = x[i];
        g[start + i * stride] = if v > i16::MAX as i32 {
            i16::MAX
        } else if v < i16::MIN as i32 {
            i16::MIN
        } else {
            v as i16
        };
        i += 1;
    }
}

/// Inverse transform of a control grid of side `side` (row-major): the coefficients of every
/// level, coarsest first, are turned back into control values. Level `k` works on the top-left
/// square of side `grid_sizes(side).0[k]`: columns first, then rows. Works in place on 16-bit
/// values (saturating), so that a decoder needs no wider copy of the grid.
pub const fn inverse_grid_transform(g: &mut [i16; MAX_CONTROL], side: usize) {
    let (sizes, levels) = grid_sizes(side);
    let mut k = levels;
    while k > 0 {
        k -= 1;
        let m = sizes[k];
        let mut j = 0;
        while j < m {
            inverse_line(g, j, side, m);
            j += 1;
        }
        j = 0;
        while j < m {
            inverse_line(g, j * side, 1, m);
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
    let table = grid_entries(&BAND_MULTIPLIERS, side);
    let mult = i32::from(table.get(i).copied().unwrap_or(0));
    ((step * mult + BAND_ONE / 2) >> 6).max(1)
}

/// Number of control-value quantisers (the 'cquant' element, coded on 4 bits).
pub const CONTROL_QUANTISERS: usize = 14;
/// Control step of each control quantiser, in sample units (1/16 grey level).
pub const CONTROL_STEPS: [i32; CONTROL_QUANTISERS] = [
    24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048,
];

/// Number of weight quantisers (the 'wquant' element, 2 bits).
pub const WEIGHT_QUANTISERS: usize = 4;

/// How the free weights of a leaf are quantised.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WeightQuantiser {
    /// No weights coded: the smooth default scheme.
    Default,
    /// Uniform: deviation from the default is `index * step` (weight units).
    Uniform(i32),
    /// Lloyd-Max: deviation from the default is a level of the stream's codebook.
    Codebook,
}

/// The weight quantiser of each 'wquant' value.
pub const WEIGHT_QUANTISER_KINDS: [WeightQuantiser; WEIGHT_QUANTISERS] = [
    WeightQuantiser::Default,
    WeightQuantiser::Uniform(WEIGHT_ONE / 32),
    WeightQuantiser::Uniform(WEIGHT_ONE / 8),
    WeightQuantiser::Codebook,
];

/// Weight classes, each with its own contexts and Lloyd-Max codebook.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WeightClass {
    /// Rules for new points on grid lines.
    Line = 0,
    /// Rules for new points inside grid cells.
    Cell = 1,
}

/// Default line rule taps for phase `r` of `N` transforms, weights on line points
/// `a-1, a, a+1, a+2`: 4-point interpolation that reproduces straight lines, with side lobes
/// twice those of cubic interpolation (midpoint `(-1, 5, 5, -1) / 8` instead of
/// `(-1, 9, 9, -1) / 16`; quarter points `(-448, 3648, 1216, -320)` instead of
/// `(-224, 3360, 1120, -160)`): these code photographs better than the cubic taps and than
/// side lobes of other sizes (see docs/decisions.md).
pub const fn default_line_taps(n: u8, r: usize) -> [i32; 4] {
    match (n, r) {
        (4, 1) => [-448, 3648, 1216, -320],
        (4, 3) => [-320, 1216, 3648, -448],
        _ => [-512, 2560, 2560, -512],
    }
}

/// Default cell rule taps for phases `(r1, r2)` of `N` transforms, weights on the new points at
/// column phase `r2` of old rows `a1-1, a1, a1+1, a1+2`: the line rule of row phase `r1`, so
/// that the default scheme is the tensor product of the line rules (a blend of the new points
/// on the cell's four sides cannot reproduce a quadratic; see docs/decisions.md).
pub const fn default_cell_taps(n: u8, r1: usize, _r2: usize) -> [i32; 4] {
    default_line_taps(n, r1)
}

/// The point of a line of points `0..=m` (`m >= 1`) that tap `t` of a rule for the interval
/// `a..a+1` weighs: point `a + t - 1`, mirrored at the line's ends (point `-1` is point 1,
/// point `m + 1` is point `m - 1`). Mirroring rather than repeating the end point or
/// extrapolating the line: it codes photographs best (see docs/decisions.md).
#[inline]
pub const fn tap_point(a: usize, t: usize, m: usize) -> usize {
    let j = a + t;
    if j == 0 {
        1
    } else if j > m + 1 {
        2 * m + 1 - j
    } else {
        j - 1
    }
}

/// The tap of a rule that is not coded: it makes the taps sum to one.
pub const LINE_DEPENDENT_TAP: usize = 1;
/// The tap of a cell rule that is not coded.
pub const CELL_DEPENDENT_TAP: usize = 0;

/// Fully expanded subdivision weights of one patch, in weight units (Q12).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Weights {
    /// `line[dir][r-1]`: taps for new points on horizontal (`dir` 0, along a row) and vertical
    /// (`dir` 1, along a column) lines at phase `r`.
    pub line: [[[i16; 4]; 3]; 2],
    /// `cell[r1-1][r2-1]`: taps for new points at row phase `r1` and column phase `r2`, on the
    /// new points at column phase `r2` of old rows `a1-1, a1, a1+1, a1+2` ([`tap_point`]).
    pub cell: [[[i16; 4]; 3]; 3],
}

/// A rule's taps in 16 bits (every tap of a balanced rule fits: free taps are at most
/// [`WEIGHT_LIMIT`] in magnitude, so the dependent one is at most `WEIGHT_ONE + 3 *
/// WEIGHT_LIMIT`), which halves a patch's weights on a decoder's stack.
const fn narrow(taps: [i32; 4]) -> [i16; 4] {
    [
        taps[0] as i16,
        taps[1] as i16,
        taps[2] as i16,
        taps[3] as i16,
    ]
}

impl Weights {
    /// The smooth default scheme of model `model`.
    pub fn default_for(model: ModelType) -> Self {
        let n = model.transforms;
        let mut w = Weights {
            line: [[[0; 4]; 3]; 2],
            cell: [[[0; 4]; 3]; 3],
        };
        for r in 1..n as usize {
            w.line[0][r - 1] = narrow(default_line_taps(n, r));
            w.line[1][r - 1] = narrow(default_line_taps(n, r));
            for r2 in 1..n as usize {
                w.cell[r - 1][r2 - 1] = narrow(default_cell_taps(n, r, r2));
            }
        }
        w
    }

    /// Builds the weights of `model` from the deviations of its free taps from the default
    /// (`deviations.len() >= model.weight_count()`, in the canonical order of
    /// [`for_each_free_tap`]). Free taps are clamped to `[-WEIGHT_LIMIT, WEIGHT_LIMIT]`, and each
    /// rule's dependent tap makes its taps sum to exactly [`WEIGHT_ONE`].
    pub fn from_deviations(model: ModelType, deviations: &[i32]) -> Self {
        let mut w = Self::default_for(model);
        let mut i = 0;
        for_each_free_tap(model, |slot| {
            w.deviate(slot, deviations.get(i).copied().unwrap_or(0));
            i += 1;
        });
        w.balance();
        w
    }

    /// Adds `deviation` to the free tap `slot`, clamped to `[-WEIGHT_LIMIT, WEIGHT_LIMIT]`.
    pub fn deviate(&mut self, slot: TapSlot, deviation: i32) {
        let tap = self.tap_mut(slot);
        *tap = i32::from(*tap)
            .saturating_add(deviation)
            .clamp(-WEIGHT_LIMIT, WEIGHT_LIMIT) as i16;
    }

    /// Sets every rule's dependent tap so that its taps sum to exactly [`WEIGHT_ONE`].
    pub fn balance(&mut self) {
        for rule in self.line.iter_mut().flatten() {
            rule[LINE_DEPENDENT_TAP] = 0;
            let s: i32 = rule.iter().map(|&t| i32::from(t)).sum();
            rule[LINE_DEPENDENT_TAP] = (WEIGHT_ONE - s) as i16;
        }
        for rule in self.cell.iter_mut().flatten() {
            rule[CELL_DEPENDENT_TAP] = 0;
            let s: i32 = rule.iter().map(|&t| i32::from(t)).sum();
            rule[CELL_DEPENDENT_TAP] = (WEIGHT_ONE - s) as i16;
        }
    }

    /// The tap addressed by `slot`.
    pub fn tap_mut(&mut self, slot: TapSlot) -> &mut i16 {
        match slot {
            TapSlot::Line { dir, phase, tap } => &mut self.line[dir][phase - 1][tap],
            TapSlot::Cell { r1, r2, tap } => &mut self.cell[r1 - 1][r2 - 1][tap],
        }
    }
}

/// Address of one free weight.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TapSlot {
    /// A line-rule tap.
    Line {
        /// 0: horizontal lines, 1: vertical lines.
        dir: usize,
        /// Phase `r` in `1..N`.
        phase: usize,
        /// Tap index 0..4 (never the dependent one).
        tap: usize,
    },
    /// A cell-rule tap.
    Cell {
        /// Row phase `r1` in `1..N`.
        r1: usize,
        /// Column phase `r2` in `1..N`.
        r2: usize,
        /// Tap index 0..4 (never the dependent one).
        tap: usize,
    },
}

impl TapSlot {
    /// The coefficient class of this weight.
    pub fn class(self) -> WeightClass {
        match self {
            TapSlot::Line { .. } => WeightClass::Line,
            TapSlot::Cell { .. } => WeightClass::Cell,
        }
    }
}

/// Visits the free taps of `model` in canonical (coding) order: line rules (horizontal then
/// vertical, phases ascending, taps ascending), then cell rules (row phase, column phase, taps).
pub fn for_each_free_tap(model: ModelType, mut f: impl FnMut(TapSlot)) {
    if model.weight_count() == 0 {
        return;
    }
    let n = model.transforms as usize;
    for dir in 0..2 {
        for phase in 1..n {
            for tap in (0..4).filter(|&t| t != LINE_DEPENDENT_TAP) {
                f(TapSlot::Line { dir, phase, tap });
            }
        }
    }
    for r1 in 1..n {
        for r2 in 1..n {
            for tap in (0..4).filter(|&t| t != CELL_DEPENDENT_TAP) {
                f(TapSlot::Cell { r1, r2, tap });
            }
        }
    }
}

/// Rounded division of a sample value by a quantiser step (ties away from zero); used for
/// prediction in the index domain.
pub fn div_round(v: i32, step: i32) -> i32 {
    if v >= 0 {
        (v + step / 2) / step
    } else {
        -((-v + step / 2) / step)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
