//! Writing the stream: decoder-core's quadtree walk driven by a [`Plan`], with the range
//! encoder as its coder.
//!
//! Above [`super::rate`] (it writes the plans rate control makes); below [`super::analysis`],
//! whose trial encode it writes.

use super::candidates::{CandidateTree, NodeAnalysis};
use super::chroma::{choose, ChromaCache, ChromaChoice, ColourPlanes};
use super::error::EncodeError;
use super::plane::{ImagePrediction, Plane};
use super::rate::{Decision, LocalContexts, Plan};
use crate::entropy::{BitCounter, RangeEncoder};
use decoder_core::internal::entropy::{Coder, PayloadError, Prob, PROB_ONE};
use decoder_core::internal::prediction::Frontier;
use decoder_core::internal::prediction::SamplePrediction;
use decoder_core::internal::syntax::{
    code_leaf, control_step, seal, ChromaContexts, Contexts, Header, LeafSyntax,
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

/// The syntax of every leaf `plan` (of `tree`'s candidates) codes, and of the candidates the
/// walk weighs against it ([`choose_leaf`]) at nodes that do not hold their indices, made from
/// the image `image` predicts from: in parallel, not one by one in the walk.
fn plan_leaves(tree: &CandidateTree, plan: &Plan, image: &ImagePrediction) -> PlanLeaves {
    let mut wanted = Vec::new();
    if let Some(top) = tree.levels().last() {
        for na in top.nodes.iter().flatten() {
            cut_leaves(tree, plan, (na.node, false), &mut wanted);
        }
    }
    wanted
        .into_par_iter()
        .flat_map_iter(|(node, c)| {
            let k = usize::from(c);
            let na = tree.node(&node).filter(|na| k < na.candidates.len());
            let mut made = Vec::new();
            if let Some(na) = na {
                made.push(k);
                if na.indices.is_none() {
                    made.extend(hull_neighbours(na, k, CHOICE_REACH));
                }
            }
            made.into_iter().filter_map(move |k| {
                let na = na?;
                Some((leaf_key(&node, u16::try_from(k).ok()?), na.leaf(k, image)))
            })
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

/// What a walk reads to write a plan: the candidates, the plan, the syntax of its leaves, the
/// image it is made from, the chroma. Their nodes lie `origin` pixels from the stream's (the
/// walk's): a part of the image analysed on its own ([`write_in_parts`]) has nodes of its own.
#[derive(Clone, Copy)]
struct PlanSource<'a> {
    tree: &'a CandidateTree,
    plan: &'a Plan,
    /// The syntax of the plan's leaves.
    plan_leaves: &'a PlanLeaves,
    /// The image the syntax is made from.
    image: ImagePrediction<'a>,
    /// The chroma of a colour stream.
    colour: Option<&'a ColourPlanes>,
    /// Chroma options reconstructed by earlier writes.
    cache: &'a ChromaCache,
    /// Where the candidates' image lies in the stream's, pixels.
    origin: (u32, u32),
}

impl PlanSource<'_> {
    /// The candidates' node at the stream's node `node` (of luma, or of chroma when `chroma`).
    fn local(&self, node: &Node, chroma: bool) -> Node {
        let shift = u32::from(chroma);
        Node {
            x: node.x - (self.origin.0 >> shift),
            y: node.y - (self.origin.1 >> shift),
            log2: node.log2,
        }
    }
}

/// What a walk of plans keeps as it goes.
#[derive(Default)]
struct WalkRecord<'a> {
    leaves: usize,
    chroma_bits: f64,
    /// Chroma choices in coding order: replayed from an earlier write of the same plan, or
    /// recorded for a later one ([`ChromaMemo`]).
    tape: Vec<ChromaChoice>,
    /// How many of `tape` were replayed so far; `None` when recording.
    replay: Option<usize>,
    /// Whether chroma choices are recorded.
    recording: bool,
    /// Where each leaf's bits are counted, when they are ([`leaf_bits`]).
    meter: Option<Meter<'a>>,
    /// The node whose chroma covers its subtree, while the walk may be in it (the stream's).
    subtree: Option<Node>,
    /// The leaf contexts as the walk codes them, followed leaf by leaf: each leaf is chosen
    /// under them ([`choose_leaf`]).
    contexts: Box<Contexts>,
    /// Whether the plan's leaves are written as planned, none chosen in the walk.
    as_planned: bool,
    /// The leaf contexts block by block, when they are recorded ([`write_trial`]).
    local: Option<Box<LocalContexts>>,
}

/// The walk's visitor: splits and codes the leaves as the plan says.
struct PlanVisitor<'a, 'r, 'm> {
    source: PlanSource<'a>,
    record: &'r mut WalkRecord<'m>,
}

