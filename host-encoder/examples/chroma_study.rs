//! Chroma control steps tied to the luma step, or to each other (issue 22): decodes colour
//! streams, notes every control quantiser index as it is coded (a luma leaf's, then each
//! chroma plane's, `Cb` before `Cr`), and prices the chroma indices' 4-bit trees again with
//! shadow adaptive contexts that all start at one half and adapt as the stream's do: once as
//! the stream conditions them (by chroma model) and once per alternative (also by plane, by
//! the luma step of the leaf, by the `Cb` step of the same leaf for `Cr`). Prints the chroma
//! indices' share of the payload and each alternative's saving as a share of the payload.
//!
//! `cargo run --release -p host-encoder --example chroma_study -- STREAM.pifs...`

use decoder_core::internal::colour::CHROMA_GRIDS;
use decoder_core::internal::entropy::{Coder, PayloadError, Prob, RangeDecoder, PROB_ONE};
use decoder_core::internal::format::MAX_LEAF_LOG2;
use decoder_core::internal::prediction::{Frontier, SamplePrediction};
use decoder_core::internal::syntax::{
    control::CONTROL_STEPS, control_step, ChromaContexts, Header, LeafSyntax,
};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk_with, LeafInfo, TreeVisitor, WalkState};
use decoder_core::{DecodeError, Node, SliceSource};
use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

fn price(p: &mut Prob, bit: bool) -> f64 {
    let zero = f64::from(p.probability()) / f64::from(PROB_ONE);
    p.update(bit);
    -(if bit { 1.0 - zero } else { zero }).log2()
}

/// A quantiser's rank by step, finest first (the index order is not the step order).
fn rank(cq: u8) -> usize {
    let step = control_step(cq);
    CONTROL_STEPS.iter().filter(|&&s| s < step).count()
}

/// One chroma plane's coded quantiser and what it might be conditioned on.
#[derive(Debug, Clone, Copy)]
struct ChromaIndex {
    model: usize,
    plane: usize,
    cquant: u8,
    /// The luma quantiser of the leaf (or, for a subtree's chroma, the last luma leaf's).
    luma: u8,
    /// For `Cr`: the `Cb` quantiser of the same node.
    cb: u8,
}

#[derive(Default)]
struct Notes {
    /// The address range of the chroma contexts, once known, and the offset of each chroma
    /// quantiser context (by model and tree node).
    chroma: Option<(usize, usize)>,
    chroma_cquant: HashMap<usize, usize>,
    plane: usize,
    luma: u8,
    cb: u8,
    /// Bits of the tree being coded.
    tree: Vec<bool>,
    tree_model: usize,
    tree_cost: f64,
    indices: Vec<ChromaIndex>,
    stream_cost: f64,
    total: f64,
}

struct Pricing<'a> {
    inner: RangeDecoder<SliceSource<'a>>,
    notes: Rc<RefCell<Notes>>,
}

impl Coder for Pricing<'_> {
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        let zero = f64::from(p.probability()) / f64::from(PROB_ONE);
        let at = p as *mut Prob as usize;
        self.inner.bit(p, bit)?;
        let cost = -(if *bit { 1.0 - zero } else { zero }).log2();
        let mut n = self.notes.borrow_mut();
        n.total += cost;
        let model = match n.chroma {
            Some((lo, hi)) if (lo..hi).contains(&at) => n.chroma_cquant.get(&(at - lo)).copied(),
            _ => None,
        };
        if let Some(model) = model {
            n.tree.push(*bit);
            n.tree_model = model;
            n.tree_cost += cost;
            if n.tree.len() == 4 {
                let cquant = n.tree.iter().fold(0u8, |v, &b| (v << 1) | u8::from(b));
                let (plane, luma, cb, tree_model) = (n.plane, n.luma, n.cb, n.tree_model);
                n.indices.push(ChromaIndex {
                    model: tree_model,
                    plane,
                    cquant,
                    luma,
                    cb,
                });
                if plane == 0 {
                    n.cb = cquant;
                }
                n.stream_cost += n.tree_cost;
                n.tree.clear();
                n.tree_cost = 0.0;
            }
        }
        Ok(())
    }

    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
        self.inner.bypass(bit)?;
        self.notes.borrow_mut().total += 1.0;
        Ok(())
    }
}

struct Reader(Rc<RefCell<Notes>>);

