//! `pifs`: encode, decode and inspect PIFS images, and draw an image's rate/distortion curve.

#[macro_use]
mod say;

mod batch;
mod compare;
mod curve;
mod decode;
mod demo;
mod display;
mod encode;
mod error;
mod info;
mod leaves_svg;
mod memory;
mod output;
mod packets;
mod plot;
mod progress;
mod rd;
mod signals;

use clap::{Parser, Subcommand};
use host_encoder::io::OutputFormat;
use std::path::PathBuf;
use std::process::ExitCode;

/// Largest image `pifs decode` and `pifs info` accept unless told otherwise: 2^28 pixels
/// (16384 x 16384; 256 MiB of output). Decoding needs memory for a band of rows, not the image.
const DEFAULT_MAX_PIXELS: u64 = 1 << 28;

/// `--format` of `pifs decode`.
fn parse_format(name: &str) -> Result<OutputFormat, String> {
    OutputFormat::from_name(name).ok_or_else(|| format!("'{name}' is not png, pgm, pnm or ppm"))
}

/// Fractal (projected-IFS quadtree) image codec for low-bandwidth links and small displays.
///
/// Without a subcommand, runs the demo (see `pifs demo --help`).
#[derive(Parser, Debug)]
#[command(name = "pifs", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Encode an image (PNG, JPEG, PGM/PPM, BMP, TIFF, WebP, GIF) into a PIFS stream.
    Encode(encode::EncodeArgs),
    /// Decode a PIFS stream into an image (.png, .pgm, .pnm or .ppm, by the output's name).
    ///
    /// .ppm repeats the grey in three channels, for tools that read colour only. The image is
    /// written band by band: memory follows the width, not the image.
    Decode {
        /// Input stream, "-" for standard input; or packets: a directory of .pkt files, a framed
        /// packet file or several packet files.
        ///
        /// A stream's header is checked before anything else is read, and no more than the stream
        /// it declares is read. Of packets, whatever subset is there is decoded, and what is
        /// missing is reported.
        #[arg(required = true, num_args = 1..)]
        input: Vec<PathBuf>,
        /// Output image: .png, .pgm, .pnm or .ppm; "-" writes standard output (PNG unless --format
        /// says otherwise).
        ///
        /// Anything else is refused before decoding. An existing file is replaced atomically and
        /// keeps its permissions, a symbolic link is followed, a device or a FIFO is written
        /// through.
        #[arg(short, long)]
        output: PathBuf,
        /// Image format, whatever the output's name: png, pgm, pnm or ppm.
        #[arg(long, value_parser = parse_format)]
        format: Option<OutputFormat>,
        /// Refuse streams of more pixels than this.
        ///
        /// Checked on the header, before anything is allocated.
        #[arg(long, default_value_t = DEFAULT_MAX_PIXELS)]
        max_pixels: u64,
        /// Decode at this scale of the coded size: 1/8, 1/4, 1/2, 1, 2 or 4.
        ///
        /// 1/8 to 1/2: the full decode's pixels at even, fourth or eighth positions, for a fraction
        /// of the work; 2 and 4: the patches refined below the pixel, their edges smoothed (for a
        /// picture sent small and shown large; bicubic upscaling of the normal decode is a little
        /// softer and closer). The image is ceil(width x scale) by ceil(height x scale). Packets
        /// too: each region drawn at that scale.
        #[arg(long, default_value = "1", value_parser = decode::parse_scale)]
        scale: decoder_core::Scale,
        /// Read the input as packets even when it could be a stream.
        ///
        /// For framed packets on standard input ("-") or from a serial device.
        #[arg(long)]
        packets: bool,
        /// Read framed packets as they arrive and write the picture again after each one that adds
        /// to it.
        ///
        /// From standard input, a FIFO or a serial device (its line in raw mode: `stty -F DEV
        /// raw`), as a gateway shows a picture filling in; the output is always a whole image
        /// (replaced atomically). Ends once no packet of the picture is missing, or at the end of
        /// the input. Implies --packets.
        #[arg(long)]
        follow: bool,
        /// Write the decoded heightmap as a hillshaded relief, for a quick look at a terrain.
        ///
        /// Light from the north-west, 45 degrees up; a grayscale stream's values are the heights.
        /// Optional value: the vertical exaggeration in height units per pixel [default: auto, the
        /// median slope drawn at 20 degrees].
        #[arg(long, value_name = "Z", num_args = 0..=1, default_missing_value = "auto",
              value_parser = decode::parse_z_factor)]
        hillshade: Option<decode::ZFactor>,
        /// Write the picture as a small display of fewer levels shows it: rgb565, rgb666, gray4,
        /// gray2 or mono.
        ///
        /// Each pixel converted to the panel's colours as the device's embedded-graphics drawing
        /// converts it (dithering included): rgb565 (ST7789, ILI9341, SSD1351), rgb666 (ILI9488),
        /// gray4 (16-grey OLEDs), gray2 (4-grey e-paper) or mono (SSD1306/SH1106 OLEDs, memory
        /// LCDs); with --scale for a thumbnail. A packet set: the picture assembled from what
        /// arrived, each pixel as the device draws it.
        #[arg(long, value_name = "PANEL", value_parser = display::parse_panel)]
        display: Option<display::Panel>,
        /// How --display reaches the panel's levels: ordered or nearest.
        ///
        /// ordered: a 4x4 Bayer dither, the device's default (shades kept, no bands); nearest: each
        /// pixel to its nearest level.
        #[arg(long, requires = "display", default_value = "ordered",
              value_parser = display::parse_dither)]
        dither: decoder_core::graphics::Dither,
    },
    /// Describe a PIFS stream; with --svg, draw its quadtree over the decoded image.
    ///
    /// Dimensions, size, leaves per size, model and quantiser use, read from the entropy-coded
    /// syntax without drawing a pixel (unless --svg asks for the drawing).
    Info {
        /// Input stream, "-" for standard input; or packets: directories of .pkt files or framed
        /// packet files (several: packets heard by several receivers, merged).
        #[arg(required = true, num_args = 1..)]
        input: Vec<PathBuf>,
        /// Also draw the quadtree over the decoded image into this SVG file.
        ///
        /// Leaves are outlined in a colour per model.
        #[arg(long, value_name = "FILE")]
        svg: Option<PathBuf>,
        /// Refuse streams of more pixels than this.
        ///
        /// Checked on the header, before the payload is read.
        #[arg(long, default_value_t = DEFAULT_MAX_PIXELS)]
        max_pixels: u64,
        /// Print the description as one JSON object on standard output.
        ///
        /// For scripts and gateways: a packet set's `missing` indices are the packets to ask for
        /// again.
        #[arg(long)]
        json: bool,
        /// Read the input as packets even when it could be a stream.
        ///
        /// For framed packets on standard input ("-") or from a serial device.
        #[arg(long, conflicts_with = "svg")]
        packets: bool,
    },
    /// Rate/distortion curve of an image from one analysis: bytes, bpp and PSNR per rate.
    ///
    /// One analysis serves every rate. Optionally writes the points as CSV, draws them beside
    /// other codecs' points as SVG, and writes the streams.
    Rd(rd::RdArgs),
    /// Tools for packets: simulate a lossy link, send the missing packets again.
    #[command(subcommand)]
    Packets(PacketsCommand),
    /// Fractal curves: fit a projected-IFS curve to a polyline or a sampled function, draw it,
    /// describe it.
    #[command(subcommand)]
    Curve(curve::CurveCommand),
    /// Encode and decode the bundled sample into ./pifs-demo/ (what `pifs` alone does).
    ///
    /// The sample is built into the binary; the outputs go under the current directory.
    Demo,
}

