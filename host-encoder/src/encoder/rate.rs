//! Rate control: the rates of the candidates, the Lagrangian bottom-up pruning of the quadtree
//! (thesis Alg. 2) and the search for the multiplier that meets a target (thesis III.3.6.3).
//!
//! Rates come from decoder-core's own syntax code run on a [`BitCounter`] whose contexts start
//! from a snapshot of the real coder's state (a leaf's, the contexts a trial encode had at the end
//! of the block around it: [`LocalContexts`]), so the estimate follows the real coder where the
//! leaf is; each target then corrects its aim by the real coder's size.
//!
//! Above [`super::candidates`] (it rates and chooses among them); below [`super::writer`], which
//! writes the [`Plan`]s it makes.

use super::candidates::{Candidate, CandidateTree, ChromaCost, NodeAnalysis, WithCandidates};
use super::plane::ImagePrediction;
use super::quantise::ResidualPrices;
use crate::entropy::BitCounter;
use decoder_core::internal::format::MAX_LEAF_LOG2;
use decoder_core::internal::syntax::{code_leaf, code_split, Contexts, Header, LeafSyntax};
use decoder_core::internal::walk::{node_kind, NodeKind};
use decoder_core::Node;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::{Arc, OnceLock};

/// The rates rate control works with: each candidate carries its bits and its error
/// ([`Candidate::bits`], read in place: copies of them were 12 bytes a candidate in every
/// table), and the table prices the split flags under the same contexts.
#[derive(Debug, Clone)]
pub struct RateTable {
    split_bits: Vec<[f64; 2]>,
}

/// Of `candidates`, the one with the least cost `sse + lambda * bits` (the first of equals).
fn best_leaf(candidates: &[Candidate], lambda: f64) -> Option<LeafChoice> {
    let mut best: Option<LeafChoice> = None;
    for (k, c) in candidates.iter().enumerate() {
        let bits = f64::from(c.bits);
        let j = c.sse + lambda * bits;
        if best.is_none_or(|b| j < b.cost.j) {
            best = Some(LeafChoice {
                cost: Cost {
                    j,
                    sse: c.sse,
                    bits,
                },
                candidate: k as u16,
            });
        }
    }
    best
}

impl RateTable {
    /// An empty table (no node rated).
    pub fn empty() -> RateTable {
        RateTable {
            split_bits: Vec::new(),
        }
    }
}

/// What the optimiser decided for one node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Coded as a leaf with this candidate.
    Leaf(u16),
    /// Split into four.
    Split,
    /// Split into four, the node coding the chroma of its whole subtree (colour): the nodes
    /// below follow [`Plan::subtree_decisions`].
    SplitWithChroma,
}

/// A quadtree cut with one candidate per leaf.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Decisions per level (same layout as the levels of the [`CandidateTree`]).
    pub decisions: Vec<Vec<Decision>>,
    /// Colour: the decisions of nodes inside a subtree whose chroma a node above codes, where
    /// leaves carry no chroma (same layout; never [`Decision::SplitWithChroma`]). Empty for
    /// grayscale.
    pub subtree_decisions: Vec<Vec<Decision>>,
    /// Estimated squared error (exact: leaves are reconstructed independently).
    pub sse: f64,
    /// Estimated payload bits.
    pub bits: f64,
    /// The multiplier it was optimised for.
    pub lambda: f64,
}

/// A known point of the rate/distortion curve (a plan's multiplier and figures): where a
/// multiplier search starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchor {
    /// The multiplier.
    pub lambda: f64,
    /// Estimated payload bits at it.
    pub bits: f64,
    /// Squared error at it.
    pub sse: f64,
}

impl Plan {
    /// This plan as a starting point for searches.
    pub fn anchor(&self) -> Anchor {
        Anchor {
            lambda: self.lambda,
            bits: self.bits,
            sse: self.sse,
        }
    }

    /// The decision for `node` of `tree` (the tree the plan was made for), if it was analysed;
    /// `in_subtree`: the node lies in a subtree whose chroma a node above it codes.
    pub fn decision(
        &self,
        tree: &CandidateTree,
        node: &Node,
        in_subtree: bool,
    ) -> Option<Decision> {
        let level = tree.level(node.log2)?;
        let decisions = if in_subtree {
            &self.subtree_decisions
        } else {
            &self.decisions
        };
        decisions
            .get(usize::from(node.log2 - tree.min_leaf_log2()))?
            .get(level.index(node.x, node.y))
            .copied()
    }
}

/// The Lagrangian cost `j = sse + lambda * bits` of a node's best cut (of the node as a leaf,
/// or of its subtree), with its error and bits.
#[derive(Debug, Clone, Copy)]
struct Cost {
    j: f64,
    sse: f64,
    bits: f64,
}

impl Cost {
    const ZERO: Cost = Cost {
        j: 0.0,
        sse: 0.0,
        bits: 0.0,
    };

    /// A node with no way of coding it.
    const INFINITE: Cost = Cost {
        j: f64::INFINITY,
        sse: f64::INFINITY,
        bits: f64::INFINITY,
    };

