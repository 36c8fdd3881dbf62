//! The host's input and output, tried the way users and gateways use them (issue 20): one test
//! per behaviour, each asserting it and writing its rows of `docs/robustness.md`.

use super::doc;
use super::{gray_png, mask_encoder_figures, noise, Scratch};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The tests with rows in the host section, in the order of their rows.
pub const TESTS: &[&str] = &[
    "encode_refuses_a_flat_8000x8000_png_up_front",
    "encode_is_bounded_by_its_memory_budget",
    "decode_writes_large_images_in_bands",
    "decode_and_info_refuse_dev_zero_at_once",
    "info_checks_limits_and_draws_no_pixels",
    "output_to_devices_fifos_and_links",
    "output_modes_follow_the_umask_or_the_file",
    "output_is_checked_before_the_work",
    "no_litter_when_interrupted",
    "pipes_carry_streams_and_images",
    "exif_orientation_is_applied",
    "multi_page_tiff_notes_its_first_page",
    "animated_gif_notes_its_first_frame",
    "target_messages_say_what_to_ask_for",
];

#[test]
fn every_host_test_has_its_rows() {
    if std::env::var_os("PIFS_WRITE_ROBUSTNESS_TABLE").is_some() {
        return;
    }
    assert_eq!(
        doc::host_tests_in_doc(),
        TESTS,
        "docs/robustness.md is out of date: run `bash scripts/robustness-table.sh`"
    );
}

fn pifs_path() -> &'static str {
    env!("CARGO_BIN_EXE_pifs")
}

fn pifs() -> Command {
    Command::new(pifs_path())
}

/// A scratch directory for one test, readable by every user (the tests that drop privileges
/// read their inputs there).
fn scratch(name: &str) -> Scratch {
    let dir = Scratch::new(&format!("host-{name}"));
    set_mode(&dir, 0o755);
    dir
}

fn set_mode(path: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
}

fn mode_of(path: &Path) -> u32 {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(path).unwrap().permissions().mode() & 0o7777
}

/// A row: what was tried, the command (the scratch directory shown as `DIR`), the outcome.
fn row(dir: &Path, tried: &str, command: &str, outcome: &str) -> String {
    let d = dir.to_string_lossy();
    format!(
        "| {tried} | `{}` | {} |",
        command.replace(&*d, "DIR"),
        outcome.replace(&*d, "DIR").replace('|', "\\|")
    )
}

/// The one line of a refused command, as the table shows it.
fn message(dir: &Path, out: &Output) -> String {
    let line = refused(out);
    format!(
        "`{}`",
        mask_encoder_figures(&line.replace(&*dir.to_string_lossy(), "DIR"))
    )
}

fn refused(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "accepted: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(out.status.code().is_some(), "killed: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr:?}");
    assert!(stderr.starts_with("pifs: "), "{stderr:?}");
    stderr.trim_end().to_string()
}

fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A command's output, wall time and peak resident memory.
struct Measured {
    out: Output,
    seconds: f64,
    peak_mb: f64,
}

/// Runs `pifs args` under `/usr/bin/time` (after the `wrapper` command, such as `prlimit`).
fn measured(wrapper: &[&str], args: &[&str]) -> Measured {
    let stats = tempfile::NamedTempFile::new().unwrap();
    let time = Path::new("/usr/bin/time");
    assert!(
        time.exists(),
        "these tests measure memory with GNU time (/usr/bin/time)"
    );
    let start = Instant::now();
    let out = Command::new(time)
        .args(["-f", "%M", "-o"])
        .arg(stats.path())
        .args(wrapper)
        .arg(pifs_path())
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let text = std::fs::read_to_string(stats.path()).unwrap();
    let kb: f64 = text
        .lines()
        .last()
        .and_then(|l| l.trim().parse().ok())
        .unwrap_or_else(|| panic!("no peak in {text:?}"));
    Measured {
        out,
        seconds,
        peak_mb: kb * 1024.0 / 1e6,
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A PNG of `w x h` gray pixels whose image data is an empty zlib stream: what a reader
/// learns from its header, without the gigabytes of a real one.
fn png_header_only(path: &Path, w: u32, h: u32) {
    let chunk = |kind: &[u8; 4], data: &[u8]| {
        let mut crc = decoder_core::internal::checksum::Crc32::default();
        crc.update(kind);
        crc.update(data);
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        out.extend_from_slice(&crc.value().to_be_bytes());
        out
    };
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(
        b"IDAT",
        &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
    ));
    png.extend(chunk(b"IEND", &[]));
    std::fs::write(path, png).unwrap();
}

/// A flat `w x h` 8-bit grayscale PNG, written row by row.
fn flat_png(path: &Path, w: u32, h: u32, value: u8) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut encoder = png::Encoder::new(file, w, h);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder
        .write_header()
        .unwrap()
        .into_stream_writer()
        .unwrap();
    let row = vec![value; w as usize];
    for _ in 0..h {
        writer.write_all(&row).unwrap();
    }
    writer.finish().unwrap();
}

