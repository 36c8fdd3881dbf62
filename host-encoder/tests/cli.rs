//! The `pifs` command line: a round trip through files. Malformed inputs are in
//! `robustness_table.rs`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn pifs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pifs"))
        .args(args)
        .output()
        .expect("pifs runs")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pifs-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A 40x24 test image with a gradient and an edge.
fn write_png(path: &Path) {
    let img = image::GrayImage::from_fn(40, 24, |x, y| {
        image::Luma([(x * 5 + y * 3 + if x > 20 { 60 } else { 0 }) as u8])
    });
    img.save(path).unwrap();
}

#[test]
fn encode_decode_info_round_trip() {
    let dir = scratch("roundtrip");
    let png = dir.join("in.png");
    write_png(&png);
    let stream = dir.join("out.pifs");
    let out = pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        stream.to_str().unwrap(),
        "--bytes",
        "200",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let size = std::fs::metadata(&stream).unwrap().len();
    assert!(size <= 200 && size > 13, "size {size}");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("PSNR") && stdout.contains("bpp"),
        "{stdout}"
    );

    let decoded = dir.join("out.pgm");
    let out = pifs(&[
        "decode",
        stream.to_str().unwrap(),
        "-o",
        decoded.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&decoded).unwrap().to_luma8();
    assert_eq!(img.dimensions(), (40, 24));
    let mut expected = vec![0u8; 40 * 24];
    let bytes = std::fs::read(&stream).unwrap();
    decoder_core::Decoder::new(&bytes)
        .and_then(|d| d.decode_into(&mut expected))
        .unwrap();
    assert_eq!(img.as_raw(), &expected);

    let out = pifs(&["info", stream.to_str().unwrap()]);
    assert!(out.status.success());
    let info = String::from_utf8_lossy(&out.stdout);
    assert!(
        info.contains("40x24") && info.contains("leaves") && info.contains("pixel grids"),
        "{info}"
    );
}
