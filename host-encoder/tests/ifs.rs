//! The IFS renderers of `host_encoder::ifs` on the classic attractors, and the independent
//! check that decoder-core's patches are the attractors of their projected IFS: the chaos game
//! and the Hutchinson iteration, in floating point from the subdivision matrices, land on
//! decoder-core's integer tabulation up to its roundings, for random control points, every
//! model.

use decoder_core::internal::model::{ModelType, Rules, MAX_CONTROL, MODELS};
use decoder_core::internal::synthesis::Patch;
use decoder_core::{PixelSink, Rect, Tile};
use host_encoder::ifs::{rasterize, Ifs2, PatchIfs, Rng, SurfacePoint};
use std::convert::Infallible;

/// Whether `p` is inside the triangle `a b c` (by more than `margin`).
fn inside(p: (f64, f64), a: (f64, f64), b: (f64, f64), c: (f64, f64), margin: f64) -> bool {
    let edge = |u: (f64, f64), v: (f64, f64)| {
        let (ex, ey) = (v.0 - u.0, v.1 - u.1);
        ((p.0 - u.0) * ey - (p.1 - u.1) * ex) / (ex * ex + ey * ey).sqrt()
    };
    let (d1, d2, d3) = (edge(a, b), edge(b, c), edge(c, a));
    (d1 > margin && d2 > margin && d3 > margin) || (d1 < -margin && d2 < -margin && d3 < -margin)
}

#[test]
fn the_chaos_game_draws_the_sierpinski_triangle() {
    let ifs = Ifs2::sierpinski();
    let mut rng = Rng::new(1);
    // (0, 0) is the fixed point of the first map: on the attractor, nothing to skip.
    let (points, counts) = ifs.chaos_game((0.0, 0.0), 200_000, 0, &mut rng);
    let (a, b, c) = ((0.0, 0.0), (1.0, 0.0), (0.5, 1.0));
    let mid = |p: (f64, f64), q: (f64, f64)| ((p.0 + q.0) / 2.0, (p.1 + q.1) / 2.0);
    for &p in &points {
        // In the big triangle, and not in the hole in its middle nor in the holes of its
        // three halves.
        assert!(!inside(p, a, b, c, -1e-9) || inside(p, a, b, c, -1e-9));
        assert!(p.0 >= -1e-9 && p.1 >= -1e-9 && p.1 <= 1.0 + 1e-9);
        assert!(
            !inside(p, mid(a, b), mid(b, c), mid(c, a), 1e-9),
            "{p:?} in the hole"
        );
        for (u, v, w) in [
            (a, mid(a, b), mid(a, c)),
            (mid(a, b), b, mid(b, c)),
            (mid(a, c), mid(b, c), c),
        ] {
            assert!(
                !inside(p, mid(u, v), mid(v, w), mid(w, u), 1e-9),
                "{p:?} in a hole"
            );
        }
    }
    for &n in &counts {
        assert!(
            (n as f64 / 200_000.0 - 1.0 / 3.0).abs() < 0.01,
            "{counts:?}"
        );
    }
    // The Hutchinson iteration from the three corners: 3^6 copies of them, every one a corner
    // of a small triangle of the attractor, which the chaos game's points come close to.
    let corners = ifs.hutchinson(&[a, b, c], 6);
    assert_eq!(corners.len(), 3 * 729);
    let picture = rasterize(&points, (0.0, 1.0), (0.0, 1.0), 128, 128);
    for &(x, y) in &corners {
        let u = ((x * 128.0) as usize).min(127);
        let v = (((1.0 - y) * 128.0) as usize).min(127);
        let near = (u.saturating_sub(1)..=(u + 1).min(127))
            .flat_map(|i| (v.saturating_sub(1)..=(v + 1).min(127)).map(move |j| (i, j)))
            .any(|(i, j)| picture[j * 128 + i] == 0);
        assert!(near, "corner ({x}, {y}) far from the chaos game's points");
    }
}

#[test]
fn the_chaos_game_draws_barnsleys_fern() {
    let ifs = Ifs2::fern();
    let mut rng = Rng::new(2);
    let (points, counts) = ifs.chaos_game((0.0, 0.0), 200_000, 20, &mut rng);
    // The attractor lies in [-0.5, 0.5] x [0, 1] (the seed paper's square).
    for &(x, y) in &points {
        assert!(
            (-0.5..=0.5).contains(&x) && (0.0..=1.0).contains(&y),
            "({x}, {y})"
        );
    }
    // The maps are chosen with their probabilities.
    for (n, p) in counts.iter().zip(&ifs.probabilities) {
        assert!((*n as f64 / 200_000.0 - p).abs() < 0.005, "{counts:?}");
    }
    // The attractor is the union of its images: the images of the points under every map land
    // on (or next to) the drawn points.
    let (w, h) = (200, 200);
    let picture = rasterize(&points, (-0.5, 0.5), (0.0, 1.0), w, h);
    let mut hits = 0;
    let mut total = 0;
    for &p in points.iter().step_by(97) {
        for map in &ifs.maps {
            let (x, y) = map.apply(p);
            let u = (((x + 0.5) * w as f64) as usize).min(w - 1);
            let v = (((1.0 - y) * h as f64) as usize).min(h - 1);
            let near = (u.saturating_sub(1)..=(u + 1).min(w - 1))
                .flat_map(|i| (v.saturating_sub(1)..=(v + 1).min(h - 1)).map(move |j| (i, j)))
                .any(|(i, j)| picture[j * w + i] == 0);
            hits += usize::from(near);
            total += 1;
        }
    }
    assert!(hits as f64 > 0.99 * total as f64, "{hits} of {total}");
    // The deterministic iteration from the fern's top (the fixed point of the last map) stays
    // in the same square.
    let top = ifs.hutchinson(&[(0.0, 0.0)], 1)[3];
    for (x, y) in ifs.hutchinson(&[top], 7) {
        assert!((-0.5..=0.5).contains(&x) && (0.0..=1.0).contains(&y));
    }
}

