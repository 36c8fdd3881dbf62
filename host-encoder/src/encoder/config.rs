//! What an analysis and an encode are asked for: the analysis's settings and the targets an
//! encode must meet.
//!
//! Bottom layer of the encoder: uses nothing else of it.

use decoder_core::internal::format::CODING_TILE;
use decoder_core::internal::model::SAMPLE_ONE;
use decoder_core::SampleRange;
use std::fmt;

/// Settings of the analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct EncoderConfig {
    /// Smallest leaf side, as a power of two (1 to 7; other values are taken as the nearest).
    /// Default 2 (4 px); [`EncoderConfig::for_targets`] chooses 3 for rates up to
    /// [`LOW_RATE_BPP`].
    pub min_leaf_log2: u8,
    /// Largest leaf side, as a power of two (at most 7, the format's largest; a larger value is
    /// taken as 7, a smaller one than the smallest leaf as that). Default 7 (128 px): larger
    /// leaves were not chosen in practice and their projections are costly (see
    /// docs/decisions.md).
    pub max_leaf_log2: u8,
    /// Bit rate of the trial encode whose contexts, block by block, price the candidates: the
    /// closer to the targets to come, the better the choices (see docs/decisions.md).
    pub trial_bpp: f64,
    /// Width of the stripes the image is coded in, in coding tiles of 128 pixels (0, the
    /// default: one stripe as wide as the image). Prediction and edge smoothing do not cross a
    /// stripe's left edge, where a seam shows at low rates; a decoder holds one byte per
    /// column of a stripe (two in colour), and decoder-core's default decoder holds
    /// [`DEFAULT_STRIPE_TILES`] (512 pixels): code wider images for it with that, as packets
    /// are (see docs/decisions.md).
    pub stripe: u8,
    /// Strength of the smoothing of leaf edges every stream gets (0: none; at most
    /// decoder-core's `MAX_DEBLOCK`), or `None` to choose it per stream: the strongest that
    /// does not add to the stream's error.
    pub deblock: Option<u8>,
    /// `Some(m)`: quantise every fit at the coarse control steps, make a plan at the trial
    /// rate from them, and try finer steps at a node only while each lowers its error by at
    /// least that plan's multiplier over `m` per bit added (steps that pay only at rates far
    /// above the trial's are not searched). `None`: every step at every node, for an
    /// analysis that must serve any target.
    pub fine_steps: Option<f64>,
    /// What the analysis minimises besides the bits: the plain squared error, or the error
    /// weighted by local contrast ([`Tune`]).
    pub tune: Tune,
    /// `Some`: the plane is a 16-bit surface whose grey levels stand for values in this range
    /// (grey 0 `low`, 255 `high`), coded as 16-bit streams (decoded to values in the range at
    /// 1/16 grey level, unsmoothed). `None`: 8-bit streams.
    pub range: Option<SampleRange>,
    /// `Some(e)`: the largest error per pixel the streams are meant to keep, in grey levels (of
    /// a 16-bit surface, in its own units): a candidate's distortion adds [`BOUND_PENALTY`]
    /// times the square of each pixel's excess over it, so that rate control spends its bits
    /// where the bound needs them (`pifs encode --max-error`). Grayscale and surfaces.
    pub error_bound: Option<f64>,
}

/// The weight of a pixel's squared excess over [`EncoderConfig::error_bound`] in a
/// candidate's distortion, against one of its squared error (see docs/decisions.md).
pub const BOUND_PENALTY: f64 = 16384.0;

/// What an encode's distortion is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Tune {
    /// The squared error, every pixel alike: the most PSNR for the bytes.
    Psnr,
    /// The squared error weighted by local contrast, as SSIM and the eye weigh it: an error
    /// on a smooth surface counts more than the same error in texture. Higher SSIM for a few
    /// hundredths of a dB of PSNR (see docs/decisions.md).
    #[default]
    Ssim,
}

/// Decoder-core's default stripe capacity, in coding tiles (512 pixels): the stripes of
/// packets, and of streams for decoders that hold no more.
pub const DEFAULT_STRIPE_TILES: u8 =
    (decoder_core::internal::format::DEFAULT_STRIPE as u32 / CODING_TILE) as u8;

/// [`EncoderConfig::stripe`] for one stripe as wide as the image.
pub const WHOLE_WIDTH: u8 = 0;

impl EncoderConfig {
    /// The default settings for an analysis that serves `targets` on an image of `pixels`
    /// pixels, as `pifs` chooses them: the trial rate of [`Target::trial_bpp`], fine steps
    /// searched near it ([`FINE_STEP_MARGIN`]) when every target is a rate below
    /// [`FINE_STEPS_BELOW_BPP`] (a quality target's rate is not known before the analysis), and
    /// leaves from [`LOW_RATE_MIN_LEAF_LOG2`] when every target is a rate of at most
    /// [`LOW_RATE_BPP`].
    pub fn for_targets(targets: &[Target], pixels: usize) -> EncoderConfig {
        let all_rates = |below: &dyn Fn(f64) -> bool| {
            !targets.is_empty() && (targets.iter()).all(|t| t.bpp(pixels).is_some_and(below))
        };
        let defaults = EncoderConfig::default();
        EncoderConfig {
            trial_bpp: Target::trial_bpp(targets, pixels),
            fine_steps: all_rates(&|b| b < FINE_STEPS_BELOW_BPP).then_some(FINE_STEP_MARGIN),
            min_leaf_log2: match all_rates(&|b| b <= LOW_RATE_BPP) {
                true => LOW_RATE_MIN_LEAF_LOG2,
                false => defaults.min_leaf_log2,
            },
            ..defaults
        }
    }

