//! The `pifs` command line: a round trip through files. Malformed inputs are in
//! `robustness_table.rs`.

#[path = "common/scratch.rs"]
mod scratch;

use scratch::Scratch;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn pifs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pifs"))
        .args(args)
        .output()
        .expect("pifs runs")
}

/// `pifs ARGS` with `input` on its standard input.
fn pifs_with_stdin(args: &[&str], input: &[u8]) -> Output {
    use std::io::Write;
    let mut child = Command::new(env!("CARGO_BIN_EXE_pifs"))
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("pifs runs");
    let mut stdin = child.stdin.take().expect("a pipe");
    // A refusal may come before the input is read: a broken pipe then is no failure.
    let _ = stdin.write_all(input);
    drop(stdin);
    child.wait_with_output().expect("pifs ends")
}

fn scratch(name: &str) -> Scratch {
    Scratch::new(&format!("cli-{name}"))
}

/// A 40x24 test image with a gradient and an edge.
fn write_png(path: &Path) {
    let img = image::GrayImage::from_fn(40, 24, |x, y| {
        image::Luma([(x * 5 + y * 3 + if x > 20 { 60 } else { 0 }) as u8])
    });
    img.save(path).unwrap();
}

#[test]
fn encode_decode_info_round_trip() {
    let dir = scratch("roundtrip");
    let png = dir.join("in.png");
    write_png(&png);
    let stream = dir.join("out.pifs");
    let out = pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        stream.to_str().unwrap(),
        "--bytes",
        "200",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let size = std::fs::metadata(&stream).unwrap().len();
    assert!(size <= 200 && size > 13, "size {size}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("PSNR") && stdout.contains("bpp"),
        "{stdout}"
    );

    let decoded = dir.join("out.pgm");
    let out = pifs(&[
        "decode",
        stream.to_str().unwrap(),
        "-o",
        decoded.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&decoded).unwrap().to_luma8();
    assert_eq!(img.dimensions(), (40, 24));
    let mut expected = vec![0u8; 40 * 24];
    let bytes = std::fs::read(&stream).unwrap();
    decoder_core::Decoder::new(&bytes)
        .and_then(|d| d.decode_into(&mut expected))
        .unwrap();
    assert_eq!(img.as_raw(), &expected);

    let out = pifs(&["info", stream.to_str().unwrap()]);
    assert!(out.status.success());
    let info = String::from_utf8_lossy(&out.stdout);
    assert!(
        info.contains("40x24") && info.contains("leaves") && info.contains("pixel grids"),
        "{info}"
    );
}

/// A textured test image: waves, an edge and a little deterministic noise.
fn textured(w: u32, h: u32) -> image::GrayImage {
    image::GrayImage::from_fn(w, h, |x, y| {
        let wave = 60.0 * ((x as f64) * 0.45).sin() * ((y as f64) * 0.3).cos();
        let edge = if x + y > (w + h) / 2 { 50.0 } else { 0.0 };
        let noise = ((x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(2_246_822_519)) >> 27) as f64;
        image::Luma([(100.0 + wave + edge + noise).clamp(0.0, 255.0) as u8])
    })
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

/// The standard output of a command that succeeded.
fn ok_bytes(out: &Output) -> Vec<u8> {
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout.clone()
}

/// The one line a refused command prints on stderr, after checking it is one line and the
/// exit is non-zero.
fn refused(out: &Output) -> String {
    assert!(
        !out.status.success(),
        "accepted: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr:?}");
    assert!(stderr.starts_with("pifs: "), "{stderr:?}");
    stderr.trim_end().to_string()
}

/// The pixels the decoder makes of the stream at `path` (as a host decodes: stripes of any
/// width).
fn decoded(path: &Path) -> (u32, u32, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let decoder = decoder_core::Decoder::new(&bytes)
        .unwrap()
        .stripe_capacity::<65536>();
    let (w, h) = (decoder.header().width, decoder.header().height);
    let channels = usize::from(decoder.header().channels);
    let mut px = vec![0u8; decoder.header().pixel_count() * channels];
    decoder.decode_into(&mut px).unwrap();
    (u32::from(w), u32::from(h), px)
}

/// The PSNR figure of an encode's line ("PSNR 31.20 dB").
fn psnr_of(stdout: &str) -> f64 {
    let at = stdout.find("PSNR ").expect("a PSNR figure") + 5;
    stdout[at..]
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn images_of_any_size_encode_with_the_default_target() {
    let dir = scratch("tiny");
    for (w, h) in [(1, 1), (7, 1), (13, 9)] {
        let png = dir.join(format!("{w}x{h}.png"));
        textured(w, h).save(&png).unwrap();
        let stream = dir.join(format!("{w}x{h}.pifs"));
        let out = pifs(&[
            "encode",
            png.to_str().unwrap(),
            "-o",
            stream.to_str().unwrap(),
        ]);
        let stdout = ok(&out);
        // Too small for the default rate: the smallest stream, and the line says so.
        assert!(stdout.contains("wrote the smallest"), "{w}x{h}: {stdout}");
        assert!(
            out.stderr.is_empty(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let back = dir.join(format!("{w}x{h}-back.png"));
        ok(&pifs(&[
            "decode",
            stream.to_str().unwrap(),
            "-o",
            back.to_str().unwrap(),
        ]));
        let img = image::open(&back).unwrap().to_luma8();
        let (dw, dh, px) = decoded(&stream);
        assert_eq!((img.width(), img.height()), (w, h));
        assert_eq!((dw, dh), (w, h));
        assert_eq!(img.as_raw(), &px);
    }
    // An explicit rate is a hard budget, however small the image.
    let png = dir.join("13x9.png");
    let stream = dir.join("hard.pifs");
    let line = refused(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        stream.to_str().unwrap(),
        "--bpp",
        "0.25",
    ]));
    assert!(
        line.contains("--bpp 0.25 allows 3 bytes for this 13x9 image"),
        "{line}"
    );
    assert!(!stream.exists());
}

#[test]
fn a_stream_too_wide_for_the_default_decoder_is_named_at_encode() {
    let dir = scratch("wide");
    let png = dir.join("wide.png");
    textured(640, 24).save(&png).unwrap();
    let whole = dir.join("whole.pifs");
    let stdout = ok(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        whole.to_str().unwrap(),
        "--bpp",
        "1",
    ]));
    assert!(
        stdout.contains("note: stripes of 640 px, wider than the 512 columns")
            && stdout.contains("--stripe-width 512"),
        "{stdout}"
    );
    // The note is true: decoder-core's default decoder refuses the stream.
    let bytes = std::fs::read(&whole).unwrap();
    let err = decoder_core::Decoder::new(&bytes[..])
        .unwrap()
        .decode_into(&mut vec![0u8; 640 * 24])
        .unwrap_err();
    assert!(
        matches!(err, decoder_core::DecodeError::StripeTooWide { .. }),
        "{err:?}"
    );
    // Coded in stripes of 512 it decodes there, and no note is printed.
    let narrow = dir.join("narrow.pifs");
    let stdout = ok(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        narrow.to_str().unwrap(),
        "--bpp",
        "1",
        "--stripe-width",
        "512",
    ]));
    assert!(!stdout.contains("note:"), "{stdout}");
    let bytes = std::fs::read(&narrow).unwrap();
    decoder_core::Decoder::new(&bytes[..])
        .unwrap()
        .decode_into(&mut vec![0u8; 640 * 24])
        .unwrap();
}

#[test]
fn the_best_psnr_reported_is_reached() {
    let dir = scratch("psnr");
    let png = dir.join("tex.png");
    // A gentle slope under a one-level checkerboard: nodes whose bilinear patch reproduces them
    // within half a grey level squared settle, so the best stream is not lossless (the
    // textured image is, with the finest steps).
    image::GrayImage::from_fn(48, 40, |x, y| {
        image::Luma([(60 + x + y / 2 + ((x ^ y) & 1)) as u8])
    })
    .save(&png)
    .unwrap();
    let out_path = dir.join("q.pifs");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "encode",
            png.to_str().unwrap(),
            "-o",
            out_path.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        pifs(&args)
    };
    let line = refused(&run(&["--psnr", "150"]));
    assert!(!out_path.exists(), "a refused encode wrote its output");
    let marker = "the best this encoder reaches is ";
    let at = line.find(marker).expect(&line) + marker.len();
    let best: f64 = line[at..].trim_end_matches(" dB").parse().expect(&line);
    assert!(best > 30.0 && best < 150.0, "{line}");
    // The figure shown is reached, and anything below it.
    for target in [best, best - 0.01] {
        let stdout = ok(&run(&["--psnr", &format!("{target:.2}")]));
        assert!(psnr_of(&stdout) >= target, "--psnr {target}: {stdout}");
    }
    // No other target writes a better stream: the largest budget reaches the same (shown
    // rounded to nearest, where the refusal rounds down: at most 0.01 dB apart).
    let stdout = ok(&run(&["--bytes", "10000000"]));
    let top = psnr_of(&stdout);
    assert!(
        top <= best + 0.01 + 1e-9,
        "--bytes reaches {top} dB, above the best reported {best}"
    );
    let stdout = ok(&run(&["--bpp", "100"]));
    assert!(psnr_of(&stdout) <= best + 0.01 + 1e-9, "{stdout}");
}