    /// This cost with chroma `chroma` (both planes) at its cheapest for `lambda` added.
    fn with_chroma(self, chroma: &ChromaCost, lambda: f64) -> Cost {
        chroma.cheapest(lambda).fold(self, |cost, p| {
            let (sse, bits) = (f64::from(p.sse), f64::from(p.bits));
            cost.plus(Cost {
                j: sse + lambda * bits,
                sse,
                bits,
            })
        })
    }

    /// The costs of two subtrees together.
    fn plus(self, other: Cost) -> Cost {
        Cost {
            j: self.j + other.j,
            sse: self.sse + other.sse,
            bits: self.bits + other.bits,
        }
    }

    /// This cost with a split flag of `flag_bits` bits in front.
    fn with_flag(self, lambda: f64, flag_bits: f64) -> Cost {
        Cost {
            j: self.j + lambda * flag_bits,
            sse: self.sse,
            bits: self.bits + flag_bits,
        }
    }
}

/// A node's best candidate as a leaf.
#[derive(Debug, Clone, Copy)]
struct LeafChoice {
    cost: Cost,
    /// Index into the node's candidate list.
    candidate: u16,
}

impl LeafChoice {
    /// This leaf with its chroma, at its cheapest for `lambda`, added to its cost.
    fn with_chroma(self, chroma: &ChromaCost, lambda: f64) -> LeafChoice {
        let cost = self.cost.with_chroma(chroma, lambda);
        LeafChoice { cost, ..self }
    }
}

/// A node's best cut and its decision, as the image's and inside a subtree whose chroma a node
/// above codes (colour; the same for grayscale).
struct NodeCut {
    cost: Cost,
    decision: Decision,
    luma_cost: Cost,
    luma_decision: Decision,
}

/// What the flag saying whether a split node codes its subtree's chroma is taken to cost
/// (no, yes), in bits: a guess of how rarely a node does, which the stream's adaptive context
/// corrects. (Priced with the trained contexts instead, the streams lost 0 to 0.02 dB.)
const SUBTREE_FLAG_BITS: [f64; 2] = [0.2, 2.5];

/// The best cuts of one level's nodes, row-major: what splitting a node of the level above
/// costs.
struct LevelCosts {
    costs: Vec<Cost>,
    cols: u32,
    rows: u32,
}

impl LevelCosts {
    /// The cost of splitting the node at column `cx`, row `cy` of the level above: its
    /// children's (those in the image) together.
    fn split(&self, cx: u32, cy: u32) -> Cost {
        let mut total = Cost::ZERO;
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (bx, by) = (2 * cx + dx, 2 * cy + dy);
            if bx < self.cols && by < self.rows {
                total = total.plus(self.costs[(by * self.cols + bx) as usize]);
            }
        }
        total
    }
}

/// The better of coding a node of kind `kind` as `leaf` or splitting it at cost `split` (where
/// either is possible), with the split flag's bits `flag` (`[leaf, split]`) where it is coded.
fn decide(
    kind: NodeKind,
    leaf: Option<LeafChoice>,
    split: Option<Cost>,
    lambda: f64,
    flag: &[f64; 2],
) -> (Cost, Decision) {
    match (kind, leaf, split) {
        (NodeKind::ForcedLeaf, Some(l), _) => (l.cost, Decision::Leaf(l.candidate)),
        (NodeKind::Flagged, Some(l), Some(s)) => {
            let as_leaf = l.cost.with_flag(lambda, flag[0]);
            let as_split = s.with_flag(lambda, flag[1]);
            if as_leaf.j <= as_split.j {
                (as_leaf, Decision::Leaf(l.candidate))
            } else {
                (as_split, Decision::Split)
            }
        }
        (_, _, Some(s)) => (s, Decision::Split),
        (_, Some(l), None) => (l.cost, Decision::Leaf(l.candidate)),
        (_, None, None) => (Cost::INFINITE, Decision::Split),
    }
}

impl RateTable {
    /// The rates of the candidates as they stand (each rated from `snapshot`), with the split
    /// flags priced from `snapshot` too.
    pub fn of_contexts(snapshot: &Contexts) -> RateTable {
        let split_bits = (0..=decoder_core::internal::format::MAX_LEAF_LOG2)
            .map(|log2| {
                let mut out = [0.0; 2];
                for (flag, slot) in out.iter_mut().enumerate() {
                    let mut counter = BitCounter::default();
                    let mut ctx = snapshot.clone();
                    let _ = code_split(&mut counter, &mut ctx, log2, &mut (flag == 1));
                    *slot = counter.bits();
                }
                out
            })
            .collect();
        RateTable { split_bits }
    }

