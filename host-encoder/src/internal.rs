//! Machinery the project's tests and fuzz seeds share with the encoder. Not part of the public
//! API: no stability promise.
//!
//! [`synthetic_stream`] writes a valid stream of any size without an analysis (whose memory
//! grows with the image): a quadtree of equal leaves whose syntax the caller chooses. The tests
//! that need a 16384 x 16384 or a 65535 x 65535 stream, and the fuzz seeds of large declared
//! dimensions, are made with it.

pub use crate::encoder::forward_grid_transform;
pub use crate::entropy::RangeEncoder;

use decoder_core::internal::format::{CODING_TILE, DEFAULT_STRIPE};
use decoder_core::internal::format::{MAX_LEAF_LOG2, MIN_LEAF_LOG2};
use decoder_core::internal::prediction::{Frontier, SamplePrediction};
use decoder_core::internal::syntax::{control_step, seal, Header, LeafSyntax};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk, LeafInfo, TreeVisitor};
use decoder_core::{DecodeError, Node};

/// Splits every node above the leaf size and lets the caller fill each leaf.
struct Uniform<F> {
    leaf_log2: u8,
    fill: F,
}

impl<F: FnMut(&Node, &mut LeafSyntax)> TreeVisitor for Uniform<F> {
    type Error = DecodeError;

    fn split(&mut self, node: &Node) -> bool {
        node.log2 > self.leaf_log2
    }

    fn prepare_leaf<P: SamplePrediction>(&mut self, node: &Node, _: &P, leaf: &mut LeafSyntax) {
        (self.fill)(node, leaf);
    }

    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        let step = control_step(info.cquant);
        frontier.record(&info.node, step, patch, &mut Discard);
        Ok(())
    }
}

/// The edge smoothing of synthetic streams: some, so that they exercise it.
const SYNTHETIC_DEBLOCK: u8 = 4;

/// A complete stream (header, payload, checksum) of a `width x height` image whose quadtree
/// has leaves of side `2^leaf_log2` (within the format's range), in the default 512-pixel
/// stripes with some edge smoothing, wherever the image allows,
/// each leaf's syntax set by `fill` (it starts from [`LeafSyntax::default`]: the first model,
/// DPCM, every control index 0). Syntax the format cannot code for a leaf (a model its size
/// does not allow, say) is coded as the nearest it can, as the encoder's writer would.
pub fn synthetic_stream(
    width: u16,
    height: u16,
    leaf_log2: u8,
    fill: impl FnMut(&Node, &mut LeafSyntax),
) -> Result<Vec<u8>, DecodeError> {
    let leaf_log2 = leaf_log2.clamp(MIN_LEAF_LOG2, MAX_LEAF_LOG2);
    let header = Header {
        width: width.max(1),
        height: height.max(1),
        channels: 1,
        bit_depth: 8,
        min_leaf_log2: MIN_LEAF_LOG2.max(leaf_log2.saturating_sub(1)),
        max_leaf_log2: leaf_log2,
        stripe: (DEFAULT_STRIPE as u32 / CODING_TILE) as u8,
        deblock: SYNTHETIC_DEBLOCK,
        payload_len: 0,
        checksum: 0,
        range: None,
    };
    let mut coder = RangeEncoder::new();
    walk::<_, _, DEFAULT_STRIPE>(&header, &mut coder, &mut Uniform { leaf_log2, fill })?;
    let payload = coder.finish();
    let header = Header {
        payload_len: payload.len() as u32,
        ..header
    };
    let mut bytes = vec![0u8; header.encoded_len()];
    header.write(&mut bytes);
    bytes.extend_from_slice(&payload);
    seal(&mut bytes);
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_streams_decode() {
        let stream = synthetic_stream(300, 200, 6, |node, leaf| {
            leaf.control[0] = ((node.x / 64 + node.y / 64) % 5) as i16 - 2;
        })
        .unwrap();
        let decoder = decoder_core::Decoder::new(&stream).unwrap();
        assert_eq!(
            (decoder.header().width, decoder.header().height),
            (300, 200)
        );
        let mut px = vec![0u8; 300 * 200];
        decoder.decode_into(&mut px).unwrap();
        assert!(px.iter().any(|&p| p != px[0]), "a flat image");
    }
}
