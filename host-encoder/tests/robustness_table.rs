//! The `pifs` command line against malformed, unusual and hostile inputs. Every case runs the
//! real binary; the test asserts, for every refused input: a non-zero exit (never a panic), a
//! single line on stderr starting with `pifs: `, and no output left behind (a file that existed
//! before is untouched); for every accepted one: success and a valid output. It then renders the
//! outcomes as the table of `docs/robustness.md` and fails if the committed table differs, so the
//! document stays true. Regenerate it with `bash scripts/robustness-table.sh`.

#[path = "robustness_table/doc.rs"]
mod doc;
#[path = "robustness_table/host.rs"]
mod host;
#[path = "common/scratch.rs"]
mod scratch;

use scratch::Scratch;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// What a case must do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Expect {
    /// Refused: non-zero exit, one line, no output.
    Refused,
    /// Accepted: exit 0 and a valid output file.
    Accepted,
}

struct Case {
    /// What the input is, for the table.
    what: &'static str,
    /// Arguments; `{dir}` is the scratch directory.
    args: Vec<String>,
    /// The output path the command would write (checked for leftovers or validity).
    output: Option<PathBuf>,
    /// Put a file at the output path before running, which a refused command must not touch.
    existing_output: bool,
    expect: Expect,
}

fn pifs() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pifs"))
}

fn scratch() -> Scratch {
    Scratch::new("robustness")
}

fn gray_png(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> u8) {
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([f(x, y)]))
        .save(path)
        .unwrap();
}

/// Deterministic noise.
fn noise(x: u32, y: u32) -> u8 {
    let v =
        (x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(2_246_822_519)).wrapping_mul(747_796_405);
    (v >> 24) as u8
}

