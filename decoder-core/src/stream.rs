//! Streaming and region decoding.
//!
//! [`decode_stream`] decodes from any [`ByteSource`] (a UART, a radio link, an SPI flash read
//! sequentially) without ever holding the stream in memory: the header is collected into a small
//! fixed buffer ([`MAX_HEADER_LEN`] bytes), parsed with [`Header::parse`], and the payload is fed
//! straight into the [`RangeDecoder`]. Each byte is pulled exactly once, in order.
//!
//! [`decode_region`] and [`decode_stream_region`] only synthesise the pixels inside a clip
//! rectangle. The whole payload is still entropy-decoded (the arithmetic coder and the adaptive
//! contexts must see every bit), but leaves outside the clip produce no pixels and cost no
//! synthesis.

use crate::bitstream::LeafSyntax;
use crate::bitstream::{
    stream_checksum, Header, CHECKSUM_BYTES, FIXED_HEADER_LEN, MAX_CODEBOOK, MAX_LENGTH_BYTES,
};
use crate::checksum::Crc32;
use crate::entropy::{ByteSource, Coder, RangeDecoder, SliceSource};
use crate::error::DecodeError;
use crate::patch::{Patch, PixelSink, Rect};
use crate::prediction::Frontier;
use crate::quadtree::{self, LeafInfo, Node, TreeVisitor};

/// Longest possible header: the fixed part, the longest payload length and two codebooks of
/// [`MAX_CODEBOOK`] levels (`17 + 5 + 2 * (1 + 2 * 16) = 88` bytes).
/// [`decode_stream`] never buffers more.
pub const MAX_HEADER_LEN: usize = FIXED_HEADER_LEN + MAX_LENGTH_BYTES + 2 * (1 + 2 * MAX_CODEBOOK);

/// Reads exactly the header's bytes from `source` and parses them.
///
/// The fixed part is read first; further bytes (the payload length and the optional codebooks)
/// are pulled one at a time only while [`Header::parse`] reports the header as truncated, so the
/// source is left at the first payload byte. Errors are those of [`Header::parse`] on the same
/// bytes; a source that ends early gives [`DecodeError::Truncated`] (or
/// [`DecodeError::BadMagic`], like a short slice would).
pub fn read_header_from<B: ByteSource>(source: &mut B) -> Result<Header, DecodeError> {
    read_header_checksummed(source).map(|(header, _)| header)
}

/// [`read_header_from`], also returning the CRC-32 state after the header's checksummed bytes.
pub(crate) fn read_header_checksummed<B: ByteSource>(
    source: &mut B,
) -> Result<(Header, Crc32), DecodeError> {
    let mut buf = [0u8; MAX_HEADER_LEN];
    let mut len = 0;
    while len < FIXED_HEADER_LEN {
        match source.next_byte() {
            Some(b) => {
                buf[len] = b;
                len += 1;
            }
            None => break,
        }
    }
    loop {
        match Header::parse(&buf[..len]) {
            Ok((header, _)) => {
                let mut crc = Crc32::default();
                crc.update(&buf[..CHECKSUM_BYTES.start]);
                crc.update(&buf[CHECKSUM_BYTES.end..len]);
                return Ok((header, crc));
            }
            Err(DecodeError::Truncated) if (FIXED_HEADER_LEN..MAX_HEADER_LEN).contains(&len) => {
                buf[len] = source.next_byte().ok_or(DecodeError::Truncated)?;
                len += 1;
            }
            Err(e) => return Err(e),
        }
    }
}

/// Decodes a stream read sequentially from `source`, handing pixels to `sink` tile by tile.
///
/// Produces the tiles (same order, same pixels) of [`crate::decode`] on the same bytes, while
/// holding at most [`MAX_HEADER_LEN`] bytes of the stream at a time. Because nothing is held,
/// the stream's checksum can only be checked at the end: a damaged stream may draw damaged
/// pixels before [`DecodeError::ChecksumMismatch`] (or the error it caused) is returned. Exactly
/// the header's and the payload's bytes are pulled from `source`, never one more.
pub fn decode_stream<B: ByteSource, S: PixelSink>(
    source: B,
    sink: &mut S,
) -> Result<Header, DecodeError> {
    decode_stream_region(source, Rect::of_size(u32::MAX, u32::MAX), sink)
}

