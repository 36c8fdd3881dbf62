//! The fuzz checks. Each takes arbitrary bytes and panics only when the codec breaks a promise:
//!
//! - [`decode_bytes`]: decoding never panics, never writes outside the image or a pixel twice,
//!   and `Ok` means every pixel was written; the bytes are tried as given and with their
//!   checksum made to match, so that damage also reaches the syntax checks behind the checksum.
//! - [`stream_equals_slice`]: the stream decoded from memory and delivered byte by byte through
//!   the streaming decoder gives the same result and the same tiles, and the streaming decoder
//!   never pulls a byte past the stream's end.
//! - [`roundtrip`]: a small image made of the bytes encodes within its budget and decodes to
//!   exactly the encoder's reconstruction.

use crate::CoverageSink;
use decoder_core::internal::syntax::seal;
use decoder_core::ByteSource;
use decoder_core::{DecodeError, PixelSink};

/// Largest image [`decode_bytes`] decodes into a buffer (larger headers are checked against a
/// small buffer and the caller's limits only).
const MAX_PIXELS: u64 = 1 << 16;

/// Check (a): arbitrary bytes through every in-memory decoding path.
pub fn decode_bytes(data: &[u8]) {
    decode_checked(data);
    let mut sealed = data.to_vec();
    seal(&mut sealed);
    decode_checked(&sealed);
}

fn decode_checked(data: &[u8]) {
    let header = match decoder_core::Header::read(data) {
        Ok(h) => h,
        Err(e) => {
            let mut sink = CoverageSink::new(1, 1);
            assert_eq!(crate::decode(data, &mut sink).err(), Some(e));
            assert_eq!(sink.tiles, 0, "tiles drawn from a stream with a bad header");
            return;
        }
    };
    let limits = decoder_core::Limits::pixels(MAX_PIXELS);
    if limits.check(&header).is_err() {
        let mut small = [0u8; 64];
        // A stream that passes its checks is refused for the buffer, before anything is
        // decoded.
        if let (true, Ok(decoder)) = (
            header.pixel_count() > small.len(),
            decoder_core::Decoder::new(data),
        ) {
            assert_eq!(
                decoder.decode_into(&mut small),
                Err(DecodeError::BufferTooSmall)
            );
        }
        return;
    }
    let mut sink = CoverageSink::new(u32::from(header.width), u32::from(header.height));
    let result = crate::decode(data, &mut sink);
    assert!(sink.violations.is_empty(), "{:?}", sink.violations[0]);
    assert!(
        sink.counts.iter().all(|&c| c <= 1),
        "a pixel was written twice"
    );
    if decoder_core::Decoder::new(data).is_err() {
        assert_eq!(sink.tiles, 0, "a stream that failed its checks was drawn");
    }
    if result.is_ok() {
        assert!(
            sink.counts.iter().all(|&c| c == 1),
            "Ok, but a pixel was never written"
        );
    }
}

/// A digest of the tiles a decoder produces, in order (64-bit FNV-1a over positions, sizes and
/// pixels): cheap enough to keep the fuzzer fast, and two tile sequences that differ collide
/// with probability about 2^-64.
#[derive(Debug, PartialEq, Eq)]
struct Tiles {
    count: usize,
    digest: u64,
}

impl Default for Tiles {
    fn default() -> Self {
        Tiles {
            count: 0,
            digest: 0xcbf2_9ce4_8422_2325,
        }
    }
}

impl Tiles {
    fn eat(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.digest = (self.digest ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
}

impl PixelSink for Tiles {
    type Error = std::convert::Infallible;

    fn tile(&mut self, tile: decoder_core::Tile<'_>) -> Result<(), Self::Error> {
        self.count += 1;
        let decoder_core::Rect { x, y, w, h } = tile.area;
        for v in [x, y, w, h] {
            self.eat(&v.to_le_bytes());
        }
        self.eat(tile.pixels);
        Ok(())
    }
}

/// Delivers a slice one byte at a time and counts the bytes pulled.
struct OneByOne<'a> {
    data: &'a [u8],
    pulled: usize,
}

impl ByteSource for OneByOne<'_> {
    fn next_byte(&mut self) -> Option<u8> {
        let b = self.data.get(self.pulled).copied();
        if b.is_some() {
            self.pulled += 1;
        }
        b
    }
}

