//! Rate control: Lagrangian bottom-up pruning of the quadtree (thesis Alg. 2) and the search for
//! the multiplier that meets a target (thesis III.3.6.3).
//!
//! Rates come from decoder-core's own syntax code run on a [`BitCounter`] whose contexts start
//! from a snapshot of the real coder's state (the contexts a trial encode ended with), so the
//! estimate follows the real coder; each target then corrects its aim by the real coder's size.

use super::analysis::Analysis;
use crate::entropy::BitCounter;
use decoder_core::internal::syntax::control::WeightQuantiser;
use decoder_core::internal::syntax::control::WEIGHT_QUANTISER_KINDS;
use decoder_core::internal::syntax::{code_leaf, code_split, Contexts, Header};
use decoder_core::internal::walk::{node_kind, NodeKind};
use decoder_core::Node;
use rayon::prelude::*;

/// Per-candidate rates (bits) under one context snapshot, with the candidates' errors, laid
/// out flat per level so that the optimiser's inner loop reads three contiguous arrays.
#[derive(Debug, Clone)]
pub struct RateTable {
    levels: Vec<LevelRates>,
    split_bits: Vec<[f64; 2]>,
}

/// The candidates of one level's nodes: node `i`'s are `first[i]..first[i + 1]`, in the order
/// of its candidate list.
#[derive(Debug, Clone, Default)]
struct LevelRates {
    first: Vec<u32>,
    bits: Vec<f32>,
    sse: Vec<f64>,
    /// Whether the candidate needs the Lloyd-Max codebooks.
    codebook: Vec<bool>,
}

impl LevelRates {
    fn range(&self, node: usize) -> std::ops::Range<usize> {
        self.first[node] as usize..self.first[node + 1] as usize
    }

    /// The level's candidates `keep` lists per node (indices into each node's list).
    fn select(&self, keep: &[Vec<u16>]) -> LevelRates {
        let mut out = LevelRates {
            first: vec![0],
            ..LevelRates::default()
        };
        for (i, keep) in keep.iter().enumerate() {
            let start = self.first[i] as usize;
            for &ci in keep {
                let k = start + usize::from(ci);
                out.bits.push(self.bits[k]);
                out.sse.push(self.sse[k]);
                out.codebook.push(self.codebook[k]);
            }
            out.first.push(out.bits.len() as u32);
        }
        out
    }
}

impl RateTable {
    /// An empty table (no node rated).
    pub fn empty() -> RateTable {
        RateTable {
            levels: Vec::new(),
            split_bits: Vec::new(),
        }
    }

    /// This table restricted to the candidates `keep` lists per node (as
    /// [`RateTable::lambda_optimal`] returns them), for the candidate lists pruned to them.
    pub fn select(&self, keep: &[Vec<Vec<u16>>]) -> RateTable {
        RateTable {
            levels: self
                .levels
                .iter()
                .zip(keep)
                .map(|(level, keep)| level.select(keep))
                .collect(),
            split_bits: self.split_bits.clone(),
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
}

/// A quadtree cut with one candidate per leaf.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Decisions per level (same layout as the analysis levels).
    pub decisions: Vec<Vec<Decision>>,
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

    /// The decision for `node`, if it was analysed.
    pub fn decision(&self, analysis: &Analysis, node: &Node) -> Option<Decision> {
        let level = analysis.level(node.log2)?;
        let i = (node.y >> node.log2) * level.cols + (node.x >> node.log2);
        self.decisions
            .get(usize::from(node.log2 - analysis.header.min_leaf_log2))?
            .get(i as usize)
            .copied()
    }
}

impl RateTable {
    /// Rates of every candidate, coded from the context state `snapshot`.
    pub fn new(analysis: &Analysis, snapshot: &Contexts) -> RateTable {
        let levels = analysis
            .levels
            .iter()
            .map(|level| {
                let per_node: Vec<Vec<f32>> = level
                    .nodes
                    .par_iter()
                    .map(|na| {
                        let Some(na) = na else { return Vec::new() };
                        let prediction = super::analysis::ImagePrediction {
                            plane: &analysis.plane,
                        };
                        // Frozen counters leave the contexts alone: one copy per node.
                        let mut ctx = snapshot.clone();
                        na.candidates
                            .iter()
                            .map(|c| {
                                let mut leaf = na.leaf(c);
                                let mut counter = BitCounter::frozen();
                                match code_leaf(
                                    &mut counter,
                                    &mut ctx,
                                    &na.node,
                                    &prediction,
                                    &mut leaf,
                                ) {
                                    Ok(()) => counter.bits() as f32,
                                    Err(_) => f32::INFINITY,
                                }
                            })
                            .collect()
                    })
                    .collect();
                let mut rates = LevelRates {
                    first: vec![0],
                    ..LevelRates::default()
                };
                for (na, bits) in level.nodes.iter().zip(per_node) {
                    if let Some(na) = na {
                        rates.bits.extend_from_slice(&bits);
                        for c in &na.candidates {
                            rates.sse.push(c.sse);
                            rates.codebook.push(
                                WEIGHT_QUANTISER_KINDS[usize::from(c.wq)]
                                    == WeightQuantiser::Codebook,
                            );
                        }
                    }
                    rates.first.push(rates.bits.len() as u32);
                }
                rates
            })
            .collect();
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
        RateTable { levels, split_bits }
    }