impl PlanVisitor<'_, '_, '_> {
    /// The plan's decision for `node`, the next node of the walk: inside the subtree whose
    /// chroma a node above codes, the plan's decisions for such subtrees.
    fn decision(&mut self, node: &Node) -> Option<Decision> {
        let inside = self.record.subtree.is_some_and(|s| {
            node.log2 < s.log2
                && node.x >= s.x
                && node.y >= s.y
                && node.x - s.x < s.size()
                && node.y - s.y < s.size()
        });
        if !inside {
            self.record.subtree = None;
        }
        let local = self.source.local(node, false);
        self.source.plan.decision(self.source.tree, &local, inside)
    }
}

/// A prediction whose coordinates lie `(dx, dy)` from the caller's: the walk's frontier seen
/// from a part of the image analysed on its own.
struct Shifted<'p, P> {
    inner: &'p P,
    dx: u32,
    dy: u32,
}

impl<P: SamplePrediction> SamplePrediction for Shifted<'_, P> {
    fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
        self.inner.beside(above, x + self.dx, y + self.dy)
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

impl TreeVisitor for PlanVisitor<'_, '_, '_> {
    type Error = DecodeError;

    fn split(&mut self, node: &Node) -> bool {
        !matches!(self.decision(node), Some(Decision::Leaf(_)))
    }

    fn chroma_subtree(&mut self, node: &Node) -> bool {
        let source = self.source;
        let local = source.local(node, false);
        let here = source.colour.is_some()
            && source.plan.decision(source.tree, &local, false) == Some(Decision::SplitWithChroma);
        if here {
            self.record.subtree = Some(*node);
        }
        here
    }

    fn prepare_leaf<P: SamplePrediction>(
        &mut self,
        node: &Node,
        prediction: &P,
        leaf: &mut LeafSyntax,
    ) {
        // The contexts after the leaf, when choosing it coded it already.
        let mut after = None;
        if let Some(Decision::Leaf(c)) = self.decision(node) {
            let source = self.source;
            let local = source.local(node, false);
            let na = source.tree.node(&local);
            if let Some(made) = source.plan_leaves.get(&leaf_key(&local, c)) {
                *leaf = *made;
            } else if let Some(na) = na {
                *leaf = na.leaf(usize::from(c), &source.image);
            }
            if let Some(na) = na.filter(|_| !self.record.as_planned) {
                let chosen = Chosen {
                    candidate: usize::from(c),
                    leaf: *leaf,
                };
                let here = LeafPlace {
                    node,
                    local,
                    prediction,
                    contexts: &self.record.contexts,
                };
                let priced = choose_leaf(na, chosen, &here, &source);
                *leaf = priced.leaf;
                after = priced.contexts;
            }
        }
        let contexts = &mut self.record.contexts;
        if let Some(local) = &mut self.record.local {
            local.enter(node, contexts);
        }
        match after {
            Some(after) => *contexts = after,
            None => {
                let mut coded = *leaf;
                // A leaf the syntax cannot code fails the walk too: nothing to follow.
                let _ = code_leaf(
                    &mut BitCounter::default(),
                    contexts,
                    node,
                    prediction,
                    &mut coded,
                );
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
        let source = self.source;
        let record = &mut *self.record;
        if let Some(colour) = source.colour {
            if let Some(pos) = record.replay {
                if let Some(choice) = record.tape.get(pos).copied() {
                    record.replay = Some(pos + 1);
                    *leaf = choice.syntax;
                    record.chroma_bits += choice.bits;
                    return;
                }
                // The tape ran out (it should not): choose from here on, recording nothing.
                record.replay = Some(usize::MAX);
            }
            // The node's errors count `weight` times, as in the analysis: the same choice as
            // its bits counting `1 / weight` times.
            let local = source.local(node, true);
            let weight = source.tree.masking().chroma_weight(&local);
            let shifted = Shifted {
                inner: prediction,
                dx: source.origin.0 / 2,
                dy: source.origin.1 / 2,
            };
            let choice = choose(
                &colour.chroma[plane & 1],
                plane,
                &local,
                &shifted,
                contexts,
                source.plan.lambda / weight,
                source.cache,
            );
            *leaf = choice.syntax;
            record.chroma_bits += choice.bits;
            if record.replay.is_none() && record.recording {
                record.tape.push(choice);
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
        let record = &mut *self.record;
        record.leaves += 1;
        if let Some(meter) = &mut record.meter {
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

/// The leaf the plan chose at a node: its candidate number and syntax.
#[derive(Clone, Copy)]
struct Chosen {
    candidate: usize,
    leaf: LeafSyntax,
}

/// Where the walk codes a leaf: the stream's node, the candidates' node, the pixels beside
/// it, the contexts.
struct LeafPlace<'p, P> {
    node: &'p Node,
    local: Node,
    prediction: &'p P,
    contexts: &'p Contexts,
}

/// A leaf, and the contexts after coding it (none if the syntax cannot code it).
struct PricedLeaf {
    leaf: LeafSyntax,
    contexts: Option<Box<Contexts>>,
}

/// The candidate of `na` within [`CHOICE_REACH`] places of the plan's `chosen` one on the
/// node's rate/distortion hull ([`hull_neighbours`]) of least `sse + lambda * bits` and no more
/// bits than the chosen one, its bits coded at `here` as the walk will code them: under the
/// walk's adapted contexts and predicted from the pixels earlier leaves drew, where the plan
/// priced it under the trial encode's contexts around the node and predicted from the image.
/// A leaf never costs more than the plan's would, so that a plan's stream is never larger for
/// the choice and rate control can still bisect between plans (docs/decisions.md).
fn choose_leaf<P: SamplePrediction>(
    na: &NodeAnalysis,
    chosen: Chosen,
    here: &LeafPlace<P>,
    source: &PlanSource,
) -> PricedLeaf {
    // Its bits, and the contexts after it.
    let coded = |leaf: LeafSyntax| {
        let mut coded = leaf;
        let mut contexts = Box::new(here.contexts.clone());
        let mut counter = BitCounter::default();
        match code_leaf(
            &mut counter,
            &mut contexts,
            here.node,
            here.prediction,
            &mut coded,
        ) {
            Ok(()) => (
                counter.bits(),
                PricedLeaf {
                    leaf,
                    contexts: Some(contexts),
                },
            ),
            Err(_) => (
                f64::INFINITY,
                PricedLeaf {
                    leaf,
                    contexts: None,
                },
            ),
        }
    };
    let lambda = source.plan.lambda;
    let (planned, plan_leaf) = coded(chosen.leaf);
    let mut best = (
        na.candidates[chosen.candidate].sse + lambda * planned,
        plan_leaf,
    );
    for k in hull_neighbours(na, chosen.candidate, CHOICE_REACH) {
        let made = u16::try_from(k)
            .ok()
            .and_then(|c| source.plan_leaves.get(&leaf_key(&here.local, c)).copied());
        let (bits, priced) = coded(made.unwrap_or_else(|| na.leaf(k, &source.image)));
        let j = na.candidates[k].sse + lambda * bits;
        if bits <= planned && j < best.0 {
            best = (j, priced);
        }
    }
    best.1
}

/// How far along a node's hull, in candidates, the walk looks from the plan's choice
/// ([`choose_leaf`]): 2 did as well as the whole hull (docs/decisions.md).
const CHOICE_REACH: usize = 2;

/// The candidates of `na` within `reach` places of candidate `k` in the order of their bits
/// (the node's rate/distortion hull, after the final pruning), `k` left out.
fn hull_neighbours(na: &NodeAnalysis, k: usize, reach: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..na.candidates.len()).collect();
    order.sort_by(|&a, &b| na.candidates[a].bits.total_cmp(&na.candidates[b].bits));
    let at = order.iter().position(|&j| j == k).unwrap_or(0);
    let range = at.saturating_sub(reach)..(at + reach + 1).min(order.len());
    order[range].iter().copied().filter(|&j| j != k).collect()
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
    walk_plan(
        (tree, prediction),
        header,
        plan,
        colour,
        cache,
        WalkMode::Write,
    )
    .map(|t| t.written)
}

/// A trial encode: the stream and the leaf contexts block by block.
pub struct TrialStream {
    /// The stream.
    pub written: Written,
    /// The leaf contexts at the end of each block and of the walk.
    pub local: LocalContexts,
}

/// [`write`] for a trial encode, following the leaf contexts block by block: a grayscale
/// stream (of a colour image, its luma), whatever `header`'s channels.
pub fn write_trial(
    (tree, prediction): (&CandidateTree, &ImagePrediction),
    header: &Header,
    plan: &Plan,
    cache: &ChromaCache,
) -> Result<TrialStream, EncodeError> {
    walk_plan(
        (tree, prediction),
        &Header {
            channels: 1,
            ..*header
        },
        plan,
        None,
        cache,
        WalkMode::Trial,
    )
}

/// [`write`] for a grayscale stream with its leaves as the plan chose them, none chosen in the
/// walk: what [`choose_leaf`] is measured against.
#[cfg(test)]
pub fn write_as_planned(
    (tree, prediction): (&CandidateTree, &ImagePrediction),
    header: &Header,
    plan: &Plan,
    cache: &ChromaCache,
) -> Result<Written, EncodeError> {
    let mode = WalkMode::AsPlanned;
    walk_plan((tree, prediction), header, plan, None, cache, mode).map(|t| t.written)
}

/// What a walk of a plan does besides writing it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum WalkMode {
    /// Chooses each leaf in the walk ([`choose_leaf`]).
    Write,
    /// That, and records the leaf contexts block by block ([`write_trial`]).
    Trial,
    /// Writes the plan's leaves as planned.
    #[cfg(test)]
    AsPlanned,
}

/// [`write`], as `mode` says.
fn walk_plan(
    (tree, prediction): (&CandidateTree, &ImagePrediction),
    header: &Header,
    plan: &Plan,
    colour: Option<&ColourPlanes>,
    cache: &ChromaCache,
    mode: WalkMode,
) -> Result<TrialStream, EncodeError> {
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
    let plan_leaves = plan_leaves(tree, plan, prediction);
    let mut record = WalkRecord {
        replay: tape.as_ref().map(|_| 0),
        tape: tape.unwrap_or_default(),
        recording: true,
        local: (mode == WalkMode::Trial).then(Box::default),
        #[cfg(test)]
        as_planned: mode == WalkMode::AsPlanned,
        ..WalkRecord::default()
    };
    let source = PlanSource {
        tree,
        plan,
        plan_leaves: &plan_leaves,
        image: *prediction,
        colour,
        cache,
        origin: (0, 0),
    };
    let mut visitor = PlanVisitor {
        source,
        record: &mut record,
    };
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
            choices: std::mem::take(&mut record.tape),
        };
        CHROMA_MEMO.with(|m| *m.borrow_mut() = Some(memo));
    }
    let mut local = record.local.take().map(|l| *l).unwrap_or_default();
    local.finish(&record.contexts);
    let written = sealed(header, coder.finish(), state.contexts, &record)?;
    Ok(TrialStream { written, local })
}

/// The stream of `header` with `payload`, the contexts the walk ended with and what it
/// recorded.
fn sealed(
    header: &Header,
    payload: Vec<u8>,
    final_contexts: Contexts,
    record: &WalkRecord,
) -> Result<Written, EncodeError> {
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
        final_contexts,
        leaves: record.leaves,
        chroma_bits: record.chroma_bits,
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
    let plan_leaves = plan_leaves(tree, plan, image);
    let mut record = WalkRecord {
        meter: Some(meter),
        ..WalkRecord::default()
    };
    let mut visitor = PlanVisitor {
        source: PlanSource {
            tree,
            plan,
            plan_leaves: &plan_leaves,
            image: *image,
            colour,
            cache,
            origin: (0, 0),
        },
        record: &mut record,
    };
    let mut coder = MeteredEncoder {
        inner: RangeEncoder::new(),
        total: &total,
    };
    let mut state = Box::new(WalkState::<MAX_STRIPE>::default());
    walk_with(header, &mut coder, &mut visitor, &mut state).map_err(EncodeError::Syntax)?;
    Ok(record.meter.map(|m| m.leaves).unwrap_or_default())
}

/// A part of the image analysed on its own and planned, for [`write_in_parts`].
#[derive(Debug)]
pub struct Part {
    /// Where the part lies in the image (its top-left pixel): its nodes are relative to it.
    pub origin: (u32, u32),
    /// The part's candidates.
    pub tree: CandidateTree,
    /// The part's pixels, cut with the row above them (`Plane::crop`): its candidates'
    /// syntax is made from them.
    pub plane: Plane,
    /// The pixels the part's trial encode drew (`Analysis::drawn`).
    pub drawn: Option<Plane>,
    /// The part's chroma, for a colour stream.
    pub colour: Option<ColourPlanes>,
    /// Chroma options reconstructed so far.
    pub cache: ChromaCache,
    /// The plan of the part's leaves.
    pub plan: Plan,
}

impl Part {
    /// The part as its analysis predicts from it, coded in stripes of `stripe` pixels.
    fn image(&self, stripe: u32) -> ImagePrediction<'_> {
        ImagePrediction::new(&self.plane, stripe).with_drawn(self.drawn.as_ref())
    }

    fn contains(&self, node: &Node) -> bool {
        let (x, y) = self.origin;
        node.x >= x
            && node.y >= y
            && node.x - x < self.plane.width
            && node.y - y < self.plane.height
    }
}

