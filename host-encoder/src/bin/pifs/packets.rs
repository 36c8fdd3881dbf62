//! Packets on the command line: `pifs encode --packets DIR` (or `--packet-size N -o FILE`),
//! `pifs decode` of a packet directory or a framed packet file, `pifs packets drop` (loss for
//! testing) and `pifs info` of packets.
//!
//! Two containers: a directory of one file per packet (`0000.pkt`, `0001.pkt`, ... by
//! index), or a framed file for serial links, each packet behind its length (two bytes,
//! little-endian; `docs/bitstream.md`, section 9).

use crate::encode::Analysed;
use crate::error::{CliError, Result};
use crate::progress::RegionsProgress;
use clap::Args;
use decoder_core::{Packet, PacketKind, Scale};
use host_encoder::io::{self, Content, Output, OutputFormat};
use host_encoder::packets::{
    assemble_at, frame, packetise_with_progress, parity_for_loss, unframe, AssembleError,
    Assembled, PacketOptions, Packetised, ParityChoice,
};
use host_encoder::{EncoderConfig, Target};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The packet options of `pifs encode`.
#[derive(Args, Debug, Clone)]
pub struct PacketArgs {
    /// Cut the image into self-contained packets, one file per packet in DIR.
    ///
    /// Files 0000.pkt, 0001.pkt, ...; DIR must not exist or be empty. A receiver decodes any subset
    /// of them, in any order.
    #[arg(long, value_name = "DIR")]
    pub packets: Option<PathBuf>,
    /// Largest packet in bytes, 48 to 1024 [default: 255, a LoRa payload; 233 for Meshtastic].
    ///
    /// With -o instead of --packets, the packets are written one after the other into one file,
    /// each behind its length (2 bytes, little-endian).
    #[arg(long, value_name = "BYTES")]
    pub packet_size: Option<usize>,
    /// The image's number in every packet (0 to 65535) [default: made from the packets' content].
    ///
    /// It tells a receiver's images apart. Without it, a CRC-16 of the packets: different
    /// pictures, or one picture coded differently, get different numbers (but for one chance in
    /// 65 536), the same packets the same number.
    #[arg(long, value_name = "N")]
    pub image_id: Option<u16>,
    /// No preview packet: every packet codes a region.
    ///
    /// A lost one is then interpolated from the regions around it.
    #[arg(long)]
    pub no_preview: bool,
    /// Send the preview twice, first and half way.
    ///
    /// From 8 packets on, for one packet of the budget: a receiver then loses it only when it loses
    /// both copies.
    #[arg(long)]
    pub repeat_preview: bool,
    /// Parity packets to send after the others, within the target.
    ///
    /// Any N of the N + K packets rebuild them all (a receiver that holds the whole set, such as a
    /// gateway or `pifs decode`, rebuilds what was lost).
    #[arg(long, default_value_t = 0, value_name = "K")]
    pub parity: usize,
    /// The share of packets the link loses (0 to 0.5): parity sized for it (instead of --parity).
    ///
    /// As many parity packets as give the best picture on average over such losses; 0.1 for a
    /// tenth.
    #[arg(long, value_name = "SHARE", conflicts_with = "parity")]
    pub expect_loss: Option<f64>,
}

impl PacketArgs {
    /// Whether the encode writes packets.
    pub fn wanted(&self) -> bool {
        self.packets.is_some() || self.packet_size.is_some()
    }

    /// The first option given that only packets use, if any (refused without packets rather
    /// than ignored).
    pub fn packet_only_option(&self) -> Option<&'static str> {
        [
            (self.parity > 0, "--parity"),
            (self.expect_loss.is_some(), "--expect-loss"),
            (self.no_preview, "--no-preview"),
            (self.repeat_preview, "--repeat-preview"),
            (self.image_id.is_some(), "--image-id"),
        ]
        .into_iter()
        .find_map(|(given, name)| given.then_some(name))
    }

    fn options(&self) -> PacketOptions {
        PacketOptions {
            size: self
                .packet_size
                .unwrap_or(host_encoder::packets::DEFAULT_PACKET_SIZE),
            image_id: self.image_id,
            preview: !self.no_preview,
            repeat_preview: self.repeat_preview,
            parity: self.parity,
        }
    }
}