impl TreeVisitor for Reader {
    type Error = DecodeError;
    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        self.0.borrow_mut().luma = info.cquant;
        frontier.record(&info.node, control_step(info.cquant), patch, &mut Discard);
        Ok(())
    }

    fn prepare_chroma<P: SamplePrediction>(
        &mut self,
        _node: &Node,
        plane: usize,
        _prediction: &P,
        contexts: &ChromaContexts,
        _leaf: &mut LeafSyntax,
    ) {
        let mut n = self.0.borrow_mut();
        n.plane = plane;
        if n.chroma.is_none() {
            let base = contexts as *const ChromaContexts as usize;
            n.chroma = Some((base, base + std::mem::size_of::<ChromaContexts>()));
            // Offsets of the quantiser contexts, from a copy laid out alike.
            let mut copy = contexts.clone();
            let copy_base = &copy as *const ChromaContexts as usize;
            let models = MAX_LEAF_LOG2 as usize * CHROMA_GRIDS.len();
            let mut i = 0;
            let mut offsets = HashMap::new();
            copy.for_each_prob(|p| {
                if (models..models + CHROMA_GRIDS.len() * 16).contains(&i) {
                    offsets.insert(p as *mut Prob as usize - copy_base, (i - models) / 16);
                }
                i += 1;
            });
            n.chroma_cquant = offsets;
        }
    }
}

/// Prices the chroma indices with a tree of shadow contexts per key.
fn shadow_cost(indices: &[ChromaIndex], key: &dyn Fn(&ChromaIndex) -> usize) -> f64 {
    let mut trees: HashMap<usize, [Prob; 16]> = HashMap::new();
    let mut cost = 0.0;
    for ix in indices {
        let tree = trees.entry(key(ix)).or_insert([Prob::FRESH; 16]);
        let mut node = 1usize;
        for i in (0..4).rev() {
            let b = (ix.cquant >> i) & 1 == 1;
            cost += price(&mut tree[node % 16], b);
            node = (node << 1) | usize::from(b);
        }
    }
    cost
}

fn main() {
    type Key = fn(&ChromaIndex) -> usize;
    let alternatives: [(&str, Key); 6] = [
        ("by plane", |ix| ix.model * 2 + ix.plane),
        ("by the luma step (4 classes)", |ix| {
            ix.model * 4 + rank(ix.luma) / 4
        }),
        ("by the luma step (16)", |ix| ix.model * 16 + rank(ix.luma)),
        ("Cr by the Cb step (4 classes)", |ix| {
            if ix.plane == 0 {
                ix.model
            } else {
                100 + ix.model * 4 + rank(ix.cb) / 4
            }
        }),
        ("Cr by the Cb step (16)", |ix| {
            if ix.plane == 0 {
                ix.model
            } else {
                100 + ix.model * 16 + rank(ix.cb)
            }
        }),
        ("Cb by the luma step, Cr by the Cb step (4 classes)", |ix| {
            if ix.plane == 0 {
                ix.model * 4 + rank(ix.luma) / 4
            } else {
                100 + ix.model * 4 + rank(ix.cb) / 4
            }
        }),
    ];
    let mut payload = 0.0;
    let mut stream = 0.0;
    let mut base = 0.0;
    let mut saved = [0.0; 6];
    let mut same = (0usize, 0usize);
    for path in std::env::args().skip(1) {
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let (header, at) = Header::parse(&bytes).unwrap_or_else(|e| panic!("{path}: {e}"));
        assert_eq!(header.channels, 3, "{path}: colour streams only");
        let data = &bytes[at..at + header.payload_len as usize];
        let notes = Rc::new(RefCell::new(Notes::default()));
        let mut coder = Pricing {
            inner: RangeDecoder::new(SliceSource::new(data)).expect("a payload"),
            notes: notes.clone(),
        };
        let mut state = Box::<WalkState<65536>>::default();
        let mut reader = Reader(notes.clone());
        walk_with(&header, &mut coder, &mut reader, &mut state)
            .unwrap_or_else(|e| panic!("{path}: {e}"));
        let n = notes.borrow();
        let b = shadow_cost(&n.indices, &|ix| ix.model);
        payload += n.total;
        stream += n.stream_cost;
        base += b;
        for (k, (_, key)) in alternatives.iter().enumerate() {
            saved[k] += b - shadow_cost(&n.indices, key);
        }
        for ix in n.indices.iter().filter(|ix| ix.plane == 1) {
            same.0 += usize::from(ix.cquant == ix.cb);
            same.1 += 1;
        }
        eprintln!(
            "{path}: {} chroma indices, {:.1}% of the payload",
            n.indices.len(),
            100.0 * n.stream_cost / n.total
        );
    }
    println!(
        "chroma quantiser indices: {:.2}% of the payload as coded, {:.2}% with fresh shadow contexts; Cr's equal to Cb's in {:.1}% of nodes",
        100.0 * stream / payload,
        100.0 * base / payload,
        100.0 * same.0 as f64 / same.1.max(1) as f64
    );
    for (k, (name, _)) in alternatives.iter().enumerate() {
        println!(
            "  {name}: {:+.3}% of the payload",
            -100.0 * saved[k] / payload
        );
    }
}
