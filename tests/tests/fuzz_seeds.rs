//! The fuzz targets' seeds (`fuzz/seeds/<kind>/`), made by the encoder from the deterministic
//! images of `common` and committed, so that every fuzz run (and `fuzz_replay`) starts from
//! streams that use every model, both control codings, every control quantiser, every leaf size,
//! many image sizes and colour (at odd sizes too, where the
//! chroma planes end half outside the image):
//!
//! ```text
//! cargo test -p pifs-tests --test fuzz_seeds -- --ignored regenerate
//! ```
//!
//! Regenerate after a format change (the test below fails until then). The kinds:
//!
//! - `streams/`: `.pifs` streams, for `decode_bytes` and `stream_equals_slice`;
//! - `roundtrip/`: inputs of the `roundtrip` check (size bytes, a budget byte, pixels);
//! - `encode_input/`: image files of every format and kind the host reads (grey, colour,
//!   alpha, 16-bit, palette, EXIF-oriented JPEG, a TIFF of two pages, PNM, BMP);
//! - `large_dimensions/`: inputs of that check (declared size, leaf sizes, channels, payload),
//!   the payloads of the encoder's gray and colour streams under large declared sizes;
//! - `packets/`: framed packet sets (gray, colour, with and without a preview, whole and with
//!   packets missing), for `decode_packets`.

mod common;

use decoder_core::internal::model::MODELS;
use decoder_core::internal::syntax::control::CONTROL_QUANTISERS;
use decoder_core::internal::syntax::ControlCoding;
use decoder_core::{Header, LeafInfo, STREAM_TAG, VERSION};
use host_encoder::{EncoderConfig, Plane, Target};
use std::collections::BTreeSet;
use std::path::PathBuf;

/// Seed files: name and bytes.
type Files = Vec<(String, Vec<u8>)>;

fn seeds_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds")
}

/// An image, the encoder's settings, and the targets each written as a seed stream.
struct Spec {
    name: &'static str,
    image: Image,
    config: EncoderConfig,
    targets: Vec<Target>,
}

/// A seed image: a grayscale plane, or RGB pixels encoded as a colour stream (YCbCr 4:2:0).
enum Image {
    Gray(Plane),
    Rgb {
        width: u32,
        height: u32,
        rgb: Vec<u8>,
    },
}

impl Image {
    /// A colour image of `common::synthetic_rgb`.
    fn rgb(width: u32, height: u32, seed: u32) -> Image {
        Image::Rgb {
            width,
            height,
            rgb: common::synthetic_rgb(width, height, seed),
        }
    }

    /// Values of the decoded image (pixels times channels).
    fn values(&self) -> usize {
        match self {
            Image::Gray(plane) => plane.data.len(),
            Image::Rgb { rgb, .. } => rgb.len(),
        }
    }

    fn analyse(&self, config: &EncoderConfig) -> host_encoder::Analysis {
        match self {
            Image::Gray(plane) => common::analyse_with(plane.clone(), config),
            Image::Rgb { width, height, rgb } => {
                host_encoder::analyse_colour(*width, *height, rgb.clone(), config, &|_| {})
                    .expect("colour analysis")
            }
        }
    }
}

/// The seeds' settings: stripes of 512 pixels, as the committed seeds were made.
fn config(min_leaf_log2: u8, max_leaf_log2: u8) -> EncoderConfig {
    EncoderConfig {
        min_leaf_log2,
        max_leaf_log2,
        stripe: host_encoder::DEFAULT_STRIPE_TILES,
        ..EncoderConfig::default()
    }
}

/// A noise image: every pixel independent (the finest quantisers pay here).
fn noise(width: u32, height: u32, seed: u32) -> Plane {
    let mut rng = common::Lcg::new(seed);
    let data = (0..width * height).map(|_| rng.below(256) as u8).collect();
    Plane::new(width, height, data)
}

