//! The leaves and chroma nodes of a colour stream, one per line in coding order: `L x y side`
//! for a luma leaf (luma pixels), `C x y side` for a chroma node (chroma-plane pixels, printed
//! before the first leaf it covers): where a decoded picture's patches meet, for studies of
//! their edges (`bench/experiments/chroma_ramps.py`).
//!
//! `cargo run --release -p host-encoder --example chroma_nodes -- STREAM.pifs > NODES.txt`

use decoder_core::internal::colour::{ChromaFrontier, ChromaPatch};
use decoder_core::internal::entropy::RangeDecoder;
use decoder_core::internal::prediction::Frontier;
use decoder_core::internal::syntax::{control_step, Header};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk_with, LeafInfo, TreeVisitor, WalkState};
use decoder_core::{DecodeError, SliceSource};

/// Collects each luma leaf and each chroma node once (a subtree's chroma is handed to each of
/// its leaves).
struct Nodes(Vec<(char, u32, u32, u32)>);

impl TreeVisitor for Nodes {
    type Error = DecodeError;
    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        frontier.record(&info.node, control_step(info.cquant), patch, &mut Discard);
        Ok(())
    }

    fn leaf_colour<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        chroma: &ChromaPatch,
        frontier: &mut Frontier<STRIPE>,
        _chroma_frontier: &ChromaFrontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        let n = chroma.node;
        let node = ('C', n.x, n.y, 1u32 << n.log2);
        if self.0.iter().rev().find(|m| m.0 == 'C') != Some(&node) {
            self.0.push(node);
        }
        let l = info.node;
        self.0.push(('L', l.x, l.y, 1u32 << l.log2));
        self.leaf(info, patch, frontier)
    }
}

fn main() {
    let path = std::env::args().nth(1).expect("a stream");
    let stream = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let (header, at) = Header::parse(&stream).unwrap_or_else(|e| panic!("{path}: {e}"));
    assert_eq!(header.channels, 3, "{path}: colour streams only");
    let payload = &stream[at..at + header.payload_len as usize];
    let mut state = Box::<WalkState<65536>>::default();
    let mut coder = RangeDecoder::new(SliceSource::new(payload)).expect("a payload");
    let mut nodes = Nodes(Vec::new());
    walk_with(&header, &mut coder, &mut nodes, &mut state)
        .unwrap_or_else(|e| panic!("{path}: {e}"));
    for (kind, x, y, s) in nodes.0 {
        println!("{kind} {x} {y} {s}");
    }
}