    /// The best cut of `tree` (whose candidates this table rates) for multiplier `lambda`
    /// (squared error per bit).
    pub(super) fn optimise(&self, tree: &CandidateTree, header: &Header, lambda: f64) -> Plan {
        let min = tree.min_leaf_log2();
        let colour = header.channels == 3;
        let mut decisions: Vec<Vec<Decision>> = Vec::with_capacity(tree.levels().len());
        let mut subtree_decisions: Vec<Vec<Decision>> = Vec::new();
        let empty = || LevelCosts {
            costs: Vec::new(),
            cols: 0,
            rows: 0,
        };
        // The best cuts of the level below: as the image's (`below`), and inside a subtree
        // whose chroma is coded above, without chroma (`below_luma`, colour only).
        let (mut below, mut below_luma) = (empty(), empty());
        for level in tree.levels() {
            let rows = (u32::from(header.height) + (1 << level.log2) - 1) >> level.log2;
            let flag = &self.split_bits[usize::from(level.log2).min(self.split_bits.len() - 1)];
            // Nodes of a level are independent given the level below.
            let (below_ref, below_luma_ref) = (&below, &below_luma);
            let cut = |i: usize| {
                let i = i as u32;
                let (cx, cy) = (i % level.cols, i / level.cols);
                let node = Node {
                    x: cx << level.log2,
                    y: cy << level.log2,
                    log2: level.log2,
                };
                let kind = node_kind(header, &node);
                let na = level.nodes[i as usize].as_ref();
                let candidates = na.map_or(&[][..], |na| &na.candidates[..]);
                let luma = best_leaf(candidates, lambda);
                let leaf = luma.map(|l| match na {
                    Some(na) => l.with_chroma(&na.chroma, lambda),
                    None => l,
                });
                if !colour {
                    let split = (level.log2 > min).then(|| below_ref.split(cx, cy));
                    let (cost, decision) = decide(kind, leaf, split, lambda, flag);
                    return NodeCut {
                        cost,
                        decision,
                        luma_cost: cost,
                        luma_decision: decision,
                    };
                }
                let split_luma = (level.log2 > min).then(|| below_luma_ref.split(cx, cy));
                let (luma_cost, luma_decision) = decide(kind, luma, split_luma, lambda, flag);
                // A flagged split node outside such subtrees says whether it codes its
                // subtree's chroma: the cheaper of its children's own cuts and its chroma
                // over their cuts without chroma.
                let mut with_chroma = false;
                let split = (level.log2 > min).then(|| {
                    let own = below_ref.split(cx, cy);
                    let (NodeKind::Flagged, Some(na)) = (kind, na) else {
                        return own;
                    };
                    let own = own.with_flag(lambda, SUBTREE_FLAG_BITS[0]);
                    let covered = below_luma_ref
                        .split(cx, cy)
                        .with_chroma(&na.chroma, lambda)
                        .with_flag(lambda, SUBTREE_FLAG_BITS[1]);
                    with_chroma = covered.j < own.j;
                    if with_chroma {
                        covered
                    } else {
                        own
                    }
                });
                let (cost, mut decision) = decide(kind, leaf, split, lambda, flag);
                if decision == Decision::Split && with_chroma {
                    decision = Decision::SplitWithChroma;
                }
                NodeCut {
                    cost,
                    decision,
                    luma_cost,
                    luma_decision,
                }
            };
            // Written in place, level by level: each node's cut goes straight to the arrays
            // the plan and the next level keep. A node is a few nanoseconds of work: they are
            // handed out in chunks.
            let n = (level.cols * rows) as usize;
            let mut costs = vec![Cost::ZERO; n];
            let mut level_decisions = vec![Decision::Split; n];
            if colour {
                let mut luma_costs = vec![Cost::ZERO; n];
                let mut luma_decisions = vec![Decision::Split; n];
                (costs.par_iter_mut().zip(&mut level_decisions))
                    .zip(luma_costs.par_iter_mut().zip(&mut luma_decisions))
                    .enumerate()
                    .with_min_len(1024)
                    .for_each(|(i, ((cost, decision), (luma_cost, luma_decision)))| {
                        let cut = cut(i);
                        (*cost, *decision) = (cut.cost, cut.decision);
                        (*luma_cost, *luma_decision) = (cut.luma_cost, cut.luma_decision);
                    });
                below_luma = LevelCosts {
                    costs: luma_costs,
                    cols: level.cols,
                    rows,
                };
                subtree_decisions.push(luma_decisions);
            } else {
                (costs.par_iter_mut().zip(&mut level_decisions))
                    .enumerate()
                    .with_min_len(1024)
                    .for_each(|(i, (cost, decision))| {
                        let cut = cut(i);
                        (*cost, *decision) = (cut.cost, cut.decision);
                    });
            }
            below = LevelCosts {
                costs,
                cols: level.cols,
                rows,
            };
            decisions.push(level_decisions);
        }
        let root = below.costs.first().copied().unwrap_or(Cost::ZERO);
        Plan {
            decisions,
            subtree_decisions,
            sse: root.sse,
            bits: root.bits,
            lambda,
        }
    }

    /// A plan of roughly `budget_bits` (within about 10% in the multiplier), cheaply: enough
    /// to gather coding statistics.
    pub fn rough_plan_for_bits<T: WithCandidates + ?Sized>(
        &self,
        nodes: &T,
        header: &Header,
        budget_bits: f64,
    ) -> Plan {
        let search = Search::new(Constraint::Rate, budget_bits, 0.1);
        self.search(nodes.candidates(), header, search, None)
    }