/// Why a walk of parts stopped.
#[derive(Debug)]
enum PartsFailure {
    Syntax(DecodeError),
    /// A part could not be made.
    Part(EncodeError),
}

impl From<DecodeError> for PartsFailure {
    fn from(e: DecodeError) -> Self {
        PartsFailure::Syntax(e)
    }
}

/// The walk's visitor over parts: holds one part at a time, asking for the next as the walk
/// leaves it.
struct PartsVisitor<'n> {
    /// The part the walk is in, with the syntax of its plan's leaves.
    held: Option<(Part, PlanLeaves)>,
    record: WalkRecord<'static>,
    /// Makes the next part from the payload bits written so far.
    next: &'n mut dyn FnMut(f64) -> Result<Part, EncodeError>,
    /// Payload bits written so far.
    total: &'n Cell<f64>,
    /// The stream's stripe width, pixels.
    stripe: u32,
    /// Why the walk must stop, once a part could not be made.
    failed: Option<EncodeError>,
}

impl PartsVisitor<'_> {
    /// Calls `visit` with the visitor of the part holding `node` (the next part, made now, when
    /// the walk has left the one held); `None` once a part could not be made.
    fn in_part<R>(
        &mut self,
        node: &Node,
        visit: impl FnOnce(&mut PlanVisitor<'_, '_, 'static>) -> R,
    ) -> Option<R> {
        if self.failed.is_some() {
            return None;
        }
        if !self.held.as_ref().is_some_and(|(p, _)| p.contains(node)) {
            // One part in memory at a time.
            self.held = None;
            let made = (self.next)(self.total.get()).and_then(|part| {
                if !part.contains(node) {
                    return Err(EncodeError::Internal("parts out of coding order"));
                }
                let leaves = plan_leaves(&part.tree, &part.plan, &part.image(self.stripe));
                Ok((part, leaves))
            });
            match made {
                Ok(held) => self.held = Some(held),
                Err(e) => {
                    self.failed = Some(e);
                    return None;
                }
            }
        }
        let (part, leaves) = self.held.as_ref()?;
        let mut visitor = PlanVisitor {
            source: PlanSource {
                tree: &part.tree,
                plan: &part.plan,
                plan_leaves: leaves,
                image: part.image(self.stripe),
                colour: part.colour.as_ref(),
                cache: &part.cache,
                origin: part.origin,
            },
            record: &mut self.record,
        };
        Some(visit(&mut visitor))
    }
}

