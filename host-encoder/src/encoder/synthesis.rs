//! Floating-point tabulation of a patch, with derivatives, for fitting: the model the fitter
//! ([`super::fit`]) optimises.
//!
//! Bottom of the encoder's stages: uses only decoder-core's model.
//!
//! It follows decoder-core's integer synthesis rule for rule (same subdivision, same taps, same
//! mirroring of indices at a line's ends), without rounding. Each sample carries a vector: its value, then its
//! derivatives with respect to every control value (the patch is linear in them: they are also
//! its values for unit control values).

use decoder_core::internal::model::{tap_point, ModelType, Rules, WEIGHT_ONE};

/// A patch model ready to be tabulated in floating point.
#[derive(Debug, Clone)]
pub struct Tabulator {
    model: ModelType,
    /// The line rule of each phase (also the column and cell rules), real-valued.
    taps: [[f64; 4]; 3],
    /// Floats per sample: 1 (value only) or `1 + control`.
    k: usize,
    block: u32,
    scratch: Vec<Vec<f64>>,
}

impl Tabulator {
    /// Prepares `model` and, when `derivatives` is set, derivative tracking.
    pub fn new(model: ModelType, derivatives: bool) -> Self {
        let taps = Rules::of(model)
            .taps
            .map(|rule| rule.map(|t| f64::from(t) / f64::from(WEIGHT_ONE)));
        let k = if derivatives {
            1 + model.control_count()
        } else {
            1
        };
        Tabulator {
            model,
            taps,
            k,
            block: 0,
            scratch: Vec::new(),
        }
    }

    /// Tabulates the block of side `2^log2` with control values `control` (grey levels,
    /// row-major) and calls `emit(dx, dy, sample)` for every sample `(dx, dy)` (offsets in the
    /// block, `0..=2^log2`: the owned pixels and the shared row and column past them) accepted
    /// by `want`. `any(dx, dy, ext)` tells whether a square of
    /// side `ext` holds any wanted sample, so that squares without one are not subdivided.
    pub fn run(
        &mut self,
        control: &[f64],
        log2: u8,
        want: &dyn Fn(u32, u32) -> bool,
        any: &dyn Fn(u32, u32, u32) -> bool,
        emit: &mut dyn FnMut(u32, u32, &[f64]),
    ) {
        let m = usize::from(self.model.intervals);
        let side = m + 1;
        let k = self.k;
        let mut g = vec![0.0; side * side * k];
        for (j, &c) in control.iter().enumerate().take(side * side) {
            g[j * k] = c;
            if k > 1 {
                g[j * k + 1 + j] = 1.0;
            }
        }
        let sp = (1u32 << log2) / m as u32;
        self.block = 1 << log2;
        self.recurse(&g, 0, 0, sp, 0, want, any, emit);
    }

    #[allow(clippy::too_many_arguments)]
    fn recurse(
        &mut self,
        g: &[f64],
        x: u32,
        y: u32,
        sp: u32,
        level: usize,
        want: &dyn Fn(u32, u32) -> bool,
        any: &dyn Fn(u32, u32, u32) -> bool,
        emit: &mut dyn FnMut(u32, u32, &[f64]),
    ) {
        if !any(x, y, self.model.intervals as u32 * sp + 1) {
            return;
        }
        let m = usize::from(self.model.intervals);
        let n = usize::from(self.model.transforms);
        let k = self.k;
        let rs = n * m + 1;
        while self.scratch.len() < 2 * (level + 1) {
            self.scratch.push(Vec::new());
        }
        let mut r = std::mem::take(&mut self.scratch[2 * level]);
        r.clear();
        r.resize(rs * rs * k, 0.0);
        self.refine(g, &mut r);
        if sp <= n as u32 {
            let stride = n / sp as usize;
            let ext = m as u32 * sp;
            // Windows on the block's far edges also emit the shared row/column beyond it.
            let last_x = if x + ext == self.block { ext } else { ext - 1 };
            let last_y = if y + ext == self.block { ext } else { ext - 1 };
            for dy in 0..=last_y {
                for dx in 0..=last_x {
                    if want(x + dx, y + dy) {
                        let q = ((dy as usize * stride) * rs + dx as usize * stride) * k;
                        emit(x + dx, y + dy, &r[q..q + k]);
                    }
                }
            }
        } else {
            let csp = sp / n as u32;
            let side = m + 1;
            let mut child = std::mem::take(&mut self.scratch[2 * level + 1]);
            child.clear();
            child.resize(side * side * k, 0.0);
            for i in 0..n {
                for j in 0..n {
                    for u in 0..side {
                        let src = ((i * m + u) * rs + j * m) * k;
                        child[u * side * k..(u + 1) * side * k]
                            .copy_from_slice(&r[src..src + side * k]);
                    }
                    let cx = x + (j * m) as u32 * csp;
                    let cy = y + (i * m) as u32 * csp;
                    self.recurse(&child, cx, cy, csp, level + 1, want, any, emit);
                }
            }
            self.scratch[2 * level + 1] = child;
        }
        self.scratch[2 * level] = r;
    }

    /// One subdivision step of the grid `g` (side m+1) into `r` (side N*m+1).
    fn refine(&self, g: &[f64], r: &mut [f64]) {
        let m = usize::from(self.model.intervals);
        let n = usize::from(self.model.transforms);
        let side = m + 1;
        let rs = n * m + 1;
        let k = self.k;
        for u in 0..side {
            for v in 0..side {
                let (d, s) = (((u * n) * rs + v * n) * k, (u * side + v) * k);
                r[d..d + k].copy_from_slice(&g[s..s + k]);
            }
        }
        // Line points: rows (dir 0) and columns (dir 1).
        for dir in 0..2 {
            for line in 0..side {
                for a in 0..m {
                    for ph in 1..n {
                        let taps = &self.taps[ph - 1];
                        let src = |t: usize| -> usize {
                            let idx = tap_point(a, t, m);
                            if dir == 0 {
                                (line * side + idx) * k
                            } else {
                                (idx * side + line) * k
                            }
                        };
                        let dst = if dir == 0 {
                            ((line * n) * rs + a * n + ph) * k
                        } else {
                            ((a * n + ph) * rs + line * n) * k
                        };
                        let (s0, s1, s2, s3) = (src(0), src(1), src(2), src(3));
                        for e in 0..k {
                            r[dst + e] = taps[0] * g[s0 + e]
                                + taps[1] * g[s1 + e]
                                + taps[2] * g[s2 + e]
                                + taps[3] * g[s3 + e];
                        }
                    }
                }
            }
        }
        // Cell points, from the new points at the same column phase on the nearest rows.
        for a1 in 0..m {
            for a2 in 0..m {
                for r1 in 1..n {
                    for r2 in 1..n {
                        // The cell rule of row phase r1 is that phase's line rule.
                        let taps = &self.taps[r1 - 1];
                        let at = |q1: usize, q2: usize| (q1 * rs + q2) * k;
                        let srcs: [usize; 4] =
                            std::array::from_fn(|t| at(tap_point(a1, t, m) * n, a2 * n + r2));
                        let dst = at(a1 * n + r1, a2 * n + r2);
                        for e in 0..k {
                            r[dst + e] = taps[0] * r[srcs[0] + e]
                                + taps[1] * r[srcs[1] + e]
                                + taps[2] * r[srcs[2] + e]
                                + taps[3] * r[srcs[3] + e];
                        }
                    }
                }
            }
        }
    }
}