/// A valid `side x side` stream of 128-px leaves with a pattern, cached per format version
/// in the target directory (the 65535 x 65535 one takes half a minute to write).
fn synthetic(side: u16) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let path = dir.join(format!(
        "pifs-synthetic-{side}-v{}.pifs",
        decoder_core::VERSION
    ));
    if !path.exists() {
        let stream = host_encoder::internal::synthetic_stream(side, side, 7, |node, leaf| {
            let (i, j) = (node.x / 128, node.y / 128);
            leaf.control[0] = ((i * 7 + j * 3) % 9) as i16 - 4;
            leaf.control[1] = ((i + j) % 3) as i16 - 1;
        })
        .unwrap();
        let tmp = dir.join(format!("{}.{}", path.display(), std::process::id()));
        std::fs::write(&tmp, stream).unwrap();
        std::fs::rename(&tmp, &path).unwrap();
    }
    path
}

/// The scratch inputs most tests share: a 64x48 PNG and its stream.
fn small_inputs(dir: &Path) -> (PathBuf, PathBuf) {
    let png = dir.join("good.png");
    gray_png(&png, 64, 48, |x, y| (x * 3 + y * 2) as u8);
    let stream = dir.join("good.pifs");
    ok(&pifs()
        .args(["encode", "--bytes", "300", "-o", s(&stream), s(&png)])
        .output()
        .unwrap());
    (png, stream)
}

fn decoded(stream: &[u8]) -> (u32, u32, Vec<u8>) {
    let decoder = decoder_core::Decoder::new(stream).unwrap();
    let (w, h) = (decoder.header().width, decoder.header().height);
    let mut px = vec![0u8; decoder.header().pixel_count()];
    decoder.decode_into(&mut px).unwrap();
    (u32::from(w), u32::from(h), px)
}

/// PSNR of a decoded image of [`noise`].
fn psnr_of_noise((w, h, px): &(u32, u32, Vec<u8>)) -> f64 {
    let sse: f64 = (0..*h)
        .flat_map(|y| (0..*w).map(move |x| (x, y)))
        .zip(px)
        .map(|((x, y), &p)| (f64::from(p) - f64::from(noise(x, y))).powi(2))
        .sum();
    10.0 * (255.0f64.powi(2) * px.len() as f64 / sse).log10()
}

fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".pifs-tmp"))
        .collect()
}

fn record(test: &str, rows: &[String]) {
    doc::host_rows(TESTS, test, rows);
}

#[test]
fn encode_refuses_a_flat_8000x8000_png_up_front() {
    let dir = scratch("flat8000");
    let png = dir.join("flat-8000.png");
    flat_png(&png, 8000, 8000, 128);
    let out = dir.join("f.pifs");
    let run = measured(&[], &["encode", s(&png), "-o", s(&out)]);
    let msg = message(&dir, &run.out);
    assert!(msg.contains("--max-pixels"), "{msg}");
    assert!(run.seconds < 1.0, "{} s", run.seconds);
    assert!(run.peak_mb < 50.0, "{} MB", run.peak_mb);
    assert!(!out.exists());
    let mut rows = vec![row(
        &dir,
        "encode a flat 8000x8000 PNG",
        &format!("pifs encode {} -o {}", s(&png), s(&out)),
        &format!("refused in < 1 s, peak < 50 MB, before decoding a pixel: {msg}; no output"),
    )];
    // Past --max-pixels, the memory the analysis needs decides (for 3.6 gigapixels, more
    // than any machine running the tests has). Only the PNG's header is read.
    let huge = dir.join("header-60000.png");
    png_header_only(&huge, 60000, 60000);
    let run = measured(
        &[],
        &[
            "encode",
            s(&huge),
            "-o",
            s(&out),
            "--max-pixels",
            "4000000000",
            "--max-memory",
            "16G",
        ],
    );
    let msg = message(&dir, &run.out);
    assert!(msg.contains("--max-memory"), "{msg}");
    assert!(run.seconds < 1.0 && run.peak_mb < 50.0);
    assert!(!out.exists());
    rows.push(row(
        &dir,
        "a 60000x60000 PNG header with --max-pixels raised",
        &format!(
            "pifs encode {} -o {} --max-pixels 4000000000 --max-memory 16G",
            s(&huge),
            s(&out)
        ),
        &format!("refused in < 1 s by the memory allowed: {msg}; no output"),
    ));
    record("encode_refuses_a_flat_8000x8000_png_up_front", &rows);
}

/// The figure of "needs about 318 MiB" in a refusal, in MB.
fn needs_mb(line: &str) -> f64 {
    let at = line.find("needs about ").expect(line) + "needs about ".len();
    let mut words = line[at..].split_whitespace();
    let value: f64 = words.next().unwrap().parse().unwrap();
    match words.next().unwrap().trim_end_matches(',') {
        "GiB" => value * 1073.741824,
        "MiB" => value * 1.048576,
        other => panic!("unit {other} in {line}"),
    }
}

