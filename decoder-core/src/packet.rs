//! Packets for lossy links (`docs/bitstream.md`, section 9): an image sent as self-contained
//! packets of a few hundred bytes, each a rectangle of the image coded as its own stream
//! (fresh contexts, nothing predicted from outside it) behind a compact header and its own
//! CRC-16. Any subset, in any order, decodes: each packet draws its region and nothing else; a
//! *preview* packet codes the whole image coarsely, to show first and to fill the regions of
//! lost packets.
//!
//! Where a packet's bytes are parsed: [`Packet::parse`]. Where its pixels are made: the
//! ordinary walk of its region's stream, through [`Packet::decode`].

use crate::checksum::crc16;
use crate::decoder::Decoder;
use crate::error::{DecodeError, DrawError, HeaderField};
use crate::format::{read_leb128, write_leb128, Leb128Error, PACKET_TAG};
use crate::geometry::Rect;
use crate::syntax::{
    check_coding_fields, check_first_byte, read_side, side_error, write_side, Header, CODING_BYTES,
    DEBLOCK_SHIFT, FLAG_CODING, FLAG_COLOUR,
};
use crate::synthesis::{PixelSink, Scale, Tile};

/// Regions are placed and sized in units of this many pixels.
pub const REGION_UNIT: u32 = 8;
/// The packet's CRC-16 trails it.
pub const CRC_LEN: usize = 2;
/// Flag bit: a preview packet (the whole image, coarse; no region fields). The other bits are
/// a stream's ([`FLAG_COLOUR`], [`FLAG_CODING`], the smoothing strength).
const FLAG_PREVIEW: u8 = 2;
/// The leaf sizes (`max << 4 | min`) and the stripe of a packet without its coding flag: the
/// reference encoder's defaults for packets (leaves of 4 to 128 pixels, stripes of 512).
pub const DEFAULT_CODING: [u8; 2] = [0x72, 4];
/// A varint of the packet header holds at most 16 bits: three LEB128 bytes.
const MAX_VARINT_BYTES: usize = 3;

/// What a packet covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PacketKind {
    /// The whole image, coarsely: shown first, and under every region that did not arrive.
    Preview,
    /// One rectangle of the image at the stream's full quality.
    Region,
}

/// One packet, parsed and checked (its CRC, every field): what a receiver needs to place it
/// without any other packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Packet<'a> {
    /// Which image the packet belongs to (the sender numbers its images).
    pub image_id: u16,
    /// This packet's number, `0..count`.
    pub index: u16,
    /// How many packets the image was sent as (previews included).
    pub count: u16,
    /// Preview or region.
    pub kind: PacketKind,
    /// The whole image's width, pixels.
    pub width: u16,
    /// The whole image's height, pixels.
    pub height: u16,
    /// Channels of the image: 1 (gray) or 3 (colour).
    pub channels: u8,
    /// The pixels this packet draws, in image coordinates (the whole image for a preview).
    pub region: Rect,
    /// The region's stream: its header (the region's size, the coding fields) ...
    stream: Header,
    /// ... and its arithmetic-coded payload.
    payload: &'a [u8],
    /// The scale it draws at ([`Packet::scale`]).
    scale: Scale,
}

