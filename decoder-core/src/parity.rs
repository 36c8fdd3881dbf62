//! Rebuilding lost packets from parity packets (`docs/bitstream.md`, section 9), without
//! allocating: for a receiver that can hold an image's packets (a gateway, or a device with
//! the RAM for them), not for one drawing packets as they come in 4 KiB.
//!
//! The code is the systematic Reed–Solomon erasure code of section 9: its shards are, byte by
//! byte, the values at the points `0 .. N + K` of the polynomial of degree below `N` that takes
//! the data shards' bytes at the points `0 .. N` (over GF(2^8)). So any `N` shards held give
//! every other one by Lagrange interpolation, with no matrix of the code and no system to
//! solve. Where a parity packet's bytes are parsed: [`ParityPacket::parse`]; where a lost
//! packet is made again: [`Rebuild::rebuild`] and [`Rebuild::packet`].

use crate::checksum::crc16;
use crate::error::{DecodeError, HeaderField};
use crate::format::{mod255, PACKET_TAG, PARITY_TAG};
use crate::packet::{packet_crc, read_field, Packet, CRC_LEN};
use crate::syntax::check_first_byte;
use core::fmt;

/// The most shards, data and parity, one code covers: the field's elements.
pub const MAX_SHARDS: usize = 256;
/// The bytes before a packet's fields: the tag and the image id.
const HEAD: usize = 3;
/// The byte that ends a shard's content, before its zeros.
const CONTENT_END: u8 = 0x80;

/// One parity packet, parsed and checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParityPacket<'a> {
    /// The image's number.
    pub image_id: u16,
    /// This parity packet's number `k`: the code's point `count + k`.
    pub index: u16,
    /// How many data packets the code protects (the data packets' `count`).
    pub count: u16,
    /// The shard.
    pub shard: &'a [u8],
}

impl<'a> ParityPacket<'a> {
    /// Parses and checks a parity packet: its tag, its CRC-16, its fields.
    pub fn parse(data: &'a [u8]) -> Result<Self, DecodeError> {
        check_first_byte(data, PARITY_TAG)?;
        if data.len() < HEAD + 2 + 1 + CRC_LEN {
            return Err(DecodeError::Truncated);
        }
        let (body, crc) = data
            .split_at_checked(data.len().saturating_sub(CRC_LEN))
            .ok_or(DecodeError::Truncated)?;
        let (&[c0, c1], &[_, id0, id1, ..]) = (crc, body) else {
            return Err(DecodeError::Truncated);
        };
        let stored = u32::from(u16::from_le_bytes([c0, c1]));
        let computed = u32::from(crc16(body));
        if computed != stored {
            return Err(DecodeError::ChecksumMismatch { stored, computed });
        }
        let image_id = u16::from_le_bytes([id0, id1]);
        let mut pos = HEAD;
        let index = read_field(body, &mut pos)?;
        let count = read_field(body, &mut pos)?;
        let shard = body.get(pos..).unwrap_or_default();
        if count == 0 || usize::from(count) + usize::from(index) >= MAX_SHARDS || shard.is_empty() {
            return Err(DecodeError::InvalidHeader(HeaderField::PacketField));
        }
        Ok(ParityPacket {
            image_id,
            index,
            count,
            shard,
        })
    }
}

/// Why a packet could not be added or rebuilt ([`Rebuild`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RebuildError {
    /// The packet belongs to another image, or to another code (its count, its shard's
    /// length).
    OtherImage,
    /// The packet's bytes do not read as a packet.
    Decode(DecodeError),
    /// The buffer has no slot for this parity packet (slots for `count + index + 1` shards
    /// are needed).
    NoSlot,
    /// Fewer parity packets than lost data packets arrived.
    NotEnough {
        /// Data packets missing.
        missing: usize,
        /// Parity packets held.
        parity: usize,
    },
    /// A rebuilt shard has no end byte: the packets held were not all of one code.
    Inconsistent,
    /// That data packet is neither held nor rebuilt.
    NotHeld,
    /// The output buffer is too small for the packet.
    OutputTooSmall,
}

