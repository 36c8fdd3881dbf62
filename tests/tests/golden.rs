//! Golden vectors: `.pifs` streams in `tests/golden/` with the SHA-256 of their decoded pixels in
//! `tests/golden/golden.txt`. The normal tests decode them with decoder-core alone (no encoder),
//! so any change of what a stream decodes to (syntax, synthesis, rounding) fails here.
//!
//! The streams are made from the deterministic synthetic images of `common` by the ignored test
//! `regenerate`:
//!
//! ```text
//! cargo test -p pifs-tests --test golden -- --ignored regenerate
//! ```
//!
//! Regenerate only for an intended format change, together with a bump of
//! `decoder_core::internal::format::VERSION`.

mod common;

use common::{analyse_with, decode_all, golden_dir, golden_list, sha256_hex, CoverageSink};
use decoder_core::internal::format::{MAGIC, VERSION};
use decoder_core::internal::model::MODELS;
use decoder_core::internal::syntax::control::{
    WeightQuantiser, WEIGHT_QUANTISERS, WEIGHT_QUANTISER_KINDS,
};
use decoder_core::internal::syntax::{ControlCoding, FLAG_CODEBOOKS};
use decoder_core::LeafInfo;
use host_encoder::{EncoderConfig, Plane, Target};
use std::collections::BTreeSet;

/// The 'wquant' value of Lloyd-Max codebook weights.
fn codebook_wquant() -> u8 {
    WEIGHT_QUANTISER_KINDS
        .iter()
        .position(|&k| k == WeightQuantiser::Codebook)
        .expect("a codebook weight quantiser") as u8
}

/// One golden stream: file name, image, encoder settings, and the targets to try in order (the
/// first that gives a stream with the required property is kept).
struct Spec {
    file: &'static str,
    plane: Plane,
    config: EncoderConfig,
    targets: Vec<Target>,
    /// The stream must carry Lloyd-Max codebooks and code leaves with them.
    needs_codebooks: bool,
    /// A colour image (RGB, `plane`'s size): the stream is a colour stream.
    rgb: Option<Vec<u8>>,
}

/// The golden set.
fn specs() -> Vec<Spec> {
    let config = |min_leaf_log2, max_leaf_log2, codebook_levels| EncoderConfig {
        min_leaf_log2,
        max_leaf_log2,
        codebook_levels,
        fit_weights: true,
        ..EncoderConfig::default()
    };
    let image64 = common::synthetic(64, 64, 7, 6);
    let plain = |file, plane, config, target| Spec {
        file,
        plane,
        config,
        targets: vec![target],
        needs_codebooks: false,
        rgb: None,
    };
    vec![
        plain(
            "gradient_16x16.pifs",
            common::gradient(16, 16),
            config(2, 4, 0),
            Target::Bpp(2.0),
        ),
        plain(
            "textured_33x17.pifs",
            common::synthetic(33, 17, 5, 12),
            config(1, 4, 8),
            Target::Bytes(160),
        ),
        plain(
            "low_64x64.pifs",
            image64.clone(),
            config(2, 5, 8),
            Target::Bpp(0.2),
        ),
        plain(
            "high_64x64.pifs",
            image64,
            config(2, 5, 8),
            Target::Bpp(1.5),
        ),
        Spec {
            // The encoder picks codebooks only where they pay for their header bytes: near the
            // best quality of a larger image. Which rate that is depends on the encoder's
            // tuning, so several are tried. Leaves from 16 px: at 8 px the 9x9 model is a
            // pixel grid, which has no weights and wins where the weighted leaves would.
            file: "codebooks_128x128.pifs",
            plane: common::synthetic(128, 128, 1, 4),
            config: config(4, 5, 16),
            targets: vec![
                Target::Bpp(1.0),
                Target::Bpp(2.0),
                Target::Bpp(1.5),
                Target::Bpp(3.0),
                Target::Psnr(38.0),
                Target::Bpp(0.75),
                Target::Bpp(4.0),
            ],
            needs_codebooks: true,
            rgb: None,
        },
        Spec {
            // Odd sizes (chroma planes of 19 x 15), leaves from 2 px (chroma leaves of 1 px)
            // to 32 px.
            file: "colour_37x29.pifs",
            plane: common::synthetic(37, 29, 3, 6),
            config: config(1, 5, 0),
            targets: vec![Target::Bpp(1.5)],
            needs_codebooks: false,
            rgb: Some(common::synthetic_rgb(37, 29, 11)),
        },
    ]
}

