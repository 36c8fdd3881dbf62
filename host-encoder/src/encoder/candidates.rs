//! What the analysis keeps: per quadtree node, its fits and its candidates (each a way of
//! coding the node as a leaf, with its distortion), level by level. Rate control and the writer
//! read these through [`WithCandidates`], without knowing the analysis that made them.
//!
//! Above [`super::quantise`] (a candidate is a quantised fit, made again when its syntax is
//! needed); below [`super::rate`].

use super::fit::{fit_default, Fit};
use super::ids::{ControlQuantiserId, Models};
use super::masking::Masking;
use super::plane::ImagePrediction;
use super::quantise::{
    quantise, ControlTargets, ResidualPrices, Rounding, ROUNDING_LAMBDA, ROUNDING_VARIANTS,
};
use decoder_core::internal::syntax::{ControlCoding, LeafSyntax};
use decoder_core::Node;
use std::sync::Arc;

/// One way of coding a node as a leaf.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Index into the node's fits ([`NodeAnalysis::fits`]).
    pub fit: u8,
    /// Control quantiser.
    pub cq: ControlQuantiserId,
    /// Control coding.
    pub coding: ControlCoding,
    /// How its control indices were rounded.
    pub rounding: RoundingId,
    /// Squared error over the node's in-image pixels, times the node's weight
    /// ([`CandidateTree::masking`]).
    pub sse: f64,
    /// Its bits, coded from the contexts it was last rated from: those every stream starts from
    /// during the passes, the trial encode's once the analysis is done. Rate control reads
    /// them (and `sse`) in place.
    pub bits: f32,
}

/// How a candidate's control indices were rounded ([`Rounding`]), in a few bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RoundingId {
    /// The multiplier: 0 for [`ROUNDING_LAMBDA`], `k + 1` for [`ROUNDING_VARIANTS`]`[k]`.
    pub multiplier: u8,
    /// Whether it was rounded knowing the trial encode: the bits priced under the trial's
    /// contexts around the node ([`NodeAnalysis::prices`]) and its edges predicted from the
    /// pixels the trial drew ([`ImagePrediction::drawn`]), instead of the contexts every
    /// stream starts from and the image's own pixels.
    pub block_prices: bool,
}

impl RoundingId {
    /// The roundings of a candidate's variants: every multiplier, the bits priced under its
    /// block's contexts. (With the prices every stream starts from too, they gained at most
    /// 0.008 dB for 13% more encoding time: docs/decisions.md.)
    pub fn variants() -> impl Iterator<Item = RoundingId> {
        (0..=ROUNDING_VARIANTS.len() as u8).map(|multiplier| RoundingId {
            multiplier,
            block_prices: true,
        })
    }

    /// The prediction its indices were rounded against, of those `image` knows.
    pub fn prediction<'a>(self, image: &ImagePrediction<'a>) -> ImagePrediction<'a> {
        if self.block_prices {
            image.drawn()
        } else {
            image.own()
        }
    }

    /// The rounding, `block` being the prices of the node's block ([`NodeAnalysis::prices`]).
    pub fn with(self, block: Option<&ResidualPrices>) -> Rounding<'_> {
        let lambda = match self.multiplier.checked_sub(1) {
            None => ROUNDING_LAMBDA,
            Some(k) => ROUNDING_VARIANTS[usize::from(k)],
        };
        match block.filter(|_| self.block_prices) {
            Some(prices) => Rounding { lambda, prices },
            None => Rounding::from_start(lambda),
        }
    }
}