    /// The plan with the least distortion whose estimated payload fits in `budget_bits`
    /// (the cheapest plan if none fits). `hint`: a plan near the answer, if known.
    pub fn plan_for_bits<T: WithCandidates + ?Sized>(
        &self,
        nodes: &T,
        header: &Header,
        budget_bits: f64,
        hint: Option<Anchor>,
    ) -> Plan {
        let search = Search::new(Constraint::Rate, budget_bits, 1e-3);
        self.search(nodes.candidates(), header, search, hint)
    }

    /// The cheapest plan whose squared error is at most `max_sse` (the best plan if none is).
    /// `hint`: a plan near the answer, if known.
    pub fn plan_for_sse<T: WithCandidates + ?Sized>(
        &self,
        nodes: &T,
        header: &Header,
        max_sse: f64,
        hint: Option<Anchor>,
    ) -> Plan {
        let search = Search::new(Constraint::Distortion, max_sse, 1e-3);
        self.search(nodes.candidates(), header, search, hint)
    }

    /// Search on the logarithm of the multiplier. Plans get cheaper and worse as it grows, so a
    /// rate constraint holds from some multiplier on (we want the smallest such), and a
    /// distortion constraint holds up to some multiplier (we want the largest). The search
    /// brackets the answer ([`Search::bracket`]), then narrows the bracket
    /// ([`Search::narrow`]).
    fn search(
        &self,
        tree: &CandidateTree,
        header: &Header,
        search: Search,
        hint: Option<Anchor>,
    ) -> Plan {
        let planner = Planner {
            rates: self,
            tree,
            header,
        };
        let bracket = search.bracket(&planner, hint);
        // No answer inside the range: the end nearest to one (the smallest multiplier when even
        // it meets the constraint or misses it, the largest likewise).
        if search.above(&bracket.plan_lo) {
            return bracket.plan_lo;
        }
        if !search.above(&bracket.plan_hi) {
            return bracket.plan_hi;
        }
        search.narrow(&planner, bracket)
    }
}

/// Plans for one tree and header, by the logarithm of their multiplier.
struct Planner<'a> {
    rates: &'a RateTable,
    tree: &'a CandidateTree,
    header: &'a Header,
}

impl Planner<'_> {
    /// The best cut for the multiplier `exp(log_lambda)`.
    fn at(&self, log_lambda: f64) -> Plan {
        self.rates
            .optimise(self.tree, self.header, log_lambda.exp())
    }
}

/// Side (log2) of the smallest blocks whose own contexts price their nodes' leaves
/// ([`LocalContexts`]): 16, 32 and 64 did the same, the 128 tile less (docs/decisions.md).
pub const LOCAL_LOG2: u8 = 6;

/// A block of the image, by its side (log2) and its position in blocks of that side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Block {
    x: u32,
    y: u32,
    log2: u8,
}

impl Block {
    /// The block of side `2^log2` around `node`'s corner.
    fn around(node: &Node, log2: u8) -> Block {
        Block {
            x: node.x >> log2,
            y: node.y >> log2,
            log2,
        }
    }
}

/// Contexts at one point of a trial encode, with the prices of the control residuals under
/// them (made when first asked for: most blocks' are never needed).
#[derive(Debug, Default)]
pub struct PricedContexts {
    /// The contexts.
    pub contexts: Contexts,
    prices: OnceLock<Arc<ResidualPrices>>,
}

impl PricedContexts {
    fn new(contexts: Contexts) -> PricedContexts {
        PricedContexts {
            contexts,
            prices: OnceLock::new(),
        }
    }

    /// The control residuals' bits under these contexts.
    pub fn prices(&self) -> Arc<ResidualPrices> {
        Arc::clone(
            self.prices
                .get_or_init(|| Arc::new(ResidualPrices::under(&self.contexts))),
        )
    }
}

/// The leaf contexts of a walk as they were at the end of every block of `2^LOCAL_LOG2`
/// pixels and of every larger block the walk coded as one or more whole leaves, and at the
/// walk's end. The contexts adapt within a few dozen bits, so the state a stream ends with
/// describes only its last region; a node's leaf is priced from the state after its own block
/// instead (the trial encode's statistics there).
#[derive(Debug, Default)]
pub struct LocalContexts {
    /// At each side (log2), the block the walk is in, if its leaves are no larger than it.
    open: [Option<Block>; MAX_LEAF_LOG2 as usize + 1],
    /// The contexts at the end of each block.
    ends: HashMap<Block, PricedContexts>,
    /// The contexts at the walk's end.
    last: PricedContexts,
}