/// Decodes `bytes` and records which models and quantisers its leaves use.
fn usage_of(name: &str, bytes: &[u8], mut usage: Usage) -> Usage {
    let h = decoder_core::Header::read(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
    let mut sink = CoverageSink::new(u32::from(h.width), u32::from(h.height));
    decoder_core::Decoder::new(bytes)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .observe(|leaf| usage.leaf(leaf))
        .decode(&mut sink)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    usage
}

/// Checks that the golden set reaches every reconstruction path of decoder-core: all model
/// types, all weight quantisers (default, both uniform steps, Lloyd-Max codebook), and pixel
/// grids with both control codings.
fn assert_full_usage(usage: &Usage) {
    let all_models: BTreeSet<u8> = (0..MODELS.len() as u8).collect();
    let all_wquants: BTreeSet<u8> = (0..WEIGHT_QUANTISERS as u8).collect();
    assert_eq!(usage.models, all_models, "model types used");
    assert_eq!(usage.wquants, all_wquants, "weight quantisers used");
    // Pixel grids code only their block's values, with both codings.
    assert!(!usage.pixel_grids.is_empty(), "no pixel grid");
    assert_eq!(
        usage.pixel_grid_codings,
        BTreeSet::from([0, 1]),
        "pixel grid codings"
    );
    assert!(
        usage.leaf_sizes.len() >= 4,
        "leaf sizes {:?}",
        usage.leaf_sizes
    );
}

#[test]
#[ignore = "writes tests/golden/; run explicitly to regenerate the golden vectors"]
fn regenerate() {
    let dir = golden_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let mut list = String::from(
        "# <file> <width> <height> <sha256 of the decoded pixels>\n\
         # Generated by: cargo test -p pifs-tests --test golden -- --ignored regenerate\n",
    );
    let mut total = Usage::default();
    for spec in specs() {
        let file = spec.file;
        let analysis = match &spec.rgb {
            Some(rgb) => host_encoder::analyse_colour(
                spec.plane.width,
                spec.plane.height,
                rgb.clone(),
                &spec.config,
                &|_| {},
            )
            .expect("colour analysis"),
            None => analyse_with(spec.plane.clone(), &spec.config),
        };
        let mut chosen = None;
        for &target in &spec.targets {
            let e = match analysis.encode(target) {
                Ok(e) => e,
                Err(err) if spec.targets.len() > 1 => {
                    println!("{file}: {target:?}: {err}");
                    continue;
                }
                Err(err) => panic!("{file}: {target:?}: {err}"),
            };
            let usage = usage_of(file, &e.bytes, Usage::default());
            if !spec.needs_codebooks || usage.wquants.contains(&codebook_wquant()) {
                chosen = Some((target, e));
                break;
            }
            println!("{file}: {target:?} codes no leaf with a codebook");
        }
        let (target, e) = chosen.unwrap_or_else(|| {
            panic!("{file}: no target gives a stream with codebook-coded leaves; adjust its spec")
        });
        let (header, pixels) = decode_all(&e.bytes).unwrap();
        assert!(
            pixels == e.reconstruction,
            "{file}: decode != reconstruction"
        );
        std::fs::write(dir.join(file), &e.bytes).unwrap();
        list.push_str(&format!(
            "{file} {} {} {}\n",
            header.width,
            header.height,
            sha256_hex(&pixels)
        ));
        total = usage_of(file, &e.bytes, total);
        println!(
            "{file}: {target:?}: {}x{}, {} bytes, {:.2} dB, codebooks {}, leaves {}",
            header.width,
            header.height,
            e.bytes.len(),
            e.psnr,
            header.has_codebooks(),
            e.leaves
        );
    }
    std::fs::write(dir.join("golden.txt"), list).unwrap();
    assert_full_usage(&total);
    regenerate_packets(&dir);
}

/// One golden packet set: file, image (and its colour), packet size, whole budget, and the
/// packets the lossy check loses.
struct PacketSpec {
    file: &'static str,
    plane: Plane,
    rgb: Option<Vec<u8>>,
    size: usize,
    bytes: usize,
    lost: Vec<u16>,
}

fn packet_specs() -> Vec<PacketSpec> {
    vec![
        PacketSpec {
            file: "packets_gray_64x48.pifsp",
            plane: common::synthetic(64, 48, 21, 5),
            rgb: None,
            size: 48,
            bytes: 8 * 48,
            lost: vec![2, 5],
        },
        PacketSpec {
            file: "packets_colour_40x32.pifsp",
            plane: common::synthetic(40, 32, 22, 4),
            rgb: Some(common::synthetic_rgb(40, 32, 23)),
            size: 64,
            bytes: 6 * 64,
            lost: vec![1, 4],
        },
    ]
}

/// Writes the golden packet sets and `packets.txt`.
fn regenerate_packets(dir: &std::path::Path) {
    use host_encoder::packets::{assemble, frame, packetise, PacketOptions};
    let mut list = String::from(
        "# <file> <width> <height> <lost indices> <sha256 of all assembled> <sha256 without the lost>\n\
         # Generated by: cargo test -p pifs-tests --test golden -- --ignored regenerate\n",
    );
    for spec in packet_specs() {
        let config = EncoderConfig {
            codebook_levels: 0,
            ..EncoderConfig::default()
        };
        let analysis = match &spec.rgb {
            Some(rgb) => host_encoder::analyse_colour(
                spec.plane.width,
                spec.plane.height,
                rgb.clone(),
                &config,
                &|_| {},
            )
            .expect("colour analysis"),
            None => analyse_with(spec.plane.clone(), &config),
        };
        let options = PacketOptions {
            size: spec.size,
            image_id: 7,
            preview: true,
            repeat_preview: false,
            parity: 0,
        };
        let made = packetise(&analysis, &config, Target::Bytes(spec.bytes), &options)
            .unwrap_or_else(|e| panic!("{}: {e}", spec.file));
        let all = assemble(made.packets.iter().map(Vec::as_slice), u64::MAX).unwrap();
        assert_eq!(all.pixels, made.reconstruction, "{}", spec.file);
        let kept: Vec<&[u8]> = made
            .packets
            .iter()
            .enumerate()
            .filter(|(i, _)| !spec.lost.contains(&(*i as u16)))
            .map(|(_, p)| p.as_slice())
            .collect();
        let lossy = assemble(kept, u64::MAX).unwrap();
        assert!(lossy.preview && lossy.missing == spec.lost, "{}", spec.file);
        std::fs::write(dir.join(spec.file), frame(&made.packets)).unwrap();
        let lost: Vec<String> = spec.lost.iter().map(u16::to_string).collect();
        list.push_str(&format!(
            "{} {} {} {} {} {}\n",
            spec.file,
            spec.plane.width,
            spec.plane.height,
            lost.join(","),
            sha256_hex(&all.pixels),
            sha256_hex(&lossy.pixels)
        ));
        println!(
            "{}: {} packets, {} bytes, {:.2} dB",
            spec.file,
            made.packets.len(),
            made.total_bytes(),
            made.psnr
        );
    }
    std::fs::write(dir.join("packets.txt"), list).unwrap();
}

#[test]
fn golden_packets_assemble_to_the_recorded_pixels() {
    use host_encoder::packets::assemble;
    let list = common::golden_packets();
    assert!(list.len() >= 2, "packets.txt lists {} sets", list.len());
    for g in &list {
        let (all, kept) = common::golden_packet_set(g);
        for p in &all {
            assert_eq!(p[1], VERSION, "{}: packet version", g.file);
        }
        let whole = assemble(all.iter().map(Vec::as_slice), u64::MAX).unwrap();
        assert_eq!(
            sha256_hex(&whole.pixels),
            g.sha256_all,
            "{}: all packets",
            g.file
        );
        assert!(whole.missing.is_empty());
        // Any order, with duplicates: the same picture.
        let mut scrambled: Vec<&[u8]> = kept.iter().rev().map(Vec::as_slice).collect();
        scrambled.push(kept[0].as_slice());
        let lossy = assemble(scrambled, u64::MAX).unwrap();
        assert_eq!(
            sha256_hex(&lossy.pixels),
            g.sha256_lossy,
            "{}: lossy",
            g.file
        );
        assert_eq!(lossy.missing, g.lost, "{}", g.file);
        assert_eq!(lossy.duplicates, 1);
        assert_eq!(
            (lossy.width, lossy.height),
            (u32::from(g.width), u32::from(g.height))
        );
    }
}

#[test]
fn golden_streams_decode_to_the_recorded_pixels() {
    let list = golden_list();
    assert!(list.len() >= 4, "golden.txt lists {} streams", list.len());
    let mut failures = Vec::new();
    for g in &list {
        let bytes = std::fs::read(golden_dir().join(&g.file)).unwrap();
        assert_eq!(bytes[..4], MAGIC, "{}: magic", g.file);
        assert_eq!(
            bytes[4], VERSION,
            "{}: the golden stream is bitstream version {} but decoder-core is version {VERSION}: \
             regenerate the golden vectors after a version bump",
            g.file, bytes[4]
        );
        let (header, pixels) = match decode_all(&bytes) {
            Ok(r) => r,
            Err(e) => {
                failures.push(format!("{}: decode error {e}", g.file));
                continue;
            }
        };
        assert_eq!(
            (header.width, header.height),
            (g.width, g.height),
            "{}: dimensions",
            g.file
        );
        assert_eq!(
            pixels.len(),
            usize::from(g.width) * usize::from(g.height) * usize::from(header.channels)
        );
        let hash = sha256_hex(&pixels);
        if hash != g.sha256 {
            failures.push(format!(
                "{}: decoded pixels hash to {hash}, golden.txt says {}",
                g.file, g.sha256
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "decoder output changed without a bitstream version bump:\n{}",
        failures.join("\n")
    );
}

#[test]
fn tile_sink_decodes_golden_streams_identically() {
    for g in golden_list() {
        let bytes = std::fs::read(golden_dir().join(&g.file)).unwrap();
        let mut sink = CoverageSink::new(u32::from(g.width), u32::from(g.height));
        pifs_tests::decode(&bytes, &mut sink).unwrap();
        assert!(
            sink.violations.is_empty(),
            "{}: {:?}",
            g.file,
            sink.violations
        );
        assert_eq!(sink.not_once(5), vec![], "{}", g.file);
        assert_eq!(sha256_hex(&sink.pixels), g.sha256, "{}", g.file);
    }
}

#[test]
fn every_golden_file_is_listed_and_the_set_is_varied() {
    let listed: BTreeSet<String> = golden_list().into_iter().map(|g| g.file).collect();
    let on_disk: BTreeSet<String> = std::fs::read_dir(golden_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".pifs"))
        .collect();
    assert_eq!(listed, on_disk, "golden.txt and tests/golden/*.pifs differ");
    // The set exercises both header forms (with and without Lloyd-Max codebooks) and more than
    // one smallest leaf size.
    let headers: Vec<_> = common::golden_streams()
        .iter()
        .map(|(_, b)| decoder_core::Header::read(b).unwrap())
        .collect();
    assert!(headers.iter().any(|h| h.has_codebooks()));
    assert!(headers.iter().any(|h| !h.has_codebooks()));
    assert!(headers.iter().any(|h| h.channels == 3), "a colour stream");
    assert!(
        headers.iter().any(|h| h.channels == 1),
        "a grayscale stream"
    );
    let min_leaves: BTreeSet<u8> = headers.iter().map(|h| h.min_leaf_log2).collect();
    assert!(min_leaves.len() > 1, "{min_leaves:?}");
    for (name, b) in common::golden_streams() {
        let h = decoder_core::Header::read(&b).unwrap();
        assert_eq!(h.has_codebooks(), b[7] & FLAG_CODEBOOKS != 0, "{name}");
    }
}

#[derive(Default)]
struct Usage {
    models: BTreeSet<u8>,
    wquants: BTreeSet<u8>,
    leaf_sizes: BTreeSet<u8>,
    /// The models used as pixel grids (control points one pixel apart).
    pixel_grids: BTreeSet<u8>,
    /// The control codings used on pixel grids (DPCM 0, transform 1).
    pixel_grid_codings: BTreeSet<u8>,
}

impl Usage {
    fn leaf(&mut self, info: &LeafInfo) {
        self.models.insert(info.model);
        self.wquants.insert(info.wquant);
        self.leaf_sizes.insert(info.node.log2);
        if !MODELS[usize::from(info.model)].subdivides(info.node.log2) {
            self.pixel_grids.insert(info.model);
            self.pixel_grid_codings
                .insert(u8::from(info.coding == ControlCoding::Transform));
        }
    }
}

#[test]
fn golden_streams_exercise_every_model_and_weight_quantiser() {
    let mut usage = Usage::default();
    for (name, bytes) in common::golden_streams() {
        usage = usage_of(&name, &bytes, usage);
    }
    assert_full_usage(&usage);
}

#[test]
fn golden_specs_match_golden_list() {
    // The generator and the list agree on file names and sizes (a renamed spec without a
    // regeneration fails here).
    let from_specs: Vec<(String, u16, u16)> = specs()
        .iter()
        .map(|s| {
            (
                s.file.to_string(),
                s.plane.width as u16,
                s.plane.height as u16,
            )
        })
        .collect();
    let from_list: Vec<(String, u16, u16)> = golden_list()
        .into_iter()
        .map(|g| (g.file, g.width, g.height))
        .collect();
    assert_eq!(from_specs, from_list);
}

/// The specification's tables of initial context probabilities (`docs/initial-contexts.md`,
/// luma's then chroma's) are the ones decoder-core starts every stream from.
#[test]
fn initial_context_tables_match_the_specification() {
    use decoder_core::internal::syntax::initial_contexts::{
        CHROMA_INITIAL_PROBABILITIES, INITIAL_PROBABILITIES,
    };
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/initial-contexts.md");
    let text = std::fs::read_to_string(path).expect("docs/initial-contexts.md");
    let tables: Vec<Vec<u8>> = text
        .split("```")
        .skip(1)
        .step_by(2)
        .map(|block| {
            block
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|t| !t.is_empty())
                .map(|t| t.parse().expect("a probability in 1/256"))
                .collect()
        })
        .collect();
    assert_eq!(
        tables,
        [
            INITIAL_PROBABILITIES.to_vec(),
            CHROMA_INITIAL_PROBABILITIES.to_vec()
        ]
    );
}
