//! `pifs encode`, and the analysis and stream writing that `rd` and the demo share with it.

use crate::error::{CliError, Result};
use crate::output::{self, Kind};
use crate::progress::{Progress, Work};
use clap::Args;
use host_encoder::{
    analyse, analyse_colour, io, Analysis, EncodeError, Encoded, EncoderConfig, Plane, Target,
};
use std::path::PathBuf;
use std::time::Instant;

/// The target when none is given: a rate, not a ceiling (see [`encode_stream`]).
pub const DEFAULT_BPP: f64 = 0.25;

/// Arguments of `pifs encode`.
#[derive(Args, Debug)]
pub struct EncodeArgs {
    /// Input image (PNG, JPEG, PGM/PPM, BMP, TIFF). A colour image gives a colour stream
    /// (YCbCr 4:2:0) unless --gray; a gray one (or a colour image whose pixels are all gray)
    /// a grayscale stream.
    pub input: PathBuf,
    /// Encode in grayscale (the image's luma), even from a colour image.
    #[arg(long)]
    pub gray: bool,
    /// Output stream. Any name but an image format's (.png, .jpg, ... are refused, so that a
    /// stream never poses as an image); .pifs by convention.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Target bits per pixel, whole file, never exceeded [default: 0.25, or the smallest
    /// stream when the image is too small for that rate].
    #[arg(long, group = "target")]
    pub bpp: Option<f64>,
    /// Largest file size in bytes, header included, never exceeded.
    #[arg(long, group = "target")]
    pub bytes: Option<usize>,
    /// Smallest file reaching this PSNR (dB); if no stream does, the error says the best
    /// reachable.
    #[arg(long, group = "target")]
    pub psnr: Option<f64>,
    #[command(flatten)]
    pub analysis: AnalysisArgs,
}

/// The analysis settings of `encode` and `rd`.
#[derive(Args, Debug, Clone)]
pub struct AnalysisArgs {
    /// Smallest leaf side as a power of two. Leaves of 2 px make encoding much longer for
    /// little gain: 4 px leaves already code each pixel with a pixel grid.
    #[arg(long, default_value_t = EncoderConfig::default().min_leaf_log2, value_parser = clap::value_parser!(u8).range(1..=7))]
    pub min_leaf_log2: u8,
    /// Largest leaf side as a power of two.
    #[arg(long, default_value_t = EncoderConfig::default().max_leaf_log2, value_parser = clap::value_parser!(u8).range(1..=7))]
    pub max_leaf_log2: u8,
    /// Also fit the subdivision weights (the thesis's full inverse problem): a much longer
    /// analysis for very little gain.
    #[arg(long)]
    pub fit_weights: bool,
    /// Width of the stripes the image is coded in, in pixels (a multiple of 128), or `full` for
    /// one stripe as wide as the image. A decoder holds one byte per column of a stripe:
    /// decoder-core holds 512 unless told otherwise, so wider stripes are for decoders that
    /// hold more (prediction and edge smoothing stop at a stripe's left edge).
    #[arg(long, default_value = "512", value_parser = parse_stripe)]
    pub stripe_width: u8,
    /// Strength of the smoothing of leaf edges: `auto` (the strongest that does not add to
    /// the error), or 0 (none) to 16.
    #[arg(long, default_value = "auto", value_parser = parse_deblock)]
    pub deblock: Deblock,
}

/// `--deblock`: a fixed edge-smoothing strength, or `None` for the encoder's choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Deblock(pub Option<u8>);

/// `--stripe-width`: pixels (a positive multiple of 128, at most 255 * 128) or `full`, as the
/// header's stripe field (tiles of 128 pixels; 0 for the whole width).
fn parse_stripe(s: &str) -> std::result::Result<u8, String> {
    if s == "full" {
        return Ok(0);
    }
    let px: u32 = s
        .parse()
        .map_err(|_| format!("'{s}' is not a width in pixels or 'full'"))?;
    if px == 0 || !px.is_multiple_of(128) || px / 128 > 255 {
        return Err(format!(
            "{px} is not a multiple of 128 from 128 to 32640 (or 'full')"
        ));
    }
    Ok((px / 128) as u8)
}

/// `--deblock`: `auto` or a strength from 0 to 16.
fn parse_deblock(s: &str) -> std::result::Result<Deblock, String> {
    if s == "auto" {
        return Ok(Deblock(None));
    }
    match s.parse::<u8>() {
        Ok(v) if v <= 16 => Ok(Deblock(Some(v))),
        _ => Err(format!("'{s}' is not 'auto' or a strength from 0 to 16")),
    }
}