/// The finest control steps (16 and 12, 1/16 grey) code a pixel grid's values to within half a
/// grey level: the highest quality target makes a textured 8-bit image lossless, and so does
/// `--max-error 0`.
#[test]
fn the_highest_quality_is_lossless() {
    let dir = scratch("lossless");
    let png = dir.join("tex.png");
    let image = textured(48, 40);
    image.save(&png).unwrap();
    for (target, said) in [
        (["--psnr", "150"], "PSNR inf dB"),
        (["--max-error", "0"], "largest error 0"),
    ] {
        let out_path = dir.join("top.pifs");
        let mut args = vec![
            "encode",
            png.to_str().unwrap(),
            "-o",
            out_path.to_str().unwrap(),
        ];
        args.extend(target);
        let line = ok(&pifs(&args));
        assert!(line.contains(said), "{target:?}: {line}");
        let bytes = std::fs::read(&out_path).unwrap();
        let mut decoded = vec![0u8; 48 * 40];
        decoder_core::Decoder::new(&bytes)
            .and_then(|d| d.decode_into(&mut decoded))
            .unwrap();
        assert_eq!(decoded, image.as_raw().as_slice(), "{target:?}");
    }
    let line = refused(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "--max-error=-1",
        "-o",
        dir.join("none.pifs").to_str().unwrap(),
    ]));
    assert!(line.contains("from 0 (lossless) up"), "{line}");
}

#[test]
fn output_names_must_fit_what_is_written() {
    let dir = scratch("names");
    let png = dir.join("in.png");
    write_png(&png);
    let image_name = dir.join("out.png");
    let line = refused(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        image_name.to_str().unwrap(),
    ]));
    assert_eq!(
        line,
        format!(
            "pifs: refusing to write a PIFS stream into {}: use a .pifs name",
            image_name.display()
        )
    );
    assert!(!image_name.exists());
    // Any other name is a stream's.
    let stream = dir.join("payload.bin");
    ok(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        stream.to_str().unwrap(),
        "--bytes",
        "150",
    ]));
    // Decode: the extension chooses the format; none or an unknown one is refused, with the
    // list, before anything is read.
    for name in ["decoded", "decoded.", "decoded.jpg"] {
        let out = dir.join(name);
        let line = refused(&pifs(&[
            "decode",
            "/nonexistent/stream.pifs",
            "-o",
            out.to_str().unwrap(),
        ]));
        assert!(line.contains("(use .png, .pgm, .pnm or .ppm)"), "{line}");
        assert!(line.contains(out.to_str().unwrap()), "{line}");
        assert!(!out.exists());
    }
    let (w, h, px) = decoded(&stream);
    for (name, magic) in [
        ("d.png", &b"\x89PNG"[..]),
        ("d.pgm", b"P5"),
        ("d.pnm", b"P5"),
        ("d.ppm", b"P6"),
    ] {
        let out = dir.join(name);
        ok(&pifs(&[
            "decode",
            stream.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]));
        let bytes = std::fs::read(&out).unwrap();
        assert!(bytes.starts_with(magic), "{name}");
        let img = image::load_from_memory(&bytes).unwrap().to_luma8();
        assert_eq!((img.width(), img.height()), (w, h));
        assert_eq!(img.as_raw(), &px, "{name}");
    }
}

/// Standard base64 decoding (no line breaks), for the image an SVG embeds.
fn unbase64(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let mut out = Vec::new();
    for chunk in text.as_bytes().chunks(4) {
        let digits: Vec<u8> = chunk
            .iter()
            .copied()
            .filter(|&c| c != b'=')
            .map(value)
            .collect();
        let n = digits
            .iter()
            .enumerate()
            .fold(0u32, |n, (i, &d)| n | (u32::from(d) << (18 - 6 * i)));
        out.extend_from_slice(&n.to_be_bytes()[1..digits.len()]);
    }
    out
}

#[test]
fn info_draws_every_leaf_over_the_decoded_image() {
    let dir = scratch("svg");
    let png = dir.join("tex.png");
    textured(40, 24).save(&png).unwrap();
    let stream = dir.join("tex.pifs");
    ok(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        stream.to_str().unwrap(),
        "--bpp",
        "2",
    ]));
    let plain = ok(&pifs(&["info", stream.to_str().unwrap()]));
    let svg_path = dir.join("leaves.svg");
    let with_svg = ok(&pifs(&[
        "info",
        stream.to_str().unwrap(),
        "--svg",
        svg_path.to_str().unwrap(),
    ]));
    // The same figures, plus where the drawing is.
    assert!(with_svg.starts_with(&plain), "{plain}\n---\n{with_svg}");
    assert!(with_svg.contains("leaves.svg"));
    let leaves: usize = plain
        .lines()
        .find_map(|l| l.trim().strip_prefix("leaves"))
        .and_then(|n| n.trim().parse().ok())
        .expect("a leaf count");
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("class=\"leaf\"").count(), leaves);
    assert!(leaves > 1, "a quadtree worth drawing");
    // Each model in the legend, and the leaves' colours are the legend's.
    for name in ["2x2 bilinear", "3x3/2x2", "5x5/2x2", "9x9/4x4"] {
        assert!(svg.contains(name), "{name}");
    }
    let marker = "data:image/png;base64,";
    let at = svg.find(marker).unwrap() + marker.len();
    let end = at + svg[at..].find('"').unwrap();
    let embedded = image::load_from_memory(&unbase64(&svg[at..end]))
        .unwrap()
        .to_luma8();
    let (w, h, px) = decoded(&stream);
    assert_eq!((embedded.width(), embedded.height()), (w, h));
    assert_eq!(embedded.as_raw(), &px);
    // An image name for the drawing is refused.
    let line = refused(&pifs(&[
        "info",
        stream.to_str().unwrap(),
        "--svg",
        dir.join("l.png").to_str().unwrap(),
    ]));
    assert!(line.contains("use a .svg name"), "{line}");
}

#[test]
fn rd_prints_writes_and_draws_the_curve_from_one_analysis() {
    let dir = scratch("rd");
    let png = dir.join("tex.png");
    textured(48, 32).save(&png).unwrap();
    let anchors = dir.join("anchors.csv");
    std::fs::write(
        &anchors,
        "set,image,width,height,codec,target_bpp,status,param,bytes,bpp,psnr,psnr_interp,enc_s,dec_s,n_encodes,note\n\
         t,tex.png,48,32,jpeg,0.5,ok,q=10,96,0.5,24.5,24.5,0.01,0.01,5,\n\
         t,tex.png,48,32,jpeg,1,ok,q=30,190,0.99,28.25,28.3,0.01,0.01,5,\n\
         t,tex.png,48,32,jpeg,0.25,unreachable,q=1,120,0.625,,,,,1,\"lowest setting, too big\"\n\
         t,other.png,48,32,webp,1,ok,q=30,190,0.99,99.5,28.3,0.01,0.01,5,\n",
    )
    .unwrap();
    let (csv, svg, streams) = (dir.join("rd.csv"), dir.join("rd.svg"), dir.join("streams"));
    let stdout = ok(&pifs(&[
        "rd",
        png.to_str().unwrap(),
        "--rates",
        "0.5,1,2",
        "--csv",
        csv.to_str().unwrap(),
        "--plot",
        svg.to_str().unwrap(),
        "--compare",
        anchors.to_str().unwrap(),
        "--out-dir",
        streams.to_str().unwrap(),
    ]));
    assert!(stdout.contains("one analysis"), "{stdout}");
    // The CSV: a header, then one row per rate, each a stream that was written.
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("codec,bpp,psnr,bytes"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 3, "{text}");
    let mut last_psnr = 0.0;
    for (row, rate) in rows.iter().zip(["0.5", "1", "2"]) {
        assert_eq!(row[0], "pifs");
        let (bpp, psnr, bytes): (f64, f64, usize) = (
            row[1].parse().unwrap(),
            row[2].parse().unwrap(),
            row[3].parse().unwrap(),
        );
        assert!(bpp <= rate.parse::<f64>().unwrap() + 1e-9, "{row:?}");
        assert!(psnr > last_psnr, "PSNR grows with the rate: {text}");
        last_psnr = psnr;
        let stream = streams.join(format!("tex-{rate}bpp.pifs"));
        assert_eq!(std::fs::metadata(&stream).unwrap().len() as usize, bytes);
        // The table shows the same figures.
        assert!(stdout.contains(&format!("{psnr:.2}")), "{stdout}");
        let (w, h, _) = decoded(&stream);
        assert_eq!((w, h), (48, 32));
    }
    // The plot: our curve and this image's other codec (not the other image's), with a
    // marker per point (3 of ours, 2 of jpeg's ok rows).
    let drawing = std::fs::read_to_string(&svg).unwrap();
    assert!(drawing.starts_with("<svg"));
    let texts: Vec<&str> = drawing.lines().map(str::trim).collect();
    assert!(texts.contains(&"pifs") && texts.contains(&"jpeg"), "legend");
    assert!(!drawing.contains("webp"));
    assert_eq!(drawing.matches("<circle").count(), 5);
    // --compare needs --plot; a CSV without the columns is refused before the analysis.
    refused(&pifs(&[
        "rd",
        png.to_str().unwrap(),
        "--compare",
        anchors.to_str().unwrap(),
    ]));
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "name,rate\nx,1\n").unwrap();
    let line = refused(&pifs(&[
        "rd",
        png.to_str().unwrap(),
        "--plot",
        dir.join("x.svg").to_str().unwrap(),
        "--compare",
        bad.to_str().unwrap(),
    ]));
    assert!(
        line.contains("bad.csv") && line.contains("'codec'"),
        "{line}"
    );
    assert!(!dir.join("x.svg").exists());
}