/// Encodes the image of `analysed` (its overview: [`host_encoder::packets::overview_config`])
/// for `target` as packets whose regions are analysed with `config`, and writes them to
/// `--packets DIR` or, framed, to `output`; prints a one-line summary.
pub fn encode(
    analysed: &Analysed,
    config: &EncoderConfig,
    args: &PacketArgs,
    target: Target,
    output: Option<&Path>,
) -> Result<()> {
    let mut options = args.options();
    let started = std::time::Instant::now();
    let refused = |e: host_encoder::packets::PacketError| CliError::Refused(e.to_string());
    let sized = match args.expect_loss {
        Some(loss) => {
            let choice =
                parity_for_loss(&analysed.analysis, target, &options, loss).map_err(refused)?;
            options.parity = choice.parity;
            Some((loss, choice))
        }
        None => None,
    };
    let progress = RegionsProgress::on_terminal();
    let made = packetise_with_progress(&analysed.analysis, config, target, &options, &|done| {
        if let Some(p) = &progress {
            p.made(done);
        }
    });
    if let Some(p) = &progress {
        p.finish();
    }
    let made = made.map_err(refused)?;
    let shown = match (&args.packets, output) {
        (Some(dir), _) => {
            let named: Vec<(String, &Vec<u8>)> = made
                .packets
                .iter()
                .enumerate()
                .map(|(i, p)| (packet_name(i), p))
                .collect();
            write_named(dir, &named)?;
            dir.clone()
        }
        (None, Some(path)) => {
            let mut out = Output::create(path, Content::Binary("PIFS packets"))?;
            let framed = frame(&made.packets);
            out.write_all(&framed).map_err(|e| out.error(e))?;
            let name = out.name().to_path_buf();
            out.commit()?;
            name
        }
        (None, None) => return Err(CliError::Refused("packets need --packets DIR or -o".into())),
    };
    let mut line = summary(&shown, analysed, &made, &options, started);
    if let Some((loss, choice)) = sized {
        line += &sized_for(loss, &choice);
    }
    say!("{line}");
    Ok(())
}

/// The one-line summary of an encode into packets.
fn summary(
    shown: &Path,
    analysed: &Analysed,
    made: &Packetised,
    options: &PacketOptions,
    started: std::time::Instant,
) -> String {
    let (w, h) = analysed.size();
    let total = made.total_bytes();
    format!(
        "{}: {w}x{h} -> image {}, {} {} of at most {} bytes ({} preview, {} parity), {total} bytes, {:.4} bpp, {} bytes of headers and checksums ({:.1}%), PSNR {:.2} dB with every packet, analysis {:.2} s + packets {:.2} s",
        shown.display(),
        made.image_id,
        made.packets.len(),
        if made.packets.len() == 1 {
            "packet"
        } else {
            "packets"
        },
        options.size,
        made.previews,
        made.parity,
        analysed.bpp(total),
        made.overhead_bytes,
        100.0 * made.overhead_bytes as f64 / total.max(1) as f64,
        made.psnr,
        analysed.seconds,
        started.elapsed().as_secs_f64(),
    )
}

/// What the summary adds when the parity packets were sized for a loss rate.
fn sized_for(loss: f64, choice: &ParityChoice) -> String {
    format!(
        "; {} parity for {:.0}% loss, about {:.2} dB expected",
        choice.parity,
        100.0 * loss,
        choice.expected_psnr
    )
}

/// The name of the packet sent at position `index` in a directory.
fn packet_name(index: usize) -> String {
    format!("{index:04}.pkt")
}

/// Whether `path` holds packets rather than a stream: a directory, or a regular file that is
/// not a stream ([`host_encoder::packets::is_stream_data`]); devices, pipes and standard input
/// are read as streams, header first.
pub fn is_packet_input(path: &Path) -> bool {
    if path.is_dir() {
        return true;
    }
    if io::is_std_stream(path) || !path.metadata().is_ok_and(|m| m.is_file()) {
        return false;
    }
    use std::io::Read;
    match std::fs::File::open(path) {
        Ok(f) => {
            let mut data = Vec::new();
            f.take(MAX_PACKET_INPUT).read_to_end(&mut data).is_ok()
                && !data.is_empty()
                && !host_encoder::packets::is_stream_data(&data)
        }
        Err(_) => false,
    }
}

/// The largest packet file (or standard input) read: 64 MiB, 250 000 packets of 255 bytes.
const MAX_PACKET_INPUT: u64 = 1 << 26;

