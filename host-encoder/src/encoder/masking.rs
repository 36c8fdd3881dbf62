//! Contrast masking: how much an error counts where it falls. The same squared error is plain
//! to see on a smooth surface and hidden in texture; SSIM, which follows the eye there, scores
//! an error relative to the local variance (its structure term divides by `2 sigma^2 + C2`).
//! The analysis multiplies each node's squared errors by the node's weight, so that the
//! quadtree's cut and the control steps buy fidelity where it shows (see docs/decisions.md).
//!
//! Above [`super::plane`] (the image it weighs); below [`super::candidates`].

use super::config::Tune;
use super::plane::Plane;
use decoder_core::Node;

/// Side of the blocks whose variance sets the weights, pixels: about SSIM's window.
const BLOCK: u32 = 8;

/// Variance (grey levels squared) added to every block's: smooth blocks differ by less than
/// their variances do, as SSIM's constants make them (see docs/decisions.md).
const VARIANCE_FLOOR: f64 = 1000.0;

/// How strongly the weight follows the variance: `((v + floor) / mean)^-STRENGTH` (see
/// docs/decisions.md).
const STRENGTH: f64 = 0.3;

/// The smallest node whose errors take its blocks' weight whole: a smaller node's weight `w`
/// is softened to `w^(side / MASKED_FROM)`, closer to 1, so that small leaves in texture are
/// not made coarse where they meet (measured against leaf-edge steps and SSIM, see
/// docs/decisions.md).
const MASKED_FROM: u32 = 16;

/// The error weights of an image, by blocks of [`BLOCK`] pixels, as a summed-area table so
/// that any node's mean weight takes four reads. The weights' mean over the image is 1.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Masking {
    /// Blocks per row and per column (0 for uniform weights).
    cols: u32,
    rows: u32,
    /// `(cols + 1) x (rows + 1)` sums of the weights above and left of each block corner.
    sums: Vec<f64>,
}

/// How an image's block variances become weights: `((v + floor) / g)^-STRENGTH / mean`, `g`
/// the geometric mean of `v + floor` over the image's blocks and `mean` the mean of the
/// unscaled weights, so that the weights' mean over the image is 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContrastScale {
    /// `ln g`.
    log_mean: f64,
    /// The mean of `((v + floor) / g)^-STRENGTH` over the blocks.
    mean: f64,
}

impl ContrastScale {
    /// The scale of `plane`'s weights under `tune`: `None` for uniform weights
    /// ([`Tune::Psnr`], or an empty plane).
    pub fn of(plane: &Plane, tune: Tune) -> Option<ContrastScale> {
        if tune == Tune::Psnr {
            return None;
        }
        let (cols, rows) = (plane.width.div_ceil(BLOCK), plane.height.div_ceil(BLOCK));
        if cols == 0 || rows == 0 {
            return None;
        }
        let spread: Vec<f64> = (0..rows)
            .flat_map(|r| (0..cols).map(move |c| (c, r)))
            .map(|(c, r)| block_variance(plane, c, r) + VARIANCE_FLOOR)
            .collect();
        let log_mean = spread.iter().map(|v| v.ln()).sum::<f64>() / spread.len() as f64;
        let raw = ContrastScale {
            log_mean,
            mean: 1.0,
        };
        let mean = spread.iter().map(|&v| raw.unscaled(v)).sum::<f64>() / spread.len() as f64;
        Some(ContrastScale { log_mean, mean })
    }

    /// The weight of a block whose variance plus the floor is `spread`, before the scaling to a
    /// mean of 1.
    fn unscaled(&self, spread: f64) -> f64 {
        (-STRENGTH * (spread.ln() - self.log_mean)).exp()
    }

    /// The weight of a block of variance `variance`.
    fn weight(&self, variance: f64) -> f64 {
        self.unscaled(variance + VARIANCE_FLOOR) / self.mean
    }
}

impl Masking {
    /// Every error counts the same ([`Tune::Psnr`]).
    pub fn uniform() -> Masking {
        Masking::default()
    }

    /// The weights of `plane`'s errors scaled by `scale` (by [`Tune::Psnr`]'s none, uniform):
    /// a part of an image cut on block edges gets, from its image's scale, the weights the
    /// whole image's errors have there.
    pub fn scaled(plane: &Plane, scale: Option<ContrastScale>) -> Masking {
        let Some(scale) = scale else {
            return Masking::uniform();
        };
        let (cols, rows) = (plane.width.div_ceil(BLOCK), plane.height.div_ceil(BLOCK));
        if cols == 0 || rows == 0 {
            return Masking::uniform();
        }
        let stride = cols as usize + 1;
        let mut sums = vec![0.0f64; stride * (rows as usize + 1)];
        for r in 0..rows as usize {
            for c in 0..cols as usize {
                let at = (r + 1) * stride + c + 1;
                let weight = scale.weight(block_variance(plane, c as u32, r as u32));
                sums[at] = weight + sums[at - 1] + sums[at - stride] - sums[at - stride - 1];
            }
        }
        Masking { cols, rows, sums }
    }