fn specs() -> Vec<Spec> {
    let bpp = |rates: &[f64]| rates.iter().map(|&r| Target::Bpp(r)).collect::<Vec<_>>();
    vec![
        Spec {
            name: "one-pixel",
            image: Image::Gray(Plane::new(1, 1, vec![77])),
            config: config(1, 7),
            targets: vec![Target::Bytes(64)],
        },
        Spec {
            name: "strip-37x3",
            image: Image::Gray(common::synthetic(37, 3, 3, 8)),
            config: config(1, 3),
            targets: bpp(&[3.0, 8.0]),
        },
        Spec {
            name: "gradient-16x16",
            image: Image::Gray(common::gradient(16, 16)),
            config: config(2, 4),
            targets: bpp(&[0.5, 2.0]),
        },
        Spec {
            name: "textured-33x17",
            image: Image::Gray(common::synthetic(33, 17, 5, 12)),
            config: config(1, 4),
            targets: vec![Target::Bytes(160), Target::Bpp(3.0)],
        },
        Spec {
            name: "noise-24x24",
            image: Image::Gray(noise(24, 24, 9)),
            config: config(1, 3),
            targets: bpp(&[2.0, 8.0]),
        },
        Spec {
            name: "synthetic-64x64",
            image: Image::Gray(common::synthetic(64, 64, 7, 6)),
            config: config(2, 5),
            targets: bpp(&[0.05, 0.2, 0.5, 1.0, 1.5]),
        },
        Spec {
            name: "synthetic-100x60",
            image: Image::Gray(common::synthetic(100, 60, 11, 20)),
            config: config(2, 6),
            targets: vec![Target::Bpp(0.1), Target::Psnr(30.0), Target::Bpp(2.5)],
        },
        Spec {
            name: "textured-128x128",
            image: Image::Gray(common::synthetic(128, 128, 1, 4)),
            config: config(4, 5),
            targets: bpp(&[1.0, 2.0, 3.0]),
        },
        Spec {
            name: "flat-200x150",
            image: Image::Gray(Plane::new(200, 150, vec![131; 200 * 150])),
            config: config(2, 7),
            targets: vec![Target::Bytes(64)],
        },
        Spec {
            name: "synthetic-256x192",
            image: Image::Gray(common::synthetic(256, 192, 13, 10)),
            config: config(3, 7),
            targets: bpp(&[0.02, 0.25, 1.0]),
        },
        Spec {
            // A 16-bit surface (its samples delivered as values in the header's range).
            name: "surface16-40x36",
            image: Image::Gray(common::synthetic(40, 36, 19, 3)),
            config: EncoderConfig {
                range: Some(decoder_core::SampleRange::covering(500, 60000)),
                ..config(1, 5)
            },
            targets: bpp(&[0.5, 2.0]),
        },
        // Colour (YCbCr 4:2:0): chroma planes of half the size rounded up, so odd sizes leave
        // a chroma row or column half outside the image.
        Spec {
            name: "colour-1x1",
            image: Image::Rgb {
                width: 1,
                height: 1,
                rgb: vec![200, 30, 90],
            },
            config: config(1, 7),
            targets: vec![Target::Bytes(64)],
        },
        Spec {
            name: "colour-33x2",
            image: Image::rgb(33, 2, 4),
            config: config(1, 3),
            targets: bpp(&[4.0]),
        },
        Spec {
            name: "colour-45x31",
            image: Image::rgb(45, 31, 17),
            config: config(1, 4),
            targets: bpp(&[0.75, 3.0]),
        },
        Spec {
            name: "colour-64x48",
            image: Image::rgb(64, 48, 23),
            config: config(2, 5),
            targets: bpp(&[0.25, 1.5]),
        },
        Spec {
            // Stripes of one coding tile (128 px, chroma stripes of 64): three, the last 45 px wide
            // (chroma 23 of 151).
            name: "colour-301x45",
            image: Image::rgb(301, 45, 29),
            config: EncoderConfig {
                stripe: 1,
                ..config(2, 5)
            },
            targets: bpp(&[0.1, 0.5]),
        },
    ]
}

