//! Iterated function systems drawn the classic ways, as an independent check of the patches.
//!
//! An IFS is a finite set of contracting maps `W_1 … W_n`; its *attractor* is the one compact
//! set `A` with `A = W_1(A) ∪ … ∪ W_n(A)`. Two ways draw it (Bélair & Rousseau, *Des fractals
//! utiles*; the course notes on IFS):
//!
//! - the **chaos game** (random iteration): from a point of `A`, apply a map chosen at random
//!   (with probability `p_i`), again and again; every iterate stays on `A` and, with
//!   probability 1, the iterates come arbitrarily close to every point of it;
//! - the **Hutchinson iteration** (deterministic): from a set, take the union of its images
//!   under every map, again and again; the sets converge to `A`.
//!
//! [`Ifs2`] does both for affine maps of the plane (the Sierpinski triangle and Barnsley's fern
//! of the seed paper). [`PatchIfs`] does both for a decoder patch: a projected IFS (thesis
//! II.1) is the attractor of the maps `W_k(s, t, x) = ((j + s) / N, (i + t) / N, T_k x)`, one per
//! child `k = (i, j)` of the `N x N` subdivision, where `(s, t)` is the parameter and `x` the
//! barycentric coordinates over the `(m + 1)^2` control points, `T_k` the subdivision matrix
//! (column `q` holds the weights of the parent's points in child point `q`). The surface is the
//! projection `F(s, t) = P x` by the control values `P`. The matrices are built here, in
//! floating point, from the rules of the specification (`docs/bitstream.md`): nothing of
//! decoder-core's integer synthesis is used, so a test can compare the two.
//!
//! The subdivision scheme is interpolating: the surface passes through its control points, so
//! `(c / m, r / m, e_q)` (the control point `q = (r, c)`) is a point of the attractor, and a
//! chaos game started there never leaves it. After `n` maps its parameter is a multiple of
//! `1 / (m N^n)`: a point of the grid the decoder tabulates after `n` subdivisions, where the
//! integer tabulation must agree with it up to its roundings.

use decoder_core::internal::model::{default_line_taps, tap_point, ModelType};
use decoder_core::internal::synthesis::Patch;

/// A small deterministic random generator (xorshift64*), so that drawings and tests repeat.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator from `seed` (any value).
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15 | 1)
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (v >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `0..n` (`n >= 1`).
    pub fn below(&mut self, n: usize) -> usize {
        ((self.unit() * n as f64) as usize).min(n - 1)
    }
}

/// An affine map of the plane: `(x, y) -> (a x + b y + e, c x + d y + f)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    /// The linear part, row by row, then the translation: `[a, b, c, d, e, f]`.
    pub coefficients: [f64; 6],
}

impl Affine {
    /// The image of `(x, y)`.
    pub fn apply(&self, (x, y): (f64, f64)) -> (f64, f64) {
        let [a, b, c, d, e, f] = self.coefficients;
        (a * x + b * y + e, c * x + d * y + f)
    }
}

/// An IFS of affine maps of the plane, with a probability per map for the chaos game.
#[derive(Debug, Clone, PartialEq)]
pub struct Ifs2 {
    /// The maps.
    pub maps: Vec<Affine>,
    /// The probability of each map (summing to 1).
    pub probabilities: Vec<f64>,
}

impl Ifs2 {
    /// The Sierpinski triangle of the seed paper (section 2): three maps halving distances,
    /// towards the corners `(0, 0)`, `(1, 0)` and `(1/2, 1)`, each with probability 1/3.
    pub fn sierpinski() -> Ifs2 {
        let map = |e: f64, f: f64| Affine {
            coefficients: [0.5, 0.0, 0.0, 0.5, e, f],
        };
        Ifs2 {
            maps: vec![map(0.0, 0.0), map(0.5, 0.0), map(0.25, 0.5)],
            probabilities: vec![1.0 / 3.0; 3],
        }
    }

    /// Barnsley's fern as the seed paper codes it (section 3): the stem, the two lower
    /// leaves and the rest of the fern, with probabilities 0.01, 0.07, 0.07 and 0.85; its
    /// attractor lies in `[-0.5, 0.5] x [0, 1]`.
    pub fn fern() -> Ifs2 {
        let map = |coefficients| Affine { coefficients };
        Ifs2 {
            maps: vec![
                map([0.0, 0.0, 0.0, 0.16, 0.0, 0.0]),
                map([0.2, -0.26, 0.23, 0.22, 0.0, 0.16]),
                map([-0.15, 0.28, 0.26, 0.24, 0.0, 0.044]),
                map([0.85, 0.04, -0.04, 0.85, 0.0, 0.16]),
            ],
            probabilities: vec![0.01, 0.07, 0.07, 0.85],
        }
    }