impl LocalContexts {
    /// Notes that the walk codes a leaf at `node` next, its contexts being `contexts`: closes
    /// the blocks the walk has left.
    pub fn enter(&mut self, node: &Node, contexts: &Contexts) {
        for log2 in LOCAL_LOG2..=MAX_LEAF_LOG2 {
            let block = (log2 >= node.log2).then(|| Block::around(node, log2));
            let open = &mut self.open[usize::from(log2)];
            if *open != block {
                if let Some(left) = std::mem::replace(open, block) {
                    self.ends
                        .insert(left, PricedContexts::new(contexts.clone()));
                }
            }
        }
    }

    /// Closes the blocks still open: the walk is over, its contexts being `contexts`.
    pub fn finish(&mut self, contexts: &Contexts) {
        for open in &mut self.open {
            if let Some(left) = open.take() {
                self.ends
                    .insert(left, PricedContexts::new(contexts.clone()));
            }
        }
        self.last = PricedContexts::new(contexts.clone());
    }

    /// The contexts at the end of the smallest block around `node` that the walk coded in
    /// leaves no larger than it, or else at the walk's end.
    pub fn around(&self, node: &Node) -> &PricedContexts {
        (LOCAL_LOG2.max(node.log2)..=MAX_LEAF_LOG2)
            .find_map(|log2| self.ends.get(&Block::around(node, log2)))
            .unwrap_or(&self.last)
    }
}

/// Rates every candidate of `na` (whose syntax is made again from the image `prediction`
/// predicts from) from the context state `snapshot` (frozen: every candidate is priced from
/// the same state), predicting from the pixels a trial encode drew where `prediction` knows
/// them ([`ImagePrediction::drawn`]): infinite bits for a candidate the syntax cannot code.
pub fn rate_node(na: &mut NodeAnalysis, prediction: &ImagePrediction, snapshot: &Contexts) {
    let mut ctx = snapshot.clone();
    let leaves = na.leaves(prediction);
    let drawn = prediction.drawn();
    for (c, leaf) in na.candidates.iter_mut().zip(&leaves) {
        c.bits = leaf_bits(&na.node, leaf, &drawn, &mut ctx);
    }
}

/// The bits of `leaf` at `node`, coded from the context state `ctx` (left as it is); infinite
/// if the syntax cannot code it.
pub fn leaf_bits(
    node: &Node,
    leaf: &LeafSyntax,
    prediction: &ImagePrediction,
    ctx: &mut Contexts,
) -> f32 {
    let mut leaf = *leaf;
    let mut counter = BitCounter::frozen();
    match code_leaf(&mut counter, ctx, node, prediction, &mut leaf) {
        Ok(()) => counter.bits() as f32,
        Err(_) => f32::INFINITY,
    }
}

/// The candidates of `na` that are its best leaf for some multiplier in `lambdas`: their
/// indices, ascending.
pub fn node_hull(na: &NodeAnalysis, lambdas: &std::ops::RangeInclusive<f64>) -> Vec<u16> {
    let points: Vec<(f64, f64)> = (na.candidates.iter())
        .map(|c| (f64::from(c.bits), c.sse))
        .collect();
    lower_hull_in(&points, lambdas)
}

/// Keeps of the candidates of `na` those [`node_hull`] lists: what no multiplier wants is
/// never stored.
pub fn prune_node(na: &mut NodeAnalysis, lambdas: &std::ops::RangeInclusive<f64>) {
    let keep = node_hull(na, lambdas);
    na.retain(&keep);
}

/// The lower convex hull of rate/error points `(bits, sse)` added one at a time: the vertices,
/// by rising bits and falling error. Tells whether a point could still minimise `sse + lambda *
/// bits` for some positive `lambda` among all points added so far.
#[derive(Debug, Default)]
pub struct GrowingHull {
    vertices: Vec<(f64, f64)>,
}

impl GrowingHull {
    /// Adds point `p` (a point the hull covers changes nothing).
    pub fn add(&mut self, p: (f64, f64)) {
        if !(p.0.is_finite() && p.1.is_finite()) || self.covers(p) {
            return;
        }
        let at = self.vertices.partition_point(|v| v.0 < p.0);
        self.vertices.insert(at, p);
        // Vertices with as many bits and no less error are dominated.
        let v = &mut self.vertices;
        let mut end = at + 1;
        while end < v.len() && v[end].1 >= p.1 {
            end += 1;
        }
        v.drain(at + 1..end);
        // Neighbours no longer convex: on or above the segment through their neighbours.
        let mut at = at;
        while at >= 2 && on_or_above(v[at - 2], v[at - 1], v[at]) {
            v.remove(at - 1);
            at -= 1;
        }
        while at + 2 < v.len() && on_or_above(v[at], v[at + 1], v[at + 2]) {
            v.remove(at + 1);
        }
    }

    /// The hull's vertices, by rising bits and falling error.
    pub fn vertices(&self) -> &[(f64, f64)] {
        &self.vertices
    }

    /// Whether point `p` lies on or above the hull: no positive multiplier prefers it to the
    /// points added so far (nor to any added later, which only lower the hull).
    pub fn covers(&self, p: (f64, f64)) -> bool {
        let v = &self.vertices;
        let at = v.partition_point(|q| q.0 <= p.0);
        if at == 0 {
            // Fewer bits than every vertex.
            return false;
        }
        let a = v[at - 1];
        if a.1 <= p.1 {
            return true;
        }
        v.get(at).is_some_and(|&b| on_or_above(a, p, b))
    }
}

