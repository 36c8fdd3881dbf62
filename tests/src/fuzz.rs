//! The fuzz checks. Each takes arbitrary bytes and panics only when the codec breaks a promise:
//!
//! - [`decode_bytes`]: decoding never panics, never writes outside the image or a pixel twice,
//!   and `Ok` means every pixel was written; the bytes are tried as given and with their
//!   checksum made to match, so that damage also reaches the syntax checks behind the checksum.
//!   Every tile also goes through the display adapter (`graphics::DrawSink`, dithered onto
//!   RGB565), whatever its shape.
//! - [`stream_equals_slice`]: the stream decoded from memory and delivered byte by byte through
//!   the streaming decoder gives the same result and the same tiles, and the streaming decoder
//!   never pulls a byte past the stream's end.
//! - [`roundtrip`]: a small image made of the bytes encodes within its budget and decodes to
//!   exactly the encoder's reconstruction.
//! - [`encode_input`]: image file bytes through the host's input side, as `pifs encode` reads
//!   them (header first, then the pixels within limits, orientation applied, converted to
//!   luma): never a panic, the decoded image is the size its header said, and a small one
//!   goes on through the encoder and back.
//! - [`large_dimensions`]: a valid, checksummed header declaring large dimensions, gray or
//!   colour, with a small payload: the host reads it header first (refusing it beyond its limits after the header
//!   alone, and never reading past the declared stream and one byte), and writes it band by
//!   band exactly as `decode_into` decodes it, or fails with the same error.
//! - [`decode_packets`]: a framed set of packets as a receiver gets them: each packet alone
//!   (also with its CRC made to match) draws only inside its region, no pixel twice, every one
//!   when it decodes, at the coded size and at a scale the input's length chooses; drawn around
//!   the other packets' regions, nothing inside them; and the host's assembly of the whole set,
//!   at the coded size and at that scale, never panics and gives an image of the size its
//!   packets declare.

use crate::CoverageSink;
use decoder_core::graphics::DrawSink;
use decoder_core::internal::syntax::seal;
use decoder_core::ByteSource;
use decoder_core::Tile;
use decoder_core::{DecodeError, PixelSink};
use embedded_graphics_core::draw_target::DrawTarget;
use embedded_graphics_core::geometry::{OriginDimensions, Size};
use embedded_graphics_core::pixelcolor::Rgb565;
use embedded_graphics_core::Pixel;

/// Largest image [`decode_bytes`] and [`stream_equals_slice`] decode (larger headers are checked
/// against a small buffer and the caller's limits only): the decoder's work follows the
/// declared image, not the input, and these two targets stay fast. [`large_dimensions`] decodes
/// up to 2^20 pixels and reads headers of any size.
const MAX_PIXELS: u64 = 1 << 16;

/// Check (a): arbitrary bytes through every in-memory decoding path.
pub fn decode_bytes(data: &[u8]) {
    decode_checked(data);
    let mut sealed = data.to_vec();
    seal(&mut sealed);
    // Bytes whose checksum already matches were just checked.
    if sealed != data {
        decode_checked(&sealed);
    }
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
    if let Err(e) = decoder_core::Decoder::new(data) {
        // Refused before drawing: no pixel buffer needed to check that nothing was drawn.
        let mut tiles = Tiles::default();
        assert_eq!(crate::decode(data, &mut tiles), Err(e));
        assert_eq!(tiles.count, 0, "a stream that failed its checks was drawn");
        return;
    }
    let mut sink = Drawn {
        coverage: CoverageSink::new(u32::from(header.width), u32::from(header.height)),
        panel: NullPanel,
    };
    let result = crate::decode(data, &mut sink);
    let sink = sink.coverage;
    assert!(sink.violations.is_empty(), "{:?}", sink.violations[0]);
    assert!(
        sink.counts.iter().all(|&c| c <= 1),
        "a pixel was written twice"
    );
    if result.is_ok() {
        assert!(
            sink.counts.iter().all(|&c| c == 1),
            "Ok, but a pixel was never written"
        );
    }
    // A 16-bit stream's every tile carries its values, in the header's range; an 8-bit
    // stream's none.
    match header.range {
        Some(range) => {
            assert_eq!(sink.tiles_with_values, sink.tiles, "a tile without values");
            if let Some((lo, hi)) = sink.value_extremes {
                assert!(lo >= range.low && hi <= range.high(), "values out of range");
            }
        }
        None => assert_eq!(sink.tiles_with_values, 0, "values from an 8-bit stream"),
    }
}