/// Writes every input file the cases use.
fn make_inputs(dir: &Path) {
    let p = |n: &str| dir.join(n);
    gray_png(&p("good.png"), 64, 48, |x, y| (x * 3 + y * 2) as u8);
    std::fs::write(p("empty.png"), b"").unwrap();
    let good = std::fs::read(p("good.png")).unwrap();
    std::fs::write(p("truncated.png"), &good[..good.len() / 2]).unwrap();
    let mut corrupt = good.clone();
    let mid = corrupt.len() / 2;
    for b in &mut corrupt[mid..mid + 16] {
        *b ^= 0xA5;
    }
    std::fs::write(p("corrupt-data.png"), &corrupt).unwrap();
    let rgb = image::RgbImage::from_fn(32, 32, |x, y| image::Rgb([x as u8 * 8, y as u8 * 8, 90]));
    let mut jpeg = Vec::new();
    image::DynamicImage::ImageRgb8(rgb)
        .write_to(
            &mut std::io::Cursor::new(&mut jpeg),
            image::ImageFormat::Jpeg,
        )
        .unwrap();
    std::fs::write(p("truncated.jpg"), &jpeg[..jpeg.len() / 2]).unwrap();
    std::fs::write(p("text.png"), b"this is not an image\n").unwrap();
    let random: Vec<u8> = (0..4096u32).map(|i| noise(i, 7)).collect();
    std::fs::write(p("random.jpg"), &random).unwrap();
    std::fs::create_dir_all(p("a-directory")).unwrap();
    std::fs::write(p("a-file"), b"x").unwrap();
    // Unusual but valid images.
    image::ImageBuffer::<image::Luma<u16>, _>::from_fn(40, 30, |x, y| {
        image::Luma([(x * 1500 + y * 700) as u16])
    })
    .save(p("gray16.png"))
    .unwrap();
    image::ImageBuffer::<image::Rgba<u16>, _>::from_fn(40, 30, |x, y| {
        image::Rgba([(x * 1500) as u16, (y * 2000) as u16, 30000, 65535])
    })
    .save(p("rgba16.png"))
    .unwrap();
    image::RgbaImage::from_fn(40, 30, |x, y| {
        image::Rgba([200, (x * 6) as u8, 40, (y * 8) as u8])
    })
    .save(p("rgba.png"))
    .unwrap();
    image::GrayAlphaImage::from_fn(40, 30, |x, y| image::LumaA([(x * 6) as u8, (y * 8) as u8]))
        .save(p("gray-alpha.png"))
        .unwrap();
    write_palette_png(&p("palette.png"));
    gray_png(&p("one-pixel.png"), 1, 1, |_, _| 77);
    gray_png(&p("flat.png"), 64, 64, |_, _| 128);
    gray_png(&p("noise.png"), 64, 64, noise);
    // A slope under a one-level checkerboard: its nodes settle (a bilinear patch reproduces
    // them within half a grey level squared), so its best stream is not lossless.
    gray_png(&p("slope.png"), 64, 64, |x, y| {
        (60 + x + y / 2 + ((x ^ y) & 1)) as u8
    });
    gray_png(&p("wide-65535x1.png"), 65535, 1, |x, _| (x % 251) as u8);
    gray_png(&p("too-wide-65536x1.png"), 65536, 1, |x, _| x as u8);
    // Curves.
    let curve: String = (0..40).map(|i| format!("{i},{}\n", (i * i) % 7)).collect();
    std::fs::write(p("curve.csv"), curve).unwrap();
    std::fs::write(p("bad-curve.csv"), "x,y\n0,1\n1,two\n").unwrap();
    std::fs::write(p("one-point.csv"), "0,1\n").unwrap();
    std::fs::write(p("random.csv"), &random).unwrap();
    std::fs::write(
        p("curved-path.svg"),
        r#"<svg xmlns="http://www.w3.org/2000/svg"><path d="M0 0 C1 1 2 1 3 0"/></svg>"#,
    )
    .unwrap();
    std::fs::write(
        p("not-a-curve.json"),
        r#"{"format": "pifs-curve", "version": 2}"#,
    )
    .unwrap();
    // Streams.
    let encode = |args: &[&str], output: &Path| {
        let out = pifs()
            .arg("encode")
            .args(args)
            .arg("-o")
            .arg(output)
            .arg(p("good.png"))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let stream = p("good.pifs");
    encode(&["--bytes", "300"], &stream);
    let bytes = std::fs::read(&stream).unwrap();
    // Packets, framed.
    encode(&["--bytes", "600", "--packet-size", "64"], &p("good.pifsp"));
    std::fs::write(p("empty.pifs"), b"").unwrap();
    std::fs::write(p("truncated.pifs"), &bytes[..bytes.len() * 2 / 3]).unwrap();
    let mut flipped = bytes.clone();
    let at = bytes.len() - 10;
    flipped[at] ^= 0x10;
    std::fs::write(p("bit-flip.pifs"), &flipped).unwrap();
    let mut newer = bytes.clone();
    newer[0] = decoder_core::STREAM_TAG + 1;
    std::fs::write(p("version-next.pifs"), &newer).unwrap();
    let mut before = bytes.clone();
    before[0] = decoder_core::STREAM_TAG - 1;
    std::fs::write(p("version-before.pifs"), &before).unwrap();
    // Format 21's opening: `PIFS`, its version byte, then what its header held.
    let mut older = b"PIFS".to_vec();
    older.push(21);
    older.extend_from_slice(&bytes[1..]);
    std::fs::write(p("version-21.pifs"), &older).unwrap();
    let mut longer = bytes.clone();
    longer.extend_from_slice(b"trailing");
    std::fs::write(p("trailing-bytes.pifs"), &longer).unwrap();
    // A valid, checksummed header announcing 65535 x 65535 pixels, with a tiny payload.
    let (mut header, offset) = decoder_core::Header::parse(&bytes).unwrap();
    header.width = 65535;
    header.height = 65535;
    let mut huge = vec![0u8; header.encoded_len()];
    header.write(&mut huge);
    huge.extend_from_slice(&bytes[offset..]);
    decoder_core::internal::syntax::seal(&mut huge);
    std::fs::write(p("huge-header.pifs"), &huge).unwrap();
}

/// A 4-colour indexed PNG, 32x32 pixels, written by hand (colour type 3, bit depth 8, the image
/// data in one stored zlib block): the `image` crate does not write palette images.
fn write_palette_png(path: &Path) {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&decoder_core::internal::checksum::crc32(&body).to_be_bytes());
    }
    let (w, h) = (32u32, 32u32);
    let mut raw = Vec::new();
    for y in 0..h {
        raw.push(0); // filter: none
        for x in 0..w {
            raw.push(((x / 2 + y / 4) % 4) as u8);
        }
    }
    // zlib: header, one stored block, Adler-32.
    let mut z = vec![0x78, 0x01, 0x01];
    z.extend_from_slice(&(raw.len() as u16).to_le_bytes());
    z.extend_from_slice(&(!(raw.len() as u16)).to_le_bytes());
    z.extend_from_slice(&raw);
    let (mut a, mut b) = (1u32, 0u32);
    for &v in &raw {
        a = (a + u32::from(v)) % 65521;
        b = (b + a) % 65521;
    }
    z.extend_from_slice(&((b << 16) | a).to_be_bytes());
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 3, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    chunk(
        &mut png,
        b"PLTE",
        &[255, 0, 0, 0, 255, 0, 0, 0, 255, 250, 250, 250],
    );
    chunk(&mut png, b"IDAT", &z);
    chunk(&mut png, b"IEND", &[]);
    std::fs::write(path, png).unwrap();
}