/// The quantisation targets of `fit`, the fit of `node` in the image `image` predicts from.
pub fn targets_of(image: &ImagePrediction, node: &Node, fit: &Fit) -> ControlTargets {
    ControlTargets::of(fit, node.log2).with_edges(image, node, fit.model)
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

    /// The hull of plane `p`'s options (0: `Cb`, 1: `Cr`; none if not priced).
    pub fn plane(&self, p: usize) -> &[RatePoint] {
        self.planes
            .as_ref()
            .and_then(|planes| planes.get(p))
            .map_or(&[], |hull| hull.as_slice())
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
    pub fits: Models,
    /// Every (fit, quantiser, rounding) kept, with its distortion and bits.
    pub candidates: Vec<Candidate>,
    /// The candidates' control indices, one after the other, if the node holds them; if not,
    /// [`NodeAnalysis::leaf`] makes them again (quantising again costs time, holding them
    /// every node of a large image costs a third of the analysis's memory). Boxed: a node that
    /// does not hold them pays one word.
    #[allow(clippy::box_collection)] // one word, not three, in the many nodes that hold none
    pub indices: Option<Box<Vec<i16>>>,
    /// What its chroma costs as a leaf (colour analyses only).
    pub chroma: ChromaCost,
    /// The residuals' bits under the trial encode's contexts around the node, once the final
    /// pruning has rounded candidates with them ([`Candidate::block_prices`]).
    pub prices: Option<Arc<ResidualPrices>>,
}

impl NodeAnalysis {
    /// A node with no candidates yet, holding their indices if `holds`.
    pub fn new(node: Node, holds: bool) -> NodeAnalysis {
        NodeAnalysis {
            node,
            fits: Models::none(),
            candidates: Vec::new(),
            indices: holds.then(Box::default),
            chroma: ChromaCost::default(),
            prices: None,
        }
    }

    /// Room for `candidates` more candidates holding `indices` more indices in all.
    pub fn reserve(&mut self, candidates: usize, indices: usize) {
        self.candidates.reserve(candidates);
        if let Some(held) = &mut self.indices {
            held.reserve(indices);
        }
    }

    /// Drops every candidate.
    pub fn clear(&mut self) {
        self.candidates.clear();
        if let Some(held) = &mut self.indices {
            held.clear();
        }
    }

    /// Adds candidate `c` whose syntax is `leaf`.
    pub fn push(&mut self, c: Candidate, leaf: &LeafSyntax) {
        let n = self.index_count(&c);
        if let Some(indices) = &mut self.indices {
            indices.extend_from_slice(&leaf.control[..n]);
        }
        self.candidates.push(c);
    }

    /// How many control indices candidate `c` has.
    fn index_count(&self, c: &Candidate) -> usize {
        self.fits[usize::from(c.fit)].model().control_count()
    }

    /// The syntax of candidate `c` whose indices are `indices`.
    fn held_leaf(&self, c: &Candidate, indices: &[i16]) -> LeafSyntax {
        let mut leaf = super::ids::leaf_syntax(self.fits[usize::from(c.fit)], c.cq, c.coding);
        leaf.control[..indices.len()].copy_from_slice(indices);
        leaf
    }

    /// The node's fit number `fit`, made again from `image`'s plane, with its quantisation
    /// targets predicting as `image` does.
    pub fn fit_and_targets(&self, fit: u8, image: &ImagePrediction) -> (Fit, ControlTargets) {
        let fit = fit_default(image.plane, &self.node, self.fits[usize::from(fit)]);
        let targets = targets_of(image, &self.node, &fit);
        (fit, targets)
    }

    /// The leaf syntax of candidate number `k`: the indices the node holds, or else made again
    /// from the image `image` predicts from (the fit, by its model, its targets predicting as
    /// its rounding did, [`RoundingId::prediction`], then its quantiser and rounding).
    pub fn leaf(&self, k: usize, image: &ImagePrediction) -> LeafSyntax {
        let c = &self.candidates[k];
        match &self.indices {
            Some(indices) => {
                let at: usize = (self.candidates[..k].iter())
                    .map(|c| self.index_count(c))
                    .sum();
                self.held_leaf(c, &indices[at..][..self.index_count(c)])
            }
            None => {
                let (fit, targets) = self.fit_and_targets(c.fit, &c.rounding.prediction(image));
                let rounding = c.rounding.with(self.prices.as_deref());
                quantise(&fit, &targets, c.cq, c.coding, rounding).leaf
            }
        }
    }

    /// The leaf syntax of every candidate, in order ([`NodeAnalysis::leaf`], each fit made
    /// once).
    pub fn leaves(&self, image: &ImagePrediction) -> Vec<LeafSyntax> {
        if let Some(indices) = &self.indices {
            let mut at = 0;
            return (self.candidates.iter())
                .map(|c| {
                    let n = self.index_count(c);
                    at += n;
                    self.held_leaf(c, &indices[at - n..at])
                })
                .collect();
        }
        // Each fit made once, its targets once per prediction its candidates were rounded
        // against.
        let mut fits: Vec<Option<Fit>> = (0..self.fits.len()).map(|_| None).collect();
        let mut targets: Vec<Option<ControlTargets>> =
            (0..2 * self.fits.len()).map(|_| None).collect();
        self.candidates
            .iter()
            .map(|c| {
                let f = usize::from(c.fit);
                let fit = fits[f]
                    .get_or_insert_with(|| fit_default(image.plane, &self.node, self.fits[f]));
                let targets = targets[2 * f + usize::from(c.rounding.block_prices)]
                    .get_or_insert_with(|| {
                        targets_of(&c.rounding.prediction(image), &self.node, fit)
                    });
                let rounding = c.rounding.with(self.prices.as_deref());
                quantise(fit, targets, c.cq, c.coding, rounding).leaf
            })
            .collect()
    }

    /// Keeps the candidates `keep` lists (indices into the candidate list, ascending), and
    /// only their indices.
    pub fn retain(&mut self, keep: &[u16]) {
        if let Some(held) = &self.indices {
            // Where each candidate's indices start, and where the last ends.
            let mut starts = Vec::with_capacity(self.candidates.len() + 1);
            starts.push(0);
            for c in &self.candidates {
                starts.push(starts[starts.len() - 1] + self.index_count(c));
            }
            let span = |k: u16| starts[usize::from(k)]..starts[usize::from(k) + 1];
            let mut indices = Vec::with_capacity(keep.iter().map(|&k| span(k).len()).sum());
            for &k in keep {
                indices.extend_from_slice(&held[span(k)]);
            }
            self.indices = Some(Box::new(indices));
        }
        self.candidates = keep
            .iter()
            .map(|&k| self.candidates[usize::from(k)])
            .collect();
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
