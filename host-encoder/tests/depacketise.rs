//! `docs/depacketise.py`, a depacketiser written from the specification's section 9 alone,
//! reads the reference encoder's packets as `pifs info --json` does, and rebuilds lost packets
//! from parity as the reference tool does: the specification says enough for a gateway author. Needs `python3` (any Python 3, no modules beyond its own).

#[path = "common/scratch.rs"]
mod scratch;

use scratch::Scratch;
use serde_json::Value;
use std::path::Path;
use std::process::Command;

fn run(program: &str, args: &[&str]) -> Vec<u8> {
    let out = Command::new(program)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{program} runs ({e}; python3 is needed by this test)"));
    assert!(
        out.status.success(),
        "{program} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

fn pifs(args: &[&str]) -> Vec<u8> {
    run(env!("CARGO_BIN_EXE_pifs"), args)
}

/// The depacketiser's one image of `paths`, and how many packets it refused.
fn depacketise(paths: &[&Path]) -> (Value, u64) {
    depacketise_into(paths, None)
}

/// The same, its data packets (rebuilt ones too) written under `out` when given.
fn depacketise_into(paths: &[&Path], out: Option<&Path>) -> (Value, u64) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/depacketise.py");
    let mut args = vec![script.to_str().unwrap(), "--json"];
    if let Some(out) = out {
        args.extend(["--write", out.to_str().unwrap()]);
    }
    args.extend(paths.iter().map(|p| p.to_str().unwrap()));
    let out: Value = serde_json::from_slice(&run("python3", &args)).expect("JSON");
    let images = out["images"].as_array().expect("a list of images");
    assert_eq!(images.len(), 1, "{out}");
    (images[0].clone(), out["damaged"].as_u64().unwrap())
}

/// `pifs packets drop`: the packets of `sent` that survive a loss of `loss` (random seed
/// `seed`), copied into `received`.
fn lose(sent: &Path, received: &Path, loss: &str, seed: &str) {
    pifs(&[
        "packets",
        "drop",
        "--loss",
        loss,
        "--seed",
        seed,
        sent.to_str().unwrap(),
        received.to_str().unwrap(),
    ]);
}

fn info(paths: &[&Path]) -> Value {
    let mut args = vec!["info", "--json"];
    args.extend(paths.iter().map(|p| p.to_str().unwrap()));
    serde_json::from_slice(&pifs(&args)).expect("JSON")
}

/// A colour picture with texture, so that its regions differ in size.
fn write_png(path: &Path, w: u32, h: u32) {
    image::RgbImage::from_fn(w, h, |x, y| {
        let t = ((x * 7 + y * 13) % 64) as u8;
        image::Rgb([(x * 2) as u8 ^ t, (y * 3) as u8, 200 - t])
    })
    .save(path)
    .unwrap();
}

fn indices(v: &Value) -> Vec<u64> {
    v.as_array()
        .expect("a list")
        .iter()
        .map(|i| i.as_u64().unwrap())
        .collect()
}

fn assert_same_image(ours: &Value, reference: &Value) {
    for field in [
        "image_id", "count", "width", "height", "channels", "previews",
    ] {
        assert_eq!(
            ours[field], reference[field],
            "{field}: {ours} / {reference}"
        );
    }
}

/// Packets with non-default coding fields, a lossy subset with a duplicate and a damaged packet:
/// the same image, packets, missing packets and region coverage as the reference tool says.
#[test]
fn the_specification_suffices_to_sort_packets() {
    let dir = Scratch::new("depacketise-sort");
    let png = dir.join("in.png");
    write_png(&png, 203, 141);
    let sent = dir.join("sent");
    pifs(&[
        "encode",
        png.to_str().unwrap(),
        "--bpp",
        "1.5",
        "--packets",
        sent.to_str().unwrap(),
        "--packet-size",
        "96",
        "--image-id",
        "40001",
        "--min-leaf-log2",
        "3",
    ]);
    let received = dir.join("received");
    lose(&sent, &received, "0.3", "5");
    let all = |d: &Path| -> Vec<std::path::PathBuf> {
        let mut v: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        v.sort();
        v
    };
    let kept = all(&received);
    assert!(kept.len() >= 4, "{} packets kept", kept.len());
    // A duplicate of one packet and a damaged copy of another, beside the set.
    let extra = dir.join("extra");
    std::fs::create_dir(&extra).unwrap();
    std::fs::copy(&kept[1], extra.join("again.pkt")).unwrap();
    let mut damaged = std::fs::read(&kept[2]).unwrap();
    damaged[8] ^= 0x10;
    std::fs::write(extra.join("damaged.pkt"), damaged).unwrap();

    let (whole, refused) = depacketise(&[&sent]);
    let reference = info(&[&sent]);
    assert_same_image(&whole, &reference);
    assert_eq!(refused, 0);
    assert_eq!(whole["missing"], Value::Array(vec![]), "{whole}");
    assert_eq!(whole["region_coverage"].as_f64(), Some(1.0));

    let (ours, refused) = depacketise(&[&received, &extra]);
    let reference = info(&[&received, &extra]);
    assert_same_image(&ours, &reference);
    assert_eq!(indices(&ours["received"]), indices(&reference["received"]));
    assert_eq!(indices(&ours["missing"]), indices(&reference["missing"]));
    assert!(!indices(&ours["missing"]).is_empty(), "{ours}");
    let coverage = ours["region_coverage"].as_f64().unwrap();
    assert!(
        (coverage - reference["coverage"].as_f64().unwrap()).abs() < 1e-9,
        "{ours} / {reference}"
    );
    assert_eq!(refused, reference["ignored"]["damaged"].as_u64().unwrap());
    assert_eq!(refused, 1);
    assert_eq!(ours["duplicates"], reference["ignored"]["duplicates"]);
    assert_eq!(ours["duplicates"].as_u64(), Some(1));
}

/// Framed packets with parity: every data and parity packet read from the framing; and from a
/// lossy set, the same packets rebuilt from parity as the reference tool rebuilds, byte for
/// byte the packets sent (the Reed-Solomon code as section 9 states it).
#[test]
fn framed_packets_and_parity_are_read_as_specified() {
    let dir = Scratch::new("depacketise-framed");
    let png = dir.join("in.png");
    write_png(&png, 120, 96);
    let encode = |output: &[&str]| {
        let mut args = vec!["encode", png.to_str().unwrap(), "--bpp", "2"];
        args.extend(["--packet-size", "120", "--parity", "3"]);
        args.extend(output);
        pifs(&args);
    };
    let framed = dir.join("photo.pifsp");
    encode(&["-o", framed.to_str().unwrap()]);
    let (ours, refused) = depacketise(&[&framed]);
    let reference = info(&[&framed]);
    assert_same_image(&ours, &reference);
    assert_eq!(refused, 0);
    assert_eq!(indices(&ours["parity"]), vec![0, 1, 2]);
    assert_eq!(indices(&ours["received"]), indices(&reference["received"]));

    let sent = dir.join("sent");
    encode(&["--packets", sent.to_str().unwrap()]);
    let received = dir.join("received");
    lose(&sent, &received, "0.1", "1");
    let rebuilt_dir = dir.join("rebuilt");
    let (ours, _) = depacketise_into(&[&received], Some(&rebuilt_dir));
    let reference = info(&[&received]);
    assert_same_image(&ours, &reference);
    let rebuilt = indices(&reference["rebuilt_from_parity"]);
    assert!(!rebuilt.is_empty(), "{reference}");
    assert_eq!(indices(&ours["rebuilt_from_parity"]), rebuilt);
    assert_eq!(indices(&ours["received"]), indices(&reference["received"]));
    assert_eq!(ours["missing"], Value::Array(vec![]), "{ours}");
    // Every data packet, rebuilt ones included, is the one sent, byte for byte.
    let written = rebuilt_dir.join(ours["image_id"].to_string());
    let count = ours["count"].as_u64().unwrap();
    for index in 0..count {
        let name = format!("{index:04}.pkt");
        let ours = std::fs::read(written.join(&name)).expect("every packet written");
        assert_eq!(ours, std::fs::read(sent.join(&name)).unwrap(), "{name}");
    }
}
