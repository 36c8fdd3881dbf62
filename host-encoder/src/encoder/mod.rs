//! The encoder: analysis, quantisation, rate control and writing, mirroring decoder-core's
//! layout.

pub mod analysis;
pub mod fit;
pub mod quantise;
pub mod rate;
pub mod synthesis;
pub mod writer;

use analysis::Analysis;
use decoder_core::internal::syntax::{Codebook, Header};
use decoder_core::DecodeError;
use std::fmt;

/// An 8-bit grayscale image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Plane {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major samples.
    pub data: Vec<u8>,
}

impl Plane {
    /// Wraps row-major samples (`data.len() == width * height`).
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Self {
        assert_eq!(
            data.len(),
            width as usize * height as usize,
            "plane size mismatch"
        );
        Plane {
            width,
            height,
            data,
        }
    }

    /// The sample at `(x, y)`.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> u8 {
        self.data[y as usize * self.width as usize + x as usize]
    }
}

/// Settings of the analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct EncoderConfig {
    /// Smallest leaf side, as a power of two (1 to 7; other values are taken as the nearest).
    pub min_leaf_log2: u8,
    /// Largest leaf side, as a power of two (at most 7, the format's largest; a larger value is
    /// taken as 7, a smaller one than the smallest leaf as that). Default 7 (128 px): larger
    /// leaves were not chosen in practice and their projections are costly (see
    /// docs/decisions.md).
    pub max_leaf_log2: u8,
    /// Levels of the Lloyd-Max weight codebooks (0: none).
    pub codebook_levels: usize,
    /// Whether to fit the free subdivision weights as well as the control values (the
    /// thesis's full inverse problem). Off by default: it makes the analysis much longer for
    /// a negligible gain, since the default scheme fitted exactly (a linear least-squares
    /// problem) is nearly always the better buy (see docs/decisions.md).
    pub fit_weights: bool,
    /// Bit rate of the trial encode whose final contexts train the rate estimates: the closer
    /// to the targets to come, the closer the estimates (see docs/decisions.md).
    pub trial_bpp: f64,
}

impl EncoderConfig {
    /// The default settings for an analysis that serves `targets` on an image of `pixels`
    /// pixels, as `pifs` chooses them: the trial rate of [`Target::trial_bpp`].
    pub fn for_targets(targets: &[Target], pixels: usize) -> EncoderConfig {
        EncoderConfig {
            trial_bpp: Target::trial_bpp(targets, pixels),
            ..EncoderConfig::default()
        }
    }
}

impl Default for EncoderConfig {
    fn default() -> Self {
        EncoderConfig {
            min_leaf_log2: 2,
            max_leaf_log2: 7,
            codebook_levels: 8,
            fit_weights: false,
            trial_bpp: MIN_TRIAL_BPP,
        }
    }
}

/// The lowest trial rate [`Target::trial_bpp`] chooses: below it, trials at the targets' own
/// rates made no measurable difference (see docs/decisions.md).
pub const MIN_TRIAL_BPP: f64 = 0.2;

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
    /// the geometric mean of their rates, but at least [`MIN_TRIAL_BPP`].
    pub fn trial_bpp(targets: &[Target], pixels: usize) -> f64 {
        let logs: Vec<f64> = targets
            .iter()
            .filter_map(|t| t.bpp(pixels))
            .filter(|b| b.is_finite() && *b > 0.0)
            .map(f64::ln)
            .collect();
        if logs.is_empty() {
            return MIN_TRIAL_BPP;
        }
        (logs.iter().sum::<f64>() / logs.len() as f64)
            .exp()
            .max(MIN_TRIAL_BPP)
    }
}

