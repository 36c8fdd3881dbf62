//! The example firmware (`firmware-example/`) on emulated Cortex-M boards.
//!
//! Each test builds the firmware for one target with a nested `cargo build --release` (run in
//! the firmware folder, so that its `.cargo/config.toml` applies), runs it under
//! `qemu-system-arm` (with a hang guard), and checks that QEMU exits successfully and that, for
//! every golden vector of `tests/golden/golden.txt`, the firmware's hashes equal the ones the
//! host computes here with decoder-core:
//!
//! - `sha256`: the row-major decoded pixels (also checked against `golden.txt`);
//! - `tiles`: the tiles in arrival order (per tile `x, y, w, h` as u32 LE, then the pixels);
//! - `PIFS-FB`: the frame-buffer decode of the smallest vector;
//! - `PIFS-PACKETS`: each golden packet set of `tests/golden/packets.txt`, received out of
//!   order with some packets lost, hashed from a frame buffer; `PIFS-PACKETS-DRAWN`: the same
//!   received onto a display through `graphics::DrawSink` (RGB565 for colour, 1-bit for gray,
//!   dithered);
//! - `PIFS-PARITY`: the golden parity set of `tests/golden/parity.txt`, its lost data packets
//!   rebuilt on the device from its parity packets (`decoder_core::Rebuild`) and drawn: the
//!   whole set's picture;
//! - `PIFS-SCALED`: the row-major hash of every vector decoded at 1/4, 1/2 and 2 times its size
//!   (`PifsImage::with_scale`);
//! - `PIFS-VALUES`: the values of every 16-bit vector (`tests/golden/values.txt`), row-major,
//!   each u16 little-endian.
//!
//! Colour vectors are drawn by the firmware on an `Rgb565` display: their hashes are of each
//! pixel's RGB565 value (u16 little-endian) instead of the luma byte, which the host computes
//! from its RGB decode as `PifsImage` draws it by default: ordered-dithered at the pixel's
//! position in the (scaled) image (`FromGray::from_rgb_with`, `Threshold::ordered`).
//!
//! Before running it, each test checks that the firmware holds no decoder panic path (no
//! decoder-core source location in its loaded data): the decoder answers any bytes with a
//! value, never a panic.
//!
//! QEMU is required: without `qemu-system-arm` these tests fail (CI installs it with
//! `apt-get install -y --no-install-recommends qemu-system-arm`).

mod common;

use common::{decode_all, golden_dir, golden_list, sha256_hex};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const QEMU: &str = "qemu-system-arm";
/// Hang guard for one QEMU run (a run takes about a second; a wrong memory layout hangs).
const QEMU_TIMEOUT: Duration = Duration::from_secs(120);

struct Board {
    target: &'static str,
    machine: &'static str,
    cpu: &'static str,
    ram: &'static str,
}

const LM3S6965EVB: Board = Board {
    target: "thumbv7m-none-eabi",
    machine: "lm3s6965evb",
    cpu: "cortex-m3",
    ram: "64 KiB",
};

const MICROBIT: Board = Board {
    target: "thumbv6m-none-eabi",
    machine: "microbit",
    cpu: "cortex-m0",
    ram: "16 KiB",
};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn require_qemu() {
    match Command::new(QEMU).arg("--version").output() {
        Ok(out) if out.status.success() => {}
        Ok(out) => panic!("`{QEMU} --version` failed: {out:?}"),
        Err(e) => panic!(
            "{QEMU} is required by this test but could not be run ({e}). Install it with:\n    \
             apt-get update && apt-get install -y --no-install-recommends qemu-system-arm"
        ),
    }
}

