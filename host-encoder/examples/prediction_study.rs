//! What predicting a grid-transform leaf's coefficients from the pixels beside the leaf would
//! save: decodes each grayscale stream, and for each leaf coded by the grid transform forms a
//! prediction grid from the pixels above and left of the leaf (several predictors), transforms
//! it, and prices the leaf's indices as coded and as residuals against the prediction's
//! rounded indices, with the same shadow adaptive models. Prints each predictor's saving as a
//! share of the payload, alone and chosen per leaf.
//!
//! `cargo run --release -p host-encoder --example prediction_study -- STREAM.pifs...`

use decoder_core::internal::entropy::{
    Coder, IntContexts, PayloadError, Prob, RangeDecoder, PROB_ONE,
};
use decoder_core::internal::model::{MAX_CONTROL, MODELS};
use decoder_core::internal::prediction::{Frontier, SamplePrediction};
use decoder_core::internal::syntax::control::{band_level, coefficient_step, transform_order};
use decoder_core::internal::syntax::{control_step, ControlCoding, Header, LeafSyntax};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk_with, LeafInfo, TreeVisitor, WalkState};
use decoder_core::{DecodeError, Node, SliceSource};
use host_encoder::internal::forward_grid_transform;
use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

struct Logging<'a> {
    inner: RangeDecoder<SliceSource<'a>>,
    log: Rc<RefCell<Vec<i32>>>,
}

impl Coder for Logging<'_> {
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        self.inner.bit(p, bit)
    }
    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
        self.inner.bypass(bit)
    }
    fn int(&mut self, ints: &mut IntContexts, ctx: usize, v: &mut i32) -> Result<(), PayloadError> {
        ints.code_bits(&mut self.inner, ctx, v)?;
        self.log.borrow_mut().push(*v);
        Ok(())
    }
}

/// Shadow adaptive pricing of integers: a zero flag and a greater-than-one flag per band
/// level, a bypass sign, Exp-Golomb bits for the rest.
#[derive(Default)]
struct Pricer {
    probs: HashMap<(usize, usize), Prob>,
    bits: f64,
}

impl Pricer {
    fn flag(&mut self, key: (usize, usize), b: bool) -> f64 {
        let p = self.probs.entry(key).or_default();
        let zero = f64::from(p.probability()) / f64::from(PROB_ONE);
        p.update(b);
        -(if b { 1.0 - zero } else { zero }).log2()
    }
    fn int(&mut self, band: usize, v: i32) -> f64 {
        let mut bits = self.flag((band, 0), v != 0);
        if v != 0 {
            bits += 1.0;
            let a = v.unsigned_abs();
            bits += self.flag((band, 1), a > 1);
            if a > 1 {
                bits += 1.0 + 2.0 * f64::from((a - 1).ilog2());
            }
        }
        bits
    }
    /// The bits of a leaf's indices without adapting (for choosing).
    fn peek(&self, ints: &[(usize, i32)]) -> f64 {
        let mut copy = Pricer {
            probs: self.probs.clone(),
            bits: 0.0,
        };
        ints.iter().map(|&(b, v)| copy.int(b, v)).sum()
    }
    fn commit(&mut self, ints: &[(usize, i32)]) {
        for &(b, v) in ints {
            self.bits += self.int(b, v);
        }
    }
}

/// The forward grid transform (the encoder's) of a grid of side `side`, row-major.
fn forward(g: &mut [f64], side: usize) {
    let mut grid = [0.0; MAX_CONTROL];
    grid[..g.len()].copy_from_slice(g);
    forward_grid_transform(&mut grid, side);
    g.copy_from_slice(&grid[..g.len()]);
}

/// The predictors: the stream's own (the low band against the mean of the pixels beside),
/// then the prediction grids [`prediction_grid`] makes.
const PREDICTORS: [&str; 6] = [
    "dc-mean",
    "vertical",
    "horizontal",
    "average",
    "planar",
    "smooth",
];

/// The pixels beside a leaf (1/16 level) at its control points: `above[c]` over column `c`,
/// `left[r]` beside row `r`, the nearest known pixel where one is not known.
struct Beside {
    above: Vec<f64>,
    left: Vec<f64>,
}

impl Beside {
    /// The pixels beside a grid of side `side` and spacing `sp` from those beside the leaf;
    /// `None` when no pixel beside it is known.
    fn of(above: &[Option<i32>], left: &[Option<i32>], side: usize, sp: usize) -> Option<Beside> {
        let edge = |v: &[Option<i32>], o: usize| {
            let o = o.min(v.len() - 1);
            (0..=o).rev().find_map(|k| v[k]).map(f64::from)
        };
        let first = edge(above, 0).or(edge(left, 0))?;
        let line = |v: &[Option<i32>]| -> Vec<f64> {
            (0..side)
                .map(|k| edge(v, k * sp).unwrap_or(first))
                .collect()
        };
        Some(Beside {
            above: line(above),
            left: line(left),
        })
    }

