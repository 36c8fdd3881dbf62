//! Rate/distortion sweep in colour: analyses each image as colour ([`host_encoder::analyse_colour`]),
//! encodes it at every target rate, decodes every stream with decoder-core and prints one CSV
//! row per (image, rate): PSNR-RGB (the MSE over R, G and B), PSNR-Y, PSNR-Cb, PSNR-Cr and
//! PSNR-YCbCr (6:1:1), all on floating-point full-range BT.601 YCbCr of both images as
//! `../shared/bench/anchors.py --colour` measures them, and the share of the payload spent on
//! chroma.
//!
//! `cargo run --release -p host-encoder --example rd_sweep_colour -- [--bpp 0.05,0.1] IMAGE...`
//!
//! Each rate is encoded from the analysis `pifs` would make for it alone; rates for which that
//! is the same analysis share it.

mod common;

use host_encoder::{analyse_colour, io, Analysis, EncoderConfig, Target};
use std::time::Instant;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let rates = common::take_rates(&mut args, &[0.05, 0.1, 0.25, 0.5, 1.0]);
    println!("image,width,height,target_bpp,bytes,bpp,psnr_rgb,psnr_y,psnr_cb,psnr_cr,psnr_ycbcr611,chroma_share,analysis_s,encode_s,decode_ms,leaves");
    for path in &args {
        let image = io::load_image(std::path::Path::new(path)).expect("readable image");
        let io::Loaded::Rgb {
            width,
            height,
            data,
        } = image
        else {
            eprintln!("{path}: not a colour image, skipped");
            continue;
        };
        let name = std::path::Path::new(path)
            .file_name()
            .map_or(path.clone(), |n| n.to_string_lossy().into_owned());
        let pixels = (width * height) as usize;
        let config_for = |bpp: f64| EncoderConfig::for_targets(&[Target::Bpp(bpp)], pixels);
        let mut configs: Vec<EncoderConfig> = Vec::new();
        for &r in &rates {
            let config = config_for(r);
            if !configs.contains(&config) {
                configs.push(config);
            }
        }
        for config in configs {
            let t = Instant::now();
            let analysis =
                analyse_colour(width, height, data.clone(), &config, &|_| {}).expect("analysis");
            let analysis_s = t.elapsed().as_secs_f64();
            for &bpp in rates.iter().filter(|&&r| config_for(r) == config) {
                sweep_one(&analysis, &name, &data, bpp, analysis_s);
            }
        }
    }
}

/// Full-range BT.601 YCbCr of an RGB pixel, in floating point (as the anchors measure).
fn ycbcr(p: &[u8]) -> [f64; 3] {
    let (r, g, b) = (f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
    [
        0.299 * r + 0.587 * g + 0.114 * b,
        128.0 - 0.168736 * r - 0.331264 * g + 0.5 * b,
        128.0 + 0.5 * r - 0.418688 * g - 0.081312 * b,
    ]
}

fn psnr(sse: f64, n: f64) -> f64 {
    10.0 * (255.0f64 * 255.0 * n / sse.max(1e-12)).log10()
}

/// Encodes `analysis` at `bpp`, decodes it with decoder-core and prints the CSV row.
fn sweep_one(analysis: &Analysis, name: &str, original: &[u8], bpp: f64, analysis_s: f64) {
    let (w, h) = (analysis.width(), analysis.height());
    let t = Instant::now();
    match analysis.encode(Target::Bpp(bpp)) {
        Ok(e) => {
            let encode_s = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let mut pixels = vec![0u8; original.len()];
            decoder_core::Decoder::new(&e.bytes)
                .and_then(|d| {
                    d.stripe_capacity::<{ io::HOST_STRIPE }>()
                        .decode_into(&mut pixels)
                })
                .expect("own stream decodes");
            let decode_ms = t.elapsed().as_secs_f64() * 1e3;
            let sse_rgb: f64 = pixels
                .iter()
                .zip(original)
                .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
                .sum();
            let mut sse = [0f64; 3];
            for (a, b) in pixels.chunks_exact(3).zip(original.chunks_exact(3)) {
                let (ya, yb) = (ycbcr(a), ycbcr(b));
                for c in 0..3 {
                    sse[c] += (ya[c] - yb[c]).powi(2);
                }
            }
            let n = f64::from(w * h);
            let p = [psnr(sse[0], n), psnr(sse[1], n), psnr(sse[2], n)];
            println!(
                "{name},{w},{h},{bpp},{},{:.5},{:.3},{:.3},{:.3},{:.3},{:.3},{:.4},{analysis_s:.2},{encode_s:.2},{decode_ms:.1},{}",
                e.bytes.len(),
                e.bytes.len() as f64 * 8.0 / n,
                psnr(sse_rgb, 3.0 * n),
                p[0],
                p[1],
                p[2],
                (6.0 * p[0] + p[1] + p[2]) / 8.0,
                e.chroma_bits / e.actual_payload_bits.max(1.0),
                e.leaves
            );
        }
        Err(err) => println!("{name},{w},{h},{bpp},,,,,,,,,{analysis_s:.2},,,# {err}"),
    }
}