/// What the leaves of a set of streams use.
#[derive(Default, Debug)]
struct Usage {
    models: BTreeSet<u8>,
    /// (model, coding) for the models that have a choice.
    codings: BTreeSet<(u8, u8)>,
    cquants: BTreeSet<u8>,
    leaf_sizes: BTreeSet<u8>,
    sizes: BTreeSet<(u16, u16)>,
    /// Channels of the streams (1: grayscale, 3: colour).
    channels: BTreeSet<u8>,
    /// Sizes of the colour streams.
    colour_sizes: BTreeSet<(u16, u16)>,
    /// Bit depths of the streams.
    depths: BTreeSet<u8>,
}

impl Usage {
    fn leaf(&mut self, info: &LeafInfo) {
        self.models.insert(info.model);
        if MODELS[usize::from(info.model)].has_coding_choice() {
            self.codings.insert((
                info.model,
                u8::from(info.coding == ControlCoding::Transform),
            ));
        }
        self.cquants.insert(info.cquant);
        self.leaf_sizes.insert(info.node.log2);
    }

    fn stream(&mut self, name: &str, bytes: &[u8]) {
        let header = Header::read(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        self.sizes.insert((header.width, header.height));
        self.channels.insert(header.channels);
        self.depths.insert(header.bit_depth);
        if header.channels == 3 {
            self.colour_sizes.insert((header.width, header.height));
        }
        decoder_core::Decoder::new(bytes)
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .observe(|leaf: &LeafInfo| self.leaf(leaf))
            .verify()
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }

    /// What is missing from a full set, if anything.
    fn missing(&self) -> Vec<String> {
        let mut out = Vec::new();
        let models: BTreeSet<u8> = (0..MODELS.len() as u8).collect();
        if self.models != models {
            out.push(format!("models {:?} of {models:?}", self.models));
        }
        let codings: BTreeSet<(u8, u8)> = (0..MODELS.len() as u8)
            .filter(|&m| MODELS[usize::from(m)].has_coding_choice())
            .flat_map(|m| [(m, 0), (m, 1)])
            .collect();
        if self.codings != codings {
            out.push(format!("codings {:?} of {codings:?}", self.codings));
        }
        let cquants: BTreeSet<u8> = (0..CONTROL_QUANTISERS as u8).collect();
        if self.cquants != cquants {
            out.push(format!(
                "control quantisers {:?} of {cquants:?}",
                self.cquants
            ));
        }
        let leaf_sizes: BTreeSet<u8> = (1..=7).collect();
        if self.leaf_sizes != leaf_sizes {
            out.push(format!(
                "leaf sizes {:?} of {leaf_sizes:?}",
                self.leaf_sizes
            ));
        }
        if self.sizes.len() < 8 {
            out.push(format!("only {} image sizes", self.sizes.len()));
        }
        if self.channels != BTreeSet::from([1, 3]) {
            out.push(format!("channels {:?} of [1, 3]", self.channels));
        }
        if self.depths != BTreeSet::from([8, 16]) {
            out.push(format!("bit depths {:?} of [8, 16]", self.depths));
        }
        // Chroma planes are half the size rounded up: odd sides reach their edge cases.
        let odd = |(w, h): (u16, u16)| w % 2 == 1 && h % 2 == 1 && w > 1 && h > 1;
        if self.colour_sizes.len() < 4 || !self.colour_sizes.iter().any(|&s| odd(s)) {
            out.push(format!(
                "four colour sizes, one of odd width and height (not 1): {:?}",
                self.colour_sizes
            ));
        }
        out
    }
}

fn target_name(target: Target) -> String {
    match target {
        Target::Bpp(b) => format!("{b}bpp"),
        Target::Bytes(n) => format!("{n}bytes"),
        Target::Psnr(p) => format!("{p}dB"),
    }
}

/// The seed streams the specs make, by file name.
fn make_streams() -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for spec in specs() {
        let analysis = spec.image.analyse(&spec.config);
        for &target in &spec.targets {
            // A rate below the smallest stream gets the smallest stream.
            let encoded = match analysis.encode(target) {
                Err(host_encoder::EncodeError::BudgetTooSmall { smallest, .. }) => {
                    analysis.encode(Target::Bytes(smallest))
                }
                other => other,
            }
            .unwrap_or_else(|e| panic!("{}: {target:?}: {e}", spec.name));
            let mut px = vec![0u8; spec.image.values()];
            pifs_tests::decode_into(&encoded.bytes, &mut px).unwrap();
            assert!(
                px == encoded.reconstruction,
                "{}: decoder and encoder disagree",
                spec.name
            );
            out.push((
                format!("{}-{}.pifs", spec.name, target_name(target)),
                encoded.bytes,
            ));
        }
    }
    out
}