    /// For every analysed node, the candidates that are the node's best leaf for some
    /// multiplier in `lambdas` (indices into its candidate list, ascending): the vertices of
    /// the lower convex hull of its (rate, error) points whose multipliers meet the range.
    /// With `layers` above one, also those of the hulls of what is left, layer by layer
    /// (candidates that come close to being best).
    pub fn lambda_optimal(
        &self,
        analysis: &Analysis,
        lambdas: std::ops::RangeInclusive<f64>,
        layers: usize,
    ) -> Vec<Vec<Vec<u16>>> {
        analysis
            .levels
            .iter()
            .enumerate()
            .map(|(li, level)| {
                level
                    .nodes
                    .par_iter()
                    .enumerate()
                    .map(|(i, na)| {
                        if na.is_none() {
                            return Vec::new();
                        }
                        let rates = &self.levels[li];
                        let mut points: Vec<(f64, f64)> = rates
                            .range(i)
                            .map(|k| (f64::from(rates.bits[k]), rates.sse[k]))
                            .collect();
                        let mut keep = Vec::new();
                        for _ in 0..layers {
                            let layer = lower_hull_in(&points, &lambdas);
                            for &k in &layer {
                                // Out of the next layer's way.
                                points[usize::from(k)] = (f64::INFINITY, f64::INFINITY);
                            }
                            keep.extend(layer);
                        }
                        keep.sort_unstable();
                        keep
                    })
                    .collect()
            })
            .collect()
    }

    /// The best cut for multiplier `lambda` (squared error per bit). Candidates using the
    /// Lloyd-Max codebooks are allowed only when `header` carries them.
    pub fn optimise(&self, analysis: &Analysis, header: &Header, lambda: f64) -> Plan {
        let min = analysis.header.min_leaf_log2;
        let mut decisions: Vec<Vec<Decision>> = Vec::with_capacity(analysis.levels.len());
        // (J, sse, bits) per node of the level below.
        let mut below: Vec<(f64, f64, f64)> = Vec::new();
        let mut below_cols = 0u32;
        let mut below_rows = 0u32;
        for (li, level) in analysis.levels.iter().enumerate() {
            let rows = (u32::from(header.height) + (1 << level.log2) - 1) >> level.log2;
            // Nodes of a level are independent given the level below.
            let below_ref = &below;
            let rates = &self.levels[li];
            let codebooks = header.has_codebooks();
            let (here, dec): (Vec<(f64, f64, f64)>, Vec<Decision>) = (0..level.cols * rows)
                .into_par_iter()
                // A node is a few nanoseconds of work: hand them out in chunks.
                .with_min_len(1024)
                .map(|i| {
                    let (cx, cy) = (i % level.cols, i / level.cols);
                    let node = Node {
                        x: cx << level.log2,
                        y: cy << level.log2,
                        log2: level.log2,
                    };
                    let kind = node_kind(header, &node);
                    let leaf = {
                        let range = rates.range(i as usize);
                        let start = range.start;
                        let mut best: Option<(f64, f64, f64, u16)> = None;
                        for k in range {
                            if rates.codebook[k] && !codebooks {
                                continue;
                            }
                            let bits = f64::from(rates.bits[k]);
                            let j = rates.sse[k] + lambda * bits;
                            if best.is_none_or(|b| j < b.0) {
                                best = Some((j, rates.sse[k], bits, (k - start) as u16));
                            }
                        }
                        best
                    };
                    let split = (level.log2 > min).then(|| {
                        let mut acc = (0.0, 0.0, 0.0);
                        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            let (bx, by) = (2 * cx + dx, 2 * cy + dy);
                            if bx < below_cols && by < below_rows {
                                let b = below_ref[(by * below_cols + bx) as usize];
                                acc = (acc.0 + b.0, acc.1 + b.1, acc.2 + b.2);
                            }
                        }
                        acc
                    });
                    let flag =
                        &self.split_bits[usize::from(level.log2).min(self.split_bits.len() - 1)];
                    match (kind, leaf, split) {
                        (NodeKind::ForcedLeaf, Some(l), _) => {
                            ((l.0, l.1, l.2), Decision::Leaf(l.3))
                        }
                        (NodeKind::Flagged, Some(l), Some(s)) => {
                            let jl = l.0 + lambda * flag[0];
                            let js = s.0 + lambda * flag[1];
                            if jl <= js {
                                ((jl, l.1, l.2 + flag[0]), Decision::Leaf(l.3))
                            } else {
                                ((js, s.1, s.2 + flag[1]), Decision::Split)
                            }
                        }
                        (_, _, Some(s)) => (s, Decision::Split),
                        (_, Some(l), None) => ((l.0, l.1, l.2), Decision::Leaf(l.3)),
                        (_, None, None) => (
                            (f64::INFINITY, f64::INFINITY, f64::INFINITY),
                            Decision::Split,
                        ),
                    }
                })
                .unzip();
            below = here;
            below_cols = level.cols;
            below_rows = rows;
            decisions.push(dec);
        }
        let root = below.first().copied().unwrap_or((0.0, 0.0, 0.0));
        Plan {
            decisions,
            sse: root.1,
            bits: root.2,
            lambda,
        }
    }

