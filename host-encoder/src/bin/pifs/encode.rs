//! `pifs encode`, and the image loading, analysis and stream writing that `rd` and the demo
//! share with it.
//!
//! An encode is checked before its work: the target's numbers, the output (opened, so that an
//! unwritable directory is reported at once), and the image's header against `--max-pixels`
//! and the memory the analysis would need ([`crate::memory`]). Only then are the pixels decoded
//! (with the `image` crate's allocation limit set) and analysed.

use crate::error::{CliError, Result};
use crate::memory;
use crate::output::{self, Kind};
use crate::progress::{Progress, Work};
use crate::say;
use clap::Args;
use host_encoder::io::{self, Content, ImageLimits, ImageProbe, Output};
use host_encoder::{
    analyse_colour_in_parts, analyse_in_parts, Analysis, EncodeError, Encoded, EncoderConfig,
    Target, Tune,
};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Largest image `pifs encode` and `pifs rd` accept unless told otherwise: 2^25 pixels (33.6
/// megapixels: a 24-megapixel phone photo, a 6K frame), whose grayscale analysis is estimated
/// at about 2.6 GB ([`crate::memory`]: a 6000x4000 photo 2.0 GB, measured at 0.82 GB); a
/// machine with less memory refuses smaller images by `--max-memory`.
pub const DEFAULT_MAX_PIXELS: u64 = 1 << 25;

/// The target when none is given: a rate, not a ceiling (see [`encode_stream`]).
pub const DEFAULT_BPP: f64 = 0.25;

/// Arguments of `pifs encode`.
#[derive(Args, Debug)]
pub struct EncodeArgs {
    /// Input images (PNG, JPEG, PGM/PPM, BMP, TIFF, WebP, GIF); "-" reads standard input.
    ///
    /// The EXIF orientation is applied, the first page of a TIFF (frame of a GIF or WebP)
    /// taken. A colour image gives a colour stream (YCbCr 4:2:0) unless --gray; a gray one (or
    /// a colour image whose pixels are all gray) a grayscale stream. Several images need
    /// --out-dir.
    #[arg(required = true, num_args = 1..)]
    pub input: Vec<PathBuf>,
    /// Encode in grayscale (the image's luma), even from a colour image.
    #[arg(long)]
    pub gray: bool,
    /// Output stream (.pifs by convention; "-" writes standard output).
    ///
    /// Any name but an image format's (.png, .jpg, ... are refused, so that a stream never poses as
    /// an image). An existing file is replaced atomically and keeps its permissions, a symbolic
    /// link is followed, a device or a FIFO is written through.
    #[arg(
        short,
        long,
        required_unless_present_any = ["out_dir", "packets"],
        conflicts_with = "out_dir"
    )]
    pub output: Option<PathBuf>,
    /// Batch: each input's stream to DIR/NAME.pifs, the images spread over the cores.
    ///
    /// NAME is the input's file name without the extension; DIR is made if missing. One summary
    /// line each; a failure is reported and the others go on (the exit status says whether any
    /// failed).
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    /// Target bits per pixel, whole file, never exceeded [default: 0.25, or the smallest
    /// stream when the image is too small for that rate].
    #[arg(long, group = "target")]
    pub bpp: Option<f64>,
    /// Largest file size in bytes, header included, never exceeded.
    #[arg(long, group = "target")]
    pub bytes: Option<usize>,
    /// Smallest file reaching this PSNR (dB).
    ///
    /// Of a 16-bit surface, the PSNR of its range. If no stream reaches it, the error says the best
    /// reachable.
    #[arg(long, group = "target")]
    pub psnr: Option<f64>,
    /// Smallest file whose every pixel is within this of the image (0: lossless).
    ///
    /// In grey levels, or in a 16-bit surface's own units (metres of a heightmap). Grayscale images
    /// and surfaces.
    #[arg(long, group = "target", value_name = "ERROR")]
    pub max_error: Option<f64>,
    #[command(flatten)]
    pub analysis: AnalysisArgs,
    #[command(flatten)]
    pub packets: crate::packets::PacketArgs,
    #[command(flatten)]
    pub limits: InputLimits,
}

/// How `encode` and `rd` take an image: bounds checked on its header before its pixels are
/// decoded, and the size it is scaled to.
#[derive(Args, Debug, Clone, Default)]
pub struct InputLimits {
    /// Scale the image to fit within WxH pixels first, such as 240x240 or 128x64.
    ///
    /// The size of the display it is for: the shape is kept (enlarging too), and --bpp then counts
    /// the scaled pixels.
    #[arg(long, value_name = "WxH", value_parser = io::Fit::parse)]
    pub resize: Option<io::Fit>,
    /// Refuse images of more pixels than this [default: 33554432, 2^25].
    #[arg(long, value_name = "PIXELS")]
    pub max_pixels: Option<u64>,
    /// Memory the encode may use, such as 800M or 4G [default: what the system has available].
    ///
    /// Linux: free memory, cgroup and ulimit. An 8-bit image whose analysis would need more is
    /// analysed in parts (one band of the image at a time, for twice the time); one that would need
    /// more even so is refused before it is decoded.
    #[arg(long, value_name = "SIZE", value_parser = memory::parse_size)]
    pub max_memory: Option<u64>,
}