/// Like [`decode_stream`], but only the pixels inside `clip` (image coordinates) are synthesised
/// and handed to `sink`; the payload is still read and entropy-decoded to its end.
pub fn decode_stream_region<B: ByteSource, S: PixelSink>(
    mut source: B,
    clip: Rect,
    sink: &mut S,
) -> Result<Header, DecodeError> {
    let (header, crc) = read_header_checksummed(&mut source)?;
    let payload = StreamPayload::new(source, &header, crc);
    walk_payload(&header, payload, clip, sink, |_| false)?;
    Ok(header)
}

/// Parses the header of the whole stream `data`, checks that the stream is exactly as long as
/// the header says and that its checksum matches, and returns the header and the payload.
/// Every decoding path over a slice starts here, so a damaged stream is refused before
/// anything is drawn.
pub fn open(data: &[u8]) -> Result<(Header, &[u8]), DecodeError> {
    let (header, offset) = Header::parse(data)?;
    let end = offset as u64 + u64::from(header.payload_len);
    if (data.len() as u64) < end {
        return Err(DecodeError::Truncated);
    }
    if data.len() as u64 > end {
        return Err(DecodeError::InvalidHeader(
            "payload length (bytes follow the payload)",
        ));
    }
    let computed = stream_checksum(data);
    if computed != header.checksum {
        return Err(DecodeError::ChecksumMismatch {
            stored: header.checksum,
            computed,
        });
    }
    Ok((header, &data[offset..]))
}

/// Decodes the stream in `data`, synthesising only the pixels inside `clip` (image
/// coordinates): tiles are those of [`crate::decode`], cut to the clip. The whole payload is
/// still entropy-decoded, so payload errors are reported wherever they are.
pub fn decode_region<S: PixelSink>(
    data: &[u8],
    clip: Rect,
    sink: &mut S,
) -> Result<Header, DecodeError> {
    let (header, payload) = open(data)?;
    walk_payload(&header, SliceSource::new(payload), clip, sink, |_| false)?;
    Ok(header)
}

/// The error [`walk_payload`] returns when its `stop` predicate ended the walk.
pub(crate) const STOPPED: DecodeError = DecodeError::InvalidData("walk stopped by the pixel sink");

/// A source of exactly one stream's payload, which knows how to check, once the walk is done,
/// that the payload was whole and (for a stream not verified beforehand) undamaged.
pub(crate) trait Payload: ByteSource {
    /// Whether [`Payload::finish`] checks the stream's checksum: the payload must then be read
    /// to its end even when no pixel of it is wanted.
    #[cfg_attr(not(feature = "embedded-graphics"), allow(dead_code))]
    const CHECKS_CHECKSUM: bool;

    /// After the walk: `Ok` when the walk used exactly the payload (and the checksum matches).
    fn finish(self, header: &Header) -> Result<(), DecodeError>;

    /// After a walk that failed with `error`: the error to report. A payload not verified
    /// beforehand reads the rest of its declared length, so that damage is reported as such
    /// ([`DecodeError::ChecksumMismatch`]) whichever syntax check it happened to trip first,
    /// exactly as the in-memory decoder reports it.
    fn after_error(self, header: &Header, error: DecodeError) -> DecodeError;
}

/// A payload in memory, already verified by [`open`] (exactly `payload_len` bytes, checksum
/// matched).
impl Payload for SliceSource<'_> {
    const CHECKS_CHECKSUM: bool = false;

    fn finish(mut self, _header: &Header) -> Result<(), DecodeError> {
        match self.next_byte() {
            None => Ok(()),
            Some(_) => Err(DecodeError::InvalidData("payload length")),
        }
    }

    fn after_error(self, _header: &Header, error: DecodeError) -> DecodeError {
        error
    }
}

/// The payload of a sequential source: at most the header's payload length is pulled, and
/// every byte goes through the stream's CRC, checked at the end.
pub(crate) struct StreamPayload<B> {
    inner: B,
    remaining: u32,
    crc: Crc32,
}

impl<B: ByteSource> StreamPayload<B> {
    /// The payload of a stream with `header`; `crc` is the checksum state after the header.
    pub(crate) fn new(inner: B, header: &Header, crc: Crc32) -> Self {
        StreamPayload {
            inner,
            remaining: header.payload_len,
            crc,
        }
    }
}

impl<B: ByteSource> ByteSource for StreamPayload<B> {
    #[inline]
    fn next_byte(&mut self) -> Option<u8> {
        if self.remaining == 0 {
            return None;
        }
        let b = self.inner.next_byte()?;
        self.remaining -= 1;
        self.crc.update_byte(b);
        Some(b)
    }
}

impl<B: ByteSource> Payload for StreamPayload<B> {
    const CHECKS_CHECKSUM: bool = true;

