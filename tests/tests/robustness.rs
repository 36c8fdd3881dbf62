//! The decoder never panics: random byte strings, random payloads behind valid headers, golden
//! streams truncated at every length, with random bit flips and random byte overwrites. Every
//! call returns `Ok` or a typed `Err`, never writes outside the image, and malformed headers
//! give the right typed error.

mod common;

use common::{golden_streams, sealed_stream, CoverageSink};
use decoder_core::internal::format::{FIRST_TAGGED_VERSION, PACKET_TAG, STREAM_TAG, VERSION};
use decoder_core::internal::syntax::{
    seal, Header, CHECKSUM_BYTES, FLAG_CODING, FLAG_COLOUR, FLAG_DEEP,
};
use decoder_core::{DecodeError, Limits};
use proptest::prelude::*;
use std::sync::OnceLock;

/// Largest image the tests allocate a buffer for; larger claimed images must be refused with
/// `BufferTooSmall` when given a smaller buffer.
const MAX_PIXELS: usize = 1 << 22;

fn streams() -> &'static [(String, Vec<u8>)] {
    static STREAMS: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
    STREAMS.get_or_init(golden_streams)
}

/// Decodes `data` as a decoder-core user would, checking the invariants that hold whatever the
/// bytes: no panic (the caller is a test, a panic fails it), a header error for an unparsable
/// header, and a buffer error for a buffer smaller than the header claims.
fn decode_checked(data: &[u8]) -> Result<(), DecodeError> {
    let header = match decoder_core::Header::read(data) {
        Ok(h) => h,
        Err(e) => {
            // The same error through the full decoder, whatever the buffer.
            let mut buf = [0u8; 16];
            assert_eq!(pifs_tests::decode_into(data, &mut buf), Err(e));
            let mut sink = CoverageSink::new(1, 1);
            assert_eq!(pifs_tests::decode(data, &mut sink).err(), Some(e));
            assert_eq!(sink.tiles, 0);
            return Err(e);
        }
    };
    let n = header.pixel_count();
    assert!(n > 0);
    if n > MAX_PIXELS {
        // A stream that passes its checks is refused for the buffer, before anything is
        // decoded.
        let mut small = vec![0u8; 1024];
        let decoder = decoder_core::Decoder::new(data)?;
        assert_eq!(
            decoder.decode_into(&mut small),
            Err(DecodeError::BufferTooSmall)
        );
        return Err(DecodeError::BufferTooSmall);
    }
    let mut out = vec![0u8; n * usize::from(header.channels)];
    let result = pifs_tests::decode_into(data, &mut out);
    if let Ok(h) = result {
        assert_eq!(h, header);
    }
    // The tile interface on the same bytes: the same outcome, and whatever the payload, no tile
    // outside the image or larger than a tile, and no pixel twice.
    let mut sink = CoverageSink::new(u32::from(header.width), u32::from(header.height));
    let via_sink = pifs_tests::decode(data, &mut sink);
    assert_eq!(via_sink, result);
    assert!(sink.violations.is_empty(), "{:?}", &sink.violations[..1]);
    assert!(
        sink.counts.iter().all(|&c| c <= 1),
        "a pixel was written twice"
    );
    if result.is_ok() {
        assert!(
            sink.counts.iter().all(|&c| c == 1),
            "a pixel was never written"
        );
        assert!(sink.pixels == out);
    }
    result.map(|_| ())
}

/// A header for a `width x height` image.
fn header(width: u16, height: u16, min_leaf: u8, max_leaf: u8) -> Header {
    Header {
        width,
        height,
        channels: 1,
        bit_depth: 8,
        min_leaf_log2: min_leaf,
        max_leaf_log2: max_leaf,
        stripe: 0,
        deblock: 0,
        payload_len: 0,
        checksum: 0,
        range: None,
    }
}

/// The header bytes of a `width x height` image whose payload is `payload_len` bytes (the
/// checksum field left at zero).
fn header_bytes(width: u16, height: u16, payload_len: u32) -> Vec<u8> {
    let h = Header {
        payload_len,
        ..header(width, height, 2, 4)
    };
    let mut bytes = vec![0; h.encoded_len()];
    h.write(&mut bytes);
    bytes
}