impl<'a> Packet<'a> {
    /// Parses and checks one packet: its CRC-16 first (a damaged packet is refused before
    /// anything else is read), then every field.
    pub fn parse(data: &'a [u8]) -> Result<Self, DecodeError> {
        check_first_byte(data, PACKET_TAG)?;
        if data.len() < 1 + CRC_LEN {
            return Err(DecodeError::Truncated);
        }
        let (body, crc) = data.split_at(data.len() - CRC_LEN);
        let stored = u32::from(u16::from_le_bytes([crc[0], crc[1]]));
        let computed = u32::from(crc16(body));
        if computed != stored {
            return Err(DecodeError::ChecksumMismatch { stored, computed });
        }
        let mut reader = Reader { data: body, pos: 1 };
        let image_id = u16::from_le_bytes([reader.byte()?, reader.byte()?]);
        let flags = reader.byte()?;
        let channels = if flags & FLAG_COLOUR != 0 { 3 } else { 1 };
        if channels == 3 && !cfg!(feature = "colour") {
            return Err(DecodeError::UnsupportedChannels(channels));
        }
        let index = reader.varint()?;
        let count = reader.varint()?;
        if index >= count {
            return Err(DecodeError::InvalidHeader(HeaderField::PacketField));
        }
        let width = read_side(reader.data, &mut reader.pos).map_err(side_error)?;
        let height = read_side(reader.data, &mut reader.pos).map_err(side_error)?;
        let (kind, region) = if flags & FLAG_PREVIEW != 0 {
            let whole = Rect::of_size(width.into(), height.into());
            (PacketKind::Preview, whole)
        } else {
            let mut units = [0u32; 4];
            for unit in units.iter_mut() {
                *unit = u32::from(reader.varint()?);
            }
            (PacketKind::Region, region_of(units, width, height)?)
        };
        let [leaf_sizes, stripe] = if flags & FLAG_CODING != 0 {
            // Written only when not the defaults, as in a stream's header.
            match [reader.byte()?, reader.byte()?] {
                DEFAULT_CODING => {
                    return Err(DecodeError::InvalidHeader(HeaderField::CodingFields))
                }
                fields => fields,
            }
        } else {
            DEFAULT_CODING
        };
        let deblock = flags >> DEBLOCK_SHIFT;
        let (min_leaf_log2, max_leaf_log2) = check_coding_fields(leaf_sizes, deblock)?;
        let payload = body.get(reader.pos..).unwrap_or_default();
        let stream = Header {
            // The region lies in the image, so its sides fit 16 bits.
            width: region.w as u16,
            height: region.h as u16,
            channels,
            bit_depth: 8,
            min_leaf_log2,
            max_leaf_log2,
            stripe,
            deblock,
            payload_len: payload.len() as u32,
            checksum: stored,
            range: None,
        };
        Ok(Packet {
            image_id,
            index,
            count,
            kind,
            width,
            height,
            channels,
            region,
            stream,
            payload,
            scale: Scale::One,
        })
    }

    /// The header of the region's stream (its size is the region's; its checksum is the
    /// packet's).
    pub fn stream_header(&self) -> &Header {
        &self.stream
    }

    /// The packet drawn at `scale` of the image's size (see [`Scale`]): its drawing methods
    /// then take and give coordinates of the scaled image, where its region is
    /// [`Packet::output_region`]. Regions start on multiples of [`REGION_UNIT`] pixels, so
    /// at every scale they meet exactly and their pixels are those of the whole picture
    /// decoded at that scale.
    pub fn scale(mut self, scale: Scale) -> Self {
        self.scale = scale;
        self
    }

    /// Width and height of the whole image at the packet's scale ([`Packet::scale`]), rounded
    /// up as a scaled decode's ([`Scale::apply`]).
    pub fn output_size(&self) -> (u32, u32) {
        (
            self.scale.apply(self.width.into()),
            self.scale.apply(self.height.into()),
        )
    }

    /// The pixels this packet draws at its scale ([`Packet::scale`]; at the coded size,
    /// [`Packet::region`]).
    pub fn output_region(&self) -> Rect {
        let k = self.scale.log2();
        let place = |v: u32| if k >= 0 { v << k } else { v >> -k };
        Rect {
            x: place(self.region.x),
            y: place(self.region.y),
            w: self.scale.apply(self.region.w),
            h: self.scale.apply(self.region.h),
        }
    }

    /// Draws the packet's region into `sink`, in image coordinates: every pixel of
    /// [`Packet::output_region`], tile by tile.
    pub fn decode<S: PixelSink + ?Sized>(&self, sink: &mut S) -> Result<(), DrawError<S::Error>> {
        self.decode_clipped(Rect::EVERYTHING, sink)
    }

    /// Draws only the pixels of the packet's region inside `area` (image coordinates): how a
    /// receiver fills a lost region from the preview, or redraws part of the screen. The
    /// whole payload is still decoded.
    pub fn decode_clipped<S: PixelSink + ?Sized>(
        &self,
        area: Rect,
        sink: &mut S,
    ) -> Result<(), DrawError<S::Error>> {
        let region = self.output_region();
        let inside = area.intersect(&region);
        let local = Rect {
            x: inside.x.saturating_sub(region.x),
            y: inside.y.saturating_sub(region.y),
            ..inside
        };
        let mut placed = Placed {
            sink,
            dx: region.x,
            dy: region.y,
        };
        Decoder::packet(self.stream, self.payload)
            .scale(self.scale)
            .clip(local)
            .decode(&mut placed)?;
        Ok(())
    }
}

