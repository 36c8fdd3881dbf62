//! Round trips: what the encoder reports as its reconstruction is exactly what decoder-core
//! decodes from the bytes, its PSNR figure is the PSNR of those pixels, and the tile sink
//! interface hands out every pixel exactly once.

mod common;

use common::{analyse_with, decode_all, gradient, psnr_u8, small_config, sse, synthetic};
use decoder_core::internal::model::MODELS;
use decoder_core::LeafInfo;
use host_encoder::{Encoded, EncoderConfig, Plane, Target};
use std::sync::OnceLock;

/// One encoded stream and what it was made from.
struct Case {
    name: String,
    plane: Plane,
    config: EncoderConfig,
    encoded: Encoded,
}

const TARGETS: [f64; 3] = [0.3, 1.0, 2.0];

/// Every (image, target) pair, encoded once for all tests of this file.
fn cases() -> &'static [Case] {
    static CASES: OnceLock<Vec<Case>> = OnceLock::new();
    CASES.get_or_init(|| {
        let config = EncoderConfig {
            max_leaf_log2: 4,
            ..small_config()
        };
        let images = [
            ("gradient 48x40", gradient(48, 40), config.clone()),
            ("textured 64x64", synthetic(64, 64, 7, 6), config.clone()),
            ("noisy 40x56", synthetic(40, 56, 3, 20), config.clone()),
        ];
        let mut out = Vec::new();
        for (name, plane, config) in images {
            let analysis = analyse_with(plane.clone(), &config);
            for bpp in TARGETS {
                let encoded = analysis
                    .encode(Target::Bpp(bpp))
                    .unwrap_or_else(|e| panic!("{name} at {bpp} bpp: {e}"));
                out.push(Case {
                    name: format!("{name} at {bpp} bpp"),
                    plane: plane.clone(),
                    config: config.clone(),
                    encoded,
                });
            }
        }
        out
    })
}

#[test]
fn decode_into_equals_reconstruction_bit_for_bit() {
    for case in cases() {
        let e = &case.encoded;
        let (header, decoded) = decode_all(&e.bytes).expect(&case.name);
        assert_eq!(
            (u32::from(header.width), u32::from(header.height)),
            (case.plane.width, case.plane.height),
            "{}: header dimensions",
            case.name
        );
        assert_eq!(
            (header.min_leaf_log2, header.max_leaf_log2),
            (case.config.min_leaf_log2, case.config.max_leaf_log2),
            "{}: header leaf sizes",
            case.name
        );
        assert_eq!(
            e.reconstruction.len(),
            header.pixel_count(),
            "{}",
            case.name
        );
        if let Some(i) = decoded
            .iter()
            .zip(&e.reconstruction)
            .position(|(a, b)| a != b)
        {
            panic!(
                "{}: decoded pixel {} (x {}, y {}) is {} but the encoder's reconstruction is {}",
                case.name,
                i,
                i % case.plane.width as usize,
                i / case.plane.width as usize,
                decoded[i],
                e.reconstruction[i]
            );
        }
    }
}

#[test]
fn reported_psnr_is_the_psnr_of_the_decoded_pixels() {
    for case in cases() {
        let e = &case.encoded;
        let (_, decoded) = decode_all(&e.bytes).expect(&case.name);
        let measured_sse = sse(&decoded, &case.plane.data);
        assert_eq!(measured_sse, e.sse, "{}: SSE", case.name);
        let measured = psnr_u8(&decoded, &case.plane.data);
        assert_eq!(measured, e.psnr, "{}: PSNR", case.name);
        // A sanity bound on the figure itself: these images are far from lossless, but any
        // sensible encode at >= 0.3 bpp is well above 15 dB.
        assert!(
            e.psnr.is_finite() && e.psnr > 15.0,
            "{}: PSNR {}",
            case.name,
            e.psnr
        );
    }
}

#[test]
fn reported_payload_bits_match_the_stream() {
    for case in cases() {
        let e = &case.encoded;
        let header = decoder_core::Header::read(&e.bytes).expect(&case.name);
        let payload_bits = (e.bytes.len() - header.encoded_len()) as f64 * 8.0;
        assert_eq!(e.actual_payload_bits, payload_bits, "{}", case.name);
    }
}

#[test]
fn higher_rate_is_not_worse() {
    // Within one image the cases are in increasing rate order.
    for group in cases().chunks(TARGETS.len()) {
        for pair in group.windows(2) {
            let (lo, hi) = (&pair[0].encoded, &pair[1].encoded);
            assert!(
                hi.bytes.len() >= lo.bytes.len() && hi.sse <= lo.sse,
                "{} ({} bytes, {:.3} dB) vs {} ({} bytes, {:.3} dB)",
                pair[0].name,
                lo.bytes.len(),
                lo.psnr,
                pair[1].name,
                hi.bytes.len(),
                hi.psnr
            );
        }
    }
}

#[test]
fn pixel_sink_receives_every_pixel_exactly_once() {
    for case in cases() {
        let mut sink = common::CoverageSink::new(case.plane.width, case.plane.height);
        let header = pifs_tests::decode(&case.encoded.bytes, &mut sink).expect(&case.name);
        assert_eq!(
            (u32::from(header.width), u32::from(header.height)),
            (case.plane.width, case.plane.height)
        );
        assert!(
            sink.violations.is_empty(),
            "{}: {:?}",
            case.name,
            &sink.violations[..sink.violations.len().min(5)]
        );
        assert_eq!(
            sink.not_once(5),
            vec![],
            "{}: pixels not written exactly once (x, y, count)",
            case.name
        );
        assert!(sink.tiles > 0);
        assert!(
            sink.pixels == case.encoded.reconstruction,
            "{}: tile pixels differ from the reconstruction",
            case.name
        );
    }
}

