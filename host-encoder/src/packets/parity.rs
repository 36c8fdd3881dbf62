//! Parity packets (`docs/bitstream.md`, section 9): `K` packets computed over an image's `N`
//! packets by a Reed–Solomon erasure code over GF(2^8), so that any `N` of the `N + K`
//! rebuild every one. A receiver needs them all in memory to rebuild: this is for gateways and
//! hosts, not for a microcontroller drawing packets as they come.

use decoder_core::internal::packet::{packet_crc, read_field, write_field, CRC_LEN};
pub use decoder_core::internal::syntax::PARITY_TAG;
use decoder_core::PACKET_TAG;
use reed_solomon_erasure::galois_8::ReedSolomon;

/// The most packets, data and parity, one code covers (the field's size).
pub const MAX_SHARDS: usize = 256;

/// The bytes of a packet (data or parity) before its fields: the tag and the image id.
const HEAD: usize = 3;

/// The byte that ends a shard's content, before its zeros (ISO/IEC 7816-4 padding).
const CONTENT_END: u8 = 0x80;

/// Bytes of an unsigned LEB128 field holding `v`.
fn field_len(v: usize) -> usize {
    match v {
        0..128 => 1,
        128..16384 => 2,
        _ => 3,
    }
}

/// The largest data packet that `parity` parity packets leave room for in packets of at most
/// `size` bytes. A shard leaves out what a parity packet carries anyway or the shard's place
/// gives (tag, image id, index, count, checksum) and adds an end byte, so a parity packet is
/// at most the longest data packet plus its own index field: `size` less the largest one.
pub fn data_packet_size(size: usize, parity: usize) -> usize {
    size.saturating_sub(field_len(parity.saturating_sub(1)))
}

/// One parity packet, parsed and checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Parity<'a> {
    /// The image's number.
    pub image_id: u16,
    /// This parity packet's number: row `count + index` of the code.
    pub index: u16,
    /// How many data packets the code protects (the data packets' `count`).
    pub count: u16,
    /// The shard.
    pub shard: &'a [u8],
}

impl<'a> Parity<'a> {
    /// Parses a parity packet, its CRC-16 first; `None` for anything else.
    pub fn parse(data: &'a [u8]) -> Option<Self> {
        if data.len() < HEAD + 3 + CRC_LEN || data[0] != PARITY_TAG {
            return None;
        }
        let (body, crc) = data.split_at(data.len() - CRC_LEN);
        if packet_crc(body) != crc {
            return None;
        }
        let image_id = u16::from_le_bytes([body[1], body[2]]);
        let mut pos = HEAD;
        let index = read_field(body, &mut pos).ok()?;
        let count = read_field(body, &mut pos).ok()?;
        let shard = &body[pos..];
        let valid =
            count > 0 && usize::from(count) + usize::from(index) < MAX_SHARDS && !shard.is_empty();
        valid.then_some(Parity {
            image_id,
            index,
            count,
            shard,
        })
    }
}

/// A data packet's content: the packet without its tag, image id, index, count and checksum
/// (its flags, then the fields from the width on, and the payload). `None` when its fields do
/// not read.
fn content_of(packet: &[u8]) -> Option<Vec<u8>> {
    let body = packet.get(..packet.len().checked_sub(CRC_LEN)?)?;
    let flags = *body.get(HEAD)?;
    let mut pos = HEAD + 1;
    read_field(body, &mut pos).ok()?;
    read_field(body, &mut pos).ok()?;
    let mut content = Vec::with_capacity(body.len() - pos + 1);
    content.push(flags);
    content.extend_from_slice(&body[pos..]);
    Some(content)
}

/// A data packet's shard of `len` bytes: its content, the end byte, zeros. `None` when it does
/// not fit.
fn shard_of(packet: &[u8], len: usize) -> Option<Vec<u8>> {
    let mut shard = content_of(packet)?;
    if shard.len() >= len {
        return None;
    }
    shard.push(CONTENT_END);
    shard.resize(len, 0);
    Some(shard)
}