fn cases(dir: &Path) -> Vec<Case> {
    let refuse = |what: &'static str, args: &[&str], output: Option<&str>| Case {
        what,
        args: args
            .iter()
            .map(|a| a.replace("{dir}", &dir.to_string_lossy()))
            .collect(),
        output: output.map(|o| PathBuf::from(o.replace("{dir}", &dir.to_string_lossy()))),
        existing_output: false,
        expect: Expect::Refused,
    };
    let accept = |what: &'static str, args: &[&str], output: &str| Case {
        expect: Expect::Accepted,
        ..refuse(what, args, Some(output))
    };
    let keep = |mut c: Case| {
        c.existing_output = true;
        c
    };
    vec![
        // encode: unreadable inputs
        refuse(
            "missing input file",
            &["encode", "{dir}/nope.png", "-o", "{dir}/o1.pifs"],
            Some("{dir}/o1.pifs"),
        ),
        refuse(
            "input is a directory",
            &["encode", "{dir}/a-directory", "-o", "{dir}/o2.pifs"],
            Some("{dir}/o2.pifs"),
        ),
        refuse(
            "empty file",
            &["encode", "{dir}/empty.png", "-o", "{dir}/o3.pifs"],
            Some("{dir}/o3.pifs"),
        ),
        refuse(
            "truncated PNG",
            &["encode", "{dir}/truncated.png", "-o", "{dir}/o4.pifs"],
            Some("{dir}/o4.pifs"),
        ),
        keep(refuse(
            "PNG with damaged image data (existing output kept)",
            &["encode", "{dir}/corrupt-data.png", "-o", "{dir}/o5.pifs"],
            Some("{dir}/o5.pifs"),
        )),
        refuse(
            "truncated JPEG",
            &["encode", "{dir}/truncated.jpg", "-o", "{dir}/o6.pifs"],
            Some("{dir}/o6.pifs"),
        ),
        refuse(
            "text file named .png",
            &["encode", "{dir}/text.png", "-o", "{dir}/o7.pifs"],
            Some("{dir}/o7.pifs"),
        ),
        refuse(
            "random bytes named .jpg",
            &["encode", "{dir}/random.jpg", "-o", "{dir}/o8.pifs"],
            Some("{dir}/o8.pifs"),
        ),
        refuse(
            "a .pifs stream given to encode",
            &["encode", "{dir}/good.pifs", "-o", "{dir}/o9.pifs"],
            Some("{dir}/o9.pifs"),
        ),
        refuse(
            "image wider than 65535 pixels",
            &[
                "encode",
                "{dir}/too-wide-65536x1.png",
                "-o",
                "{dir}/o10.pifs",
            ],
            Some("{dir}/o10.pifs"),
        ),
        // encode: outputs
        refuse(
            "output in a missing directory",
            &["encode", "{dir}/good.png", "-o", "{dir}/missing/o.pifs"],
            Some("{dir}/missing/o.pifs"),
        ),
        refuse(
            "output is a directory",
            &["encode", "{dir}/good.png", "-o", "{dir}/a-directory"],
            None,
        ),
        refuse(
            "output below a regular file",
            &["encode", "{dir}/good.png", "-o", "{dir}/a-file/o.pifs"],
            None,
        ),
        refuse(
            "output is the input file",
            &["encode", "{dir}/good.png", "-o", "{dir}/good.png"],
            None,
        ),
        refuse(
            "output on a read-only file system",
            &["encode", "{dir}/good.png", "-o", "/proc/pifs-out.pifs"],
            Some("/proc/pifs-out.pifs"),
        ),
        // encode: targets and flags
        keep(refuse(
            "impossible budget --bytes 3 (existing output kept)",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o11.pifs",
                "--bytes",
                "3",
            ],
            Some("{dir}/o11.pifs"),
        )),
        refuse(
            "--bytes 0",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o12.pifs",
                "--bytes",
                "0",
            ],
            Some("{dir}/o12.pifs"),
        ),
        refuse(
            "--bpp 0",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o13.pifs",
                "--bpp",
                "0",
            ],
            Some("{dir}/o13.pifs"),
        ),
        refuse(
            "--bpp -1",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o14.pifs",
                "--bpp=-1",
            ],
            Some("{dir}/o14.pifs"),
        ),
        refuse(
            "--bpp NaN",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o15.pifs",
                "--bpp",
                "NaN",
            ],
            Some("{dir}/o15.pifs"),
        ),
        refuse(
            "--bpp not a number",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o16.pifs",
                "--bpp",
                "lots",
            ],
            Some("{dir}/o16.pifs"),
        ),
        keep(refuse(
            "unreachable quality --psnr 200 (existing output kept)",
            &[
                "encode",
                "{dir}/slope.png",
                "-o",
                "{dir}/o17.pifs",
                "--psnr",
                "200",
            ],
            Some("{dir}/o17.pifs"),
        )),
        refuse(
            "--psnr 0",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o18.pifs",
                "--psnr",
                "0",
            ],
            Some("{dir}/o18.pifs"),
        ),
        refuse(
            "conflicting targets --bpp and --bytes",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o19.pifs",
                "--bpp",
                "0.5",
                "--bytes",
                "100",
            ],
            Some("{dir}/o19.pifs"),
        ),
        refuse(
            "--min-leaf-log2 0",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o20.pifs",
                "--min-leaf-log2",
                "0",
            ],
            Some("{dir}/o20.pifs"),
        ),
        refuse(
            "--max-leaf-log2 8",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o21.pifs",
                "--max-leaf-log2",
                "8",
            ],
            Some("{dir}/o21.pifs"),
        ),
        refuse(
            "unknown flag",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o22.pifs",
                "--quality",
                "9",
            ],
            Some("{dir}/o22.pifs"),
        ),
        refuse(
            "a packet option without packets",
            &[
                "encode",
                "{dir}/good.png",
                "-o",
                "{dir}/o24.pifs",
                "--parity",
                "3",
            ],
            Some("{dir}/o24.pifs"),
        ),
        refuse(
            "--expect-loss out of range",
            &[
                "encode",
                "{dir}/good.png",
                "--packets",
                "{dir}/pk-loss",
                "--bpp",
                "1",
                "--expect-loss",
                "0.9",
            ],
            Some("{dir}/pk-loss"),
        ),
        refuse(
            "stream output named like an image",
            &["encode", "{dir}/good.png", "-o", "{dir}/o23.png"],
            Some("{dir}/o23.png"),
        ),
        refuse("no output given", &["encode", "{dir}/good.png"], None),
        refuse("unknown subcommand", &["compress", "{dir}/good.png"], None),
        // decode and info
        refuse(
            "decode: missing file",
            &["decode", "{dir}/nope.pifs", "-o", "{dir}/d1.png"],
            Some("{dir}/d1.png"),
        ),
        refuse(
            "decode: input is a directory",
            &["decode", "{dir}/a-directory", "-o", "{dir}/d2.png"],
            Some("{dir}/d2.png"),
        ),
        refuse(
            "decode: a PNG given to decode",
            &["decode", "{dir}/good.png", "-o", "{dir}/d3.png"],
            Some("{dir}/d3.png"),
        ),
        refuse(
            "decode --follow: a PNG read as framed packets",
            &[
                "decode",
                "{dir}/good.png",
                "--follow",
                "-o",
                "{dir}/d3f.png",
            ],
            Some("{dir}/d3f.png"),
        ),
        refuse(
            "info: --svg of several inputs",
            &[
                "info",
                "{dir}/good.pifsp",
                "{dir}/good.pifsp",
                "--svg",
                "{dir}/i9.svg",
            ],
            Some("{dir}/i9.svg"),
        ),
        refuse(
            "packets resend: a packet the set does not hold",
            &[
                "packets",
                "resend",
                "{dir}/good.pifsp",
                "--only",
                "0,400",
                "-o",
                "{dir}/r1.pifsp",
            ],
            Some("{dir}/r1.pifsp"),
        ),
        refuse(
            "packets resend: indices backwards",
            &[
                "packets",
                "resend",
                "{dir}/good.pifsp",
                "--only",
                "5-2",
                "-o",
                "{dir}/r2.pifsp",
            ],
            Some("{dir}/r2.pifsp"),
        ),
        refuse(
            "decode --follow: into standard output",
            &["decode", "{dir}/good.png", "--follow", "-o", "-"],
            None,
        ),
        refuse(
            "decode: empty file",
            &["decode", "{dir}/empty.pifs", "-o", "{dir}/d4.png"],
            Some("{dir}/d4.png"),
        ),
        keep(refuse(
            "decode: truncated stream (existing output kept)",
            &["decode", "{dir}/truncated.pifs", "-o", "{dir}/d5.png"],
            Some("{dir}/d5.png"),
        )),
        refuse(
            "decode: one flipped bit in the payload",
            &["decode", "{dir}/bit-flip.pifs", "-o", "{dir}/d6.png"],
            Some("{dir}/d6.png"),
        ),
        refuse(
            "decode: stream from a newer format version",
            &["decode", "{dir}/version-next.pifs", "-o", "{dir}/d7.png"],
            Some("{dir}/d7.png"),
        ),
        refuse(
            "decode: stream of the format version before",
            &["decode", "{dir}/version-before.pifs", "-o", "{dir}/d7a.png"],
            Some("{dir}/d7a.png"),
        ),
        refuse(
            "decode: stream of format 21",
            &["decode", "{dir}/version-21.pifs", "-o", "{dir}/d7b.png"],
            Some("{dir}/d7b.png"),
        ),
        refuse(
            "decode: bytes after the stream",
            &["decode", "{dir}/trailing-bytes.pifs", "-o", "{dir}/d8.png"],
            Some("{dir}/d8.png"),
        ),
        refuse(
            "decode: header announcing 65535x65535 pixels",
            &["decode", "{dir}/huge-header.pifs", "-o", "{dir}/d9.png"],
            Some("{dir}/d9.png"),
        ),
        refuse(
            "decode: image above --max-pixels",
            &[
                "decode",
                "{dir}/good.pifs",
                "-o",
                "{dir}/d10.png",
                "--max-pixels",
                "1000",
            ],
            Some("{dir}/d10.png"),
        ),
        refuse(
            "decode: packets whose picture at --scale 4 is above --max-pixels",
            &[
                "decode",
                "{dir}/good.pifsp",
                "-o",
                "{dir}/d10s.png",
                "--scale",
                "4",
                "--max-pixels",
                "10000",
            ],
            Some("{dir}/d10s.png"),
        ),
        refuse(
            "decode: unsupported output format .jpg",
            &["decode", "{dir}/good.pifs", "-o", "{dir}/d11.jpg"],
            Some("{dir}/d11.jpg"),
        ),
        refuse(
            "decode: output without an extension",
            &["decode", "{dir}/good.pifs", "-o", "{dir}/d12"],
            Some("{dir}/d12"),
        ),
        refuse(
            "decode: output in a missing directory",
            &["decode", "{dir}/good.pifs", "-o", "{dir}/missing/d.png"],
            Some("{dir}/missing/d.png"),
        ),
        refuse("info: a PNG", &["info", "{dir}/good.png"], None),
        refuse(
            "info: truncated stream",
            &["info", "{dir}/truncated.pifs"],
            None,
        ),
        refuse(
            "info: drawing named like an image",
            &["info", "{dir}/good.pifs", "--svg", "{dir}/i1.png"],
            Some("{dir}/i1.png"),
        ),
        refuse(
            "rd: a rate of 0",
            &["rd", "{dir}/good.png", "--rates", "0.1,0"],
            None,
        ),
        // unusual but valid images
        accept(
            "16-bit grayscale PNG",
            &[
                "encode",
                "{dir}/gray16.png",
                "-o",
                "{dir}/a1.pifs",
                "--bytes",
                "200",
            ],
            "{dir}/a1.pifs",
        ),
        accept(
            "16-bit RGBA PNG",
            &[
                "encode",
                "{dir}/rgba16.png",
                "-o",
                "{dir}/a2.pifs",
                "--bytes",
                "200",
            ],
            "{dir}/a2.pifs",
        ),
        accept(
            "RGBA PNG (composited over white)",
            &[
                "encode",
                "{dir}/rgba.png",
                "-o",
                "{dir}/a3.pifs",
                "--bytes",
                "200",
            ],
            "{dir}/a3.pifs",
        ),
        accept(
            "grayscale + alpha PNG",
            &[
                "encode",
                "{dir}/gray-alpha.png",
                "-o",
                "{dir}/a4.pifs",
                "--bytes",
                "200",
            ],
            "{dir}/a4.pifs",
        ),
        accept(
            "palette PNG",
            &[
                "encode",
                "{dir}/palette.png",
                "-o",
                "{dir}/a5.pifs",
                "--bytes",
                "200",
            ],
            "{dir}/a5.pifs",
        ),
        accept(
            "1x1 image",
            &[
                "encode",
                "{dir}/one-pixel.png",
                "-o",
                "{dir}/a6.pifs",
                "--bytes",
                "200",
            ],
            "{dir}/a6.pifs",
        ),
        accept(
            "flat image",
            &["encode", "{dir}/flat.png", "-o", "{dir}/a7.pifs"],
            "{dir}/a7.pifs",
        ),
        accept(
            "pure noise",
            &[
                "encode",
                "{dir}/noise.png",
                "-o",
                "{dir}/a8.pifs",
                "--bpp",
                "1",
            ],
            "{dir}/a8.pifs",
        ),
        accept(
            "65535x1 image",
            &[
                "encode",
                "{dir}/wide-65535x1.png",
                "-o",
                "{dir}/a9.pifs",
                "--bpp",
                "0.5",
            ],
            "{dir}/a9.pifs",
        ),
        accept(
            "decode of a valid stream",
            &["decode", "{dir}/good.pifs", "-o", "{dir}/a10.png"],
            "{dir}/a10.png",
        ),
        accept(
            "decode to PPM (the grey in every channel)",
            &["decode", "{dir}/good.pifs", "-o", "{dir}/a11.ppm"],
            "{dir}/a11.ppm",
        ),
        accept(
            "1x1 image, no target (the smallest stream)",
            &["encode", "{dir}/one-pixel.png", "-o", "{dir}/a12.pifs"],
            "{dir}/a12.pifs",
        ),
        // curves
        refuse(
            "curve CSV with a line that is not numbers",
            &[
                "curve",
                "fit",
                "{dir}/bad-curve.csv",
                "--points",
                "4",
                "-o",
                "{dir}/c1.json",
            ],
            Some("{dir}/c1.json"),
        ),
        keep(refuse(
            "curve CSV of one point (existing output kept)",
            &[
                "curve",
                "fit",
                "{dir}/one-point.csv",
                "--points",
                "4",
                "-o",
                "{dir}/c2.json",
            ],
            Some("{dir}/c2.json"),
        )),
        refuse(
            "random bytes named .csv",
            &[
                "curve",
                "fit",
                "{dir}/random.csv",
                "--points",
                "4",
                "-o",
                "{dir}/c3.json",
            ],
            Some("{dir}/c3.json"),
        ),
        refuse(
            "SVG path with curved segments",
            &[
                "curve",
                "fit",
                "{dir}/curved-path.svg",
                "--points",
                "4",
                "-o",
                "{dir}/c4.json",
            ],
            Some("{dir}/c4.json"),
        ),
        refuse(
            "more parameters than resampled coordinates",
            &[
                "curve",
                "fit",
                "{dir}/curve.csv",
                "--points",
                "12",
                "--resample",
                "20",
                "-o",
                "{dir}/c5.json",
            ],
            Some("{dir}/c5.json"),
        ),
        refuse(
            "curve fit to an image name",
            &[
                "curve",
                "fit",
                "{dir}/curve.csv",
                "--points",
                "4",
                "-o",
                "{dir}/c6.png",
            ],
            Some("{dir}/c6.png"),
        ),
        refuse(
            "curve file of another version",
            &[
                "curve",
                "render",
                "{dir}/not-a-curve.json",
                "-o",
                "{dir}/c7.svg",
            ],
            Some("{dir}/c7.svg"),
        ),
        accept(
            "curve fit of a CSV polyline",
            &[
                "curve",
                "fit",
                "{dir}/curve.csv",
                "--points",
                "4",
                "-o",
                "{dir}/c8.json",
            ],
            "{dir}/c8.json",
        ),
    ]
}