    /// The rest of the payload (which a valid stream does not have) goes into the checksum,
    /// which must match (damage is the likeliest cause of a short walk); then the walk must
    /// have used the whole payload.
    fn finish(self, header: &Header) -> Result<(), DecodeError> {
        let unread = self.remaining != 0;
        self.drain_and_check(header)?;
        if unread {
            return Err(DecodeError::InvalidData("payload length"));
        }
        Ok(())
    }

    fn after_error(self, header: &Header, error: DecodeError) -> DecodeError {
        self.drain_and_check(header).err().unwrap_or(error)
    }
}

impl<B: ByteSource> StreamPayload<B> {
    /// Reads the rest of the declared payload into the checksum and compares it.
    fn drain_and_check(mut self, header: &Header) -> Result<(), DecodeError> {
        while self.next_byte().is_some() {}
        if self.remaining != 0 {
            return Err(DecodeError::Truncated);
        }
        let computed = self.crc.value();
        if computed != header.checksum {
            return Err(DecodeError::ChecksumMismatch {
                stored: header.checksum,
                computed,
            });
        }
        Ok(())
    }
}

/// Runs the quadtree walk over the payload in `source`, rendering leaves into `sink` cut to
/// `clip` (itself cut to the image), then checks the payload ([`Payload::finish`]). After every
/// leaf, `stop(sink)` may end the walk early: it then returns [`STOPPED`].
pub(crate) fn walk_payload<P, S, F>(
    header: &Header,
    source: P,
    clip: Rect,
    sink: &mut S,
    stop: F,
) -> Result<(), DecodeError>
where
    P: Payload,
    S: PixelSink,
    F: Fn(&S) -> bool,
{
    let mut coder =
        RangeDecoder::start(source).map_err(|(source, e)| source.after_error(header, e))?;
    let image = Rect::of_size(header.width.into(), header.height.into());
    let mut visitor = ClipVisitor {
        clip: intersect(clip, image),
        image,
        sink,
        stop,
    };
    match run_walk(header, &mut coder, &mut visitor) {
        Ok(()) => coder.into_source().finish(header),
        // The sink asked to stop: nothing is wrong with the stream.
        Err(STOPPED) => Err(STOPPED),
        Err(e) => Err(coder.into_source().after_error(header, e)),
    }
}

/// The walk, its final state dropped: every decoding path goes through here. Not inlined, so
/// that the walk's state (the adaptive contexts and the prediction memory) stays in this one
/// frame instead of being copied into every caller's.
#[inline(never)]
pub(crate) fn run_walk<C: Coder, V: TreeVisitor>(
    header: &Header,
    coder: &mut C,
    visitor: &mut V,
) -> Result<(), DecodeError> {
    let mut state = quadtree::WalkState::FRESH;
    state.contexts.start();
    quadtree::walk_with(header, coder, visitor, &mut state)
}

/// The intersection of two rectangles (an empty rectangle at the origin when they are
/// disjoint).
pub fn intersect(a: Rect, b: Rect) -> Rect {
    let x0 = a.x.max(b.x);
    let y0 = a.y.max(b.y);
    let x1 = (u64::from(a.x) + u64::from(a.w)).min(u64::from(b.x) + u64::from(b.w));
    let y1 = (u64::from(a.y) + u64::from(a.h)).min(u64::from(b.y) + u64::from(b.h));
    if x1 <= u64::from(x0) || y1 <= u64::from(y0) {
        return Rect::of_size(0, 0);
    }
    // Both ends are at most one of the inputs' ends, which fit in u32 + u32; the sizes are at
    // most the smaller input's size, so they fit in u32.
    Rect {
        x: x0,
        y: y0,
        w: (x1 - u64::from(x0)) as u32,
        h: (y1 - u64::from(y0)) as u32,
    }
}

struct ClipVisitor<'s, S, F> {
    clip: Rect,
    image: Rect,
    sink: &'s mut S,
    stop: F,
}

impl<S: PixelSink, F: Fn(&S) -> bool> ClipVisitor<'_, S, F> {
    /// Whether the sink asked to stop.
    fn stopped(&self) -> Result<(), DecodeError> {
        if (self.stop)(self.sink) {
            Err(STOPPED)
        } else {
            Ok(())
        }
    }
}