/// Files and directories under `dir`, recursively, with their sizes.
fn listing(dir: &Path) -> Vec<(PathBuf, u64)> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return out;
    };
    for e in entries.flatten() {
        let path = e.path();
        if path.is_dir() {
            out.push((path.clone(), 0));
            out.extend(listing(&path));
        } else {
            out.push((path.clone(), e.metadata().map(|m| m.len()).unwrap_or(0)));
        }
    }
    out.sort();
    out
}

#[test]
fn the_demo_runs_from_any_directory_and_writes_only_there() {
    let dir = scratch("demo");
    let home = dir.join("home");
    let cwd = dir.join("work");
    std::fs::create_dir_all(&home).unwrap();
    std::fs::create_dir_all(&cwd).unwrap();
    // The source tree's demo and output directories, before.
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let root = manifest.parent().unwrap();
    let watched = [
        root.join("pifs-demo"),
        root.join("out"),
        manifest.join("pifs-demo"),
        manifest.join("out"),
    ];
    let before: Vec<_> = watched.iter().map(|d| listing(d)).collect();
    let out = Command::new(env!("CARGO_BIN_EXE_pifs"))
        .current_dir(&cwd)
        .env("HOME", &home)
        .env("TMPDIR", &home)
        .output()
        .expect("pifs runs");
    let stdout = ok(&out);
    assert!(stdout.contains("pifs-demo"), "{stdout}");
    let after: Vec<_> = watched.iter().map(|d| listing(d)).collect();
    assert_eq!(before, after, "the demo wrote into the source tree");
    assert!(listing(&home).is_empty(), "{:?}", listing(&home));
    // Only ./pifs-demo/, with a stream and its decoded image per rate.
    let top: Vec<_> = std::fs::read_dir(&cwd)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(top, ["pifs-demo"]);
    for bpp in ["0.05", "0.1", "0.25"] {
        let stream = cwd.join(format!("pifs-demo/kodim23-{bpp}bpp.pifs"));
        let size = std::fs::metadata(&stream).unwrap().len() as f64;
        assert!(size * 8.0 <= bpp.parse::<f64>().unwrap() * 768.0 * 512.0);
        // The sample is colour: the stream and its PNG are RGB.
        let (w, h, px) = decoded(&stream);
        assert_eq!(px.len(), 3 * w as usize * h as usize, "a colour stream");
        let img = image::open(stream.with_extension("png")).unwrap().to_rgb8();
        assert_eq!((img.width(), img.height()), (w, h));
        assert_eq!(img.as_raw(), &px);
    }
    assert_eq!(listing(&cwd.join("pifs-demo")).len(), 6);
    // `pifs demo` is the same command.
    let help = ok(&pifs(&["demo", "--help"]));
    assert!(help.contains("pifs-demo"), "{help}");
}

/// A 48x32 colour test image: a gradient in each channel.
fn colour_gradient() -> image::RgbImage {
    image::RgbImage::from_fn(48, 32, |x, y| {
        image::Rgb([(x * 5) as u8, (y * 7) as u8, (200 - x * 2 - y) as u8])
    })
}

/// A gray (`textured`) and a colour (`colour_gradient`) PNG in `dir`.
fn gray_and_colour(dir: &Path) -> (PathBuf, PathBuf) {
    let (gray, colour) = (dir.join("gray.png"), dir.join("colour.png"));
    textured(40, 24).save(&gray).unwrap();
    colour_gradient().save(&colour).unwrap();
    (gray, colour)
}

/// A colour PNG gives a colour stream (`info` says so) that decodes to a colour PNG and PPM
/// close to the input; `--gray` gives a grayscale stream of the same image.
#[test]
fn colour_images_stay_colour_unless_gray() {
    let dir = scratch("colour");
    let png = dir.join("in.png");
    let img = colour_gradient();
    img.save(&png).unwrap();
    let run = |args: &[&str]| {
        let out = pifs(args);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let colour = dir.join("colour.pifs");
    let said = run(&["encode", &s(&png), "-o", &s(&colour), "--bpp", "2"]);
    assert!(said.contains("colour, PSNR-RGB"), "{said}");
    let info = run(&["info", &s(&colour)]);
    assert!(
        info.contains("3 channel(s)") && info.contains("colour (YCbCr"),
        "{info}"
    );
    for ext in ["png", "ppm"] {
        let out = dir.join(format!("out.{ext}"));
        run(&["decode", &s(&colour), "-o", &s(&out)]);
        let back = image::open(&out).unwrap();
        assert!(back.color().has_color(), "{ext}: decoded without colour");
        let back = back.to_rgb8();
        let sse: f64 = back
            .as_raw()
            .iter()
            .zip(img.as_raw())
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum();
        let psnr = 10.0 * (255.0f64.powi(2) * img.as_raw().len() as f64 / sse).log10();
        assert!(psnr > 30.0, "{ext}: PSNR-RGB {psnr:.2} dB");
    }
    let gray = dir.join("gray.pifs");
    let said = run(&["encode", &s(&png), "-o", &s(&gray), "--bpp", "2", "--gray"]);
    assert!(said.contains("gray, PSNR"), "{said}");
    let info = run(&["info", &s(&gray)]);
    assert!(
        info.contains("1 channel(s)") && info.contains("grayscale"),
        "{info}"
    );
}

/// `--out-dir` encodes a batch: one stream per image, named after it, one summary line each;
/// an image that fails is reported, leaves nothing behind and does not stop the others, and
/// the exit status says that one failed.
#[test]
fn a_batch_encodes_every_image_it_can() {
    let dir = scratch("batch");
    let mut inputs = Vec::new();
    for (name, w, h) in [("a", 48, 32), ("b", 33, 20), ("c", 64, 64)] {
        let path = dir.join(format!("{name}.png"));
        textured(w, h).save(&path).unwrap();
        inputs.push(path);
    }
    let bad = dir.join("broken.png");
    std::fs::write(&bad, b"not an image at all").unwrap();
    inputs.insert(1, bad);
    let out_dir = dir.join("streams");
    let mut args: Vec<&str> = vec!["encode"];
    args.extend(inputs.iter().map(|p| p.to_str().unwrap()));
    args.extend(["--out-dir", out_dir.to_str().unwrap(), "--bpp", "0.5"]);
    let out = pifs(&args);
    assert!(!out.status.success(), "a failed image went unreported");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stdout.lines().count(), 3, "{stdout}");
    assert!(stderr.contains("broken.png"), "{stderr}");
    assert!(
        stderr.trim_end().ends_with("1 of 4 images failed"),
        "{stderr}"
    );
    for (name, w, h) in [("a", 48, 32), ("b", 33, 20), ("c", 64, 64)] {
        let stream = out_dir.join(format!("{name}.pifs"));
        assert!(stdout.contains(stream.to_str().unwrap()), "{stdout}");
        let (dw, dh, _) = decoded(&stream);
        assert_eq!((dw, dh), (w, h));
    }
    let written: Vec<_> = std::fs::read_dir(&out_dir).unwrap().flatten().collect();
    assert_eq!(written.len(), 3, "{written:?}");

    // Several images need --out-dir; two that would write the same stream are refused.
    let two = [inputs[0].to_str().unwrap(), inputs[2].to_str().unwrap()];
    let line = refused(&pifs(&["encode", two[0], two[1], "-o", "x.pifs"]));
    assert!(line.contains("--out-dir"), "{line}");
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    let twin = other.join("a.png");
    std::fs::copy(&inputs[0], &twin).unwrap();
    let line = refused(&pifs(&[
        "encode",
        two[0],
        twin.to_str().unwrap(),
        "--out-dir",
        out_dir.to_str().unwrap(),
    ]));
    assert!(line.contains("would both be written"), "{line}");
}