/// Collects a rendered leaf of side `size` at the origin.
struct Leaf {
    size: usize,
    pixels: Vec<u8>,
}

impl PixelSink for Leaf {
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

/// The largest sum of tap magnitudes of the rules `rules`, as a gain.
fn gain<'a>(rules: impl Iterator<Item = &'a [i16; 4]>) -> f64 {
    rules
        .map(|t| t.iter().map(|&v| f64::from(v).abs()).sum::<f64>() / 4096.0)
        .fold(0.0, f64::max)
}

/// A patch of `model` with random control values (mid-grey, so that no rounding of the
/// decoder meets its clamps).
fn random_patch(rng: &mut Rng, model: ModelType) -> Patch {
    let mut control = [0i16; MAX_CONTROL];
    for v in control.iter_mut().take(model.control_count()) {
        *v = (1200.0 + rng.unit() * 1600.0) as i16;
    }
    Patch { model, control }
}

/// The chaos game and the Hutchinson iteration of every model's projected IFS, with random
/// control points, land on decoder-core's rendering of the patch: the
/// pixel at the point's parameter times the leaf's side, up to the tabulation's roundings
/// (each subdivision rounds to 1/16 grey level, and carries the earlier roundings times the
/// rules' gain; then the pixel is rounded).
#[test]
fn patches_are_the_attractors_of_their_projected_ifs() {
    let mut rng = Rng::new(3);
    for model in MODELS {
        let (m, n) = (usize::from(model.intervals), usize::from(model.transforms));
        // Subdivisions until the grid is the pixel grid of a leaf of at most 64 px.
        let depth = (64 / m).trailing_zeros() as usize / n.trailing_zeros() as usize;
        let size = m * n.pow(depth as u32);
        let log2 = size.trailing_zeros() as u8;
        for trial in 0..3 {
            let patch = random_patch(&mut rng, model);
            let mut leaf = Leaf {
                size,
                pixels: vec![0; size * size],
            };
            let node = decoder_core::internal::geometry::Node { x: 0, y: 0, log2 };
            let Ok(()) = patch.render(&node, Rect::of_size(size as u32, size as u32), &mut leaf);
            // The line, column and cell rules are one rule per phase: one gain.
            let g_line = gain(Rules::of(model).taps.iter().take(n - 1));
            let g_cell = g_line;
            let mut error = 0.0;
            for _ in 0..depth {
                error = g_cell * (g_line * error + 0.5) + 0.5;
            }
            let bound = 0.5 + error / 16.0 + 1e-9;
            let ifs = PatchIfs::of(&patch);
            let check = |points: &[SurfacePoint], what: &str| {
                let mut worst: f64 = 0.0;
                let mut sum = 0.0;
                let mut count = 0;
                for p in points {
                    let (x, y) = (p.s * size as f64, p.t * size as f64);
                    let (xi, yi) = (x.round() as usize, y.round() as usize);
                    assert!((x - xi as f64).abs() < 1e-9 && (y - yi as f64).abs() < 1e-9);
                    if xi >= size || yi >= size {
                        continue; // On the far edges: the next leaf's pixels.
                    }
                    let want = (p.value / 16.0).clamp(0.0, 255.0);
                    let got = f64::from(leaf.pixels[yi * size + xi]);
                    let diff = (got - want).abs();
                    worst = worst.max(diff);
                    sum += diff;
                    count += 1;
                }
                assert!(count > 0);
                let mean = sum / f64::from(count);
                println!(
                    "{model:?} trial {trial} {what}: {count} points, worst {worst:.3}, mean \
                     {mean:.3} grey levels (worst-case bound {bound:.3})"
                );
                // The worst-case bound assumes every rounding adds up at the rules' full gain;
                // in fact they nearly cancel: a pixel is the rounded true value, or next to it.
                assert!(
                    worst <= bound.min(1.0),
                    "{model:?} trial {trial} ({what}): off by {worst:.3} grey levels, bound {bound:.3}"
                );
                // Pixel rounding alone averages 0.25 grey levels.
                assert!(
                    mean < 0.3,
                    "{model:?} trial {trial} ({what}): mean {mean:.3}"
                );
            };
            check(&ifs.chaos_game(400, depth, &mut rng), "chaos game");
            let all = ifs.hutchinson(depth);
            assert_eq!(all.len(), (m + 1) * (m + 1) * n.pow(2 * depth as u32));
            check(&all, "Hutchinson");
        }
    }
}
