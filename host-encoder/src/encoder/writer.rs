//! Writing the stream: decoder-core's quadtree walk driven by a [`Plan`], with the range
//! encoder as its coder; and the image the stream decodes to, rendered from the plan.
//!
//! Above [`super::rate`] (it writes the plans rate control makes); below [`super::analysis`],
//! whose trial encode it writes.

use super::candidates::CandidateTree;
use super::error::EncodeError;
use super::rate::{Decision, Plan};
use crate::entropy::RangeEncoder;
use decoder_core::internal::prediction::Frontier;
use decoder_core::internal::syntax::{
    reconstruct as reconstruct_patch, seal, Contexts, Header, LeafSyntax,
};
use decoder_core::internal::synthesis::Patch;
use decoder_core::internal::walk::{node_kind, walk, LeafInfo, NodeKind, TreeVisitor};
use decoder_core::{DecodeError, Node, PixelSink, Rect, Tile};
use rayon::prelude::*;
use std::convert::Infallible;

/// A written stream and the encoder's own reconstruction of it.
#[derive(Debug, Clone)]
pub struct Written {
    /// The complete stream (header and payload).
    pub bytes: Vec<u8>,
    /// Size of the payload alone, in bits.
    pub payload_bits: f64,
    /// Context state at the end of the payload (seeds the next rate estimate).
    pub final_contexts: Contexts,
    /// Leaves coded.
    pub leaves: usize,
}

/// The walk's visitor: splits and codes the leaves as the plan says.
struct PlanVisitor<'a> {
    tree: &'a CandidateTree,
    plan: &'a Plan,
    leaves: usize,
}

impl TreeVisitor for PlanVisitor<'_> {
    type Error = DecodeError;

    fn split(&mut self, node: &Node) -> bool {
        !matches!(self.plan.decision(self.tree, node), Some(Decision::Leaf(_)))
    }

    fn prepare_leaf(&mut self, node: &Node, leaf: &mut LeafSyntax) {
        let na = self.tree.node(node);
        if let (Some(na), Some(Decision::Leaf(ci))) = (na, self.plan.decision(self.tree, node)) {
            let c = &na.candidates[usize::from(ci)];
            *leaf = na.leaf(c);
        }
    }

    fn leaf(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier,
    ) -> Result<(), DecodeError> {
        frontier.record(&info.node, patch);
        self.leaves += 1;
        Ok(())
    }
}

/// Writes the stream for `plan` (of `tree`'s candidates) with `header`.
pub fn write(tree: &CandidateTree, header: &Header, plan: &Plan) -> Result<Written, EncodeError> {
    let mut visitor = PlanVisitor {
        tree,
        plan,
        leaves: 0,
    };
    let mut coder = RangeEncoder::new();
    let state = walk(header, &mut coder, &mut visitor).map_err(EncodeError::Syntax)?;
    let payload = coder.finish();
    let header = Header {
        payload_len: u32::try_from(payload.len())
            .map_err(|_| EncodeError::Internal("a payload of 4 GiB or more"))?,
        ..*header
    };
    let mut bytes = vec![0u8; header.encoded_len()];
    header.write(&mut bytes);
    bytes.extend_from_slice(&payload);
    seal(&mut bytes);
    Ok(Written {
        payload_bits: payload.len() as f64 * 8.0,
        bytes,
        final_contexts: state.contexts,
        leaves: visitor.leaves,
    })
}

/// The image a stream written for `plan` decodes to, rendered straight from `tree`'s
/// candidates: a leaf's patch depends on its syntax alone (its first control index is coded
/// against a prediction, but reconstructed from the index), so the leaves are rendered in
/// parallel.
pub fn reconstruct(
    tree: &CandidateTree,
    header: &Header,
    plan: &Plan,
) -> Result<Vec<u8>, EncodeError> {
    let (width, height) = (u32::from(header.width), u32::from(header.height));
    // The plan's leaves, found as the walk finds them.
    let mut leaves = Vec::new();
    let mut stack = vec![Node {
        x: 0,
        y: 0,
        log2: header.root_log2(),
    }];
    while let Some(node) = stack.pop() {
        let leaf = match node_kind(header, &node) {
            NodeKind::Outside => continue,
            NodeKind::ForcedSplit => false,
            NodeKind::ForcedLeaf | NodeKind::Flagged => {
                matches!(plan.decision(tree, &node), Some(Decision::Leaf(_)))
            }
        };
        if leaf {
            leaves.push(node);
        } else if node.log2 > header.min_leaf_log2 {
            let (half, log2) = (1 << (node.log2 - 1), node.log2 - 1);
            for (dx, dy) in [(0, 0), (half, 0), (0, half), (half, half)] {
                stack.push(Node {
                    x: node.x + dx,
                    y: node.y + dy,
                    log2,
                });
            }
        } else {
            return Err(EncodeError::Internal("a plan without a leaf"));
        }
    }
    let tiles: Vec<Tiles> = leaves
        .par_iter()
        .map(|node| {
            let na = tree
                .node(node)
                .ok_or(EncodeError::Internal("a leaf that was not analysed"))?;
            let Some(Decision::Leaf(ci)) = plan.decision(tree, node) else {
                return Err(EncodeError::Internal("a leaf without a candidate"));
            };
            let leaf = na.leaf(&na.candidates[usize::from(ci)]);
            let patch = reconstruct_patch(header, &leaf, node.log2).map_err(EncodeError::Syntax)?;
            let mut tiles = Tiles::default();
            let Ok(()) = patch.render(node, Rect::of_size(width, height), &mut tiles);
            Ok(tiles)
        })
        .collect::<Result<_, _>>()?;
    let mut image = vec![0u8; header.pixel_count()];
    let row_len = width as usize;
    for t in &tiles {
        for &(Rect { x, y, w, h }, start) in &t.rects {
            let (x, w) = (x as usize, w as usize);
            for row in 0..h as usize {
                let at = (y as usize + row) * row_len + x;
                let from = start + row * w;
                image[at..at + w].copy_from_slice(&t.pixels[from..from + w]);
            }
        }
    }
    Ok(image)
}

/// The tiles one leaf renders, their pixels one after the other.
#[derive(Default)]
struct Tiles {
    /// Each tile's area, and where its pixels start in `pixels`.
    rects: Vec<(Rect, usize)>,
    pixels: Vec<u8>,
}

impl PixelSink for Tiles {
    type Error = Infallible;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
        let Rect { w, h, .. } = tile.area;
        self.rects.push((tile.area, self.pixels.len()));
        self.pixels
            .extend_from_slice(&tile.pixels[..(w * h) as usize]);
        Ok(())
    }
}