/// Why an encode failed.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum EncodeError {
    /// The image is larger than the format allows (65535 per side) or empty.
    BadDimensions {
        /// Width of the image, pixels.
        width: u32,
        /// Height of the image, pixels.
        height: u32,
    },
    /// The target is not a positive finite number.
    BadTarget(Target),
    /// Even the smallest stream is larger than the budget.
    BudgetTooSmall {
        /// The budget, bytes.
        budget: usize,
        /// The smallest stream the encoder can write for this image, bytes.
        smallest: usize,
    },
    /// The PSNR cannot be reached.
    QualityUnreachable {
        /// Requested PSNR, dB.
        requested: f64,
        /// Best reachable, dB: the PSNR of the analysis's highest-quality stream (the one a
        /// budget of unlimited bytes writes from it), so that any target up to it is met.
        best: f64,
    },
    /// The shared syntax code refused what the encoder asked it to write (a bug).
    Syntax(DecodeError),
    /// The encoder's own bookkeeping is inconsistent (a bug); the text says what was found.
    Internal(&'static str),
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::BadDimensions { width, height } => write!(
                f,
                "image size {width}x{height} is not supported (1 to 65535 per side)"
            ),
            EncodeError::BadTarget(t) => write!(f, "invalid target: {t}"),
            EncodeError::BudgetTooSmall { budget, smallest } => {
                write!(f, "budget of {budget} bytes is too small: the smallest stream for this image is {smallest} bytes")
            }
            EncodeError::QualityUnreachable { requested, best } => {
                // Rounded down: a target of the figure shown is reachable.
                let best = (best * 100.0).floor() / 100.0;
                write!(f, "PSNR {requested:.2} dB is unreachable: the best this encoder reaches is {best:.2} dB")
            }
            EncodeError::Syntax(_) => {
                write!(f, "internal encoder error: the syntax refused a leaf")
            }
            EncodeError::Internal(what) => write!(f, "internal encoder error: {what}"),
        }
    }
}

impl std::error::Error for EncodeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            EncodeError::Syntax(e) => Some(e),
            _ => None,
        }
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

/// An encoded stream with its figures.
#[derive(Debug, Clone)]
pub struct Encoded {
    /// The complete `.pifs` stream.
    pub bytes: Vec<u8>,
    /// The encoder's closed-loop reconstruction (equal to what any decoder produces).
    pub reconstruction: Vec<u8>,
    /// Squared error of the reconstruction.
    pub sse: f64,
    /// PSNR of the reconstruction, dB (infinite when lossless).
    pub psnr: f64,
    /// Payload bits the rate model predicted for the final plan.
    pub estimated_payload_bits: f64,
    /// Payload bits actually written.
    pub actual_payload_bits: f64,
    /// Leaves in the quadtree cut.
    pub leaves: usize,
}

/// Most passes that spend the bytes a budget's stream left unused.
const SPEND_PASSES: usize = 6;

/// Most plans a quality target tries before it gives up.
const QUALITY_PASSES: usize = 8;

/// A budget's stream is left as it is once it uses all but this share of the budget.
const SPEND_UNTIL: f64 = 0.003;

/// PSNR (peak 255) of a squared error over `pixels` pixels.
pub fn psnr(sse: f64, pixels: usize) -> f64 {
    if sse <= 0.0 {
        return f64::INFINITY;
    }
    10.0 * (255.0f64 * 255.0 * pixels as f64 / sse).log10()
}