/// Builds the firmware for `target`; returns the ELF's path.
fn build_firmware(target: &str) -> PathBuf {
    let dir = root().join("firmware-example");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(cargo)
        .args(["build", "--release", "--target", target])
        .current_dir(&dir)
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("CARGO_BUILD_TARGET")
        .env_remove("CARGO_BUILD_TARGET_DIR")
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_RUSTFLAGS")
        .output()
        .expect("run cargo");
    assert!(
        out.status.success(),
        "building the firmware for {target} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // `.cargo/config.toml` of the firmware puts its builds in <root>/target/firmware.
    let elf = root()
        .join("target/firmware")
        .join(target)
        .join("release/pifs-firmware-example");
    assert!(elf.is_file(), "{} missing after the build", elf.display());
    elf
}

/// The decoder-core source paths in the loaded sections of the firmware `elf` (a 32-bit
/// little-endian ELF). A panic path carries its source location, file name included, into the
/// firmware's read-only data, and nothing else in decoder-core does: none there means the
/// decoder cannot panic, whatever the bytes it is given (the debug sections, which are not
/// loaded, are skipped).
fn decoder_panic_sites(elf: &Path) -> Vec<String> {
    const NEEDLE: &[u8] = b"decoder-core/src/";
    const SHF_ALLOC: u32 = 2;
    let data = std::fs::read(elf).expect("read the firmware");
    let u16_at = |at: usize| u16::from_le_bytes([data[at], data[at + 1]]) as usize;
    let u32_at = |at: usize| u32::from_le_bytes(data[at..at + 4].try_into().unwrap());
    assert_eq!(
        &data[..5],
        b"\x7fELF\x01",
        "{}: not a 32-bit ELF",
        elf.display()
    );
    let (shoff, shentsize, shnum) = (u32_at(0x20) as usize, u16_at(0x2E), u16_at(0x30));
    let mut sites = Vec::new();
    for k in 0..shnum {
        let header = shoff + k * shentsize;
        let (kind, flags) = (u32_at(header + 4), u32_at(header + 8));
        // Sections with contents (not NOBITS) that are loaded.
        if kind == 8 || flags & SHF_ALLOC == 0 {
            continue;
        }
        let (offset, size) = (
            u32_at(header + 0x10) as usize,
            u32_at(header + 0x14) as usize,
        );
        let bytes = &data[offset..offset + size];
        let mut at = 0;
        while let Some(found) = bytes[at..].windows(NEEDLE.len()).position(|w| w == NEEDLE) {
            let start = at + found;
            let end = bytes[start..]
                .iter()
                .position(|&b| b == 0 || !b.is_ascii_graphic())
                .map_or(bytes.len(), |n| start + n);
            sites.push(String::from_utf8_lossy(&bytes[start..end]).into_owned());
            at = end;
        }
    }
    sites
}

/// Runs `elf` on `board`; returns (exit code, stdout bytes, stderr text).
fn run_qemu(board: &Board, elf: &Path) -> (Option<i32>, Vec<u8>, String) {
    let mut child = Command::new(QEMU)
        .args(["-cpu", board.cpu, "-machine", board.machine])
        .args(["-display", "none", "-monitor", "none", "-serial", "none"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=0", "-kernel"])
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {QEMU}: {e}"));
    let mut stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let out_reader = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = stdout.read_to_end(&mut v);
        v
    });
    let err_reader = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = stderr.read_to_end(&mut s);
        String::from_utf8_lossy(&s).into_owned()
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for QEMU") {
            break Some(status);
        }
        if start.elapsed() > QEMU_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let stdout = out_reader.join().unwrap();
    let stderr = err_reader.join().unwrap();
    match status {
        Some(status) => (status.code(), stdout, stderr),
        None => panic!(
            "{} on {}: QEMU did not finish within {QEMU_TIMEOUT:?} (hung firmware?); stderr so \
             far:\n{stderr}",
            board.target, board.machine
        ),
    }
}

/// `key=value` fields of a line.
fn fields(line: &str) -> BTreeMap<&str, &str> {
    line.split_whitespace()
        .filter_map(|f| f.split_once('='))
        .collect()
}

/// The bytes the firmware hashes of decoded pixels `area` (row-major, in image coordinates):
/// luma bytes as they are; RGB (three bytes a pixel) as the RGB565 value the firmware's
/// display gets, dithered at the pixel's position, u16 little-endian.
fn display_bytes(pixels: &[u8], channels: u8, area: decoder_core::Rect) -> Vec<u8> {
    use decoder_core::graphics::{FromGray, Threshold};
    use embedded_graphics::pixelcolor::raw::{RawData, RawU16};
    use embedded_graphics::pixelcolor::Rgb565;
    if channels != 3 {
        return pixels.to_vec();
    }
    let w = area.w.max(1) as usize;
    pixels
        .chunks_exact(3)
        .enumerate()
        .flat_map(|(i, p)| {
            let (x, y) = (area.x + (i % w) as u32, area.y + (i / w) as u32);
            let c = Rgb565::from_rgb_with(p[0], p[1], p[2], Threshold::ordered(x, y));
            RawU16::from(c).into_inner().to_le_bytes()
        })
        .collect()
}