impl fmt::Display for RebuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RebuildError::OtherImage => write!(f, "a packet of another image or code"),
            RebuildError::Decode(e) => write!(f, "{e}"),
            RebuildError::NoSlot => write!(f, "no room for that parity packet"),
            RebuildError::NotEnough { missing, parity } => write!(
                f,
                "{missing} data packets missing and {parity} parity packets held"
            ),
            RebuildError::Inconsistent => write!(f, "the packets held are not of one code"),
            RebuildError::NotHeld => write!(f, "that packet is neither held nor rebuilt"),
            RebuildError::OutputTooSmall => write!(f, "the output buffer is too small"),
        }
    }
}

impl core::error::Error for RebuildError {}

impl From<DecodeError> for RebuildError {
    fn from(e: DecodeError) -> Self {
        RebuildError::Decode(e)
    }
}

/// An image's packets gathered to rebuild the lost ones, in a buffer the caller lends: one
/// slot per shard, the data packets' first (by index), then the parity packets'
/// ([`Rebuild::buffer_len`]). Packets are added as they arrive, data or parity, in any order:
/// the first one added says which image and code the rebuild is for.
///
/// ```no_run
/// use decoder_core::{Packet, ParityPacket, Rebuild};
/// # struct NullSink;
/// # impl decoder_core::PixelSink for NullSink {
/// #     type Error = core::convert::Infallible;
/// #     fn tile(&mut self, _: decoder_core::Tile<'_>) -> Result<(), Self::Error> { Ok(()) }
/// # }
/// # fn next_packet() -> Option<&'static [u8]> { None }
/// # let mut sink = NullSink;
/// const LINK_PACKET: usize = 255;
/// // Room for 40 data packets and 8 parity packets of the link's largest size.
/// let mut buf = [0u8; Rebuild::buffer_len(40, 8, LINK_PACKET)];
/// let mut rebuild = Rebuild::new(LINK_PACKET, &mut buf);
/// while let Some(bytes) = next_packet() {
///     // A packet that fails its checks, or is another image's, counts as lost.
///     let _ = match ParityPacket::parse(bytes) {
///         Ok(parity) => rebuild.add_parity(&parity),
///         Err(_) => rebuild.add_packet(bytes),
///     };
/// }
/// if rebuild.packets_short() > 0 {
///     // Too few to rebuild: that many more of any of the image's packets would do.
///     return Ok(());
/// }
/// rebuild.rebuild()?;
/// let mut packet = [0u8; LINK_PACKET];
/// let mut index = 0;
/// while rebuild.has(index) {
///     let len = rebuild.packet(index, &mut packet)?;
///     if let Ok(p) = Packet::parse(&packet[..len]) {
///         let _ = p.decode(&mut sink);
///     }
///     index += 1;
/// }
/// # Ok::<(), decoder_core::RebuildError>(())
/// ```
#[derive(Debug)]
pub struct Rebuild<'b> {
    buf: &'b mut [u8],
    /// The bytes of a slot: at least the code's shard length (shorter shards end in zeros,
    /// which the code keeps: a shard's bytes past its length are zero in every shard).
    slot_len: usize,
    /// The image and code of the first packet added.
    code: Option<Code>,
    /// The code's shard length, once a parity packet has said it.
    shard_len: Option<usize>,
    /// Which slots hold a shard (a slot's number is its point of the code).
    held: Points,
}

/// Which image and code a rebuild's packets belong to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Code {
    image_id: u16,
    /// The data packets' count (below 256: `count + index < 256`).
    count: u8,
}

impl<'b> Rebuild<'b> {
    /// A rebuild with slots of `slot_len` bytes in `buf`. Any slot length from the code's shard
    /// length up works; a receiver that knows only its link's largest packet gives that (a
    /// shard is shorter than any packet of its code).
    pub fn new(slot_len: usize, buf: &'b mut [u8]) -> Self {
        Rebuild {
            buf,
            slot_len,
            code: None,
            shard_len: None,
            held: Points::default(),
        }
    }

    /// The bytes of buffer a rebuild needs for `count` data packets, `parity` parity packets
    /// and slots of `slot_len` bytes.
    pub const fn buffer_len(count: usize, parity: usize, slot_len: usize) -> usize {
        (count + parity) * slot_len
    }