/// Inputs of the `roundtrip` check: width-1, height-1, a budget byte, pixels.
fn roundtrip_seeds() -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for (name, plane, budget) in [
        ("gradient-16x12", common::gradient(16, 12), 40u8),
        ("textured-33x17", common::synthetic(33, 17, 5, 12), 200),
        ("noise-9x7", noise(9, 7, 3), 255),
        ("flat-48x48", Plane::new(48, 48, vec![90; 48 * 48]), 1),
    ] {
        let mut bytes = vec![(plane.width - 1) as u8, (plane.height - 1) as u8, budget];
        bytes.extend_from_slice(&plane.data);
        out.push((format!("{name}.bin"), bytes));
    }
    out
}

/// Image files of every kind the host reads.
fn encode_input_seeds() -> Vec<(String, Vec<u8>)> {
    use image::{DynamicImage, ImageFormat};
    let gray = |w: u32, h: u32| {
        image::GrayImage::from_fn(w, h, |x, y| image::Luma([(x * 9 + y * 5) as u8]))
    };
    let encode = |img: &DynamicImage, format: ImageFormat| {
        let mut out = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut out), format)
            .unwrap();
        out
    };
    let rgb = DynamicImage::ImageRgb8(image::RgbImage::from_fn(20, 14, |x, y| {
        image::Rgb([(x * 12) as u8, (y * 17) as u8, 99])
    }));
    let rgba = DynamicImage::ImageRgba8(image::RgbaImage::from_fn(12, 10, |x, y| {
        image::Rgba([200, (x * 20) as u8, 40, (y * 25) as u8])
    }));
    let gray16 = DynamicImage::ImageLuma16(image::ImageBuffer::from_fn(10, 8, |x, y| {
        image::Luma([(x * 6000 + y * 900) as u16])
    }));
    let g = DynamicImage::ImageLuma8(gray(16, 12));
    let mut out = vec![
        ("gray.png".to_string(), encode(&g, ImageFormat::Png)),
        ("rgb.png".into(), encode(&rgb, ImageFormat::Png)),
        ("rgba.png".into(), encode(&rgba, ImageFormat::Png)),
        ("gray16.png".into(), encode(&gray16, ImageFormat::Png)),
        ("rgb.jpg".into(), encode(&rgb, ImageFormat::Jpeg)),
        ("gray.pgm".into(), encode(&g, ImageFormat::Pnm)),
        ("rgb.ppm".into(), encode(&rgb, ImageFormat::Pnm)),
        ("rgb.bmp".into(), encode(&rgb, ImageFormat::Bmp)),
        ("rgba.tiff".into(), encode(&rgba, ImageFormat::Tiff)),
        ("palette.png".into(), palette_png()),
        (
            "oriented-6.jpg".into(),
            with_orientation(&encode(&rgb, ImageFormat::Jpeg), 6),
        ),
        ("pages-2.tiff".into(), two_page_tiff()),
    ];
    out.sort();
    out
}

/// A 4-colour indexed PNG, 8x8 (the `image` crate writes no palette images): stored zlib.
fn palette_png() -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&decoder_core::internal::checksum::crc32(&body).to_be_bytes());
    }
    let (w, h) = (8u32, 8u32);
    let mut raw = Vec::new();
    for y in 0..h {
        raw.push(0);
        raw.extend((0..w).map(|x| ((x + y) % 4) as u8));
    }
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
    png
}