/// SHA-256 of the tiles in arrival order, as the firmware's `tiles=` field.
struct TileHash(Sha256);

impl decoder_core::PixelSink for TileHash {
    type Error = std::convert::Infallible;

    fn tile(&mut self, tile: decoder_core::Tile<'_>) -> Result<(), Self::Error> {
        let decoder_core::Rect { x, y, w, h } = tile.area;
        for v in [x, y, w, h] {
            self.0.update(v.to_le_bytes());
        }
        self.0
            .update(display_bytes(tile.pixels, tile.channels, tile.area));
        Ok(())
    }
}

/// Per golden vector: (width, height, row-major sha256, tile sha256), from the host decoder.
fn host_hashes() -> BTreeMap<String, (u16, u16, String, String)> {
    let list = golden_list();
    assert!(!list.is_empty(), "golden.txt lists no vectors");
    list.into_iter()
        .map(|g| {
            let stream = std::fs::read(golden_dir().join(&g.file)).unwrap();
            let (header, pixels) =
                decode_all(&stream).unwrap_or_else(|e| panic!("{}: host decode: {e}", g.file));
            assert_eq!(
                sha256_hex(&pixels),
                g.sha256,
                "{}: the host decoder disagrees with golden.txt",
                g.file
            );
            let whole = decoder_core::Rect::of_size(header.width.into(), header.height.into());
            let sha = sha256_hex(&display_bytes(&pixels, header.channels, whole));
            assert_eq!(
                (header.width, header.height),
                (g.width, g.height),
                "{}",
                g.file
            );
            let mut tiles = TileHash(Sha256::new());
            pifs_tests::decode(&stream, &mut tiles).unwrap();
            let tiles: String = tiles
                .0
                .finalize()
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect();
            (g.file, (g.width, g.height, sha, tiles))
        })
        .collect()
}

/// Per golden vector and scale (1/4, 1/2, 2): the row-major sha256 of the host's scaled decode,
/// keyed `name scale-log2`, with the scaled width and height.
fn host_scaled_hashes() -> BTreeMap<String, (u32, u32, String)> {
    let mut out = BTreeMap::new();
    for g in golden_list() {
        let stream = std::fs::read(golden_dir().join(&g.file)).unwrap();
        for scale in [
            decoder_core::Scale::Quarter,
            decoder_core::Scale::Half,
            decoder_core::Scale::Double,
        ] {
            let decoder = decoder_core::Decoder::new(&stream).unwrap().scale(scale);
            let (w, h) = decoder.output_size();
            let channels = decoder.header().channels;
            let mut pixels = vec![0u8; (w * h) as usize * usize::from(channels)];
            decoder.decode_into(&mut pixels).unwrap();
            out.insert(
                format!("{} {}", g.file, scale.log2()),
                (
                    w,
                    h,
                    sha256_hex(&display_bytes(
                        &pixels,
                        channels,
                        decoder_core::Rect::of_size(w, h),
                    )),
                ),
            );
        }
    }
    out
}

