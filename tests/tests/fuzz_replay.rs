//! The fuzz checks (`pifs_tests::fuzz`, also run by `cargo fuzz` in `fuzz/`) on stable: every
//! committed regression input and golden vector, then a deterministic batch of mutations of
//! them (bit flips, byte overwrites, cuts, splices), so every test run is a short fuzz run.

mod common;

use common::{golden_streams, Lcg};
use pifs_tests::fuzz;
use std::path::PathBuf;

type Check = fn(&[u8]);

const TARGETS: [(&str, Check, usize); 3] = [
    ("decode_bytes", fuzz::decode_bytes, 4000),
    ("stream_equals_slice", fuzz::stream_equals_slice, 1500),
    ("roundtrip", fuzz::roundtrip, 12),
];

/// Golden vectors and the committed regression inputs of `target`.
fn seeds(target: &str) -> Vec<Vec<u8>> {
    let mut out: Vec<Vec<u8>> = golden_streams().into_iter().map(|(_, b)| b).collect();
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz/regressions")
        .join(target);
    if let Ok(entries) = std::fs::read_dir(dir) {
        let mut files: Vec<_> = entries.flatten().map(|e| e.path()).collect();
        files.sort();
        for f in files {
            if f.extension().is_none_or(|e| e != "md") {
                out.push(std::fs::read(f).unwrap());
            }
        }
    }
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
    for (name, check, mutations) in TARGETS {
        let seeds = seeds(name);
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
