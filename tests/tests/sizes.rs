//! Image sizes: degenerate, odd, just past a power of two, large, and the format's largest
//! side. Each encodes, decodes to exactly the encoder's reconstruction, is covered pixel by pixel
//! by the tile sink, and `decode_into` rejects a buffer that is too small.

mod common;

use common::{analyse_with, decode_all, small_config, synthetic, CoverageSink};
use decoder_core::DecodeError;
use host_encoder::{EncoderConfig, Target};

/// Settings for the large images: 8x8 leaves only, which keeps the analysis fast, and stripes
/// of 512 pixels, so that the widest images are coded in many stripes and decoded with
/// decoder-core's default frontier.
fn large_config() -> EncoderConfig {
    EncoderConfig {
        min_leaf_log2: 3,
        max_leaf_log2: 3,
        stripe: host_encoder::DEFAULT_STRIPE_TILES,
        ..EncoderConfig::default()
    }
}

fn check_size(width: u32, height: u32, config: &EncoderConfig, target: Target) {
    let what = format!("{width}x{height}");
    let plane = synthetic(width, height, width * 31 + height, 8);
    let analysis = analyse_with(plane.clone(), config);
    let e = analysis
        .encode(target)
        .unwrap_or_else(|err| panic!("{what} {target:?}: {err}"));
    if let Target::Bytes(n) = target {
        assert!(e.bytes.len() <= n, "{what}: {} bytes", e.bytes.len());
    }
    let (header, decoded) = decode_all(&e.bytes).unwrap_or_else(|err| panic!("{what}: {err}"));
    assert_eq!(
        (u32::from(header.width), u32::from(header.height)),
        (width, height),
        "{what}: header"
    );
    assert_eq!(decoded.len(), (width * height) as usize);
    assert!(
        decoded == e.reconstruction,
        "{what}: decode != reconstruction"
    );
    assert_eq!(common::sse(&decoded, &plane.data), e.sse, "{what}: SSE");

    let mut sink = CoverageSink::new(width, height);
    pifs_tests::decode(&e.bytes, &mut sink).unwrap();
    assert!(sink.violations.is_empty(), "{what}: {:?}", sink.violations);
    assert_eq!(sink.not_once(5), vec![], "{what}: (x, y, count)");
    assert!(sink.pixels == decoded, "{what}: sink pixels");

    // Too small: one pixel short, and empty.
    let n = header.pixel_count();
    for len in [n - 1, 0] {
        let mut short = vec![0u8; len];
        assert_eq!(
            pifs_tests::decode_into(&e.bytes, &mut short),
            Err(DecodeError::BufferTooSmall),
            "{what}: buffer of {len} bytes"
        );
    }
    // Larger than needed: the image goes to the front, the rest is left alone.
    let mut long = vec![0xA5u8; n + 7];
    pifs_tests::decode_into(&e.bytes, &mut long).unwrap();
    assert!(long[..n] == decoded[..], "{what}: oversized buffer");
    assert!(
        long[n..].iter().all(|&b| b == 0xA5),
        "{what}: wrote past the image"
    );
}

#[test]
fn one_pixel() {
    // At 0.5 bpp a 1x1 image has a budget of 0 bytes: a byte budget instead.
    check_size(1, 1, &small_config(), Target::Bytes(64));
}

#[test]
fn one_pixel_smallest_leaves() {
    let config = EncoderConfig {
        min_leaf_log2: 1,
        max_leaf_log2: 1,
        ..EncoderConfig::default()
    };
    check_size(1, 1, &config, Target::Bytes(64));
}

#[test]
fn one_column() {
    check_size(1, 7, &small_config(), Target::Bytes(64));
}

#[test]
fn one_row() {
    check_size(7, 1, &small_config(), Target::Bytes(64));
}

#[test]
fn odd_13x9() {
    check_size(13, 9, &small_config(), Target::Bytes(64));
}

#[test]
fn odd_13x9_at_0_5_bpp_is_an_error() {
    // 13x9 at 0.5 bpp is 7 bytes, less than any stream: an error, not a panic or an overshoot.
    let analysis = analyse_with(synthetic(13, 9, 1, 8), &small_config());
    assert!(matches!(
        analysis.encode(Target::Bpp(0.5)),
        Err(host_encoder::EncodeError::BudgetTooSmall { budget: 7, .. })
    ));
}

#[test]
fn just_past_a_power_of_two_257x257() {
    check_size(257, 257, &large_config(), Target::Bpp(0.5));
}

#[test]
fn large_601x401() {
    check_size(601, 401, &large_config(), Target::Bpp(0.5));
}

#[test]
fn widest_strip_65535x2() {
    // The largest side the format allows: the quadtree root is 2^16 (larger than any leaf).
    // 4x4 leaves only: the cheapest analysis of a strip this long; 128 stripes of 512.
    let config = EncoderConfig {
        min_leaf_log2: 2,
        max_leaf_log2: 2,
        stripe: host_encoder::DEFAULT_STRIPE_TILES,
        ..EncoderConfig::default()
    };
    check_size(65535, 2, &config, Target::Psnr(25.0));
}
