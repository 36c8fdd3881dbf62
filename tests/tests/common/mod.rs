//! Shared helpers of the integration tests: deterministic synthetic images, PSNR, hashing,
//! encoder settings small enough to keep the suite fast.
#![allow(dead_code)]

use host_encoder::{analyse, Analysis, EncoderConfig, Plane};
use sha2::{Digest, Sha256};
use std::path::PathBuf;

/// A 32-bit linear congruential generator (Numerical Recipes constants): deterministic on
/// every platform, no dependency.
#[derive(Debug, Clone)]
pub struct Lcg(u32);

impl Lcg {
    pub fn new(seed: u32) -> Self {
        Lcg(seed ^ 0x9E37_79B9)
    }

    pub fn next_u32(&mut self) -> u32 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        self.0
    }

    /// Uniform in `0..n` (high bits: the low bits of an LCG are weak).
    pub fn below(&mut self, n: u32) -> u32 {
        ((u64::from(self.next_u32() >> 8) * u64::from(n)) >> 24) as u32
    }

    /// Uniform in `[-1, 1)`.
    pub fn unit(&mut self) -> f64 {
        f64::from(self.next_u32() >> 8) / f64::from(1u32 << 23) - 1.0
    }
}

/// A smooth diagonal gradient.
pub fn gradient(width: u32, height: u32) -> Plane {
    let mut data = Vec::with_capacity(width as usize * height as usize);
    let (w, h) = (f64::from(width.max(2) - 1), f64::from(height.max(2) - 1));
    for y in 0..height {
        for x in 0..width {
            let v = 20.0 + 150.0 * f64::from(x) / w + 70.0 * f64::from(y) / h;
            data.push(v.round().clamp(0.0, 255.0) as u8);
        }
    }
    Plane::new(width, height, data)
}

/// A synthetic test image: a gradient, a bright disc and a dark bar (edges), and a little
/// pseudo-random texture of amplitude `noise` grey levels. Deterministic in `seed`.
pub fn synthetic(width: u32, height: u32, seed: u32, noise: u32) -> Plane {
    let mut rng = Lcg::new(seed);
    let (wf, hf) = (f64::from(width), f64::from(height));
    let (cx, cy, r) = (wf * 0.62, hf * 0.38, wf.min(hf) * 0.22);
    let bar_x0 = (wf * 0.15) as u32;
    let bar_x1 = bar_x0 + (width / 8).max(1);
    let mut data = Vec::with_capacity(width as usize * height as usize);
    for y in 0..height {
        for x in 0..width {
            let (xf, yf) = (f64::from(x), f64::from(y));
            let mut v = 40.0 + 120.0 * xf / wf.max(1.0) + 60.0 * yf / hf.max(1.0);
            v += 12.0 * (xf * 0.21).sin() * (yf * 0.13).cos();
            if (xf - cx).powi(2) + (yf - cy).powi(2) < r * r {
                v += 55.0;
            }
            if (bar_x0..bar_x1).contains(&x) && y > height / 3 {
                v -= 70.0;
            }
            let n = if noise > 0 {
                rng.below(2 * noise + 1) as f64 - f64::from(noise)
            } else {
                0.0
            };
            data.push((v + n).round().clamp(0.0, 255.0) as u8);
        }
    }
    Plane::new(width, height, data)
}

/// Leaf settings small enough for fast tests: leaves from 4x4 to 32x32.
pub fn small_config() -> EncoderConfig {
    EncoderConfig {
        min_leaf_log2: 2,
        max_leaf_log2: 5,
        ..EncoderConfig::default()
    }
}

/// A deterministic RGB image (`3 * width * height` bytes): red is a [`synthetic`] plane of
/// seed `seed`, green the one of `seed + 1` mirrored left to right, blue the one of `seed + 2`
/// inverted (so that hue and saturation vary across the image, with shared edges).
#[allow(dead_code)]
pub fn synthetic_rgb(width: u32, height: u32, seed: u32) -> Vec<u8> {
    let planes: Vec<Plane> = (0..3)
        .map(|k| synthetic(width, height, seed + k, 6))
        .collect();
    let mut out = Vec::with_capacity(3 * planes[0].data.len());
    for y in 0..height {
        for x in 0..width {
            out.push(planes[0].get(x, y));
            out.push(planes[1].get(width - 1 - x, y));
            out.push(255 - planes[2].get(x, y));
        }
    }
    out
}

/// Analyses `plane` with `config`, panicking on error (test helper).
pub fn analyse_with(plane: Plane, config: &EncoderConfig) -> Analysis {
    analyse(plane, config, &|_| {}).expect("analysis")
}

/// Squared error between two equally long pixel buffers.
pub fn sse(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(&p, &q)| {
            let d = f64::from(p) - f64::from(q);
            d * d
        })
        .sum()
}

/// PSNR (peak 255) between two equally long pixel buffers.
pub fn psnr_u8(a: &[u8], b: &[u8]) -> f64 {
    host_encoder::psnr(sse(a, b), a.len())
}

/// Decodes `stream` with decoder-core into a fresh buffer sized from its header.
pub fn decode_all(
    stream: &[u8],
) -> Result<(decoder_core::Header, Vec<u8>), decoder_core::DecodeError> {
    let header = decoder_core::Header::read(stream)?;
    let mut out = vec![0u8; header.pixel_count() * usize::from(header.channels)];
    let h = pifs_tests::decode_into(stream, &mut out)?;
    assert_eq!(h, header, "decode_into returned a different header");
    Ok((header, out))
}

/// Lower-case hexadecimal SHA-256.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// `tests/golden/`.
pub fn golden_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("golden")
}