impl Analysis {
    /// Encodes for `target`. May be called any number of times on one analysis.
    pub fn encode(&self, target: Target) -> Result<Encoded, EncodeError> {
        let pixels = self.header.pixel_count();
        let budget = match target {
            Target::Bpp(b) if b.is_finite() && b > 0.0 => {
                Some((b * pixels as f64 / 8.0).floor() as usize)
            }
            Target::Bytes(n) if n > 0 => Some(n),
            Target::Psnr(p) if p.is_finite() && p > 0.0 => None,
            other => return Err(EncodeError::BadTarget(other)),
        };
        let mut variants = vec![Header {
            codebooks: [Codebook::EMPTY; 2],
            ..self.header
        }];
        if self.header.has_codebooks() {
            variants.push(self.header);
        }
        let mut best: Option<Encoded> = None;
        let mut last_err = None;
        for header in variants {
            let result = match (budget, target) {
                (Some(n), _) => self.encode_budget(&header, n),
                (None, Target::Psnr(p)) => self.encode_quality(&header, p),
                _ => unreachable!("targets are validated above"),
            };
            match result {
                Ok(e) => {
                    let better = match (&best, budget) {
                        (None, _) => true,
                        (Some(b), Some(_)) => e.sse < b.sse,
                        (Some(b), None) => e.bytes.len() < b.bytes.len(),
                    };
                    if better {
                        best = Some(e);
                    }
                }
                Err(e) => last_err = Some(e),
            }
        }
        best.ok_or_else(|| last_err.unwrap_or(EncodeError::Internal("no header variant")))
    }

    /// The encoded stream `written` of `plan`, with its reconstruction and figures.
    fn finish(
        &self,
        header: &Header,
        plan: &rate::Plan,
        written: writer::Written,
    ) -> Result<Encoded, EncodeError> {
        let reconstruction = writer::reconstruct(self, header, plan)?;
        let pixels = self.header.pixel_count();
        let sse: f64 = reconstruction
            .iter()
            .zip(&self.plane.data)
            .map(|(&a, &b)| {
                let d = f64::from(a) - f64::from(b);
                d * d
            })
            .sum();
        Ok(Encoded {
            psnr: psnr(sse, pixels),
            sse,
            estimated_payload_bits: plan.bits,
            actual_payload_bits: written.payload_bits,
            leaves: written.leaves,
            bytes: written.bytes,
            reconstruction,
        })
    }

    fn write(&self, header: &Header, plan: &rate::Plan) -> Result<writer::Written, EncodeError> {
        writer::write(self, header, plan)
    }

    /// Best stream of at most `budget` bytes. The analysis's rates ([`Analysis::rates`], from
    /// a trial encode's contexts) plan it; the real coder's size then corrects the plan's aim:
    /// down until the stream fits, then up to spend what it left unused.
    fn encode_budget(&self, header: &Header, budget: usize) -> Result<Encoded, EncodeError> {
        // The header (its payload length at most as long as for a payload of `budget` bytes)
        // and the four bytes of the range coder's flush.
        let longest_header = Header {
            payload_len: u32::try_from(budget).unwrap_or(u32::MAX),
            ..*header
        };
        let overhead = (longest_header.encoded_len() + 4) as f64 * 8.0;
        let mut aim = budget as f64 * 8.0 - overhead;
        let mut plan = self
            .rates
            .plan_for_bits(self, header, aim, Some(self.trial));
        let mut written = self.write(header, &plan)?;
        // Tighten the aim until the real stream fits.
        let mut tries = 0;
        while written.bytes.len() > budget {
            tries += 1;
            let excess = (written.bytes.len() - budget) as f64 * 8.0;
            aim -= excess.max(8.0) * if tries > 4 { 2.0 } else { 1.0 };
            let smaller = self
                .rates
                .plan_for_bits(self, header, aim, Some(plan.anchor()));
            let smaller_written = self.write(header, &smaller)?;
            if smaller_written.bytes.len() >= written.bytes.len() && aim < -overhead || tries > 40 {
                return Err(EncodeError::BudgetTooSmall {
                    budget,
                    smallest: smaller_written.bytes.len(),
                });
            }
            plan = smaller;
            written = smaller_written;
        }
        // The estimate is off by a few percent: spend what the stream left unused (scaled by
        // the estimate's error), keeping a larger stream only if it fits. An aim whose stream
        // did not fit bounds the next ones: they bisect towards it.
        let mut too_large: Option<f64> = None;
        for _ in 0..SPEND_PASSES {
            let unused = budget.saturating_sub(written.bytes.len()) as f64 * 8.0;
            if unused <= SPEND_UNTIL * budget as f64 * 8.0 {
                break;
            }
            let scale = (plan.bits / written.payload_bits.max(1.0)).clamp(0.5, 2.0);
            let mut next = aim + 0.9 * scale * unused;
            if let Some(bound) = too_large {
                next = next.min(0.5 * (aim + bound));
            }
            let larger = self
                .rates
                .plan_for_bits(self, header, next, Some(plan.anchor()));
            if larger.bits <= plan.bits {
                // No plan between this one and the bound: the budget falls in a gap of the
                // lower convex hull.
                if too_large.is_some() {
                    break;
                }
                aim = next;
                continue;
            }
            let larger_written = self.write(header, &larger)?;
            if larger_written.bytes.len() > budget {
                too_large = Some(next);
                continue;
            }
            aim = next;
            plan = larger;
            written = larger_written;
        }
        self.finish(header, &plan, written)
    }

