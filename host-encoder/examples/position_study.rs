//! What the zero flags of the control residuals would cost with contexts that know where a
//! residual is: decodes each grayscale stream, logs every coded integer of a leaf, and once the
//! leaf is known (its model, side and coding) puts each integer at its grid position and prices
//! its zero flag with shadow adaptive contexts (all starting at one half, adapting as the
//! stream's do): once by the stream's own context (the integer class and its neighbourhood
//! context), and once per alternative that adds to that context
//!
//! - the magnitude (0, 1, 2+) of a grid-transform detail's parent (the coefficient of the next
//!   coarser level at the same orientation and half the position; the low band for the
//!   coarsest details);
//! - the leaf's size, for a leaf's first value;
//! - how many of the leaf's residuals so far were not zero (0, 1, 2+);
//! - the magnitude of the leaf's first-value residual, for every residual of the leaf.
//!
//! And the signs: each with one shadow context (the stream's), and a DPCM first-row or
//! first-column residual's also by the direction of the change between the pixels beside its
//! point and beside the point before it (what its prediction was made from).
//!
//! And two ways of not coding a leaf's trailing zeros (the zero flags after its last residual
//! that is not zero, its first value apart): an end flag after every residual that is not
//! zero (whether another follows; a context per integer class and magnitude 1, 2+) and one
//! flag before the rest of the leaf (whether any residual after the first value is not zero;
//! a context per coding and grid side), the zero flags then priced only where still coded.
//!
//! Prints each alternative's saving as a share of the payload.
//!
//! `cargo run --release -p host-encoder --example position_study -- STREAM.pifs...`

use decoder_core::internal::entropy::{
    Coder, IntContexts, PayloadError, Prob, RangeDecoder, PROB_ONE,
};
use decoder_core::internal::model::MODELS;
use decoder_core::internal::prediction::Frontier;
use decoder_core::internal::prediction::SamplePrediction;
use decoder_core::internal::syntax::control::{grid_sizes, transform_order};
use decoder_core::internal::syntax::{control_step, ControlCoding, Header, LeafSyntax};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk_with, LeafInfo, TreeVisitor, WalkState};
use decoder_core::{DecodeError, Node, SliceSource};
use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

/// One coded integer: its context array (by address: class and step group), its zero-flag
/// context, its value.
#[derive(Clone, Copy)]
struct Coded {
    key: usize,
    ctx: usize,
    value: i32,
}

/// Codes as the stream's decoder does, logging every integer.
struct Logging<'a> {
    inner: RangeDecoder<SliceSource<'a>>,
    log: Rc<RefCell<Vec<Coded>>>,
}

impl Coder for Logging<'_> {
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        self.inner.bit(p, bit)
    }
    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
        self.inner.bypass(bit)
    }
    fn int(&mut self, ints: &mut IntContexts, ctx: usize, v: &mut i32) -> Result<(), PayloadError> {
        let key = ints as *mut IntContexts as usize;
        ints.code_bits(&mut self.inner, ctx, v)?;
        self.log.borrow_mut().push(Coded {
            key,
            ctx: ctx.min(4),
            value: *v,
        });
        Ok(())
    }
}

/// Shadow zero-flag contexts by an arbitrary key, and the bits they priced.
#[derive(Default)]
struct Shadow {
    probs: HashMap<(usize, usize, usize), Prob>,
    bits: f64,
}

impl Shadow {
    fn price(&mut self, key: (usize, usize, usize), nonzero: bool) {
        let p = self.probs.entry(key).or_default();
        let zero = f64::from(p.probability()) / f64::from(PROB_ONE);
        p.update(nonzero);
        self.bits -= (if nonzero { 1.0 - zero } else { zero }).log2();
    }
}

#[derive(Default)]
struct Study {
    base: Shadow,
    parent: Shadow,
    size: Shadow,
    so_far: Shadow,
    first: Shadow,
    sign_base: Shadow,
    sign_edge: Shadow,
    end_zero: Shadow,
    end_flag: Shadow,
    skip_zero: Shadow,
    skip_flag: Shadow,
    trailing: u64,
    integers: u64,
    leaves: u64,
    transform_leaves: u64,
}

