//! Decoding time of PIFS streams on the host, in process: each stream is decoded into a buffer
//! `REPEATS` times (default 15, environment variable `REPEATS`) and the median is kept.
//!
//! ```text
//! cargo run --release -p host-encoder --example decode_speed -- STREAM.pifs...
//! ```
//!
//! Prints one line per stream (`name pixels median_ms`) and the median over the streams; with
//! `SCALE=1/4` (or any `pifs decode --scale` value) decodes at that scale, and with
//! `CLIP=X,Y,W,H` draws only that rectangle of the (scaled) image.

use decoder_core::{Decoder, Rect, Scale};
use host_encoder::io::HOST_STRIPE;
use std::time::Instant;

fn main() {
    let repeats: usize = std::env::var("REPEATS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(15);
    let scale = match std::env::var("SCALE").as_deref() {
        Ok("1/8") => Scale::Eighth,
        Ok("1/4") => Scale::Quarter,
        Ok("1/2") => Scale::Half,
        Ok("2") => Scale::Double,
        Ok("4") => Scale::Quadruple,
        _ => Scale::One,
    };
    let clip = std::env::var("CLIP").ok().map(|v| {
        let f: Vec<u32> = v.split(',').filter_map(|n| n.trim().parse().ok()).collect();
        assert_eq!(f.len(), 4, "CLIP=X,Y,W,H");
        Rect {
            x: f[0],
            y: f[1],
            w: f[2],
            h: f[3],
        }
    });
    let mut medians = Vec::new();
    for path in std::env::args().skip(1) {
        let data = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let decoder = Decoder::new(&data)
            .unwrap_or_else(|e| panic!("{path}: {e}"))
            .stripe_capacity::<HOST_STRIPE>();
        let channels = usize::from(decoder.header().channels);
        let (w, h) = decoder.scale(scale).output_size();
        let mut out = vec![0u8; (w * h) as usize * channels];
        let mut times = Vec::with_capacity(repeats);
        for _ in 0..repeats {
            let start = Instant::now();
            Decoder::new(&data)
                .and_then(|d| {
                    d.stripe_capacity::<HOST_STRIPE>()
                        .scale(scale)
                        .clip(clip.unwrap_or(Rect::EVERYTHING))
                        .decode_into(&mut out)
                })
                .unwrap_or_else(|e| panic!("{path}: {e}"));
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        println!("{path} {} {median:.3}", w * h);
        medians.push(median);
    }
    medians.sort_by(f64::total_cmp);
    if !medians.is_empty() {
        println!(
            "median over {} streams: {:.3} ms (min {:.3}, max {:.3})",
            medians.len(),
            medians[medians.len() / 2],
            medians[0],
            medians[medians.len() - 1]
        );
    }
}