impl Default for AnalysisArgs {
    fn default() -> Self {
        let d = EncoderConfig::default();
        AnalysisArgs {
            min_leaf_log2: d.min_leaf_log2,
            max_leaf_log2: d.max_leaf_log2,
            fit_weights: d.fit_weights,
            stripe_width: d.stripe,
            deblock: Deblock(d.deblock),
        }
    }
}

impl AnalysisArgs {
    /// The analysis's settings for `targets` on an image of `pixels` pixels.
    fn config(&self, pixels: usize, targets: &[Target]) -> EncoderConfig {
        let chosen = EncoderConfig::for_targets(targets, pixels);
        EncoderConfig {
            min_leaf_log2: self.min_leaf_log2,
            max_leaf_log2: self.max_leaf_log2.max(self.min_leaf_log2),
            fit_weights: self.fit_weights,
            stripe: self.stripe_width,
            deblock: self.deblock.0,
            ..chosen
        }
    }
}

/// An analysed image.
#[derive(Debug)]
pub struct Analysed {
    /// The analysis.
    pub analysis: Analysis,
    /// Its wall time, seconds.
    pub seconds: f64,
}

impl Analysed {
    /// Width and height, pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.analysis.width(), self.analysis.height())
    }

    /// Bits per pixel of a stream of `bytes` bytes.
    pub fn bpp(&self, bytes: usize) -> f64 {
        let (w, h) = self.size();
        bytes as f64 * 8.0 / (f64::from(w) * f64::from(h))
    }
}

