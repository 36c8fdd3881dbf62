//! Images too large to analyse whole, encoded part by part: part of the public API (the
//! encoder's root, above every stage).
//!
//! An analysis keeps about 30 bytes a pixel until its streams are written, so a 16384 x 16384
//! image needs about 8 GB at once. Here the image is cut into parts, each a run of coding
//! tiles that follow each other in the stream (bands of a stripe), analysed on its own with the
//! row above it ([`Plane::crop`]) and the whole image's error weights: the analysis the whole
//! image's would make there, but for its trial encode. A first pass keeps only each part's
//! rate/distortion curve (its plans' estimated bits and error on a grid of multipliers); a
//! stream is then written in one walk that analyses each part again as it enters it and plans
//! it for its share of what the budget has left: what its curve gives at the multiplier at
//! which the curves of the parts still to come spend it (scaled by how far the parts written
//! so far were off their estimates), the last part taking all that is left. Only one part's
//! analysis is held at a time: memory grows with the part, not the image, for twice the
//! analysis time.

use super::analysis::{header_for, Analysis};
use super::chroma::ColourPlanes;
use super::masking::ContrastScale;
use super::rate::Plan;
use super::writer::{self, Part};
use super::{
    decode, psnr, EncodeError, Encoded, EncoderConfig, Fidelity, Plane, Target, DEBLOCK_STRENGTHS,
};
use decoder_core::internal::colour::rgb_to_ycbcr;
use decoder_core::internal::format::CODING_TILE;
use decoder_core::internal::syntax::Header;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Called once a part is analysed.
type Report<'a> = dyn Fn() + Sync + 'a;

/// The largest parts `pifs encode` asks for, pixels (a part is at least one band of a stripe,
/// and a stripe's last part takes a short rest with it): two bands of a 16384-pixel-wide
/// image, whose encode in parts peaked at 0.80 GB (docs/results.md).
pub const PART_PIXELS: u64 = 1 << 22;

/// A stream written in parts that leaves more than this share of its budget unused is written
/// again, aimed higher: the last part's plan is made from estimates alone, which miss by
/// a few per cent (each write analyses every part again).
const UNUSED_SHARE: f64 = 0.02;

/// How many times a stream in parts may be written to fit a budget (each write analyses every
/// part again). The size is not monotonic in the aim near the budget (the parts' shares move
/// in steps: a test image of `parts.rs` gave 3980, 4056 and 4078 bytes for aims rising by 0.3%
/// each), so the search needs a few bisections past its first overshoot.
const BUDGET_WRITES: usize = 6;

/// The multipliers each part's curve is measured at: `2^(k / 2 - 10)`, squared error per bit,
/// from rates above 8 bits a pixel to below any stream's smallest.
const CURVE_POINTS: usize = 81;

fn curve_lambda(k: usize) -> f64 {
    (k as f64 / 2.0 - 10.0).exp2()
}

/// Where a part lies in the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Area {
    /// Top-left pixel.
    origin: (u32, u32),
    /// Width and height, pixels.
    size: (u32, u32),
}

/// A part of the image: where it lies, and its rate/distortion curve.
#[derive(Debug, Clone)]
struct PartCurve {
    area: Area,
    /// Estimated payload bits of its plan at each multiplier of [`curve_lambda`].
    bits: Vec<f64>,
    /// Estimated (weighted) squared error of the same plans.
    sse: Vec<f64>,
}

impl PartCurve {
    /// `values` (of this curve) at the multiplier `exp(log_lambda)`, interpolated linearly in
    /// the logarithm of the multiplier.
    fn at(values: &[f64], log_lambda: f64) -> f64 {
        let k = (log_lambda / std::f64::consts::LN_2 + 10.0) * 2.0;
        let last = (values.len() - 1) as f64;
        let k = k.clamp(0.0, last);
        let lo = (k.floor() as usize).min(values.len() - 2);
        let t = k - lo as f64;
        values[lo] * (1.0 - t) + values[lo + 1] * t
    }
}

/// The image an analysis in parts encodes.
#[derive(Debug, Clone)]
enum Source {
    Gray(Plane),
    Rgb {
        width: u32,
        height: u32,
        rgb: Vec<u8>,
    },
}