/// `jpeg` with an EXIF segment saying `orientation`.
fn with_orientation(jpeg: &[u8], orientation: u16) -> Vec<u8> {
    let mut tiff = b"MM\0\x2a\0\0\0\x08".to_vec();
    tiff.extend_from_slice(&1u16.to_be_bytes());
    tiff.extend_from_slice(&0x0112u16.to_be_bytes());
    tiff.extend_from_slice(&3u16.to_be_bytes());
    tiff.extend_from_slice(&1u32.to_be_bytes());
    tiff.extend_from_slice(&orientation.to_be_bytes());
    tiff.extend_from_slice(&[0, 0, 0, 0, 0, 0]);
    let mut body = b"Exif\0\0".to_vec();
    body.extend_from_slice(&tiff);
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&[0xFF, 0xE1]);
    out.extend_from_slice(&((body.len() + 2) as u16).to_be_bytes());
    out.extend_from_slice(&body);
    out.extend_from_slice(&jpeg[2..]);
    out
}

/// A TIFF of two grey pages, 12x9 then 6x4, written by hand (little-endian, uncompressed).
fn two_page_tiff() -> Vec<u8> {
    let pages = [(12u32, 9u32), (6, 4)];
    let mut out = b"II\x2a\0".to_vec();
    out.extend_from_slice(&8u32.to_le_bytes());
    for (i, &(w, h)) in pages.iter().enumerate() {
        let entries: u16 = 8;
        let ifd_len = 2 + 12 * u32::from(entries) + 4;
        let ifd_at = out.len() as u32;
        let data_at = ifd_at + ifd_len;
        let next = if i + 1 < pages.len() {
            data_at + w * h
        } else {
            0
        };
        out.extend_from_slice(&entries.to_le_bytes());
        let mut entry = |tag: u16, kind: u16, value: u32| {
            out.extend_from_slice(&tag.to_le_bytes());
            out.extend_from_slice(&kind.to_le_bytes());
            out.extend_from_slice(&1u32.to_le_bytes());
            out.extend_from_slice(&value.to_le_bytes());
        };
        entry(256, 4, w); // width
        entry(257, 4, h); // height
        entry(258, 3, 8); // bits per sample
        entry(259, 3, 1); // no compression
        entry(262, 3, 1); // black is zero
        entry(273, 4, data_at); // strip offset
        entry(278, 4, h); // rows per strip
        entry(279, 4, w * h); // strip bytes
        out.extend_from_slice(&next.to_le_bytes());
        out.extend((0..w * h).map(|v| (v * 7 + i as u32 * 100) as u8));
    }
    out
}

