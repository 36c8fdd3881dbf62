//! The encoder, as stages from the bottom up (each module uses only those before it, as the
//! `layering` tests check):
//!
//! - [`ids`], [`plane`], [`config`], [`error`]: typed indices into the format's tables, the
//!   image, the settings and targets, the errors;
//! - [`synthesis`]: floating-point tabulation of a patch with exact derivatives;
//! - [`fit`]: every model fitted to a block (the inverse problem);
//! - [`quantise`]: a fit's parameters made syntax elements;
//! - [`candidates`]: what the analysis keeps per node, level by level;
//! - [`rate`]: rates of the candidates, the Lagrangian pruning of the quadtree and the search
//!   for the multiplier that meets a target;
//! - [`writer`]: the stream of a plan, and its reconstruction;
//! - [`analysis`]: the driver that runs the stages on an image;
//! - this module: the public API, [`analyse`] and [`Analysis::encode`] for any [`Target`];
//!   with [`parts`], images too large to analyse whole ([`analyse_in_parts`]).

mod analysis;
mod candidates;
mod chroma;
mod config;
mod error;
mod fit;
mod ids;
mod masking;
mod parts;
mod plane;
mod quantise;
mod rate;
mod synthesis;
mod writer;

#[cfg(test)]
mod layering;

pub use analysis::{analysis_steps, Analysis, AnalysisStage, AnalysisSteps, AnalysisTiming};
pub use chroma::{ColourPlanes, CHROMA_WEIGHTS};
pub use config::{
    EncoderConfig, Target, Tune, BOUND_PENALTY, DEFAULT_STRIPE_TILES, DEFAULT_TRIAL_BPP,
    FINE_STEPS_BELOW_BPP, FINE_STEP_MARGIN, LOW_RATE_BPP, LOW_RATE_MIN_LEAF_LOG2, MIN_TRIAL_BPP,
    WHOLE_WIDTH,
};
pub use error::EncodeError;
pub use parts::{analyse_colour_in_parts, analyse_in_parts, AnalysisInParts, PART_PIXELS};
pub use plane::{psnr, Plane};
pub use quantise::forward_grid_transform;
pub(crate) use writer::LeafBits;

use decoder_core::internal::syntax::Header;
use decoder_core::SampleRange;
use rayon::prelude::*;

/// An encoded stream with its figures.
#[derive(Debug, Clone)]
pub struct Encoded {
    /// The complete `.pifs` stream.
    pub bytes: Vec<u8>,
    /// The encoder's closed-loop reconstruction (equal to what any decoder produces).
    pub reconstruction: Vec<u8>,
    /// Squared error of the reconstruction (of a 16-bit surface: of the stream's values
    /// against the surface at 1/16 of a grey level, in grey levels squared).
    pub sse: f64,
    /// PSNR of the reconstruction, dB (infinite when lossless; of a 16-bit surface, the PSNR
    /// of its range).
    pub psnr: f64,
    /// Payload bits the rate model predicted for the final plan.
    pub estimated_payload_bits: f64,
    /// Payload bits actually written.
    pub actual_payload_bits: f64,
    /// Leaves in the quadtree cut.
    pub leaves: usize,
    /// Channels: 1 (grayscale; `reconstruction` is luma) or 3 (colour; `reconstruction` is
    /// RGB, and `sse` and `psnr` are over the three channels).
    pub channels: u8,
    /// Payload bits of the chroma planes, estimated from the contexts' probabilities (0 for
    /// grayscale).
    pub chroma_bits: f64,
}

/// The stream [`Analysis::fit_budget`] found for a budget, with its plan and the aim (payload
/// bits by the rate estimate) that planned it.
struct BudgetFit {
    plan: rate::Plan,
    encoded: Encoded,
    aim: f64,
}

/// Which error a smoothing strength must not add to.
#[derive(Debug, Clone, Copy)]
enum Fidelity {
    /// The error the analysis minimises ([`Analysis::distortion`]): for budgets.
    Weighted,
    /// The plain squared error: for PSNR targets, which smoothing must not make miss.
    Plain,
}