fn check_board(board: &Board) {
    require_qemu();
    let expected = host_hashes();
    let elf = build_firmware(board.target);
    let sites = decoder_panic_sites(&elf);
    assert!(
        sites.is_empty(),
        "{}: the decoder has panic paths (their files are in the firmware's data): {sites:?}",
        board.target
    );
    let (code, _defmt_frames, stderr) = run_qemu(board, &elf);
    let context = format!(
        "{} on QEMU {} ({}, {} RAM)",
        board.target, board.machine, board.cpu, board.ram
    );
    let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("PIFS")).collect();
    for l in &lines {
        println!("{}: {l}", board.machine);
    }
    if stderr.contains("Lockup") {
        panic!(
            "{context}: the firmware locked up (usually a stack overflow: the decoder needs more \
             stack than the board has); last lines:\n{}",
            stderr
                .lines()
                .rev()
                .take(12)
                .collect::<Vec<_>>()
                .into_iter()
                .rev()
                .collect::<Vec<_>>()
                .join("\n")
        );
    }
    let errors: Vec<&&str> = lines
        .iter()
        .filter(|l| l.starts_with("PIFS-ERROR") || l.starts_with("PIFS-PANIC"))
        .collect();
    assert!(errors.is_empty(), "{context}: {errors:#?}");
    assert_eq!(
        code,
        Some(0),
        "{context}: QEMU exit status; stderr:\n{stderr}"
    );

    let mut seen = BTreeMap::new();
    for l in lines.iter().filter(|l| l.starts_with("PIFS name=")) {
        let f = fields(l);
        let name = f["name"].to_string();
        let (w, h, sha, tiles) = expected
            .get(&name)
            .unwrap_or_else(|| panic!("{context}: unknown vector in {l:?}"));
        assert_eq!(f["w"], w.to_string(), "{context}: {name} width");
        assert_eq!(f["h"], h.to_string(), "{context}: {name} height");
        assert_eq!(
            f["sha256"], sha,
            "{context}: {name}: pixel hash differs from the host's"
        );
        assert_eq!(
            f["tiles"], tiles,
            "{context}: {name}: tile hash differs from the host's"
        );
        let stack: usize = f["stack"].parse().expect("stack");
        let instr: u64 = f["instr"].parse().expect("instr");
        assert!(stack > 0, "{context}: {name}: no stack measured");
        assert!(instr > 0, "{context}: {name}: no instructions counted");
        assert!(
            seen.insert(name.clone(), ()).is_none(),
            "{context}: {name} twice"
        );
    }
    let missing: Vec<&String> = expected.keys().filter(|k| !seen.contains_key(*k)).collect();
    assert!(missing.is_empty(), "{context}: no result for {missing:?}");
    let colour = expected
        .keys()
        .filter(|k| {
            let stream = std::fs::read(golden_dir().join(k)).unwrap();
            decoder_core::Header::read(&stream).unwrap().channels == 3
        })
        .count();
    assert!(colour > 0, "{context}: no colour vector drawn in RGB565");

    let scaled = host_scaled_hashes();
    let mut seen_scaled = 0;
    for l in lines.iter().filter(|l| l.starts_with("PIFS-SCALED ")) {
        let f = fields(l);
        let key = format!("{} {}", f["name"], f["scale"]);
        let (w, h, sha) = scaled
            .get(&key)
            .unwrap_or_else(|| panic!("{context}: unknown scaled decode in {l:?}"));
        assert_eq!(
            (f["w"], f["h"]),
            (&*w.to_string(), &*h.to_string()),
            "{context}: {key}"
        );
        assert_eq!(
            f["sha256"], sha,
            "{context}: {key}: scaled decode differs from the host's"
        );
        seen_scaled += 1;
    }
    assert_eq!(
        seen_scaled,
        scaled.len(),
        "{context}: scaled decodes missing"
    );

    check_packets(&context, &lines);
    check_parity(&context, &lines);
    check_values(&context, &lines);

    let fb: Vec<&&str> = lines.iter().filter(|l| l.starts_with("PIFS-FB ")).collect();
    assert_eq!(fb.len(), 1, "{context}: frame-buffer lines {fb:?}");
    let f = fields(fb[0]);
    assert_eq!(
        f["sha256"], expected[f["name"]].2,
        "{context}: frame-buffer decode of {} differs from the host's",
        f["name"]
    );
}

/// Every 16-bit golden stream's values, decoded by the firmware one clipped row at a time,
/// hash as the host's do (and as `values.txt` records).
fn check_values(context: &str, lines: &[&str]) {
    let expected = common::golden_values();
    assert!(!expected.is_empty(), "values.txt lists no stream");
    let got: BTreeMap<&str, &str> = lines
        .iter()
        .filter(|l| l.starts_with("PIFS-VALUES "))
        .map(|l| {
            let f = fields(l);
            (f["name"], f["sha256"])
        })
        .collect();
    for g in &expected {
        let stream = std::fs::read(golden_dir().join(&g.file)).unwrap();
        assert_eq!(
            sha256_hex(&common::decode_values(&stream).unwrap()),
            g.sha256,
            "{}: host values",
            g.file
        );
        assert_eq!(
            got.get(g.file.as_str()).copied(),
            Some(g.sha256.as_str()),
            "{context}: {}: values differ from the host's",
            g.file
        );
    }
    assert_eq!(got.len(), expected.len(), "{context}: values of {got:?}");
}