/// `pifs rd` on a colour image draws the colour curve (PSNR on RGB, colour streams) unless
/// `--gray`, and the PSNR it reports is the decoded colour stream's.
#[test]
fn rd_keeps_colour_unless_gray() {
    let dir = scratch("rd-colour");
    let png = dir.join("in.png");
    let img = colour_gradient();
    img.save(&png).unwrap();
    for (gray, channels) in [(false, 3), (true, 1)] {
        let streams = dir.join(format!("streams-{channels}"));
        let mut args = vec![
            "rd",
            png.to_str().unwrap(),
            "--rates",
            "1,3",
            "--out-dir",
            streams.to_str().unwrap(),
        ];
        if gray {
            args.push("--gray");
        }
        let stdout = ok(&pifs(&args));
        let said = if gray { "gray" } else { "colour (PSNR on RGB)" };
        assert!(stdout.contains(said), "{stdout}");
        let stream = streams.join("in-3bpp.pifs");
        let (w, h, px) = decoded(&stream);
        assert_eq!((w, h, px.len()), (48, 32, 48 * 32 * channels));
        if gray {
            continue;
        }
        let mse = img
            .as_raw()
            .iter()
            .zip(&px)
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum::<f64>()
            / px.len() as f64;
        let psnr = 10.0 * (255.0f64 * 255.0 / mse).log10();
        let reported: f64 = stdout
            .lines()
            .find(|l| l.trim_start().starts_with('3'))
            .and_then(|l| l.split_whitespace().last())
            .and_then(|v| v.parse().ok())
            .expect("a row for 3 bpp");
        assert!((psnr - reported).abs() < 0.01, "{psnr} against {reported}");
    }
}

/// Reads a PNG back as gray pixels.
fn png_pixels(path: &Path) -> Vec<u8> {
    image::open(path).unwrap().to_luma8().into_raw()
}

