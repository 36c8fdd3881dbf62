//! Trains the probabilities every adaptive context starts a stream with: encodes each training
//! image at each rate, reads back the contexts' states at the end of every stream, and writes
//! their mean probability of a `0` (over the streams that used the context) as
//! `decoder-core/src/syntax/initial_contexts.rs` and `docs/initial-contexts.md`.
//!
//! `cargo run --release -p host-encoder --example train_contexts -- [IMAGE...]`
//!
//! Without images, the thesis's test images (`../shared/images/sipi/*.png`): training on them
//! keeps the Kodak images, on which the codec is measured, out of the training set. Changing
//! the table changes the bitstream: bump its version and regenerate the golden vectors.

use decoder_core::internal::entropy::{RangeDecoder, INITIAL_COUNT, PROB_ONE};
use decoder_core::internal::prediction::{Frontier, SamplePrediction};
use decoder_core::internal::syntax::{control_step, Contexts, Header, LeafSyntax, CONTEXT_COUNT};
use decoder_core::internal::synthesis::{Discard, Patch};
use decoder_core::internal::walk::{walk, LeafInfo, TreeVisitor};
use decoder_core::DecodeError;
use decoder_core::Node;
use decoder_core::SliceSource;
use host_encoder::{analyse, io, EncoderConfig, Target};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The rates every image is encoded at: those of the benchmark.
const RATES: [f64; 4] = [0.05, 0.1, 0.25, 0.5];

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut images: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
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
    let mut sums = vec![0.0f64; CONTEXT_COUNT];
    let mut uses = vec![0u32; CONTEXT_COUNT];
    let mut streams = 0;
    for path in &images {
        let plane = io::load_luma(path).unwrap_or_else(|e| panic!("{e}"));
        let pixels = plane.data.len();
        for bpp in RATES {
            let target = Target::Bpp(bpp);
            let config = EncoderConfig::for_targets(&[target], pixels);
            let analysis = analyse(plane.clone(), &config, &|_| {}).expect("analysis");
            let encoded = analysis.encode(target).expect("encode");
            let mut contexts = final_contexts(&encoded.bytes).expect("a valid stream");
            let mut i = 0;
            contexts.for_each_prob(|p| {
                if p.count() > INITIAL_COUNT {
                    sums[i] += f64::from(p.probability()) / f64::from(PROB_ONE);
                    uses[i] += 1;
                }
                i += 1;
            });
            streams += 1;
            eprintln!(
                "{} at {bpp} bpp: {} bytes",
                path.display(),
                encoded.bytes.len()
            );
        }
    }
    // Unused contexts start at one half.
    let table: Vec<u8> = sums
        .iter()
        .zip(&uses)
        .map(|(&s, &n)| {
            let p = if n == 0 { 0.5 } else { s / f64::from(n) };
            (p * 256.0).round().clamp(1.0, 255.0) as u8
        })
        .collect();
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
    write_rust(
        &root.join("decoder-core/src/syntax/initial_contexts.rs"),
        &table,
        &source,
    );
    write_markdown(&root.join("docs/initial-contexts.md"), &table, &source);
    eprintln!("wrote the table of {CONTEXT_COUNT} initial probabilities, trained on {source}");
}

/// The contexts at the end of `stream`'s payload.
fn final_contexts(stream: &[u8]) -> Result<Contexts, DecodeError> {
    struct Reader;
    impl TreeVisitor for Reader {
        type Error = DecodeError;

        fn split(&mut self, _node: &Node) -> bool {
            false
        }
        fn prepare_leaf<P: SamplePrediction>(
            &mut self,
            _node: &Node,
            _prediction: &P,
            _leaf: &mut LeafSyntax,
        ) {
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
    Ok(walk::<_, _, { 1 << 16 }>(&header, &mut decoder, &mut Reader)?.contexts)
}

fn rows(table: &[u8]) -> impl Iterator<Item = String> + '_ {
    table
        .chunks(16)
        .map(|row| row.iter().map(u8::to_string).collect::<Vec<_>>().join(", "))
}

fn write_rust(path: &Path, table: &[u8], source: &str) {
    let mut out = String::new();
    out.push_str(
        "//! The probability every adaptive context starts a stream with: entry `i` is `P(bit = 0)`\n\
         //! in 1/256 for the `i`-th context in [`super::Contexts::for_each_prob`] order\n\
         //! ([`crate::entropy::Prob::initial`]).\n//!\n",
    );
    let _ = writeln!(out, "//! Trained on {source}.");
    out.push_str(
        "//! Generated by `cargo run --release -p host-encoder --example train_contexts`, with the\n\
         //! specification's table (`docs/initial-contexts.md`); do not edit by hand.\n\n\
         /// Initial probabilities of a `0`, in 1/256, in [`super::Contexts::for_each_prob`]\n\
         /// order.\n\
         pub const INITIAL_PROBABILITIES: [u8; super::CONTEXT_COUNT] = [\n",
    );
    for row in rows(table) {
        let _ = writeln!(out, "    {row},");
    }
    out.push_str("];\n");
    std::fs::write(path, out).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

fn write_markdown(path: &Path, table: &[u8], source: &str) {
    let mut out = String::from("# Initial context probabilities\n\n");
    let _ = writeln!(
        out,
        "Part of the bitstream specification ([`bitstream.md`](bitstream.md), section 2): the\n\
         probability `P(bit = 0)`, in 1/256, that each of the {} adaptive contexts starts every\n\
         stream with, in the order given there, 16 per line. Trained on {source}; generated by\n\
         `cargo run --release -p host-encoder --example train_contexts`.\n",
        table.len()
    );
    out.push_str("```\n");
    for row in rows(table) {
        let _ = writeln!(out, "{row}");
    }
    out.push_str("```\n");
    std::fs::write(path, out).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}