#[allow(unused_imports)]
pub use pifs_tests::CoverageSink;

/// The fields of every line of the list `tests/golden/<name>` (blank lines and lines
/// starting with `#` are skipped), each line checked to have `fields` of them.
fn list_lines(name: &str, fields: usize) -> Vec<Vec<String>> {
    let path = golden_dir().join(name);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (run the `regenerate` golden test)", path.display()));
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| {
            let f: Vec<String> = l.split_whitespace().map(str::to_string).collect();
            assert_eq!(f.len(), fields, "{name}: bad line {l:?}");
            f
        })
        .collect()
}

/// One line of `tests/golden/golden.txt`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GoldenEntry {
    pub file: String,
    pub width: u16,
    pub height: u16,
    pub sha256: String,
}

/// Parses `tests/golden/golden.txt` (`<file> <width> <height> <sha256>` per line; blank lines
/// and lines starting with `#` are ignored).
pub fn golden_list() -> Vec<GoldenEntry> {
    entries("golden.txt")
}

/// The lines of a list in `golden.txt`'s form (`<file> <width> <height> <sha256>`).
fn entries(name: &str) -> Vec<GoldenEntry> {
    list_lines(name, 4)
        .into_iter()
        .map(|f| GoldenEntry {
            file: f[0].clone(),
            width: f[1].parse().expect("width"),
            height: f[2].parse().expect("height"),
            sha256: f[3].to_string(),
        })
        .collect()
}

/// Parses `tests/golden/values.txt`: the 16-bit golden streams, each with the SHA-256 of its
/// decoded values (row-major, each value little-endian), in `golden.txt`'s form.
#[allow(dead_code)]
pub fn golden_values() -> Vec<GoldenEntry> {
    entries("values.txt")
}

/// A stream's decoded values ([`decoder_core::Decoder::decode_values_into`]) as the bytes
/// `values.txt` hashes: row-major, little-endian.
#[allow(dead_code)]
pub fn decode_values(stream: &[u8]) -> Result<Vec<u8>, decoder_core::DecodeError> {
    let header = decoder_core::Header::read(stream)?;
    let mut out = vec![0u16; header.pixel_count() * usize::from(header.channels)];
    decoder_core::Decoder::new(stream)?.decode_values_into(&mut out)?;
    Ok(out.iter().flat_map(|v| v.to_le_bytes()).collect())
}

/// The golden streams: `(file name, bytes)`.
pub fn golden_streams() -> Vec<(String, Vec<u8>)> {
    golden_list()
        .into_iter()
        .map(|g| {
            let path = golden_dir().join(&g.file);
            let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            (g.file, bytes)
        })
        .collect()
}

/// A complete, correctly checksummed stream: `header` (its payload length set to fit) and
/// `payload`, so that tests reach the payload syntax behind the checksum.
pub fn sealed_stream(header: &decoder_core::Header, payload: &[u8]) -> Vec<u8> {
    let header = decoder_core::Header {
        payload_len: payload.len() as u32,
        ..*header
    };
    let mut bytes = vec![0u8; header.encoded_len()];
    header.write(&mut bytes);
    bytes.extend_from_slice(payload);
    decoder_core::internal::syntax::seal(&mut bytes);
    bytes
}

/// One line of `tests/golden/packets.txt`: a framed packet set, the packets a receiver is
/// made to lose, and the SHA-256 of the image assembled from all of them and from the rest.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GoldenPackets {
    pub file: String,
    pub width: u16,
    pub height: u16,
    pub lost: Vec<u16>,
    pub sha256_all: String,
    pub sha256_lossy: String,
}

/// Parses `tests/golden/packets.txt` (`<file> <width> <height> <lost,indices> <sha256 of all>
/// <sha256 with the lost ones missing>` per line).
pub fn golden_packets() -> Vec<GoldenPackets> {
    list_lines("packets.txt", 6)
        .into_iter()
        .map(|f| GoldenPackets {
            file: f[0].clone(),
            width: f[1].parse().expect("width"),
            height: f[2].parse().expect("height"),
            lost: f[3].split(',').map(|i| i.parse().expect("index")).collect(),
            sha256_all: f[4].to_string(),
            sha256_lossy: f[5].to_string(),
        })
        .collect()
}

/// `tests/golden/parity.txt`: a packet set with parity packets, the data packets lost, the
/// picture of the whole set.
pub struct GoldenParity {
    pub file: String,
    pub width: u16,
    pub height: u16,
    pub lost: Vec<u16>,
    pub sha256_all: String,
}

/// Parses `tests/golden/parity.txt` (`<file> <width> <height> <lost,indices> <sha256 of
/// all>`, one line).
pub fn golden_parity() -> GoldenParity {
    let mut lines = list_lines("parity.txt", 5);
    assert_eq!(lines.len(), 1, "parity.txt: one set");
    let f = lines.remove(0);
    GoldenParity {
        file: f[0].clone(),
        width: f[1].parse().expect("width"),
        height: f[2].parse().expect("height"),
        lost: f[3].split(',').map(|i| i.parse().expect("index")).collect(),
        sha256_all: f[4].to_string(),
    }
}

/// The packets of a framed golden set, and those left when `lost` are lost.
pub fn golden_packet_set(g: &GoldenPackets) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    let path = golden_dir().join(&g.file);
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let all = host_encoder::packets::unframe(&bytes);
    let kept = all
        .iter()
        .filter(|p| {
            let index = decoder_core::Packet::parse(p).expect("golden packet").index;
            !g.lost.contains(&index)
        })
        .cloned()
        .collect();
    (all, kept)
}
