//! Where a grayscale stream's bits go: decodes each stream with a coder that prices every
//! decision at the probability its context gave it before the decision (`-log2 p`; a bypass
//! bit costs 1) and sums the prices by syntax element: split flags, the leaf's model, control
//! quantiser and control coding, and the control residuals by class (a leaf's first value,
//! DPCM edges and interior, transform detail bands) and by part (zero flag, sign, magnitude
//! prefix, bypass suffix). The sum is the payload's ideal length, which the range coder
//! reaches to within a few bytes.
//!
//! `cargo run --release -p host-encoder --example bit_budget -- STREAM.pifs...`

use decoder_core::internal::entropy::{
    Coder, IntContexts, PayloadError, Prob, RangeDecoder, PROB_ONE,
};
use decoder_core::internal::format::MAX_LEAF_LOG2;
use decoder_core::internal::model::MODEL_COUNT;
use decoder_core::internal::prediction::Frontier;
use decoder_core::internal::syntax::{control_step, Header, CONTROL_CLASSES, STEP_GROUPS};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk_with, LeafInfo, TreeVisitor, WalkState};
use decoder_core::{DecodeError, SliceSource};
use std::collections::{BTreeMap, HashMap};

/// The syntax element a context codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Element {
    Split,
    Model,
    Cquant,
    Coding,
    /// Control residuals of a class, in one of its parts.
    Residual(usize, Part),
}

/// A part of a coded integer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Part {
    Zero,
    Sign,
    Prefix,
    Suffix,
}

const CLASS_NAMES: [&str; CONTROL_CLASSES] = [
    "first value (one neighbour or none)",
    "first value (both neighbours)",
    "DPCM first row and column",
    "DPCM interior",
    "transform detail, finest band",
    "transform detail, second band",
    "transform detail, coarser bands",
];

impl Element {
    fn name(self) -> String {
        match self {
            Element::Split => "split flags".into(),
            Element::Model => "leaf model".into(),
            Element::Cquant => "control quantiser".into(),
            Element::Coding => "control coding (DPCM or transform)".into(),
            Element::Residual(class, part) => format!(
                "residuals, {}: {}",
                CLASS_NAMES.get(class).copied().unwrap_or("?"),
                match part {
                    Part::Zero => "zero flags",
                    Part::Sign => "signs",
                    Part::Prefix => "magnitude prefixes",
                    Part::Suffix => "magnitude suffixes (bypass)",
                }
            ),
        }
    }
}

/// The element of every context of a stream's contexts, by address, in
/// `Contexts::for_each_prob`'s order (split, model, cquant, coding, then each class's
/// integers in step group order).
fn elements(state: &mut WalkState) -> HashMap<usize, Element> {
    let splits = usize::from(MAX_LEAF_LOG2) + 1;
    let models = splits * MODEL_COUNT;
    let cquants = MODEL_COUNT * 16;
    let codings = MODEL_COUNT;
    let mut map = HashMap::new();
    let mut i = 0;
    state.contexts.for_each_prob(|p: &mut Prob| {
        let element = if i < splits {
            Element::Split
        } else if i < splits + models {
            Element::Model
        } else if i < splits + models + cquants {
            Element::Cquant
        } else if i < splits + models + cquants + codings {
            Element::Coding
        } else {
            let k = i - (splits + models + cquants + codings);
            let class = (k / IntContexts::COUNT) % CONTROL_CLASSES;
            let within = k % IntContexts::COUNT;
            // The zero flags, the sign, the prefix bits (IntContexts::for_each_prob).
            let zero_contexts = IntContexts::COUNT - 1 - PREFIX_CONTEXTS;
            let part = if within < zero_contexts {
                Part::Zero
            } else if within == zero_contexts {
                Part::Sign
            } else {
                Part::Prefix
            };
            Element::Residual(class, part)
        };
        map.insert(p as *mut Prob as usize, element);
        i += 1;
    });
    assert_eq!(
        i,
        splits + models + cquants + codings + STEP_GROUPS * CONTROL_CLASSES * IntContexts::COUNT
    );
    map
}

/// Prefix contexts of an integer (`IntContexts::COUNT` is the zero flags, the sign and these).
const PREFIX_CONTEXTS: usize = decoder_core::internal::entropy::PREFIX_CONTEXTS;

/// A range decoder that prices what it decodes.
struct Pricing<'a> {
    inner: RangeDecoder<SliceSource<'a>>,
    elements: HashMap<usize, Element>,
    /// The class of the integer being decoded (for its bypass bits).
    class: Option<usize>,
    bits: BTreeMap<Element, f64>,
    /// Decisions coded, by element.
    decisions: BTreeMap<Element, u64>,
}

impl Coder for Pricing<'_> {
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        let zero = f64::from(p.probability()) / f64::from(PROB_ONE);
        let at = p as *mut Prob as usize;
        self.inner.bit(p, bit)?;
        let cost = -(if *bit { 1.0 - zero } else { zero }).log2();
        let element = self
            .elements
            .get(&at)
            .copied()
            .expect("a context of the stream");
        *self.bits.entry(element).or_default() += cost;
        *self.decisions.entry(element).or_default() += 1;
        Ok(())
    }

    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
        self.inner.bypass(bit)?;
        let class = self.class.expect("bypass bits only in integers");
        *self
            .bits
            .entry(Element::Residual(class, Part::Suffix))
            .or_default() += 1.0;
        Ok(())
    }

    fn int(&mut self, ints: &mut IntContexts, ctx: usize, v: &mut i32) -> Result<(), PayloadError> {
        let mut first = 0;
        ints.for_each_prob(|p| {
            if first == 0 {
                first = p as *mut Prob as usize;
            }
        });
        self.class = match self.elements.get(&first) {
            Some(Element::Residual(class, _)) => Some(*class),
            _ => None,
        };
        let result = ints.code_bits(self, ctx, v);
        self.class = None;
        result
    }
}