const SENTINEL: &[u8] = b"an earlier file that must survive\n";

/// Runs one case and returns its table row.
fn run(case: &Case, dir: &Path) -> String {
    if let Some(out) = &case.output {
        if case.existing_output {
            std::fs::write(out, SENTINEL).unwrap();
        } else {
            let _ = std::fs::remove_file(out);
        }
    }
    let out = pifs().args(&case.args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let code = out.status.code();
    let label = &case.what;
    assert!(!stderr.contains("panicked"), "{label}: panic: {stderr}");
    assert_ne!(code, Some(101), "{label}: exit 101");
    assert!(code.is_some(), "{label}: killed by a signal");
    let output_state = match &case.output {
        None => "none".to_string(),
        Some(p) => match std::fs::read(p) {
            Err(_) => "none".to_string(),
            Ok(b) if b == SENTINEL => "earlier file untouched".to_string(),
            Ok(_) => "the new output".to_string(),
        },
    };
    match case.expect {
        Expect::Refused => {
            assert_ne!(code, Some(0), "{label}: accepted");
            assert_eq!(stderr.trim_end().lines().count(), 1, "{label}: {stderr:?}");
            assert!(stderr.starts_with("pifs: "), "{label}: {stderr:?}");
            let expected = if case.existing_output {
                "earlier file untouched"
            } else {
                "none"
            };
            assert_eq!(output_state, expected, "{label}: output left behind");
            let leftovers = std::fs::read_dir(dir)
                .unwrap()
                .filter_map(Result::ok)
                .filter(|e| e.file_name().to_string_lossy().starts_with(".pifs-tmp"))
                .count();
            assert_eq!(leftovers, 0, "{label}: temporary file left behind");
        }
        Expect::Accepted => {
            assert_eq!(code, Some(0), "{label}: {stderr}");
            let path = case.output.as_ref().unwrap();
            let bytes = std::fs::read(path).unwrap();
            if path.extension().is_some_and(|e| e == "pifs") {
                // As a host decodes: stripes of any width.
                let decoder = decoder_core::Decoder::new(&bytes)
                    .unwrap_or_else(|e| panic!("{label}: {e}"))
                    .stripe_capacity::<65536>();
                let mut px = vec![
                    0u8;
                    decoder.header().pixel_count()
                        * usize::from(decoder.header().channels)
                ];
                decoder
                    .decode_into(&mut px)
                    .unwrap_or_else(|e| panic!("{label}: {e}"));
            } else if path.extension().is_some_and(|e| e == "json") {
                let text = String::from_utf8(bytes).unwrap();
                host_encoder::curve::CurveFile::parse(&text)
                    .unwrap_or_else(|e| panic!("{label}: {e}"));
            } else {
                image::open(path).unwrap_or_else(|e| panic!("{label}: {e}"));
            }
        }
    }
    let message = mask_encoder_figures(&stderr.trim_end().replace(&*dir.to_string_lossy(), "DIR"));
    let message = if message.is_empty() {
        "—".into()
    } else {
        format!("`{}`", message.replace('|', "\\|"))
    };
    let command = case
        .args
        .iter()
        .map(|a| a.replace(&*dir.to_string_lossy(), "DIR"))
        .collect::<Vec<_>>()
        .join(" ");
    let outcome = match case.expect {
        Expect::Refused => format!("refused, exit {}", code.unwrap()),
        Expect::Accepted => "accepted, exit 0".into(),
    };
    format!("| {label} | `pifs {command}` | {outcome} | {message} | {output_state} |")
}

/// The figures in a message that come out of the encoder (smallest stream, best PSNR, the
/// checksums of a stream it wrote, the rates and sizes that follow from them) depend on
/// floating-point details of the machine, and a memory budget on the machine itself; the table
/// shows them as `N`.
pub fn mask_encoder_figures(message: &str) -> String {
    let mut out = message.to_string();
    for (marker, end) in [
        ("smallest stream for this image is ", " bytes"),
        ("reaches is ", " dB"),
        ("its checksum is ", ","),
        ("the header says ", ""),
        ("is N bytes: use --bpp ", " or more"),
        ("or more, or --bytes ", ""),
        ("is N bytes: use --bytes ", " or more"),
        ("more than ", " allowed by the memory available"),
    ] {
        let mut from = 0;
        while let Some(start) = out[from..].find(marker).map(|i| from + i + marker.len()) {
            let len = if end.is_empty() {
                out.len() - start
            } else {
                match out[start..].find(end) {
                    Some(l) => l,
                    None => break,
                }
            };
            out.replace_range(start..start + len, "N");
            from = start + 1;
        }
    }
    out
}

/// Kills an encode mid-way (SIGKILL during the analysis) and checks the output path: absent
/// when there was none, and an earlier file there intact.
fn interrupted_encode(dir: &Path) -> Vec<String> {
    let input = dir.join("big-noise.png");
    gray_png(&input, 768, 512, noise);
    let mut rows = Vec::new();
    for existing in [false, true] {
        let output = dir.join(format!("killed-{existing}.pifs"));
        if existing {
            std::fs::write(&output, SENTINEL).unwrap();
        }
        let mut child = pifs()
            .args(["encode", "--bpp", "0.5", "-o"])
            .arg(&output)
            .arg(&input)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(700));
        let still_running = child.try_wait().unwrap().is_none();
        assert!(still_running, "the encode ended before it could be killed");
        child.kill().unwrap();
        child.wait().unwrap();
        let state = match std::fs::read(&output) {
            Err(_) => "none",
            Ok(b) if b == SENTINEL => "earlier file untouched",
            Ok(_) => panic!("a killed encode left a file at its output path"),
        };
        assert_eq!(
            state,
            if existing {
                "earlier file untouched"
            } else {
                "none"
            }
        );
        let what = if existing {
            "encode killed (SIGKILL) mid-way, output existed"
        } else {
            "encode killed (SIGKILL) mid-way"
        };
        rows.push(format!(
            "| {what} | `pifs encode --bpp 0.5 -o DIR/{} DIR/big-noise.png` | killed after 0.7 s | — | {state} |",
            output.file_name().unwrap().to_string_lossy()
        ));
    }
    rows
}