    /// A map chosen with the maps' probabilities.
    fn pick(&self, rng: &mut Rng) -> usize {
        let mut u = rng.unit();
        for (i, &p) in self.probabilities.iter().enumerate() {
            if u < p {
                return i;
            }
            u -= p;
        }
        self.maps.len() - 1
    }

    /// The chaos game: `steps` iterates from `start`, the first `skip` dropped (a start off
    /// the attractor needs a few maps to come close to it: each map contracts the distance).
    /// Also returns how often each map was chosen.
    pub fn chaos_game(
        &self,
        start: (f64, f64),
        steps: usize,
        skip: usize,
        rng: &mut Rng,
    ) -> (Vec<(f64, f64)>, Vec<usize>) {
        let mut p = start;
        let mut points = Vec::with_capacity(steps.saturating_sub(skip));
        let mut counts = vec![0; self.maps.len()];
        for n in 0..steps {
            let k = self.pick(rng);
            counts[k] += 1;
            p = self.maps[k].apply(p);
            if n >= skip {
                points.push(p);
            }
        }
        (points, counts)
    }

    /// The Hutchinson iteration: `iterations` times, the union of the images of `set` under
    /// every map.
    pub fn hutchinson(&self, set: &[(f64, f64)], iterations: usize) -> Vec<(f64, f64)> {
        let mut set = set.to_vec();
        for _ in 0..iterations {
            set = set
                .iter()
                .flat_map(|&p| self.maps.iter().map(move |w| w.apply(p)))
                .collect();
        }
        set
    }
}

/// Draws `points` (inside the rectangle `x0..x1 x y0..y1`, `y` up) as black pixels on a white
/// `width x height` image, row-major.
pub fn rasterize(
    points: &[(f64, f64)],
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    width: usize,
    height: usize,
) -> Vec<u8> {
    let mut image = vec![255u8; width * height];
    for &(x, y) in points {
        let u = ((x - x0) / (x1 - x0) * width as f64).floor();
        let v = ((y1 - y) / (y1 - y0) * height as f64).floor();
        if u >= 0.0 && v >= 0.0 && (u as usize) < width && (v as usize) < height {
            image[v as usize * width + u as usize] = 0;
        }
    }
    image
}

/// A point of a patch's surface: its parameter `(s, t)` in `[0, 1]^2` (column, row) and its
/// value in sample units (1/16 grey level), `F(s, t) = P x`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Column parameter.
    pub s: f64,
    /// Row parameter.
    pub t: f64,
    /// The value, in sample units.
    pub value: f64,
}

/// A patch's projected IFS in explicit form: its subdivision matrices and control values, in
/// floating point.
#[derive(Debug, Clone, PartialEq)]
pub struct PatchIfs {
    /// Intervals of the control grid per side (`m`).
    pub m: usize,
    /// Transforms per side (`N`).
    pub n: usize,
    /// The control values `P`, row-major, `(m + 1)^2` of them.
    pub control: Vec<f64>,
    /// `T_k` for the children `k = i N + j`, row-major `(m + 1)^2 x (m + 1)^2`: entry
    /// `(p, q)` is the weight of parent point `p` in child point `q`.
    pub maps: Vec<Vec<f64>>,
}

