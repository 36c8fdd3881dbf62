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

// [`ModelType::spacing`] divides by a model's interval count with a shift.
const _: () = {
    let mut i = 0;
    while i < MODELS.len() {
        assert!(MODELS[i].intervals.is_power_of_two());
        i += 1;
    }
};

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
        // Every model's interval count is a power of two: a shift, not a division.
        size >> self.intervals.trailing_zeros()
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
        // A copy of a table built at compile time (a leaf's weights start from it).
        DEFAULT_WEIGHTS[usize::from(model.transforms == 4)]
    }

    /// [`Weights::default_for`] the models of `n` transforms.
    const fn default_of(n: u8) -> Self {
        let mut w = Weights {
            line: [[[0; 4]; 3]; 2],
            cell: [[[0; 4]; 3]; 3],
        };
        let mut r = 1;
        while r < n as usize {
            w.line[0][r - 1] = narrow(default_line_taps(n, r));
            w.line[1][r - 1] = narrow(default_line_taps(n, r));
            let mut r2 = 1;
            while r2 < n as usize {
                w.cell[r - 1][r2 - 1] = narrow(default_cell_taps(n, r, r2));
                r2 += 1;
            }
            r += 1;
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

/// The default weights of the models of two and of four transforms.
const DEFAULT_WEIGHTS: [Weights; 2] = [Weights::default_of(2), Weights::default_of(4)];

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