/// `pifs packets ...`.
#[derive(Subcommand, Debug)]
enum PacketsCommand {
    /// Copy the packets of a directory that survive a simulated loss into another (for
    /// testing what a receiver shows).
    Drop(packets::DropArgs),
    /// Frame the packets a receiver asks for again (by index), for the link.
    ///
    /// The indices are the `missing` of `pifs info --json` or of `pifs decode`'s line, such as
    /// 2,5-7; the packets go out framed as `pifs encode -o` frames them (each behind its length,
    /// two bytes, little-endian), in the order of their indices.
    Resend(packets::ResendArgs),
}

/// One line on stderr for an argument error (`--help` has the details), clap's own output
/// for help and version.
fn parse_arguments() -> Result<Cli, ExitCode> {
    let e = match Cli::try_parse() {
        Ok(cli) => return Ok(cli),
        Err(e) => e,
    };
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        e.exit();
    }
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
    Err(ExitCode::from(2))
}

fn main() -> ExitCode {
    let cli = match parse_arguments() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    signals::clean_up_on_termination();
    let result = match cli.command {
        Some(Command::Encode(args)) => encode::run(&args),
        Some(Command::Decode {
            input,
            output,
            format,
            max_pixels,
            scale,
            packets,
            follow,
            hillshade,
            display,
            dither,
        }) => decode::run(
            &input,
            &output,
            format,
            &decoder_core::Limits::pixels(max_pixels),
            decode::Drawing {
                scale,
                packets,
                follow,
                hillshade,
                display: display.map(|panel| display::Showing { panel, dither }),
            },
        ),
        Some(Command::Info {
            input,
            svg,
            max_pixels,
            json,
            packets,
        }) => info::run(
            &input,
            svg.as_deref(),
            &decoder_core::Limits::pixels(max_pixels),
            json,
            packets,
        ),
        Some(Command::Rd(args)) => rd::run(&args),
        Some(Command::Packets(PacketsCommand::Drop(args))) => packets::drop_packets(&args),
        Some(Command::Packets(PacketsCommand::Resend(args))) => packets::resend(&args),
        Some(Command::Curve(command)) => curve::run(&command),
        Some(Command::Demo) | None => demo::run(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pifs: {e}");
            ExitCode::FAILURE
        }
    }
}
