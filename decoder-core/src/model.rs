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
/// Fixed-point scale of samples: a grey level `g` is stored as `g * 16`.
pub const SAMPLE_ONE: i32 = 1 << SAMPLE_BITS;
pub use crate::format::SAMPLE_BITS;
/// Smallest representable sample value (grey level -256).
pub const SAMPLE_MIN: i32 = -256 * SAMPLE_ONE;
/// Largest representable sample value (grey level 511.9375).
pub const SAMPLE_MAX: i32 = 512 * SAMPLE_ONE - 1;

/// Largest control grid side (`m + 1`).
pub const MAX_GRID: usize = 9;
/// Largest number of control values of a model.
pub const MAX_CONTROL: usize = MAX_GRID * MAX_GRID;
/// Number of model types.
pub const MODEL_COUNT: usize = 4;

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
/// Type 0 is the degenerate bilinear patch (2x2 control values); types 1-3 are three of the
/// thesis's four (III.2.2): its 5x5/4x4 type draws nearly the 5x5/2x2 type's surface with the
/// default rules, so it went with the free weights (format 18, see docs/decisions.md).
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
        intervals: 8,
        transforms: 4,
    },
];

// [`ModelType::spacing`] divides by a model's interval count with a shift,
// [`ModelType::fits_block`] needs every model's control grid to be its own, and every grid fits
// the control arrays ([`ModelType::control_count`]).
const _: () = {
    let mut i = 0;
    while i < MODELS.len() {
        assert!(MODELS[i].intervals.is_power_of_two());
        assert!(MODELS[i].grid() <= MAX_GRID);
        let mut j = 0;
        while j < i {
            assert!(MODELS[j].intervals != MODELS[i].intervals);
            j += 1;
        }
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
        let count = self.grid() * self.grid();
        // Every model's grid fits (a `const` check above); the bound lets the compiler see
        // that the control arrays are indexed within it.
        if count < MAX_CONTROL {
            count
        } else {
            MAX_CONTROL
        }
    }

    /// Whether leaves of this model choose their control coding (the 'transform' flag): all
    /// but the bilinear model, whose four values the transform does not help.
    pub const fn has_coding_choice(self) -> bool {
        self.intervals >= 2
    }

    /// Whether this model may code a block of side `2^log2`: its control points must be at
    /// least one pixel apart (at one pixel apart, a *pixel grid*: the control values are the
    /// block's pixels and nothing is subdivided, see [`ModelType::coded_side`]). No two models
    /// share a control grid, so no two draw the same pixel grid.
    pub const fn fits_block(self, log2: u8) -> bool {
        if log2 >= 16 {
            return false;
        }
        let size = 1u32 << log2;
        let m = self.intervals as u32;
        size >= m
    }

    /// `log2 N`: the shift of one subdivision (a compare rather than a count of trailing zeros,
    /// which a Cortex-M0 makes with a multiply and a table).
    #[inline(always)]
    pub const fn transforms_log2(self) -> u32 {
        match self.transforms {
            2 => 1,
            4 => 2,
            n => n.trailing_zeros(),
        }
    }

    /// Whether a leaf of side `2^log2` subdivides this model's control grid at least once
    /// (its control points are at least two pixels apart); otherwise it is a pixel grid.
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

/// The subdivision rules of the models of `N` transforms, in weight units (Q12): the taps of
/// the line rule of each phase `r` (`taps[r - 1]`), which is also the column rule and the cell
/// rule of row phase `r` (the default scheme is a tensor product). The same for every patch:
/// free weights never paid for their bits (format 18, see docs/decisions.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rules {
    /// Taps on line points `a-1, a, a+1, a+2` ([`tap_point`]) for phases `1..N`.
    pub taps: [[i16; 4]; 3],
}

impl Rules {
    /// The rules of model `model` (a table built at compile time).
    #[inline]
    pub fn of(model: ModelType) -> &'static Rules {
        &RULES[usize::from(model.transforms == 4)]
    }

    /// The rules of the models of `n` transforms (each tap fits 16 bits).
    const fn build(n: u8) -> Rules {
        let mut rules = Rules { taps: [[0; 4]; 3] };
        let mut r = 1;
        while r < n as usize {
            let t = default_line_taps(n, r);
            rules.taps[r - 1] = [t[0] as i16, t[1] as i16, t[2] as i16, t[3] as i16];
            r += 1;
        }
        rules
    }
}

/// The rules of the models of two and of four transforms.
const RULES: [Rules; 2] = [Rules::build(2), Rules::build(4)];