impl Packet<'_> {
    /// Draws the packet's pixels that lie outside every rectangle of `drawn` (image
    /// coordinates at the packet's scale: the regions' [`Packet::output_region`]): how a
    /// preview that arrives after some regions fills only the rest, whatever the order the
    /// packets came in. Tiles reach `sink` cut into runs of a row.
    pub fn decode_around<S: PixelSink + ?Sized>(
        &self,
        drawn: &[Rect],
        sink: &mut S,
    ) -> Result<(), DrawError<S::Error>> {
        let mut around = Around { drawn, sink };
        self.decode(&mut around)
    }
}

/// A sink that passes on only the pixels outside `drawn`, row run by row run.
struct Around<'r, 's, S: ?Sized> {
    drawn: &'r [Rect],
    sink: &'s mut S,
}

impl<S: PixelSink + ?Sized> PixelSink for Around<'_, '_, S> {
    type Error = S::Error;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), S::Error> {
        let area = tile.area;
        let ch = usize::from(tile.channels.max(1));
        let row_len = area.w as usize * ch;
        if row_len == 0 {
            return Ok(());
        }
        // Row by row without `chunks_exact`, whose set-up divides (a routine call on a
        // Cortex-M0).
        let mut rest = tile.pixels;
        let mut y = area.y;
        while let Some((row, tail)) = rest.split_at_checked(row_len) {
            rest = tail;
            let mut x = area.x;
            let end = area.x + area.w;
            while x < end {
                // Skip drawn pixels, then pass the run up to the next drawn one.
                if let Some(skip) = self.drawn.iter().find(|d| d.contains_point(x, y)) {
                    x = skip.right().min(u64::from(end)) as u32;
                    continue;
                }
                let stop = self
                    .drawn
                    .iter()
                    .filter(|d| d.y <= y && u64::from(y) < d.bottom() && d.x > x)
                    .map(|d| d.x)
                    .min()
                    .unwrap_or(end)
                    .min(end);
                let from = (x - area.x) as usize * ch;
                let to = (stop - area.x) as usize * ch;
                let run = Rect {
                    x,
                    y,
                    w: stop - x,
                    h: 1,
                };
                let Some(pixels) = row.get(from..to) else {
                    return Ok(());
                };
                self.sink.tile(Tile {
                    area: run,
                    pixels,
                    ..tile
                })?;
                x = stop;
            }
            y += 1;
        }
        Ok(())
    }
}

/// The region that the fields `[x, y, w, h]` (in [`REGION_UNIT`]s) give in an image of
/// `width` by `height`: it must start inside the image and end in its last unit.
fn region_of(units: [u32; 4], width: u16, height: u16) -> Result<Rect, DecodeError> {
    let [x, y, w, h] = units.map(|u| u * REGION_UNIT);
    let (width, height) = (u32::from(width), u32::from(height));
    let fits = |start: u32, size: u32, side: u32| {
        size > 0 && start < side && start + size < side + REGION_UNIT
    };
    if !fits(x, w, width) || !fits(y, h, height) {
        return Err(DecodeError::InvalidHeader(HeaderField::Region));
    }
    Ok(Rect {
        x,
        y,
        w: w.min(width - x),
        h: h.min(height - y),
    })
}

/// Reads a packet header's fields.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn byte(&mut self) -> Result<u8, DecodeError> {
        let b = *self.data.get(self.pos).ok_or(DecodeError::Truncated)?;
        self.pos += 1;
        Ok(b)
    }

    /// A field: an unsigned LEB128 value of at most 16 bits ([`read_field`]).
    fn varint(&mut self) -> Result<u16, DecodeError> {
        read_field(self.data, &mut self.pos)
    }
}