    /// The mean weight of the blocks `node` covers (inside the image), softened below
    /// [`MASKED_FROM`] pixels: what its squared errors are multiplied by.
    pub fn weight(&self, node: &Node) -> f64 {
        if self.cols == 0 || self.rows == 0 {
            return 1.0;
        }
        let end = |start: u32, blocks: u32| {
            let first = (start / BLOCK).min(blocks - 1);
            let last = (start.saturating_add(node.size()).div_ceil(BLOCK)).clamp(first + 1, blocks);
            (first as usize, last as usize)
        };
        let (c0, c1) = end(node.x, self.cols);
        let (r0, r1) = end(node.y, self.rows);
        let stride = self.cols as usize + 1;
        let at = |c: usize, r: usize| self.sums[r * stride + c];
        let sum = at(c1, r1) - at(c0, r1) - at(c1, r0) + at(c0, r0);
        let weight = sum / ((c1 - c0) * (r1 - r0)) as f64;
        match node.size() {
            side if side < MASKED_FROM => weight.powf(f64::from(side) / f64::from(MASKED_FROM)),
            _ => weight,
        }
    }

    /// The weighted squared error of a whole reconstruction (`channels` values a pixel, rows of
    /// `width` pixels) against `reference`: each pixel's squared error times its block's weight;
    /// `None` when every weight is 1 (the plain squared error is the same).
    pub fn weighted_sse(
        &self,
        width: u32,
        channels: usize,
        reference: &[u8],
        reconstruction: &[u8],
    ) -> Option<f64> {
        if self.cols == 0 || self.rows == 0 || width == 0 {
            return None;
        }
        let row_len = width as usize * channels;
        let stride = self.cols as usize + 1;
        let mut total = 0.0;
        for (y, (a, b)) in reference
            .chunks(row_len)
            .zip(reconstruction.chunks(row_len))
            .enumerate()
        {
            let r = (y / BLOCK as usize).min(self.rows as usize - 1);
            for (c, (a, b)) in a
                .chunks(BLOCK as usize * channels)
                .zip(b.chunks(BLOCK as usize * channels))
                .enumerate()
            {
                let at = |c: usize, r: usize| self.sums[r * stride + c];
                let weight = at(c + 1, r + 1) - at(c, r + 1) - at(c + 1, r) + at(c, r);
                let sse: u64 = a
                    .iter()
                    .zip(b)
                    .map(|(&p, &q)| u64::from(p.abs_diff(q)).pow(2))
                    .sum();
                total += weight * sse as f64;
            }
        }
        Some(total)
    }

    /// The weight of the luma pixels under the chroma node `chroma` (half the luma's
    /// coordinates and side).
    pub fn chroma_weight(&self, chroma: &Node) -> f64 {
        self.weight(&Node {
            x: chroma.x.saturating_mul(2),
            y: chroma.y.saturating_mul(2),
            log2: chroma.log2 + 1,
        })
    }
}

/// Variance of block `(c, r)`'s pixels inside the plane.
fn block_variance(plane: &Plane, c: u32, r: u32) -> f64 {
    let (x0, y0) = (c * BLOCK, r * BLOCK);
    let (x1, y1) = (
        (x0 + BLOCK).min(plane.width),
        (y0 + BLOCK).min(plane.height),
    );
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for y in y0..y1 {
        for x in x0..x1 {
            let v = plane.value(x, y);
            sum += v;
            sum2 += v * v;
        }
    }
    let n = f64::from((x1 - x0) * (y1 - y0));
    (sum2 / n - (sum / n) * (sum / n)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(x: u32, y: u32, log2: u8) -> Node {
        Node { x, y, log2 }
    }

    /// Left half flat, right half noisy: errors weigh more on the flat side, and the mean
    /// weight over the image is 1.
    #[test]
    fn flat_blocks_weigh_more_than_textured_ones() {
        let (w, h) = (64u32, 32u32);
        let mut seed = 1u32;
        let data = (0..w * h)
            .map(|i| {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                if i % w < 32 {
                    100
                } else {
                    (seed >> 24) as u8
                }
            })
            .collect();
        let plane = Plane::new(w, h, data);
        let m = Masking::scaled(&plane, ContrastScale::of(&plane, Tune::Ssim));
        let (flat, noisy) = (m.weight(&node(0, 0, 5)), m.weight(&node(32, 0, 5)));
        assert!(flat > 1.5 * noisy, "flat {flat}, noisy {noisy}");
        assert!(((flat + noisy) / 2.0 - 1.0).abs() < 1e-9);
        // A node reaching past the image counts its blocks inside it.
        assert!((m.weight(&node(32, 0, 7)) - noisy).abs() < 1e-9);
        // The chroma node (16, 0) of side 16 lies under the luma node (32, 0) of side 32.
        assert!((m.chroma_weight(&node(16, 0, 4)) - noisy).abs() < 1e-9);
    }

    #[test]
    fn psnr_tuning_weighs_every_error_alike() {
        let plane = Plane::new(16, 16, (0..=255).collect());
        let m = Masking::scaled(&plane, ContrastScale::of(&plane, Tune::Psnr));
        assert_eq!(m.weight(&node(0, 0, 4)), 1.0);
        assert_eq!(m, Masking::uniform());
    }
}