/// Every tile checked by a [`CoverageSink`] and drawn through the display adapter.
struct Drawn {
    coverage: CoverageSink,
    panel: NullPanel,
}

impl PixelSink for Drawn {
    type Error = std::convert::Infallible;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Self::Error> {
        self.coverage.tile(tile)?;
        DrawSink::new(&mut self.panel).tile(tile)
    }
}

/// An RGB565 display that takes every colour drawn onto it and keeps none.
struct NullPanel;

impl OriginDimensions for NullPanel {
    fn size(&self) -> Size {
        Size::new(u32::from(u16::MAX), u32::from(u16::MAX))
    }
}

impl DrawTarget for NullPanel {
    type Color = Rgb565;
    type Error = std::convert::Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<Rgb565>>>(
        &mut self,
        pixels: I,
    ) -> Result<(), Self::Error> {
        for pixel in pixels {
            std::hint::black_box(pixel);
        }
        Ok(())
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
    if sealed != data {
        stream_vs_slice(&sealed);
    }
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

/// Largest input [`encode_input`] looks at: a fuzzer's inputs stay small, a file's header must
/// not make the host allocate by what it declares.
pub const MAX_IMAGE_BYTES: usize = 1 << 16;

/// Check (d): image file bytes through the host's input side.
pub fn encode_input(data: &[u8]) {
    use host_encoder::io::{DecodedImage, ImageLimits, ImageProbe};
    if data.len() > MAX_IMAGE_BYTES {
        return;
    }
    // No extension: the contents decide the format, as for standard input.
    let path = std::path::Path::new("fuzz-input");
    let limits = ImageLimits {
        max_pixels: 1 << 16,
        max_alloc: 1 << 24,
    };
    let probe = ImageProbe::read(data, path);
    let decoded = DecodedImage::decode(data, path, &limits);
    let (probe, decoded) = match (probe, decoded) {
        (Ok(p), Ok(d)) => (p, d),
        (Err(_), Ok(_)) => panic!("decoded an image whose header was refused"),
        _ => return,
    };
    let plane = decoded.plane;
    assert_eq!(
        (plane.width, plane.height),
        (probe.width, probe.height),
        "decoded size differs from the header's"
    );
    assert_eq!(plane.data.len() as u64, probe.pixels());
    if probe.pixels() > 24 * 24 || probe.pixels() == 0 {
        return;
    }
    let n = plane.data.len();
    let budget = 40 + data.len() % 200;
    let analysis = host_encoder::analyse(plane, &host_encoder::EncoderConfig::default(), &|_| {})
        .expect("analysis of a small image");
    match analysis.encode(host_encoder::Target::Bytes(budget)) {
        Ok(encoded) => {
            assert!(encoded.bytes.len() <= budget, "budget overshot");
            let mut out = vec![0u8; n];
            crate::decode_into(&encoded.bytes, &mut out).expect("decodes");
            assert!(
                out == encoded.reconstruction,
                "decoder and encoder disagree"
            );
        }
        Err(host_encoder::EncodeError::BudgetTooSmall { .. }) => {}
        Err(e) => panic!("encode failed: {e}"),
    }
}

/// Limits of [`large_dimensions`]: the host refuses headers above this many pixels...
const LARGE_LIMIT: u64 = 1 << 26;
/// ... and the stream is decoded band by band only up to this many pixels and leaves (the
/// work of a decode follows the declared image, not the payload).
const LARGE_DECODE_PIXELS: u64 = 1 << 20;
const LARGE_DECODE_LEAVES: u64 = 1 << 14;

/// Bytes of a [`large_stream`] input before its payload: sizes, leaf sizes, channels.
pub const LARGE_PREFIX: usize = 6;

/// The byte of a [`large_stream`] input that chooses a header's leaf sizes and stripe width,
/// when it can say them (largest leaf of 16 to 128 px, at most three sizes apart; stripe of 0,
/// 1, 2 or 4 coding tiles), with the edge smoothing of 0, 2, 8 and 16 nearest the header's.
pub fn large_leaf_byte(header: &decoder_core::Header) -> Option<u8> {
    let max = header.max_leaf_log2.checked_sub(4).filter(|&m| m < 4)?;
    let span = header
        .max_leaf_log2
        .checked_sub(header.min_leaf_log2)
        .filter(|&d| d < 4)?;
    let stripe = [0, 1, 2, 4].iter().position(|&s| s == header.stripe)? as u8;
    let deblock = (0..4u8)
        .min_by_key(|&k| [0u8, 2, 8, 16][usize::from(k)].abs_diff(header.deblock))
        .unwrap_or(0);
    Some(max | span << 2 | stripe << 4 | deblock << 6)
}

/// The stream [`large_dimensions`] makes of `data`: width and height (big-endian, 2 bytes
/// each), a byte choosing the leaf sizes (bits 0–3), the stripe width (bits 4–5: the whole
/// width, 1, 2 or 4 coding tiles) and the edge smoothing (bits 6–7), a byte choosing the
/// channels (bit 0: 1, grayscale, or 3, colour; bit 1: a 16-bit grayscale stream), the rest the payload;
/// header written and sealed.
pub fn large_stream(data: &[u8]) -> Option<Vec<u8>> {
    use decoder_core::internal::syntax::Header;
    use decoder_core::SampleRange;
    if data.len() < LARGE_PREFIX {
        return None;
    }
    let width = u16::from_be_bytes([data[0], data[1]]).max(1);
    let height = u16::from_be_bytes([data[2], data[3]]).max(1);
    let max_leaf_log2 = 4 + data[4] % 4;
    let min_leaf_log2 = (max_leaf_log2 - (data[4] >> 2) % 4).max(1);
    let payload = &data[LARGE_PREFIX..];
    let channels = if data[5] & 1 == 0 { 1 } else { 3 };
    // Bit 1 of the channels byte: a 16-bit stream (grayscale, unsmoothed, the widest range).
    let range = (channels == 1 && data[5] & 2 != 0).then_some(SampleRange::covering(0, u16::MAX));
    let header = Header {
        width,
        height,
        channels,
        bit_depth: if range.is_some() { 16 } else { 8 },
        min_leaf_log2,
        max_leaf_log2,
        stripe: [0, 1, 2, 4][usize::from(data[4] >> 4) % 4],
        deblock: match range {
            Some(_) => 0,
            None => [0, 2, 8, 16][usize::from(data[4] >> 6)],
        },
        payload_len: payload.len() as u32,
        checksum: 0,
        range,
    };
    let mut stream = vec![0u8; header.encoded_len()];
    header.write(&mut stream);
    stream.extend_from_slice(payload);
    seal(&mut stream);
    Some(stream)
}

/// Reads a slice and counts what it hands out.
struct CountingReader<'a> {
    data: &'a [u8],
    pulled: usize,
}

impl std::io::Read for CountingReader<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.data.len() - self.pulled);
        buf[..n].copy_from_slice(&self.data[self.pulled..self.pulled + n]);
        self.pulled += n;
        Ok(n)
    }
}

