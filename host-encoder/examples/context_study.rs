//! What other conditioning of the control residuals' bits would save: decodes each stream and
//! prices every coded integer twice with shadow adaptive contexts that all start at one half
//! and adapt as the stream's do: once with the stream's structure (a zero flag per
//! neighbourhood context, one sign context, six prefix contexts, bypass suffixes) and once per
//! alternative (prefix bits also by neighbourhood, the sign by neighbourhood or by the
//! previous integer's sign, the top suffix bit context coded, the zero flag also by whether
//! the previous integer of its class was zero). Prints each alternative's saving as a share
//! of the payload.
//!
//! `cargo run --release -p host-encoder --example context_study -- STREAM.pifs...`

use decoder_core::internal::entropy::{
    Coder, IntContexts, PayloadError, Prob, RangeDecoder, PROB_ONE,
};
use decoder_core::internal::prediction::{Frontier, SamplePrediction};
use decoder_core::internal::syntax::{control_step, Header, LeafSyntax};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk_with, LeafInfo, TreeVisitor, WalkState};
use decoder_core::{DecodeError, Node, SliceSource};
use std::collections::HashMap;

fn price(p: &mut Prob, bit: bool) -> f64 {
    let zero = f64::from(p.probability()) / f64::from(PROB_ONE);
    p.update(bit);
    -(if bit { 1.0 - zero } else { zero }).log2()
}

#[derive(Default, Clone)]
struct Shadow {
    zero: [Prob; 5],
    sign: Prob,
    sign_ctx: [Prob; 5],
    prefix: [Prob; 6],
    prefix_ctx: [[Prob; 6]; 5],
    prefix_ctx3: [[Prob; 6]; 3],
    suffix: [[Prob; 2]; 12],
    prev_zero: [[Prob; 2]; 5],
    last_nonzero: bool,
    sign_prev: [Prob; 3],
    last_sign: usize,
}

#[derive(Default, Debug, Clone, Copy)]
struct Tally {
    zero: f64,
    sign: f64,
    prefix: f64,
    suffix: f64,
    sign_ctx: f64,
    prefix_ctx: f64,
    prefix_ctx3: f64,
    suffix_ctx: f64,
    zero_prev: f64,
    sign_prev: f64,
    n: u64,
}

struct Pricing<'a> {
    inner: RangeDecoder<SliceSource<'a>>,
    shadows: HashMap<usize, Shadow>,
    tally: Tally,
    other: f64,
}

impl Coder for Pricing<'_> {
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        let zero = f64::from(p.probability()) / f64::from(PROB_ONE);
        self.inner.bit(p, bit)?;
        self.other += -(if *bit { 1.0 - zero } else { zero }).log2();
        Ok(())
    }
    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
        self.inner.bypass(bit)?;
        self.other += 1.0;
        Ok(())
    }
    fn int(&mut self, ints: &mut IntContexts, ctx: usize, v: &mut i32) -> Result<(), PayloadError> {
        let key = ints as *mut IntContexts as usize;
        ints.code_bits(&mut self.inner, ctx, v)?;
        let ctx = ctx.min(4);
        let s = self.shadows.entry(key).or_default();
        let t = &mut self.tally;
        t.n += 1;
        let nz = *v != 0;
        t.zero += price(&mut s.zero[ctx], nz);
        t.zero_prev += price(&mut s.prev_zero[ctx][usize::from(s.last_nonzero)], nz);
        s.last_nonzero = nz;
        if !nz {
            s.last_sign = 0;
            return Ok(());
        }
        t.sign_prev += price(&mut s.sign_prev[s.last_sign], *v < 0);
        s.last_sign = if *v < 0 { 2 } else { 1 };
        t.sign += price(&mut s.sign, *v < 0);
        t.sign_ctx += price(&mut s.sign_ctx[ctx], *v < 0);
        let m = v.unsigned_abs();
        let k_in = 31 - m.leading_zeros() as usize;
        let c3 = match ctx {
            0 => 0,
            1 | 2 => 1,
            _ => 2,
        };
        for k in 0..=k_in {
            let more = k < k_in;
            if k >= 12 {
                break;
            }
            t.prefix += price(&mut s.prefix[k.min(5)], more);
            t.prefix_ctx += price(&mut s.prefix_ctx[ctx][k.min(5)], more);
            t.prefix_ctx3 += price(&mut s.prefix_ctx3[c3][k.min(5)], more);
        }
        t.suffix += k_in as f64;
        // The top suffix bit context-coded by k; the rest bypass.
        if k_in >= 1 {
            let top = (m >> (k_in - 1)) & 1 == 1;
            t.suffix_ctx += price(&mut s.suffix[k_in][0], top) + (k_in - 1) as f64;
        }
        Ok(())
    }
}

struct Reader;

impl TreeVisitor for Reader {
    type Error = DecodeError;
    fn prepare_leaf<P: SamplePrediction>(&mut self, _n: &Node, _p: &P, _l: &mut LeafSyntax) {}
    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        frontier.record(&info.node, control_step(info.cquant), patch, &mut Discard);
        Ok(())
    }
}

fn main() {
    let mut all = Tally::default();
    let mut payload = 0.0;
    for path in std::env::args().skip(1) {
        let stream = std::fs::read(&path).unwrap();
        let (header, at) = Header::parse(&stream).unwrap();
        let data = &stream[at..at + header.payload_len as usize];
        let mut state = Box::<WalkState>::default();
        let mut coder = Pricing {
            inner: RangeDecoder::new(SliceSource::new(data)).unwrap(),
            shadows: HashMap::new(),
            tally: Tally::default(),
            other: 0.0,
        };
        walk_with(&header, &mut coder, &mut Reader, &mut state).unwrap();
        let t = coder.tally;
        payload += 8.0 * f64::from(header.payload_len);
        all.zero += t.zero;
        all.sign += t.sign;
        all.prefix += t.prefix;
        all.suffix += t.suffix;
        all.sign_ctx += t.sign_ctx;
        all.prefix_ctx += t.prefix_ctx;
        all.prefix_ctx3 += t.prefix_ctx3;
        all.suffix_ctx += t.suffix_ctx;
        all.zero_prev += t.zero_prev;
        all.sign_prev += t.sign_prev;
        all.n += t.n;
    }
    let t = all;
    let pct = |d: f64| 100.0 * d / payload;
    println!("payload bits {payload:.0}, ints {}", t.n);
    println!(
        "shadow base: zero {:.1}% sign {:.1}% prefix {:.1}% suffix {:.1}%",
        pct(t.zero),
        pct(t.sign),
        pct(t.prefix),
        pct(t.suffix)
    );
    println!("sign on ctx: {:+.2}%", pct(t.sign_ctx - t.sign));
    println!("prefix on ctx (5): {:+.2}%", pct(t.prefix_ctx - t.prefix));
    println!("prefix on ctx (3): {:+.2}%", pct(t.prefix_ctx3 - t.prefix));
    println!(
        "top suffix bit coded: {:+.2}%",
        pct(t.suffix_ctx - t.suffix)
    );
    println!(
        "zero also on previous int's zero: {:+.2}%",
        pct(t.zero_prev - t.zero)
    );
    println!(
        "sign on previous int sign: {:+.2}%",
        pct(t.sign_prev - t.sign)
    );
}