    /// A plan of roughly `budget_bits` (within about 10% in the multiplier), cheaply: enough
    /// to gather coding statistics.
    pub fn rough_plan_for_bits(
        &self,
        analysis: &Analysis,
        header: &Header,
        budget_bits: f64,
    ) -> Plan {
        let search = Search::new(Constraint::Rate, budget_bits, 0.1);
        self.search(analysis, header, search, None)
    }

    /// The plan with the least distortion whose estimated payload fits in `budget_bits`
    /// (the cheapest plan if none fits). `hint`: a plan near the answer, if known.
    pub fn plan_for_bits(
        &self,
        analysis: &Analysis,
        header: &Header,
        budget_bits: f64,
        hint: Option<Anchor>,
    ) -> Plan {
        let search = Search::new(Constraint::Rate, budget_bits, 1e-3);
        self.search(analysis, header, search, hint)
    }

    /// The cheapest plan whose squared error is at most `max_sse` (the best plan if none is).
    /// `hint`: a plan near the answer, if known.
    pub fn plan_for_sse(
        &self,
        analysis: &Analysis,
        header: &Header,
        max_sse: f64,
        hint: Option<Anchor>,
    ) -> Plan {
        let search = Search::new(Constraint::Distortion, max_sse, 1e-3);
        self.search(analysis, header, search, hint)
    }

