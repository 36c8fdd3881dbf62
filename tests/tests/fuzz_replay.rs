//! The fuzz checks (`pifs_tests::fuzz`, also run by `cargo fuzz` in `fuzz/`) on stable: every
//! committed seed (`fuzz/seeds/`, made by the encoder: see `fuzz_seeds.rs`), golden vector and
//! regression input (`fuzz/regressions/<target>/`), then a deterministic batch of mutations of
//! them (bit flips, byte overwrites, cuts, splices), so every test run is a short fuzz run.

mod common;

use common::{golden_streams, Lcg};
use pifs_tests::fuzz;
use std::path::{Path, PathBuf};

type Check = fn(&[u8]);

/// Each target, its check, its seed kinds (under `fuzz/seeds/`) and its mutations per run.
const TARGETS: [(&str, Check, &[&str], usize); 6] = [
    ("decode_bytes", fuzz::decode_bytes, &["streams"], 4000),
    (
        "stream_equals_slice",
        fuzz::stream_equals_slice,
        &["streams"],
        1500,
    ),
    ("roundtrip", fuzz::roundtrip, &["roundtrip"], 12),
    ("encode_input", fuzz::encode_input, &["encode_input"], 600),
    (
        "large_dimensions",
        fuzz::large_dimensions,
        &["large_dimensions"],
        300,
    ),
    ("decode_packets", fuzz::decode_packets, &["packets"], 1500),
];

fn files_in(dir: &Path) -> Vec<Vec<u8>> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    files.sort();
    files
        .into_iter()
        .filter(|f| f.is_file() && f.extension().is_none_or(|e| e != "md"))
        .map(|f| std::fs::read(f).unwrap())
        .collect()
}

/// The seeds of `target`: its kinds of `fuzz/seeds/`, the golden vectors for the stream
/// targets, and its committed regression inputs.
fn seeds(target: &str, kinds: &[&str]) -> Vec<Vec<u8>> {
    let fuzz_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz");
    let mut out = Vec::new();
    for kind in kinds {
        out.extend(files_in(&fuzz_dir.join("seeds").join(kind)));
    }
    if kinds.contains(&"streams") {
        out.extend(golden_streams().into_iter().map(|(_, b)| b));
    }
    out.extend(files_in(&fuzz_dir.join("regressions").join(target)));
    out
}

fn mutate(rng: &mut Lcg, seeds: &[Vec<u8>]) -> Vec<u8> {
    let mut data = seeds[rng.below(seeds.len() as u32) as usize].clone();
    for _ in 0..1 + rng.below(4) {
        let len = data.len().max(1) as u32;
        match rng.below(5) {
            0 if !data.is_empty() => {
                let i = rng.below(len) as usize;
                data[i] ^= 1 << rng.below(8);
            }
            1 if !data.is_empty() => {
                let i = rng.below(len) as usize;
                data[i] = rng.below(256) as u8;
            }
            2 => data.truncate(rng.below(len + 1) as usize),
            3 => {
                let other = &seeds[rng.below(seeds.len() as u32) as usize];
                let at = rng.below(len + 1) as usize;
                let from = rng.below(other.len() as u32 + 1) as usize;
                data.truncate(at.min(data.len()));
                data.extend_from_slice(&other[from..]);
            }
            _ => data.extend((0..rng.below(16)).map(|_| rng.below(256) as u8)),
        }
    }
    data
}

#[test]
fn fuzz_checks_hold_on_seeds_and_mutations() {
    for (name, check, kinds, mutations) in TARGETS {
        let seeds = seeds(name, kinds);
        assert!(!seeds.is_empty(), "{name}: no seeds");
        for s in &seeds {
            check(s);
        }
        let mut rng = Lcg::new(0x5EED ^ name.len() as u32);
        for _ in 0..mutations {
            check(&mutate(&mut rng, &seeds));
        }
    }
}

/// Every target of `fuzz/Cargo.toml` is replayed here.
#[test]
fn every_fuzz_target_is_replayed() {
    let manifest = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/Cargo.toml"),
    )
    .unwrap();
    let declared: Vec<&str> = manifest
        .lines()
        .filter_map(|l| l.strip_prefix("name = \""))
        .map(|l| l.trim_end_matches('"'))
        .filter(|n| *n != "pifs-fuzz")
        .collect();
    let replayed: Vec<&str> = TARGETS.iter().map(|t| t.0).collect();
    assert_eq!(declared, replayed);
}