/// An image analysed part by part ([`analyse_in_parts`]): serves any number of targets, each
/// written by analysing every part again.
#[derive(Debug, Clone)]
pub struct AnalysisInParts {
    source: Source,
    config: EncoderConfig,
    /// The whole image's contrast scale (its error weights).
    scale: Option<ContrastScale>,
    /// Header of its streams.
    header: Header,
    parts: Vec<PartCurve>,
}

/// The parts of an image of `header` of about `part_pixels` pixels: runs of whole bands of
/// coding tiles within a stripe, in coding order.
fn cut(header: &Header, part_pixels: u64) -> Vec<Area> {
    let (width, height) = (u32::from(header.width), u32::from(header.height));
    let stripe = header.stripe_width();
    let mut parts = Vec::new();
    for x in (0..width).step_by(stripe as usize) {
        let w = stripe.min(width - x);
        let bands = (part_pixels / (u64::from(w) * u64::from(CODING_TILE))).max(1);
        let h = u32::try_from(bands * u64::from(CODING_TILE)).unwrap_or(u32::MAX);
        let mut y = 0;
        while y < height {
            // A short last band joins the part before it.
            let rest = height - y;
            let take = if rest <= h + h / 2 { rest } else { h };
            parts.push(Area {
                origin: (x, y),
                size: (w, take),
            });
            y += take;
        }
    }
    parts
}