#[test]
fn encode_is_bounded_by_its_memory_budget() {
    let dir = scratch("budget");
    // More than the cap below holds by the estimate, even analysed in parts (its smallest
    // parts are bands of 8000 x 320 pixels).
    let big = dir.join("noise-8000x1000.png");
    gray_png(&big, 8000, 1000, noise);
    let small = dir.join("noise-250.png");
    gray_png(&small, 250, 250, noise);
    let mid = dir.join("noise-500.png");
    gray_png(&mid, 500, 500, noise);
    let parted = dir.join("noise-500x900.png");
    gray_png(&parted, 500, 900, noise);
    let out = dir.join("b.pifs");
    let cap = ["prlimit", "--as=400000000"];
    let mut rows = Vec::new();

    let run = measured(&cap, &["encode", s(&big), "-o", s(&out)]);
    let msg = message(&dir, &run.out);
    assert!(
        msg.contains("--max-memory") && msg.contains("in parts"),
        "{msg}"
    );
    assert!(run.seconds < 1.0);
    assert!(!out.exists());
    rows.push(row(
        &dir,
        "encode 8000x1000 under a 400 MB address-space cap",
        &format!(
            "prlimit --as=400000000 pifs encode {} -o {}",
            s(&big),
            s(&out)
        ),
        &format!("refused in < 1 s, never an allocation abort: {msg}"),
    ));

    let run = measured(&cap, &["encode", s(&small), "-o", s(&out)]);
    ok(&run.out);
    decoded(&std::fs::read(&out).unwrap());
    rows.push(row(
        &dir,
        "encode 250x250 under the same cap",
        &format!(
            "prlimit --as=400000000 pifs encode {} -o {}",
            s(&small),
            s(&out)
        ),
        "encoded within it; the stream decodes",
    ));

    // Too large to analyse whole in the budget given: analysed in parts, within it.
    let budget = ["encode", s(&parted), "-o", s(&out), "--bytes", "20000"];
    let run = measured(&[], &[&budget[..], &["--max-memory", "120M"]].concat());
    let said = ok(&run.out);
    assert!(said.contains("analysing it in parts"), "{said}");
    assert!(run.peak_mb <= 120.0, "{} MB", run.peak_mb);
    let stream = std::fs::read(&out).unwrap();
    assert!(stream.len() <= 20000, "{} bytes", stream.len());
    let parts_psnr = psnr_of_noise(&decoded(&stream));
    let run = measured(&[], &budget);
    ok(&run.out);
    let whole = std::fs::read(&out).unwrap();
    let whole_psnr = psnr_of_noise(&decoded(&whole));
    assert!(
        (parts_psnr - whole_psnr).abs() < 0.1,
        "in parts {parts_psnr} dB, whole {whole_psnr} dB"
    );
    rows.push(row(
        &dir,
        "a budget given with --max-memory that the whole analysis exceeds",
        &format!(
            "pifs encode {} -o {} --bytes 20000 --max-memory 120M",
            s(&parted),
            s(&out)
        ),
        "analysed in parts within it (peak <= 120 MB); the stream decodes, fits --bytes, and \
         its PSNR is within 0.1 dB of the stream of the whole image's analysis",
    ));

    // The estimate behind these refusals bounds what an encode really takes.
    let estimate_of = |input: &Path| {
        needs_mb(&refused(
            &pifs()
                .args(["encode", s(input), "-o", s(&out), "--max-memory", "10M"])
                .output()
                .unwrap(),
        ))
    };
    let encode_within = |input: &Path, estimate: f64, what: &str| {
        let run = measured(&[], &["encode", s(input), "-o", s(&out)]);
        ok(&run.out);
        assert!(
            run.peak_mb <= estimate && run.peak_mb >= estimate / 3.0,
            "{what}: estimated {estimate} MB, measured {} MB",
            run.peak_mb
        );
    };
    let estimate = estimate_of(&mid);
    encode_within(&mid, estimate, "500x500");
    rows.push(row(
        &dir,
        "the memory estimate against a measured encode of 500x500 noise",
        &format!("pifs encode {} -o {}", s(&mid), s(&out)),
        "peak between a third of the estimate and the estimate",
    ));

    // A colour encode holds RGB pixels beside the luma analysis: priced above the grayscale
    // one of the same size, and still bounding what it takes.
    let colour = dir.join("noise-500-rgb.png");
    image::RgbImage::from_fn(500, 500, |x, y| {
        image::Rgb([noise(x, y), noise(x + 500, y), noise(x, y + 500)])
    })
    .save(&colour)
    .unwrap();
    let colour_estimate = estimate_of(&colour);
    assert!(
        colour_estimate > estimate,
        "500x500: colour estimated {colour_estimate} MB, gray {estimate} MB"
    );
    encode_within(&colour, colour_estimate, "500x500 colour");
    let header = decoder_core::Header::read(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(header.channels, 3, "a colour stream");
    rows.push(row(
        &dir,
        "the same for 500x500 colour noise",
        &format!("pifs encode {} -o {}", s(&colour), s(&out)),
        "a colour stream; estimated above the grayscale encode, peak between a third of the \
         estimate and the estimate",
    ));
    record("encode_is_bounded_by_its_memory_budget", &rows);
}

#[test]
fn decode_writes_large_images_in_bands() {
    let dir = scratch("bands");
    let stream = synthetic(16384);
    let bytes = std::fs::read(&stream).unwrap();
    let (w, h, reference) = decoded(&bytes);
    assert_eq!((w, h), (16384, 16384));
    let mut rows = Vec::new();

    let png_path = dir.join("big.png");
    let run = measured(&[], &["decode", s(&stream), "-o", s(&png_path)]);
    ok(&run.out);
    assert!(run.peak_mb < 64.0, "PNG: {} MB", run.peak_mb);
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&png_path).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    assert_eq!((reader.info().width, reader.info().height), (w, h));
    let mut y = 0usize;
    while let Some(row_data) = reader.next_row().unwrap() {
        let want = &reference[y * w as usize..(y + 1) * w as usize];
        assert!(row_data.data() == want, "PNG row {y} differs");
        y += 1;
    }
    assert_eq!(y, h as usize);
    std::fs::remove_file(&png_path).unwrap();
    rows.push(row(
        &dir,
        "decode a 16384x16384 stream (the default --max-pixels, 2^28) to PNG",
        &format!("pifs decode {} -o {}", "DIR/16384.pifs", s(&png_path)),
        "written band by band: peak < 64 MB; every row equal to the decoder's",
    ));

    let pgm_path = dir.join("big.pgm");
    let run = measured(
        &["prlimit", "--as=200000000"],
        &["decode", s(&stream), "-o", s(&pgm_path)],
    );
    ok(&run.out);
    assert!(run.peak_mb < 64.0, "PGM: {} MB", run.peak_mb);
    let pgm = std::fs::read(&pgm_path).unwrap();
    let header = format!("P5\n{w} {h}\n255\n");
    assert!(pgm.starts_with(header.as_bytes()));
    assert!(pgm[header.len()..] == reference[..], "PGM pixels differ");
    std::fs::remove_file(&pgm_path).unwrap();
    rows.push(row(
        &dir,
        "the same to PGM, under a 200 MB address-space cap",
        &format!(
            "prlimit --as=200000000 pifs decode {} -o {}",
            "DIR/16384.pifs",
            s(&pgm_path)
        ),
        "decoded: peak < 64 MB; the pixels equal the decoder's",
    ));
    record("decode_writes_large_images_in_bands", &rows);
}