    /// Prediction grid `p` (`1..PREDICTORS.len()`), transformed.
    fn prediction_grid(&self, p: usize) -> Vec<f64> {
        let side = self.above.len();
        let last = (side - 1).max(1) as f64;
        let corner = 0.5 * (self.above[0] + self.left[0]);
        let (right, bottom) = (self.above[side - 1], self.left[side - 1]);
        let mut g = vec![0.0f64; side * side];
        for r in 0..side {
            for c in 0..side {
                let (a, l) = (self.above[c], self.left[r]);
                let (wr, wc) = (r as f64 / last, c as f64 / last);
                g[r * side + c] = match p {
                    1 => a,
                    2 => l,
                    3 => 0.5 * (a + l),
                    4 => (a + l - corner).clamp(-4096.0, 8191.0),
                    _ => 0.5 * ((1.0 - wr) * a + wr * bottom + (1.0 - wc) * l + wc * right),
                };
            }
        }
        forward(&mut g, side);
        g
    }
}

/// One way of coding a leaf's indices: (band level, integer) in coding order.
type Coding = Vec<(usize, i32)>;

/// The prices of one comparison: the leaves as the stream codes them (`base`), each predictor
/// alone, and the best per leaf with its mode bits.
struct Comparison {
    base: Pricer,
    alone: Vec<Pricer>,
    chosen: Pricer,
    modes: Pricer,
    counts: Vec<u64>,
}

impl Comparison {
    fn new() -> Comparison {
        let n = PREDICTORS.len() - 1;
        Comparison {
            base: Pricer::default(),
            alone: (0..n).map(|_| Pricer::default()).collect(),
            chosen: Pricer::default(),
            modes: Pricer::default(),
            counts: vec![0; n + 1],
        }
    }

    /// Prices a leaf coded as `base` or by each of `options`.
    fn add(&mut self, base: &Coding, options: &[Coding]) {
        self.base.commit(base);
        for (pricer, option) in self.alone.iter_mut().zip(options) {
            pricer.commit(option);
        }
        let mut best = (self.chosen.peek(base), 0usize);
        for (o, option) in options.iter().enumerate() {
            let bits = self.chosen.peek(option);
            if bits < best.0 {
                best = (bits, o + 1);
            }
        }
        let pick = if best.1 == 0 {
            base
        } else {
            &options[best.1 - 1]
        };
        self.chosen.commit(pick);
        // The mode, unary with adaptive flags.
        for m in 0..PREDICTORS.len() - 1 {
            let hit = m == best.1;
            self.modes.bits += self.modes.flag((100, m), hit);
            if hit {
                break;
            }
        }
        self.counts[best.1] += 1;
    }

    fn print(&self, pct: impl Fn(f64) -> f64) {
        for (o, pricer) in self.alone.iter().enumerate() {
            println!(
                "{:>12}: {:+.2}%",
                PREDICTORS[o + 1],
                pct(pricer.bits - self.base.bits)
            );
        }
        println!(
            "  the best per leaf: {:+.2}%, its mode bits {:.2}%; choices {:?}",
            pct(self.chosen.bits - self.base.bits),
            pct(self.modes.bits),
            self.counts
        );
    }
}

/// The original's luma (1/16 level) and its width and height.
struct Original {
    luma: Vec<f64>,
    width: usize,
    height: usize,
}

struct Reader {
    log: Rc<RefCell<Vec<i32>>>,
    above: Vec<Option<i32>>,
    left: Vec<Option<i32>>,
    leaves: u64,
    skipped: u64,
    /// The stream's indices against residuals from each prediction.
    coded: Comparison,
    /// The same for the low band and the coarse details only.
    coarse: Comparison,
    /// The original's samples through a plain dead-zone quantiser, when the original is given.
    original: Option<Original>,
    naive: Comparison,
}

/// `n / q` rounded half away from zero, in integers (the syntax's rounding).
fn round_div(n: i32, q: i32) -> i32 {
    if n >= 0 {
        (n + q / 2) / q
    } else {
        -((-n + q / 2) / q)
    }
}

/// A plain dead-zone quantiser (rounding offset 0.3).
fn dead_zone(v: f64, q: i32) -> i32 {
    let k = (v.abs() / f64::from(q) + 0.3).floor() as i32;
    if v < 0.0 {
        -k
    } else {
        k
    }
}