/// Analyses `plane` once for `targets`, with a progress display on a terminal.
pub fn analyse_plane(plane: Plane, args: &AnalysisArgs, targets: &[Target]) -> Result<Analysed> {
    let start = Instant::now();
    let config = args.config(plane.data.len(), targets);
    let work = Work::new(
        plane.width,
        plane.height,
        config.min_leaf_log2,
        config.max_leaf_log2,
    );
    let progress = Progress::on_terminal(work);
    let result = analyse(plane, &config, &|n| {
        if let Some(p) = &progress {
            p.nodes_done(n);
        }
    });
    if let Some(p) = &progress {
        p.finish();
    }
    Ok(Analysed {
        analysis: result?,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Analyses a loaded image ([`analyse_plane`]), in colour when it is colour.
pub fn analyse_loaded(
    image: &io::Loaded,
    args: &AnalysisArgs,
    targets: &[Target],
) -> Result<Analysed> {
    let io::Loaded::Rgb {
        width,
        height,
        data,
    } = image
    else {
        let io::Loaded::Gray(plane) = image else {
            unreachable!("two variants")
        };
        return analyse_plane(plane.clone(), args, targets);
    };
    let start = Instant::now();
    let pixels = *width as usize * *height as usize;
    let config = args.config(pixels, targets);
    let work = Work::new(*width, *height, config.min_leaf_log2, config.max_leaf_log2);
    let progress = Progress::on_terminal(work);
    let result = analyse_colour(*width, *height, data.clone(), &config, &|n| {
        if let Some(p) = &progress {
            p.nodes_done(n);
        }
    });
    if let Some(p) = &progress {
        p.finish();
    }
    Ok(Analysed {
        analysis: result?,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Loads `path` as the encoder takes it: colour unless `gray` (or the image is gray).
pub fn load_input(path: &std::path::Path, gray: bool) -> Result<io::Loaded> {
    Ok(if gray {
        io::Loaded::Gray(io::load_luma(path)?)
    } else {
        io::load_image(path)?
    })
}

/// A stream to write: its target, and whether the user chose it or it is the default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Job {
    /// What to encode for.
    pub target: Target,
    /// The default target stands for "a sensible size", not a limit: an image too small for
    /// its budget gets its smallest stream instead of an error.
    pub is_default: bool,
}

/// The stream for `job`, and what was done instead of the job's target, if anything.
pub fn encode_stream(analysis: &Analysis, job: Job) -> Result<(Encoded, Option<String>)> {
    let first = match analysis.encode(job.target) {
        Err(EncodeError::BudgetTooSmall { budget, smallest }) if job.is_default => {
            (budget, smallest)
        }
        other => return Ok((other?, None)),
    };
    let (budget, mut smallest) = first;
    // The smallest stream's size comes from the search that failed; ask for it exactly (a
    // second refusal names a size that fits).
    for _ in 0..4 {
        match analysis.encode(Target::Bytes(smallest)) {
            Ok(encoded) => {
                let note = format!(
                    "the default {DEFAULT_BPP} bpp allows {budget} bytes, less than the smallest stream for this image: wrote the smallest"
                );
                return Ok((encoded, Some(note)));
            }
            Err(EncodeError::BudgetTooSmall { smallest: s, .. }) if s > smallest => smallest = s,
            Err(e) => return Err(e.into()),
        }
    }
    Err(CliError::Encode(EncodeError::Internal(
        "the smallest stream does not fit its own size",
    )))
}

/// Encodes `job` from `analysed`, writes the stream to `output` atomically and prints its
/// figures.
pub fn write_stream(analysed: &Analysed, job: Job, output: &std::path::Path) -> Result<Encoded> {
    let t = Instant::now();
    let (encoded, note) = encode_stream(&analysed.analysis, job)?;
    io::write_atomic(output, &encoded.bytes)?;
    let (w, h) = analysed.size();
    let gap = 100.0 * (encoded.estimated_payload_bits - encoded.actual_payload_bits)
        / encoded.actual_payload_bits.max(1.0);
    let note = note.map(|n| format!(" ({n})")).unwrap_or_default();
    let kind = if encoded.channels == 3 {
        format!(
            "colour, PSNR-RGB {:.2} dB, chroma {:.1}% of the payload",
            encoded.psnr,
            100.0 * encoded.chroma_bits / encoded.actual_payload_bits.max(1.0)
        )
    } else {
        format!("gray, PSNR {:.2} dB", encoded.psnr)
    };
    println!(
        "{}: {w}x{h} -> {} bytes, {:.4} bpp, {kind}, {} leaves, rate estimate {gap:+.2}% off, analysis {:.2} s + encode {:.2} s{note}",
        output.display(),
        encoded.bytes.len(),
        analysed.bpp(encoded.bytes.len()),
        encoded.leaves,
        analysed.seconds,
        t.elapsed().as_secs_f64()
    );
    Ok(encoded)
}

/// Refuses a target that is not a positive number, naming the option.
pub fn validate_target(target: Target) -> Result<()> {
    let why = match target {
        Target::Bpp(b) if !(b.is_finite() && b > 0.0) => {
            format!("--bpp must be a positive number, got {b}")
        }
        Target::Bytes(0) => "--bytes must be at least 1".into(),
        Target::Psnr(p) if !(p.is_finite() && p > 0.0) => {
            format!("--psnr must be a positive number, got {p}")
        }
        _ => return Ok(()),
    };
    Err(CliError::Refused(why))
}

impl EncodeArgs {
    /// The job the options ask for.
    fn job(&self) -> Job {
        let chosen = match (self.bpp, self.bytes, self.psnr) {
            (_, Some(n), _) => Some(Target::Bytes(n)),
            (_, _, Some(p)) => Some(Target::Psnr(p)),
            (Some(b), _, _) => Some(Target::Bpp(b)),
            _ => None,
        };
        Job {
            target: chosen.unwrap_or(Target::Bpp(DEFAULT_BPP)),
            is_default: chosen.is_none(),
        }
    }
}

/// `pifs encode`.
pub fn run(args: &EncodeArgs) -> Result<()> {
    let job = args.job();
    validate_target(job.target)?;
    output::check(&args.output, Some(&args.input), Kind::Stream)?;
    let image = load_input(&args.input, args.gray)?;
    let analysed = analyse_loaded(&image, &args.analysis, &[job.target])?;
    match write_stream(&analysed, job, &args.output) {
        Err(CliError::Encode(EncodeError::QualityUnreachable { .. })) => {
            // A quality target's analysis is tuned (its trial encode, which trains the rate
            // estimates and places the finer roundings) for moderate rates, where most
            // targets lie. Tuned for the highest rate instead, as a budget of unlimited bytes
            // tunes it, it reaches the best PSNR of any analysis: that one decides, and the
            // best it reports is what `--bytes` with a large budget writes.
            println!(
                "{}: the target is beyond this analysis; analysing again, tuned for the highest rate",
                args.input.display()
            );
            let mut top = analyse_loaded(&image, &args.analysis, &[TOP_TUNING])?;
            top.seconds += analysed.seconds;
            write_stream(&top, job, &args.output)?;
            Ok(())
        }
        other => other.map(|_| ()),
    }
}

/// The target whose analysis reaches the highest quality: a budget of unlimited bytes.
pub const TOP_TUNING: Target = Target::Bytes(usize::MAX);