/// The grid position of each coded integer of a leaf of side `side`, in coding order.
fn positions(side: usize, transform: bool) -> Vec<(usize, usize)> {
    if transform {
        return transform_order(side)
            .iter()
            .take(side * side)
            .map(|&i| (usize::from(i) / side, usize::from(i) % side))
            .collect();
    }
    let mut out = vec![(0, 0)];
    out.extend((1..side).map(|c| (0, c)));
    for r in 1..side {
        out.extend((0..side).map(|c| (r, c)));
    }
    out
}

/// The parent of detail `(r, c)` of a grid of side `side` in the transform's layout (low band
/// of each level first along each line): the same orientation at the next coarser level, half
/// the position within the band; the low band `(0, 0)` for the coarsest details.
fn parent(side: usize, r: usize, c: usize) -> (usize, usize) {
    let (sizes, levels) = grid_sizes(side);
    let mut k = 0;
    while k < levels && r < sizes[k + 1] && c < sizes[k + 1] {
        k += 1;
    }
    if k + 1 >= levels {
        return (0, 0);
    }
    let (s1, s2) = (sizes[k + 1], sizes[k + 2]);
    let map = |v: usize| {
        if v >= s1 {
            s2 + (v - s1) / 2
        } else {
            v / 2
        }
    };
    (map(r), map(c))
}

struct Reader {
    log: Rc<RefCell<Vec<Coded>>>,
    study: Study,
    /// The pixels above and left of the leaf being coded, by offset along its edge (`None`
    /// where not known), recorded before it is coded.
    above: Vec<Option<i32>>,
    left: Vec<Option<i32>>,
}

impl Reader {
    fn price_leaf(&mut self, info: &LeafInfo) {
        let ints: Vec<Coded> = self.log.borrow_mut().drain(..).collect();
        let model = MODELS[usize::from(info.model)];
        let side = model.coded_side(info.node.log2);
        let transform = info.coding == ControlCoding::Transform;
        let order = positions(side, transform);
        let spacing = model.spacing(info.node.log2) as usize;
        if ints.len() != order.len() {
            // Not a luma leaf's control values alone (a colour stream): not priced.
            return;
        }
        let s = &mut self.study;
        s.leaves += 1;
        s.transform_leaves += u64::from(transform);
        let mut grid = vec![0i32; side * side];
        let mag = |v: i32| v.unsigned_abs().min(2) as usize;
        let first = mag(ints[0].value);
        let mut nonzeros = 0usize;
        let last = (ints.iter().enumerate().skip(1))
            .rev()
            .find(|(_, c)| c.value != 0)
            .map(|(k, _)| k);
        let kind = (usize::MAX, usize::from(transform), side);
        s.end_flag.price(kind, last.is_some());
        s.skip_flag.price(kind, last.is_some());
        s.integers += ints.len() as u64;
        s.trailing += (ints.len() - 1 - last.unwrap_or(0)) as u64;
        for (k, coded) in ints.iter().enumerate() {
            let (nz, key) = (coded.value != 0, (coded.key, coded.ctx, 0));
            if k == 0 {
                s.end_zero.price(key, nz);
                s.skip_zero.price(key, nz);
            } else if let Some(last) = last {
                s.skip_zero.price(key, nz);
                if k <= last {
                    s.end_zero.price(key, nz);
                    if nz {
                        s.end_flag.price((coded.key, 1, mag(coded.value)), k < last);
                    }
                }
            }
        }
        for (k, (coded, &(r, c))) in ints.iter().zip(&order).enumerate() {
            let nz = coded.value != 0;
            let (key, ctx) = (coded.key, coded.ctx);
            s.base.price((key, ctx, 0), nz);
            let parent_mag = if transform && k > 0 {
                let (pr, pc) = parent(side, r, c);
                1 + mag(grid[pr * side + pc])
            } else {
                0
            };
            s.parent.price((key, ctx, parent_mag), nz);
            let size = if k == 0 {
                1 + usize::from(info.node.log2)
            } else {
                0
            };
            s.size.price((key, ctx, size), nz);
            s.so_far.price((key, ctx, nonzeros.min(2)), nz);
            s.first
                .price((key, ctx, if k == 0 { 3 } else { first }), nz);
            if nz {
                let negative = coded.value < 0;
                s.sign_base.price((key, 0, 0), negative);
                // A DPCM first-row or first-column residual: the sign of the change between
                // the pixels beside its point and beside the point before it.
                let beside = |edge: &[Option<i32>], k: usize| {
                    let a = edge.get(k * spacing).copied().flatten()?;
                    let b = edge.get((k - 1) * spacing).copied().flatten()?;
                    Some(1 + usize::from(a > b) + 2 * usize::from(a < b))
                };
                let change = match (transform, r, c) {
                    (false, 0, c) if c > 0 => beside(&self.above, c).unwrap_or(0),
                    (false, r, 0) if r > 0 => beside(&self.left, r).unwrap_or(0),
                    _ => 0,
                };
                s.sign_edge.price((key, 0, change), negative);
            }
            grid[r * side + c] = coded.value;
            nonzeros += usize::from(nz);
        }
    }
}