/// A leaf's model and control quantiser.
#[derive(Debug, Clone, Copy)]
struct Choice {
    model: u8,
    cquant: u8,
}

/// What a leaf's quantiser is conditioned on: a key from the leaves of a stream (in coding
/// order) and the leaf's index.
type Condition<'a> = &'a dyn Fn(&[Choice], usize) -> u32;

/// A decoder that draws nothing but what prediction needs, and notes each leaf's choices in
/// coding order.
struct Reader(Vec<Choice>);

impl TreeVisitor for Reader {
    type Error = DecodeError;
    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), DecodeError> {
        self.0.push(Choice {
            model: info.model,
            cquant: info.cquant,
        });
        frontier.record(&info.node, control_step(info.cquant), patch, &mut Discard);
        Ok(())
    }
}

fn main() {
    let mut total: BTreeMap<Element, f64> = BTreeMap::new();
    let mut payload_bits = 0.0;
    let mut leaves: Vec<Vec<Choice>> = Vec::new();
    let mut decisions: BTreeMap<Element, u64> = BTreeMap::new();
    for path in std::env::args().skip(1) {
        let stream = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let (header, at) = Header::parse(&stream).unwrap_or_else(|e| panic!("{path}: {e}"));
        assert_eq!(header.channels, 1, "{path}: grayscale streams only");
        let payload = &stream[at..at + header.payload_len as usize];
        let mut state = Box::<WalkState>::default();
        let elements = elements(&mut state);
        let mut coder = Pricing {
            inner: RangeDecoder::new(SliceSource::new(payload)).expect("a payload"),
            elements,
            class: None,
            bits: BTreeMap::new(),
            decisions: BTreeMap::new(),
        };
        let mut reader = Reader(Vec::new());
        walk_with(&header, &mut coder, &mut reader, &mut state)
            .unwrap_or_else(|e| panic!("{path}: {e}"));
        leaves.push(reader.0);
        let priced: f64 = coder.bits.values().sum();
        eprintln!(
            "{path}: {} payload bytes, {:.0} bytes priced",
            header.payload_len,
            priced / 8.0
        );
        payload_bits += 8.0 * f64::from(header.payload_len);
        for (e, b) in coder.bits {
            *total.entry(e).or_default() += b;
        }
        for (e, n) in coder.decisions {
            *decisions.entry(e).or_default() += n;
        }
    }
    let priced: f64 = total.values().sum();
    let share = |keep: &dyn Fn(&Element) -> bool| {
        100.0
            * total
                .iter()
                .filter(|(e, _)| keep(e))
                .map(|(_, b)| b)
                .sum::<f64>()
            / priced
    };
    let part = |want: Part| move |e: &Element| matches!(e, Element::Residual(_, p) if *p == want);
    println!(
        "summary: split flags {:.1}%, leaf model, quantiser and coding {:.1}%, residual zero \
         flags {:.1}%, signs {:.1}%, magnitudes {:.1}% (prefixes {:.1}%, bypass suffixes {:.1}%)",
        share(&|e| *e == Element::Split),
        share(&|e| matches!(e, Element::Model | Element::Cquant | Element::Coding)),
        share(&part(Part::Zero)),
        share(&part(Part::Sign)),
        share(&|e| part(Part::Prefix)(e) || part(Part::Suffix)(e)),
        share(&part(Part::Prefix)),
        share(&part(Part::Suffix)),
    );
    // What the control quantiser would cost with other conditioning: the empirical
    // conditional entropy over all leaves (an adaptive coder pays it and its learning).
    let entropy = |given: Condition| {
        let mut joint: HashMap<(u32, u8), f64> = HashMap::new();
        let mut marginal: HashMap<u32, f64> = HashMap::new();
        for stream in &leaves {
            for (i, leaf) in stream.iter().enumerate() {
                let k = given(stream, i);
                *joint.entry((k, leaf.cquant)).or_default() += 1.0;
                *marginal.entry(k).or_default() += 1.0;
            }
        }
        joint
            .iter()
            .map(|((k, _), n)| -n * (n / marginal[k]).log2())
            .sum::<f64>()
    };
    let model = |s: &[Choice], i: usize| u32::from(s[i].model);
    let previous = |s: &[Choice], i: usize| match i {
        0 => 255,
        _ => u32::from(s[i - 1].cquant),
    };
    let by_model = entropy(&model);
    let by_prev = entropy(&previous);
    let by_model_prev = entropy(&|s, i| model(s, i) << 8 | previous(s, i));
    let coded = total
        .iter()
        .filter(|(e, _)| **e == Element::Cquant)
        .map(|(_, b)| b)
        .sum::<f64>();
    println!(
        "control quantiser: {:.1}% of the bits as coded; empirical entropy given the model \
         {:.1}%, given the previous leaf's quantiser {:.1}%, given both {:.1}% ({} leaves)",
        100.0 * coded / priced,
        100.0 * by_model / priced,
        100.0 * by_prev / priced,
        100.0 * by_model_prev / priced,
        leaves.iter().map(Vec::len).sum::<usize>()
    );
    println!("| element | share of the bits | bits per context-coded decision |");
    println!("|---|---:|---:|");
    for (e, b) in &total {
        let per = match decisions.get(e) {
            Some(&n) if n > 0 => format!("{:.3}", b / n as f64),
            _ => "(bypass)".into(),
        };
        println!("| {} | {:.1}% | {per} |", e.name(), 100.0 * b / priced);
    }
    println!(
        "| (priced / payload) | {:.4} |",
        priced / payload_bits.max(1.0)
    );
}