/// Check (e): large declared dimensions, small payloads, through the host's stream input and
/// band writer.
pub fn large_dimensions(data: &[u8]) {
    use host_encoder::io::{decode_to_image, FileError, OutputFormat, StreamInput};
    let Some(stream) = large_stream(data) else {
        return;
    };
    let header =
        decoder_core::Header::read(&stream).expect("a header written by the encoder's rules");
    // Followed by endless zeros, as a pipe might be: read header first, bounded.
    let mut tail = stream.clone();
    tail.extend_from_slice(&[0; 64]);
    let mut reader = CountingReader {
        data: &tail,
        pulled: 0,
    };
    let name = std::path::Path::new("fuzz.pifs");
    let limits = decoder_core::Limits::pixels(LARGE_LIMIT);
    let result = StreamInput::from_reader(&mut reader, name, &limits);
    if limits.check(&header).is_err() {
        assert!(
            matches!(
                result,
                Err(FileError::Stream {
                    source: DecodeError::TooLarge { .. },
                    ..
                })
            ),
            "a header beyond the limits was not refused"
        );
        assert_eq!(
            reader.pulled,
            header.encoded_len(),
            "read past a refused header"
        );
        return;
    }
    assert_eq!(
        reader.pulled as u64,
        header.stream_len() + 1,
        "read past the stream"
    );
    assert!(result.is_err(), "bytes after the stream were accepted");
    let input = StreamInput::from_reader(&stream[..], name, &limits).expect("a sealed stream");
    let pixels = header.pixel_count() as u64;
    let leaves = pixels >> (2 * u32::from(header.min_leaf_log2));
    if pixels > LARGE_DECODE_PIXELS || leaves > LARGE_DECODE_LEAVES {
        return;
    }
    let channels = usize::from(header.channels);
    let mut want = vec![0u8; header.pixel_count() * channels];
    let reference = decoder_core::Decoder::new(&stream)
        .expect("a sealed stream")
        .stripe_capacity::<{ host_encoder::io::HOST_STRIPE }>()
        .decode_into(&mut want);
    // The smallest band (a leaf's height of rows): as many decodes as the order needs.
    // PPM holds a colour stream's pixels as they are, PGM a gray one's.
    let (format, magic) = if channels == 3 {
        (OutputFormat::Ppm, "P6")
    } else {
        (OutputFormat::Pgm, "P5")
    };
    let banded = decode_to_image(
        &input,
        format,
        decoder_core::Scale::One,
        Vec::new(),
        name,
        1,
    );
    match (reference, banded) {
        (Ok(_), Ok((_, pgm))) => {
            let head = format!("{magic}\n{} {}\n255\n", header.width, header.height);
            assert!(pgm.starts_with(head.as_bytes()));
            assert!(pgm[head.len()..] == want[..], "banded pixels differ");
        }
        (Err(e), Err(FileError::Stream { source, .. })) => {
            assert_eq!(source, e, "banded and whole decodes fail differently")
        }
        (Ok(_), Err(e)) => panic!("the banded decode failed: {e}"),
        (Err(e), Ok(_)) => panic!("the banded decode succeeded where decode_into failed: {e}"),
        (Err(_), Err(e)) => panic!("the banded decode failed otherwise: {e}"),
    }
}