impl Fidelity {
    /// This error of `encoded`, a stream of `analysis`.
    fn error(self, analysis: &Analysis, encoded: &Encoded) -> f64 {
        match self {
            Fidelity::Weighted => analysis.distortion(encoded),
            Fidelity::Plain => encoded.sse,
        }
    }
}

/// Most passes that spend the bytes a budget's stream left unused.
const SPEND_PASSES: usize = 6;

/// Most plans a quality target tries before it gives up.
const QUALITY_PASSES: usize = 8;

/// A budget's stream is left as it is once it uses all but this share of the budget.
const SPEND_UNTIL: f64 = 0.003;

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
        // A fixed smoothing strength is every stream's; otherwise each target chooses one.
        let header = Header {
            deblock: self.deblock.unwrap_or(0),
            ..self.header
        };
        match (budget, target) {
            (Some(n), _) => self.encode_budget(&header, n),
            (None, Target::Psnr(p)) => self.encode_quality(&header, p),
            _ => unreachable!("targets are validated above"),
        }
    }

    /// The encoded stream `written` of `plan`, with its reconstruction and figures.
    fn finish(&self, plan: &rate::Plan, written: writer::Written) -> Result<Encoded, EncodeError> {
        let reconstruction = decode(&written.bytes)?;
        let channels = self.header.channels;
        let pixels = self.header.pixel_count() * usize::from(channels);
        let reference = match &self.colour {
            Some(colour) => &colour.rgb,
            None => &self.plane.data,
        };
        let sse: f64 = match (&self.plane.fine, self.header.range) {
            (Some(fine), Some(range)) => surface_sse(&written.bytes, fine, range)?,
            _ => reconstruction
                .iter()
                .zip(reference)
                .map(|(&a, &b)| {
                    let d = f64::from(a) - f64::from(b);
                    d * d
                })
                .sum(),
        };
        Ok(Encoded {
            psnr: psnr(sse, pixels),
            sse,
            estimated_payload_bits: plan.bits,
            actual_payload_bits: written.payload_bits,
            leaves: written.leaves,
            channels,
            chroma_bits: written.chroma_bits,
            bytes: written.bytes,
            reconstruction,
        })
    }

    /// What the analysis minimises, of a written stream: its squared error, weighted as the
    /// candidates' ([`masking::Masking`]).
    fn distortion(&self, encoded: &Encoded) -> f64 {
        let reference = match &self.colour {
            Some(colour) => &colour.rgb,
            None => &self.plane.data,
        };
        let channels = usize::from(encoded.channels);
        self.tree
            .masking()
            .weighted_sse(
                self.plane.width,
                channels,
                reference,
                &encoded.reconstruction,
            )
            .unwrap_or(encoded.sse)
    }

    /// The image as the analysis predicts from it: what its candidates' syntax is made from.
    fn image(&self) -> plane::ImagePrediction<'_> {
        analysis::prediction_of(&self.plane, &self.header).with_drawn(self.drawn.as_ref())
    }

    fn write(&self, header: &Header, plan: &rate::Plan) -> Result<writer::Written, EncodeError> {
        writer::write(
            (&self.tree, &self.image()),
            header,
            plan,
            self.colour.as_ref(),
            &self.chroma_cache,
        )
    }

    /// Best stream of at most `budget` bytes: planned without edge smoothing, then, if a
    /// smoothing strength lowers that plan's error ([`Analysis::smoothing_for`], the error as
    /// the analysis weighs it: [`Analysis::distortion`]), planned again with it from where the
    /// first planning ended (smoothing changes the stream's size a little). If that stream's
    /// error is larger than the unsmoothed one's, the next weaker strength that passes is
    /// planned, and so on: the picture goes unsmoothed only when no strength keeps the error
    /// (see docs/decisions.md).
    fn encode_budget(&self, header: &Header, budget: usize) -> Result<Encoded, EncodeError> {
        let unsmoothed = self.fit_budget(header, budget, None)?;
        let mut below = u8::MAX;
        while let Some(deblock) = self.smoothing_for(
            header,
            &unsmoothed.plan,
            &unsmoothed.encoded,
            below,
            Fidelity::Weighted,
        )? {
            let smoothed_header = Header { deblock, ..*header };
            let smoothed = self.fit_budget(&smoothed_header, budget, Some(&unsmoothed))?;
            if self.distortion(&smoothed.encoded) <= self.distortion(&unsmoothed.encoded) {
                return Ok(smoothed.encoded);
            }
            below = deblock;
        }
        Ok(unsmoothed.encoded)
    }

    /// Best stream of at most `budget` bytes with `header`'s edge smoothing, and its plan. The
    /// analysis's rates ([`Analysis::rates`], from
    /// a trial encode's contexts) plan it; the real coder's size then corrects the plan's aim:
    /// down until the stream fits, then up to spend what it left unused. Starts from the aim
    /// and plan `from` ended with, if given (a fit of the same budget under another header),
    /// else from the budget and the trial's plan.
    fn fit_budget(
        &self,
        header: &Header,
        budget: usize,
        from: Option<&BudgetFit>,
    ) -> Result<BudgetFit, EncodeError> {
        // The header (its payload length at most as long as for a payload of `budget` bytes)
        // and the four bytes of the range coder's flush.
        let longest_header = Header {
            payload_len: u32::try_from(budget).unwrap_or(u32::MAX),
            ..*header
        };
        let overhead = (longest_header.encoded_len() + 4) as f64 * 8.0;
        let mut aim = from.map_or(budget as f64 * 8.0 - overhead, |f| f.aim);
        let hint = from.map_or(self.trial, |f| f.plan.anchor());
        let mut plan = self.rates.plan_for_bits(self, header, aim, Some(hint));
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
        let encoded = self.finish(&plan, written)?;
        Ok(BudgetFit { plan, encoded, aim })
    }

    /// Smallest stream whose PSNR reaches `db`. The plan's error is an estimate (exact fits'
    /// quadratic forms): while the real stream misses the target, the plan aims lower by the
    /// miss. When no pass reaches it, the highest-quality stream ([`Analysis::best_stream`])
    /// is the last resort: a target up to its PSNR is always met, and its PSNR is the best
    /// that [`EncodeError::QualityUnreachable`] reports.
    fn encode_quality(&self, header: &Header, db: f64) -> Result<Encoded, EncodeError> {
        let channels = f64::from(self.header.channels);
        let pixels = self.header.pixel_count() as f64 * channels;
        let max_sse = 255.0 * 255.0 * pixels / 10f64.powf(db / 10.0);
        // The plan's error is luma's: a colour stream's RGB error is at least three times it.
        let mut aim = max_sse / channels;
        let mut anchor = self.trial;
        for _ in 0..QUALITY_PASSES {
            let plan = self.rates.plan_for_sse(self, header, aim, Some(anchor));
            let written = self.write(header, &plan)?;
            let encoded = self.finish(&plan, written)?;
            if encoded.sse <= max_sse {
                return self.smoothed(header, &plan, encoded);
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

    /// The stream of least error this analysis writes: the plan of the smallest multiplier,
    /// which spends all the rate it wants (what a budget of unlimited bytes writes).
    fn best_stream(&self) -> Result<Encoded, EncodeError> {
        let header = Header {
            deblock: self.deblock.unwrap_or(0),
            ..self.header
        };
        let plan = self.rates.plan_for_bits(self, &header, f64::INFINITY, None);
        let written = self.write(&header, &plan)?;
        let encoded = self.finish(&plan, written)?;
        self.smoothed(&header, &plan, encoded)
    }

    /// The stream of `plan` with the smoothing strength [`Analysis::smoothing_for`] chooses,
    /// or `unsmoothed` (the plan's stream without smoothing) when it chooses none.
    fn smoothed(
        &self,
        header: &Header,
        plan: &rate::Plan,
        unsmoothed: Encoded,
    ) -> Result<Encoded, EncodeError> {
        let Some(deblock) =
            self.smoothing_for(header, plan, &unsmoothed, u8::MAX, Fidelity::Plain)?
        else {
            return Ok(unsmoothed);
        };
        let header = Header { deblock, ..*header };
        let written = self.write(&header, plan)?;
        self.finish(plan, written)
    }

    /// The smoothing of leaf edges ([`Header::deblock`]) for the streams of `plan` when the
    /// analysis has no fixed strength: the strongest below `below` that leaves the error
    /// (`fidelity`'s) no larger than `unsmoothed`'s (the plan's stream without smoothing);
    /// `None` for none. Smoothing steps across leaf edges makes the picture continuous where
    /// the leaves' errors differ; among the strengths that do not cost fidelity, the strongest
    /// leaves the fewest visible edges (see docs/decisions.md).
    fn smoothing_for(
        &self,
        header: &Header,
        plan: &rate::Plan,
        unsmoothed: &Encoded,
        below: u8,
        fidelity: Fidelity,
    ) -> Result<Option<u8>, EncodeError> {
        if self.deblock.is_some() {
            // Fixed: already in the header.
            return Ok(None);
        }
        // Strongest first, as many at once as there are threads: each is a sequential write.
        let strengths: Vec<u8> = DEBLOCK_STRENGTHS
            .iter()
            .rev()
            .copied()
            .filter(|&d| d != 0 && d < below)
            .collect();
        for batch in strengths.chunks(rayon::current_num_threads().max(1)) {
            let errors: Vec<Result<f64, EncodeError>> = batch
                .par_iter()
                .map(|&deblock| {
                    let header = Header { deblock, ..*header };
                    let written = self.write(&header, plan)?;
                    Ok(fidelity.error(self, &self.finish(plan, written)?))
                })
                .collect();
            let limit = fidelity.error(self, unsmoothed);
            for (&deblock, error) in batch.iter().zip(errors) {
                if error? <= limit {
                    return Ok(Some(deblock));
                }
            }
        }
        Ok(None)
    }
}

/// What packets (`crate::packets`) need of an analysis: streams of a budget, where a stream's
/// bits go, and the analysis of a part of the image.
impl Analysis {
    /// The image's own pixels, as streams' reconstructions hold them (gray, or RGB triples).
    pub(crate) fn source(&self) -> &[u8] {
        match &self.colour {
            Some(colour) => &colour.rgb,
            None => &self.plane.data,
        }
    }

    /// The best stream of at most `budget` bytes.
    pub(crate) fn encode_plain(&self, budget: usize) -> Result<Encoded, EncodeError> {
        let header = Header {
            deblock: self.deblock.unwrap_or(0),
            ..self.header
        };
        self.encode_budget(&header, budget)
    }

    /// The bits each leaf costs in the plan of the stream [`Analysis::encode_plain`] makes for
    /// `budget` bytes (before its smoothing strength is chosen, which changes no leaf).
    pub(crate) fn leaf_bits(&self, budget: usize) -> Result<Vec<LeafBits>, EncodeError> {
        let header = Header {
            deblock: self.deblock.unwrap_or(0),
            ..self.header
        };
        let plan = self.fit_budget(&header, budget, None)?.plan;
        writer::leaf_bits(
            (&self.tree, &self.image()),
            &header,
            &plan,
            self.colour.as_ref(),
            &self.chroma_cache,
        )
    }

    /// The analysis of the rectangle `area` of this analysis's image, as an image of its own
    /// (colour when this one is), with `config`.
    pub(crate) fn region(
        &self,
        area: decoder_core::Rect,
        config: &EncoderConfig,
    ) -> Result<Analysis, EncodeError> {
        let (x0, y0, w, h) = (
            area.x as usize,
            area.y as usize,
            area.w as usize,
            area.h as usize,
        );
        let width = self.plane.width as usize;
        let crop = |data: &[u8], channels: usize| -> Vec<u8> {
            (y0..y0 + h)
                .flat_map(|y| {
                    let start = (y * width + x0) * channels;
                    data[start..start + w * channels].iter().copied()
                })
                .collect()
        };
        match &self.colour {
            Some(colour) => analyse_colour(area.w, area.h, crop(&colour.rgb, 3), config, &|_| {}),
            None => analyse(
                Plane::new(area.w, area.h, crop(&self.plane.data, 1)),
                config,
                &|_| {},
            ),
        }
    }
}

/// The edge-smoothing strengths an encode tries, weakest first ([`Header::deblock`]: a step
/// is smoothed by a third when it is at most `strength / 2` control steps, by less up to four
/// times that).
const DEBLOCK_STRENGTHS: [u8; 8] = [0, 1, 2, 3, 4, 6, 8, 12];

/// Analyses an image with `config`; the result encodes any number of targets. `progress` is
/// called with the number of node steps done so far (every node of a leaf size fitted, its
/// candidates made, and refined: [`analysis_steps`] lists them in order). Fails with
/// [`EncodeError::BadDimensions`] on an image the format cannot hold (empty, or more than
/// 65535 pixels on a side).
pub fn analyse(
    plane: Plane,
    config: &EncoderConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Analysis, EncodeError> {
    Analysis::run(plane, None, config, progress)
}

/// Analyses an RGB image (`3 * width * height` bytes, row-major) for colour streams: the
/// analysis of its luma ([`analyse`]) with, at every node, what its chroma costs (converted by
/// decoder-core's integer BT.601 conversion, chroma subsampled 4:2:0), which the quadtree's
/// cut weighs too. Streams' error is then the RGB squared error.
pub fn analyse_colour(
    width: u32,
    height: u32,
    rgb: Vec<u8>,
    config: &EncoderConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Analysis, EncodeError> {
    if rgb.len() != 3 * width as usize * height as usize {
        return Err(EncodeError::Internal("RGB buffer size mismatch"));
    }
    let (luma, colour) = ColourPlanes::from_rgb(width, height, rgb);
    Analysis::run(luma, Some(colour), config, progress)
}

/// The image a stream decodes to, by decoder-core (what every decoder shows).
/// The squared error of a 16-bit stream's values against a surface's targets `fine` (1/16 grey
/// level), in grey levels squared (so that its PSNR, peak 255, is the PSNR of the range).
fn surface_sse(stream: &[u8], fine: &[u16], range: SampleRange) -> Result<f64, EncodeError> {
    let decoder = decoder_core::Decoder::new(stream)
        .map_err(EncodeError::Syntax)?
        .stripe_capacity::<{ 1 << 16 }>();
    let mut values = vec![0u16; fine.len()];
    decoder
        .decode_values_into(&mut values)
        .map_err(EncodeError::Syntax)?;
    let grey = f64::from(SampleRange::STEP_ONE) / f64::from(range.step);
    Ok(values
        .iter()
        .zip(fine)
        .map(|(&v, &s)| {
            let target = range.value(s as i16);
            let d = (f64::from(v) - f64::from(target)) * grey;
            d * d
        })
        .sum())
}

fn decode(stream: &[u8]) -> Result<Vec<u8>, EncodeError> {
    let decoder = decoder_core::Decoder::new(stream)
        .map_err(EncodeError::Syntax)?
        .stripe_capacity::<{ 1 << 16 }>();
    let channels = usize::from(decoder.header().channels);
    let mut pixels = vec![0u8; decoder.header().pixel_count() * channels];
    decoder
        .decode_into(&mut pixels)
        .map_err(EncodeError::Syntax)?;
    Ok(pixels)
}