/// A packet header's field at `*pos` (advanced past it): an unsigned LEB128 value of at most
/// 16 bits in at most three bytes, without a redundant final zero group.
pub fn read_field(data: &[u8], pos: &mut usize) -> Result<u16, DecodeError> {
    match read_leb128(data, pos, MAX_VARINT_BYTES) {
        Ok(v) => u16::try_from(v).map_err(|_| DecodeError::InvalidHeader(HeaderField::PacketField)),
        Err(Leb128Error::Truncated) => Err(DecodeError::Truncated),
        Err(Leb128Error::Malformed) => Err(DecodeError::InvalidHeader(HeaderField::PacketField)),
    }
}

/// A sink that moves every tile by the region's origin.
struct Placed<'s, S: ?Sized> {
    sink: &'s mut S,
    dx: u32,
    dy: u32,
}

impl<S: PixelSink + ?Sized> PixelSink for Placed<'_, S> {
    type Error = S::Error;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), S::Error> {
        let area = Rect {
            x: tile.area.x + self.dx,
            y: tile.area.y + self.dy,
            ..tile.area
        };
        self.sink.tile(Tile { area, ..tile })
    }
}

/// Writes a packet header's field (`value` as unsigned LEB128) into `out` at `pos`; returns
/// the position after it.
pub fn write_field(out: &mut [u8], pos: usize, value: u16) -> usize {
    write_leb128(out, pos, u32::from(value))
}

/// The fields of a packet header, for writers of packets ([`PacketHeader::write_packet`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PacketHeader {
    /// See [`Packet::image_id`].
    pub image_id: u16,
    /// See [`Packet::index`].
    pub index: u16,
    /// See [`Packet::count`].
    pub count: u16,
    /// Width of the whole image.
    pub width: u16,
    /// Height of the whole image.
    pub height: u16,
    /// 1 or 3.
    pub channels: u8,
    /// `None` for a preview; else the region, in [`REGION_UNIT`]s: `[x, y, w, h]`.
    pub region_units: Option<[u16; 4]>,
    /// The region stream's leaf sizes (`max << 4 | min`) and stripe.
    pub coding: [u8; 2],
    /// The region stream's edge-smoothing strength.
    pub deblock: u8,
}

/// The longest packet header: the tag, the image id, the flags, eight three-byte varints and
/// the coding fields.
pub const MAX_PACKET_HEADER_LEN: usize = 4 + 8 * MAX_VARINT_BYTES + CODING_BYTES;

impl PacketHeader {
    /// Writes the header into `out` (at least [`MAX_PACKET_HEADER_LEN`] bytes); returns its
    /// length.
    pub fn write(&self, out: &mut [u8]) -> usize {
        let id = self.image_id.to_le_bytes();
        let mut flags = self.deblock << DEBLOCK_SHIFT;
        if self.channels == 3 {
            flags |= FLAG_COLOUR;
        }
        if self.region_units.is_none() {
            flags |= FLAG_PREVIEW;
        }
        let custom = self.coding != DEFAULT_CODING;
        if custom {
            flags |= FLAG_CODING;
        }
        out[..4].copy_from_slice(&[PACKET_TAG, id[0], id[1], flags]);
        let mut pos = write_field(out, 4, self.index);
        pos = write_field(out, pos, self.count);
        pos = write_side(out, pos, self.width);
        pos = write_side(out, pos, self.height);
        for v in self.region_units.into_iter().flatten() {
            pos = write_field(out, pos, v);
        }
        if custom {
            out[pos..pos + 2].copy_from_slice(&self.coding);
            pos += 2;
        }
        pos
    }
}

impl PacketHeader {
    /// Writes the whole packet into `out`: this header, `payload`, the CRC-16; returns its
    /// length, or `None` when `out` is too short (it needs [`MAX_PACKET_HEADER_LEN`] + the
    /// payload + [`CRC_LEN`] bytes at most).
    pub fn write_packet(&self, payload: &[u8], out: &mut [u8]) -> Option<usize> {
        let mut head = [0u8; MAX_PACKET_HEADER_LEN];
        let len = self.write(&mut head);
        let end = len + payload.len();
        out.get_mut(..len)?.copy_from_slice(&head[..len]);
        out.get_mut(len..end)?.copy_from_slice(payload);
        let crc = packet_crc(&out[..end]);
        out.get_mut(end..end + CRC_LEN)?.copy_from_slice(&crc);
        Some(end + CRC_LEN)
    }
}