impl InputLimits {
    fn max_pixels(&self) -> u64 {
        self.max_pixels.unwrap_or(DEFAULT_MAX_PIXELS)
    }

    /// The memory budget and where it comes from, for messages.
    fn memory(&self) -> Option<(u64, &'static str)> {
        match self.max_memory {
            Some(m) => Some((m, "--max-memory")),
            None => memory::available().map(|m| (m, "the memory available (see --max-memory)")),
        }
    }
}

/// An image file read and its header checked against the limits, its pixels not yet decoded.
#[derive(Debug)]
pub struct Checked {
    /// The path given.
    pub path: PathBuf,
    /// The file's bytes.
    pub bytes: Vec<u8>,
    /// What its header says.
    pub probe: ImageProbe,
    /// What the image decoder may allocate.
    max_alloc: u64,
    /// The box the image is scaled to fit, if any.
    fit: Option<io::Fit>,
    /// For an image too large to analyse whole in the memory allowed: the pixels of the parts
    /// it is analysed in instead ([`host_encoder::analyse_in_parts`]).
    pub in_parts: Option<u64>,
}

/// Reads the image at `path` (`-`: standard input) and checks its header against `limits` and
/// the memory an analysis with `analysis` needs, in colour when the header's colour type has
/// colour unless `gray`: a refusal is one line naming the option that would let it through.
pub fn check_image(
    path: &Path,
    limits: &InputLimits,
    analysis: &AnalysisArgs,
    gray: bool,
) -> Result<Checked> {
    let name = io::input_name(path);
    let budget = limits.memory();
    let max_input = budget.map_or(u64::MAX, |(b, _)| b);
    let bytes = io::read_input(path, "an image", max_input)?;
    let probe = ImageProbe::read(&bytes, &name)?;
    let (w, h) = (probe.width, probe.height);
    if !(1..=u32::from(u16::MAX)).contains(&w) || !(1..=u32::from(u16::MAX)).contains(&h) {
        return Err(EncodeError::BadDimensions {
            width: w,
            height: h,
        }
        .into());
    }
    // The encoder sees the image at its fitted size; the image decoder at its own.
    let (fw, fh) = limits.resize.map_or((w, h), |fit| fit.size_of(w, h));
    let pixels = probe.pixels();
    // Priced in colour on the header's word: a colour type whose pixels are all gray is
    // encoded in grayscale, for less.
    let channels = if probe.colour && !gray { 3 } else { 1 };
    let size = memory::ImageSize {
        width: u64::from(fw),
        height: u64::from(fh),
        decoded_bytes: probe.decoded_bytes,
    };
    // Priced with the default smallest leaf when none is given: at low rates the analysis
    // stops at larger leaves and needs less.
    let min_leaf_log2 = analysis
        .min_leaf_log2
        .unwrap_or(EncoderConfig::default().min_leaf_log2);
    let per_pixel = memory::per_pixel(size, channels, min_leaf_log2);
    let need = memory::encode_bytes(size, channels, min_leaf_log2);
    if pixels > limits.max_pixels() {
        return Err(CliError::Refused(format!(
            "{}: {w}x{h} is {:.1} megapixels, more than --max-pixels {} allows (encoding it needs about {}, {per_pixel} bytes per pixel)",
            name.display(),
            pixels as f64 / 1e6,
            limits.max_pixels(),
            memory::human(need),
        )));
    }
    let mut in_parts = None;
    if let Some((budget, source)) = budget {
        if need > budget {
            // Analysed part by part, an image needs memory for one part only.
            let stripe = u64::from(analysis.stripe_width.unwrap_or(0)) * 128;
            match memory::parts_within(size, channels, min_leaf_log2, stripe, budget) {
                Ok((part_pixels, parts_need)) => {
                    say!(
                        "{}: encoding {fw}x{fh} whole needs about {}, more than {} allowed by {source}: analysing it in parts (about {}, twice the time)",
                        name.display(),
                        memory::human(need),
                        memory::human(budget),
                        memory::human(parts_need),
                    );
                    in_parts = Some(part_pixels);
                }
                Err(parts_need) => {
                    return Err(CliError::Refused(format!(
                        "{}: encoding {fw}x{fh} needs about {} ({per_pixel} bytes per pixel), or {} analysed in parts, more than {} allowed by {source}",
                        name.display(),
                        memory::human(need),
                        memory::human(parts_need),
                        memory::human(budget),
                    )));
                }
            }
        }
    }
    Ok(Checked {
        path: name,
        bytes,
        probe,
        max_alloc: budget.map_or(u64::MAX, |(b, _)| b),
        fit: limits.resize,
        in_parts,
    })
}