impl TreeVisitor for PartsVisitor<'_> {
    type Error = PartsFailure;

    fn split(&mut self, node: &Node) -> bool {
        self.in_part(node, |v| v.split(node)).unwrap_or(false)
    }

    fn chroma_subtree(&mut self, node: &Node) -> bool {
        self.in_part(node, |v| v.chroma_subtree(node))
            .unwrap_or(false)
    }

    fn prepare_leaf<P: SamplePrediction>(
        &mut self,
        node: &Node,
        prediction: &P,
        leaf: &mut LeafSyntax,
    ) {
        self.in_part(node, |v| v.prepare_leaf(node, prediction, leaf));
    }

    fn prepare_chroma<P: SamplePrediction>(
        &mut self,
        node: &Node,
        plane: usize,
        prediction: &P,
        contexts: &ChromaContexts,
        leaf: &mut LeafSyntax,
    ) {
        // The leaf's luma was prepared in the part that holds it.
        let luma = Node {
            x: node.x * 2,
            y: node.y * 2,
            log2: node.log2 + 1,
        };
        self.in_part(&luma, |v| {
            v.prepare_chroma(node, plane, prediction, contexts, leaf)
        });
    }

    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), PartsFailure> {
        match self.in_part(&info.node, |v| v.leaf(info, patch, frontier)) {
            Some(done) => done.map_err(PartsFailure::Syntax),
            None => {
                Err(PartsFailure::Part(self.failed.take().unwrap_or(
                    EncodeError::Internal("a part could not be made"),
                )))
            }
        }
    }
}