impl Reader {
    fn price_leaf(&mut self, info: &LeafInfo) {
        let ints: Vec<i32> = self.log.borrow_mut().drain(..).collect();
        if info.coding != ControlCoding::Transform {
            return;
        }
        let model = MODELS[usize::from(info.model)];
        let side = model.coded_side(info.node.log2);
        if ints.len() != side * side {
            return;
        }
        let sp = model.spacing(info.node.log2) as usize;
        let Some(beside) = Beside::of(&self.above, &self.left, side, sp) else {
            self.skipped += 1;
            return;
        };
        self.leaves += 1;
        let step = control_step(info.cquant);
        let order: Vec<usize> = (transform_order(side).iter())
            .take(side * side)
            .map(|&i| usize::from(i))
            .collect();
        let band = |i: usize| band_level(side, i / side, i % side);
        let q = coefficient_step(side, step);
        // The stream's low band is a residual against the mean of the known pixels beside.
        let size = info.node.size() as usize;
        let known: Vec<i32> = (self.above[..size].iter().chain(&self.left[..size]))
            .filter_map(|v| *v)
            .collect();
        let mean = known.iter().sum::<i32>() / known.len() as i32;
        let mut k = vec![0i32; side * side];
        for (&i, &v) in order.iter().zip(&ints) {
            k[i] = v;
        }
        k[0] += round_div(mean, q);
        let as_coded: Coding = order
            .iter()
            .zip(&ints)
            .map(|(&i, &v)| (band(i), v))
            .collect();
        let grids: Vec<Vec<f64>> = (1..PREDICTORS.len())
            .map(|p| beside.prediction_grid(p))
            .collect();
        let against = |g: &Vec<f64>, coarse_only: bool| -> Coding {
            (order.iter())
                .map(|&i| {
                    let predicted = (g[i] / f64::from(q)).round() as i32;
                    let used = !coarse_only || i == 0 || band(i) >= 1;
                    (band(i), if used { k[i] - predicted } else { k[i] })
                })
                .collect()
        };
        let options: Vec<Coding> = grids.iter().map(|g| against(g, false)).collect();
        self.coded.add(&as_coded, &options);
        let coarse: Vec<Coding> = grids.iter().map(|g| against(g, true)).collect();
        self.coarse.add(&as_coded, &coarse);
        if let Some(original) = &self.original {
            // The original's samples at the control points, transformed.
            let (x0, y0) = (info.node.x as usize, info.node.y as usize);
            let mut t = vec![0.0f64; side * side];
            for r in 0..side {
                for c in 0..side {
                    let x = (x0 + c * sp).min(original.width - 1);
                    let y = (y0 + r * sp).min(original.height - 1);
                    t[r * side + c] = original.luma[y * original.width + x];
                }
            }
            forward(&mut t, side);
            let plain: Coding = (order.iter())
                .map(|&i| {
                    let v = if i == 0 { t[0] - f64::from(mean) } else { t[i] };
                    (band(i), dead_zone(v, q))
                })
                .collect();
            let predicted: Vec<Coding> = (grids.iter())
                .map(|g| {
                    (order.iter())
                        .map(|&i| (band(i), dead_zone(t[i] - g[i], q)))
                        .collect()
                })
                .collect();
            self.naive.add(&plain, &predicted);
        }
    }
}

impl TreeVisitor for Reader {
    type Error = DecodeError;
    fn prepare_leaf<P: SamplePrediction>(&mut self, n: &Node, p: &P, _l: &mut LeafSyntax) {
        let s = n.size() + 1;
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
        above: Vec::new(),
        left: Vec::new(),
        leaves: 0,
        skipped: 0,
        coded: Comparison::new(),
        coarse: Comparison::new(),
        original: None,
        naive: Comparison::new(),
    };
    let mut with_originals = false;
    for arg in std::env::args().skip(1) {
        let (path, original) = match arg.split_once('=') {
            Some((p, o)) => (p.to_string(), Some(o.to_string())),
            None => (arg.clone(), None),
        };
        with_originals |= original.is_some();
        reader.original = original.map(|o| {
            let img = image::open(&o).expect("reads the original").to_rgb8();
            let luma = (img.pixels())
                .map(|p| {
                    let [r, g, b] = p.0.map(f64::from);
                    16.0 * (0.299 * r + 0.587 * g + 0.114 * b)
                })
                .collect();
            Original {
                luma,
                width: img.width() as usize,
                height: img.height() as usize,
            }
        });
        let stream = std::fs::read(&path).expect("reads the stream");
        let (header, at) = Header::parse(&stream).expect("a stream");
        assert_eq!(header.channels, 1, "{path}: grayscale streams only");
        let data = &stream[at..at + header.payload_len as usize];
        let mut state = Box::<WalkState<{ 1 << 16 }>>::default();
        let mut coder = Logging {
            inner: RangeDecoder::new(SliceSource::new(data)).expect("a payload"),
            log: log.clone(),
        };
        walk_with(&header, &mut coder, &mut reader, &mut state).expect("decodes");
        payload += 8.0 * f64::from(header.payload_len);
    }
    let r = &reader;
    let pct = |d: f64| 100.0 * d / payload;
    println!(
        "payload bits {payload:.0}; grid-transform leaves priced {} (skipped, nothing beside: {}); \
         their indices as coded, shadow-priced: {:.2}% of the payload",
        r.leaves,
        r.skipped,
        pct(r.coded.base.bits)
    );
    println!("residuals against each prediction, every coefficient:");
    r.coded.print(pct);
    println!("the low band and the coarse details only:");
    r.coarse.print(pct);
    if with_originals {
        println!(
            "the originals' samples through a dead-zone quantiser (as the stream: {:.2}%):",
            pct(r.naive.base.bits)
        );
        r.naive.print(pct);
    }
}