/// Whether point `b` lies on or above the segment from `a` to `c` (`a.0 <= b.0 <= c.0`).
fn on_or_above(a: (f64, f64), b: (f64, f64), c: (f64, f64)) -> bool {
    (b.1 - a.1) * (c.0 - a.0) >= (c.1 - a.1) * (b.0 - a.0)
}

/// Indices of the points `(bits, sse)` that minimise `sse + lambda * bits` for some `lambda` in
/// `lambdas`: the vertices of the lower convex hull whose range of multipliers meets it.
fn lower_hull_in(points: &[(f64, f64)], lambdas: &std::ops::RangeInclusive<f64>) -> Vec<u16> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&k| points[k].0.is_finite() && points[k].1.is_finite())
        .collect();
    // By rate, then error: among equal rates only the least error can be on the hull.
    order.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    });
    order.dedup_by(|b, a| points[*a].0 == points[*b].0);
    // Monotone chain, keeping only strictly decreasing error (the lower-left hull).
    let mut hull: Vec<usize> = Vec::new();
    for k in order {
        let p = points[k];
        if hull.last().is_some_and(|&h| points[h].1 <= p.1) {
            continue;
        }
        while hull.len() >= 2 {
            let (a, b) = (points[hull[hull.len() - 2]], points[hull[hull.len() - 1]]);
            // b is on or above the segment a-p: not a vertex.
            if on_or_above(a, b, p) {
                hull.pop();
            } else {
                break;
            }
        }
        hull.push(k);
    }
    // Vertex j is optimal for multipliers between the slopes of its two edges.
    let slope = |a: usize, b: usize| (points[a].1 - points[b].1) / (points[b].0 - points[a].0);
    let mut keep: Vec<u16> = (0..hull.len())
        .filter(|&j| {
            let hi = if j == 0 {
                f64::INFINITY
            } else {
                slope(hull[j - 1], hull[j])
            };
            let lo = if j + 1 == hull.len() {
                0.0
            } else {
                slope(hull[j], hull[j + 1])
            };
            lo <= *lambdas.end() && hi >= *lambdas.start()
        })
        .map(|j| hull[j] as u16)
        .collect();
    keep.sort_unstable();
    keep
}

/// What a multiplier search looks for: the plan whose `constraint` quantity is at most
/// `limit`, down to `tolerance` in the log of the multiplier or relative to `limit`.
#[derive(Debug, Clone, Copy)]
struct Search {
    constraint: Constraint,
    limit: f64,
    tolerance: f64,
}

/// Half the width of the first bracket around a hint's guess, at most (in the logarithm of
/// the multiplier).
const FIRST_HALF_WIDTH: f64 = 0.1;

/// The multipliers searched (squared error per bit).
const LAMBDA_RANGE: std::ops::RangeInclusive<f64> = 1e-4..=1e9;

/// The quantity a search constrains.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Constraint {
    /// The estimated payload bits.
    Rate,
    /// The squared error.
    Distortion,
}

/// Two plans whose multipliers (by their logarithms `lo < hi`) bracket a search's answer.
struct Bracket {
    lo: f64,
    hi: f64,
    plan_lo: Plan,
    plan_hi: Plan,
}

impl Search {
    fn new(constraint: Constraint, limit: f64, tolerance: f64) -> Search {
        Search {
            constraint,
            limit,
            tolerance,
        }
    }

    /// The constrained quantity of `plan`.
    fn measure(&self, plan: &Plan) -> f64 {
        match self.constraint {
            Constraint::Rate => plan.bits,
            Constraint::Distortion => plan.sse,
        }
    }

    /// Whether `plan` meets the constraint.
    fn meets(&self, plan: &Plan) -> bool {
        self.measure(plan) <= self.limit
    }

    /// Whether `plan` lies above the answer's multiplier.
    fn above(&self, plan: &Plan) -> bool {
        matches!(
            (self.constraint, self.meets(plan)),
            (Constraint::Rate, true) | (Constraint::Distortion, false)
        )
    }

    /// The logarithm of the constrained quantity of `plan` (only its differences matter).
    fn log_measure(&self, plan: &Plan) -> f64 {
        self.measure(plan).max(1e-9).ln()
    }

    /// The logarithms of the ends of [`LAMBDA_RANGE`].
    fn log_range() -> (f64, f64) {
        (LAMBDA_RANGE.start().ln(), LAMBDA_RANGE.end().ln())
    }