/// Analyses `plane` (an 8-bit grayscale image) in parts of about `part_pixels` pixels
/// ([`PART_PIXELS`] by default) with `config`, keeping only each part's rate/distortion curve.
/// `progress` is called with the parts analysed so far.
pub fn analyse_in_parts(
    plane: Plane,
    config: &EncoderConfig,
    part_pixels: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<AnalysisInParts, EncodeError> {
    AnalysisInParts::run(Source::Gray(plane), config, part_pixels, progress)
}

/// [`analyse_in_parts`] for an RGB image (`3 * width * height` bytes, row-major): colour
/// streams, as [`super::analyse_colour`] writes them.
pub fn analyse_colour_in_parts(
    width: u32,
    height: u32,
    rgb: Vec<u8>,
    config: &EncoderConfig,
    part_pixels: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<AnalysisInParts, EncodeError> {
    if rgb.len() != 3 * width as usize * height as usize {
        return Err(EncodeError::Internal("RGB buffer size mismatch"));
    }
    let source = Source::Rgb { width, height, rgb };
    AnalysisInParts::run(source, config, part_pixels, progress)
}

impl AnalysisInParts {
    fn run(
        source: Source,
        config: &EncoderConfig,
        part_pixels: u64,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<AnalysisInParts, EncodeError> {
        let (scale, mut header) = match &source {
            Source::Gray(plane) => {
                if plane.fine.is_some() {
                    return Err(EncodeError::Unsupported(
                        "a 16-bit surface analysed in parts",
                    ));
                }
                (
                    ContrastScale::of(plane, config.tune),
                    header_for(plane, config)?,
                )
            }
            Source::Rgb { width, height, rgb } => {
                // The plain luma, for the contrast statistics and the header (the coded luma,
                // `ColourPlanes::from_rgb`'s, also needs the chroma planes): no copy of the RGB.
                let luma = rgb
                    .chunks_exact(3)
                    .map(|p| rgb_to_ycbcr(p[0], p[1], p[2])[0])
                    .collect();
                let luma = Plane::new(*width, *height, luma);
                (
                    ContrastScale::of(&luma, config.tune),
                    header_for(&luma, config)?,
                )
            }
        };
        if matches!(source, Source::Rgb { .. }) {
            header.channels = 3;
        }
        let mut analysis = AnalysisInParts {
            source,
            config: config.clone(),
            scale,
            header,
            parts: Vec::new(),
        };
        for (k, area) in cut(&header, part_pixels).into_iter().enumerate() {
            let part = analysis.analyse_part(area, false)?;
            let header = part.header;
            let (bits, sse) = (0..CURVE_POINTS)
                .into_par_iter()
                .map(|k| {
                    let plan = part.rates.optimise(&part.tree, &header, curve_lambda(k));
                    (plan.bits, plan.sse)
                })
                .unzip();
            analysis.parts.push(PartCurve { area, bits, sse });
            progress(k as u64 + 1);
        }
        Ok(analysis)
    }

    /// How many parts the image is analysed in.
    pub fn parts(&self) -> usize {
        self.parts.len()
    }

    /// The analysis of the part at `area`: as the stream codes it (with the row above it), or
    /// `alone`, as an image of its own.
    fn analyse_part(&self, area: Area, alone: bool) -> Result<Analysis, EncodeError> {
        let Area { origin, size } = area;
        let keep = |plane: Plane| if alone { plane.alone() } else { plane };
        let (x, y) = origin;
        let (w, h) = size;
        match &self.source {
            Source::Gray(plane) => {
                let crop = keep(plane.crop(origin, size));
                Analysis::run_part(crop, None, &self.config, self.scale, &|_| {})
            }
            Source::Rgb { width, rgb, .. } => {
                // Two rows above the part (when there are), so that its luma and its chroma
                // (of 2 x 2 blocks) both keep the row above them.
                let above = y.min(2);
                let stride = 3 * *width as usize;
                let rows = (y - above) as usize..(y + h) as usize;
                let cut: Vec<u8> = rows
                    .flat_map(|r| {
                        let start = r * stride + 3 * x as usize;
                        rgb[start..start + 3 * w as usize].iter().copied()
                    })
                    .collect();
                let (luma, planes) = ColourPlanes::from_rgb(w, h + above, cut);
                let luma = keep(luma.crop((0, above), size));
                let chroma_size = (w.div_ceil(2), h.div_ceil(2));
                let colour = ColourPlanes {
                    chroma: planes
                        .chroma
                        .map(|c| keep(c.crop((0, above / 2), chroma_size))),
                    rgb: planes.rgb[3 * (above * w) as usize..].to_vec(),
                };
                Analysis::run_part(luma, Some(colour), &self.config, self.scale, &|_| {})
            }
        }
    }

    /// How many parts [`analyse_in_parts`] cuts a `width` x `height` image into under
    /// `config`, parts of about `part_pixels` pixels.
    pub fn count(width: u32, height: u32, config: &EncoderConfig, part_pixels: u64) -> usize {
        match super::analysis::header_of_size(width, height, config) {
            Ok(header) => cut(&header, part_pixels).len(),
            Err(_) => 0,
        }
    }

    /// Encodes for `target`, analysing every part again as the stream reaches it.
    pub fn encode(&self, target: Target) -> Result<Encoded, EncodeError> {
        self.encode_reporting(target, &|_| {})
    }

    /// [`AnalysisInParts::encode`], calling `progress` with the number of parts analysed so far
    /// (those that choose the edge smoothing, then every part of the stream; again if the
    /// stream must be written again to fit its budget or to spend it).
    pub fn encode_reporting(
        &self,
        target: Target,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Encoded, EncodeError> {
        let pixels = self.header.pixel_count();
        let done = AtomicU64::new(0);
        let report = || progress(done.fetch_add(1, Ordering::Relaxed) + 1);
        match target {
            Target::Bpp(b) if b.is_finite() && b > 0.0 => {
                self.encode_budget((b * pixels as f64 / 8.0).floor() as usize, &report)
            }
            Target::Bytes(n) if n > 0 => self.encode_budget(n, &report),
            Target::Psnr(p) if p.is_finite() && p > 0.0 => self.encode_quality(p, &report),
            other => Err(EncodeError::BadTarget(other)),
        }
    }

    /// The stream of at most `budget` bytes, in at most [`BUDGET_WRITES`] writes: aimed a
    /// little below it, lower by what it missed by while nothing fitted, higher by most of what
    /// it left while that is more than [`UNUSED_SHARE`] of the budget; once a stream has fitted
    /// and another has not, the next aim lies between theirs. The largest stream that fitted
    /// is kept.
    fn encode_budget(&self, budget: usize, report: &Report) -> Result<Encoded, EncodeError> {
        let longest = Header {
            payload_len: u32::try_from(budget).unwrap_or(u32::MAX),
            ..self.header
        };
        let overhead = (longest.encoded_len() + 4) as f64 * 8.0;
        let mut aim = (budget as f64 * 8.0 - overhead) * 0.998;
        // The largest stream that fitted, with its aim; the lowest aim whose stream did not.
        let mut fitted: Option<(f64, Encoded)> = None;
        let mut too_large: Option<f64> = None;
        let mut smallest = usize::MAX;
        for _ in 0..BUDGET_WRITES {
            let encoded = self.write(&Aim::Bits(aim), report)?;
            let size = encoded.bytes.len();
            smallest = smallest.min(size);
            if size <= budget {
                let unused = (budget - size) as f64 * 8.0;
                if unused <= UNUSED_SHARE * budget as f64 * 8.0 {
                    return Ok(encoded);
                }
                let next = aim + 0.9 * unused;
                if fitted.as_ref().is_none_or(|(_, f)| f.bytes.len() < size) {
                    fitted = Some((aim, encoded));
                }
                aim = too_large.map_or(next, |bound| next.min(0.5 * (aim + bound)));
            } else {
                too_large = Some(too_large.map_or(aim, |bound| bound.min(aim)));
                aim = match &fitted {
                    Some((below, _)) => 0.5 * (below + aim),
                    None => {
                        let excess = (size - budget) as f64 * 8.0;
                        aim - 1.5 * excess - 0.002 * aim.max(0.0)
                    }
                };
                if aim <= 0.0 {
                    return Err(EncodeError::BudgetTooSmall { budget, smallest });
                }
            }
        }
        fitted
            .map(|(_, encoded)| encoded)
            .ok_or(EncodeError::Internal(
                "a budget the parts missed four times",
            ))
    }

    /// The stream whose PSNR reaches `db`: planned at the multiplier whose estimated error
    /// meets it, lower by the miss while the stream misses it.
    fn encode_quality(&self, db: f64, report: &Report) -> Result<Encoded, EncodeError> {
        let channels = f64::from(self.header.channels);
        let values = self.header.pixel_count() as f64 * channels;
        let max_sse = 255.0 * 255.0 * values / 10f64.powf(db / 10.0);
        // The plans' error is luma's: a colour stream's RGB error is about three times it.
        let mut aim = max_sse / channels;
        let mut best = None;
        for _ in 0..4 {
            let encoded = self.write(&Aim::Sse(aim), report)?;
            if encoded.sse <= max_sse {
                return Ok(encoded);
            }
            aim *= (max_sse / encoded.sse).min(0.995);
            best = Some(encoded.psnr);
        }
        Err(EncodeError::QualityUnreachable {
            requested: db,
            best: best.unwrap_or(0.0),
        })
    }

    /// Part `k`'s share of `aim`: what its curve gives at the multiplier at which the parts
    /// from `k` on spend the aim's bits (their estimates times `scale`), or at which all
    /// parts' error adds up to the aim's; the last part's share of bits is all that is left.
    /// Parts' curves are measured at a few multipliers only: the part's plan is then searched
    /// for its share on its own candidates.
    fn share_for(&self, aim: &Aim, k: usize, scale: f64) -> f64 {
        let Some(part) = self.parts.get(k) else {
            return 0.0;
        };
        match aim {
            // The last part spends what is left.
            Aim::Bits(bits) if k + 1 == self.parts.len() => bits / scale,
            Aim::Bits(_) => PartCurve::at(&part.bits, self.log_lambda_for(aim, k, scale)),
            Aim::Sse(_) => PartCurve::at(&part.sse, self.log_lambda_for(aim, k, scale)),
        }
    }

    /// The logarithm of the multiplier at which the parts from `k` on spend the aim's bits
    /// (their estimates times `scale`), or at which all parts' error adds up to the aim's.
    fn log_lambda_for(&self, aim: &Aim, k: usize, scale: f64) -> f64 {
        let parts = match aim {
            Aim::Bits(_) => &self.parts[k.min(self.parts.len())..],
            Aim::Sse(_) => &self.parts[..],
        };
        // Both sums are monotonic in the multiplier: bits fall, error rises.
        let too_low = |log_lambda: f64| match aim {
            Aim::Bits(bits) => {
                let spent: f64 = parts
                    .iter()
                    .map(|p| PartCurve::at(&p.bits, log_lambda))
                    .sum();
                spent * scale > *bits
            }
            Aim::Sse(sse) => {
                let error: f64 = parts
                    .iter()
                    .map(|p| PartCurve::at(&p.sse, log_lambda))
                    .sum();
                error <= *sse
            }
        };
        let (mut a, mut b) = (curve_lambda(0).ln(), curve_lambda(CURVE_POINTS - 1).ln());
        if !too_low(a) {
            return a;
        }
        if too_low(b) {
            return b;
        }
        for _ in 0..60 {
            let mid = 0.5 * (a + b);
            if too_low(mid) {
                a = mid;
            } else {
                b = mid;
            }
        }
        b
    }

    /// The plan of part `k` (analysed: `analysis`) for its share of `aim` ([`share_for`]).
    fn plan_part(&self, analysis: &Analysis, aim: &Aim, k: usize, scale: f64) -> Plan {
        let share = self.share_for(aim, k, scale);
        let header = &analysis.header;
        match aim {
            Aim::Bits(_) => analysis.rates.plan_for_bits(analysis, header, share, None),
            Aim::Sse(_) => analysis.rates.plan_for_sse(analysis, header, share, None),
        }
    }

    /// Writes one stream for `aim`, part by part, with the edge smoothing the first part
    /// chooses (or the configured one).
    fn write(&self, aim: &Aim, report: &Report) -> Result<Encoded, EncodeError> {
        let mut planned = 0.0;
        // The first part's bits and estimate: it starts the contexts, so it misses its
        // estimate by more than the parts after it.
        let mut first_part = (0.0, 0.0);
        let mut next = 0usize;
        let first = self.first_part(aim, report)?;
        let header = Header {
            deblock: first.deblock,
            ..self.header
        };
        let mut first = Some(first.part);
        let mut make = |written: f64| -> Result<Part, EncodeError> {
            let k = next;
            next += 1;
            let part = match first.take() {
                Some(part) => part,
                None => {
                    let curve = self
                        .parts
                        .get(k)
                        .ok_or(EncodeError::Internal("too few parts"))?;
                    if k == 1 {
                        first_part = (written, planned);
                    }
                    // How far the parts written so far were off their estimates: the
                    // parts after the first, once there are.
                    let (bits, estimate) = match k {
                        1 => (written, planned),
                        _ => (written - first_part.0, planned - first_part.1),
                    };
                    let scale = match estimate {
                        e if e > 0.0 => (bits / e).clamp(0.5, 2.0),
                        _ => 1.0,
                    };
                    let left = match aim {
                        Aim::Bits(bits) => Aim::Bits(bits - written),
                        Aim::Sse(sse) => Aim::Sse(*sse),
                    };
                    let analysis = self.analyse_part(curve.area, false)?;
                    report();
                    let plan = self.plan_part(&analysis, &left, k, scale);
                    into_part(analysis, curve.area.origin, plan)
                }
            };
            planned += part.plan.bits;
            Ok(part)
        };
        let written = writer::write_in_parts(&header, &mut make)?;
        let reconstruction = decode(&written.bytes)?;
        let reference: &[u8] = match &self.source {
            Source::Gray(plane) => &plane.data,
            Source::Rgb { rgb, .. } => rgb,
        };
        let sse: f64 = reconstruction
            .iter()
            .zip(reference)
            .map(|(&a, &b)| {
                let d = f64::from(a) - f64::from(b);
                d * d
            })
            .sum();
        Ok(Encoded {
            psnr: psnr(sse, reference.len()),
            sse,
            estimated_payload_bits: planned,
            actual_payload_bits: written.payload_bits,
            leaves: written.leaves,
            channels: self.header.channels,
            chroma_bits: written.chroma_bits,
            bytes: written.bytes,
            reconstruction,
        })
    }

    /// The first part, analysed and planned for `aim`, and the edge smoothing every part's
    /// stream gets: the configured one, or the strongest that adds no error to a few parts
    /// spread over the image ([`SMOOTHING_SAMPLES`]), each written as an image of its own at
    /// the multiplier of the aim (their errors added up: the rule of a whole image's stream,
    /// [`Analysis::smoothing_for`], on a sample of it). The first part, which starts the
    /// image, is the same analysed alone or not.
    fn first_part(&self, aim: &Aim, report: &Report) -> Result<FirstPart, EncodeError> {
        let first = self
            .parts
            .first()
            .ok_or(EncodeError::Internal("no parts"))?;
        let smoothing = match self.config.deblock {
            Some(_) => None,
            None => Some(self.sampled_smoothing_errors(aim, report)?),
        };
        // Analysed after the samples: one analysis in memory at a time.
        let analysis = self.analyse_part(first.area, true)?;
        report();
        let plan = self.plan_part(&analysis, aim, 0, 1.0);
        let deblock = match smoothing {
            None => analysis.deblock.unwrap_or(0),
            Some(mut errors) => {
                for (e, more) in errors.iter_mut().zip(smoothing_errors(&analysis, &plan)?) {
                    *e += more;
                }
                let unsmoothed = errors[0];
                DEBLOCK_STRENGTHS
                    .iter()
                    .zip(&errors)
                    .filter(|(_, &e)| e <= unsmoothed)
                    .map(|(&d, _)| d)
                    .max()
                    .unwrap_or(0)
            }
        };
        Ok(FirstPart {
            part: into_part(analysis, first.area.origin, plan),
            deblock,
        })
    }

    /// The errors of the streams of the parts past the first that choose the edge smoothing
    /// ([`SMOOTHING_SAMPLES`], spread over the image), each analysed alone and planned at the
    /// multiplier of `aim`, with each strength of [`DEBLOCK_STRENGTHS`], added up.
    fn sampled_smoothing_errors(
        &self,
        aim: &Aim,
        report: &Report,
    ) -> Result<Vec<f64>, EncodeError> {
        let lambda = self.log_lambda_for(aim, 0, 1.0).exp();
        let mut errors = vec![0.0; DEBLOCK_STRENGTHS.len()];
        let n = self.parts.len();
        let samples = SMOOTHING_SAMPLES.min(n);
        for s in 1..samples {
            let curve = &self.parts[s * (n - 1) / (samples - 1)];
            let sample = self.analyse_part(curve.area, true)?;
            report();
            let plan = sample.rates.optimise(&sample.tree, &sample.header, lambda);
            for (e, more) in errors.iter_mut().zip(smoothing_errors(&sample, &plan)?) {
                *e += more;
            }
        }
        Ok(errors)
    }
}

/// How many parts, spread over the image, choose its edge smoothing.
const SMOOTHING_SAMPLES: usize = 3;

/// The error (as the analysis weighs it) of `plan`'s stream of `analysis`'s image with each
/// smoothing strength of [`DEBLOCK_STRENGTHS`].
fn smoothing_errors(analysis: &Analysis, plan: &Plan) -> Result<Vec<f64>, EncodeError> {
    DEBLOCK_STRENGTHS
        .par_iter()
        .map(|&deblock| {
            let header = Header {
                deblock,
                ..analysis.header
            };
            let encoded = analysis.finish(plan, analysis.write(&header, plan)?)?;
            Ok(Fidelity::Weighted.error(analysis, &encoded))
        })
        .collect()
}

/// What a stream of parts is planned for.
enum Aim {
    /// Payload bits.
    Bits(f64),
    /// Estimated (weighted) squared error.
    Sse(f64),
}

/// The first part of a stream, with the edge smoothing chosen on it.
struct FirstPart {
    part: Part,
    deblock: u8,
}

/// The part the writer walks, from its analysis and its plan.
fn into_part(analysis: Analysis, origin: (u32, u32), plan: Plan) -> Part {
    Part {
        origin,
        tree: analysis.tree,
        plane: analysis.plane,
        drawn: analysis.drawn,
        colour: analysis.colour,
        cache: analysis.chroma_cache,
        plan,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encoder::analysis::header_of_size;
    use crate::encoder::{analyse, analyse_colour};

    /// A smooth surface with texture of every strength from none to rough (so that parts
    /// differ and the rate/distortion curves have no gaps).
    fn textured(w: u32, h: u32) -> Vec<u8> {
        let mut seed = 11u32;
        (0..w * h)
            .map(|i| {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let (x, y) = (f64::from(i % w), f64::from(i / w));
                let smooth = 128.0 + 70.0 * (x / 23.0).sin() * (y / 31.0).cos() - 0.1 * y;
                let roughness = (x + y) / f64::from(w + h);
                let grain = f64::from(seed >> 24) / 255.0 - 0.5;
                (smooth + 48.0 * roughness * grain).clamp(0.0, 255.0) as u8
            })
            .collect()
    }

    fn config() -> EncoderConfig {
        EncoderConfig {
            max_leaf_log2: 6,
            ..EncoderConfig::for_targets(&[Target::Bytes(4000)], 384 * 448)
        }
    }

    /// Parts are runs of whole bands of a stripe, in coding order, covering the image once; a
    /// short last band joins the part above it.
    #[test]
    fn parts_cover_the_image_in_coding_order() {
        let header = header_of_size(
            640,
            300,
            &EncoderConfig {
                stripe: 4,
                ..EncoderConfig::default()
            },
        )
        .expect("a header");
        let parts = cut(&header, 1);
        let area = |x, y, w, h| Area {
            origin: (x, y),
            size: (w, h),
        };
        assert_eq!(
            parts,
            vec![
                area(0, 0, 512, 128),
                area(0, 128, 512, 172),
                area(512, 0, 128, 128),
                area(512, 128, 128, 172),
            ]
        );
        let area: u32 = parts.iter().map(|p| p.size.0 * p.size.1).sum();
        assert_eq!(area, 640 * 300);
    }

    /// One stream written part by part: within its budget, spending nearly all of it, decoding
    /// to the reconstruction it reports, and about as good as the stream of the whole image's
    /// analysis.
    #[test]
    fn a_stream_in_parts_fits_its_budget_and_matches_the_whole_analysis() {
        let (w, h) = (384, 448);
        let plane = Plane::new(w, h, textured(w, h));
        let config = config();
        let parted = analyse_in_parts(plane.clone(), &config, 1, &|_| {}).expect("parts");
        assert_eq!(parted.parts(), 3);
        assert_eq!(AnalysisInParts::count(w, h, &config, 1), 3);
        let budget = 4000;
        let encoded = parted.encode(Target::Bytes(budget)).expect("a stream");
        assert!(
            encoded.bytes.len() <= budget,
            "{} bytes",
            encoded.bytes.len()
        );
        assert!(
            encoded.bytes.len() >= budget * 97 / 100,
            "{} bytes",
            encoded.bytes.len()
        );
        assert_eq!(
            decode(&encoded.bytes).expect("decodes"),
            encoded.reconstruction
        );
        let whole = analyse(plane, &config, &|_| {})
            .expect("an analysis")
            .encode(Target::Bytes(budget))
            .expect("a stream");
        assert!(
            (encoded.psnr - whole.psnr).abs() < 0.3,
            "in parts {} dB, whole {} dB",
            encoded.psnr,
            whole.psnr
        );
        // A quality target: the least the parts' curves say reaches it, checked on the stream.
        let target = whole.psnr - 1.0;
        let quality = parted.encode(Target::Psnr(target)).expect("a stream");
        assert!(quality.psnr >= target, "{} dB", quality.psnr);
        assert!(quality.bytes.len() < encoded.bytes.len());
    }

    /// A colour image in parts: a colour stream within its budget, near the whole analysis's.
    #[test]
    fn colour_in_parts_writes_a_colour_stream() {
        let (w, h) = (256, 384);
        let luma = textured(w, h);
        let rgb: Vec<u8> = luma
            .iter()
            .enumerate()
            .flat_map(|(i, &l)| {
                let x = (i as u32 % w) as u8;
                [l, l / 2 + x / 4, 255 - l]
            })
            .collect();
        let config = config();
        let budget = 5000;
        let parted =
            analyse_colour_in_parts(w, h, rgb.clone(), &config, 1, &|_| {}).expect("parts");
        assert_eq!(parted.parts(), 3);
        let encoded = parted.encode(Target::Bytes(budget)).expect("a stream");
        assert_eq!(encoded.channels, 3);
        assert!(
            encoded.bytes.len() <= budget,
            "{} bytes",
            encoded.bytes.len()
        );
        let whole = analyse_colour(w, h, rgb, &config, &|_| {})
            .expect("an analysis")
            .encode(Target::Bytes(budget))
            .expect("a stream");
        assert!(
            (encoded.psnr - whole.psnr).abs() < 0.3,
            "in parts {} dB, whole {} dB",
            encoded.psnr,
            whole.psnr
        );
    }
}
