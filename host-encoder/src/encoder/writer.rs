//! Writing the stream: decoder-core's quadtree walk driven by a [`Plan`], with the range
//! encoder as its coder.
//!
//! Above [`super::rate`] (it writes the plans rate control makes); below [`super::analysis`],
//! whose trial encode it writes.

use super::candidates::CandidateTree;
use super::chroma::{choose, ChromaCache, ChromaChoice, ColourPlanes};
use super::error::EncodeError;
use super::plane::ImagePrediction;
use super::rate::{Decision, Plan};
use crate::entropy::RangeEncoder;
use decoder_core::internal::entropy::{Coder, PayloadError, Prob, PROB_ONE};
use decoder_core::internal::prediction::Frontier;
use decoder_core::internal::prediction::SamplePrediction;
use decoder_core::internal::syntax::{
    control_step, seal, ChromaContexts, Contexts, Header, LeafSyntax,
};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk_with, LeafInfo, TreeVisitor, WalkState};
use decoder_core::{DecodeError, Node};
use rayon::prelude::*;
use std::cell::{Cell, RefCell};
use std::collections::HashMap;

/// The widest stripe the writer holds prediction memory for: any the format allows.
const MAX_STRIPE: usize = 1 << 16;

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
    /// Payload bits of the chroma planes (estimated from the contexts' probabilities as each
    /// leaf's chroma was chosen; 0 for a grayscale stream).
    pub chroma_bits: f64,
}

/// The syntax of a plan's leaves, made again from the image before the walk (in parallel),
/// by node (side as a power of two, then its top-left pixel) and candidate.
type PlanLeaves = HashMap<(u8, u32, u32, u16), LeafSyntax>;

/// The syntax of every leaf `plan` (of `tree`'s candidates) codes, made from the image `image`
/// predicts from.
fn plan_leaves(tree: &CandidateTree, plan: &Plan, image: &ImagePrediction) -> PlanLeaves {
    let mut wanted = Vec::new();
    if let Some(top) = tree.levels().last() {
        for na in top.nodes.iter().flatten() {
            cut_leaves(tree, plan, (na.node, false), &mut wanted);
        }
    }
    wanted
        .into_par_iter()
        .filter_map(|(node, c)| {
            let na = tree.node(&node)?;
            let k = usize::from(c);
            (k < na.candidates.len()).then(|| (leaf_key(&node, c), na.leaf(k, image)))
        })
        .collect()
}

/// Where [`PlanLeaves`] keeps the syntax of candidate `c` of `node`.
fn leaf_key(node: &Node, c: u16) -> (u8, u32, u32, u16) {
    (node.log2, node.x, node.y, c)
}

/// Adds to `leaves` the leaves of `plan`'s cut at and below `node` (`in_subtree`: inside a
/// subtree whose chroma a node above codes), with their candidates.
fn cut_leaves(
    tree: &CandidateTree,
    plan: &Plan,
    (node, in_subtree): (Node, bool),
    leaves: &mut Vec<(Node, u16)>,
) {
    let decision = plan.decision(tree, &node, in_subtree);
    let below = match decision {
        None => return,
        Some(Decision::Leaf(c)) => return leaves.push((node, c)),
        Some(Decision::Split) => in_subtree,
        Some(Decision::SplitWithChroma) => true,
    };
    if node.log2 <= tree.min_leaf_log2() {
        return;
    }
    let half = node.size() / 2;
    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let child = Node {
            x: node.x + dx * half,
            y: node.y + dy * half,
            log2: node.log2 - 1,
        };
        if tree.node(&child).is_some() {
            cut_leaves(tree, plan, (child, below), leaves);
        }
    }
}

/// The walk's visitor: splits and codes the leaves as the plan says.
struct PlanVisitor<'a> {
    tree: &'a CandidateTree,
    plan: &'a Plan,
    /// The syntax of the plan's leaves.
    plan_leaves: PlanLeaves,
    /// The image the syntax is made from.
    image: ImagePrediction<'a>,
    leaves: usize,
    /// The chroma of a colour stream.
    colour: Option<&'a ColourPlanes>,
    /// Chroma options reconstructed by earlier writes.
    cache: &'a ChromaCache,
    chroma_bits: f64,
    /// Chroma choices in coding order: replayed from an earlier write of the same plan, or
    /// recorded for a later one ([`ChromaMemo`]).
    tape: Vec<ChromaChoice>,
    /// How many of `tape` were replayed so far; `None` when recording.
    replay: Option<usize>,
    /// Where each leaf's bits are counted, when they are ([`leaf_bits`]).
    meter: Option<Meter<'a>>,
    /// The node whose chroma covers its subtree, while the walk may be in it.
    subtree: Option<Node>,
}