impl Checked {
    /// Refuses an image too large to analyse whole in the memory allowed, for what (`done`)
    /// needs the whole image analysed.
    pub fn whole(&self, done: &str) -> Result<()> {
        match self.in_parts {
            Some(_) => Err(CliError::Refused(format!(
                "{}: {done} from an analysis of the whole image, which needs more memory than allowed (see --max-memory)",
                self.path.display()
            ))),
            None => Ok(()),
        }
    }

    /// Decodes the pixels as the encoder takes them (colour unless `gray` or the image is
    /// gray; a 16-bit grayscale image as a surface unless `depth` says 8), orientation
    /// applied; a note for a TIFF of several pages or an animated GIF or WebP (the first is
    /// taken).
    pub fn decode(self, gray: bool, depth: io::Depth) -> Result<io::Loaded> {
        let decoded = self.decode_image(depth)?;
        Ok(decoded.into_loaded(gray, depth))
    }

    fn decode_image(self, depth: io::Depth) -> Result<io::DecodedImage> {
        let limits = ImageLimits {
            max_pixels: u64::MAX,
            max_alloc: self.max_alloc,
        };
        let decoded = io::DecodedImage::decode_fitted(&self.bytes, &self.path, &limits, self.fit)
            .map_err(|e| match e {
            io::FileError::Decode {
                source: image::ImageError::Limits(_),
                ..
            } => CliError::Refused(format!("{e} (see --max-memory)")),
            other => other.into(),
        })?;
        let (width, height) = (decoded.plane.width, decoded.plane.height);
        if (width, height) != (self.probe.width, self.probe.height) {
            say!(
                "{}: {}x{} resized to {width}x{height}",
                self.path.display(),
                self.probe.width,
                self.probe.height
            );
        }
        if decoded.pages > 1 {
            let what = match decoded.format {
                image::ImageFormat::Gif | image::ImageFormat::WebP => "frames",
                _ => "pages",
            };
            say!(
                "{}: note: {} {what}; encoding the first",
                self.path.display(),
                decoded.pages
            );
        }
        let range = decoded.surface.as_ref().map(|s| (s.min, s.max));
        if let (Some((low, high)), io::Depth::Eight) = (range, depth) {
            // Fewer than 64 of the 256 grey levels: a heightmap, most likely, flattened.
            let levels = u32::from(high - low) * 255 / 65535 + 1;
            if levels < 64 {
                say!(
                    "{}: note: 16-bit samples from {} to {} become {levels} grey levels of 8 \
                     bits with --depth 8 (the default codes them as a 16-bit surface)",
                    self.path.display(),
                    low,
                    high
                );
            }
        }
        Ok(decoded)
    }
}

/// The analysis settings of `encode` and `rd`.
#[derive(Args, Debug, Clone)]
pub struct AnalysisArgs {
    /// Smallest leaf side as a power of two [default: 2, or 3 at rates of at most 0.1 bpp].
    ///
    /// Leaves of 2 px make encoding much longer for little gain: 4 px leaves already code each
    /// pixel with a pixel grid. At 0.1 bpp and below, 4 px leaves are nearly never worth their
    /// bits, and leaving them out takes a little over half the time.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=7))]
    pub min_leaf_log2: Option<u8>,
    /// Largest leaf side as a power of two.
    #[arg(long, default_value_t = EncoderConfig::default().max_leaf_log2, value_parser = clap::value_parser!(u8).range(1..=7))]
    pub max_leaf_log2: u8,
    /// Width of the stripes the image is coded in: pixels (a multiple of 128), or `full` [default:
    /// full; packets: 512].
    ///
    /// Prediction and edge smoothing stop at a stripe's left edge, which shows at low rates. A
    /// decoder holds one byte per column of a stripe (two in colour) and decoder-core's default one
    /// holds 512: give 512 for it when the image is wider.
    #[arg(long, value_parser = parse_stripe)]
    pub stripe_width: Option<u8>,
    /// Strength of the smoothing of leaf edges: `auto`, or 0 (none) to 16.
    ///
    /// `auto` is the strongest that does not add to the error.
    #[arg(long, default_value = "auto", value_parser = parse_deblock)]
    pub deblock: Deblock,
    /// What the encoder minimises with the bytes: `ssim` or `psnr`.
    ///
    /// `ssim`: the error weighted by local contrast as the eye sees it (an error on a smooth
    /// surface counts more than in texture). `psnr`: the plain squared error (a few hundredths of a
    /// dB more PSNR, less SSIM).
    #[arg(long, default_value = "ssim", value_parser = parse_tune)]
    pub tune: Tune,
    /// Bit depth of the stream: `auto` or `8`.
    ///
    /// `auto`: 16 for a 16-bit grayscale image such as a heightmap (its range goes in the header
    /// and it decodes to values in its own units), 8 for any other image. `8`: a 16-bit image
    /// mapped to 8 bits from its type's full range.
    #[arg(long, default_value = "auto", value_parser = parse_depth)]
    pub depth: io::Depth,
    /// The bound on each pixel's error the analysis works to (`--max-error`'s), if any.
    #[arg(skip)]
    pub error_bound: Option<f64>,
}