    /// Adds a parity packet of the image and code (the first packet added sets them).
    /// [`RebuildError::NoSlot`] when the buffer has no slot for it or its shard is longer
    /// than a slot.
    pub fn add_parity(&mut self, parity: &ParityPacket<'_>) -> Result<(), RebuildError> {
        let code = self.code_of(parity.image_id, parity.count)?;
        let len = parity.shard.len();
        if self.shard_len.is_some_and(|known| known != len) {
            return Err(RebuildError::OtherImage);
        }
        if len > self.slot_len {
            return Err(RebuildError::NoSlot);
        }
        // Data shards held so far must end within this code's shard length.
        let longer = (0..code.count).filter(|&i| self.held.contains(i)).any(|i| {
            self.slot(i)
                .and_then(|s| s.get(len..))
                .is_some_and(|tail| tail.iter().any(|&b| b != 0))
        });
        if longer {
            return Err(RebuildError::OtherImage);
        }
        let point = usize::from(code.count) + usize::from(parity.index);
        let point = u8::try_from(point).map_err(|_| RebuildError::OtherImage)?;
        let slot = self.slot_mut(point)?;
        slot.fill(0);
        copy(slot, parity.shard);
        self.code = Some(code);
        self.shard_len = Some(len);
        self.held.insert(point);
        Ok(())
    }

    /// Adds a data packet of the image (its bytes as received; checked as [`Packet::parse`]
    /// checks them; the first packet added sets the image and code).
    pub fn add_packet(&mut self, data: &[u8]) -> Result<(), RebuildError> {
        let packet = Packet::parse(data)?;
        let code = self.code_of(packet.image_id, packet.count)?;
        let len = self.shard_len.unwrap_or(self.slot_len);
        // Below the count, so below 256.
        let point = packet.index as u8;
        let slot = self.slot_mut(point)?;
        let (shard, rest) = slot.split_at_mut(len.min(slot.len()));
        shard_of(data, shard).map_err(|_| RebuildError::OtherImage)?;
        rest.fill(0);
        self.code = Some(code);
        self.held.insert(point);
        Ok(())
    }

    /// The code of a packet of image `image_id` sent as `count` data packets, if it is the
    /// rebuild's (or the rebuild has none yet).
    fn code_of(&self, image_id: u16, count: u16) -> Result<Code, RebuildError> {
        let count = u8::try_from(count).map_err(|_| RebuildError::NoSlot)?;
        let code = Code { image_id, count };
        match self.code {
            Some(known) if known != code => Err(RebuildError::OtherImage),
            _ => Ok(code),
        }
    }

    /// The data packets' count (0 before any packet is added).
    fn count(&self) -> u8 {
        self.code.map_or(0, |c| c.count)
    }

    /// Whether data packet `index` is held (received, or rebuilt).
    pub fn has(&self, index: u16) -> bool {
        index < u16::from(self.count()) && self.held.contains(index as u8)
    }

    /// How many data packets are missing (0 before any packet is added).
    pub fn missing(&self) -> usize {
        (0..self.count())
            .filter(|&i| !self.held.contains(i))
            .count()
    }

    /// How many parity packets are held.
    pub fn parity_held(&self) -> usize {
        let count = self.count();
        self.held.iter().filter(|&p| p >= count).count()
    }

    /// How many more packets, any data or parity packets of the image not held, would let
    /// [`Rebuild::rebuild`] make every missing one (0 when it can).
    pub fn packets_short(&self) -> usize {
        self.missing().saturating_sub(self.parity_held())
    }

    /// Makes every missing data packet again from the packets held (any `count` of the
    /// `count + parity` shards): each lost shard is the code's polynomial at its point,
    /// interpolated (Lagrange) from `count` points whose shards are held. It needs a few
    /// hundred bytes of stack, whatever is lost.
    pub fn rebuild(&mut self) -> Result<(), RebuildError> {
        let missing = self.missing();
        if missing == 0 {
            return Ok(());
        }
        let count = self.count();
        // The points whose shards are known: the data held and the first `missing` parity
        // shards held, listed (`known[..n]`).
        let mut known = [0u8; MAX_SHARDS];
        let (mut n, mut used, mut held) = (0, 0, 0);
        for point in self.held.iter() {
            let take = point < count || used < missing;
            if point >= count {
                held += 1;
                used += usize::from(take);
            }
            if let (true, Some(slot)) = (take, known.get_mut(n)) {
                *slot = point;
                n += 1;
            }
        }
        if used < missing {
            return Err(RebuildError::NotEnough {
                missing,
                parity: held,
            });
        }
        let known = known.get(..n).unwrap_or_default();
        // The logarithm of each known point's denominator, `prod (q - q')` over the others.
        let mut denominator = [0u8; MAX_SHARDS];
        for (d, &q) in denominator.iter_mut().zip(known) {
            let sum: usize = known
                .iter()
                .filter(|&&other| other != q)
                .map(|&other| usize::from(LOG[usize::from(q ^ other)]))
                .sum();
            *d = mod255(sum) as u8;
        }
        for m in 0..count {
            if self.held.contains(m) {
                continue;
            }
            // The Lagrange basis of `q` at `m`: `prod (m - q') / (q - q')` over `q' != q`.
            let numerator: usize = known
                .iter()
                .map(|&q| usize::from(LOG[usize::from(m ^ q)]))
                .sum();
            self.slot_mut(m)?.fill(0);
            for (&q, &d) in known.iter().zip(&denominator) {
                let log = mod255(numerator) + 2 * 255
                    - usize::from(LOG[usize::from(m ^ q)])
                    - usize::from(d);
                self.add_scaled(m, q, mod255(log) as u8);
            }
        }
        for m in 0..count {
            self.held.insert(m);
        }
        Ok(())
    }