#[test]
fn packets_are_written_lost_and_decoded_from_any_subset() {
    let dir = scratch("packets");
    let png = dir.join("in.png");
    textured(96, 64).save(&png).unwrap();
    let packets = dir.join("pk");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let out = pifs(&[
        "encode",
        &s(&png),
        "--packets",
        &s(&packets),
        "--packet-size",
        "64",
        "--bytes",
        "960",
    ]);
    let line = ok(&out);
    assert!(
        line.contains("15 packets of at most 64 bytes (1 preview, 0 parity)"),
        "{line}"
    );
    let mut names: Vec<String> = std::fs::read_dir(&packets)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names.len(), 15);
    assert_eq!(names[0], "0000.pkt");
    for n in &names {
        let len = std::fs::metadata(packets.join(n)).unwrap().len();
        assert!(len <= 64, "{n}: {len} bytes");
    }
    // Everything, from the directory and from the framed file, gives the same picture.
    let whole = dir.join("whole.png");
    let line = ok(&pifs(&["decode", &s(&packets), "-o", &s(&whole)]));
    assert!(line.contains("from 15 of 15 packets"), "{line}");
    let framed = dir.join("all.pifsp");
    ok(&pifs(&[
        "encode",
        &s(&png),
        "-o",
        &s(&framed),
        "--packet-size",
        "64",
        "--bytes",
        "960",
    ]));
    let from_framed = dir.join("framed.png");
    ok(&pifs(&["decode", &s(&framed), "-o", &s(&from_framed)]));
    assert_eq!(png_pixels(&whole), png_pixels(&from_framed));
    // At half size: the whole picture's even pixels.
    let half = dir.join("half.png");
    let line = ok(&pifs(&[
        "decode",
        &s(&packets),
        "-o",
        &s(&half),
        "--scale",
        "1/2",
    ]));
    assert!(line.contains("48x32"), "{line}");
    let full = image::open(&whole).unwrap().to_luma8();
    let halved = image::open(&half).unwrap().to_luma8();
    assert_eq!(halved.dimensions(), (48, 32));
    for (x, y, p) in halved.enumerate_pixels() {
        assert_eq!(p, full.get_pixel(2 * x, 2 * y), "({x}, {y})");
    }
    // The framed form on standard output holds the packets alone (the summary goes to
    // standard error).
    let out = pifs(&[
        "encode",
        &s(&png),
        "-o",
        "-",
        "--packet-size",
        "64",
        "--bytes",
        "960",
    ]);
    assert!(out.status.success());
    assert_eq!(out.stdout, std::fs::read(&framed).unwrap());
    assert!(String::from_utf8_lossy(&out.stderr).contains("15 packets"));
    // The framed form on standard input.
    let from_stdin = dir.join("stdin.png");
    let out = Command::new(env!("CARGO_BIN_EXE_pifs"))
        .args(["decode", "-", "--packets", "-o", &s(&from_stdin)])
        .stdin(std::fs::File::open(&framed).unwrap())
        .output()
        .unwrap();
    ok(&out);
    assert_eq!(png_pixels(&whole), png_pixels(&from_stdin));
    // Without --packets, standard input is read as a stream: refused in one line that says
    // what to give, and no output left.
    let unsaid = dir.join("unsaid.png");
    let framed_bytes = std::fs::read(&framed).unwrap();
    let out = pifs_with_stdin(&["decode", "-", "-o", &s(&unsaid)], &framed_bytes);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("not a PIFS stream") && err.contains("--packets"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!unsaid.exists());
    // `pifs info --packets` describes the framed packets on standard input.
    let out = pifs_with_stdin(&["info", "-", "--packets", "--json"], &framed_bytes);
    let described: serde_json::Value = serde_json::from_slice(&ok_bytes(&out)).unwrap();
    assert_eq!(described["count"], 15);
    assert_eq!(described["missing"], serde_json::json!([]));
    // --follow: the picture written again after each packet that adds to it (a repeated
    // packet adds nothing), ending as the whole set's once nothing is missing (what follows,
    // here a damaged frame, is not read).
    let frames = host_encoder::packets::unframe(&framed_bytes);
    let mut repeated = frames.clone();
    repeated.insert(3, frames[2].clone());
    repeated.push(vec![0x70; 40]);
    let followed = dir.join("followed.png");
    let out = pifs_with_stdin(
        &["decode", "-", "--follow", "-o", &s(&followed)],
        &host_encoder::packets::frame(&repeated),
    );
    let lines = ok(&out);
    assert_eq!(lines.lines().count(), 15, "{lines}");
    assert!(
        lines.lines().next().unwrap().contains("from 1 of 15"),
        "{lines}"
    );
    assert_eq!(png_pixels(&whole), png_pixels(&followed));
    // Cut after three packets (the third one short): the picture of the first two.
    let two = dir.join("two.png");
    let mut cut = host_encoder::packets::frame(&frames[..3]);
    cut.truncate(cut.len() - 5);
    let lines = ok(&pifs_with_stdin(
        &["decode", "-", "--follow", "-o", &s(&two)],
        &cut,
    ));
    assert_eq!(lines.lines().count(), 2, "{lines}");
    let first_two = dir.join("first-two.pifsp");
    std::fs::write(&first_two, host_encoder::packets::frame(&frames[..2])).unwrap();
    let expected = dir.join("expected-two.png");
    ok(&pifs(&["decode", &s(&first_two), "-o", &s(&expected)]));
    assert_eq!(png_pixels(&expected), png_pixels(&two));
    // Nothing valid, or an output it cannot rewrite: refused in one line, nothing written.
    for (args, input) in [
        (vec!["decode", "-", "--follow", "-o", "NEVER"], &b""[..]),
        (
            vec!["decode", "-", "--follow", "-o", "NEVER"],
            &b"\x03\x00abc"[..],
        ),
        (vec!["decode", "-", "--follow", "-o", "-"], &cut[..]),
    ] {
        let never = dir.join("never.png");
        let args: Vec<String> = args
            .iter()
            .map(|a| {
                if *a == "NEVER" {
                    s(&never)
                } else {
                    a.to_string()
                }
            })
            .collect();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = pifs_with_stdin(&args, input);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(!never.exists());
    }
    // Loss: the survivors decode, and the report names the missing packets.
    let lossy = dir.join("lossy");
    let line = ok(&pifs(&[
        "packets",
        "drop",
        "--loss",
        "0.3",
        "--seed",
        "3",
        &s(&packets),
        &s(&lossy),
    ]));
    assert!(line.contains("of 15 packets"), "{line}");
    let kept = std::fs::read_dir(&lossy).unwrap().count();
    assert!(kept < 15 && kept > 0, "{kept}");
    let partial = dir.join("partial.png");
    let line = ok(&pifs(&["decode", &s(&lossy), "-o", &s(&partial)]));
    assert!(line.contains("missing: "), "{line}");
    // The missing packets sent again (`pifs packets resend`, the indices as the receiver
    // reports them), merged with what arrived: the whole picture.
    let out = pifs(&["info", &s(&lossy), "--json"]);
    let described: serde_json::Value = serde_json::from_slice(&ok_bytes(&out)).unwrap();
    let missing: Vec<String> = described["missing"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i.to_string())
        .collect();
    assert_eq!(missing.len(), 15 - kept);
    let again = dir.join("again.pifsp");
    ok(&pifs(&[
        "packets",
        "resend",
        &s(&packets),
        "--only",
        &missing.join(","),
        "-o",
        &s(&again),
    ]));
    assert_eq!(
        host_encoder::packets::unframe(&std::fs::read(&again).unwrap()).len(),
        15 - kept
    );
    let merged = dir.join("merged.png");
    let line = ok(&pifs(&[
        "decode",
        &s(&lossy),
        &s(&again),
        "-o",
        &s(&merged),
    ]));
    assert!(line.contains("from 15 of 15 packets"), "{line}");
    assert_eq!(png_pixels(&whole), png_pixels(&merged));
    let out = pifs(&["info", &s(&lossy), &s(&again), "--json"]);
    let described: serde_json::Value = serde_json::from_slice(&ok_bytes(&out)).unwrap();
    assert_eq!(described["missing"], serde_json::json!([]));
    assert_eq!(described["received"].as_array().unwrap().len(), 15);
    // An index the set does not hold, or no indices: refused, nothing written.
    for only in ["3,15", "7-2", ""] {
        let never = dir.join("never.pifsp");
        let out = pifs(&[
            "packets",
            "resend",
            &s(&packets),
            "--only",
            only,
            "-o",
            &s(&never),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.lines().count() == 1,
            "{only}: {err}"
        );
        assert!(!never.exists());
    }
    // A list of packet files: two regions alone.
    let two = dir.join("two.png");
    let line = ok(&pifs(&[
        "decode",
        &s(&packets.join("0003.pkt")),
        &s(&packets.join("0007.pkt")),
        "-o",
        &s(&two),
    ]));
    assert!(line.contains("from 2 of 15 packets"), "{line}");
    let info = ok(&pifs(&["info", &s(&packets)]));
    assert!(info.contains("96x64 gray, sent as 15 packets"), "{info}");
    // A set directory that is not empty is refused, and nothing is left behind.
    let refusal = refused(&pifs(&[
        "encode",
        &s(&png),
        "--packets",
        &s(&packets),
        "--bytes",
        "960",
        "--packet-size",
        "64",
    ]));
    assert!(refusal.contains("is not an empty directory"), "{refusal}");
    // Files that are no packets: one line, no output.
    let junk = dir.join("junk.bin");
    std::fs::write(&junk, b"not a packet at all").unwrap();
    let bad = dir.join("bad.png");
    let refusal = refused(&pifs(&["decode", &s(&junk), "-o", &s(&bad)]));
    assert!(refusal.contains("no valid packet"), "{refusal}");
    assert!(!bad.exists());
    let refusal = refused(&pifs(&[
        "encode",
        &s(&png),
        "--packets",
        &s(&dir.join("small")),
        "--bytes",
        "40",
        "--packet-size",
        "64",
    ]));
    assert!(refusal.contains("holds no packet"), "{refusal}");
    assert!(!dir.join("small").exists());
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("partial"))
        .filter(|n| n != "partial.png")
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// `pifs curve fit`, `render` and `info` through files: CSV and SVG in, JSON, SVG and CSV
/// out; bad input refused in one line with no output left behind.
#[test]
fn parity_is_sized_for_the_loss_a_link_expects() {
    let dir = scratch("expect-loss");
    let png = dir.join("in.png");
    textured(96, 64).save(&png).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let encode = |name: &str, extra: &[&str]| {
        let mut args = vec![
            "encode".to_string(),
            s(&png),
            "--packets".into(),
            s(&dir.join(name)),
            "--packet-size".into(),
            "64".into(),
            "--bytes".into(),
            "1920".into(),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        pifs(&args.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let line = ok(&encode("lossy", &["--expect-loss", "0.2"]));
    assert!(line.contains("parity for 20% loss"), "{line}");
    let parity: usize = line
        .split(" preview, ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|k| k.parse().ok())
        .expect("a parity count");
    assert!(parity > 0, "{line}");
    let written = std::fs::read_dir(dir.join("lossy")).unwrap().count();
    assert!(written > parity, "{written} packets, {parity} parity");
    // A rate out of range, or with a parity count of its own: refused, nothing written.
    assert!(refused(&encode("bad", &["--expect-loss", "0.7"])).contains("0.7"));
    refused(&encode("both", &["--expect-loss", "0.1", "--parity", "2"]));
    assert!(!dir.join("bad").exists() && !dir.join("both").exists());
    // Without a preview a lost region is interpolated: parity is sized all the same.
    let line = ok(&encode(
        "nopreview",
        &["--no-preview", "--expect-loss", "0.2"],
    ));
    assert!(line.contains("(0 preview, "), "{line}");
    // Packet options without packets are refused, not ignored.
    let stream = dir.join("x.pifs");
    for option in [
        &["--expect-loss", "0.1"][..],
        &["--parity", "2"],
        &["--no-preview"],
    ] {
        let mut args = vec![
            "encode",
            png.to_str().unwrap(),
            "-o",
            stream.to_str().unwrap(),
        ];
        args.extend_from_slice(option);
        assert!(refused(&pifs(&args)).contains(option[0]));
        assert!(!stream.exists());
    }
}

#[test]
fn curve_fit_render_info_round_trip() {
    let dir = scratch("curve");
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();
    // A cubic Bézier's points (control points 0,0 1,3 3,-1 4,1), as CSV and as an SVG path.
    let bezier = |t: f64| {
        let b = [
            (1.0 - t).powi(3),
            3.0 * t * (1.0 - t).powi(2),
            3.0 * t * t * (1.0 - t),
            t.powi(3),
        ];
        let (xs, ys) = ([0.0, 1.0, 3.0, 4.0], [0.0, 3.0, -1.0, 1.0]);
        let dot = |v: [f64; 4]| b.iter().zip(v).map(|(w, c)| w * c).sum::<f64>();
        (dot(xs), dot(ys))
    };
    let points: Vec<(f64, f64)> = (0..=256).map(|i| bezier(i as f64 / 256.0)).collect();
    let csv: String = std::iter::once("x,y\n".to_string())
        .chain(points.iter().map(|(x, y)| format!("{x},{y}\n")))
        .collect();
    std::fs::write(path("in.csv"), csv).unwrap();
    let d: Vec<String> = points.iter().map(|(x, y)| format!("{x},{y}")).collect();
    std::fs::write(
        path("in.svg"),
        format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg"><path d="M{}"/></svg>"#,
            d.join(" L")
        ),
    )
    .unwrap();
    for (input, json) in [("in.csv", "c.json"), ("in.svg", "s.json")] {
        let stdout = ok(&pifs(&[
            "curve",
            "fit",
            &path(input),
            "--points",
            "4",
            "--smooth",
            "-o",
            &path(json),
        ]));
        assert!(stdout.contains("8 parameters"), "{stdout}");
        let file: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path(json)).unwrap()).unwrap();
        assert_eq!(file["format"], "pifs-curve");
        assert_eq!(file["y_down"], input.ends_with(".svg"));
        // The smooth rules reproduce a Bézier: the fit is exact to rounding.
        let rms = file["fit"]["rms"].as_f64().unwrap();
        assert!(rms < 1e-4, "{input}: rms {rms}");
    }
    ok(&pifs(&[
        "curve",
        "render",
        &path("c.json"),
        "--depth",
        "4",
        "-o",
        &path("t.csv"),
    ]));
    let table = std::fs::read_to_string(path("t.csv")).unwrap();
    assert_eq!(table.lines().count(), 17);
    let last: Vec<f64> = table
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        (last[0] - 4.0).abs() < 1e-3 && (last[1] - 1.0).abs() < 1e-3,
        "{last:?}"
    );
    ok(&pifs(&[
        "curve",
        "render",
        &path("s.json"),
        "--data",
        &path("in.svg"),
        "-o",
        &path("d.svg"),
    ]));
    assert!(std::fs::read_to_string(path("d.svg"))
        .unwrap()
        .contains("projected-IFS curve"));
    let info = ok(&pifs(&[
        "curve",
        "info",
        &path("c.json"),
        "--data",
        &path("in.csv"),
    ]));
    assert!(
        info.contains("4 control points, 2 maps") && info.contains("against"),
        "{info}"
    );

    // Refusals: one line, non-zero exit, no output file.
    std::fs::write(path("bad.csv"), "0,0\n1,one\n").unwrap();
    std::fs::write(path("bad.json"), "{\"format\": \"pifs-curve\"}").unwrap();
    let fit = |input: &str, options: &[&str], output: &str| -> Vec<String> {
        let (input, output) = (path(input), path(output));
        ["curve", "fit", &input]
            .into_iter()
            .chain(options.iter().copied())
            .chain(["-o", &output])
            .map(String::from)
            .collect()
    };
    let render = |input: &str, output: &str| -> Vec<String> {
        vec![
            "curve".into(),
            "render".into(),
            path(input),
            "-o".into(),
            path(output),
        ]
    };
    for args in [
        fit("bad.csv", &["--points", "4"], "x.json"),
        fit("in.csv", &["--points", "1"], "x.json"),
        fit("in.csv", &["--points", "4", "--depth", "40"], "x.json"),
        fit("in.csv", &["--points", "4"], "x.png"),
        render("bad.json", "x.svg"),
        render("c.json", "x.txt"),
    ] {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(&pifs(&args));
    }
    for name in ["x.json", "x.png", "x.svg", "x.txt"] {
        assert!(!dir.join(name).exists(), "{name}");
    }
}