#[test]
fn decode_and_info_refuse_dev_zero_at_once() {
    let dir = scratch("zero");
    let out = dir.join("z.png");
    let mut rows = Vec::new();
    for args in [
        vec!["decode", "/dev/zero", "-o", s(&out)],
        vec!["info", "/dev/zero"],
    ] {
        let run = measured(&[], &args);
        let msg = message(&dir, &run.out);
        assert!(run.seconds < 0.1, "{args:?}: {} s", run.seconds);
        assert!(run.peak_mb < 10.0, "{args:?}: {} MB", run.peak_mb);
        assert!(!out.exists());
        rows.push(row(
            &dir,
            &format!("`pifs {}` on endless zeros", args[0]),
            &format!("pifs {}", args.join(" ")),
            &format!("refused in < 0.1 s, peak < 10 MB, after reading one byte: {msg}"),
        ));
    }
    record("decode_and_info_refuse_dev_zero_at_once", &rows);
}

#[test]
fn info_checks_limits_and_draws_no_pixels() {
    let dir = scratch("info");
    let huge = synthetic(65535);
    let run = measured(&[], &["info", s(&huge)]);
    let msg = message(&dir, &run.out).replace(&*huge.display().to_string(), "DIR/65535.pifs");
    assert!(msg.contains("--max-pixels"), "{msg}");
    assert!(run.seconds < 0.1 && run.peak_mb < 10.0);
    let mut rows = vec![row(
        &dir,
        "`pifs info` on a valid 65535x65535 stream",
        "pifs info DIR/65535.pifs",
        &format!("refused in < 0.1 s by the default --max-pixels (2^28): {msg}"),
    )];
    let big = synthetic(16384);
    let run = measured(&[], &["info", s(&big)]);
    let stdout = ok(&run.out);
    assert!(stdout.contains("16384x16384"), "{stdout}");
    assert!(run.peak_mb < 10.0, "{} MB", run.peak_mb);
    rows.push(row(
        &dir,
        "`pifs info` on a valid 16384x16384 stream",
        "pifs info DIR/16384.pifs",
        "described with peak < 10 MB: the syntax is entropy-decoded, no band of pixels drawn (only the edge pixels prediction needs)",
    ));
    record("info_checks_limits_and_draws_no_pixels", &rows);
}

fn is_char_device(path: &Path) -> bool {
    use std::os::unix::fs::FileTypeExt;
    std::fs::metadata(path)
        .map(|m| m.file_type().is_char_device())
        .unwrap_or(false)
}