/// Inputs of the `large_dimensions` check: the payloads of some seed streams under large
/// declared sizes. Grayscale payloads under sizes up to 65535 x 65535 with assorted leaf sizes;
/// colour payloads under their own stream's leaf sizes and stripe (so that they decode as far
/// as a payload of a smaller image can), at odd sizes the check decodes (up to 2^14 leaves of
/// the smallest size) and one it refuses.
fn large_dimension_seeds(streams: &[(String, Vec<u8>)]) -> Vec<(String, Vec<u8>)> {
    let seed = |name: &str, bytes: &[u8], (w, h): (u16, u16), leaves: u8| {
        let (header, offset) = Header::parse(bytes).unwrap();
        let mut seed = Vec::new();
        seed.extend_from_slice(&w.to_be_bytes());
        seed.extend_from_slice(&h.to_be_bytes());
        seed.push(leaves);
        seed.push(u8::from(header.channels == 3) | u8::from(header.range.is_some()) << 1);
        seed.extend_from_slice(&bytes[offset..]);
        let made = pifs_tests::fuzz::large_stream(&seed).unwrap();
        let made = Header::read(&made).unwrap();
        assert_eq!(made.channels, header.channels, "{name}");
        assert_eq!(made.bit_depth, header.bit_depth, "{name}");
        (format!("{w}x{h}-{}", name.trim_end_matches(".pifs")), seed)
    };
    let mut out = Vec::new();
    let sizes: [(u16, u16, u8); 5] = [
        (65535, 65535, 3),
        (16384, 16384, 3),
        (4096, 256, 0x0F),
        (1024, 1024, 0x03),
        (300, 3000, 0x02),
    ];
    let gray = streams
        .iter()
        .filter(|(_, b)| Header::read(b).unwrap().channels == 1);
    for (k, (name, bytes)) in gray.step_by(3).enumerate() {
        let (w, h, leaves) = sizes[k % sizes.len()];
        out.push(seed(name, bytes, (w, h), leaves));
    }
    // The refused one needs no matching leaf sizes (its header alone is read).
    for (name, size, leaves) in [
        ("colour-33x2-4bpp.pifs", (65535, 65535), Some(3)),
        ("colour-45x31-3bpp.pifs", (4095, 15), None),
        ("colour-64x48-1.5bpp.pifs", (2047, 127), None),
        ("colour-301x45-0.5bpp.pifs", (1023, 255), None),
    ] {
        let bytes = &streams
            .iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no seed stream {name}"))
            .1;
        let header = Header::read(bytes).unwrap();
        if let Some(leaves) = leaves {
            out.push(seed(name, bytes, size, leaves));
            continue;
        }
        let leaves = pifs_tests::fuzz::large_leaf_byte(&header)
            .unwrap_or_else(|| panic!("{name}: leaf sizes or stripe not expressible: {header:?}"));
        let made = seed(name, bytes, size, leaves);
        let made_header = Header::read(&pifs_tests::fuzz::large_stream(&made.1).unwrap()).unwrap();
        assert_eq!(
            (
                made_header.min_leaf_log2,
                made_header.max_leaf_log2,
                made_header.stripe
            ),
            (header.min_leaf_log2, header.max_leaf_log2, header.stripe),
            "{name}: the seed's leaf sizes or stripe differ from its stream's"
        );
        out.push(made);
    }
    out
}

/// Every seed by kind (directory) and file name.
fn all_seeds() -> Vec<(&'static str, Files)> {
    let streams = make_streams();
    let large = large_dimension_seeds(&streams);
    vec![
        ("streams", streams),
        ("roundtrip", roundtrip_seeds()),
        ("encode_input", encode_input_seeds()),
        ("large_dimensions", large),
        ("packets", packet_seeds()),
    ]
}

/// One packet seed set: the image, the packet size, the packets, and the options.
struct PacketSeed {
    name: &'static str,
    w: u32,
    h: u32,
    colour: bool,
    size: usize,
    count: usize,
    preview: bool,
    parity: usize,
}

/// Framed packet sets for `decode_packets`: gray and colour, with and without a preview and
/// parity packets, at the smallest packet size and larger ones, whole and with packets
/// missing.
fn packet_seeds() -> Files {
    use host_encoder::packets::{frame, packetise, PacketOptions};
    let config = EncoderConfig {
        stripe: host_encoder::DEFAULT_STRIPE_TILES,
        ..EncoderConfig::default()
    };
    let mut out = Files::new();
    let seed = |name, w, h, colour, size, count, preview, parity| PacketSeed {
        name,
        w,
        h,
        colour,
        size,
        count,
        preview,
        parity,
    };
    let cases = [
        seed("gray-48x40", 48, 40, false, 48, 6, true, 0),
        seed("gray-72x24", 72, 24, false, 64, 5, false, 0),
        seed("colour-40x24", 40, 24, true, 64, 5, true, 0),
        seed("colour-23x17", 23, 17, true, 48, 4, false, 0),
        seed("gray-96x64-parity", 96, 64, false, 96, 8, true, 2),
    ];
    for case in cases {
        let PacketSeed { name, w, h, .. } = case;
        let plane = common::synthetic(w, h, w + h, 6);
        let analysis = if case.colour {
            host_encoder::analyse_colour(w, h, common::synthetic_rgb(w, h, w * h), &config, &|_| {})
                .unwrap()
        } else {
            common::analyse_with(plane, &config)
        };
        let options = PacketOptions {
            size: case.size,
            image_id: Some(w as u16),
            preview: case.preview,
            repeat_preview: false,
            parity: case.parity,
        };
        let budget = Target::Bytes(case.size * case.count);
        let made = packetise(&analysis, &config, budget, &options)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        out.push((format!("{name}-all.pifsp"), frame(&made.packets)));
        let odd: Vec<Vec<u8>> = made.packets.iter().skip(1).step_by(2).cloned().collect();
        out.push((format!("{name}-odd.pifsp"), frame(&odd)));
    }
    out
}