/// The CRC-16 that completes `packet` (its header and payload), to append to it.
pub fn packet_crc(packet: &[u8]) -> [u8; CRC_LEN] {
    crc16(packet).to_le_bytes()
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use core::convert::Infallible;
    use std::vec;
    use std::vec::Vec;

    /// A frame buffer of `width` pixels a row.
    struct Frame {
        width: usize,
        channels: usize,
        pixels: Vec<u8>,
    }

    impl PixelSink for Frame {
        type Error = Infallible;

        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
            let row = tile.area.w as usize * self.channels;
            for (r, src) in tile.pixels.chunks_exact(row.max(1)).enumerate() {
                let at = ((tile.area.y as usize + r) * self.width + tile.area.x as usize)
                    * self.channels;
                self.pixels[at..at + row].copy_from_slice(src);
            }
            Ok(())
        }
    }

    const GOLDEN: &[u8] = include_bytes!("../../tests/golden/textured_33x17.pifs");

    /// The golden stream's decode, and a preview packet made of its payload.
    fn preview() -> (Vec<u8>, Vec<u8>) {
        let (stream, offset) = Header::parse(GOLDEN).unwrap();
        let mut pixels = vec![0u8; stream.pixel_count()];
        Decoder::new(GOLDEN)
            .unwrap()
            .decode_into(&mut pixels)
            .unwrap();
        let header = PacketHeader {
            image_id: 0xBEEF,
            index: 0,
            count: 3,
            width: stream.width,
            height: stream.height,
            channels: 1,
            region_units: None,
            coding: [
                stream.max_leaf_log2 << 4 | stream.min_leaf_log2,
                stream.stripe,
            ],
            deblock: stream.deblock,
        };
        (pixels, seal(&header, &GOLDEN[offset..]))
    }

    fn seal(header: &PacketHeader, payload: &[u8]) -> Vec<u8> {
        let mut packet = vec![0u8; MAX_PACKET_HEADER_LEN + payload.len() + CRC_LEN];
        let len = header.write_packet(payload, &mut packet).unwrap();
        packet.truncate(len);
        packet
    }

    fn frame_of(p: &Packet<'_>) -> Frame {
        Frame {
            width: usize::from(p.width),
            channels: usize::from(p.channels),
            pixels: vec![7; usize::from(p.width) * usize::from(p.height)],
        }
    }

    #[test]
    fn a_packet_carries_a_stream_and_decodes_like_it() {
        let (pixels, packet) = preview();
        let p = Packet::parse(&packet).unwrap();
        assert_eq!(
            (p.image_id, p.index, p.count, p.kind, p.width, p.height),
            (0xBEEF, 0, 3, PacketKind::Preview, 33, 17)
        );
        assert_eq!(p.region, Rect::of_size(33, 17));
        let mut frame = frame_of(&p);
        p.decode(&mut frame).unwrap();
        assert_eq!(frame.pixels, pixels);
        // The preview drawn around two rectangles leaves them alone.
        let drawn = [
            Rect {
                x: 3,
                y: 2,
                w: 10,
                h: 5,
            },
            Rect {
                x: 20,
                y: 0,
                w: 50,
                h: 50,
            },
        ];
        let mut frame = frame_of(&p);
        p.decode_around(&drawn, &mut frame).unwrap();
        for y in 0..17 {
            for x in 0..33 {
                let inside = drawn.iter().any(|d| d.contains_point(x, y));
                let at = y as usize * 33 + x as usize;
                let want = if inside { 7 } else { pixels[at] };
                assert_eq!(frame.pixels[at], want, "({x}, {y})");
            }
        }
    }

    #[test]
    fn every_damaged_byte_is_refused_and_no_cut_panics() {
        let (_, packet) = preview();
        for i in 0..packet.len() {
            let mut bad = packet.clone();
            bad[i] ^= 0x10;
            let e = Packet::parse(&bad).unwrap_err();
            // Byte 0 is the tag: damaged, it names another kind or version.
            let want_checksum = i >= 1;
            if i == 0 {
                assert_eq!(e, DecodeError::BadMagic, "tag damaged");
            }
            assert_eq!(
                matches!(e, DecodeError::ChecksumMismatch { .. }),
                want_checksum,
                "byte {i}: {e:?}"
            );
        }
        for n in 0..packet.len() {
            assert!(Packet::parse(&packet[..n]).is_err(), "cut at {n}");
        }
    }

    #[test]
    fn fields_out_of_range_are_typed_errors() {
        let (_, good) = preview();
        let p = Packet::parse(&good).unwrap();
        let payload = p.payload;
        let base = PacketHeader {
            image_id: 1,
            index: 0,
            count: 2,
            width: 33,
            height: 17,
            channels: 1,
            region_units: Some([0, 0, 5, 3]),
            coding: [0x41, 4],
            deblock: 0,
        };
        let field = |h: PacketHeader| Packet::parse(&seal(&h, payload)).map(|p| p.region);
        assert_eq!(field(base), Ok(Rect::of_size(33, 17)));
        let bad_region = [
            [5, 0, 1, 1],
            [0, 3, 1, 1],
            [0, 0, 0, 1],
            [0, 0, 6, 1],
            [4, 2, 2, 1],
        ];
        for units in bad_region {
            let h = PacketHeader {
                region_units: Some(units),
                ..base
            };
            assert_eq!(
                field(h),
                Err(DecodeError::InvalidHeader(HeaderField::Region)),
                "{units:?}"
            );
        }
        let h = PacketHeader { index: 2, ..base };
        assert_eq!(
            field(h),
            Err(DecodeError::InvalidHeader(HeaderField::PacketField))
        );
        // A width less one of 65535 (the tag, the image id, the flags, the index and the count
        // come first).
        let reseal = |splice: &[u8], at: core::ops::Range<usize>| {
            let mut packet = seal(&base, payload);
            packet.truncate(packet.len() - CRC_LEN);
            packet.splice(at, splice.iter().copied());
            let crc = packet_crc(&packet);
            packet.extend_from_slice(&crc);
            Packet::parse(&packet).map(|p| p.index)
        };
        assert_eq!(
            reseal(&[0xFF, 0xFF, 0x03], 6..7),
            Err(DecodeError::InvalidHeader(HeaderField::Dimensions))
        );
        let h = PacketHeader {
            coding: [0x18, 4],
            ..base
        };
        assert_eq!(
            field(h),
            Err(DecodeError::InvalidHeader(HeaderField::LeafSizes))
        );
        let h = PacketHeader {
            deblock: 17,
            ..base
        };
        assert_eq!(
            field(h),
            Err(DecodeError::InvalidHeader(HeaderField::Deblock))
        );
        // A redundant final zero group in a varint (the index).
        assert_eq!(
            reseal(&[0x80, 0x00], 4..5),
            Err(DecodeError::InvalidHeader(HeaderField::PacketField))
        );
        // The coding fields written though they are the defaults: one packet, one encoding.
        let defaults = PacketHeader {
            coding: DEFAULT_CODING,
            ..base
        };
        let mut head = [0u8; MAX_PACKET_HEADER_LEN];
        let len = defaults.write(&mut head);
        let mut explicit = head[..len].to_vec();
        explicit[3] |= FLAG_CODING;
        explicit.extend_from_slice(&DEFAULT_CODING);
        explicit.extend_from_slice(payload);
        let crc = packet_crc(&explicit);
        explicit.extend_from_slice(&crc);
        assert_eq!(
            Packet::parse(&explicit).err(),
            Some(DecodeError::InvalidHeader(HeaderField::CodingFields))
        );
        // Another kind's tag, a later version's, an earlier tagged one's, one before tags.
        let mut other = seal(&base, payload);
        other[0] = crate::format::STREAM_TAG;
        assert_eq!(Packet::parse(&other).err(), Some(DecodeError::BadMagic));
        other[0] = PACKET_TAG + 1;
        assert_eq!(
            Packet::parse(&other).err(),
            Some(DecodeError::UnsupportedVersion(crate::format::VERSION + 1))
        );
        other[0] = PACKET_TAG - 1;
        assert_eq!(
            Packet::parse(&other).err(),
            Some(DecodeError::UnsupportedVersion(crate::format::VERSION - 1))
        );
        other[0] = 0xC0 | (crate::format::FIRST_TAGGED_VERSION - 1);
        assert_eq!(Packet::parse(&other).err(), Some(DecodeError::BadMagic));
    }
}