#[test]
fn output_to_devices_fifos_and_links() {
    let dir = scratch("special");
    let (png, stream) = small_inputs(&dir);
    let mut rows = Vec::new();

    let out = pifs()
        .args(["encode", "--bytes", "300", s(&png), "-o", "/dev/null"])
        .output()
        .unwrap();
    ok(&out);
    assert!(is_char_device(Path::new("/dev/null")));
    rows.push(row(
        &dir,
        "`-o /dev/null` (timing an encoder)",
        &format!("pifs encode --bytes 300 {} -o /dev/null", s(&png)),
        "written through; /dev/null is still the character device",
    ));

    let out = pifs()
        .args(["encode", "--bytes", "300", s(&png), "-o", "/dev/full"])
        .output()
        .unwrap();
    let msg = message(&dir, &out);
    assert!(msg.contains("No space left on device"), "{msg}");
    assert!(is_char_device(Path::new("/dev/full")));
    rows.push(row(
        &dir,
        "`-o /dev/full`",
        &format!("pifs encode --bytes 300 {} -o /dev/full", s(&png)),
        &format!("refused with the real cause: {msg}; /dev/full is still the character device"),
    ));

    let fifo = dir.join("fifo.png");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success(), "mkfifo");
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            std::fs::File::open(fifo)
                .unwrap()
                .read_to_end(&mut bytes)
                .unwrap();
            bytes
        })
    };
    ok(&pifs()
        .args(["decode", s(&stream), "-o", s(&fifo)])
        .output()
        .unwrap());
    let got = reader.join().unwrap();
    let img = image::load_from_memory(&got).unwrap().to_luma8();
    let (_, _, want) = decoded(&std::fs::read(&stream).unwrap());
    assert_eq!(img.as_raw(), &want);
    {
        use std::os::unix::fs::FileTypeExt;
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    }
    rows.push(row(
        &dir,
        "`-o` onto a FIFO with a reader",
        &format!("pifs decode {} -o {}", s(&stream), s(&fifo)),
        "written through: the reader gets the image; the FIFO is still a FIFO",
    ));

    let real = dir.join("real.png");
    std::fs::write(&real, b"old").unwrap();
    let link = dir.join("link.png");
    std::os::unix::fs::symlink("real.png", &link).unwrap();
    ok(&pifs()
        .args(["decode", s(&stream), "-o", s(&link)])
        .output()
        .unwrap());
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(
        image::open(&real).unwrap().to_luma8().as_raw(),
        &want,
        "the link's target holds the image"
    );
    rows.push(row(
        &dir,
        "`-o` onto a symbolic link to a file",
        &format!("pifs decode {} -o {}", s(&stream), s(&link)),
        "followed: the file it points to is replaced atomically; the link stays a link",
    ));

    let dangling = dir.join("dangling.png");
    std::os::unix::fs::symlink("nowhere.png", &dangling).unwrap();
    let out = pifs()
        .args(["decode", s(&stream), "-o", s(&dangling)])
        .output()
        .unwrap();
    let msg = message(&dir, &out);
    assert!(!dir.join("nowhere.png").exists());
    rows.push(row(
        &dir,
        "`-o` onto a symbolic link to nothing",
        &format!("pifs decode {} -o {}", s(&stream), s(&dangling)),
        &format!("refused: {msg}"),
    ));
    assert!(leftovers(&dir).is_empty());
    record("output_to_devices_fifos_and_links", &rows);
}

#[test]
fn output_modes_follow_the_umask_or_the_file() {
    let dir = scratch("modes");
    let (_, stream) = small_inputs(&dir);
    let mut rows = Vec::new();
    for (umask, expected) in [("022", 0o644), ("077", 0o600), ("002", 0o664)] {
        let out = dir.join(format!("new-{umask}.png"));
        let status = Command::new("sh")
            .args(["-c", &format!("umask {umask}; exec \"$0\" \"$@\"")])
            .arg(pifs_path())
            .args(["decode", s(&stream), "-o", s(&out)])
            .stdout(Stdio::null())
            .status()
            .unwrap();
        assert!(status.success());
        assert_eq!(mode_of(&out), expected, "umask {umask}");
        rows.push(row(
            &dir,
            &format!("a new file, umask {umask}"),
            &format!("pifs decode {} -o {}", s(&stream), s(&out)),
            &format!("mode {expected:04o}"),
        ));
    }
    for mode in [0o644, 0o640, 0o600] {
        let out = dir.join(format!("old-{mode:o}.png"));
        std::fs::write(&out, b"old").unwrap();
        set_mode(&out, mode);
        ok(&pifs()
            .args(["decode", s(&stream), "-o", s(&out)])
            .output()
            .unwrap());
        assert_eq!(mode_of(&out), mode);
        assert!(image::open(&out).is_ok());
        rows.push(row(
            &dir,
            &format!("an existing {mode:04o} file overwritten"),
            &format!("pifs decode {} -o {}", s(&stream), s(&out)),
            &format!("replaced; still mode {mode:04o}"),
        ));
    }
    record("output_modes_follow_the_umask_or_the_file", &rows);
}

/// Runs `pifs args` as an unprivileged user: itself when it is not root, else user and group
/// 65534 (`nobody`) through `setpriv`.
fn as_normal_user(args: &[&str]) -> Output {
    let root = std::fs::metadata("/proc/self")
        .map(|m| std::os::unix::fs::MetadataExt::uid(&m) == 0)
        .unwrap_or(false);
    let mut cmd = if root {
        let mut c = Command::new("setpriv");
        c.args(["--reuid=65534", "--regid=65534", "--clear-groups"])
            .arg(pifs_path());
        c
    } else {
        pifs()
    };
    cmd.args(args).output().unwrap()
}

#[test]
fn output_is_checked_before_the_work() {
    let dir = scratch("early");
    let (png, _) = small_inputs(&dir);
    // An image whose analysis takes tens of seconds: a refusal in under one came first.
    let big = dir.join("noise-1024.png");
    gray_png(&big, 1024, 1024, noise);
    set_mode(&big, 0o644);
    let mut rows = Vec::new();

    let missing = dir.join("missing-dir/x.pifs");
    let start = Instant::now();
    let out = pifs()
        .args(["encode", s(&big), "-o", s(&missing)])
        .output()
        .unwrap();
    let msg = message(&dir, &out);
    assert!(start.elapsed() < Duration::from_secs(1));
    assert!(msg.contains("DIR/missing-dir/x.pifs"), "{msg}");
    rows.push(row(
        &dir,
        "`-o missing-dir/x.pifs` on an image whose analysis takes a minute",
        &format!("pifs encode {} -o {}", s(&big), s(&missing)),
        &format!("refused in < 1 s, naming the user's path: {msg}"),
    ));

    let locked = dir.join("locked");
    std::fs::create_dir(&locked).unwrap();
    set_mode(&locked, 0o555);
    let target = locked.join("x.pifs");
    let start = Instant::now();
    let out = as_normal_user(&["encode", s(&big), "-o", s(&target)]);
    let msg = message(&dir, &out);
    assert!(start.elapsed() < Duration::from_secs(1));
    assert!(
        msg.contains("Permission denied") && !msg.contains(".pifs-tmp"),
        "{msg}"
    );
    rows.push(row(
        &dir,
        "`-o` into a directory the user cannot write, as a normal user",
        &format!("pifs encode {} -o {}", s(&big), s(&target)),
        &format!("refused in < 1 s, naming the user's path, not a temporary file: {msg}"),
    ));

    let out = as_normal_user(&["encode", "--bytes", "300", s(&png), "-o", "/dev/full"]);
    let msg = message(&dir, &out);
    assert!(msg.contains("No space left on device"), "{msg}");
    rows.push(row(
        &dir,
        "`-o /dev/full` as a normal user",
        &format!("pifs encode --bytes 300 {} -o /dev/full", s(&png)),
        &format!("refused with the real cause: {msg}"),
    ));
    record("output_is_checked_before_the_work", &rows);
}