/// `--depth`: `auto` or `8`.
fn parse_depth(s: &str) -> std::result::Result<io::Depth, String> {
    match s {
        "auto" => Ok(io::Depth::Auto),
        "8" => Ok(io::Depth::Eight),
        _ => Err(format!("'{s}' is not 'auto' or '8'")),
    }
}

/// `--tune`: `ssim` or `psnr`.
fn parse_tune(s: &str) -> std::result::Result<Tune, String> {
    match s {
        "ssim" => Ok(Tune::Ssim),
        "psnr" => Ok(Tune::Psnr),
        _ => Err(format!("'{s}' is not 'ssim' or 'psnr'")),
    }
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
            min_leaf_log2: None,
            max_leaf_log2: d.max_leaf_log2,
            stripe_width: None,
            deblock: Deblock(d.deblock),
            tune: d.tune,
            depth: io::Depth::Auto,
            error_bound: None,
        }
    }
}

impl AnalysisArgs {
    /// These settings for packets: stripes of 512 pixels unless chosen (packets are for
    /// decoders with decoder-core's default frontier).
    pub fn for_packets(&self) -> AnalysisArgs {
        AnalysisArgs {
            stripe_width: Some(
                self.stripe_width
                    .unwrap_or(host_encoder::DEFAULT_STRIPE_TILES),
            ),
            ..self.clone()
        }
    }