/// The data packet `index` of image `image_id` sent as `count` packets, from its shard: the
/// fields every receiver knows put back around the content, and the checksum. `None` for a
/// shard without its end byte.
fn packet_of(shard: &[u8], image_id: u16, index: u16, count: u16) -> Option<Vec<u8>> {
    let end = shard.iter().rposition(|&b| b != 0)?;
    let (content, last) = (&shard[..end], shard[end]);
    let (&flags, rest) = content.split_first()?;
    if last != CONTENT_END {
        return None;
    }
    let id = image_id.to_le_bytes();
    let mut fields = [0u8; 6];
    let pos = write_field(&mut fields, 0, index);
    let pos = write_field(&mut fields, pos, count);
    let mut packet = vec![PACKET_TAG, id[0], id[1], flags];
    packet.extend_from_slice(&fields[..pos]);
    packet.extend_from_slice(rest);
    let crc = packet_crc(&packet);
    packet.extend_from_slice(&crc);
    Some(packet)
}

/// The `parity` parity packets of `packets` (the data packets, by index), for image
/// `image_id`. `None` when the code cannot cover them (more than [`MAX_SHARDS`] in all) or a
/// packet's fields do not read.
pub fn parity_packets(packets: &[Vec<u8>], parity: usize, image_id: u16) -> Option<Vec<Vec<u8>>> {
    let n = packets.len();
    if parity == 0 || n == 0 || n + parity > MAX_SHARDS {
        return None;
    }
    let contents: Option<Vec<Vec<u8>>> = packets.iter().map(|p| content_of(p)).collect();
    let len = 1 + contents?.iter().map(Vec::len).max()?;
    let mut shards: Vec<Vec<u8>> = packets
        .iter()
        .map(|p| shard_of(p, len))
        .collect::<Option<_>>()?;
    shards.extend((0..parity).map(|_| vec![0u8; len]));
    ReedSolomon::new(n, parity).ok()?.encode(&mut shards).ok()?;
    let id = image_id.to_le_bytes();
    let out = shards[n..]
        .iter()
        .enumerate()
        .map(|(k, shard)| {
            let mut packet = vec![0u8; HEAD + 6];
            packet[..HEAD].copy_from_slice(&[PARITY_TAG, id[0], id[1]]);
            let pos = write_field(&mut packet, HEAD, k as u16);
            let pos = write_field(&mut packet, pos, n as u16);
            packet.truncate(pos);
            packet.extend_from_slice(shard);
            let crc = packet_crc(&packet);
            packet.extend_from_slice(&crc);
            packet
        })
        .collect();
    Some(out)
}

/// The data packets that `received` (by index, `None` where missing) and the parity packets
/// `parities` of image `image_id` rebuild: each missing index with its bytes. Empty when too
/// few arrived (fewer than `received.len()` of all) or the parity packets disagree.
pub fn rebuild(
    received: &[Option<&[u8]>],
    parities: &[Parity<'_>],
    image_id: u16,
) -> Vec<(u16, Vec<u8>)> {
    let n = received.len();
    let Some(first) = parities.first() else {
        return Vec::new();
    };
    let len = first.shard.len();
    // The code's rows do not depend on how many parity packets were sent: the highest index
    // received is enough.
    let k = 1 + parities
        .iter()
        .map(|p| usize::from(p.index))
        .max()
        .unwrap_or(0);
    let agree = parities
        .iter()
        .all(|p| usize::from(p.count) == n && p.shard.len() == len);
    if !agree || n + k > MAX_SHARDS {
        return Vec::new();
    }
    let mut shards: Vec<Option<Vec<u8>>> = Vec::with_capacity(n + k);
    for packet in received {
        match packet {
            None => shards.push(None),
            Some(p) => match shard_of(p, len) {
                Some(shard) => shards.push(Some(shard)),
                None => return Vec::new(),
            },
        }
    }
    shards.extend((0..k).map(|_| None));
    for p in parities {
        shards[n + usize::from(p.index)] = Some(p.shard.to_vec());
    }
    let Ok(code) = ReedSolomon::new(n, k) else {
        return Vec::new();
    };
    if code.reconstruct_data(&mut shards).is_err() {
        return Vec::new();
    }
    received
        .iter()
        .enumerate()
        .filter(|(_, p)| p.is_none())
        .filter_map(|(i, _)| {
            let index = i as u16;
            let packet = packet_of(shards[i].as_ref()?, image_id, index, n as u16)?;
            Some((index, packet))
        })
        .collect()
}