/// `--tune psnr` minimises the plain squared error, the default `ssim` the error weighted by
/// contrast: on an image half smooth, half textured, at one rate, the two streams differ and
/// the SSIM tuning's has the smaller error on the smooth half (56 591 against 62 417).
/// Whole-image squared errors are not compared: the encoder's search is not exact (here the
/// PSNR tuning's is the smaller, 1 554 460 against 1 557 989). 256 x 128 pixels: at 128 x 64
/// the streams have eight leaves, and one leaf's choice decides the smooth half. Another value
/// is refused.
#[test]
fn tune_chooses_the_distortion() {
    let dir = scratch("tune");
    let png = dir.join("in.png");
    let (w, h) = (256u32, 128u32);
    let texture = textured(w, h);
    let image = image::GrayImage::from_fn(w, h, |x, y| {
        if x < w / 2 {
            let (x, y) = (f64::from(x), f64::from(y));
            image::Luma([(100.0 + 40.0 * (x / 6.0).sin() * (y / 8.0).cos()).round() as u8])
        } else {
            *texture.get_pixel(x, y)
        }
    });
    image.save(&png).unwrap();
    // Squared error of the smooth half and of the whole image.
    let errors = |extra: &[&str]| {
        let stream = dir.join(format!("out{}.pifs", extra.len()));
        let mut args = vec!["encode", png.to_str().unwrap(), "--bpp", "0.25", "-o"];
        args.push(stream.to_str().unwrap());
        args.extend_from_slice(extra);
        ok(&pifs(&args));
        let (mut smooth, mut all) = (0u64, 0u64);
        for (i, (&a, &b)) in image.as_raw().iter().zip(&decoded(&stream).2).enumerate() {
            let d = u64::from(a.abs_diff(b)).pow(2);
            all += d;
            if (i as u32 % w) < w / 2 {
                smooth += d;
            }
        }
        (smooth, all, std::fs::read(&stream).unwrap())
    };
    let ssim = errors(&[]);
    let psnr = errors(&["--tune", "psnr"]);
    assert_ne!(ssim.2, psnr.2, "the same stream for both tunings");
    assert!(
        ssim.0 < psnr.0,
        "smooth half: ssim {} psnr {}; whole: ssim {} psnr {}",
        ssim.0,
        psnr.0,
        ssim.1,
        psnr.1
    );
    let line = refused(&pifs(&["encode", png.to_str().unwrap(), "--tune", "blur"]));
    assert!(line.contains("'blur' is not 'ssim' or 'psnr'"), "{line}");
}

/// `decode --hillshade` draws a grayscale stream's decode as the relief `relief::hillshade`
/// makes of it (with a chosen exaggeration or the automatic one); a colour stream, packets or
/// a scale are refused in one line, with no output left behind.
#[test]
fn decode_draws_a_heightmap_as_a_hillshaded_relief() {
    let dir = scratch("hillshade");
    let png = dir.join("in.png");
    textured(64, 48).save(&png).unwrap();
    let stream = dir.join("in.pifs");
    ok(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        stream.to_str().unwrap(),
    ]));
    let (w, h, heights) = decoded(&stream);
    let heights: Vec<f64> = heights.iter().map(|&p| f64::from(p)).collect();
    for (option, z_factor) in [(None, None), (Some("2.5"), Some(2.5))] {
        let out = dir.join("relief.pgm");
        let mut args = vec![
            "decode",
            stream.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.push("--hillshade");
        args.extend(option);
        assert!(ok(&pifs(&args)).contains("hillshaded relief"));
        let light = host_encoder::relief::Light {
            z_factor,
            ..Default::default()
        };
        let expected = host_encoder::relief::hillshade(&heights, w as usize, h as usize, &light);
        let img = image::open(&out).unwrap().to_luma8();
        assert_eq!(img.dimensions(), (w, h));
        assert_eq!(img.as_raw(), &expected, "{option:?}");
        assert!(
            expected.iter().any(|&s| s != expected[0]),
            "a relief, not a flat gray"
        );
    }

    let colour = dir.join("colour.png");
    colour_gradient().save(&colour).unwrap();
    let colour_stream = dir.join("colour.pifs");
    ok(&pifs(&[
        "encode",
        colour.to_str().unwrap(),
        "-o",
        colour_stream.to_str().unwrap(),
    ]));
    let out = dir.join("refused.png");
    let line = refused(&pifs(&[
        "decode",
        colour_stream.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--hillshade",
    ]));
    assert!(line.contains("grayscale"), "{line}");
    let line = refused(&pifs(&[
        "decode",
        stream.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--hillshade",
        "--scale",
        "1/2",
    ]));
    assert!(line.contains("coded size"), "{line}");
    let line = refused(&pifs(&[
        "decode",
        stream.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--hillshade=-1",
    ]));
    assert!(line.contains("vertical exaggeration"), "{line}");
    assert!(!out.exists());
}

/// A 16-bit grayscale image (a heightmap) is coded as a 16-bit stream: `info` shows its depth
/// and range, `decode` writes 16-bit PNG and PGM of values in its units (finer than 256 grey
/// levels, within the error `encode` reports), `--hillshade` shades those values; `--depth 8`
/// makes an 8-bit stream (with a note when the samples span few grey levels); `--max-error`
/// keeps every value within it; packets refuse a 16-bit image in one line.
#[test]
fn sixteen_bit_heightmaps_round_trip_as_surfaces() {
    let dir = scratch("sixteen");
    let (w, h) = (64u32, 48u32);
    let height = |x: u32, y: u32| {
        let (x, y) = (f64::from(x), f64::from(y));
        1000.0 + 400.0 * (x / 9.0).sin() * (y / 13.0).cos() + 6.0 * x + 3.0 * y
    };
    let dem: Vec<u16> = (0..h)
        .flat_map(|y| (0..w).map(move |x| height(x, y).round() as u16))
        .collect();
    let png = dir.join("dem.png");
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, dem.clone())
        .unwrap()
        .save(&png)
        .unwrap();
    let (low, high) = (*dem.iter().min().unwrap(), *dem.iter().max().unwrap());
    let stream = dir.join("dem.pifs");
    let line = ok(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "--bpp",
        "2",
        "-o",
        stream.to_str().unwrap(),
    ]));
    assert!(
        line.contains(&format!("16-bit surface {low}..{high}")),
        "{line}"
    );
    let rmse_reported: f64 = {
        let at = line.find("RMSE ").unwrap() + 5;
        line[at..].split(',').next().unwrap().parse().unwrap()
    };
    let info = ok(&pifs(&["info", stream.to_str().unwrap()]));
    assert!(info.contains("16 bits"), "{info}");
    assert!(
        info.contains(&format!(
            "values           {low}..{}",
            decoder_core::SampleRange::covering(low, high).high()
        )),
        "{info}"
    );

    let read16 = |path: &Path| match image::open(path).unwrap() {
        image::DynamicImage::ImageLuma16(img) => img.into_raw(),
        other => panic!("{}: {:?}, not 16-bit gray", path.display(), other.color()),
    };
    let out_png = dir.join("out.png");
    let out_pgm = dir.join("out.pgm");
    for out in [&out_png, &out_pgm] {
        let said = ok(&pifs(&[
            "decode",
            stream.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]));
        assert!(said.contains("16-bit surface"), "{said}");
    }
    let values = read16(&out_png);
    assert_eq!(values, read16(&out_pgm), "PNG and PGM hold the same values");
    assert_eq!(values.len(), dem.len());
    assert!(values.iter().all(|v| (low..=high).contains(v)));
    let sum: f64 = values
        .iter()
        .zip(&dem)
        .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
        .sum();
    let rmse = (sum / dem.len() as f64).sqrt();
    assert!(
        (rmse - rmse_reported).abs() < 0.01,
        "{rmse} vs {rmse_reported}"
    );
    // 2 bits a sample: well within a grey level of the range (the range / 255 = 4.9).
    assert!(rmse < f64::from(high - low) / 255.0, "RMSE {rmse}");
    let distinct: std::collections::BTreeSet<u16> = values.iter().copied().collect();
    assert!(
        distinct.len() > 256,
        "{} values: no finer than grey",
        distinct.len()
    );

    // The relief of a 16-bit stream shades its values.
    let relief = dir.join("relief.png");
    ok(&pifs(&[
        "decode",
        stream.to_str().unwrap(),
        "-o",
        relief.to_str().unwrap(),
        "--hillshade",
    ]));
    let heights: Vec<f64> = values.iter().map(|&v| f64::from(v)).collect();
    let expected =
        host_encoder::relief::hillshade(&heights, w as usize, h as usize, &Default::default());
    assert_eq!(image::open(&relief).unwrap().to_luma8().as_raw(), &expected);

    // --max-error: every value within it (in metres here), the smaller error the larger file.
    // (The best stream of this surface reaches 2 m since format 21's finer steps and the bound
    // in each leaf's distortion; 7 m in format 20, 4 m before: see docs/decisions.md.)
    let mut sizes = Vec::new();
    for max in [2u16, 20] {
        let out = dir.join(format!("within-{max}.pifs"));
        let line = ok(&pifs(&[
            "encode",
            png.to_str().unwrap(),
            "--max-error",
            &max.to_string(),
            "-o",
            out.to_str().unwrap(),
        ]));
        assert!(line.contains("largest error"), "{line}");
        let bytes = std::fs::read(&out).unwrap();
        let mut values = vec![0u16; dem.len()];
        decoder_core::Decoder::new(&bytes)
            .unwrap()
            .decode_values_into(&mut values)
            .unwrap();
        let largest = values.iter().zip(&dem).map(|(a, b)| a.abs_diff(*b)).max();
        assert!(largest.unwrap() <= max, "{max}: {largest:?}");
        sizes.push(bytes.len());
    }
    assert!(sizes[0] > sizes[1], "{sizes:?}");
    let line = refused(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "--max-error",
        "0.01",
        "-o",
        dir.join("none.pifs").to_str().unwrap(),
    ]));
    assert!(line.contains("unreachable"), "{line}");
    assert!(!dir.join("none.pifs").exists());

    // --depth 8: an 8-bit stream of the samples' full 16-bit range, noted as flattened.
    let eight = dir.join("eight.pifs");
    let line = ok(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "--depth",
        "8",
        "-o",
        eight.to_str().unwrap(),
    ]));
    assert!(
        line.contains(&format!(
            "16-bit samples from {low} to {high} become 4 grey levels"
        )),
        "{line}"
    );
    assert!(ok(&pifs(&["info", eight.to_str().unwrap()])).contains("8 bits"));

    let packets = dir.join("dem.pifsp");
    let line = refused(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "--packet-size",
        "64",
        "--bytes",
        "600",
        "-o",
        packets.to_str().unwrap(),
    ]));
    assert!(line.contains("--depth 8"), "{line}");
    assert!(!packets.exists());
}