/// Most packets of one input [`decode_packets`] looks at.
const MAX_PACKETS: usize = 16;

/// Check (f): see the module's list.
pub fn decode_packets(data: &[u8]) {
    use decoder_core::internal::packet::{packet_crc, CRC_LEN};
    use decoder_core::Packet;
    let frames = host_encoder::packets::unframe(data);
    let mut inputs: Vec<Vec<u8>> = Vec::new();
    for frame in frames.into_iter().take(MAX_PACKETS) {
        let mut sealed = frame.clone();
        if sealed.len() > CRC_LEN {
            let body = sealed.len() - CRC_LEN;
            let crc = packet_crc(&sealed[..body]);
            sealed[body..].copy_from_slice(&crc);
        }
        let same = sealed == frame;
        inputs.push(frame);
        if !same {
            inputs.push(sealed);
        }
    }
    let parsed: Vec<Packet<'_>> = inputs
        .iter()
        .filter_map(|b| Packet::parse(b).ok())
        .collect();
    let regions: Vec<decoder_core::Rect> = parsed.iter().map(|p| p.region).collect();
    // A scale for the input, from its length (the bytes themselves are the packets').
    let scale = decoder_core::Scale::ALL[data.len() % decoder_core::Scale::ALL.len()];
    for (i, p) in parsed.iter().enumerate() {
        if u64::from(p.width) * u64::from(p.height) > MAX_PIXELS {
            continue;
        }
        check_packet_alone(p);
        let scaled = p.scale(scale);
        let (w, h) = scaled.output_size();
        if u64::from(w) * u64::from(h) <= MAX_PIXELS {
            check_packet_alone(&scaled);
        }
        // Around the others' regions: nothing inside them.
        let others: Vec<decoder_core::Rect> = regions
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, r)| *r)
            .collect();
        let mut sink = CoverageSink::new(u32::from(p.width), u32::from(p.height));
        let _ = p.decode_around(&others, &mut sink);
        assert!(sink.violations.is_empty(), "{:?}", sink.violations[0]);
        for (at, &count) in sink.counts.iter().enumerate() {
            let (x, y) = (
                (at % usize::from(p.width)) as u32,
                (at / usize::from(p.width)) as u32,
            );
            if count > 0 {
                assert!(
                    p.region.contains_point(x, y) && !others.iter().any(|r| r.contains_point(x, y)),
                    "drawn around: pixel ({x}, {y})"
                );
            }
        }
    }
    for scale in [decoder_core::Scale::One, scale] {
        let set = inputs.iter().map(Vec::as_slice);
        if let Ok(image) = host_encoder::packets::assemble_at(set, MAX_PIXELS, scale) {
            let expected =
                image.width as usize * image.height as usize * usize::from(image.channels);
            assert_eq!(image.pixels.len(), expected);
            assert!(image.received.len() <= usize::from(image.count));
        }
    }
    check_device_rebuild(&inputs);
}