/// The golden parity set, received by the firmware without its lost data packets, rebuilt in
/// a fixed buffer and drawn: the picture of the whole set, as the host assembles it.
fn check_parity(context: &str, lines: &[&str]) {
    let g = common::golden_parity();
    let found: Vec<&&str> = lines
        .iter()
        .filter(|l| l.starts_with("PIFS-PARITY "))
        .collect();
    assert_eq!(found.len(), 1, "{context}: parity lines {found:?}");
    let f = fields(found[0]);
    assert_eq!(f["name"], g.file, "{context}");
    assert_eq!(
        f["rebuilt"],
        g.lost.len().to_string(),
        "{context}: {}",
        g.file
    );
    assert_eq!(
        f["sha256"], g.sha256_all,
        "{context}: {}: the packets rebuilt on the device draw other pixels than the whole set",
        g.file
    );
    let stack: usize = f["stack"].parse().expect("stack");
    assert!(stack > 0, "{context}: {}: no stack measured", g.file);
}

/// Every golden packet set, received by the firmware out of order and without its lost
/// packets, draws what the host assembles from the same packets, at full and at half size.
fn check_packets(context: &str, lines: &[&str]) {
    let sets = common::golden_packets();
    let mut seen = 0;
    for l in lines.iter().filter(|l| l.starts_with("PIFS-PACKETS ")) {
        let f = fields(l);
        let g = sets
            .iter()
            .find(|g| g.file == f["name"])
            .unwrap_or_else(|| panic!("{context}: unknown packet set in {l:?}"));
        let (all, kept) = common::golden_packet_set(g);
        let host =
            host_encoder::packets::assemble(kept.iter().map(Vec::as_slice), u64::MAX).unwrap();
        assert_eq!(sha256_hex(&host.pixels), g.sha256_lossy, "{}: host", g.file);
        assert_eq!(
            f["received"],
            (all.len() - g.lost.len()).to_string(),
            "{context}: {}",
            g.file
        );
        assert_eq!(
            f["sha256"], g.sha256_lossy,
            "{context}: {}: the firmware's packets draw other pixels than the host's",
            g.file
        );
        let stack: usize = f["stack"].parse().expect("stack");
        assert!(stack > 0, "{context}: {}: no stack measured", g.file);
        let drawn = lines
            .iter()
            .find(|l| l.starts_with("PIFS-PACKETS-DRAWN ") && fields(l)["name"] == f["name"].trim())
            .unwrap_or_else(|| panic!("{context}: {}: not drawn on a display", g.file));
        assert_eq!(
            fields(drawn)["sha256"],
            sha256_hex(&panel_bytes(&host)),
            "{context}: {}: the packets drawn through DrawSink differ from the host's",
            g.file
        );
        let half = lines
            .iter()
            .find(|l| l.starts_with("PIFS-PACKETS-HALF ") && fields(l)["name"] == f["name"].trim())
            .unwrap_or_else(|| panic!("{context}: {}: not drawn at half size", g.file));
        let host_half = host_encoder::packets::assemble_at(
            kept.iter().map(Vec::as_slice),
            u64::MAX,
            decoder_core::Scale::Half,
        )
        .unwrap();
        assert_eq!(
            fields(half)["sha256"],
            sha256_hex(&host_half.pixels),
            "{context}: {}: the packets drawn at half size differ from the host's",
            g.file
        );
        seen += 1;
    }
    assert_eq!(seen, sets.len(), "{context}: packet sets missing");
}

/// The bytes of the firmware's display after a packet set (`PIFS-PACKETS-DRAWN`): an assembled
/// colour picture on RGB565 (u16 little-endian a pixel), a gray one on a 1-bit panel (a byte a
/// pixel, 0 or 1), each pixel ordered-dithered at its position.
fn panel_bytes(host: &host_encoder::packets::Assembled) -> Vec<u8> {
    use decoder_core::graphics::{FromGray, Threshold};
    use embedded_graphics::pixelcolor::raw::{RawData, RawU16};
    use embedded_graphics::pixelcolor::{BinaryColor, Rgb565};
    let w = host.width as usize;
    let step = usize::from(host.channels);
    host.pixels
        .chunks_exact(step)
        .enumerate()
        .flat_map(|(i, p)| {
            let t = Threshold::ordered((i % w) as u32, (i / w) as u32);
            match *p {
                [r, g, b] => RawU16::from(Rgb565::from_rgb_with(r, g, b, t))
                    .into_inner()
                    .to_le_bytes()
                    .to_vec(),
                _ => vec![u8::from(BinaryColor::from_gray_with(p[0], t).is_on())],
            }
        })
        .collect()
}

#[test]
fn firmware_on_cortex_m3_lm3s6965evb_matches_the_host() {
    check_board(&LM3S6965EVB);
}

#[test]
fn firmware_on_cortex_m0_microbit_matches_the_host() {
    check_board(&MICROBIT);
}