/// Writes the stream of `header` part by part, holding one part at a time: `next` makes the
/// part the walk enters next (parts come in coding order: runs of coding tiles), given the
/// payload bits written so far, so that it can plan the part for what is left of a budget.
pub fn write_in_parts(
    header: &Header,
    next: &mut dyn FnMut(f64) -> Result<Part, EncodeError>,
) -> Result<Written, EncodeError> {
    let total = Cell::new(0.0);
    let mut visitor = PartsVisitor {
        held: None,
        record: WalkRecord::default(),
        next,
        total: &total,
        stripe: header.stripe_width(),
        failed: None,
    };
    let mut coder = MeteredEncoder {
        inner: RangeEncoder::new(),
        total: &total,
    };
    let mut state = Box::new(WalkState::<MAX_STRIPE>::default());
    let walked = walk_with(header, &mut coder, &mut visitor, &mut state);
    if let Some(e) = visitor.failed.take() {
        return Err(e);
    }
    match walked {
        Ok(()) => {}
        Err(PartsFailure::Syntax(e)) => return Err(EncodeError::Syntax(e)),
        Err(PartsFailure::Part(e)) => return Err(e),
    }
    drop(visitor.held.take());
    sealed(
        header,
        coder.inner.finish(),
        state.contexts,
        &visitor.record,
    )
}