/// Starts `pifs decode stream -o out` (with named temporary files when `named`).
fn start_decode(stream: &Path, out: &Path, named: bool) -> std::process::Child {
    let mut cmd = pifs();
    cmd.args(["decode", s(stream), "-o", s(out)])
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    if named {
        cmd.env("PIFS_NAMED_TEMPORARY_FILES", "1");
    }
    cmd.spawn().unwrap()
}

fn signal(child: &std::process::Child, name: &str) {
    let ok = Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
}

#[test]
fn no_litter_when_interrupted() {
    let dir = scratch("litter");
    // Long enough to be killed while it runs, on a fast machine too: 134 megapixels of 8 px
    // leaves, over a second (large flat leaves decoded in about as long as the watch below).
    let stream = dir.join("large.pifs");
    let bytes = host_encoder::internal::synthetic_stream(16384, 8192, 3, |node, leaf| {
        leaf.control[0] = (((node.x + node.y) / 128) % 5) as i16 - 2;
        leaf.control[1] = ((node.x * 7 + node.y * 13) % 9) as i16 - 4;
    })
    .unwrap();
    std::fs::write(&stream, bytes).unwrap();
    let mut rows = Vec::new();

    // Unnamed temporary file: nothing appears beside the output at any moment.
    let out = dir.join("killed.png");
    let mut child = start_decode(&stream, &out, false);
    // Watched for a moment well short of the decode, then killed.
    let until = Instant::now() + Duration::from_millis(300);
    while Instant::now() < until {
        assert!(leftovers(&dir).is_empty(), "a named file beside the output");
        assert!(!out.exists(), "the output appeared before the decode ended");
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(child.try_wait().unwrap().is_none(), "ended before the kill");
    signal(&child, "KILL");
    child.wait().unwrap();
    assert!(leftovers(&dir).is_empty() && !out.exists());
    rows.push(row(
        &dir,
        "SIGKILL while the output is written",
        &format!("pifs decode DIR/large.pifs -o {}", s(&out)),
        "no file beside the output at any moment, none after: the temporary file has no name (O_TMPFILE) until it is complete",
    ));

    // Named temporary files (other systems): SIGTERM and SIGINT remove them.
    for (name, code) in [("TERM", 143), ("INT", 130)] {
        let out = dir.join(format!("{name}.png"));
        let mut child = start_decode(&stream, &out, true);
        let until = Instant::now() + Duration::from_secs(20);
        while leftovers(&dir).is_empty() {
            assert!(Instant::now() < until, "no temporary file appeared");
            assert!(child.try_wait().unwrap().is_none(), "ended early");
            std::thread::sleep(Duration::from_millis(5));
        }
        signal(&child, name);
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(code), "SIG{name}");
        assert!(leftovers(&dir).is_empty() && !out.exists(), "SIG{name}");
        rows.push(row(
            &dir,
            &format!("SIG{name} while a named temporary file is written (`PIFS_NAMED_TEMPORARY_FILES=1`, as on systems without O_TMPFILE)"),
            &format!("pifs decode DIR/large.pifs -o {}", s(&out)),
            &format!("exit {code}; the temporary file removed, no output"),
        ));
    }
    record("no_litter_when_interrupted", &rows);
}

/// Runs `pifs args` with its standard input a pipe fed by `cat files...`.
fn piped(files: &[&str], args: &[&str]) -> Output {
    let mut cat = Command::new("cat")
        .args(files)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let pipe = cat.stdout.take().unwrap();
    let out = pifs().args(args).stdin(Stdio::from(pipe)).output().unwrap();
    let _ = cat.kill();
    let _ = cat.wait();
    out
}