impl PatchIfs {
    /// The projected IFS of `patch`: its subdivision matrices, from the rules of the
    /// specification (the line rule on grid lines, the cell rule across the line rule's
    /// points of the four nearest rows, taps mirrored at the grid's ends), exactly.
    pub fn of(patch: &Patch) -> PatchIfs {
        let model: ModelType = patch.model;
        let m = usize::from(model.intervals);
        let n = usize::from(model.transforms);
        let side = m + 1;
        let count = side * side;
        let control: Vec<f64> = patch.control[..count]
            .iter()
            .map(|&v| f64::from(v))
            .collect();
        let mut maps = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                let mut t = vec![0.0; count * count];
                for p in 0..count {
                    // The parent grid e_p: the child's points are the weights of point p.
                    let mut basis = vec![0.0; count];
                    basis[p] = 1.0;
                    for r in 0..side {
                        for c in 0..side {
                            let v = refined(patch, &basis, i * m + r, j * m + c);
                            t[p * count + r * side + c] = v;
                        }
                    }
                }
                maps.push(t);
            }
        }
        PatchIfs {
            m,
            n,
            control,
            maps,
        }
    }

    /// `T_k x`.
    fn apply(&self, k: usize, x: &[f64]) -> Vec<f64> {
        let count = x.len();
        let t = &self.maps[k];
        (0..count)
            .map(|p| (0..count).map(|q| t[p * count + q] * x[q]).sum())
            .collect()
    }

    /// `P x`.
    fn project(&self, x: &[f64]) -> f64 {
        self.control.iter().zip(x).map(|(p, x)| p * x).sum()
    }

    /// A control point of the surface as a point of the attractor: parameter `(c / m, r / m)`,
    /// barycentric coordinates `e_q`.
    fn control_point(&self, q: usize) -> (f64, f64, Vec<f64>) {
        let side = self.m + 1;
        let mut x = vec![0.0; side * side];
        x[q] = 1.0;
        (
            (q % side) as f64 / self.m as f64,
            (q / side) as f64 / self.m as f64,
            x,
        )
    }

    /// The chaos game: `runs` runs of `depth` maps chosen uniformly at random, each from a
    /// control point chosen at random (a point of the attractor, so every iterate is one);
    /// every iterate, as a surface point.
    pub fn chaos_game(&self, runs: usize, depth: usize, rng: &mut Rng) -> Vec<SurfacePoint> {
        let side = self.m + 1;
        let mut out = Vec::with_capacity(runs * depth);
        for _ in 0..runs {
            let (mut s, mut t, mut x) = self.control_point(rng.below(side * side));
            for _ in 0..depth {
                let k = rng.below(self.n * self.n);
                let (i, j) = (k / self.n, k % self.n);
                x = self.apply(k, &x);
                s = (j as f64 + s) / self.n as f64;
                t = (i as f64 + t) / self.n as f64;
                out.push(SurfacePoint {
                    s,
                    t,
                    value: self.project(&x),
                });
            }
        }
        out
    }

    /// The Hutchinson iteration: from the control points, `depth` times the union of the images
    /// under every map: every point of the grid after `depth` subdivisions (points shared by
    /// neighbouring children come several times).
    pub fn hutchinson(&self, depth: usize) -> Vec<SurfacePoint> {
        let side = self.m + 1;
        let mut set: Vec<(f64, f64, Vec<f64>)> =
            (0..side * side).map(|q| self.control_point(q)).collect();
        for _ in 0..depth {
            let mut next = Vec::with_capacity(set.len() * self.n * self.n);
            for (s, t, x) in &set {
                for k in 0..self.n * self.n {
                    let (i, j) = (k / self.n, k % self.n);
                    next.push((
                        (j as f64 + s) / self.n as f64,
                        (i as f64 + t) / self.n as f64,
                        self.apply(k, x),
                    ));
                }
            }
            set = next;
        }
        set.into_iter()
            .map(|(s, t, x)| SurfacePoint {
                s,
                t,
                value: self.project(&x),
            })
            .collect()
    }
}

/// The refined value at refined coordinates `(q1, q2)` (row, column; `0..=N m`) of the grid
/// `g` (row-major, side `m + 1`), exactly: an old point, the line rule on a grid line, or the
/// cell rule across the line rule's points of the four nearest old rows (the specification's
/// point-by-point definition, in floating point and without rounding).
fn refined(patch: &Patch, g: &[f64], q1: usize, q2: usize) -> f64 {
    let n = usize::from(patch.model.transforms);
    let m = usize::from(patch.model.intervals);
    let (a1, r1) = (q1 / n, q1 % n);
    let (a2, r2) = (q2 / n, q2 % n);
    let weight = |t: i32| f64::from(t) / 4096.0;
    // New point at phase r between points a and a + 1 of row `fixed` (dir 0) or column.
    let line = |dir: usize, fixed: usize, a: usize, r: usize| -> f64 {
        let taps = default_line_taps(patch.model.transforms, r);
        (0..4)
            .map(|t| {
                let i = tap_point(a, t, m);
                let v = if dir == 0 {
                    g[fixed * (m + 1) + i]
                } else {
                    g[i * (m + 1) + fixed]
                };
                weight(taps[t]) * v
            })
            .sum()
    };
    match (r1, r2) {
        (0, 0) => g[a1 * (m + 1) + a2],
        (0, _) => line(0, a1, a2, r2),
        (_, 0) => line(1, a2, a1, r1),
        _ => {
            // The cell rule of row phase r1 is that phase's line rule (a tensor product).
            let taps = default_line_taps(patch.model.transforms, r1);
            (0..4)
                .map(|t| weight(taps[t]) * line(0, tap_point(a1, t, m), a2, r2))
                .sum()
        }
    }
}