#[test]
fn malformed_inputs_are_refused_cleanly_and_the_table_is_current() {
    let dir = scratch();
    make_inputs(&dir);
    let cases = cases(&dir);
    let refused = cases.iter().filter(|c| c.expect == Expect::Refused).count();
    assert!(refused >= 30, "only {refused} kinds of bad input");
    let mut rows: Vec<String> = cases.iter().map(|c| run(c, &dir)).collect();
    rows.extend(interrupted_encode(&dir));
    doc::section(doc::Section::Inputs, &render(&rows, refused));
}

fn render(rows: &[String], refused: usize) -> String {
    format!(
        "# Robustness of the `pifs` command line\n\
         \n\
         Generated by `bash scripts/robustness-table.sh` (the tests of\n\
         `host-encoder/tests/robustness_table.rs`, which also fail when this file is out of date).\n\
         Every row ran the real binary. For every refused input the test asserts a non-zero exit\n\
         that is not a panic, exactly one line on stderr, and no output left behind (where a file\n\
         existed at the output path before, it is byte for byte the same after). Accepted inputs\n\
         must produce an output that decodes. `DIR` stands for the test's scratch directory; `N`\n\
         for figures that come out of the encoder's search or the machine.\n\
         \n\
         {refused} kinds of bad input are refused; {} unusual but valid inputs are accepted.\n\
         \n\
         Conversion rule for images that are not 8-bit grayscale: colour to luma with the BT.601\n\
         weights; any bit depth scaled from its full range to 8 bits; palettes expanded;\n\
         transparency composited over white; the EXIF orientation applied; the first page of a\n\
         TIFF of several, the first frame of an animated GIF or WebP.\n\
         \n\
         | input | command | outcome | message (stderr) | file at the output path afterwards |\n\
         |---|---|---|---|---|\n\
         {}\n",
        rows.iter().filter(|r| r.contains("accepted, exit 0")).count(),
        rows.join("\n")
    )
}

