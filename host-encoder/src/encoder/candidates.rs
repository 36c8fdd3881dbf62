//! What the analysis keeps: per quadtree node, its fits and its candidates (each a way of
//! coding the node as a leaf, with its distortion), level by level. Rate control and the writer
//! read these through [`WithCandidates`], without knowing the analysis that made them.
//!
//! Above [`super::quantise`] (a candidate is a quantised fit); below [`super::rate`].

use super::ids::{ControlQuantiserId, ModelId};
use super::masking::Masking;
use decoder_core::internal::syntax::{ControlCoding, LeafSyntax};
use decoder_core::Node;

/// One way of coding a node as a leaf.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Index into the node's fits ([`NodeAnalysis::fits`]).
    pub fit: u8,
    /// Control quantiser.
    pub cq: ControlQuantiserId,
    /// Control coding.
    pub coding: ControlCoding,
    /// Squared error over the node's in-image pixels, times the node's weight
    /// ([`CandidateTree::masking`]).
    pub sse: f64,
    /// Where its quantised control indices start in [`NodeAnalysis::indices`]: kept, as every
    /// rate table and the writer need them again.
    pub at: u32,
}

/// The rate and error of one way of coding something.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RatePoint {
    /// Bits.
    pub bits: f32,
    /// Squared error, in the units of the node's luma error.
    pub sse: f32,
}

/// What coding a node's chroma costs when the node is a leaf: for each chroma plane, the
/// options on the lower convex hull of (bits, weighted error). The quadtree's cut sees it
/// beside the luma candidates' cost; empty (free) for a grayscale analysis, where it takes
/// one word in every node.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChromaCost {
    /// The hull of `Cb`'s options, then `Cr`'s.
    planes: Option<Box<[Vec<RatePoint>; 2]>>,
}

impl ChromaCost {
    /// The cost whose planes' hulls are `planes`.
    pub fn of(planes: [Vec<RatePoint>; 2]) -> ChromaCost {
        ChromaCost {
            planes: Some(Box::new(planes)),
        }
    }

    /// Each plane's option of least `sse + lambda * bits`.
    pub fn cheapest(&self, lambda: f64) -> impl Iterator<Item = &RatePoint> {
        let cost = move |p: &RatePoint| f64::from(p.sse) + lambda * f64::from(p.bits);
        self.planes
            .iter()
            .flat_map(|planes| planes.iter())
            .filter_map(move |plane| plane.iter().min_by(|a, b| cost(a).total_cmp(&cost(b))))
    }
}

/// Everything the analysis knows about one node.
#[derive(Debug, Clone)]
pub struct NodeAnalysis {
    /// The node.
    pub node: Node,
    /// Its fits, by their models (those the node supports and the analysis searches): a fit
    /// is made again when a pass needs it ([`super::fit::fit_default`]), as that is cheap next
    /// to quantising it and its control values would be a third of the analysis's memory. A
    /// candidate's `fit` indexes them.
    pub fits: Box<[ModelId]>,
    /// Every (fit, quantiser) pair with its distortion.
    pub candidates: Vec<Candidate>,
    /// The candidates' indices, one after the other (one allocation per node).
    pub indices: Vec<i16>,
    /// What its chroma costs as a leaf (colour analyses only).
    pub chroma: ChromaCost,
}

impl NodeAnalysis {
    /// The leaf syntax of candidate `c`.
    pub fn leaf(&self, c: &Candidate) -> LeafSyntax {
        let model = self.fits[usize::from(c.fit)];
        let nc = model.model().control_count();
        let mut leaf = super::ids::leaf_syntax(model, c.cq, c.coding);
        let at = c.at as usize;
        leaf.control[..nc].copy_from_slice(&self.indices[at..at + nc]);
        leaf
    }

    /// How many indices candidate `c` holds in [`NodeAnalysis::indices`].
    fn index_count(&self, c: &Candidate) -> usize {
        self.fits[usize::from(c.fit)].model().control_count()
    }