    /// Writes data packet `index` (held or rebuilt) to `out`; returns its length. The bytes
    /// are the packet as sent: tag, image id, flags, index and count put back around the
    /// shard's content, and the checksum.
    pub fn packet(&self, index: u16, out: &mut [u8]) -> Result<usize, RebuildError> {
        if !self.has(index) {
            return Err(RebuildError::NotHeld);
        }
        let shard = self.slot(index as u8).ok_or(RebuildError::NotHeld)?;
        let end = shard.iter().rposition(|&b| b != 0).unwrap_or(0);
        let (Some((&flags, rest)), Some(&CONTENT_END)) = (
            shard.get(..end).and_then(<[u8]>::split_first),
            shard.get(end),
        ) else {
            return Err(RebuildError::Inconsistent);
        };
        let (index_field, index_len) = leb128(index);
        let code = self.code.ok_or(RebuildError::NotHeld)?;
        let (count_field, count_len) = leb128(code.count.into());
        let id = code.image_id.to_le_bytes();
        let head = [PACKET_TAG, id[0], id[1], flags];
        let parts = [
            &head[..],
            index_field.get(..index_len).unwrap_or_default(),
            count_field.get(..count_len).unwrap_or_default(),
            rest,
        ];
        let body_len: usize = parts.iter().map(|p| p.len()).sum();
        let out = out
            .get_mut(..body_len + CRC_LEN)
            .ok_or(RebuildError::OutputTooSmall)?;
        let mut at = 0;
        for part in parts {
            copy(out.get_mut(at..).unwrap_or_default(), part);
            at += part.len();
        }
        let (body, crc) = out.split_at_mut(body_len.min(out.len()));
        copy(crc, &packet_crc(body));
        Ok(body_len + CRC_LEN)
    }

    fn slot(&self, point: u8) -> Option<&[u8]> {
        let start = usize::from(point) * self.slot_len;
        self.buf.get(start..start + self.slot_len)
    }

    fn slot_mut(&mut self, point: u8) -> Result<&mut [u8], RebuildError> {
        let start = usize::from(point) * self.slot_len;
        self.buf
            .get_mut(start..start + self.slot_len)
            .ok_or(RebuildError::NoSlot)
    }

    /// Slot `to` plus `2^log` times slot `from` (two different slots).
    /// Only the code's shard length is added: past it every slot is zero.
    fn add_scaled(&mut self, to: u8, from: u8, log: u8) {
        let stride = self.slot_len;
        let len = self.shard_len.unwrap_or(stride);
        let (to, from) = (usize::from(to) * stride, usize::from(from) * stride);
        let (low, high) = (to.min(from), to.max(from));
        let (first, second) = self.buf.split_at_mut(high.min(self.buf.len()));
        let (Some(low_slot), Some(high_slot)) =
            (first.get_mut(low..low + len), second.get_mut(..len))
        else {
            return;
        };
        let (dst, src) = if to < from {
            (low_slot, &*high_slot)
        } else {
            (high_slot, &*low_slot)
        };
        for (d, &v) in dst.iter_mut().zip(src) {
            if v != 0 {
                *d ^= EXP[(usize::from(LOG[usize::from(v)]) + usize::from(log)) & 511];
            }
        }
    }
}

