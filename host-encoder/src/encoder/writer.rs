//! Writing the stream: decoder-core's quadtree walk driven by a [`Plan`], with the range
//! encoder as its coder.

use super::analysis::Analysis;
use super::rate::{Decision, Plan};
use crate::entropy::RangeEncoder;
use decoder_core::bitstream::{seal, Contexts, Header, LeafSyntax};
use decoder_core::patch::{Patch, PixelSink, Rect};
use decoder_core::quadtree::{walk, LeafInfo, Node, TreeVisitor};
use decoder_core::DecodeError;

/// A written stream and the encoder's own reconstruction of it.
#[derive(Debug, Clone)]
pub struct Written {
    /// The complete stream (header and payload).
    pub bytes: Vec<u8>,
    /// Size of the payload alone, in bits.
    pub payload_bits: f64,
    /// Decoded pixels as the encoder reconstructed them, row-major (empty unless asked for).
    pub reconstruction: Vec<u8>,
    /// Context state at the end of the payload (seeds the next rate estimate).
    pub final_contexts: Contexts,
    /// Leaves coded.
    pub leaves: usize,
}

struct PlanVisitor<'a> {
    analysis: &'a Analysis,
    header: &'a Header,
    plan: &'a Plan,
    /// The reconstruction, if one is wanted.
    image: Option<Vec<u8>>,
    leaves: usize,
}

impl TreeVisitor for PlanVisitor<'_> {
    fn split(&mut self, node: &Node) -> bool {
        !matches!(
            self.plan.decision(self.analysis, node),
            Some(Decision::Leaf(_))
        )
    }

    fn prepare_leaf(&mut self, node: &Node, leaf: &mut LeafSyntax) {
        let na = self
            .analysis
            .level(node.log2)
            .and_then(|l| l.get(node.x, node.y));
        if let (Some(na), Some(Decision::Leaf(ci))) = (na, self.plan.decision(self.analysis, node))
        {
            let c = &na.candidates[usize::from(ci)];
            *leaf = na.leaf(c);
        }
    }

    fn leaf(&mut self, info: &LeafInfo, patch: &Patch) -> Result<(), DecodeError> {
        let node = &info.node;
        self.leaves += 1;
        let Some(image) = self.image.as_mut() else {
            return Ok(());
        };
        let clip = Rect::of_size(u32::from(self.header.width), u32::from(self.header.height));
        let width = usize::from(self.header.width);
        struct Into<'b> {
            image: &'b mut [u8],
            width: usize,
        }
        impl PixelSink for Into<'_> {
            fn tile(&mut self, x: u32, y: u32, w: u32, h: u32, pixels: &[u8]) {
                for (row, src) in pixels.chunks_exact(w as usize).take(h as usize).enumerate() {
                    let at = (y as usize + row) * self.width + x as usize;
                    self.image[at..at + w as usize].copy_from_slice(src);
                }
            }
        }
        patch.render(node.x, node.y, node.log2, clip, &mut Into { image, width });
        Ok(())
    }
}

/// Writes the stream for `plan` with `header`, and its reconstruction if `render`.
pub fn write(
    analysis: &Analysis,
    header: &Header,
    plan: &Plan,
    render: bool,
) -> Result<Written, DecodeError> {
    let mut visitor = PlanVisitor {
        analysis,
        header,
        plan,
        image: render.then(|| vec![0; header.pixel_count()]),
        leaves: 0,
    };
    let mut coder = RangeEncoder::new();
    let state = walk(header, &mut coder, &mut visitor)?;
    let payload = coder.finish();
    let header = Header {
        payload_len: u32::try_from(payload.len())
            .map_err(|_| DecodeError::InvalidHeader("payload length"))?,
        ..*header
    };
    let mut bytes = vec![0u8; header.encoded_len()];
    header.write(&mut bytes);
    bytes.extend_from_slice(&payload);
    seal(&mut bytes);
    Ok(Written {
        payload_bits: payload.len() as f64 * 8.0,
        bytes,
        reconstruction: visitor.image.unwrap_or_default(),
        final_contexts: state.contexts,
        leaves: visitor.leaves,
    })
}