    /// Keeps the candidates `keep` lists (indices into the candidate list, ascending) and only
    /// their indices.
    pub fn retain(&mut self, keep: &[u16]) {
        let mut indices = Vec::with_capacity(
            keep.iter()
                .map(|&k| self.index_count(&self.candidates[usize::from(k)]))
                .sum(),
        );
        let candidates = keep
            .iter()
            .map(|&k| {
                let mut c = self.candidates[usize::from(k)];
                let at = c.at as usize;
                let n = self.index_count(&c);
                c.at = indices.len() as u32;
                indices.extend_from_slice(&self.indices[at..at + n]);
                c
            })
            .collect();
        self.candidates = candidates;
        self.indices = indices;
    }
}

/// The nodes of one quadtree level.
#[derive(Debug, Clone)]
pub struct Level {
    /// Node side, as a power of two.
    pub log2: u8,
    /// Nodes per row.
    pub cols: u32,
    /// Analysed nodes, row-major; `None` outside the image.
    pub nodes: Vec<Option<NodeAnalysis>>,
}

impl Level {
    /// The index of the node at `(x, y)` (its top-left pixel) in [`Level::nodes`].
    pub fn index(&self, x: u32, y: u32) -> usize {
        ((y >> self.log2) * self.cols + (x >> self.log2)) as usize
    }

    /// The node at `(x, y)` (its top-left pixel), if analysed.
    pub fn get(&self, x: u32, y: u32) -> Option<&NodeAnalysis> {
        self.nodes.get(self.index(x, y)).and_then(Option::as_ref)
    }
}

/// Every analysed node's candidates, level by level from the smallest leaf to the root.
#[derive(Debug, Clone)]
pub struct CandidateTree {
    levels: Vec<Level>,
    min_leaf_log2: u8,
    /// The weights of the candidates' errors.
    masking: Masking,
}

impl CandidateTree {
    /// The tree of `levels`, whose first is of side `2^min_leaf_log2`, the next twice that, and
    /// so on, whose candidates' errors are weighted by `masking`.
    pub fn new(levels: Vec<Level>, min_leaf_log2: u8, masking: Masking) -> CandidateTree {
        debug_assert!(levels
            .iter()
            .zip(min_leaf_log2..)
            .all(|(l, log2)| l.log2 == log2));
        CandidateTree {
            levels,
            min_leaf_log2,
            masking,
        }
    }

    /// The weights of the candidates' errors: a candidate's `sse` is its squared error times
    /// its node's weight.
    pub fn masking(&self) -> &Masking {
        &self.masking
    }

    /// The levels, to add or drop candidates, with the weights their errors get.
    pub fn levels_and_masking_mut(&mut self) -> (&mut [Level], &Masking) {
        (&mut self.levels, &self.masking)
    }

    /// The levels, from the smallest leaf (index 0) to the root.
    pub fn levels(&self) -> &[Level] {
        &self.levels
    }

    /// The levels, to add or drop candidates.
    pub fn levels_mut(&mut self) -> &mut [Level] {
        &mut self.levels
    }

    /// Side of the smallest leaf, as a power of two (the first level's).
    pub fn min_leaf_log2(&self) -> u8 {
        self.min_leaf_log2
    }

    /// The level of nodes of side `2^log2`.
    pub fn level(&self, log2: u8) -> Option<&Level> {
        self.levels
            .get(usize::from(log2.checked_sub(self.min_leaf_log2)?))
    }

    /// The analysis of `node`, if it was analysed.
    pub fn node(&self, node: &Node) -> Option<&NodeAnalysis> {
        self.level(node.log2).and_then(|l| l.get(node.x, node.y))
    }
}

/// Whatever holds a [`CandidateTree`]: rate control and the writer take any of them, so that
/// the analysis above them can hand itself over.
pub trait WithCandidates {
    /// The candidates.
    fn candidates(&self) -> &CandidateTree;
}

impl WithCandidates for CandidateTree {
    fn candidates(&self) -> &CandidateTree {
        self
    }
}