impl TreeVisitor for Reader {
    type Error = DecodeError;
    fn prepare_leaf<P: SamplePrediction>(&mut self, n: &Node, p: &P, _l: &mut LeafSyntax) {
        let s = n.size();
        self.above = (0..s).map(|k| p.above(n.x + k, n.y)).collect();
        self.left = (0..s).map(|k| p.left(n.x, n.y + k)).collect();
    }
    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        self.price_leaf(info);
        frontier.record(&info.node, control_step(info.cquant), patch, &mut Discard);
        Ok(())
    }
}

fn main() {
    let mut payload = 0.0;
    let log = Rc::new(RefCell::new(Vec::new()));
    let mut reader = Reader {
        log: log.clone(),
        study: Study::default(),
        above: Vec::new(),
        left: Vec::new(),
    };
    for path in std::env::args().skip(1) {
        let stream = std::fs::read(&path).expect("reads the stream");
        let (header, at) = Header::parse(&stream).expect("a stream");
        assert_eq!(header.channels, 1, "{path}: grayscale streams only");
        let data = &stream[at..at + header.payload_len as usize];
        let mut state = Box::<WalkState>::default();
        let mut coder = Logging {
            inner: RangeDecoder::new(SliceSource::new(data)).expect("a payload"),
            log: log.clone(),
        };
        walk_with(&header, &mut coder, &mut reader, &mut state).expect("decodes");
        payload += 8.0 * f64::from(header.payload_len);
    }
    let s = &reader.study;
    let pct = |d: f64| 100.0 * d / payload;
    println!(
        "payload bits {payload:.0}, leaves {} ({} by the grid transform)",
        s.leaves, s.transform_leaves
    );
    println!(
        "zero flags, shadow base: {:.2}% of the payload",
        pct(s.base.bits)
    );
    println!(
        "signs, shadow base: {:.2}% of the payload",
        pct(s.sign_base.bits)
    );
    println!(
        "a DPCM edge residual's sign by the direction of the change beside it: {:+.2}%",
        pct(s.sign_edge.bits - s.sign_base.bits)
    );
    println!(
        "trailing zeros: {} of {} integers ({:.1}%)",
        s.trailing,
        s.integers,
        100.0 * s.trailing as f64 / s.integers as f64
    );
    for (name, zero, flag) in [
        (
            "an end flag after every nonzero residual",
            &s.end_zero,
            &s.end_flag,
        ),
        (
            "one flag before the rest of a leaf",
            &s.skip_zero,
            &s.skip_flag,
        ),
    ] {
        println!(
            "{name}: zero flags {:+.2}%, the flags {:.2}%, net {:+.2}%",
            pct(zero.bits - s.base.bits),
            pct(flag.bits),
            pct(zero.bits + flag.bits - s.base.bits)
        );
    }
    for (name, alt) in [
        ("a detail's parent magnitude", &s.parent),
        ("the leaf's size, for its first value", &s.size),
        ("the leaf's nonzero residuals so far", &s.so_far),
        ("the leaf's first-value magnitude", &s.first),
    ] {
        println!("{name}: {:+.2}%", pct(alt.bits - s.base.bits));
    }
}