    /// Smallest stream whose PSNR reaches `db`. The plan's error is an estimate (exact fits'
    /// quadratic forms): while the real stream misses the target, the plan aims lower by the
    /// miss. When no pass reaches it, the highest-quality stream ([`Analysis::best_stream`])
    /// is the last resort: a target up to its PSNR is always met, and its PSNR is the best
    /// that [`EncodeError::QualityUnreachable`] reports.
    fn encode_quality(&self, header: &Header, db: f64) -> Result<Encoded, EncodeError> {
        let pixels = self.header.pixel_count() as f64;
        let max_sse = 255.0 * 255.0 * pixels / 10f64.powf(db / 10.0);
        let mut aim = max_sse;
        let mut anchor = self.trial;
        for _ in 0..QUALITY_PASSES {
            let plan = self.rates.plan_for_sse(self, header, aim, Some(anchor));
            let written = self.write(header, &plan)?;
            let encoded = self.finish(header, &plan, written)?;
            if encoded.sse <= max_sse {
                return Ok(encoded);
            }
            // At least a little lower each pass, in case the plan did not change.
            aim *= (max_sse / encoded.sse).min(0.995);
            anchor = plan.anchor();
        }
        let best = self.best_stream()?;
        // A target given as the PSNR shown (rounded down) is met despite the rounding of the
        // conversion to an error.
        if best.sse <= max_sse * (1.0 + 1e-9) {
            return Ok(best);
        }
        Err(EncodeError::QualityUnreachable {
            requested: db,
            best: best.psnr,
        })
    }

    /// The stream of least error this analysis writes, with or without the codebooks: the
    /// plan of the smallest multiplier, which spends all the rate it wants (what a budget of
    /// unlimited bytes writes). The same whichever header variant asks.
    fn best_stream(&self) -> Result<Encoded, EncodeError> {
        let mut variants = vec![Header {
            codebooks: [Codebook::EMPTY; 2],
            ..self.header
        }];
        if self.header.has_codebooks() {
            variants.push(self.header);
        }
        let mut best: Option<Encoded> = None;
        for header in &variants {
            let plan = self.rates.plan_for_bits(self, header, f64::INFINITY, None);
            let written = self.write(header, &plan)?;
            let encoded = self.finish(header, &plan, written)?;
            if best.as_ref().is_none_or(|b| encoded.sse < b.sse) {
                best = Some(encoded);
            }
        }
        best.ok_or(EncodeError::Internal("no header variant"))
    }
}

/// Analyses an image with `config`; the result encodes any number of targets.
pub fn analyse(
    plane: Plane,
    config: &EncoderConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Analysis, EncodeError> {
    if plane.width == 0 || plane.height == 0 || plane.width > 65535 || plane.height > 65535 {
        return Err(EncodeError::BadDimensions {
            width: plane.width,
            height: plane.height,
        });
    }
    Ok(Analysis::run(plane, config, progress))
}