/// An image wider than decoder-core's default frontier is coded as one stripe unless told
/// otherwise: the default decoder refuses it (a host's decodes it), `pifs info` says what a
/// decoder needs, `--stripe-width 512` makes a stream the default decoder takes, and packets
/// keep stripes of 512 (wider ones refused).
#[test]
fn wide_images_are_one_stripe_unless_told_and_packets_keep_512() {
    let dir = scratch("stripes");
    let png = dir.join("wide.png");
    textured(640, 48).save(&png).unwrap();
    let (whole, narrow) = (dir.join("whole.pifs"), dir.join("narrow.pifs"));
    let encode = |out: &Path, extra: &[&str]| {
        let mut args = vec!["encode", png.to_str().unwrap(), "-o", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        ok(&pifs(&args));
        std::fs::read(out).unwrap()
    };
    let bytes = encode(&whole, &["--bytes", "900"]);
    let header = decoder_core::Header::read(&bytes).unwrap();
    assert_eq!((header.stripe, header.stripe_width()), (0, 640));
    let mut px = vec![0u8; header.pixel_count()];
    assert_eq!(
        decoder_core::Decoder::new(&bytes).and_then(|d| d.decode_into(&mut px)),
        Err(decoder_core::DecodeError::StripeTooWide {
            stripe: 640,
            capacity: 512
        })
    );
    assert_eq!(decoded(&whole).2.len(), 640 * 48);
    let info = ok(&pifs(&["info", whole.to_str().unwrap()]));
    assert!(
        info.contains("stripes of 640 px (a decoder needs 640 columns"),
        "{info}"
    );

    let bytes = encode(&narrow, &["--bytes", "900", "--stripe-width", "512"]);
    let header = decoder_core::Header::read(&bytes).unwrap();
    assert_eq!((header.stripe, header.stripe_width()), (4, 512));
    decoder_core::Decoder::new(&bytes)
        .and_then(|d| d.decode_into(&mut px))
        .unwrap();
    let info = ok(&pifs(&["info", narrow.to_str().unwrap()]));
    assert!(!info.contains("a decoder needs"), "{info}");

    let packets = dir.join("packets");
    let p = packets.to_str().unwrap();
    ok(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "--packets",
        p,
        "--bytes",
        "1500",
    ]));
    let first = std::fs::read(packets.join("0000.pkt")).unwrap();
    let packet = decoder_core::Packet::parse(&first).unwrap();
    assert_eq!(packet.stream_header().stripe_width(), 512);
    let refused = refused(&pifs(&[
        "encode",
        png.to_str().unwrap(),
        "--packets",
        dir.join("more").to_str().unwrap(),
        "--bytes",
        "1500",
        "--stripe-width",
        "full",
    ]));
    assert!(refused.contains("stripes of at most 512"), "{refused}");
}