    /// Search on the logarithm of the multiplier. Plans get cheaper and worse as it grows, so a
    /// rate constraint holds from some multiplier on (we want the smallest such), and a
    /// distortion constraint holds up to some multiplier (we want the largest). The search
    /// brackets the answer (around `hint` when there is one, widening as needed), then
    /// interpolates in log-log, where the constrained quantity is close to a straight line
    /// (false position, Illinois variant); a step that fails to halve the bracket is followed
    /// by a bisection, which bounds the search by twice bisection's.
    fn search(
        &self,
        analysis: &Analysis,
        header: &Header,
        search: Search,
        hint: Option<Anchor>,
    ) -> Plan {
        let Search {
            constraint,
            limit,
            tolerance,
        } = search;
        let measure = |p: &Plan| match constraint {
            Constraint::Rate => p.bits,
            Constraint::Distortion => p.sse,
        };
        let ok = |p: &Plan| measure(p) <= limit;
        // Whether a plan lies above the answer's multiplier.
        let above = |p: &Plan| {
            matches!(
                (constraint, ok(p)),
                (Constraint::Rate, true) | (Constraint::Distortion, false)
            )
        };
        let (floor, ceiling) = (LAMBDA_RANGE.start().ln(), LAMBDA_RANGE.end().ln());
        let (mut lo, mut hi) = match hint {
            Some(a) if a.lambda > 0.0 => {
                // Locally, ln(rate) falls and ln(error) rises by about as much as ln(lambda)
                // rises: a first guess, the bracket widens when it is off.
                let (known, slope) = match constraint {
                    Constraint::Rate => (a.bits, -1.0),
                    Constraint::Distortion => (a.sse, 1.0),
                };
                let guess = a.lambda.ln() + (limit.max(1e-9).ln() - known.max(1e-9).ln()) / slope;
                let c = guess.clamp(floor, ceiling);
                ((c - 0.1).max(floor), (c + 0.1).min(ceiling))
            }
            _ => (floor, ceiling),
        };
        let mut plan_lo = self.optimise(analysis, header, lo.exp());
        let mut plan_hi = self.optimise(analysis, header, hi.exp());
        let mut widen = 0.2;
        loop {
            if above(&plan_lo) && lo > floor {
                (hi, plan_hi) = (lo, plan_lo);
                lo = (lo - widen).max(floor);
                plan_lo = self.optimise(analysis, header, lo.exp());
            } else if !above(&plan_hi) && hi < ceiling {
                (lo, plan_lo) = (hi, plan_hi);
                hi = (hi + widen).min(ceiling);
                plan_hi = self.optimise(analysis, header, hi.exp());
            } else {
                break;
            }
            widen *= 2.0;
        }
        // No answer inside the range: the end nearest to one (the smallest multiplier when even
        // it meets the constraint or misses it, the largest likewise).
        if above(&plan_lo) {
            return plan_lo;
        }
        if !above(&plan_hi) {
            return plan_hi;
        }
        let mut best = match constraint {
            Constraint::Rate => plan_hi.clone(),
            Constraint::Distortion => plan_lo.clone(),
        };
        // ln of the constrained quantity at the ends; only its differences matter.
        let log_of = |p: &Plan| measure(p).max(1e-9).ln();
        let (mut f_lo, mut f_hi) = (log_of(&plan_lo), log_of(&plan_hi));
        let target = limit.max(1e-9).ln();
        // Which end the last interpolation replaced (true: the upper; for the Illinois
        // halving), and whether the next step must bisect.
        let mut kept: Option<bool> = None;
        let mut bisect_next = false;
        // Down to `tolerance` in the log of the multiplier (1e-3: 0.1%; the plans between two
        // multipliers that close differ by a few leaves at most), or in the constrained
        // quantity.
        while hi - lo > tolerance {
            let width = hi - lo;
            let mid = if bisect_next || !(f_lo - f_hi).is_normal() {
                0.5 * (lo + hi)
            } else {
                let t = (f_lo - target) / (f_lo - f_hi);
                // Strictly inside, so that the bracket always shrinks.
                lo + width * t.clamp(0.02, 0.98)
            };
            let p = self.optimise(analysis, header, mid.exp());
            let good = ok(&p);
            let f = log_of(&p);
            let moves_hi = above(&p);
            if moves_hi {
                (hi, f_hi) = (mid, f);
            } else {
                (lo, f_lo) = (mid, f);
            }
            if !bisect_next {
                // The same end kept by two interpolations in a row: pull its value halfway
                // to the target (Illinois), or false position creeps up on one side.
                if kept == Some(moves_hi) {
                    if moves_hi {
                        f_lo = target + 0.5 * (f_lo - target);
                    } else {
                        f_hi = target + 0.5 * (f_hi - target);
                    }
                }
                kept = Some(moves_hi);
            }
            bisect_next = !bisect_next && hi - lo > 0.5 * width;
            if good {
                // Close enough in the constrained quantity too: no multiplier in between
                // can do better by more than the tolerance.
                let done = measure(&p) >= limit * (1.0 - tolerance);
                best = p;
                if done {
                    break;
                }
            }
        }
        best
    }
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
            // b is above the segment a-p: not a vertex.
            if (b.1 - a.1) * (p.0 - a.0) >= (p.1 - a.1) * (b.0 - a.0) {
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

impl Search {
    fn new(constraint: Constraint, limit: f64, tolerance: f64) -> Search {
        Search {
            constraint,
            limit,
            tolerance,
        }
    }
}

/// The multipliers searched (squared error per bit).
const LAMBDA_RANGE: std::ops::RangeInclusive<f64> = 1e-4..=1e9;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Constraint {
    Rate,
    Distortion,
}

#[cfg(test)]
mod tests {
    use super::lower_hull_in;

    /// The hull keeps exactly the points that are best for some multiplier in the range, as a
    /// dense sweep of multipliers finds them.
    #[test]
    fn hull_matches_a_sweep_of_multipliers() {
        let mut seed = 12345u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            f64::from(seed >> 8) / f64::from(1u32 << 24)
        };
        for _ in 0..200 {
            let points: Vec<(f64, f64)> = (0..12)
                .map(|_| ((next() * 40.0).round(), (next() * 1000.0).round()))
                .collect();
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
}