/// Check (b): whole versus byte by byte, on the bytes as given and with a matching checksum.
pub fn stream_equals_slice(data: &[u8]) {
    stream_vs_slice(data);
    let mut sealed = data.to_vec();
    seal(&mut sealed);
    stream_vs_slice(&sealed);
}

fn stream_vs_slice(data: &[u8]) {
    let header = decoder_core::Header::read(data);
    if let Ok(h) = &header {
        // Keep the tile log small.
        if decoder_core::Limits::pixels(MAX_PIXELS).check(h).is_err() {
            return;
        }
    }
    // A sequential source does not end where the stream does: the streaming decoder stops at
    // the declared end, so it is compared with the in-memory decoder on exactly the stream.
    let exact = match &header {
        Ok(h) if data.len() as u64 > h.stream_len() => &data[..h.stream_len() as usize],
        _ => data,
    };
    let mut whole = Tiles::default();
    let r_whole = crate::decode(exact, &mut whole);
    let mut streamed = Tiles::default();
    let mut source = OneByOne { data, pulled: 0 };
    let r_streamed = crate::decode_stream(&mut source, &mut streamed);
    assert_eq!(r_streamed, r_whole, "streamed and in-memory results differ");
    assert!(source.pulled <= exact.len(), "read past the stream's end");
    if decoder_core::Decoder::new(exact).is_ok() {
        assert!(streamed == whole, "streamed and in-memory tiles differ");
    } else {
        assert_eq!(whole.count, 0, "a stream that failed its checks was drawn");
        // The streaming decoder may have drawn before it could tell: a prefix of the tiles it
        // would draw were the damage not there is all that can be said, so no more is checked.
    }
    if r_whole.is_ok() {
        assert_eq!(source.pulled, exact.len(), "stream not read to its end");
    }
}

/// Check (c): a small image from the bytes (`width-1`, `height-1`, a budget byte, then pixels,
/// repeated to fill the image) encodes within its budget and decodes to the encoder's
/// reconstruction.
pub fn roundtrip(data: &[u8]) {
    if data.len() < 3 {
        return;
    }
    let width = 1 + u32::from(data[0] % 48);
    let height = 1 + u32::from(data[1] % 48);
    let pixels = &data[3..];
    let n = (width * height) as usize;
    let plane: Vec<u8> = if pixels.is_empty() {
        vec![128; n]
    } else {
        pixels.iter().copied().cycle().take(n).collect()
    };
    // Budgets from a few bytes (possibly too small: then a typed error) to 2 bpp.
    let budget = 8 + usize::from(data[2]) * n / 1024;
    let plane = host_encoder::Plane::new(width, height, plane);
    let analysis = host_encoder::analyse(plane, &host_encoder::EncoderConfig::default(), &|_| {})
        .expect("analysis of a small image");
    match analysis.encode(host_encoder::Target::Bytes(budget)) {
        Ok(encoded) => {
            assert!(encoded.bytes.len() <= budget, "budget overshot");
            let mut out = vec![0u8; n];
            let header = crate::decode_into(&encoded.bytes, &mut out).expect("decodes");
            assert_eq!(
                (u32::from(header.width), u32::from(header.height)),
                (width, height)
            );
            assert!(
                out == encoded.reconstruction,
                "decoder and encoder disagree"
            );
        }
        Err(host_encoder::EncodeError::BudgetTooSmall { .. }) => {}
        Err(e) => panic!("encode failed: {e}"),
    }
}