#[test]
#[ignore = "writes fuzz/seeds/; run explicitly to regenerate the fuzz seeds"]
fn regenerate() {
    let seeds = all_seeds();
    let mut usage = Usage::default();
    for (kind, files) in &seeds {
        let dir = seeds_dir().join(kind);
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for (name, bytes) in files {
            std::fs::write(dir.join(name), bytes).unwrap();
            if *kind == "streams" {
                usage.stream(name, bytes);
                println!("{kind}/{name}: {} bytes", bytes.len());
            }
        }
    }
    let missing = usage.missing();
    assert!(
        missing.is_empty(),
        "the seed streams lack: {missing:#?}\n{usage:#?}"
    );
}

fn committed(kind: &str) -> Vec<(String, Vec<u8>)> {
    let dir = seeds_dir().join(kind);
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

/// The committed seed streams are of this format version and use everything the format has.
#[test]
fn seed_streams_are_current_and_use_every_model_and_quantiser() {
    let streams = committed("streams");
    assert!(streams.len() >= 20, "{} seed streams", streams.len());
    let mut usage = Usage::default();
    for (name, bytes) in &streams {
        assert_eq!(
            bytes.first().copied(),
            Some(STREAM_TAG),
            "fuzz/seeds/streams/{name} is not format version {VERSION}: regenerate the seeds \
             (cargo test -p pifs-tests --test fuzz_seeds -- --ignored regenerate)"
        );
        usage.stream(name, bytes);
    }
    let missing = usage.missing();
    assert!(missing.is_empty(), "the seed streams lack: {missing:#?}");
}

/// The committed seeds of every kind are the ones the generator names (a renamed or dropped
/// spec fails here until the seeds are regenerated); the image seeds are the generator's bytes.
#[test]
fn committed_seeds_match_the_generator() {
    let names = |files: &[(String, Vec<u8>)]| -> Vec<String> {
        files.iter().map(|(n, _)| n.clone()).collect()
    };
    let streams: Vec<String> = specs()
        .iter()
        .flat_map(|s| {
            s.targets
                .iter()
                .map(|&t| format!("{}-{}.pifs", s.name, target_name(t)))
                .collect::<Vec<_>>()
        })
        .collect();
    let mut streams_sorted = streams.clone();
    streams_sorted.sort();
    assert_eq!(names(&committed("streams")), streams_sorted);
    let mut roundtrip = roundtrip_seeds();
    roundtrip.sort();
    assert!(
        committed("roundtrip") == roundtrip,
        "fuzz/seeds/roundtrip differs"
    );
    let mut images = encode_input_seeds();
    images.sort();
    assert_eq!(names(&committed("encode_input")), names(&images));
    let large = committed("large_dimensions");
    assert!(large.len() >= 5);
    // Colour declared by the channel byte: a stream of the generator's layout.
    let colour = large
        .iter()
        .filter(|(_, b)| b.len() > pifs_tests::fuzz::LARGE_PREFIX && b[5] & 1 == 1)
        .count();
    assert!(colour >= 4, "{colour} colour large-dimension seeds");
    let mut packets = packet_seeds();
    packets.sort();
    assert_eq!(
        names(&committed("packets")),
        names(&packets),
        "fuzz/seeds/packets differs"
    );
}
