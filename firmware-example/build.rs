//! Build script of the example firmware:
//! - puts the memory layout of the target board into the linker's search path as `memory.x`
//!   (`thumbv6m-none-eabi`: the micro:bit's `memory/microbit.x`; any other target: the
//!   workspace-root `memory.x`, the LM3S6965);
//! - generates `vectors.rs`, the list of streams to embed: every golden vector listed in
//!   `tests/golden/golden.txt` (so new vectors are picked up without editing the firmware), or,
//!   with the `bench` feature, the streams listed in `PIFS_BENCH_STREAMS` (a `:`-separated path
//!   list).

use std::env;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

fn main() {
    let manifest = PathBuf::from(env::var("CARGO_MANIFEST_DIR").unwrap());
    let out = PathBuf::from(env::var("OUT_DIR").unwrap());
    let target = env::var("TARGET").unwrap_or_default();

    let memory = if target.starts_with("thumbv6m") {
        manifest.join("memory/microbit.x")
    } else {
        manifest.join("../memory.x")
    };
    fs::copy(&memory, out.join("memory.x")).unwrap_or_else(|e| panic!("{}: {e}", memory.display()));
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory.display());
    println!("cargo:rerun-if-changed=build.rs");

    let vectors = if env::var_os("CARGO_FEATURE_BENCH").is_some() {
        bench_vectors()
    } else {
        golden_vectors(&manifest.join("../tests/golden"))
    };
    let mut generated = generate(&vectors);
    if env::var_os("CARGO_FEATURE_BENCH").is_none() {
        generated += &packet_sets(&manifest.join("../tests/golden"));
        generated += &parity_sets(&manifest.join("../tests/golden"));
    }
    fs::write(out.join("vectors.rs"), generated).unwrap();
}

/// The golden packet sets of `tests/golden/packets.txt`: each framed file with the packets
/// the firmware is to lose, and the largest frame buffer one needs.
fn packet_sets(dir: &Path) -> String {
    let (mut s, frame) = set_list(dir, "packets.txt", "PACKET_SETS", "The golden packet sets.");
    writeln!(
        s,
        "/// Bytes of the frame buffer of the largest packet set.\npub const PACKET_FRAME_LEN: usize = {frame};"
    )
    .unwrap();
    s
}

/// The golden parity sets of `tests/golden/parity.txt`: each framed file (data packets, then
/// parity packets) with the data packets the firmware is to lose and rebuild.
fn parity_sets(dir: &Path) -> String {
    set_list(dir, "parity.txt", "PARITY_SETS", "The golden parity sets.").0
}

/// A static `name` of `PacketSet`s from the list `list` (`<file> <width> <height> <lost>
/// ...` per line), and the largest frame buffer one needs (bytes).
fn set_list(dir: &Path, list: &str, name: &str, doc: &str) -> (String, usize) {
    let list = dir.join(list);
    println!("cargo:rerun-if-changed={}", list.display());
    let text = fs::read_to_string(&list).unwrap_or_else(|e| panic!("{}: {e}", list.display()));
    let mut s = format!("/// {doc}\npub static {name}: &[PacketSet] = &[\n");
    let mut frame = 1usize;
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = line.split_whitespace().collect();
        assert!(f.len() >= 4, "{}: bad line {line:?}", list.display());
        let path = dir.join(f[0]);
        println!("cargo:rerun-if-changed={}", path.display());
        let bytes = fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let len = usize::from(u16::from_le_bytes([bytes[0], bytes[1]]));
        let first = decoder_core::Packet::parse(&bytes[2..2 + len])
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let (w, h): (usize, usize) = (f[1].parse().unwrap(), f[2].parse().unwrap());
        frame = frame.max(w * h * usize::from(first.channels));
        writeln!(
            s,
            "    PacketSet {{ name: {:?}, width: {w}, height: {h}, channels: {}, lost: &[{}], data: include_bytes!({:?}) }},",
            f[0],
            first.channels,
            f[3],
            path.canonicalize().unwrap().to_str().expect("UTF-8 path")
        )
        .unwrap();
    }
    s.push_str("];\n");
    (s, frame)
}

struct Vector {
    name: String,
    width: u16,
    height: u16,
    path: PathBuf,
}

fn golden_vectors(dir: &Path) -> Vec<Vector> {
    let list = dir.join("golden.txt");
    println!("cargo:rerun-if-changed={}", list.display());
    let text = fs::read_to_string(&list).unwrap_or_else(|e| panic!("{}: {e}", list.display()));
    let mut vectors = Vec::new();
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        assert!(fields.len() >= 3, "golden.txt: bad line {line:?}");
        let path = dir.join(fields[0]);
        println!("cargo:rerun-if-changed={}", path.display());
        vectors.push(Vector {
            name: fields[0].to_string(),
            width: fields[1].parse().expect("golden.txt: width"),
            height: fields[2].parse().expect("golden.txt: height"),
            path: path
                .canonicalize()
                .unwrap_or_else(|e| panic!("{}: {e}", path.display())),
        });
    }
    assert!(!vectors.is_empty(), "{}: no vectors", list.display());
    vectors
}

fn bench_vectors() -> Vec<Vector> {
    println!("cargo:rerun-if-env-changed=PIFS_BENCH_STREAMS");
    let list = env::var_os("PIFS_BENCH_STREAMS")
        .expect("the `bench` feature needs PIFS_BENCH_STREAMS=<paths of .pifs streams>");
    let mut vectors = Vec::new();
    for path in env::split_paths(&list) {
        println!("cargo:rerun-if-changed={}", path.display());
        let bytes = fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let header = decoder_core::Header::read(&bytes)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        vectors.push(Vector {
            name: path.file_name().unwrap().to_string_lossy().into_owned(),
            width: header.width,
            height: header.height,
            path: path.canonicalize().unwrap(),
        });
    }
    assert!(!vectors.is_empty(), "PIFS_BENCH_STREAMS is empty");
    vectors
}

fn generate(vectors: &[Vector]) -> String {
    let mut s = String::from("// Generated by build.rs.\n\n");
    s.push_str("/// The embedded streams.\npub static VECTORS: &[Vector] = &[\n");
    for v in vectors {
        writeln!(
            s,
            "    Vector {{ name: {:?}, width: {}, height: {}, data: include_bytes!({:?}) }},",
            v.name,
            v.width,
            v.height,
            v.path.to_str().expect("UTF-8 path")
        )
        .unwrap();
    }
    s.push_str("];\n");
    let max_width = vectors.iter().map(|v| v.width).max().unwrap_or(1);
    let smallest = vectors
        .iter()
        .min_by_key(|v| u32::from(v.width) * u32::from(v.height))
        .expect("at least one vector");
    writeln!(
        s,
        "/// The image also drawn into a frame buffer (the smallest).\n\
         pub const FRAME_BUFFER_VECTOR: &str = {:?};\n\
         /// Pixels of that frame buffer.\n\
         pub const FRAME_BUFFER_LEN: usize = {};",
        smallest.name,
        u32::from(smallest.width) * u32::from(smallest.height)
    )
    .unwrap();
    writeln!(
        s,
        "/// The widest embedded image.\npub const MAX_WIDTH: usize = {max_width};"
    )
    .unwrap();
    s
}