/// The `.pkt` files of the directory `dir`, by name: each name and its bytes.
fn packet_files(dir: &Path) -> Result<Vec<(String, Vec<u8>)>> {
    let failed = |e: std::io::Error| CliError::Refused(format!("{}: {e}", dir.display()));
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(failed)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "pkt") && p.is_file())
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|p| {
            let name = p
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into());
            Ok((name, std::fs::read(p).map_err(failed)?))
        })
        .collect()
}

/// The packets at `path`: every `.pkt` file of a directory (by name), one packet file, or a
/// framed file or standard input ("-").
pub fn read_packets(path: &Path) -> Result<Vec<Vec<u8>>> {
    if path.is_dir() {
        return Ok(packet_files(path)?.into_iter().map(|(_, p)| p).collect());
    }
    let data = io::read_input(path, "PIFS packets", MAX_PACKET_INPUT)?;
    if Packet::parse(&data).is_ok() {
        return Ok(vec![data]);
    }
    // An image given where a stream belongs is a slip worth naming.
    if let Ok(format) = image::guess_format(&data) {
        return Err(CliError::Refused(format!(
            "{}: {} image, not a PIFS stream or packets (use 'pifs encode' to make one)",
            path.display(),
            image_name(format)
        )));
    }
    Ok(unframe(&data))
}

/// "a PNG", "a JPEG", "a WebP": the kind of an image file, with its article.
fn image_name(format: image::ImageFormat) -> String {
    use image::ImageFormat as F;
    let name = match format {
        F::Png => "PNG".to_string(),
        F::Jpeg => "JPEG".to_string(),
        F::WebP => "WebP".to_string(),
        F::Pnm => "PNM".to_string(),
        other => format!("{other:?}").to_uppercase(),
    };
    let article = if name.starts_with(['A', 'E', 'I', 'O', 'U']) {
        "an"
    } else {
        "a"
    };
    format!("{article} {name}")
}

/// Assembles the packets at `inputs` at `scale` (an image of at most `max_pixels` at its
/// coded size and at that scale), refusing a set with no valid packet in one line.
fn assemble_inputs(
    inputs: &[PathBuf],
    max_pixels: u64,
    scale: Scale,
) -> Result<(Vec<Vec<u8>>, Assembled)> {
    let mut packets = Vec::new();
    for input in inputs {
        packets.extend(read_packets(input)?);
    }
    let input = match inputs {
        [one] => one.display().to_string(),
        _ => format!("{} files", inputs.len()),
    };
    let assembled =
        assemble_at(packets.iter().map(Vec::as_slice), max_pixels, scale).map_err(|e| {
            let hint = match e {
                AssembleError::NoValidPacket(Some(decoder_core::DecodeError::TooLarge {
                    ..
                }))
                | AssembleError::TooLarge { .. } => " (see --max-pixels)",
                _ => "",
            };
            CliError::Refused(format!("{input}: {e}{hint}"))
        })?;
    Ok((packets, assembled))
}

/// `pifs decode` of packets: whatever subset is at `inputs`, into the image `output`; reports
/// what was missing.
pub fn decode(
    inputs: &[PathBuf],
    output: &Path,
    format: OutputFormat,
    max_pixels: u64,
    scale: Scale,
    display: Option<crate::display::Showing>,
) -> Result<()> {
    let (_, mut assembled) = assemble_inputs(inputs, max_pixels, scale)?;
    let name = write_assembled(&mut assembled, output, format, display)?;
    say!("{}: {}", name.display(), describe(&assembled));
    Ok(())
}

/// Writes the picture of `assembled` (its pixels taken) to `output`, as `display` shows it if
/// given; the name the output goes by.
fn write_assembled(
    assembled: &mut Assembled,
    output: &Path,
    format: OutputFormat,
    display: Option<crate::display::Showing>,
) -> Result<PathBuf> {
    let mut picture = crate::display::Picture {
        width: assembled.width,
        height: assembled.height,
        channels: assembled.channels,
        pixels: std::mem::take(&mut assembled.pixels),
    };
    if let Some(showing) = display {
        picture = crate::display::show_picture(&picture, showing);
    }
    let bytes = format.encode(
        output,
        picture.width,
        picture.height,
        picture.channels,
        &picture.pixels,
    )?;
    crate::decode::write_image(output, &bytes)
}

