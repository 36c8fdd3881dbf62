//! Trains the probabilities every adaptive context starts a stream with: encodes each training
//! image at each rate, reads back the contexts' states at the end of every stream, and writes
//! their mean probability of a `0` (over the streams that used the context) as
//! `decoder-core/src/syntax/initial_contexts.rs` and `docs/initial-contexts.md`. Luma's contexts
//! are trained on grayscale streams, the chroma contexts on colour streams of the same images
//! (those that are in colour).
//!
//! `cargo run --release -p host-encoder --example train_contexts -- [--chroma-only] [IMAGE...]`
//!
//! With `--chroma-only`, only the chroma table is trained; luma's is kept as it is (format 15
//! trained chroma's and kept luma's, last trained for format 12).
//!
//! Without images, the thesis's test images (`../shared/images/sipi/*.png`): training on them
//! keeps the Kodak images, on which the codec is measured, out of the training set. Changing
//! the table changes the bitstream: bump its version and regenerate the golden vectors.

use decoder_core::internal::entropy::{Prob, RangeDecoder, INITIAL_COUNT, PROB_ONE};
use decoder_core::internal::prediction::{Frontier, SamplePrediction};
use decoder_core::internal::syntax::initial_contexts::INITIAL_PROBABILITIES;
use decoder_core::internal::syntax::{
    control_step, ChromaContexts, Contexts, Header, LeafSyntax, CHROMA_CONTEXT_COUNT, CONTEXT_COUNT,
};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk, LeafInfo, TreeVisitor};
use decoder_core::DecodeError;
use decoder_core::Node;
use decoder_core::SliceSource;
use host_encoder::{analyse, analyse_colour, io, EncoderConfig, Target};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The rates every image is encoded at: those of the benchmark.
const RATES: [f64; 4] = [0.05, 0.1, 0.25, 0.5];

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let chroma_only = args.first().is_some_and(|a| a == "--chroma-only");
    if chroma_only {
        args.remove(0);
    }
    let mut images: Vec<PathBuf> = args.into_iter().map(PathBuf::from).collect();
    if images.is_empty() {
        let dir = root.join("../shared/images/sipi");
        let mut found: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "png"))
            .collect();
        found.sort();
        images = found;
    }
    let mut luma = Tally::new(CONTEXT_COUNT);
    let mut chroma = Tally::new(CHROMA_CONTEXT_COUNT);
    for path in &images {
        let plane = io::load_luma(path).unwrap_or_else(|e| panic!("{e}"));
        let pixels = plane.data.len();
        for bpp in RATES.iter().copied().filter(|_| !chroma_only) {
            let target = Target::Bpp(bpp);
            let config = EncoderConfig::for_targets(&[target], pixels);
            let analysis = analyse(plane.clone(), &config, &|_| {}).expect("analysis");
            let encoded = analysis.encode(target).expect("encode");
            let (mut contexts, _) = final_contexts(&encoded.bytes).expect("a valid stream");
            luma.add(|f| contexts.for_each_prob(f));
            eprintln!(
                "{} at {bpp} bpp: {} bytes",
                path.display(),
                encoded.bytes.len()
            );
        }
        let Ok(io::Loaded::Rgb {
            width,
            height,
            data,
        }) = io::load_image(path)
        else {
            continue;
        };
        for bpp in RATES {
            let target = Target::Bpp(bpp);
            let config = EncoderConfig::for_targets(&[target], pixels);
            let analysis =
                analyse_colour(width, height, data.clone(), &config, &|_| {}).expect("analysis");
            let encoded = analysis.encode(target).expect("encode");
            let (_, contexts) = final_contexts(&encoded.bytes).expect("a valid stream");
            let mut contexts = contexts.expect("a colour stream's chroma contexts");
            chroma.add(|f| contexts.for_each_prob(f));
            eprintln!(
                "{} in colour at {bpp} bpp: {} bytes",
                path.display(),
                encoded.bytes.len()
            );
        }
    }
    let streams = if chroma_only {
        chroma.streams
    } else {
        luma.streams
    };
    let names: Vec<String> = images
        .iter()
        .map(|p| {
            p.file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned())
        })
        .collect();
    let source = format!(
        "{} ({} streams: {} at {:?} bpp)",
        names.join(", "),
        streams,
        "each",
        RATES
    );
    let chroma_source = format!(
        "the colour images among them ({} streams at the same rates)",
        chroma.streams
    );
    let (luma, source) = if chroma_only {
        let kept = format!("{source}, for format 12 (kept since)");
        (INITIAL_PROBABILITIES.to_vec(), kept)
    } else {
        (luma.table(), source)
    };
    let tables = Tables {
        luma,
        chroma: chroma.table(),
        source,
        chroma_source,
    };
    write_rust(
        &root.join("decoder-core/src/syntax/initial_contexts.rs"),
        &tables,
    );
    write_markdown(&root.join("docs/initial-contexts.md"), &tables);
    eprintln!(
        "wrote the tables of {CONTEXT_COUNT} + {CHROMA_CONTEXT_COUNT} initial probabilities, trained on {} and {}",
        tables.source, tables.chroma_source
    );
}

/// The mean final probability of a `0` of each context over the streams that used it.
struct Tally {
    sums: Vec<f64>,
    uses: Vec<u32>,
    streams: usize,
}