/// Files in `fuzz/<dir>`, counted.
fn count_files(dir: &str) -> usize {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz")
        .join(dir);
    std::fs::read_dir(path)
        .map(|d| {
            d.filter_map(Result::ok)
                .filter(|e| e.path().is_file() && e.path().extension().is_none_or(|x| x != "md"))
                .count()
        })
        .unwrap_or(0)
}

/// Thousands separated by spaces: "100 000 000".
fn grouped(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(' ');
        }
        out.push(c);
    }
    out
}

/// The fuzzing section: the targets, their seeds, and the last campaign as `fuzz/run.sh
/// --record` wrote it in `fuzz/campaign.txt`, labelled with the format version it ran on.
#[test]
fn the_fuzz_campaign_is_reported() {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz");
    let record = std::fs::read_to_string(fuzz.join("campaign.txt")).unwrap_or_default();
    let field = |name: &str| {
        record
            .lines()
            .find_map(|l| l.strip_prefix(name).map(|v| v.trim().to_string()))
    };
    let targets = [
        "decode_bytes",
        "stream_equals_slice",
        "roundtrip",
        "encode_input",
        "large_dimensions",
        "decode_packets",
    ];
    let mut text = format!(
        "## Fuzzing\n\
         \n\
         Six `cargo fuzz` targets (`fuzz/README.md`): `decode_bytes` and `stream_equals_slice`\n\
         (any bytes as a stream, in memory and byte by byte), `roundtrip` (bytes made an image,\n\
         encoded and decoded), `encode_input` (image file bytes through the host's input side,\n\
         as `pifs encode` reads them) and `large_dimensions` (a valid header declaring up to\n\
         65535 x 65535 gray or colour pixels over a small payload, read header first by the\n\
         host and written band by band, compared with `decode_into`) and `decode_packets` (a\n\
         framed set of packets, each alone and drawn around the others' regions, then the\n\
         host's assembly of the set). Their checks are in\n\
         `tests/src/fuzz.rs`; `cargo test` replays them on every seed and regression input and\n\
         on a few thousand mutations (`tests/tests/fuzz_replay.rs`). The seeds in `fuzz/seeds/`\n\
         are made by the encoder (`tests/tests/fuzz_seeds.rs`, which also checks that they are\n\
         of the current format and use every model, both control codings, every control\n\
         quantiser, every leaf size, and colour at several sizes, odd ones among them):\n\
         {} streams, {} images, {} round-trip and {} large-dimension inputs, {} packet sets;\n\
         {} regression inputs. Beyond what fuzzing shows, the decoder has no panic path: the\n\
         QEMU tests (`tests/tests/qemu.rs`) check that the Cortex-M firmware holds no\n\
         decoder-core source location, which every panic path would bring into its data.\n\
         \n",
        count_files("seeds/streams"),
        count_files("seeds/encode_input"),
        count_files("seeds/roundtrip"),
        count_files("seeds/large_dimensions"),
        count_files("seeds/packets"),
        targets
            .iter()
            .map(|t| count_files(&format!("regressions/{t}")))
            .sum::<usize>(),
    );
    let version = field("format_version").and_then(|v| v.parse::<u8>().ok());
    match version {
        None => text.push_str(
            "No campaign is recorded yet: `bash fuzz/run.sh --jobs 2 --record SECONDS` runs one\n\
             and records it in `fuzz/campaign.txt`.\n",
        ),
        Some(v) => {
            let current = decoder_core::VERSION;
            let label = if v == current {
                format!("format version {v}, the current one")
            } else {
                format!("format version {v}; the format is now version {current}: run it again")
            };
            let commands: Vec<&str> = record
                .lines()
                .filter_map(|l| l.strip_prefix("command "))
                .collect();
            // run <target> <executions> <seconds> <jobs> <date>
            let mut per_target: Vec<(String, u64, u64)> = Vec::new();
            let mut dates = Vec::new();
            for line in record.lines().filter_map(|l| l.strip_prefix("run ")) {
                let f: Vec<&str> = line.split_whitespace().collect();
                let [t, n, secs, jobs, date] = f[..] else {
                    continue;
                };
                let n: u64 = n.parse().unwrap_or(0);
                let cpu = secs.parse::<u64>().unwrap_or(0) * jobs.parse::<u64>().unwrap_or(0);
                dates.push(date.to_string());
                match per_target.iter_mut().find(|(name, ..)| name == t) {
                    Some(entry) => {
                        entry.1 += n;
                        entry.2 += cpu;
                    }
                    None => per_target.push((t.to_string(), n, cpu)),
                }
            }
            dates.sort();
            text.push_str(&format!(
                "Recorded campaign ({label}; {} to {}), no sanitizer (decoder-core forbids unsafe \
                 code), debug assertions and overflow checks on, inputs up to 64 KiB, no crash:\n\
                 \n\
                 ```text\n{}\n```\n\
                 \n\
                 | target | executions | process time |\n|---|---|---|\n",
                dates.first().map(String::as_str).unwrap_or("?"),
                dates.last().map(String::as_str).unwrap_or("?"),
                commands.join("\n"),
            ));
            let mut total = 0u64;
            for (t, n, cpu) in &per_target {
                total += n;
                text.push_str(&format!(
                    "| `{t}` | {} | {:.1} h |\n",
                    grouped(*n),
                    *cpu as f64 / 3600.0
                ));
            }
            let cpu: u64 = per_target.iter().map(|e| e.2).sum();
            text.push_str(&format!(
                "| total | {} | {:.1} h |\n",
                grouped(total),
                cpu as f64 / 3600.0
            ));
        }
    }
    doc::section(doc::Section::Fuzzing, &text);
}
