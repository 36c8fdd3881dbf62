//! Rate/distortion sweep: analyses each image, encodes it at every target rate from that
//! analysis, decodes every stream with decoder-core and prints one CSV row per (image, rate).
//!
//! `cargo run --release -p host-encoder --example rd_sweep -- [--bpp 0.05,0.1] [--min-leaf-log2 N] IMAGE...`
//!
//! Each rate is encoded from the analysis `pifs` would make for it alone (its trial rate,
//! [`host_encoder::Target::trial_bpp`]); rates for which that is the same analysis share it.

mod common;

use host_encoder::{analyse, io, psnr, Analysis, EncoderConfig, Target};
use std::time::Instant;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let rates = common::take_rates(&mut args, &[0.05, 0.1, 0.25, 0.5]);
    let min_leaf_log2: Option<u8> = common::take_option(&mut args, "--min-leaf-log2")
        .map(|v| v.parse().expect("--min-leaf-log2 takes a number"));
    println!("image,width,height,target_bpp,bytes,bpp,psnr_db,analysis_s,encode_s,decode_ms,leaves,rate_gap_pct,min_leaf_px");
    for path in &args {
        let plane = io::load_luma(std::path::Path::new(path)).expect("readable image");
        let name = std::path::Path::new(path)
            .file_name()
            .map_or(path.clone(), |n| n.to_string_lossy().into_owned());
        let pixels = plane.data.len();
        let config_for = |bpp: f64| {
            let chosen = EncoderConfig::for_targets(&[Target::Bpp(bpp)], pixels);
            let min_leaf_log2 = min_leaf_log2.unwrap_or(chosen.min_leaf_log2);
            EncoderConfig {
                min_leaf_log2,
                max_leaf_log2: chosen.max_leaf_log2.max(min_leaf_log2),
                ..chosen
            }
        };
        let mut configs: Vec<EncoderConfig> = Vec::new();
        for &r in &rates {
            let config = config_for(r);
            if !configs.contains(&config) {
                configs.push(config);
            }
        }
        for config in configs {
            let t = Instant::now();
            let analysis = analyse(plane.clone(), &config, &|_| {}).expect("analysis");
            let analysis_s = t.elapsed().as_secs_f64();
            for &bpp in rates.iter().filter(|&&r| config_for(r) == config) {
                sweep_one(&analysis, &name, &plane.data, bpp, analysis_s);
            }
        }
    }
}

/// Encodes `analysis` at `bpp`, decodes it with decoder-core and prints the CSV row.
fn sweep_one(analysis: &Analysis, name: &str, original: &[u8], bpp: f64, analysis_s: f64) {
    let (w, h) = (analysis.width(), analysis.height());
    let min_leaf = 1u32 << analysis.min_leaf_log2();
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
            let sse: f64 = pixels
                .iter()
                .zip(original)
                .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
                .sum();
            let gap = 100.0 * (e.estimated_payload_bits - e.actual_payload_bits)
                / e.actual_payload_bits.max(1.0);
            println!(
                "{name},{w},{h},{bpp},{},{:.5},{:.3},{analysis_s:.2},{encode_s:.2},{decode_ms:.1},{},{gap:.2},{min_leaf}",
                e.bytes.len(),
                e.bytes.len() as f64 * 8.0 / f64::from(w * h),
                psnr(sse, original.len()),
                e.leaves
            );
        }
        Err(err) => {
            println!("{name},{w},{h},{bpp},,,,{analysis_s:.2},,,,unreachable: {err},{min_leaf}")
        }
    }
}