/// The packets added to a device's rebuild as they come (slots as long as the longest, for
/// the first 64 points of the code): no panic, and every data packet added comes back as it
/// was, whatever was rebuilt around it.
fn check_device_rebuild(inputs: &[Vec<u8>]) {
    use decoder_core::{Packet, ParityPacket, Rebuild};
    let slot_len = inputs.iter().map(Vec::len).max().unwrap_or(0);
    let mut buf = vec![0u8; Rebuild::buffer_len(64, 0, slot_len)];
    let mut code = Rebuild::new(slot_len, &mut buf);
    let mut added: Vec<(u16, &[u8])> = Vec::new();
    for input in inputs {
        match ParityPacket::parse(input) {
            Ok(parity) => {
                let _ = code.add_parity(&parity);
            }
            Err(_) => {
                if code.add_packet(input).is_ok() {
                    let index = Packet::parse(input).map(|p| p.index).unwrap_or(u16::MAX);
                    added.retain(|&(i, _)| i != index);
                    added.push((index, input));
                }
            }
        }
    }
    let _ = code.rebuild();
    let mut out = vec![0u8; slot_len + 16];
    for index in 0..64 {
        let _ = code.packet(index, &mut out);
    }
    for (index, bytes) in added {
        let len = code
            .packet(index, &mut out)
            .expect("a packet added is held");
        assert_eq!(&out[..len], bytes, "packet {index} as added");
    }
}

/// One packet alone, at its scale: draws only inside its region, no pixel twice, all of it
/// on success.
fn check_packet_alone(p: &decoder_core::Packet<'_>) {
    let region = p.output_region();
    let (width, height) = p.output_size();
    let mut sink = CoverageSink::new(width, height);
    let result = p.decode(&mut sink);
    assert!(sink.violations.is_empty(), "{:?}", sink.violations[0]);
    for (at, &count) in sink.counts.iter().enumerate() {
        let (x, y) = ((at % width as usize) as u32, (at / width as usize) as u32);
        let inside = region.contains_point(x, y);
        assert!(
            count <= u32::from(inside),
            "packet pixel ({x}, {y}) drawn {count} times"
        );
        if result.is_ok() && inside {
            assert_eq!(count, 1, "Ok, but packet pixel ({x}, {y}) was not drawn");
        }
    }
}