    /// The first bracket to try: around where `hint` says the answer is, or the whole range.
    fn first_bracket(&self, hint: Option<Anchor>) -> (f64, f64) {
        let (floor, ceiling) = Search::log_range();
        match hint {
            Some(a) if a.lambda > 0.0 => {
                // Locally, ln(rate) falls and ln(error) rises by about as much as ln(lambda)
                // rises: a first guess, the bracket widens when it is off.
                let (known, slope) = match self.constraint {
                    Constraint::Rate => (a.bits, -1.0),
                    Constraint::Distortion => (a.sse, 1.0),
                };
                let step = (self.limit.max(1e-9).ln() - known.max(1e-9).ln()) / slope;
                let c = (a.lambda.ln() + step).clamp(floor, ceiling);
                // A few times as wide as the step from the hint: a budget's later passes
                // move the aim by a fraction of a percent.
                let half = (4.0 * step.abs()).clamp(self.tolerance, FIRST_HALF_WIDTH);
                ((c - half).max(floor), (c + half).min(ceiling))
            }
            _ => (floor, ceiling),
        }
    }

    /// A bracket of the answer: the first one ([`Search::first_bracket`]), moved and widened
    /// (by its width, then twice as much each time) until it holds the answer or reaches an
    /// end of the range.
    fn bracket(&self, planner: &Planner, hint: Option<Anchor>) -> Bracket {
        let (floor, ceiling) = Search::log_range();
        let (mut lo, mut hi) = self.first_bracket(hint);
        let mut plan_lo = planner.at(lo);
        let mut plan_hi = planner.at(hi);
        let mut widen = hi - lo;
        loop {
            if self.above(&plan_lo) && lo > floor {
                (hi, plan_hi) = (lo, plan_lo);
                lo = (lo - widen).max(floor);
                plan_lo = planner.at(lo);
            } else if !self.above(&plan_hi) && hi < ceiling {
                (lo, plan_lo) = (hi, plan_hi);
                hi = (hi + widen).min(ceiling);
                plan_hi = planner.at(hi);
            } else {
                break;
            }
            widen *= 2.0;
        }
        Bracket {
            lo,
            hi,
            plan_lo,
            plan_hi,
        }
    }

    /// Narrows `bracket` (which holds the answer) down to the tolerance and returns the best
    /// plan that meets the constraint. Interpolates in log-log, where the constrained quantity
    /// is close to a straight line ([`FalsePosition`]).
    fn narrow(&self, planner: &Planner, bracket: Bracket) -> Plan {
        let Bracket {
            lo,
            hi,
            plan_lo,
            plan_hi,
        } = bracket;
        let mut steps = FalsePosition {
            lo,
            hi,
            f_lo: self.log_measure(&plan_lo),
            f_hi: self.log_measure(&plan_hi),
            target: self.limit.max(1e-9).ln(),
            kept: None,
            bisect_next: false,
        };
        // The end that meets the constraint.
        let mut best = match self.constraint {
            Constraint::Rate => plan_hi,
            Constraint::Distortion => plan_lo,
        };
        // Down to `tolerance` in the log of the multiplier (1e-3: 0.1%; the plans between two
        // multipliers that close differ by a few leaves at most), or in the constrained
        // quantity.
        while steps.hi - steps.lo > self.tolerance {
            let mid = steps.next();
            let p = planner.at(mid);
            let good = self.meets(&p);
            steps.update(mid, self.log_measure(&p), self.above(&p));
            if good {
                // Close enough in the constrained quantity too: no multiplier in between
                // can do better by more than the tolerance.
                let done = self.measure(&p) >= self.limit * (1.0 - self.tolerance);
                best = p;
                if done {
                    break;
                }
            }
        }
        best
    }
}

/// The state of false position (Illinois variant) on the logarithms of the multiplier and of
/// the constrained quantity: a bracket `lo..hi` with the quantity's logarithm at its ends. A
/// step that fails to halve the bracket is followed by a bisection, which bounds the search by
/// twice bisection's.
struct FalsePosition {
    lo: f64,
    hi: f64,
    f_lo: f64,
    f_hi: f64,
    /// The logarithm of the limit.
    target: f64,
    /// Which end the last interpolation replaced (true: the upper; for the Illinois halving).
    kept: Option<bool>,
    /// Whether the next step must bisect.
    bisect_next: bool,
}

impl FalsePosition {
    /// The next multiplier to try (its logarithm), strictly inside the bracket.
    fn next(&self) -> f64 {
        let (lo, hi) = (self.lo, self.hi);
        if self.bisect_next || !(self.f_lo - self.f_hi).is_normal() {
            0.5 * (lo + hi)
        } else {
            let t = (self.f_lo - self.target) / (self.f_lo - self.f_hi);
            // Strictly inside, so that the bracket always shrinks.
            lo + (hi - lo) * t.clamp(0.02, 0.98)
        }
    }

    /// Takes the result of trying `mid`: the quantity's logarithm `f` there, and whether `mid`
    /// lies above the answer (and so replaces the upper end).
    fn update(&mut self, mid: f64, f: f64, moves_hi: bool) {
        let width = self.hi - self.lo;
        if moves_hi {
            (self.hi, self.f_hi) = (mid, f);
        } else {
            (self.lo, self.f_lo) = (mid, f);
        }
        if !self.bisect_next {
            // The same end kept by two interpolations in a row: pull its value halfway
            // to the target (Illinois), or false position creeps up on one side.
            if self.kept == Some(moves_hi) {
                if moves_hi {
                    self.f_lo = self.target + 0.5 * (self.f_lo - self.target);
                } else {
                    self.f_hi = self.target + 0.5 * (self.f_hi - self.target);
                }
            }
            self.kept = Some(moves_hi);
        }
        self.bisect_next = !self.bisect_next && self.hi - self.lo > 0.5 * width;
    }
}