#[test]
fn pipes_carry_streams_and_images() {
    let dir = scratch("pipes");
    let (png, stream) = small_inputs(&dir);
    let reference = std::fs::read(&stream).unwrap();
    let (w, h, pixels) = decoded(&reference);
    let mut rows = Vec::new();

    let out = piped(&[s(&png)], &["encode", "--bytes", "300", "-", "-o", "-"]);
    ok(&out);
    assert_eq!(out.stdout.first(), Some(&decoder_core::STREAM_TAG));
    assert_eq!(decoded(&out.stdout).2.len(), pixels.len());
    assert!(String::from_utf8_lossy(&out.stderr).contains("standard output: 64x48"));
    rows.push(row(
        &dir,
        "encode from a pipe to a pipe",
        &format!("cat {} \\| pifs encode --bytes 300 - -o -", s(&png)),
        "the stream on standard output, the status line on standard error",
    ));

    let file = dir.join("from-stdin.pifs");
    ok(&piped(
        &[s(&png)],
        &["encode", "--bytes", "300", "/dev/stdin", "-o", s(&file)],
    ));
    decoded(&std::fs::read(&file).unwrap());
    rows.push(row(
        &dir,
        "encode from `/dev/stdin` fed by a pipe",
        &format!(
            "cat {} \\| pifs encode --bytes 300 /dev/stdin -o {}",
            s(&png),
            s(&file)
        ),
        "encoded",
    ));

    let out = piped(&[s(&stream)], &["decode", "-", "-o", "-"]);
    ok(&out);
    let img = image::load_from_memory(&out.stdout).unwrap().to_luma8();
    assert_eq!((img.width(), img.height()), (w, h));
    assert_eq!(img.as_raw(), &pixels);
    rows.push(row(
        &dir,
        "decode from a pipe to a pipe",
        &format!("cat {} \\| pifs decode - -o -", s(&stream)),
        "a PNG on standard output, equal to the decoder's pixels",
    ));

    let out = piped(
        &[s(&stream)],
        &["decode", "-", "-o", "-", "--format", "pgm"],
    );
    ok(&out);
    assert!(out.stdout.starts_with(b"P5\n64 48\n255\n"));
    assert!(out.stdout.ends_with(&pixels));
    rows.push(row(
        &dir,
        "the same as PGM",
        &format!("cat {} \\| pifs decode - -o - --format pgm", s(&stream)),
        "a PGM on standard output, equal to the decoder's pixels",
    ));

    let out = piped(&[s(&stream)], &["info", "-"]);
    assert!(ok(&out).contains("64x48"));
    rows.push(row(
        &dir,
        "describe a stream from a pipe",
        &format!("cat {} \\| pifs info -", s(&stream)),
        "described",
    ));

    let target = dir.join("z.png");
    let start = Instant::now();
    let out = piped(
        &[s(&stream), "/dev/zero"],
        &["decode", "-", "-o", s(&target)],
    );
    let msg = message(&dir, &out);
    assert!(start.elapsed() < Duration::from_secs(1));
    assert!(!target.exists());
    rows.push(row(
        &dir,
        "a stream followed by endless zeros on a pipe",
        &format!(
            "cat {} /dev/zero \\| pifs decode - -o {}",
            s(&stream),
            s(&target)
        ),
        &format!("refused at once, reading no more than the stream and one byte: {msg}"),
    ));
    record("pipes_carry_streams_and_images", &rows);
}

/// A JPEG of `img` whose EXIF says `orientation`.
fn jpeg_with_orientation(img: &image::GrayImage, orientation: u16) -> Vec<u8> {
    let mut jpeg = Vec::new();
    image::DynamicImage::ImageLuma8(img.clone())
        .write_to(
            &mut std::io::Cursor::new(&mut jpeg),
            image::ImageFormat::Jpeg,
        )
        .unwrap();
    // APP1: "Exif\0\0", a big-endian TIFF header, one IFD holding Orientation (0x0112).
    let mut tiff = b"MM\0\x2a\0\0\0\x08".to_vec();
    tiff.extend_from_slice(&1u16.to_be_bytes());
    tiff.extend_from_slice(&0x0112u16.to_be_bytes());
    tiff.extend_from_slice(&3u16.to_be_bytes());
    tiff.extend_from_slice(&1u32.to_be_bytes());
    tiff.extend_from_slice(&orientation.to_be_bytes());
    tiff.extend_from_slice(&[0, 0]);
    tiff.extend_from_slice(&0u32.to_be_bytes());
    let mut body = b"Exif\0\0".to_vec();
    body.extend_from_slice(&tiff);
    let mut app1 = vec![0xFF, 0xE1];
    app1.extend_from_slice(&((body.len() + 2) as u16).to_be_bytes());
    app1.extend_from_slice(&body);
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&app1);
    out.extend_from_slice(&jpeg[2..]);
    out
}

fn psnr(a: &[u8], b: &[u8]) -> f64 {
    let mse = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2))
        .sum::<f64>()
        / a.len() as f64;
    10.0 * (255.0f64 * 255.0 / mse.max(1e-9)).log10()
}

#[test]
fn exif_orientation_is_applied() {
    let dir = scratch("exif");
    // Dark on the left, bright on the right, a bar at the top: any turn shows.
    let img = image::GrayImage::from_fn(64, 48, |x, y| {
        image::Luma([(x * 3 + if y < 8 { 60 } else { 0 }) as u8])
    });
    let mut rows = Vec::new();
    for (orientation, turned) in [(6u16, "a quarter turn clockwise"), (3, "a half turn")] {
        let path = dir.join(format!("phone-{orientation}.jpg"));
        std::fs::write(&path, jpeg_with_orientation(&img, orientation)).unwrap();
        let stored = image::open(&path).unwrap().to_luma8();
        let shown = match orientation {
            6 => image::imageops::rotate90(&stored),
            _ => image::imageops::rotate180(&stored),
        };
        let out = dir.join(format!("phone-{orientation}.pifs"));
        ok(&pifs()
            .args(["encode", "--bpp", "2", s(&path), "-o", s(&out)])
            .output()
            .unwrap());
        let (w, h, px) = decoded(&std::fs::read(&out).unwrap());
        assert_eq!((w, h), shown.dimensions(), "orientation {orientation}");
        let as_shown = psnr(&px, shown.as_raw());
        let as_stored = if shown.dimensions() == stored.dimensions() {
            psnr(&px, stored.as_raw())
        } else {
            0.0
        };
        assert!(
            as_shown > as_stored + 10.0,
            "orientation {orientation}: {as_shown} dB as shown, {as_stored} dB as stored"
        );
        rows.push(row(
            &dir,
            &format!("phone JPEG with EXIF orientation {orientation} ({turned})"),
            &format!("pifs encode --bpp 2 {} -o {}", s(&path), s(&out)),
            &format!(
                "encoded as shown: a {w}x{h} stream whose PSNR against the picture as shown is over 10 dB above that against the stored pixels"
            ),
        ));
    }
    record("exif_orientation_is_applied", &rows);
}

