//! `pifs`: encode, decode and inspect PIFS images.

use clap::{Args, Parser, Subcommand};
use host_encoder::{analyse, io, EncoderConfig, Target};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Largest image `pifs decode` accepts unless told otherwise: 2^28 pixels (256 MiB of output).
const DEFAULT_MAX_PIXELS: u64 = 1 << 28;

/// Fractal (projected-IFS quadtree) image codec for low-bandwidth links and small displays.
#[derive(Parser, Debug)]
#[command(name = "pifs", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Encode an image (PNG, JPEG, PGM/PPM, BMP, TIFF) into a .pifs stream.
    Encode(EncodeArgs),
    /// Decode a .pifs stream into a PNG or PGM image.
    Decode {
        /// Input .pifs file.
        input: PathBuf,
        /// Output image (.png or .pgm).
        #[arg(short, long)]
        output: PathBuf,
        /// Refuse streams of more pixels than this (checked on the header, before anything is
        /// allocated).
        #[arg(long, default_value_t = DEFAULT_MAX_PIXELS)]
        max_pixels: u64,
    },
    /// Describe a .pifs stream: dimensions, size, quadtree and model usage.
    Info {
        /// Input .pifs file.
        input: PathBuf,
    },
}

#[derive(Args, Debug)]
struct EncodeArgs {
    /// Input image.
    input: PathBuf,
    /// Output .pifs file.
    #[arg(short, long)]
    output: PathBuf,
    /// Target bits per pixel (whole file); the default target is 0.25.
    #[arg(long, group = "target")]
    bpp: Option<f64>,
    /// Largest file size in bytes (header included).
    #[arg(long, group = "target")]
    bytes: Option<usize>,
    /// Smallest file reaching this PSNR (dB).
    #[arg(long, group = "target")]
    psnr: Option<f64>,
    /// Smallest leaf side as a power of two (4 px leaves already code every pixel of their own
    /// with a pixel grid; 2 px leaves make encoding much longer for no gain).
    #[arg(long, default_value_t = EncoderConfig::default().min_leaf_log2, value_parser = clap::value_parser!(u8).range(1..=7))]
    min_leaf_log2: u8,
    /// Largest leaf side as a power of two.
    #[arg(long, default_value_t = EncoderConfig::default().max_leaf_log2, value_parser = clap::value_parser!(u8).range(1..=7))]
    max_leaf_log2: u8,
    /// Also fit the subdivision weights (the thesis's full inverse problem): a much longer
    /// analysis for very little gain.
    #[arg(long)]
    fit_weights: bool,
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                e.exit();
            }
            // One line, like every other error of this tool; `--help` has the details.
            let text = e.to_string();
            let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
            let mut first = lines
                .next()
                .unwrap_or("invalid arguments")
                .trim_start_matches("error: ")
                .to_string();
            // "the following required arguments were not provided:" names them on the next line.
            if first.ends_with(':') {
                if let Some(next) = lines.next() {
                    first = format!("{first} {next}");
                }
            }
            eprintln!("pifs: {first} (see pifs --help)");
            return ExitCode::from(2);
        }
    };
    let result = match cli.command {
        Some(Command::Encode(args)) => encode(&args),
        Some(Command::Decode {
            input,
            output,
            max_pixels,
        }) => decode(&input, &output, decoder_core::Limits::pixels(max_pixels)),
        Some(Command::Info { input }) => info(&input),
        None => demo(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pifs: {e}");
            ExitCode::FAILURE
        }
    }
}

fn target_of(args: &EncodeArgs) -> Target {
    match (args.bpp, args.bytes, args.psnr) {
        (_, Some(n), _) => Target::Bytes(n),
        (_, _, Some(p)) => Target::Psnr(p),
        (Some(b), _, _) => Target::Bpp(b),
        _ => Target::Bpp(0.25),
    }
}

fn progress_bar(total: u64) -> Option<indicatif::ProgressBar> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template("analysing {bar:40} {pos}/{len} nodes ({eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    Some(bar)
}

fn encode(args: &EncodeArgs) -> Result<(), String> {
    let target = target_of(args);
    validate_target(target)?;
    check_output(&args.output, Some(&args.input))?;
    let settings = Settings {
        min_leaf_log2: args.min_leaf_log2,
        max_leaf_log2: args.max_leaf_log2,
        fit_weights: args.fit_weights,
    };
    encode_targets(&args.input, &settings, &[(target, args.output.clone())])
}

/// The analysis settings given on the command line (the smallest leaf may be left to the
/// targets).
struct Settings {
    min_leaf_log2: u8,
    max_leaf_log2: u8,
    fit_weights: bool,
}