    /// The analysis's settings for `targets` on an image of `pixels` pixels.
    pub fn config(&self, pixels: usize, targets: &[Target]) -> EncoderConfig {
        let chosen = EncoderConfig::for_targets(targets, pixels);
        let min_leaf_log2 = self.min_leaf_log2.unwrap_or(chosen.min_leaf_log2);
        EncoderConfig {
            min_leaf_log2,
            max_leaf_log2: self.max_leaf_log2.max(min_leaf_log2),
            stripe: self.stripe_width.unwrap_or(chosen.stripe),
            deblock: self.deblock.0,
            tune: self.tune,
            error_bound: self.error_bound,
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
    /// The 16-bit surface it codes, if it is one (its streams' errors are in its units).
    pub surface: Option<io::Surface>,
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

/// Analyses a loaded image once for `targets` ([`io::Loaded::analyse`]: grayscale, colour or a
/// 16-bit surface), with a progress display on a terminal.
pub fn analyse_loaded(
    image: &io::Loaded,
    args: &AnalysisArgs,
    targets: &[Target],
) -> Result<Analysed> {
    let (width, height) = image.size();
    analyse_with(
        image,
        &args.config(width as usize * height as usize, targets),
    )
}

/// Analyses a loaded image with `config` ([`io::Loaded::config`] of it), with a progress
/// display on a terminal.
pub fn analyse_with(image: &io::Loaded, config: &EncoderConfig) -> Result<Analysed> {
    let (width, height) = image.size();
    let config = image.config(config);
    let surface = match image {
        io::Loaded::Surface(surface) => Some(surface.clone()),
        _ => None,
    };
    Ok(Analysed {
        surface,
        ..with_progress((width, height), &config, |report| {
            image.clone().analyse(&config, report)
        })?
    })
}

/// Runs `analysis` of an image of `width` x `height` under `config`, showing its progress on
/// a terminal, and times it.
fn with_progress(
    (width, height): (u32, u32),
    config: &EncoderConfig,
    analysis: impl FnOnce(&(dyn Fn(u64) + Sync)) -> std::result::Result<Analysis, EncodeError>,
) -> Result<Analysed> {
    let start = Instant::now();
    let work = Work::new(&host_encoder::analysis_steps(width, height, config));
    let progress = Progress::on_terminal(work);
    let result = analysis(&|n| {
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
        surface: None,
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

/// Encodes `job` from `analysed`, writes the stream to `output` (by the rules of
/// [`io::output`]) and prints its figures.
pub fn write_stream(analysed: &Analysed, job: Job, output: &Path) -> Result<Encoded> {
    let out = Output::create(output, Content::Binary("a PIFS stream"))?;
    write_stream_to(analysed, job, out)
}

/// Like [`write_stream`], into an output already open.
pub fn write_stream_to(analysed: &Analysed, job: Job, out: Output) -> Result<Encoded> {
    let t = Instant::now();
    let (encoded, note) =
        encode_stream(&analysed.analysis, job).map_err(|e| explain(e, job, analysed.size()))?;
    write_encoded(analysed, encoded, note, out, t)
}

/// Writes `encoded` (encoded from `analysed` since `t`) into `out` and prints its figures.
fn write_encoded(
    analysed: &Analysed,
    encoded: Encoded,
    note: Option<String>,
    out: Output,
    t: Instant,
) -> Result<Encoded> {
    let made = Made {
        size: analysed.size(),
        seconds: analysed.seconds,
        surface: analysed.surface.as_ref(),
    };
    write_made(&made, encoded, note, out, t)
}

/// What a stream was made from, for its summary.
struct Made<'a> {
    /// Width and height, pixels.
    size: (u32, u32),
    /// The analysis's wall time, seconds.
    seconds: f64,
    /// The 16-bit surface it codes, if it is one.
    surface: Option<&'a io::Surface>,
}

/// Writes `encoded` (made from `made`, encoded since `t`) into `out` and prints its figures.
fn write_made(
    made: &Made,
    encoded: Encoded,
    note: Option<String>,
    mut out: Output,
    t: Instant,
) -> Result<Encoded> {
    out.write_all(&encoded.bytes).map_err(|e| out.error(e))?;
    let name = out.name().to_path_buf();
    out.commit()?;
    let (w, h) = made.size;
    let actual = encoded.actual_payload_bits;
    let gap = 100.0 * (encoded.estimated_payload_bits - actual) / actual.max(1.0);
    let note = note.map(|n| format!(" ({n})")).unwrap_or_default();
    let kind = if let Some(surface) = made.surface {
        let error = surface_error(surface, &encoded.bytes)?;
        format!(
            "16-bit surface {}..{}, RMSE {:.2}, max error {}, PSNR {:.2} dB of the range",
            surface.min, surface.max, error.rmse, error.max, error.psnr
        )
    } else if encoded.channels == 3 {
        format!(
            "colour, PSNR-RGB {:.2} dB, chroma {:.1}% of the payload",
            encoded.psnr,
            100.0 * encoded.chroma_bits / encoded.actual_payload_bits.max(1.0)
        )
    } else {
        format!("gray, PSNR {:.2} dB", encoded.psnr)
    };
    say!(
        "{}: {w}x{h} -> {} bytes, {:.4} bpp, {kind}, {} leaves, rate estimate {gap:+.2}% off, analysis {:.2} s + encode {:.2} s{note}",
        name.display(),
        encoded.bytes.len(),
        encoded.bytes.len() as f64 * 8.0 / (f64::from(w) * f64::from(h)),
        encoded.leaves,
        made.seconds,
        t.elapsed().as_secs_f64()
    );
    if let Some(note) = stripe_note(&encoded.bytes) {
        say!("{}: {note}", name.display());
    }
    Ok(encoded)
}

/// A note, once a run, when `stream`'s stripes are wider than decoder-core's default decoder
/// holds (a microcontroller would refuse it with `StripeTooWide`), naming the option that fits.
fn stripe_note(stream: &[u8]) -> Option<String> {
    static NOTED: AtomicBool = AtomicBool::new(false);
    let stripe = decoder_core::Header::read(stream).ok()?.stripe_width();
    let capacity = decoder_core::internal::format::DEFAULT_STRIPE as u32;
    (stripe > capacity && !NOTED.swap(true, Ordering::Relaxed)).then(|| {
        format!(
            "note: stripes of {stripe} px, wider than the {capacity} columns of decoder-core's \
             default decoder (for a microcontroller, encode with --stripe-width {capacity})"
        )
    })
}

/// The error of the 16-bit `stream` against the `surface` it codes, in the surface's units.
fn surface_error(surface: &io::Surface, stream: &[u8]) -> Result<io::SurfaceError> {
    let mut values = vec![0u16; surface.values.len()];
    decoder_core::Decoder::new(stream)
        .and_then(|d| {
            d.stripe_capacity::<{ io::HOST_STRIPE }>()
                .decode_values_into(&mut values)
        })
        .map_err(|_| CliError::Encode(EncodeError::Internal("a 16-bit stream did not decode")))?;
    Ok(surface.error(&values))
}

/// A number as a person reads it: plain, or in exponent notation when very large or very
/// small (`1e300`, not three hundred digits).
pub fn number(x: f64) -> String {
    if x.is_finite() && x != 0.0 && !(1e-4..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// The option and value that ask for `target`, as the user wrote them.
fn option(target: Target) -> String {
    match target {
        Target::Bpp(b) => format!("--bpp {}", number(b)),
        Target::Bytes(n) => format!("--bytes {n}"),
        Target::Psnr(p) => format!("--psnr {}", number(p)),
    }
}

/// "1 byte", "2 bytes".
fn bytes_text(n: usize) -> String {
    if n == 1 {
        "1 byte".into()
    } else {
        format!("{n} bytes")
    }
}

/// The smallest bits per pixel, to 3 significant digits rounded up, that allows `bytes` bytes
/// on `pixels` pixels.
fn bpp_for(bytes: usize, pixels: u64) -> String {
    let exact = bytes as f64 * 8.0 / pixels.max(1) as f64;
    let digits = 3 - 1 - exact.log10().floor() as i32;
    let scale = 10f64.powi(digits);
    number((exact * scale).ceil() / scale)
}

/// An encoder refusal of `job` on a `size` image, told in terms of the option the user gave
/// and what to ask for instead.
fn explain(e: CliError, job: Job, size: (u32, u32)) -> CliError {
    let (w, h) = size;
    let pixels = u64::from(w) * u64::from(h);
    match e {
        CliError::Encode(EncodeError::BudgetTooSmall { budget, smallest }) => {
            let instead = match job.target {
                Target::Bpp(_) => format!(
                    "use --bpp {} or more, or --bytes {smallest}",
                    bpp_for(smallest, pixels)
                ),
                _ => format!("use --bytes {smallest} or more"),
            };
            CliError::Refused(format!(
                "{} allows {} for this {w}x{h} image, and the smallest stream for this image is {smallest} bytes: {instead}",
                option(job.target),
                bytes_text(budget),
            ))
        }
        CliError::Encode(EncodeError::QualityUnreachable { requested, best }) => {
            // Rounded down: a target of the figure shown is reachable.
            let best = (best * 100.0).floor() / 100.0;
            CliError::Refused(format!(
                "{} dB is unreachable for this {w}x{h} image (ask for less): the best this encoder reaches is {best:.2} dB",
                option(Target::Psnr(requested)),
            ))
        }
        other => other,
    }
}

/// The fewest bytes any stream takes: its shortest header.
fn smallest_possible_stream() -> usize {
    decoder_core::internal::syntax::MIN_HEADER_LEN
}

/// Refuses a target that is not a positive number, naming the option.
pub fn validate_target(target: Target) -> Result<()> {
    let why = match target {
        Target::Bpp(b) if !(b.is_finite() && b > 0.0) => {
            format!("--bpp must be a positive number, got {}", number(b))
        }
        Target::Bytes(0) => "--bytes must be at least 1".into(),
        Target::Psnr(p) if !(p.is_finite() && p > 0.0) => {
            format!("--psnr must be a positive number, got {}", number(p))
        }
        _ => return Ok(()),
    };
    Err(CliError::Refused(why))
}

/// Refuses, before any analysis, a size target no stream can meet on a `w x h` image.
fn check_target_fits(job: Job, w: u32, h: u32) -> Result<()> {
    if job.is_default {
        return Ok(());
    }
    let pixels = u64::from(w) * u64::from(h);
    let Some(bpp) = job.target.bpp(pixels as usize) else {
        return Ok(());
    };
    let budget = (bpp * pixels as f64 / 8.0).floor();
    let least = smallest_possible_stream();
    if budget >= least as f64 {
        return Ok(());
    }
    let instead = match job.target {
        Target::Bpp(_) => format!("--bpp {} or more", bpp_for(least, pixels)),
        _ => format!("--bytes {least} or more"),
    };
    Err(CliError::Refused(format!(
        "{} allows {} for this {w}x{h} image, and no stream is smaller than {least} bytes (its header): use {instead}",
        option(job.target),
        bytes_text(budget as usize),
    )))
}

impl EncodeArgs {
    /// The job the options ask for.
    fn job(&self) -> Job {
        let chosen = match (self.bpp, self.bytes, self.psnr) {
            (_, Some(n), _) => Some(Target::Bytes(n)),
            (_, _, Some(p)) => Some(Target::Psnr(p)),
            (Some(b), _, _) => Some(Target::Bpp(b)),
            // Its streams are searched among those of the analysis for the highest quality.
            _ if self.max_error.is_some() => Some(TOP_TUNING),
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
    if let Some(e) = args.max_error {
        if !(e.is_finite() && e >= 0.0) {
            return Err(CliError::Refused(format!(
                "--max-error must be a number from 0 (lossless) up, got {}",
                number(e)
            )));
        }
        if args.packets.wanted() {
            return Err(CliError::Refused(
                "--max-error writes a stream, not packets: use --bytes or --bpp".into(),
            ));
        }
    }
    if args.packets.wanted() {
        return encode_packets(args, job);
    }
    if let Some(option) = args.packets.packet_only_option() {
        return Err(CliError::Refused(format!(
            "{option} is for packets: add --packets DIR (or --packet-size N with -o)"
        )));
    }
    match (&args.output, &args.out_dir, args.input.as_slice()) {
        (Some(output), None, [input]) => {
            output::check(output, Some(input), Kind::Stream)?;
            if io::is_std_stream(output) {
                say::stdout_is_data();
            }
            encode_one(args, &args.limits, job, input, output)
        }
        (None, Some(dir), inputs) => crate::batch::run(args, job, inputs, dir),
        _ => Err(CliError::Refused(
            "several input images need --out-dir DIR instead of -o".into(),
        )),
    }
}

/// `pifs encode` into packets: one input, into `--packets DIR` or the framed file `-o`.
fn encode_packets(args: &EncodeArgs, job: Job) -> Result<()> {
    let [input] = args.input.as_slice() else {
        return Err(CliError::Refused(
            "packets are made from one input image".into(),
        ));
    };
    if args.out_dir.is_some() || (args.packets.packets.is_some() && args.output.is_some()) {
        return Err(CliError::Refused(
            "packets go to --packets DIR or to -o FILE (framed), not both".into(),
        ));
    }
    if let Some(output) = &args.output {
        output::check(output, Some(input), Kind::Stream)?;
        if io::is_std_stream(output) {
            say::stdout_is_data();
        }
    }
    let checked = check_image(input, &args.limits, &args.analysis, args.gray)?;
    checked.whole("packets are made")?;
    let image = checked.decode(args.gray, args.analysis.depth)?;
    if let io::Loaded::Surface(_) = image {
        return Err(CliError::Refused(format!(
            "{}: packets carry 8-bit pictures; add --depth 8 to send this 16-bit image as one",
            input.display()
        )));
    }
    let analysis = args.analysis.for_packets();
    let (width, height) = image.size();
    let config = analysis.config(width as usize * height as usize, &[job.target]);
    let overview = analyse_with(&image, &host_encoder::packets::overview_config(&config))?;
    crate::packets::encode(
        &overview,
        &config,
        &args.packets,
        job.target,
        args.output.as_deref(),
    )
}

/// Encodes `input` for `job` into `output` (both checked), within `limits`.
pub fn encode_one(
    args: &EncodeArgs,
    limits: &InputLimits,
    job: Job,
    input: &Path,
    output: &Path,
) -> Result<()> {
    let checked = check_image(input, limits, &args.analysis, args.gray)?;
    check_target_fits(job, checked.probe.width, checked.probe.height)?;
    let out = Output::create(output, Content::Binary("a PIFS stream"))?;
    let input = checked.path.clone();
    let in_parts = checked.in_parts;
    let image = checked.decode(args.gray, args.analysis.depth)?;
    if let Some(part_pixels) = in_parts {
        return encode_in_parts(args, job, (image, part_pixels), out);
    }
    if args.max_error.is_some() && matches!(image, io::Loaded::Rgb { .. }) {
        return Err(CliError::Refused(
            "--max-error needs a grayscale image or a 16-bit surface (add --gray)".into(),
        ));
    }
    if let Some(max) = args.max_error {
        let bounded = AnalysisArgs {
            error_bound: Some(max),
            ..args.analysis.clone()
        };
        let analysed = analyse_loaded(&image, &bounded, &[job.target])?;
        let t = Instant::now();
        let (encoded, note) = smallest_within(&analysed, max)?;
        return write_encoded(&analysed, encoded, Some(note), out, t).map(|_| ());
    }
    let analysed = analyse_loaded(&image, &args.analysis, &[job.target])?;
    let t = Instant::now();
    match encode_stream(&analysed.analysis, job) {
        Err(CliError::Encode(EncodeError::QualityUnreachable { .. })) => {
            // A quality target's analysis is tuned (its trial encode, which trains the rate
            // estimates and places the finer roundings) for moderate rates, where most
            // targets lie. Tuned for the highest rate instead, as a budget of unlimited bytes
            // tunes it, it reaches the best PSNR of any analysis: that one decides, and the
            // best it reports is what `--bytes` with a large budget writes.
            say!(
                "{}: the target is beyond this analysis; analysing again, tuned for the highest rate",
                input.display()
            );
            let first_seconds = analysed.seconds;
            // One analysis in memory at a time.
            drop(analysed);
            let mut top = analyse_loaded(&image, &args.analysis, &[TOP_TUNING])?;
            top.seconds += first_seconds;
            write_stream_to(&top, job, out)?;
            Ok(())
        }
        Err(e) => Err(explain(e, job, analysed.size())),
        Ok((encoded, note)) => write_encoded(&analysed, encoded, note, out, t).map(|_| ()),
    }
}

/// Encodes `image`, too large to analyse whole in the memory allowed, part by part
/// ([`host_encoder::analyse_in_parts`], parts of about `part_pixels` pixels) for `job` into
/// `out`.
fn encode_in_parts(
    args: &EncodeArgs,
    job: Job,
    (image, part_pixels): (io::Loaded, u64),
    out: Output,
) -> Result<()> {
    if args.max_error.is_some() {
        return Err(CliError::Refused(
            "--max-error needs the whole image analysed, which needs more memory than allowed (see --max-memory)".into(),
        ));
    }
    let (width, height) = match &image {
        io::Loaded::Gray(plane) => (plane.width, plane.height),
        io::Loaded::Rgb { width, height, .. } => (*width, *height),
        io::Loaded::Surface(_) => {
            return Err(CliError::Refused(
                "a 16-bit surface is analysed whole, which needs more memory than allowed: add --depth 8, or allow more with --max-memory".into(),
            ))
        }
    };
    let config = args
        .analysis
        .config(width as usize * height as usize, &[job.target]);
    let parts = host_encoder::AnalysisInParts::count(width, height, &config, part_pixels);
    // Each part is analysed twice: for its curve, then for the stream (a few more choose the
    // edge smoothing).
    let progress = Progress::on_terminal(Work::even(2 * parts as u64));
    let report = |n: u64| {
        if let Some(p) = &progress {
            p.nodes_done(n);
        }
    };
    let start = Instant::now();
    let analysis = match image {
        io::Loaded::Gray(plane) => analyse_in_parts(plane, &config, part_pixels, &report),
        io::Loaded::Rgb {
            width,
            height,
            data,
        } => analyse_colour_in_parts(width, height, data, &config, part_pixels, &report),
        io::Loaded::Surface(_) => unreachable!("refused above"),
    }?;
    let seconds = start.elapsed().as_secs_f64();
    let t = Instant::now();
    let written = |n: u64| report(parts as u64 + n);
    let encoded = analysis
        .encode_reporting(job.target, &written)
        .map_err(|e| explain(e.into(), job, (width, height)));
    if let Some(p) = &progress {
        p.finish();
    }
    let made = Made {
        size: (width, height),
        seconds,
        surface: None,
    };
    let note = format!("analysed in {parts} parts");
    write_made(&made, encoded?, Some(note), out, t).map(|_| ())
}

/// The largest error of `encoded` against the image `analysed` holds: in its units for a
/// surface, in grey levels otherwise (`None` for colour).
fn largest_error(analysed: &Analysed, encoded: &Encoded) -> Result<Option<f64>> {
    if let Some(surface) = &analysed.surface {
        return Ok(Some(f64::from(surface_error(surface, &encoded.bytes)?.max)));
    }
    if encoded.channels != 1 {
        return Ok(None);
    }
    let plane = &analysed.analysis.plane().data;
    let max = encoded
        .reconstruction
        .iter()
        .zip(plane)
        .map(|(&a, &b)| a.abs_diff(b))
        .max()
        .unwrap_or(0);
    Ok(Some(f64::from(max)))
}

/// `--max-error`: the smallest stream found whose largest error is at most `max`, by bisection
/// on the byte budget between the smallest stream and the best (the error is not strictly
/// monotonic in the bytes: a smaller stream that meets it may be missed), and what it reached.
fn smallest_within(analysed: &Analysed, max: f64) -> Result<(Encoded, String)> {
    let analysis = &analysed.analysis;
    let error = |e: &Encoded| -> Result<f64> {
        largest_error(analysed, e)?.ok_or(CliError::Encode(EncodeError::Internal(
            "a colour stream's largest error",
        )))
    };
    let top = analysis.encode(TOP_TUNING)?;
    let least = error(&top)?;
    if least > max {
        return Err(CliError::Refused(format!(
            "--max-error {} is unreachable for this image: the least this encoder reaches is {}",
            number(max),
            number(least)
        )));
    }
    let (mut lo, mut hi, mut best, mut reached) = (0, top.bytes.len(), top, least);
    while hi.saturating_sub(lo) > (hi / 200).max(1) {
        let mid = lo + (hi - lo) / 2;
        let encoded = match analysis.encode(Target::Bytes(mid)) {
            Err(EncodeError::BudgetTooSmall { .. }) => {
                lo = mid;
                continue;
            }
            other => other?,
        };
        let e = error(&encoded)?;
        if e <= max {
            // A stream may come out smaller than its budget, below budgets that failed.
            hi = encoded.bytes.len().clamp(lo, mid);
            (best, reached) = (encoded, e);
        } else {
            lo = mid;
        }
    }
    Ok((best, format!("largest error {}", number(reached))))
}

/// The target whose analysis reaches the highest quality: a budget of unlimited bytes.
pub const TOP_TUNING: Target = Target::Bytes(usize::MAX);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_read_naturally() {
        assert_eq!(number(0.25), "0.25");
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(1e-300), "1e-300");
        assert_eq!(number(0.0), "0");
        assert_eq!(number(f64::NAN), "NaN");
        assert_eq!(bpp_for(18, 9), "16");
        assert_eq!(bpp_for(18, 64 * 48), "0.0469");
        assert_eq!(bytes_text(1), "1 byte");
    }

    #[test]
    fn refusals_name_the_option_and_what_to_ask_for() {
        let job = |target| Job {
            target,
            is_default: false,
        };
        let err = check_target_fits(job(Target::Bpp(1.0)), 3, 3).unwrap_err();
        assert_eq!(
            err.to_string(),
            "--bpp 1 allows 1 byte for this 3x3 image, and no stream is smaller than 9 bytes (its header): use --bpp 8 or more"
        );
        assert!(check_target_fits(job(Target::Bpp(1.0)), 64, 48).is_ok());
        assert!(check_target_fits(job(Target::Psnr(30.0)), 1, 1).is_ok());
        let default = Job {
            target: Target::Bpp(DEFAULT_BPP),
            is_default: true,
        };
        assert!(check_target_fits(default, 1, 1).is_ok());
        let err = explain(
            CliError::Encode(EncodeError::BudgetTooSmall {
                budget: 30,
                smallest: 45,
            }),
            job(Target::Bpp(0.078)),
            (64, 48),
        );
        assert_eq!(
            err.to_string(),
            "--bpp 0.078 allows 30 bytes for this 64x48 image, and the smallest stream for this image is 45 bytes: use --bpp 0.118 or more, or --bytes 45"
        );
        let err = explain(
            CliError::Encode(EncodeError::QualityUnreachable {
                requested: 1e300,
                best: 41.234,
            }),
            job(Target::Psnr(1e300)),
            (64, 48),
        );
        assert_eq!(
            err.to_string(),
            "--psnr 1e300 dB is unreachable for this 64x48 image (ask for less): the best this encoder reaches is 41.23 dB"
        );
    }
}