impl<'a> PlanVisitor<'a> {
    /// A visitor of `plan` that chooses every chroma leaf (recording the choices), counting
    /// leaves' bits into `meter` if given.
    fn new(
        (tree, image): (&'a CandidateTree, &ImagePrediction<'a>),
        plan: &'a Plan,
        colour: Option<&'a ColourPlanes>,
        cache: &'a ChromaCache,
        meter: Option<Meter<'a>>,
    ) -> Self {
        PlanVisitor {
            tree,
            plan,
            plan_leaves: plan_leaves(tree, plan, image),
            image: *image,
            leaves: 0,
            colour,
            cache,
            chroma_bits: 0.0,
            tape: Vec::new(),
            replay: None,
            meter,
            subtree: None,
        }
    }

    /// The plan's decision for `node`, the next node of the walk: inside the subtree whose
    /// chroma a node above codes, the plan's decisions for such subtrees.
    fn decision(&mut self, node: &Node) -> Option<Decision> {
        let inside = self.subtree.is_some_and(|s| {
            node.log2 < s.log2
                && node.x >= s.x
                && node.y >= s.y
                && node.x - s.x < s.size()
                && node.y - s.y < s.size()
        });
        if !inside {
            self.subtree = None;
        }
        self.plan.decision(self.tree, node, inside)
    }
}

/// The bits of every leaf, as [`leaf_bits`] counts them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeafBits {
    /// The leaf.
    pub node: Node,
    /// Its bits (luma and chroma, and the split flags coded since the leaf before it), from
    /// the contexts' probabilities.
    pub bits: f64,
}

/// A leaf-by-leaf account of a write: the coder adds to `total`, the visitor reads it.
struct Meter<'a> {
    total: &'a Cell<f64>,
    last: f64,
    leaves: Vec<LeafBits>,
}

/// A range encoder that also adds up the information of every decision it codes.
struct MeteredEncoder<'a> {
    inner: RangeEncoder,
    total: &'a Cell<f64>,
}

impl Coder for MeteredEncoder<'_> {
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        let zero = f64::from(p.probability()) / f64::from(PROB_ONE);
        let chance = if *bit { 1.0 - zero } else { zero };
        self.total.set(self.total.get() - chance.log2());
        self.inner.bit(p, bit)
    }

    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
        self.total.set(self.total.get() + 1.0);
        self.inner.bypass(bit)
    }
}

/// The chroma choices of the last colour stream written on this thread, with what they depend
/// on: the plan's cut, candidates and multiplier, the image (by address and size) and the
/// header but for its edge smoothing (which changes luma only). Writes of the same plan with
/// other smoothing strengths replay them instead of choosing every leaf's chroma again.
struct ChromaMemo {
    decisions: Vec<Vec<Decision>>,
    subtree_decisions: Vec<Vec<Decision>>,
    lambda: u64,
    image: (usize, usize),
    header: Header,
    choices: Vec<ChromaChoice>,
}

thread_local! {
    static CHROMA_MEMO: RefCell<Option<ChromaMemo>> = const { RefCell::new(None) };
}