/// A set of the code's points (`0..256`).
#[derive(Debug, Default)]
struct Points([u32; MAX_SHARDS / 32]);

impl Points {
    fn insert(&mut self, point: u8) {
        self.0[usize::from(point >> 5)] |= 1 << (point & 31);
    }

    fn contains(&self, point: u8) -> bool {
        self.0[usize::from(point >> 5)] >> (point & 31) & 1 != 0
    }

    fn iter(&self) -> impl Iterator<Item = u8> + '_ {
        (0..=u8::MAX).filter(|&p| self.contains(p))
    }
}

/// Copies `src` to the start of `dst`, as much as fits.
fn copy(dst: &mut [u8], src: &[u8]) {
    for (d, s) in dst.iter_mut().zip(src) {
        *d = *s;
    }
}

/// `value` as unsigned LEB128: its bytes and how many.
fn leb128(value: u16) -> ([u8; 3], usize) {
    let mut out = [0u8; 3];
    let mut rest = value;
    let mut len = 0;
    for byte in out.iter_mut() {
        *byte = (rest & 0x7F) as u8;
        rest >>= 7;
        len += 1;
        if rest == 0 {
            break;
        }
        *byte |= 0x80;
    }
    (out, len)
}

/// A data packet's content: its flags byte and its bytes from the width field up to the
/// checksum (section 9).
struct Content<'a> {
    flags: u8,
    rest: &'a [u8],
}

impl<'a> Content<'a> {
    fn of(data: &'a [u8]) -> Result<Self, DecodeError> {
        let body = data
            .get(..data.len().saturating_sub(CRC_LEN))
            .ok_or(DecodeError::Truncated)?;
        let flags = *body.get(HEAD).ok_or(DecodeError::Truncated)?;
        let mut pos = HEAD + 1;
        read_field(body, &mut pos)?;
        read_field(body, &mut pos)?;
        Ok(Content {
            flags,
            rest: body.get(pos..).unwrap_or_default(),
        })
    }

    fn len(&self) -> usize {
        1 + self.rest.len()
    }
}

/// The shard of data packet `packet`, written to `out` (the shard's length): its content,
/// the end byte, zeros. For encoders that make parity packets, and for [`Rebuild`].
pub fn shard_of(packet: &[u8], out: &mut [u8]) -> Result<(), RebuildError> {
    let content = Content::of(packet)?;
    let len = content.len();
    if len >= out.len() {
        return Err(RebuildError::OutputTooSmall);
    }
    out.fill(0);
    copy(out, &[content.flags]);
    copy(out.get_mut(1..).unwrap_or_default(), content.rest);
    copy(out.get_mut(len..).unwrap_or_default(), &[CONTENT_END]);
    Ok(())
}

/// GF(2^8) with the field polynomial `x^8 + x^4 + x^3 + x^2 + 1`: powers of its generator 2,
/// twice over (so that a sum of two logarithms needs no reduction), and two unused entries.
const EXP: [u8; 512] = {
    let mut table = [0u8; 512];
    let mut value: u16 = 1;
    let mut power = 0;
    while power < 255 {
        table[power] = value as u8;
        table[power + 255] = value as u8;
        value <<= 1;
        if value & 0x100 != 0 {
            value ^= 0x11D;
        }
        power += 1;
    }
    table
};

/// The logarithms to base 2 of the field's elements (0's is unused).
const LOG: [u8; 256] = {
    let mut table = [0u8; 256];
    let mut power = 0;
    while power < 255 {
        table[EXP[power] as usize] = power as u8;
        power += 1;
    }
    table
};

#[cfg(test)]
fn mul(a: u8, b: u8) -> u8 {
    if a == 0 || b == 0 {
        0
    } else {
        EXP[(usize::from(LOG[usize::from(a)]) + usize::from(LOG[usize::from(b)])) & 511]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_field_is_the_specifications() {
        // x^8 = x^4 + x^3 + x^2 + 1: 2^8 is 0x1D; every element but 0 is a power of 2.
        assert_eq!(EXP[8], 0x1D);
        let mut seen = [false; 256];
        for &v in &EXP[..255] {
            seen[usize::from(v)] = true;
        }
        assert!(seen[1..].iter().all(|&s| s) && !seen[0]);
        assert_eq!(mul(0, 7), 0);
        assert_eq!(mul(2, 0x80), 0x1D);
    }
}
