//! Parity packets (`docs/bitstream.md`, section 9): `K` packets computed over an image's `N`
//! packets by a Reed–Solomon erasure code over GF(2^8), so that any `N` of the `N + K`
//! rebuild every one. Made here with the `reed-solomon-erasure` crate; rebuilt with
//! decoder-core's [`Rebuild`], which a device with the RAM for the packets runs too.

use decoder_core::internal::packet::{packet_crc, write_field};
use decoder_core::internal::parity::shard_of;
pub use decoder_core::internal::syntax::PARITY_TAG;
use decoder_core::{ParityPacket, Rebuild};
use reed_solomon_erasure::galois_8::ReedSolomon;

/// The most packets, data and parity, one code covers (the field's size).
pub const MAX_SHARDS: usize = decoder_core::internal::parity::MAX_SHARDS;

/// The bytes of a packet (data or parity) before its fields: the tag and the image id.
const HEAD: usize = 3;

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

/// The `parity` parity packets of `packets` (the data packets, by index), for image
/// `image_id`: the code of `docs/bitstream.md` section 9, made with the `reed-solomon-erasure`
/// crate (which the rebuild, decoder-core's own, is tested against). `None` when the code
/// cannot cover them (more than [`MAX_SHARDS`] in all) or a packet's fields do not read.
pub fn parity_packets(packets: &[Vec<u8>], parity: usize, image_id: u16) -> Option<Vec<Vec<u8>>> {
    let n = packets.len();
    if parity == 0 || n == 0 || n + parity > MAX_SHARDS {
        return None;
    }
    // The longest content (a packet less its tag, image id, index, count and checksum,
    // plus its flags) and its end byte.
    let len = packets.iter().map(|p| p.len()).max()?;
    let mut shards: Vec<Vec<u8>> = Vec::with_capacity(n + parity);
    for packet in packets {
        let mut shard = vec![0u8; len];
        shard_of(packet, &mut shard).ok()?;
        shards.push(shard);
    }
    // Cut to the longest content and its end byte.
    let used = shards
        .iter()
        .map(|s| s.iter().rposition(|&b| b != 0).map_or(0, |end| end + 1))
        .max()?;
    for shard in shards.iter_mut() {
        shard.truncate(used);
    }
    shards.extend((0..parity).map(|_| vec![0u8; used]));
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
/// `parities` of image `image_id` rebuild (decoder-core's [`Rebuild`]): each missing index
/// with its bytes. Empty when too few arrived (fewer than `received.len()` of all) or the
/// packets are not of one code.
pub fn rebuild(
    received: &[Option<&[u8]>],
    parities: &[ParityPacket<'_>],
    image_id: u16,
) -> Vec<(u16, Vec<u8>)> {
    let n = received.len();
    let Some(first) = parities.first() else {
        return Vec::new();
    };
    let slots = n
        + 1
        + parities
            .iter()
            .map(|p| usize::from(p.index))
            .max()
            .unwrap_or(0);
    let mut buf = vec![0u8; Rebuild::buffer_len(n, slots - n, first.shard.len())];
    let mut code = Rebuild::new(first.shard.len(), &mut buf);
    let added = parities.iter().all(|p| code.add_parity(p).is_ok())
        && received
            .iter()
            .flatten()
            .all(|data| code.add_packet(data).is_ok());
    if first.image_id != image_id || !added || code.rebuild().is_err() {
        return Vec::new();
    }
    let mut out = vec![0u8; first.shard.len() + HEAD + 6 + 2];
    received
        .iter()
        .enumerate()
        .filter(|(_, p)| p.is_none())
        .filter_map(|(i, _)| {
            let len = code.packet(i as u16, &mut out).ok()?;
            Some((i as u16, out[..len].to_vec()))
        })
        .collect()
}