impl<S: PixelSink, F: Fn(&S) -> bool> TreeVisitor for ClipVisitor<'_, S, F> {
    fn split(&mut self, _node: &Node) -> bool {
        false
    }

    fn prepare_leaf(&mut self, _node: &Node, _leaf: &mut LeafSyntax) {}

    // Not inlined: the synthesis buffers then live only while a leaf is drawn, instead of in
    // every frame of the recursive quadtree walk.
    #[inline(never)]
    fn leaf(&mut self, info: &LeafInfo, patch: &Patch) -> Result<(), DecodeError> {
        let node = &info.node;
        if self.clip.w > 0 && self.clip.h > 0 {
            patch.render(node.x, node.y, node.log2, self.clip, self.sink);
        }
        self.stopped()
    }

    // A leaf drawn whole (the clip holds all of it that is in the image) fills the frontier as
    // it is drawn; any other leaf has its edges rendered apart.
    #[inline(never)]
    fn leaf_with_frontier(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier,
    ) -> Result<(), DecodeError> {
        let node = &info.node;
        let square = Rect {
            x: node.x,
            y: node.y,
            w: node.size(),
            h: node.size(),
        };
        if !self.clip.contains(&intersect(square, self.image)) {
            frontier.record(node, patch);
            return self.leaf(info, patch);
        }
        let mut sink = frontier.capture(node, self.sink);
        patch.render(node.x, node.y, node.log2, self.clip, &mut sink);
        self.stopped()
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use std::path::PathBuf;
    use std::string::String;
    use std::vec::Vec;

    /// Records every tile.
    #[derive(Default, PartialEq, Debug)]
    struct Recorder {
        tiles: Vec<(u32, u32, u32, u32, Vec<u8>)>,
    }

    impl PixelSink for Recorder {
        fn tile(&mut self, x: u32, y: u32, w: u32, h: u32, pixels: &[u8]) {
            self.tiles.push((x, y, w, h, pixels.to_vec()));
        }
    }

    /// Yields one byte per call and counts the calls made after the end.
    struct ByteByByte<'a> {
        data: &'a [u8],
        pos: usize,
        past_end: usize,
    }

    impl ByteSource for ByteByByte<'_> {
        fn next_byte(&mut self) -> Option<u8> {
            let b = self.data.get(self.pos).copied();
            match b {
                Some(_) => self.pos += 1,
                None => self.past_end += 1,
            }
            b
        }
    }

    fn golden() -> Vec<(String, Vec<u8>)> {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/golden");
        let mut out = Vec::new();
        if let Ok(entries) = std::fs::read_dir(&dir) {
            for e in entries.flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                if name.ends_with(".pifs") {
                    out.push((name, std::fs::read(e.path()).unwrap()));
                }
            }
        }
        out.sort();
        out
    }

    fn header_with_codebooks() -> Vec<u8> {
        let mut h = Vec::from(*b"PIFS");
        h.extend_from_slice(&[crate::bitstream::VERSION, 1, 8, 1, 5, 0, 3, 0, 0x42]);
        // Checksum (not checked by the header parser), then a payload length of 300 (two
        // LEB128 bytes).
        h.extend_from_slice(&[1, 2, 3, 4, 0xAC, 0x02]);
        for len in [3u8, 16] {
            h.push(len);
            for i in 0..i16::from(len) {
                h.extend_from_slice(&(i * 100 - 700).to_le_bytes());
            }
        }
        h
    }

    #[test]
    fn header_is_read_exactly() {
        let mut bytes = header_with_codebooks();
        let len = bytes.len();
        bytes.extend_from_slice(&[0xAB, 0xCD]);
        let mut src = ByteByByte {
            data: &bytes,
            pos: 0,
            past_end: 0,
        };
        let header = read_header_from(&mut src).unwrap();
        assert_eq!(src.pos, len, "read past the header");
        assert_eq!(header.encoded_len(), len);
        assert_eq!(Header::parse(&bytes).unwrap(), (header, len));
        assert!(len <= MAX_HEADER_LEN);
    }

    #[test]
    fn every_truncated_header_matches_the_slice_parser() {
        let bytes = header_with_codebooks();
        for cut in 0..bytes.len() {
            let mut src = ByteByByte {
                data: &bytes[..cut],
                pos: 0,
                past_end: 0,
            };
            let streamed = read_header_from(&mut src);
            let sliced = Header::parse(&bytes[..cut]).map(|(h, _)| h);
            assert_eq!(streamed, sliced, "cut at {cut}");
        }
    }

    #[test]
    fn streamed_equals_sliced_for_every_golden_vector_and_prefix() {
        let vectors = golden();
        assert!(!vectors.is_empty(), "no golden vectors in tests/golden/");
        for (name, data) in &vectors {
            let mut sliced = Recorder::default();
            let r_slice = crate::decode(data, &mut sliced);
            let mut streamed = Recorder::default();
            let src = ByteByByte {
                data,
                pos: 0,
                past_end: 0,
            };
            let r_stream = decode_stream(src, &mut streamed);
            assert_eq!(r_stream, r_slice, "{name}");
            assert_eq!(streamed, sliced, "{name}: tiles differ");
            // Truncated streams fail identically; the slice decoder refuses them before
            // drawing, the streaming one after drawing a prefix of the image's tiles.
            for cut in (0..data.len()).step_by(1 + data.len() / 64) {
                let mut a = Recorder::default();
                let mut b = Recorder::default();
                let ra = crate::decode(&data[..cut], &mut a);
                let rb = decode_stream(SliceSource::new(&data[..cut]), &mut b);
                assert_eq!(ra, Err(DecodeError::Truncated), "{name} cut at {cut}");
                assert_eq!(ra, rb, "{name} cut at {cut}");
                assert!(
                    a.tiles.is_empty(),
                    "{name} cut at {cut}: drew a truncated stream"
                );
                assert_eq!(
                    b.tiles[..],
                    sliced.tiles[..b.tiles.len()],
                    "{name} cut at {cut}"
                );
            }
        }
    }

    #[test]
    fn region_decoding_is_the_full_decode_cut_to_the_clip() {
        for (name, data) in &golden() {
            let Ok(header) = crate::read_header(data) else {
                continue;
            };
            let (w, h) = (u32::from(header.width), u32::from(header.height));
            let mut full = std::vec![0u8; (w * h) as usize];
            if crate::decode_into(data, &mut full).is_err() {
                continue;
            }
            let clips = [
                Rect { x: 0, y: 0, w, h },
                Rect {
                    x: w / 3,
                    y: h / 4,
                    w: w / 2 + 1,
                    h: h / 3 + 1,
                },
                Rect {
                    x: w - 1,
                    y: 0,
                    w: 100,
                    h: 1,
                },
                Rect {
                    x: w,
                    y: h,
                    w: 5,
                    h: 5,
                },
            ];
            for clip in clips {
                let mut rec = Recorder::default();
                decode_region(data, clip, &mut rec).unwrap();
                let inside = intersect(clip, Rect::of_size(w, h));
                let mut seen = std::vec![0u32; (w * h) as usize];
                for (x, y, tw, th, px) in &rec.tiles {
                    assert!(
                        *tw as usize <= crate::patch::TILE && *th as usize <= crate::patch::TILE
                    );
                    for j in 0..*th {
                        for i in 0..*tw {
                            let (px_x, px_y) = (x + i, y + j);
                            assert!(
                                px_x >= inside.x
                                    && px_y >= inside.y
                                    && px_x < inside.x + inside.w
                                    && px_y < inside.y + inside.h,
                                "{name}: pixel ({px_x}, {px_y}) outside clip {clip:?}"
                            );
                            let k = (px_y * w + px_x) as usize;
                            seen[k] += 1;
                            assert_eq!(px[(j * tw + i) as usize], full[k], "{name}");
                        }
                    }
                }
                let covered = seen.iter().filter(|&&c| c == 1).count() as u32;
                assert_eq!(covered, inside.w * inside.h, "{name}: clip {clip:?}");
                assert!(seen.iter().all(|&c| c <= 1), "{name}: overdraw");
            }
        }
    }

    #[test]
    fn stop_predicate_ends_the_walk() {
        for (_, data) in &golden() {
            let Ok((header, offset)) = Header::parse(data) else {
                continue;
            };
            let mut rec = Recorder::default();
            let r = walk_payload(
                &header,
                SliceSource::new(&data[offset..]),
                Rect::of_size(u32::MAX, u32::MAX),
                &mut rec,
                |r: &Recorder| !r.tiles.is_empty(),
            );
            assert_eq!(r, Err(STOPPED));
        }
    }

    #[test]
    fn intersection() {
        let a = Rect {
            x: 2,
            y: 3,
            w: 10,
            h: 10,
        };
        assert_eq!(
            intersect(
                a,
                Rect {
                    x: 5,
                    y: 0,
                    w: 100,
                    h: 5
                }
            ),
            Rect {
                x: 5,
                y: 3,
                w: 7,
                h: 2
            }
        );
        assert_eq!(intersect(a, Rect::of_size(2, 100)), Rect::of_size(0, 0));
        assert_eq!(
            intersect(
                Rect {
                    x: u32::MAX,
                    y: u32::MAX,
                    w: u32::MAX,
                    h: u32::MAX
                },
                a
            ),
            Rect::of_size(0, 0)
        );
    }
}