    /// [`EncoderConfig::error_bound`] in whole samples (1/16 grey level, rounded down), if
    /// any: a surface's units through its range's step.
    pub(super) fn bound_in_samples(&self) -> Option<u32> {
        let one = f64::from(SAMPLE_ONE);
        self.error_bound.map(|e| {
            let samples = match self.range {
                Some(r) => e * one * f64::from(SampleRange::STEP_ONE) / f64::from(r.step),
                None => e * one,
            };
            // Saturating: a bound beyond every error bounds nothing.
            samples.max(0.0) as u32
        })
    }
}

impl Default for EncoderConfig {
    fn default() -> Self {
        EncoderConfig {
            min_leaf_log2: 2,
            max_leaf_log2: 7,
            trial_bpp: DEFAULT_TRIAL_BPP,
            stripe: WHOLE_WIDTH,
            deblock: None,
            fine_steps: None,
            tune: Tune::default(),
            range: None,
            error_bound: None,
        }
    }
}

/// The margin of [`EncoderConfig::fine_steps`] that [`EncoderConfig::for_targets`] chooses
/// for rate targets (see docs/decisions.md).
pub const FINE_STEP_MARGIN: f64 = 16.0;

/// Rate targets below this many bits per pixel (an 8-bit grayscale image's raw size) search the
/// fine control steps only where they pay near the trial's multiplier; a target at or above it
/// (the unlimited budget of the highest quality) searches every step, where the finest (lossless
/// on pixel grids) pay.
pub const FINE_STEPS_BELOW_BPP: f64 = 8.0;

/// Rate targets of at most this many bits per pixel are analysed from leaves of
/// [`LOW_RATE_MIN_LEAF_LOG2`]: 4 px leaves are nearly never worth their bits there, and the
/// analysis without them takes a little over half the time (see docs/decisions.md).
pub const LOW_RATE_BPP: f64 = 0.1;

/// The smallest leaf of [`EncoderConfig::for_targets`] for rates up to [`LOW_RATE_BPP`], as a
/// power of two: 8 px.
pub const LOW_RATE_MIN_LEAF_LOG2: u8 = 3;

/// The trial rate of an analysis for targets that name no rate (a quality target), and
/// [`EncoderConfig::default`]'s.
pub const DEFAULT_TRIAL_BPP: f64 = 0.2;

/// The lowest trial rate [`Target::trial_bpp`] chooses: a trial at the target's own rate paid
/// down to this one, the lowest measured (see docs/decisions.md).
pub const MIN_TRIAL_BPP: f64 = 0.02;

/// What an encode must achieve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// At most this many bits per pixel (whole file).
    Bpp(f64),
    /// At most this many bytes (whole file).
    Bytes(usize),
    /// The smallest file whose PSNR is at least this many dB.
    Psnr(f64),
}

impl Target {
    /// The bit rate this target asks for on an image of `pixels` pixels (`None` for a
    /// quality target).
    pub fn bpp(self, pixels: usize) -> Option<f64> {
        match self {
            Target::Bpp(b) => Some(b),
            Target::Bytes(n) => Some(n as f64 * 8.0 / pixels.max(1) as f64),
            Target::Psnr(_) => None,
        }
    }

    /// The trial rate for an analysis that serves `targets` ([`EncoderConfig::trial_bpp`]):
    /// the geometric mean of their rates, but at least [`MIN_TRIAL_BPP`];
    /// [`DEFAULT_TRIAL_BPP`] if none names a rate.
    pub fn trial_bpp(targets: &[Target], pixels: usize) -> f64 {
        let logs: Vec<f64> = targets
            .iter()
            .filter_map(|t| t.bpp(pixels))
            .filter(|b| b.is_finite() && *b > 0.0)
            .map(f64::ln)
            .collect();
        if logs.is_empty() {
            return DEFAULT_TRIAL_BPP;
        }
        (logs.iter().sum::<f64>() / logs.len() as f64)
            .exp()
            .max(MIN_TRIAL_BPP)
    }
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Target::Bpp(b) => write!(f, "{b} bits per pixel"),
            Target::Bytes(n) => write!(f, "{n} bytes"),
            Target::Psnr(p) => write!(f, "PSNR {p} dB"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{Target, DEFAULT_TRIAL_BPP, MIN_TRIAL_BPP};

    /// A trial runs at the geometric mean of the rates its analysis serves, down to
    /// [`MIN_TRIAL_BPP`]; a quality target alone gets [`DEFAULT_TRIAL_BPP`].
    #[test]
    fn trials_run_at_the_targets_rates() {
        let pixels = 768 * 512;
        let trial = |targets: &[Target]| Target::trial_bpp(targets, pixels);
        let near = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(near(trial(&[Target::Bpp(0.05)]), 0.05));
        let bytes = 2458.0 * 8.0 / pixels as f64;
        assert!(near(trial(&[Target::Bytes(2458)]), bytes));
        assert!(near(
            trial(&[Target::Bpp(0.05), Target::Bpp(0.5)]),
            0.025f64.sqrt()
        ));
        assert_eq!(trial(&[Target::Bpp(0.001)]), MIN_TRIAL_BPP);
        assert_eq!(trial(&[Target::Psnr(35.0)]), DEFAULT_TRIAL_BPP);
        assert!(near(trial(&[Target::Psnr(35.0), Target::Bpp(0.1)]), 0.1));
    }
}
