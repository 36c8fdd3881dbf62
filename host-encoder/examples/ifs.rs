//! Draws iterated function systems the classic ways, and a decoder patch as one.
//!
//! ```text
//! cargo run --release -p host-encoder --example ifs [OUTPUT_DIR]     (default: ./ifs-out)
//! ```
//!
//! Writes PNG images:
//! - `sierpinski-chaos.png`: the Sierpinski triangle by the chaos game (the seed paper's three
//!   maps, probability 1/3 each); `sierpinski-hutchinson.png`: by the Hutchinson iteration of
//!   its corners (8 times);
//! - `fern-chaos.png`: Barnsley's fern by the chaos game (the seed paper's four maps and
//!   probabilities);
//! - `patch-decoder.png`, `patch-chaos.png`, `patch-hutchinson.png`: one 3x3/2x2 patch with
//!   random control values, as decoder-core's integer
//!   tabulation draws it, and as the chaos game and the Hutchinson iteration of its projected
//!   IFS draw it (grey levels from the surface values; pixels the chaos game did not reach
//!   are white); `patch-difference.png` the difference between the Hutchinson and decoder
//!   images (mid-grey is none; every pixel is within one grey level).
//!
//! Prints how far the IFS drawings are from the decoder's.

use decoder_core::internal::geometry::Node;
use decoder_core::internal::model::{MAX_CONTROL, MODELS};
use decoder_core::internal::synthesis::Patch;
use decoder_core::{PixelSink, Rect, Tile};
use host_encoder::ifs::{rasterize, Ifs2, PatchIfs, Rng, SurfacePoint};
use std::convert::Infallible;
use std::path::{Path, PathBuf};

fn save(dir: &Path, name: &str, width: usize, height: usize, pixels: &[u8]) {
    let path = dir.join(name);
    let bytes = host_encoder::io::encode_gray(&path, width as u32, height as u32, pixels)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    host_encoder::io::write_atomic(&path, &bytes).unwrap_or_else(|e| panic!("{e}"));
    println!("wrote {}", path.display());
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

/// Surface points as a grey image of side `size` (white where no point falls).
fn surface_image(points: &[SurfacePoint], size: usize) -> Vec<u8> {
    let mut image = vec![255u8; size * size];
    for p in points {
        let (x, y) = ((p.s * size as f64).round(), (p.t * size as f64).round());
        if x < size as f64 && y < size as f64 {
            image[y as usize * size + x as usize] =
                (p.value / 16.0).round().clamp(0.0, 254.0) as u8;
        }
    }
    image
}

fn main() {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "ifs-out".into()));
    std::fs::create_dir_all(&dir).expect("create the output directory");
    let mut rng = Rng::new(2024);

    let sierpinski = Ifs2::sierpinski();
    let (points, _) = sierpinski.chaos_game((0.0, 0.0), 300_000, 0, &mut rng);
    save(
        &dir,
        "sierpinski-chaos.png",
        512,
        512,
        &rasterize(&points, (0.0, 1.0), (0.0, 1.0), 512, 512),
    );
    let corners = sierpinski.hutchinson(&[(0.0, 0.0), (1.0, 0.0), (0.5, 1.0)], 8);
    save(
        &dir,
        "sierpinski-hutchinson.png",
        512,
        512,
        &rasterize(&corners, (0.0, 1.0), (0.0, 1.0), 512, 512),
    );

    let fern = Ifs2::fern();
    let (points, counts) = fern.chaos_game((0.0, 0.0), 400_000, 20, &mut rng);
    save(
        &dir,
        "fern-chaos.png",
        400,
        600,
        &rasterize(&points, (-0.33, 0.33), (0.0, 1.0), 400, 600),
    );
    println!(
        "fern: maps chosen {counts:?} times (probabilities {:?})",
        fern.probabilities
    );

    // A 3x3/2x2 patch with random control values, on a 64 px leaf: five subdivisions down to
    // the pixel grid.
    let model = MODELS[1];
    let mut control = [0i16; MAX_CONTROL];
    for v in control.iter_mut().take(model.control_count()) {
        *v = (800.0 + rng.unit() * 2400.0) as i16;
    }
    let patch = Patch { model, control };
    let size = 64;
    let mut leaf = Leaf {
        size,
        pixels: vec![0; size * size],
    };
    let node = Node {
        x: 0,
        y: 0,
        log2: 6,
    };
    let Ok(()) = patch.render(&node, Rect::of_size(64, 64), &mut leaf);
    save(&dir, "patch-decoder.png", size, size, &leaf.pixels);
    let ifs = PatchIfs::of(&patch);
    let chaos = surface_image(&ifs.chaos_game(2000, 5, &mut rng), size);
    save(&dir, "patch-chaos.png", size, size, &chaos);
    let all = surface_image(&ifs.hutchinson(5), size);
    save(&dir, "patch-hutchinson.png", size, size, &all);
    let mut worst = 0i32;
    let difference: Vec<u8> = all
        .iter()
        .zip(&leaf.pixels)
        .map(|(&a, &b)| {
            let d = i32::from(a) - i32::from(b);
            worst = worst.max(d.abs());
            (128 + 32 * d).clamp(0, 255) as u8
        })
        .collect();
    save(&dir, "patch-difference.png", size, size, &difference);
    let reached = chaos.iter().filter(|&&v| v != 255).count();
    println!(
        "patch: the Hutchinson iteration differs from decoder-core by at most {worst} grey level(s); \
         the chaos game reached {reached} of {} pixels",
        size * size
    );
}
