//! The `pifs` command line: round trip through files, and errors that are one line, exit
//! non-zero and leave no output file behind.

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

fn assert_one_line_failure(out: &Output) {
    assert!(!out.status.success(), "expected failure, got success");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "stderr should be one line: {err:?}"
    );
    assert!(err.starts_with("pifs: "), "stderr: {err:?}");
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
    decoder_core::decode_into(&std::fs::read(&stream).unwrap(), &mut expected).unwrap();
    assert_eq!(img.as_raw(), &expected);

    let out = pifs(&["info", stream.to_str().unwrap()]);
    assert!(out.status.success());
    let info = String::from_utf8_lossy(&out.stdout);
    assert!(info.contains("40x24") && info.contains("leaves"), "{info}");
}

#[test]
fn errors_are_one_line_and_leave_no_output() {
    let dir = scratch("errors");
    let png = dir.join("in.png");
    write_png(&png);
    let junk = dir.join("junk.png");
    std::fs::write(&junk, b"this is not an image").unwrap();
    let stream = dir.join("good.pifs");
    assert!(pifs(&[
        "encode",
        png.to_str().unwrap(),
        "-o",
        stream.to_str().unwrap()
    ])
    .status
    .success());
    let out_path = dir.join("out.pifs");
    let out_png = dir.join("out.png");
    let o = out_path.to_str().unwrap();
    let out_xyz = dir.join("out.xyz");
    let cases: Vec<Vec<&str>> = vec![
        vec!["encode", "/nonexistent/in.png", "-o", o],
        vec!["encode", dir.to_str().unwrap(), "-o", o],
        vec!["encode", junk.to_str().unwrap(), "-o", o],
        vec!["encode", stream.to_str().unwrap(), "-o", o],
        vec!["encode", png.to_str().unwrap(), "-o", o, "--bytes", "3"],
        vec!["encode", png.to_str().unwrap(), "-o", o, "--bpp", "0"],
        vec!["encode", png.to_str().unwrap(), "-o", o, "--psnr", "200"],
        vec![
            "encode",
            png.to_str().unwrap(),
            "-o",
            o,
            "--bpp",
            "0.5",
            "--bytes",
            "100",
        ],
        vec![
            "encode",
            png.to_str().unwrap(),
            "-o",
            "/nonexistent/dir/out.pifs",
        ],
        vec![
            "decode",
            png.to_str().unwrap(),
            "-o",
            out_png.to_str().unwrap(),
        ],
        vec![
            "decode",
            stream.to_str().unwrap(),
            "-o",
            out_xyz.to_str().unwrap(),
        ],
        vec!["info", junk.to_str().unwrap()],
    ];
    for args in cases {
        let out = pifs(&args);
        assert_one_line_failure(&out);
        assert!(
            !out_path.exists() && !out_png.exists(),
            "output left behind by {args:?}"
        );
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().starts_with(".pifs-tmp"))
            .collect();
        assert!(
            leftovers.is_empty(),
            "temporary file left behind by {args:?}"
        );
    }
}