#[cfg(test)]
mod tests {
    use super::{lower_hull_in, Anchor, Constraint, GrowingHull, Search};

    /// Numbers in [0, 1) from a linear congruential generator started at `seed`.
    fn uniform(mut seed: u32) -> impl FnMut() -> f64 {
        move || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            f64::from(seed >> 8) / f64::from(1u32 << 24)
        }
    }

    /// `count` points `(bits, sse)` of whole numbers from 0 to `bits` and `sse`, from `next`.
    fn random_points(
        next: &mut impl FnMut() -> f64,
        count: usize,
        bits: f64,
        sse: f64,
    ) -> Vec<(f64, f64)> {
        (0..count)
            .map(|_| ((next() * bits).round(), (next() * sse).round()))
            .collect()
    }

    /// Added one at a time in any order, points leave the hull of them all, which covers them
    /// all and nothing below its vertices.
    #[test]
    fn growing_hull_is_the_hull_of_its_points() {
        let mut next = uniform(777);
        for _ in 0..500 {
            let points = random_points(&mut next, 15, 30.0, 500.0);
            let mut hull = GrowingHull::default();
            points.iter().for_each(|&p| hull.add(p));
            let mut expected: Vec<(f64, f64)> = lower_hull_in(&points, &(0.0..=f64::INFINITY))
                .iter()
                .map(|&k| points[usize::from(k)])
                .collect();
            expected.sort_by(|a, b| a.0.total_cmp(&b.0));
            assert_eq!(hull.vertices, expected, "{points:?}");
            // Every point added is on or above it; a little less error at a vertex is below.
            for &p in &points {
                assert!(hull.covers(p), "{p:?} of {points:?}");
            }
            for &(bits, sse) in &expected {
                assert!(
                    !hull.covers((bits, sse - 0.5)),
                    "{bits} {sse} of {points:?}"
                );
            }
        }
    }

    /// The hull keeps exactly the points that are best for some multiplier in the range, as a
    /// dense sweep of multipliers finds them.
    #[test]
    fn hull_matches_a_sweep_of_multipliers() {
        let mut next = uniform(12345);
        for _ in 0..200 {
            let points = random_points(&mut next, 12, 40.0, 1000.0);
            let range = 0.5..=200.0;
            let hull = lower_hull_in(&points, &range);
            let mut swept: Vec<u16> = (0..4000)
                .map(|i| 0.5 * (400f64).powf(f64::from(i) / 3999.0))
                .map(|l| {
                    let j = |k: usize| points[k].1 + l * points[k].0;
                    (0..points.len())
                        .min_by(|&a, &b| {
                            j(a).total_cmp(&j(b))
                                .then(points[a].0.total_cmp(&points[b].0))
                        })
                        .unwrap() as u16
                })
                .collect();
            swept.sort_unstable();
            swept.dedup();
            // Every swept optimum is on the hull (up to ties between equal points).
            for s in &swept {
                assert!(
                    hull.iter()
                        .any(|&h| points[usize::from(h)] == points[usize::from(*s)]),
                    "{points:?}: {s} missing from {hull:?}"
                );
            }
        }
    }

    /// A search hinted by a plan near its answer starts from a bracket a few times as wide as
    /// the step the hint implies, around the guess; a far hint from one of fixed width.
    #[test]
    fn a_near_hint_gives_a_narrow_first_bracket() {
        let hint = Anchor {
            lambda: 800.0,
            bits: 100_000.0,
            sse: 1e6,
        };
        let search = Search::new(Constraint::Rate, 99_900.0, 1e-3);
        let (lo, hi) = search.first_bracket(Some(hint));
        // ln(rate) falls as ln(lambda) rises: the guess is ln(800) + ln(100000 / 99900).
        let guess = 800f64.ln() + (100_000f64 / 99_900.0).ln();
        assert!(lo < guess && guess < hi);
        assert!((hi - lo - 8.0 * (100_000f64 / 99_900.0).ln()).abs() < 1e-12);
        // Nearly on the answer: no narrower than the tolerance either way.
        let (lo, hi) = Search::new(Constraint::Rate, 100_000.0, 1e-3).first_bracket(Some(hint));
        assert!((hi - lo - 2e-3).abs() < 1e-12);
        // Far: at most 0.2 wide.
        let (lo, hi) = Search::new(Constraint::Rate, 50_000.0, 1e-3).first_bracket(Some(hint));
        assert!((hi - lo - 0.2).abs() < 1e-12);
        assert!(((lo + hi) / 2.0 - (800f64.ln() + 2f64.ln())).abs() < 1e-12);
    }
}