impl TreeVisitor for PlanVisitor<'_> {
    type Error = DecodeError;

    fn split(&mut self, node: &Node) -> bool {
        !matches!(self.decision(node), Some(Decision::Leaf(_)))
    }

    fn chroma_subtree(&mut self, node: &Node) -> bool {
        let here = self.colour.is_some()
            && self.plan.decision(self.tree, node, false) == Some(Decision::SplitWithChroma);
        if here {
            self.subtree = Some(*node);
        }
        here
    }

    fn prepare_leaf<P: SamplePrediction>(
        &mut self,
        node: &Node,
        _prediction: &P,
        leaf: &mut LeafSyntax,
    ) {
        if let Some(Decision::Leaf(c)) = self.decision(node) {
            if let Some(made) = self.plan_leaves.get(&leaf_key(node, c)) {
                *leaf = *made;
            } else if let Some(na) = self.tree.node(node) {
                *leaf = na.leaf(usize::from(c), &self.image);
            }
        }
    }

    fn prepare_chroma<P: SamplePrediction>(
        &mut self,
        node: &Node,
        plane: usize,
        prediction: &P,
        contexts: &ChromaContexts,
        leaf: &mut LeafSyntax,
    ) {
        if let Some(colour) = self.colour {
            if let Some(pos) = self.replay {
                if let Some(choice) = self.tape.get(pos).copied() {
                    self.replay = Some(pos + 1);
                    *leaf = choice.syntax;
                    self.chroma_bits += choice.bits;
                    return;
                }
                // The tape ran out (it should not): choose from here on, recording nothing.
                self.replay = Some(usize::MAX);
            }
            // The node's errors count `weight` times, as in the analysis: the same choice as
            // its bits counting `1 / weight` times.
            let weight = self.tree.masking().chroma_weight(node);
            let choice = choose(
                &colour.chroma[plane & 1],
                plane,
                node,
                prediction,
                contexts,
                self.plan.lambda / weight,
                self.cache,
            );
            *leaf = choice.syntax;
            self.chroma_bits += choice.bits;
            if self.replay.is_none() {
                self.tape.push(choice);
            }
        }
    }

    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        frontier.record(&info.node, control_step(info.cquant), patch, &mut Discard);
        self.leaves += 1;
        if let Some(meter) = &mut self.meter {
            let now = meter.total.get();
            meter.leaves.push(LeafBits {
                node: info.node,
                bits: now - meter.last,
            });
            meter.last = now;
        }
        Ok(())
    }
}

/// Writes the stream for `plan` (of `tree`'s candidates, whose syntax is made again from the
/// image `prediction` predicts from) with `header`; a colour stream's chroma (`header.channels ==
/// 3`) is chosen leaf by leaf from `colour`, with the options `cache` holds (and keeps) for
/// them.
pub fn write(
    (tree, prediction): (&CandidateTree, &ImagePrediction),
    header: &Header,
    plan: &Plan,
    colour: Option<&ColourPlanes>,
    cache: &ChromaCache,
) -> Result<Written, EncodeError> {
    let colour = colour.filter(|_| header.channels == 3);
    let key_header = Header {
        deblock: 0,
        payload_len: 0,
        checksum: 0,
        ..*header
    };
    let image = colour.map_or((0, 0), |c| (c.rgb.as_ptr() as usize, c.rgb.len()));
    let tape = CHROMA_MEMO.with(|m| {
        m.borrow_mut().take().and_then(|memo| {
            (colour.is_some()
                && memo.lambda == plan.lambda.to_bits()
                && memo.image == image
                && memo.header == key_header
                && memo.decisions == plan.decisions
                && memo.subtree_decisions == plan.subtree_decisions)
                .then_some(memo.choices)
        })
    });
    let replay = tape.as_ref().map(|_| 0);
    let mut visitor = PlanVisitor::new((tree, prediction), plan, colour, cache, None);
    visitor.tape = tape.unwrap_or_default();
    visitor.replay = replay;
    let mut coder = RangeEncoder::new();
    let mut state = Box::new(WalkState::<MAX_STRIPE>::default());
    walk_with(header, &mut coder, &mut visitor, &mut state).map_err(EncodeError::Syntax)?;
    if colour.is_some() {
        let memo = ChromaMemo {
            decisions: plan.decisions.clone(),
            subtree_decisions: plan.subtree_decisions.clone(),
            lambda: plan.lambda.to_bits(),
            image,
            header: key_header,
            choices: std::mem::take(&mut visitor.tape),
        };
        CHROMA_MEMO.with(|m| *m.borrow_mut() = Some(memo));
    }
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
        chroma_bits: visitor.chroma_bits,
    })
}

/// The bits each leaf of `plan`'s stream costs, in coding order: where in the image a
/// stream's bits go (packets cut the image by them).
pub fn leaf_bits(
    (tree, image): (&CandidateTree, &ImagePrediction),
    header: &Header,
    plan: &Plan,
    colour: Option<&ColourPlanes>,
    cache: &ChromaCache,
) -> Result<Vec<LeafBits>, EncodeError> {
    let colour = colour.filter(|_| header.channels == 3);
    let total = Cell::new(0.0);
    let meter = Meter {
        total: &total,
        last: 0.0,
        leaves: Vec::new(),
    };
    let mut visitor = PlanVisitor::new((tree, image), plan, colour, cache, Some(meter));
    let mut coder = MeteredEncoder {
        inner: RangeEncoder::new(),
        total: &total,
    };
    let mut state = Box::new(WalkState::<MAX_STRIPE>::default());
    walk_with(header, &mut coder, &mut visitor, &mut state).map_err(EncodeError::Syntax)?;
    Ok(visitor.meter.map(|m| m.leaves).unwrap_or_default())
}