#[derive(Default)]
struct Leaves(Vec<LeafInfo>);

impl Leaves {
    fn leaf(&mut self, info: &LeafInfo) {
        self.0.push(*info);
    }
}

#[test]
fn observed_leaves_form_a_valid_quadtree_cut() {
    for case in cases() {
        let (w, h) = (case.plane.width, case.plane.height);
        let mut sink = common::CoverageSink::new(w, h);
        let mut leaves = Leaves::default();
        let header = decoder_core::Decoder::new(&case.encoded.bytes)
            .expect(&case.name)
            .observe(|leaf| leaves.leaf(leaf))
            .decode(&mut sink)
            .expect(&case.name);
        let leaves = leaves.0;
        assert_eq!(
            leaves.len(),
            case.encoded.leaves,
            "{}: leaf count",
            case.name
        );
        let mut owner = vec![0u32; w as usize * h as usize];
        for leaf in &leaves {
            let n = leaf.node;
            assert!(
                (header.min_leaf_log2..=header.max_leaf_log2).contains(&n.log2),
                "{}: leaf {n:?} outside the header's leaf sizes",
                case.name
            );
            assert!(
                n.x % n.size() == 0 && n.y % n.size() == 0,
                "{}: misaligned {n:?}",
                case.name
            );
            assert!(n.x < w && n.y < h, "{}: leaf outside the image", case.name);
            let model = MODELS
                .get(usize::from(leaf.model))
                .unwrap_or_else(|| panic!("{}: model {}", case.name, leaf.model));
            assert!(model.fits_block(n.log2), "{}: {leaf:?}", case.name);
            for y in n.y..(n.y + n.size()).min(h) {
                for x in n.x..(n.x + n.size()).min(w) {
                    owner[(y * w + x) as usize] += 1;
                }
            }
        }
        assert!(
            owner.iter().all(|&c| c == 1),
            "{}: the leaves do not partition the image",
            case.name
        );
    }
}

/// Leaf sizes outside the format's range are taken as the nearest allowed ones: the stream
/// decodes and its header says what was used.
#[test]
fn leaf_sizes_outside_the_format_are_clamped() {
    let config = EncoderConfig {
        min_leaf_log2: 0,
        max_leaf_log2: 9,
        ..small_config()
    };
    let plane = synthetic(40, 30, 3, 8);
    let encoded = analyse_with(plane.clone(), &config)
        .encode(Target::Bpp(1.0))
        .expect("an encodable image");
    let header = decoder_core::Header::read(&encoded.bytes).expect("a valid header");
    assert_eq!((header.min_leaf_log2, header.max_leaf_log2), (1, 7));
    let (_, pixels) = decode_all(&encoded.bytes).expect("a decodable stream");
    assert_eq!(pixels, encoded.reconstruction);
}

/// A colour image round trip: the stream is a colour stream, decodes to the encoder's RGB
/// reconstruction exactly, its reported PSNR is the PSNR-RGB of the decoded pixels (sensible
/// and rising with the rate), chroma takes some of the bits, and the same image's
/// luma encoded in grayscale stays a grayscale stream.
#[test]
fn colour_images_round_trip_in_colour() {
    let (w, h) = (96, 80);
    let rgb = common::synthetic_rgb(w, h, 21);
    let config = small_config();
    let analysis =
        host_encoder::analyse_colour(w, h, rgb.clone(), &config, &|_| {}).expect("analysis");
    assert_eq!(analysis.channels(), 3);
    let mut last = 0.0;
    let mut streams = Vec::new();
    for bpp in [0.5, 1.0, 2.0] {
        let e = analysis.encode(Target::Bpp(bpp)).expect("encode");
        streams.push(e.bytes.clone());
        assert!(e.bytes.len() as f64 * 8.0 <= bpp * f64::from(w * h));
        let (header, pixels) = decode_all(&e.bytes).unwrap();
        assert_eq!(header.channels, 3);
        assert_eq!(pixels.len(), rgb.len());
        assert!(
            pixels == e.reconstruction,
            "{bpp}: decode != reconstruction"
        );
        let psnr = psnr_u8(&pixels, &rgb);
        assert!((psnr - e.psnr).abs() < 1e-9, "{bpp}: {psnr} vs {}", e.psnr);
        assert!(psnr > 24.0, "{bpp} bpp: PSNR-RGB {psnr:.2} dB");
        assert!(psnr >= last - 0.1, "{bpp} bpp: {psnr:.2} after {last:.2}");
        last = psnr;
        let share = e.chroma_bits / e.actual_payload_bits;
        assert!(
            share > 0.02 && share < 1.0,
            "{bpp} bpp: chroma share {share}"
        );
        println!(
            "colour {bpp} bpp: PSNR-RGB {psnr:.2} dB, chroma {:.1}%",
            100.0 * share
        );
    }
    // Encoding again (the writer replays chroma choices of a plan it wrote last) gives the
    // same streams.
    for (bpp, first) in [0.5, 1.0, 2.0].into_iter().zip(&streams) {
        let again = analysis.encode(Target::Bpp(bpp)).expect("encode");
        assert!(&again.bytes == first, "{bpp} bpp: a second encode differs");
    }
    // The luma alone, as the grayscale encoder takes it.
    let (luma, _) = host_encoder::ColourPlanes::from_rgb(w, h, rgb);
    let gray = analyse_with(luma, &config)
        .encode(Target::Bpp(1.0))
        .expect("encode");
    let (header, pixels) = decode_all(&gray.bytes).unwrap();
    assert_eq!(header.channels, 1);
    assert_eq!(pixels.len(), (w * h) as usize);
    assert_eq!(gray.chroma_bits, 0.0);
}