/// `pifs decode --follow`: framed packets read from `inputs` (one stream) as they arrive; after
/// each packet that adds to the picture (of the image most packets so far belong to), the
/// picture is written to `output` again and reported in one line. Ends once the picture is
/// whole (no packet missing) or at the end of the input; refused, with nothing written, if no
/// valid packet came.
pub fn follow(
    inputs: &[PathBuf],
    output: &Path,
    format: OutputFormat,
    max_pixels: u64,
    scale: Scale,
    display: Option<crate::display::Showing>,
) -> Result<()> {
    let [input] = inputs else {
        return Err(CliError::Refused(
            "--follow reads one stream of framed packets".into(),
        ));
    };
    if input.is_dir() || io::is_std_stream(output) {
        return Err(CliError::Refused(
            "--follow reads framed packets (standard input, a FIFO, a device or a file) and \
             rewrites an image file: give -o FILE"
                .into(),
        ));
    }
    let name = io::input_name(input);
    let mut source = open_packet_stream(input)?;
    let mut packets: Vec<Vec<u8>> = Vec::new();
    let mut total = 0u64;
    // What the last picture written was made of: the image and its packets.
    let mut shown: Option<(u16, usize)> = None;
    let mut last_error = None;
    while let Some(packet) = next_frame(&mut source, &name)? {
        total += packet.len() as u64 + 2;
        if total > MAX_PACKET_INPUT {
            return Err(CliError::Refused(format!(
                "{}: more than {MAX_PACKET_INPUT} bytes of packets",
                name.display()
            )));
        }
        packets.push(packet);
        let mut assembled = match assemble_at(packets.iter().map(Vec::as_slice), max_pixels, scale)
        {
            Ok(a) => a,
            Err(e) => {
                last_error = Some(e);
                continue;
            }
        };
        let state = (
            assembled.image_id,
            assembled.received.len() + assembled.recovered.len(),
        );
        if shown == Some(state) {
            continue;
        }
        let written = write_assembled(&mut assembled, output, format, display)?;
        say!("{}: {}", written.display(), describe(&assembled));
        shown = Some(state);
        if assembled.missing.is_empty() {
            break;
        }
    }
    match (shown, last_error) {
        (Some(_), _) => Ok(()),
        (None, Some(e)) => Err(CliError::Refused(format!("{}: {e}", name.display()))),
        (None, None) => Err(CliError::Refused(format!(
            "{}: no packet (the input was empty)",
            name.display()
        ))),
    }
}

/// The stream of framed packets at `path` (standard input for "-").
fn open_packet_stream(path: &Path) -> Result<Box<dyn std::io::Read>> {
    if io::is_std_stream(path) {
        return Ok(Box::new(std::io::stdin().lock()));
    }
    let file = std::fs::File::open(path).map_err(|source| io::FileError::Open {
        path: io::input_name(path),
        source,
    })?;
    Ok(Box::new(file))
}

/// The next framed packet of `source` (its two length bytes, then the packet), `None` at the
/// end of the input; a last frame cut short is returned as it is (it fails its check like any
/// damaged packet), and the input ends there.
fn next_frame(source: &mut dyn std::io::Read, name: &Path) -> Result<Option<Vec<u8>>> {
    let failed = |e: std::io::Error| CliError::Refused(format!("{}: {e}", name.display()));
    let mut length = [0u8; 2];
    let got = read_full(source, &mut length).map_err(failed)?;
    if got < length.len() {
        return Ok(None);
    }
    let mut packet = vec![0u8; usize::from(u16::from_le_bytes(length))];
    let got = read_full(source, &mut packet).map_err(failed)?;
    packet.truncate(got);
    Ok(Some(packet))
}