impl Settings {
    fn config(&self, pixels: usize, jobs: &[(Target, PathBuf)]) -> EncoderConfig {
        let targets: Vec<Target> = jobs.iter().map(|(t, _)| *t).collect();
        let chosen = EncoderConfig::for_targets(&targets, pixels);
        EncoderConfig {
            min_leaf_log2: self.min_leaf_log2,
            max_leaf_log2: self.max_leaf_log2.max(self.min_leaf_log2),
            fit_weights: self.fit_weights,
            ..chosen
        }
    }
}

/// Analyses `input` once and writes one stream per `(target, output)`.
fn encode_targets(
    input: &Path,
    settings: &Settings,
    jobs: &[(Target, PathBuf)],
) -> Result<(), String> {
    let start = Instant::now();
    let plane = io::load_luma(input)?;
    let (w, h) = (plane.width, plane.height);
    let config = &settings.config(plane.data.len(), jobs);
    let bar = progress_bar(node_count(w, h, config));
    let analysis = analyse(plane, config, &|n| {
        if let Some(b) = &bar {
            b.set_position(n);
        }
    })
    .map_err(|e| e.to_string())?;
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let analysis_s = start.elapsed().as_secs_f64();
    for (target, output) in jobs {
        let t = Instant::now();
        let encoded = analysis.encode(*target).map_err(|e| e.to_string())?;
        io::write_atomic(output, &encoded.bytes)?;
        let bpp = encoded.bytes.len() as f64 * 8.0 / (f64::from(w) * f64::from(h));
        let gap = 100.0 * (encoded.estimated_payload_bits - encoded.actual_payload_bits)
            / encoded.actual_payload_bits.max(1.0);
        println!(
            "{}: {w}x{h} -> {} bytes, {bpp:.4} bpp, PSNR {:.2} dB, {} leaves, rate estimate {gap:+.2}% off, analysis {analysis_s:.2} s + encode {:.2} s",
            output.display(),
            encoded.bytes.len(),
            encoded.psnr,
            encoded.leaves,
            t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Refuses, before any work, an output path that cannot be written or that would replace the
/// input.
fn check_output(output: &Path, input: Option<&Path>) -> Result<(), String> {
    if output.is_dir() {
        return Err(format!("output {} is a directory", output.display()));
    }
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        let why = if dir.exists() {
            "is not a directory"
        } else {
            "does not exist"
        };
        return Err(format!(
            "cannot write {}: {} {why}",
            output.display(),
            dir.display()
        ));
    }
    if let Some(input) = input {
        let same = match (input.canonicalize(), output.canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        };
        if same {
            return Err(format!(
                "output {} is the input file: refusing to overwrite it",
                output.display()
            ));
        }
    }
    Ok(())
}

fn validate_target(target: Target) -> Result<(), String> {
    match target {
        Target::Bpp(b) if !(b.is_finite() && b > 0.0) => {
            Err(format!("--bpp must be a positive number, got {b}"))
        }
        Target::Bytes(0) => Err("--bytes must be at least 1".into()),
        Target::Psnr(p) if !(p.is_finite() && p > 0.0) => {
            Err(format!("--psnr must be a positive number, got {p}"))
        }
        _ => Ok(()),
    }
}

/// Number of nodes the analysis visits (for the progress bar).
fn node_count(w: u32, h: u32, config: &EncoderConfig) -> u64 {
    (config.min_leaf_log2..=config.max_leaf_log2)
        .map(|l| u64::from(w.div_ceil(1 << l)) * u64::from(h.div_ceil(1 << l)))
        .sum()
}

fn read_stream(input: &Path) -> Result<Vec<u8>, String> {
    if input.is_dir() {
        return Err(format!(
            "{} is a directory, not a .pifs stream",
            input.display()
        ));
    }
    std::fs::read(input).map_err(|e| format!("cannot read {}: {e}", input.display()))
}

fn decode(input: &Path, output: &Path, limits: decoder_core::Limits) -> Result<(), String> {
    let start = Instant::now();
    check_output(output, Some(input))?;
    // The output format is known from the name: refuse a bad one before decoding.
    io::encode_gray(output, 1, 1, &[0])?;
    let data = read_stream(input)?;
    let decoder =
        decoder_core::Decoder::new(&data).map_err(|e| format!("{}: {e}", input.display()))?;
    let decoder = decoder
        .limits(&limits)
        .map_err(|e| format!("{}: {e} (see --max-pixels)", input.display()))?;
    let mut pixels = vec![0u8; decoder.header().pixel_count()];
    let header = decoder
        .decode_into(&mut pixels)
        .map_err(|e| format!("{}: {e}", input.display()))?;
    let bytes = io::encode_gray(
        output,
        u32::from(header.width),
        u32::from(header.height),
        &pixels,
    )?;
    io::write_atomic(output, &bytes)?;
    println!(
        "{}: {}x{} decoded in {:.1} ms",
        output.display(),
        header.width,
        header.height,
        start.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}

fn info(input: &Path) -> Result<(), String> {
    struct Stats {
        per_depth: std::collections::BTreeMap<u8, usize>,
        models: [usize; decoder_core::internal::model::MODEL_COUNT],
        /// Leaves per model coded with DPCM, then with the grid transform.
        codings: [[usize; decoder_core::internal::model::MODEL_COUNT]; 2],
        cquant: [usize; decoder_core::internal::syntax::control::CONTROL_QUANTISERS],
        wquant: [usize; 4],
        /// Leaves per model whose control points are one pixel apart.
        pixel_grids: [usize; decoder_core::internal::model::MODEL_COUNT],
    }
    impl Stats {
        fn leaf(&mut self, info: &decoder_core::LeafInfo) {
            *self.per_depth.entry(info.node.log2).or_default() += 1;
            self.models[usize::from(info.model)] += 1;
            let model = decoder_core::internal::model::MODELS[usize::from(info.model)];
            if !model.subdivides(info.node.log2) {
                self.pixel_grids[usize::from(info.model)] += 1;
            }
            let coding = usize::from(
                info.coding == decoder_core::internal::syntax::ControlCoding::Transform,
            );
            self.codings[coding][usize::from(info.model)] += 1;
            self.cquant[usize::from(info.cquant)] += 1;
            self.wquant[usize::from(info.wquant)] += 1;
        }
    }
    let data = read_stream(input)?;
    let mut stats = Stats {
        per_depth: Default::default(),
        models: [0; 5],
        codings: [[0; 5]; 2],
        cquant: [0; decoder_core::internal::syntax::control::CONTROL_QUANTISERS],
        wquant: [0; 4],
        pixel_grids: [0; decoder_core::internal::model::MODEL_COUNT],
    };
    let header = decoder_core::Decoder::new(&data)
        .and_then(|d| d.observe(|leaf| stats.leaf(leaf)).verify())
        .map_err(|e| format!("{}: {e}", input.display()))?;
    let px = header.pixel_count() as f64;
    println!("{}", input.display());
    println!(
        "  format version   {}",
        decoder_core::internal::format::VERSION
    );
    println!(
        "  dimensions       {}x{}, {} channel(s), {} bits",
        header.width, header.height, header.channels, header.bit_depth
    );
    println!(
        "  size             {} bytes ({} header), {:.4} bpp",
        data.len(),
        header.encoded_len(),
        data.len() as f64 * 8.0 / px
    );
    println!(
        "  leaf sizes       {}..{} px",
        1 << header.min_leaf_log2,
        1 << header.max_leaf_log2
    );
    println!(
        "  codebooks        {}",
        if header.has_codebooks() {
            "Lloyd-Max (line, cell)"
        } else {
            "none"
        }
    );
    let total: usize = stats.per_depth.values().sum();
    println!("  leaves           {total}");
    for (log2, n) in stats.per_depth.iter().rev() {
        println!("    {:>3}x{:<3}       {n}", 1 << log2, 1 << log2);
    }
    let names = ["2x2 bilinear", "3x3/2x2", "5x5/2x2", "5x5/4x4", "9x9/4x4"];
    println!("  models           leaves (DPCM + transform) [pixel grids among them]");
    for (i, (name, n)) in names.iter().zip(stats.models).enumerate() {
        let (dpcm, transform) = (stats.codings[0][i], stats.codings[1][i]);
        let pixel_grids = stats.pixel_grids[i];
        println!("    {name:<14} {n} ({dpcm} + {transform}) [{pixel_grids}]");
    }
    println!(
        "  control quantiser use (steps {:?} /16 grey): {:?}",
        decoder_core::internal::syntax::control::CONTROL_STEPS,
        stats.cquant
    );
    println!(
        "  weight quantiser use (default, fine, coarse, Lloyd-Max): {:?}",
        stats.wquant
    );
    Ok(())
}

/// The bundled sample image, encoded and decoded with default settings.
fn demo() -> Result<(), String> {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let root = manifest.parent().unwrap_or(manifest);
    let sample = root.join("samples/kodim23.png");
    let out = root.join("out");
    std::fs::create_dir_all(&out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    println!(
        "pifs: encoding the bundled sample {} (Kodak kodim23, as grayscale)",
        sample.display()
    );
    let rates = [0.05, 0.1, 0.25];
    let jobs: Vec<(Target, PathBuf)> = rates
        .iter()
        .map(|&bpp| (Target::Bpp(bpp), out.join(format!("kodim23-{bpp}bpp.pifs"))))
        .collect();
    let settings = Settings {
        min_leaf_log2: EncoderConfig::default().min_leaf_log2,
        max_leaf_log2: EncoderConfig::default().max_leaf_log2,
        fit_weights: false,
    };
    encode_targets(&sample, &settings, &jobs)?;
    for (_, stream) in &jobs {
        decode(
            stream,
            &stream.with_extension("png"),
            decoder_core::Limits::NONE,
        )?;
    }
    println!("streams and decoded images are in {}", out.display());
    Ok(())
}