#[test]
fn multi_page_tiff_notes_its_first_page() {
    let dir = scratch("tiff");
    let path = dir.join("pages.tiff");
    {
        use tiff::encoder::{colortype, TiffEncoder};
        let file = std::fs::File::create(&path).unwrap();
        let mut tiff = TiffEncoder::new(file).unwrap();
        let first: Vec<u8> = (0..40 * 30).map(|i| (i % 200) as u8).collect();
        let second = vec![7u8; 20 * 10];
        tiff.write_image::<colortype::Gray8>(40, 30, &first)
            .unwrap();
        tiff.write_image::<colortype::Gray8>(20, 10, &second)
            .unwrap();
    }
    let what = ("a TIFF of two pages (40x30, then 20x10)", "page");
    let rows = [first_of_several(&dir, &path, what)];
    record("multi_page_tiff_notes_its_first_page", &rows);
}

#[test]
fn animated_gif_notes_its_first_frame() {
    let dir = scratch("gif");
    let path = dir.join("frames.gif");
    {
        let file = std::fs::File::create(&path).unwrap();
        let palette: Vec<u8> = (0..=255u8).flat_map(|v| [v, v, v]).collect();
        let mut gif = gif::Encoder::new(file, 40, 30, &palette).unwrap();
        for shade in [0u8, 90] {
            let pixels: Vec<u8> = (0..40 * 30).map(|i| shade + (i % 120) as u8).collect();
            gif.write_frame(&gif::Frame::from_indexed_pixels(40, 30, pixels, None))
                .unwrap();
        }
    }
    let what = ("an animated GIF of two frames (40x30)", "frame");
    let rows = [first_of_several(&dir, &path, what)];
    record("animated_gif_notes_its_first_frame", &rows);
}

/// Encodes `path`, a file of two images of which the first is 40x30 (`what`: how the row
/// names the file, and what an image of it is called), and checks that the first was encoded
/// with a note saying so; the row of the table.
fn first_of_several(dir: &Path, path: &Path, (file, image): (&str, &str)) -> String {
    let out = path.with_extension("pifs");
    let stdout = ok(&pifs()
        .args(["encode", "--bytes", "300", s(path), "-o", s(&out)])
        .output()
        .unwrap());
    let note = stdout
        .lines()
        .find(|l| l.contains("note:"))
        .expect("a note")
        .replace(&*dir.to_string_lossy(), "DIR");
    let name = path.file_name().unwrap().to_string_lossy();
    assert_eq!(
        note,
        format!("DIR/{name}: note: 2 {image}s; encoding the first")
    );
    let (w, h, _) = decoded(&std::fs::read(&out).unwrap());
    assert_eq!((w, h), (40, 30));
    row(
        dir,
        file,
        &format!("pifs encode --bytes 300 {} -o {}", s(path), s(&out)),
        &format!(
            "the first {image} encoded (a 40x30 stream), with a note on standard output: `{note}`"
        ),
    )
}

#[test]
fn target_messages_say_what_to_ask_for() {
    let dir = scratch("targets");
    let (png, _) = small_inputs(&dir);
    let tiny = dir.join("3x3.png");
    gray_png(&tiny, 3, 3, |x, y| (x * 80 + y * 20) as u8);
    // Its nodes settle (a bilinear patch within half a grey level squared): not lossless.
    let slope = dir.join("slope.png");
    gray_png(&slope, 64, 64, |x, y| {
        (60 + x + y / 2 + ((x ^ y) & 1)) as u8
    });
    let out = dir.join("t.pifs");
    let mut rows = Vec::new();
    for (tried, args) in [
        (
            "`--bpp 1e-300`",
            vec!["encode", s(&png), "-o", s(&out), "--bpp", "1e-300"],
        ),
        (
            "`--psnr 1e300`",
            vec!["encode", s(&slope), "-o", s(&out), "--psnr", "1e300"],
        ),
        (
            "3x3 image at `--bpp 1`",
            vec!["encode", s(&tiny), "-o", s(&out), "--bpp", "1"],
        ),
        (
            "a budget above a header's but below the smallest stream",
            vec!["encode", s(&png), "-o", s(&out), "--bytes", "12"],
        ),
    ] {
        let result = pifs().args(&args).output().unwrap();
        let msg = message(&dir, &result);
        assert!(msg.len() < 250, "{msg}");
        assert!(
            msg.contains(" or more") || msg.contains("ask for less"),
            "{msg}"
        );
        assert!(!out.exists());
        rows.push(row(
            &dir,
            tried,
            &format!("pifs {}", args.join(" ")),
            &format!("refused, saying what to ask for: {msg}"),
        ));
    }
    record("target_messages_say_what_to_ask_for", &rows);
}
