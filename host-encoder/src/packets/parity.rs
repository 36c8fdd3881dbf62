//! Parity packets (`docs/bitstream.md`, section 9): `K` packets computed over an image's `N`
//! packets by a Reed–Solomon erasure code over GF(2^8), so that any `N` of the `N + K`
//! rebuild every one. A receiver needs them all in memory to rebuild: this is for gateways and
//! hosts, not for a microcontroller drawing packets as they come.

use decoder_core::internal::packet::{packet_crc, read_field, write_field, CRC_LEN};
pub use decoder_core::internal::syntax::PARITY_TAG;
use reed_solomon_erasure::galois_8::ReedSolomon;

/// The most packets, data and parity, one code covers (the field's size).
pub const MAX_SHARDS: usize = 256;

/// The bytes of a parity packet before its fields: the tag and the image id.
const PARITY_HEAD: usize = 3;

/// The most bytes a parity packet adds to its shard: tag, image id, four fields of at most
/// three bytes, the checksum.
const MAX_PARITY_OVERHEAD: usize = PARITY_HEAD + 4 * 3 + CRC_LEN;

/// The largest data packet that `parity` parity packets over `count` data packets of at most
/// `size` bytes each leave room for: each parity packet carries a shard two bytes longer than
/// the longest data packet, behind its own fields.
pub fn data_packet_size(size: usize, count: usize, parity: usize) -> usize {
    let field = |v: usize| {
        if v < 128 {
            1
        } else if v < 16384 {
            2
        } else {
            3
        }
    };
    let overhead = PARITY_HEAD + field(parity) * 2 + field(count) + field(size) + CRC_LEN;
    size.saturating_sub(overhead + LENGTH_PREFIX)
}

/// Bytes a data packet takes in a shard besides itself: its length.
const LENGTH_PREFIX: usize = 2;

/// One parity packet, parsed and checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Parity<'a> {
    /// The image's number.
    pub image_id: u16,
    /// This parity packet's number, `0..parity`.
    pub index: u16,
    /// How many parity packets were sent.
    pub parity: u16,
    /// How many data packets they protect (the data packets' `count`).
    pub count: u16,
    /// The shard.
    pub shard: &'a [u8],
}

impl<'a> Parity<'a> {
    /// Parses a parity packet, its CRC-16 first; `None` for anything else.
    pub fn parse(data: &'a [u8]) -> Option<Self> {
        if data.len() < PARITY_HEAD + 4 + CRC_LEN || data[0] != PARITY_TAG {
            return None;
        }
        let (body, crc) = data.split_at(data.len() - CRC_LEN);
        if packet_crc(body) != crc {
            return None;
        }
        let image_id = u16::from_le_bytes([body[1], body[2]]);
        let mut pos = PARITY_HEAD;
        let mut fields = [0u16; 4];
        for field in fields.iter_mut() {
            *field = read_field(body, &mut pos).ok()?;
        }
        let [index, parity, count, len] = fields;
        let shard = &body[pos..];
        let valid = index < parity
            && count > 0
            && usize::from(count) + usize::from(parity) <= MAX_SHARDS
            && shard.len() == usize::from(len);
        valid.then_some(Parity {
            image_id,
            index,
            parity,
            count,
            shard,
        })
    }
}

/// A data packet as a shard of `len` bytes: its length (two bytes, little-endian), itself,
/// zeros.
fn shard_of(packet: &[u8], len: usize) -> Vec<u8> {
    let mut shard = Vec::with_capacity(len);
    shard.extend_from_slice(&(packet.len() as u16).to_le_bytes());
    shard.extend_from_slice(packet);
    shard.resize(len, 0);
    shard
}

/// The `parity` parity packets of `packets` (the data packets, by index), for image
/// `image_id`. `None` when the code cannot cover them (more than [`MAX_SHARDS`] in all).
pub fn parity_packets(packets: &[Vec<u8>], parity: usize, image_id: u16) -> Option<Vec<Vec<u8>>> {
    let n = packets.len();
    if parity == 0 || n == 0 || n + parity > MAX_SHARDS {
        return None;
    }
    let len = LENGTH_PREFIX + packets.iter().map(Vec::len).max()?;
    let mut shards: Vec<Vec<u8>> = packets.iter().map(|p| shard_of(p, len)).collect();
    shards.extend((0..parity).map(|_| vec![0u8; len]));
    ReedSolomon::new(n, parity).ok()?.encode(&mut shards).ok()?;
    let id = image_id.to_le_bytes();
    let out = shards[n..]
        .iter()
        .enumerate()
        .map(|(k, shard)| {
            let mut packet = vec![0u8; MAX_PARITY_OVERHEAD - CRC_LEN];
            packet[..PARITY_HEAD].copy_from_slice(&[PARITY_TAG, id[0], id[1]]);
            let mut pos = PARITY_HEAD;
            for v in [k, parity, n, len] {
                pos = write_field(&mut packet, pos, v as u16);
            }
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
/// `parities` of the same image rebuild: each missing index with its bytes. Empty when too
/// few arrived (fewer than `received.len()` of all) or the parity packets disagree.
pub fn rebuild(received: &[Option<&[u8]>], parities: &[Parity<'_>]) -> Vec<(u16, Vec<u8>)> {
    let n = received.len();
    let Some(first) = parities.first() else {
        return Vec::new();
    };
    let (k, len) = (usize::from(first.parity), first.shard.len());
    let agree = parities
        .iter()
        .all(|p| p.parity == first.parity && usize::from(p.count) == n && p.shard.len() == len);
    let fits = received
        .iter()
        .flatten()
        .all(|p| p.len() + LENGTH_PREFIX <= len);
    if !agree || !fits || n + k > MAX_SHARDS {
        return Vec::new();
    }
    let mut shards: Vec<Option<Vec<u8>>> = received
        .iter()
        .map(|p| p.map(|p| shard_of(p, len)))
        .collect();
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
            let shard = shards[i].as_ref()?;
            let size = usize::from(u16::from_le_bytes([shard[0], shard[1]]));
            let packet = shard.get(LENGTH_PREFIX..LENGTH_PREFIX + size)?;
            Some((i as u16, packet.to_vec()))
        })
        .collect()
}