impl Tally {
    fn new(count: usize) -> Self {
        Tally {
            sums: vec![0.0; count],
            uses: vec![0; count],
            streams: 0,
        }
    }

    /// Adds one stream's final contexts, visited by `visit` in table order.
    fn add(&mut self, visit: impl FnOnce(&mut dyn FnMut(&mut Prob))) {
        let mut i = 0;
        visit(&mut |p: &mut Prob| {
            if p.count() > INITIAL_COUNT {
                self.sums[i] += f64::from(p.probability()) / f64::from(PROB_ONE);
                self.uses[i] += 1;
            }
            i += 1;
        });
        self.streams += 1;
    }

    /// The table, in 1/256; unused contexts start at one half.
    fn table(&self) -> Vec<u8> {
        self.sums
            .iter()
            .zip(&self.uses)
            .map(|(&s, &n)| {
                let p = if n == 0 { 0.5 } else { s / f64::from(n) };
                (p * 256.0).round().clamp(1.0, 255.0) as u8
            })
            .collect()
    }
}

/// Both trained tables and what they were trained on.
struct Tables {
    luma: Vec<u8>,
    chroma: Vec<u8>,
    source: String,
    chroma_source: String,
}

/// The contexts at the end of `stream`'s payload: luma's, and for a colour stream the chroma
/// contexts as they were before its last chroma plane was coded (what the walk shows a visitor).
fn final_contexts(stream: &[u8]) -> Result<(Contexts, Option<ChromaContexts>), DecodeError> {
    struct Reader(Option<ChromaContexts>);
    impl TreeVisitor for Reader {
        type Error = DecodeError;
        fn prepare_chroma<P: SamplePrediction>(
            &mut self,
            _node: &Node,
            _plane: usize,
            _prediction: &P,
            contexts: &ChromaContexts,
            _leaf: &mut LeafSyntax,
        ) {
            self.0 = Some(contexts.clone());
        }
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
    let (header, at) = Header::parse(stream)?;
    let payload = &stream[at..at + header.payload_len as usize];
    let mut decoder = RangeDecoder::new(SliceSource::new(payload))?;
    let mut reader = Reader(None);
    let luma = walk::<_, _, { 1 << 16 }>(&header, &mut decoder, &mut reader)?.contexts;
    Ok((luma, reader.0))
}

fn rows(table: &[u8]) -> impl Iterator<Item = String> + '_ {
    table
        .chunks(16)
        .map(|row| row.iter().map(u8::to_string).collect::<Vec<_>>().join(", "))
}

fn write_rust(path: &Path, tables: &Tables) {
    let mut out = String::new();
    out.push_str(
        "//! The probability every adaptive context starts a stream with: entry `i` is `P(bit = 0)`\n\
         //! in 1/256 for the `i`-th context in [`super::Contexts::for_each_prob`] order (luma) or\n\
         //! [`super::ChromaContexts::for_each_prob`] order (chroma)\n\
         //! ([`crate::entropy::Prob::initial`]).\n//!\n",
    );
    let _ = writeln!(out, "//! Luma trained on {}.", tables.source);
    let _ = writeln!(out, "//! Chroma trained on {}.", tables.chroma_source);
    out.push_str(
        "//! Generated by `cargo run --release -p host-encoder --example train_contexts`, with the\n\
         //! specification's tables (`docs/initial-contexts.md`); do not edit by hand.\n\n\
         /// Initial probabilities of a `0`, in 1/256, in [`super::Contexts::for_each_prob`]\n\
         /// order.\n\
         pub const INITIAL_PROBABILITIES: [u8; super::CONTEXT_COUNT] = [\n",
    );
    for row in rows(&tables.luma) {
        let _ = writeln!(out, "    {row},");
    }
    out.push_str(
        "];\n\n\
         /// Initial probabilities of a `0` of the chroma contexts, in 1/256, in\n\
         /// [`super::ChromaContexts::for_each_prob`] order.\n\
         pub const CHROMA_INITIAL_PROBABILITIES: [u8; super::CHROMA_CONTEXT_COUNT] = [\n",
    );
    for row in rows(&tables.chroma) {
        let _ = writeln!(out, "    {row},");
    }
    out.push_str("];\n");
    std::fs::write(path, out).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// `table` as a fenced block of rows.
fn code_block(out: &mut String, table: &[u8]) {
    out.push_str("```\n");
    for row in rows(table) {
        let _ = writeln!(out, "{row}");
    }
    out.push_str("```\n");
}

fn write_markdown(path: &Path, tables: &Tables) {
    let mut out = String::from("# Initial context probabilities\n\n");
    let _ = writeln!(
        out,
        "Part of the bitstream specification ([`bitstream.md`](bitstream.md), section 2): the\n\
         probability `P(bit = 0)`, in 1/256, that each adaptive context starts every stream with,\n\
         in the order given there, 16 per line. Generated by\n\
         `cargo run --release -p host-encoder --example train_contexts`.\n\n\
         ## Luma\n\n\
         The {} contexts of every stream. Trained on {}.\n",
        tables.luma.len(),
        tables.source
    );
    code_block(&mut out, &tables.luma);
    out.push_str("\n## Chroma\n\n");
    let _ = writeln!(
        out,
        "The {} chroma contexts of a colour stream. Trained on {}.\n",
        tables.chroma.len(),
        tables.chroma_source
    );
    code_block(&mut out, &tables.chroma);
    std::fs::write(path, out).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}