#[test]
fn golden_streams_decode_cleanly() {
    assert!(!streams().is_empty());
    for (name, bytes) in streams() {
        assert_eq!(decode_checked(bytes), Ok(()), "{name}");
    }
}

#[test]
fn truncation_at_every_length_is_detected() {
    // The range decoder consumes its stream to the last byte (the encoder's flush bytes
    // included), so every proper prefix of a valid stream, cut in the header or anywhere in the
    // payload, is reported as truncated: never `Ok` with part of the image left unwritten.
    for (name, bytes) in streams() {
        for len in 0..bytes.len() {
            assert_eq!(
                decode_checked(&bytes[..len]),
                Err(DecodeError::Truncated),
                "{name} cut to {len} of {} bytes",
                bytes.len()
            );
        }
    }
}

#[test]
fn header_errors_are_typed() {
    let good = header_bytes(16, 16, 8);
    let with = |i: usize, v: u8| {
        let mut h = good.clone();
        h[i] = v;
        h.extend_from_slice(&[0; 8]);
        h
    };
    let sealed = |payload_len: u32, payload: &[u8]| {
        let mut h = header_bytes(16, 16, payload_len);
        h.extend_from_slice(payload);
        seal(&mut h);
        h
    };
    // `good`: tag, flags (coding fields follow), checksum, width and height less one, leaf
    // sizes, stripe, payload length.
    assert_eq!(good.len(), 11);
    let flags = |f: u8| with(1, FLAG_CODING | f);
    let deblock = |d: u8| d << decoder_core::internal::syntax::DEBLOCK_SHIFT;
    let before_length = good[..10].to_vec();
    let sides = |side_bytes: &[u8]| {
        let mut h = good[..6].to_vec();
        h.extend_from_slice(side_bytes);
        h.extend_from_slice(&good[8..]);
        h.extend_from_slice(&[0; 8]);
        h
    };
    let legacy = |version: u8| {
        let mut h = b"PIFS".to_vec();
        h.extend_from_slice(&[version, 1, 8, 0, 16, 0, 16, 0, 0x42, 0, 0, 0, 0, 0, 0, 8]);
        h
    };
    let dimensions = DecodeError::InvalidHeader(decoder_core::HeaderField::Dimensions);
    let mut cases: Vec<(&str, Vec<u8>, DecodeError)> = vec![
        ("empty", vec![], DecodeError::Truncated),
        ("the tag only", vec![STREAM_TAG], DecodeError::Truncated),
        (
            "short, good tag",
            good[..9].to_vec(),
            DecodeError::Truncated,
        ),
        ("short, bad tag", b"GIF89a".to_vec(), DecodeError::BadMagic),
        ("bad tag", with(0, b'Q'), DecodeError::BadMagic),
        ("a packet's tag", with(0, PACKET_TAG), DecodeError::BadMagic),
        (
            "a packet, whole",
            {
                let mut p = with(0, PACKET_TAG);
                p.truncate(6);
                p
            },
            DecodeError::BadMagic,
        ),
        // The version before is named; no version before the first tagged one had a tag: such
        // a byte is unknown.
        (
            "the version before",
            with(0, STREAM_TAG - 1),
            DecodeError::UnsupportedVersion(VERSION - 1),
        ),
        (
            "the version before tags",
            with(0, 0x80 | (FIRST_TAGGED_VERSION - 1)),
            DecodeError::BadMagic,
        ),
        (
            "the version after",
            with(0, STREAM_TAG + 1),
            DecodeError::UnsupportedVersion(VERSION + 1),
        ),
        (
            "version 63",
            with(0, 0xBF),
            DecodeError::UnsupportedVersion(63),
        ),
        // Format 21 and earlier opened with `PIFS`: not a stream's tag (the tool names their
        // version, `host_encoder`'s stream input).
        ("a stream of format 21", legacy(21), DecodeError::BadMagic),
        ("PIFS alone", b"PIFS".to_vec(), DecodeError::BadMagic),
        (
            "edge-smoothing strength 17",
            flags(deblock(17)),
            DecodeError::InvalidHeader(decoder_core::HeaderField::Deblock),
        ),
        (
            "edge-smoothing strength 31",
            flags(deblock(31)),
            DecodeError::InvalidHeader(decoder_core::HeaderField::Deblock),
        ),
        (
            "bit depth 16 in colour",
            flags(FLAG_DEEP | FLAG_COLOUR),
            DecodeError::UnsupportedBitDepth(16),
        ),
        (
            // The range is read from the bytes after the payload length: zeros here.
            "bit depth 16, empty value range",
            flags(FLAG_DEEP),
            DecodeError::InvalidHeader(decoder_core::HeaderField::Range),
        ),
        (
            "bit depth 16, value range cut short",
            {
                let mut h = good.clone();
                h[1] |= FLAG_DEEP;
                h.extend_from_slice(&[0, 1]);
                h
            },
            DecodeError::Truncated,
        ),
        (
            "bit depth 16, smoothed",
            flags(FLAG_DEEP | deblock(2)),
            DecodeError::InvalidHeader(decoder_core::HeaderField::Deblock),
        ),
        ("width 65536", sides(&[0xFF, 0xFF, 0x03, 15]), dimensions),
        ("height 65536", sides(&[15, 0xFF, 0xFF, 0x03]), dimensions),
        (
            "width in four bytes",
            sides(&[0x80, 0x80, 0x80, 0x00, 15]),
            dimensions,
        ),
        (
            "width with a redundant zero group",
            sides(&[0x8F, 0x00, 15]),
            dimensions,
        ),
        (
            "width 65535, cut short",
            good[..6].iter().chain(&[0xFE, 0xFF]).copied().collect(),
            DecodeError::Truncated,
        ),
        (
            "coding fields written though they are the defaults",
            {
                let mut h = with(8, 0x72);
                h[9] = 0;
                h
            },
            DecodeError::InvalidHeader(decoder_core::HeaderField::CodingFields),
        ),
        (
            "coding fields cut short",
            good[..9].to_vec(),
            DecodeError::Truncated,
        ),
        (
            "min leaf 0",
            with(8, 0x40),
            DecodeError::InvalidHeader(decoder_core::HeaderField::LeafSizes),
        ),
        (
            "min leaf above max leaf",
            with(8, 0x34),
            DecodeError::InvalidHeader(decoder_core::HeaderField::LeafSizes),
        ),
        (
            "max leaf 8",
            with(8, 0x82),
            DecodeError::InvalidHeader(decoder_core::HeaderField::LeafSizes),
        ),
        (
            "payload shorter than the coder's first four bytes",
            sealed(3, &[0; 3]),
            DecodeError::Truncated,
        ),
        (
            "payload shorter than its length says",
            sealed(9, &[0; 8]),
            DecodeError::Truncated,
        ),
        (
            "bytes after the payload",
            sealed(7, &[0; 8]),
            DecodeError::InvalidHeader(decoder_core::HeaderField::TrailingBytes),
        ),
        (
            "payload length in six bytes",
            {
                let mut h = before_length.clone();
                h.extend_from_slice(&[0x80, 0x80, 0x80, 0x80, 0x80, 0]);
                h
            },
            DecodeError::InvalidHeader(decoder_core::HeaderField::PayloadLength),
        ),
        (
            "payload length above 2^32 - 1",
            {
                let mut h = before_length.clone();
                h.extend_from_slice(&[0xFF, 0xFF, 0xFF, 0xFF, 0x10]);
                h
            },
            DecodeError::InvalidHeader(decoder_core::HeaderField::PayloadLength),
        ),
        (
            "payload length with a redundant zero group",
            {
                let mut h = before_length.clone();
                h.extend_from_slice(&[0x88, 0x00]);
                h.extend_from_slice(&[0; 8]);
                h
            },
            DecodeError::InvalidHeader(decoder_core::HeaderField::PayloadLength),
        ),
        (
            "payload length cut short",
            {
                let mut h = before_length.clone();
                h.push(0x88);
                h
            },
            DecodeError::Truncated,
        ),
        ("checksum field zero", with(CHECKSUM_BYTES.start, 0), {
            let mut h = with(CHECKSUM_BYTES.start, 0);
            h[CHECKSUM_BYTES].fill(0);
            let computed = decoder_core::internal::syntax::stream_checksum(&h);
            DecodeError::ChecksumMismatch {
                stored: 0,
                computed,
            }
        }),
    ];
    // Every other version's stream tag: a tagged one is that version, an earlier one (no
    // version before the first tagged one had a tag) unknown bytes.
    let others: Vec<(String, Vec<u8>)> = (0..64)
        .filter(|&v| v != VERSION)
        .map(|v| (format!("version {v}'s tag"), with(0, 0x80 | v)))
        .collect();
    for (what, bytes) in &others {
        let v = bytes[0] & 0x3F;
        let expected = match v >= FIRST_TAGGED_VERSION {
            true => DecodeError::UnsupportedVersion(v),
            false => DecodeError::BadMagic,
        };
        cases.push((what.as_str(), bytes.clone(), expected));
    }
    for (what, bytes, expected) in cases {
        assert_eq!(
            decoder_core::Header::read(&bytes).err().or_else(|| {
                // Header fine: the error must come from the payload.
                let mut buf = vec![0u8; 256];
                pifs_tests::decode_into(&bytes, &mut buf).err()
            }),
            Some(expected),
            "{what}"
        );
        assert_eq!(decode_checked(&bytes), Err(expected), "{what}");
    }
    // And the header of a real stream, with each of those fields damaged.
    let (name, golden) = &streams()[0];
    for (i, v, expected) in [
        (0, b'X', DecodeError::BadMagic),
        (0, 0x81, DecodeError::BadMagic),
        (
            0,
            STREAM_TAG + 1,
            DecodeError::UnsupportedVersion(VERSION + 1),
        ),
        (
            1,
            (golden[1] & 7) | (17 << 3),
            DecodeError::InvalidHeader(decoder_core::HeaderField::Deblock),
        ),
    ] {
        let mut b = golden.clone();
        b[i] = v;
        assert_eq!(decode_checked(&b), Err(expected), "{name} byte {i} = {v}");
    }
    let mut b = golden.clone();
    b[6] = 0xFF;
    assert!(decode_checked(&b).is_err(), "{name} width field damaged");
}