/// Reads until `buf` is full or the input ends; how many bytes were read.
fn read_full(source: &mut dyn std::io::Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match source.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// What a receiver got, in one line.
fn describe(a: &Assembled) -> String {
    let mut text = format!(
        "{}x{} {} from {} of {} packets (image {}), {:.1}% of the pixels from regions{}",
        a.width,
        a.height,
        if a.channels == 3 { "colour" } else { "gray" },
        a.received.len(),
        a.count,
        a.image_id,
        100.0 * a.coverage,
        match (a.coverage < 1.0, a.preview) {
            (false, _) => "",
            (true, true) => ", the rest from the preview",
            (true, false) => ", the rest interpolated",
        },
    );
    if !a.recovered.is_empty() {
        text += &format!("; rebuilt from parity: {}", ranges(&a.recovered));
    }
    if !a.missing.is_empty() {
        text += &format!("; missing: {}", ranges(&a.missing));
        if a.parity > 0 {
            text += &format!(
                " ({} parity held: any {} more of the image's packets rebuild them)",
                a.parity,
                a.packets_short()
            );
        }
    }
    for (n, what) in [
        (a.rejected, "damaged or not packets"),
        (a.foreign, "of another image"),
        (a.duplicates, "duplicates"),
    ] {
        if n > 0 {
            text += &format!("; {n} ignored ({what})");
        }
    }
    text
}

/// `1-3,7,9-10`.
fn ranges(indices: &[u16]) -> String {
    let mut parts = Vec::new();
    let mut i = 0;
    while i < indices.len() {
        let start = indices[i];
        let mut end = start;
        while i + 1 < indices.len() && indices[i + 1] == end + 1 {
            i += 1;
            end += 1;
        }
        parts.push(if start == end {
            format!("{start}")
        } else {
            format!("{start}-{end}")
        });
        i += 1;
    }
    parts.join(",")
}

/// `pifs info` of packets (those at `inputs`, merged): count, sizes, coverage; as one JSON
/// object with `json`.
pub fn info(inputs: &[PathBuf], max_pixels: u64, json: bool) -> Result<()> {
    let (packets, assembled) = assemble_inputs(inputs, max_pixels, Scale::One)?;
    let input = (inputs.iter())
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let a = &assembled;
    // The image's own packets: others (damaged, another image's) are counted apart.
    let own: Vec<&Vec<u8>> = packets.iter().filter(|p| a.owns(p)).collect();
    let sizes: Vec<usize> = own.iter().map(|p| p.len()).collect();
    let total: usize = sizes.iter().sum();
    let previews = own
        .iter()
        .filter_map(|p| Packet::parse(p).ok())
        .filter(|p| p.kind == PacketKind::Preview)
        .count();
    let bpp = total as f64 * 8.0 / (f64::from(a.width) * f64::from(a.height));
    if json {
        let object = serde_json::json!({
            "path": input,
            "kind": "packets",
            "image_id": a.image_id,
            "width": a.width,
            "height": a.height,
            "channels": a.channels,
            "count": a.count,
            "files": packets.len(),
            "packets": own.len(),
            "bytes": total,
            "bpp": bpp,
            "previews": previews,
            "preview_drawn": a.preview,
            "received": a.received,
            "missing": a.missing,
            "rebuilt_from_parity": a.recovered,
            "parity_held": a.parity,
            "packets_short": a.packets_short(),
            "coverage": a.coverage,
            "ignored": {
                "damaged": a.rejected,
                "other_image": a.foreign,
                "duplicates": a.duplicates,
            },
        });
        println!("{object}");
        return Ok(());
    }
    println!("{input}: PIFS packets");
    println!(
        "  image {}: {}x{} {}, sent as {} packets",
        a.image_id,
        a.width,
        a.height,
        if a.channels == 3 { "colour" } else { "gray" },
        a.count
    );
    let others = match packets.len() - own.len() {
        0 => String::new(),
        n => format!(" of it (and {n} other files)"),
    };
    println!(
        "  here: {} packets{others}, {total} bytes ({} to {} bytes each), {previews} preview(s), {bpp:.4} bpp",
        own.len(),
        sizes.iter().min().unwrap_or(&0),
        sizes.iter().max().unwrap_or(&0),
    );
    println!("  {}", describe(a));
    Ok(())
}

/// Arguments of `pifs packets drop`.
#[derive(Args, Debug)]
pub struct DropArgs {
    /// Packets to lose from: a directory of .pkt files.
    pub input: PathBuf,
    /// Where the packets that arrive go (a new or empty directory).
    pub output: PathBuf,
    /// Probability that a packet is lost, 0 to 1.
    #[arg(long)]
    pub loss: f64,
    /// Seed of the loss pattern (the same seed loses the same packets).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Mean length of a burst of losses (Gilbert model: a lost packet is followed by another
    /// with probability 1 - 1/BURST); 1 for independent losses.
    #[arg(long, default_value_t = 1.0)]
    pub burst: f64,
}

/// `pifs packets resend`: which packets, from where, to where.
#[derive(Args, Debug)]
pub struct ResendArgs {
    /// The packets sent: a directory of .pkt files or a framed packet file ("-": standard
    /// input).
    pub input: PathBuf,
    /// The packets to send again, by index: such as 2,5-7.
    #[arg(long, value_name = "INDICES", value_parser = parse_indices)]
    pub only: Indices,
    /// Output: the packets framed for a serial link; "-" writes standard output.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Packet indices, ascending, each once.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Indices(pub Vec<u16>);

/// Parses packet indices: numbers and ranges `a-b`, separated by commas (`2,5-7`), as the
/// `missing` of `pifs decode`'s line writes them.
pub fn parse_indices(text: &str) -> std::result::Result<Indices, String> {
    let bad = || format!("not packet indices: {text} (such as 2,5-7)");
    let mut out = std::collections::BTreeSet::new();
    for part in text.split(',') {
        let (a, b) = part.split_once('-').unwrap_or((part, part));
        let (Ok(a), Ok(b)) = (a.trim().parse::<u16>(), b.trim().parse::<u16>()) else {
            return Err(bad());
        };
        if a > b {
            return Err(bad());
        }
        out.extend(a..=b);
    }
    Ok(Indices(out.into_iter().collect()))
}

/// `pifs packets resend`: the data packets of `args.input` with the indices asked for, framed,
/// in the order of their indices; refused in one line, nothing written, when one of them is
/// not there.
pub fn resend(args: &ResendArgs) -> Result<()> {
    if io::is_std_stream(&args.output) {
        crate::say::stdout_is_data();
    }
    let mut by_index = std::collections::BTreeMap::new();
    for packet in read_packets(&args.input)? {
        if let Ok(parsed) = Packet::parse(&packet) {
            by_index.entry(parsed.index).or_insert(packet);
        }
    }
    let absent: Vec<u16> = (args.only.0.iter())
        .copied()
        .filter(|i| !by_index.contains_key(i))
        .collect();
    if !absent.is_empty() {
        return Err(CliError::Refused(format!(
            "{}: no packet {} (it holds {})",
            args.input.display(),
            ranges(&absent),
            match by_index.keys().copied().collect::<Vec<u16>>() {
                held if held.is_empty() => "no valid packet".to_string(),
                held => ranges(&held),
            }
        )));
    }
    let chosen: Vec<Vec<u8>> = (args.only.0.iter())
        .filter_map(|i| by_index.remove(i))
        .collect();
    let mut out = Output::create(&args.output, Content::Binary("PIFS packets"))?;
    out.write_all(&frame(&chosen)).map_err(|e| out.error(e))?;
    let name = out.name().to_path_buf();
    out.commit()?;
    say!(
        "{}: {} packets ({}), {} bytes framed",
        name.display(),
        chosen.len(),
        ranges(&args.only.0),
        chosen.iter().map(|p| p.len() + 2).sum::<usize>()
    );
    Ok(())
}

/// `pifs packets drop`: copies the packets that survive a simulated loss.
pub fn drop_packets(args: &DropArgs) -> Result<()> {
    if !(0.0..=1.0).contains(&args.loss) || !(1.0..=f64::MAX).contains(&args.burst) {
        return Err(CliError::Refused(
            "--loss must be from 0 to 1 and --burst at least 1".into(),
        ));
    }
    if !args.input.is_dir() {
        return Err(CliError::Refused(format!(
            "{} is not a directory of packets",
            args.input.display()
        )));
    }
    let named = packet_files(&args.input)?;
    let lost = loss_pattern(named.len(), args.loss, args.burst, args.seed);
    let kept: Vec<(String, &Vec<u8>)> = named
        .iter()
        .zip(&lost)
        .filter(|(_, &l)| !l)
        .map(|((name, p), _)| (name.clone(), p))
        .collect();
    let dropped = lost.iter().filter(|&&l| l).count();
    write_named(&args.output, &kept)?;
    say!(
        "{}: kept {} of {} packets ({dropped} lost)",
        args.output.display(),
        kept.len(),
        kept.len() + dropped
    );
    Ok(())
}

/// Writes packets into `dir` under the names given, as a whole: into a new directory beside
/// it, renamed to `dir` at the end, so that an interrupted command leaves no partial set.
/// `dir` must not exist, or be empty.
fn write_named(dir: &Path, files: &[(String, &Vec<u8>)]) -> Result<()> {
    if dir.exists() && std::fs::read_dir(dir).map_or(true, |mut d| d.next().is_some()) {
        return Err(CliError::Refused(format!(
            "{} exists and is not an empty directory",
            dir.display()
        )));
    }
    let staging = dir.with_file_name(format!(
        ".{}.partial-{}",
        dir.file_name()
            .map_or("packets".into(), |n| n.to_string_lossy()),
        std::process::id()
    ));
    let failed =
        |e: std::io::Error| CliError::Refused(format!("cannot write {}: {e}", dir.display()));
    std::fs::create_dir(&staging).map_err(failed)?;
    let written = (|| -> std::io::Result<()> {
        for (name, p) in files {
            std::fs::write(staging.join(name), p)?;
        }
        if dir.exists() {
            std::fs::remove_dir(dir)?;
        }
        std::fs::rename(&staging, dir)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(failed(e));
    }
    Ok(())
}

/// Which of `n` packets a link loses: a two-state (Gilbert) chain whose losses have mean
/// rate `loss` and mean burst length `burst` (independent losses for 1), from a seeded
/// generator (SplitMix64), so that a pattern is reproducible everywhere.
pub fn loss_pattern(n: usize, loss: f64, burst: f64, seed: u64) -> Vec<bool> {
    // SplitMix64's finaliser: neighbouring states give unrelated outputs.
    let mix = |mut z: u64| {
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;
    // The seed is mixed first, so that seeds 1, 2, 3 ... start far apart.
    let mut state = mix(seed.wrapping_mul(GOLDEN));
    let mut uniform = move || {
        state = state.wrapping_add(GOLDEN);
        (mix(state) >> 11) as f64 / (1u64 << 53) as f64
    };
    // Stay in the lost state with probability 1 - 1/burst; enter it at the rate that makes
    // the stationary loss `loss`.
    let stay = 1.0 - 1.0 / burst;
    let enter = if loss >= 1.0 {
        1.0
    } else {
        (loss * (1.0 - stay) / (1.0 - loss)).min(1.0)
    };
    let mut lost = false;
    (0..n)
        .map(|i| {
            let u = uniform();
            lost = if i == 0 || burst <= 1.0 {
                u < loss
            } else if lost {
                u < stay
            } else {
                u < enter
            };
            lost
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn losses_have_their_rate_and_bursts() {
        let n = 200_000;
        for (loss, burst) in [(0.1, 1.0), (0.2, 1.0), (0.1, 4.0)] {
            let pattern = loss_pattern(n, loss, burst, 7);
            let rate = pattern.iter().filter(|&&l| l).count() as f64 / n as f64;
            assert!((rate - loss).abs() < 0.01, "{loss} {burst}: {rate}");
            let bursts = pattern.windows(2).filter(|w| w[1] && !w[0]).count() as f64;
            let mean_burst = rate * n as f64 / bursts;
            // Independent losses run on with the loss probability itself.
            let expected = if burst == 1.0 {
                1.0 / (1.0 - loss)
            } else {
                burst
            };
            assert!(
                (mean_burst - expected).abs() < 0.05 * expected,
                "{loss} {burst}: {mean_burst}"
            );
        }
        assert_eq!(loss_pattern(50, 0.3, 1.0, 3), loss_pattern(50, 0.3, 1.0, 3));
        assert_ne!(loss_pattern(50, 0.3, 1.0, 3), loss_pattern(50, 0.3, 1.0, 4));
        // Neighbouring seeds are independent: over many seeds, a short pattern loses nothing
        // about as often as independence says ((1 - 0.05)^19 = 0.377).
        let seeds = 4000;
        let clean = (0..seeds)
            .filter(|&s| !loss_pattern(19, 0.05, 1.0, s).contains(&true))
            .count() as f64
            / seeds as f64;
        assert!((clean - 0.377).abs() < 0.03, "{clean}");
    }

    #[test]
    fn missing_indices_read_as_ranges() {
        assert_eq!(ranges(&[1, 2, 3, 7, 9, 10]), "1-3,7,9-10");
        assert_eq!(ranges(&[]), "");
    }
}