/// `pifs COMMAND INPUT -o OUTPUT ARGS...`.
fn pifs_on(command: &str, input: &Path, output: &Path, args: &[&str]) -> Output {
    let mut all = vec![
        command,
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    pifs(&all)
}

/// `decode --display PANEL` writes the picture as the panel shows it, as decoder-core's
/// embedded-graphics drawing converts it on the device: each pixel the level `FromGray::from_gray_with`
/// / `from_rgb_with` give at `Threshold::ordered` of its position (the default) or `from_gray` /
/// `from_rgb` gives (`--dither nearest`), written back as 8-bit samples; at a scale too (the
/// positions are the scaled image's); a packet set as the host assembles it, each pixel so
/// converted. An unknown panel, `--dither` alone, `--display` with `--hillshade` and a 16-bit
/// surface are refused in one line, with no output left behind.
#[test]
fn decode_shows_the_picture_as_a_panel_would() {
    use decoder_core::graphics::{FromGray, Threshold};
    use decoder_core::internal::colour::rgb_to_luma;
    use embedded_graphics_core::pixelcolor::{BinaryColor, Rgb565, Rgb888, RgbColor};
    let dir = scratch("display");
    let (gray, colour) = gray_and_colour(&dir);
    for input in [&gray, &colour] {
        let stream = input.with_extension("pifs");
        ok(&pifs_on("encode", input, &stream, &[]));
        for (scale, factor) in [
            ("1", decoder_core::Scale::One),
            ("1/2", decoder_core::Scale::Half),
        ] {
            let bytes = std::fs::read(&stream).unwrap();
            let decoder = decoder_core::Decoder::new(&bytes).unwrap().scale(factor);
            let (w, h) = decoder.output_size();
            let channels = usize::from(decoder.header().channels);
            let mut px = vec![0u8; (w * h) as usize * channels];
            decoder.decode_into(&mut px).unwrap();
            let pixel = |x: u32, y: u32| {
                let at = (y * w + x) as usize * channels;
                match channels {
                    3 => (px[at], px[at + 1], px[at + 2]),
                    _ => (px[at], px[at], px[at]),
                }
            };
            for (dither, ordered) in [("ordered", true), ("nearest", false)] {
                let mono = dir.join("mono.png");
                let said = ok(&pifs_on(
                    "decode",
                    &stream,
                    &mono,
                    &["--display", "mono", "--dither", dither, "--scale", scale],
                ));
                assert!(said.contains("mono panel"), "{said}");
                let shown = image::open(&mono).unwrap().to_luma8();
                assert_eq!(shown.dimensions(), (w, h));
                let rgb565 = dir.join("rgb565.png");
                ok(&pifs_on(
                    "decode",
                    &stream,
                    &rgb565,
                    &["--display", "rgb565", "--dither", dither, "--scale", scale],
                ));
                let shown565 = image::open(&rgb565).unwrap().to_rgb8();
                for y in 0..h {
                    for x in 0..w {
                        let (r, g, b) = pixel(x, y);
                        let luma = if channels == 3 {
                            rgb_to_luma(r, g, b)
                        } else {
                            r
                        };
                        let (on, c) = if ordered {
                            (
                                BinaryColor::from_gray_with(luma, Threshold::ordered(x, y)),
                                match channels {
                                    3 => Rgb565::from_rgb_with(r, g, b, Threshold::ordered(x, y)),
                                    _ => Rgb565::from_gray_with(luma, Threshold::ordered(x, y)),
                                },
                            )
                        } else {
                            (
                                BinaryColor::from_gray(luma),
                                match channels {
                                    3 => Rgb565::from_rgb(r, g, b),
                                    _ => Rgb565::from_gray(luma),
                                },
                            )
                        };
                        let level = if on.is_on() { 255 } else { 0 };
                        assert_eq!(shown.get_pixel(x, y).0, [level], "{x},{y} {dither}");
                        let c = Rgb888::from(c);
                        assert_eq!(
                            shown565.get_pixel(x, y).0,
                            [c.r(), c.g(), c.b()],
                            "{x},{y} {dither}"
                        );
                    }
                }
            }
        }
    }
    // A packet set: the picture the host assembles, each pixel converted as on the device.
    let packets = dir.join("packets");
    ok(&pifs(&[
        "encode",
        colour.to_str().unwrap(),
        "--packets",
        packets.to_str().unwrap(),
        "--bytes",
        "1200",
        "--packet-size",
        "128",
    ]));
    let plain = dir.join("packets.png");
    ok(&pifs_on("decode", &packets, &plain, &[]));
    let shown = dir.join("packets-565.png");
    ok(&pifs_on(
        "decode",
        &packets,
        &shown,
        &["--display", "rgb565"],
    ));
    let plain = image::open(&plain).unwrap().to_rgb8();
    let shown = image::open(&shown).unwrap().to_rgb8();
    assert_eq!(plain.dimensions(), shown.dimensions());
    for (x, y, p) in plain.enumerate_pixels() {
        let [r, g, b] = p.0;
        let c = Rgb888::from(Rgb565::from_rgb_with(r, g, b, Threshold::ordered(x, y)));
        assert_eq!(shown.get_pixel(x, y).0, [c.r(), c.g(), c.b()], "{x},{y}");
    }

    let stream = gray.with_extension("pifs");
    let out = dir.join("refused.png");
    let line = refused(&pifs_on(
        "decode",
        &stream,
        &out,
        &["--display", "mono", "--hillshade"],
    ));
    assert!(line.contains("one at a time"), "{line}");
    let line = refused(&pifs_on("decode", &stream, &out, &["--display", "cga"]));
    assert!(line.contains("not a panel"), "{line}");
    let line = refused(&pifs_on("decode", &stream, &out, &["--dither", "nearest"]));
    assert!(line.contains("--display"), "{line}");
    let heights = dir.join("heights.png");
    heights_png(&heights);
    let surface = dir.join("heights.pifs");
    ok(&pifs_on("encode", &heights, &surface, &[]));
    let line = refused(&pifs_on("decode", &surface, &out, &["--display", "mono"]));
    assert!(line.contains("16-bit surface"), "{line}");
    assert!(!out.exists());
}

/// A 32x16 16-bit grayscale PNG (a heightmap: a 16-bit stream) at `path`.
fn heights_png(path: &Path) {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(32, 16, |x, y| {
        image::Luma([(x * 1000 + y * 300) as u16])
    })
    .save(path)
    .unwrap();
}

/// `--resize WxH` scales the image to fit the box, keeping its shape, before `encode` (and
/// `rd`) code it: gray, colour and 16-bit images alike, smaller or larger; the encode says so
/// and `--bpp` counts the scaled pixels. A size that is not `WxH` is refused in one line.
#[test]
fn resize_fits_the_image_to_a_display() {
    let dir = scratch("resize");
    let (gray, colour) = gray_and_colour(&dir);
    let heights = dir.join("heights.png");
    heights_png(&heights);
    for (input, fit, size, channels) in [
        (&gray, "20x20", (20, 12), 1),
        (&colour, "24x100", (24, 16), 3),
        (&colour, "96x96", (96, 64), 3),
        (&heights, "16x16", (16, 8), 1),
    ] {
        let stream = dir.join("out.pifs");
        let said = ok(&pifs_on(
            "encode",
            input,
            &stream,
            &["--resize", fit, "--bpp", "2"],
        ));
        assert!(
            said.contains(&format!("resized to {}x{}", size.0, size.1)),
            "{said}"
        );
        let bytes = std::fs::read(&stream).unwrap();
        let header = decoder_core::Decoder::new(&bytes).unwrap();
        let header = header.header();
        assert_eq!((u32::from(header.width), u32::from(header.height)), size);
        assert_eq!(header.channels, channels);
        assert_eq!(header.range.is_some(), input == &heights);
        assert!(bytes.len() * 8 <= 2 * (size.0 * size.1) as usize, "{fit}");
    }
    let out = dir.join("refused.pifs");
    let line = refused(&pifs_on("encode", &gray, &out, &["--resize", "240"]));
    assert!(line.contains("not a size"), "{line}");
    assert!(!out.exists());
}

/// `info --json` describes a stream and a packet set as one JSON object on standard output,
/// with the figures the text gives; a packet set's `missing` are the packets not there (the
/// ones a gateway asks for again), and `received` and `missing` make up the set.
#[test]
fn info_describes_streams_and_packets_as_json() {
    let dir = scratch("info-json");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let png = dir.join("in.png");
    textured(96, 64).save(&png).unwrap();
    let stream = dir.join("x.pifs");
    ok(&pifs_on("encode", &png, &stream, &["--bytes", "500"]));
    let object: serde_json::Value =
        serde_json::from_str(&ok(&pifs(&["info", &s(&stream), "--json"]))).expect("JSON");
    let bytes = std::fs::read(&stream).unwrap();
    let header = decoder_core::Header::read(&bytes).unwrap();
    assert_eq!(object["kind"], "stream");
    assert_eq!(object["width"], 96);
    assert_eq!(object["height"], 64);
    assert_eq!(object["channels"], u64::from(header.channels));
    assert_eq!(object["bytes"], bytes.len());
    assert_eq!(object["header_bytes"], header.encoded_len());
    // The leaves, counted three ways, and as the decoder walks them.
    let mut walked = 0usize;
    decoder_core::Decoder::new(&bytes)
        .unwrap()
        .observe(|_: &decoder_core::LeafInfo| walked += 1)
        .verify()
        .unwrap();
    let sum = |v: &serde_json::Value| -> u64 {
        match v {
            serde_json::Value::Object(m) => m.values().map(|n| n.as_u64().unwrap()).sum(),
            serde_json::Value::Array(a) => a.iter().map(|m| m["leaves"].as_u64().unwrap()).sum(),
            _ => panic!("{v}"),
        }
    };
    assert_eq!(object["leaves"], walked);
    assert_eq!(sum(&object["leaves_by_side"]), walked as u64);
    assert_eq!(sum(&object["models"]), walked as u64);

    let packets = dir.join("pk");
    ok(&pifs(&[
        "encode",
        &s(&png),
        "--packets",
        &s(&packets),
        "--packet-size",
        "64",
        "--bytes",
        "960",
    ]));
    for lost in ["0003.pkt", "0007.pkt", "0008.pkt"] {
        std::fs::remove_file(packets.join(lost)).unwrap();
    }
    let object: serde_json::Value =
        serde_json::from_str(&ok(&pifs(&["info", &s(&packets), "--json"]))).expect("JSON");
    assert_eq!(object["kind"], "packets");
    assert_eq!(object["count"], 15);
    assert_eq!(object["files"], 12);
    assert_eq!(object["missing"], serde_json::json!([3, 7, 8]));
    let received: Vec<u64> = object["received"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    let expected: Vec<u64> = (0..15).filter(|i| ![3, 7, 8].contains(i)).collect();
    assert_eq!(received, expected);
    let coverage = object["coverage"].as_f64().unwrap();
    assert!(coverage > 0.0 && coverage < 1.0, "{coverage}");

    // Another picture of the same size, coded to the same packets and bytes, in the same
    // directory: its packets carry another image id (made from their content), and the image
    // most packets agree on (that one, all 15 of its packets here) is described with its own
    // packets only, the others said to be there.
    let other_png = dir.join("other.png");
    image::imageops::flip_horizontal(&textured(96, 64))
        .save(&other_png)
        .unwrap();
    let other = dir.join("pk2");
    ok(&pifs(&[
        "encode",
        &s(&other_png),
        "--packets",
        &s(&other),
        "--packet-size",
        "64",
        "--bytes",
        "960",
    ]));
    let id_of = |p: &Path| {
        let b = std::fs::read(p).unwrap();
        u16::from_le_bytes([b[1], b[2]])
    };
    let (first_id, other_id) = (
        id_of(&packets.join("0000.pkt")),
        id_of(&other.join("0000.pkt")),
    );
    assert_ne!(first_id, other_id);
    let mut other_bytes = 0;
    for entry in std::fs::read_dir(&other).unwrap() {
        let path = entry.unwrap().path();
        other_bytes += std::fs::metadata(&path).unwrap().len();
        let name = format!("b{}", path.file_name().unwrap().to_string_lossy());
        std::fs::copy(&path, packets.join(name)).unwrap();
    }
    let mixed: serde_json::Value =
        serde_json::from_str(&ok(&pifs(&["info", &s(&packets), "--json"]))).expect("JSON");
    assert_eq!(mixed["image_id"], other_id);
    assert_eq!(mixed["files"], 12 + 15);
    assert_eq!(mixed["packets"], 15);
    assert_eq!(mixed["bytes"], other_bytes);
    assert_eq!(mixed["ignored"]["other_image"], 12);
    let text = ok(&pifs(&["info", &s(&packets)]));
    assert!(
        text.contains("here: 15 packets of it (and 12 other files)"),
        "{text}"
    );
}