#[test]
fn header_claiming_a_huge_image_needs_a_huge_buffer() {
    let data = sealed_stream(&header(65535, 65535, 2, 7), &[0x55; 64]);
    let header = decoder_core::Header::read(&data).unwrap();
    assert_eq!(
        Limits::pixels(1 << 24).check(&header),
        Err(DecodeError::TooLarge {
            width: 65535,
            height: 65535
        })
    );
    assert_eq!(Limits::NONE.check(&header), Ok(()));
    let narrow = Limits {
        max_width: 65534,
        ..Limits::NONE
    };
    assert!(narrow.check(&header).is_err());
    assert_eq!(header.pixel_count(), 65535 * 65535);
    assert_eq!(header.root_log2(), 16);
    let mut small = vec![0u8; 1 << 16];
    assert_eq!(
        pifs_tests::decode_into(&data, &mut small),
        Err(DecodeError::BufferTooSmall)
    );
}

/// Index of a golden stream.
fn golden_index() -> impl Strategy<Value = usize> {
    0..streams().len()
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = decode_checked(&data);
    }

    #[test]
    fn random_bytes_after_magic_never_panic(
        tail in proptest::collection::vec(any::<u8>(), 0..512),
    ) {
        let mut data = vec![STREAM_TAG];
        data.extend_from_slice(&tail);
        let _ = decode_checked(&data);
    }

    #[test]
    fn random_payload_behind_a_valid_header_never_panics(
        width in 1u16..200,
        height in 1u16..200,
        min_leaf in 1u8..=7,
        extra in 0u8..=6,
        payload in proptest::collection::vec(any::<u8>(), 0..1024),
    ) {
        let max_leaf = (min_leaf + extra).min(7);
        let data = sealed_stream(&header(width, height, min_leaf, max_leaf), &payload);
        let result = decode_checked(&data);
        if payload.len() < 4 {
            prop_assert_eq!(result, Err(DecodeError::Truncated));
        }
    }

    #[test]
    fn truncated_golden_streams_are_errors(
        which in golden_index(),
        cut in any::<prop::sample::Index>(),
    ) {
        let bytes = &streams()[which].1;
        let len = cut.index(bytes.len());
        prop_assert_eq!(decode_checked(&bytes[..len]), Err(DecodeError::Truncated));
    }

    #[test]
    fn golden_streams_with_bit_flips_never_panic(
        which in golden_index(),
        flips in proptest::collection::vec((any::<prop::sample::Index>(), 0u8..8), 1..8),
    ) {
        let mut bytes = streams()[which].1.clone();
        for (at, bit) in &flips {
            let i = at.index(bytes.len());
            bytes[i] ^= 1 << bit;
        }
        let _ = decode_checked(&bytes);
        // And with the checksum made to match, so that the damage reaches the header and
        // payload checks behind it.
        seal(&mut bytes);
        let _ = decode_checked(&bytes);
    }

    #[test]
    fn golden_payloads_with_bit_flips_never_panic(
        which in golden_index(),
        flips in proptest::collection::vec((any::<prop::sample::Index>(), 0u8..8), 1..4),
    ) {
        // Flips confined to the payload: the header stays valid, so the range decoder and the
        // syntax checks see every damaged stream.
        let mut bytes = streams()[which].1.clone();
        let start = decoder_core::Header::read(&bytes).unwrap().encoded_len();
        for (at, bit) in &flips {
            let i = start + at.index(bytes.len() - start);
            bytes[i] ^= 1 << bit;
        }
        // CRC-32 detects every error of up to 3 flipped bits (flips of the same bit cancel).
        if bytes != streams()[which].1 {
            prop_assert!(
                matches!(decode_checked(&bytes), Err(DecodeError::ChecksumMismatch { .. })),
                "payload damage not detected"
            );
        }
        seal(&mut bytes);
        let _ = decode_checked(&bytes);
    }

    #[test]
    fn golden_streams_with_overwritten_bytes_never_panic(
        which in golden_index(),
        writes in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
    ) {
        let mut bytes = streams()[which].1.clone();
        for (at, v) in &writes {
            let i = at.index(bytes.len());
            bytes[i] = *v;
        }
        let _ = decode_checked(&bytes);
        seal(&mut bytes);
        let _ = decode_checked(&bytes);
    }

    #[test]
    fn golden_streams_with_a_random_tail_never_panic(
        which in golden_index(),
        keep in any::<prop::sample::Index>(),
        tail in proptest::collection::vec(any::<u8>(), 0..256),
    ) {
        let golden = &streams()[which].1;
        let mut bytes = golden[..keep.index(golden.len() + 1)].to_vec();
        bytes.extend_from_slice(&tail);
        let _ = decode_checked(&bytes);
    }

    #[test]
    fn golden_headers_with_random_fields_never_panic(
        which in golden_index(),
        width in any::<u16>(),
        height in any::<u16>(),
        leaves in any::<u8>(),
    ) {
        // Dimensions and leaf sizes rewritten: the payload no longer matches the header, up to
        // images far larger than the buffer cap.
        let mut bytes = streams()[which].1.clone();
        bytes[8..10].copy_from_slice(&width.to_le_bytes());
        bytes[10..12].copy_from_slice(&height.to_le_bytes());
        bytes[12] = leaves;
        seal(&mut bytes);
        let result = decode_checked(&bytes);
        if width == 0 || height == 0 {
            prop_assert!(matches!(result, Err(DecodeError::InvalidHeader(_))), "{:?}", result);
        }
    }
}
