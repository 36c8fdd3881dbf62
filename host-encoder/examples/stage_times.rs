//! Where an encode's time goes, stage by stage: for each image (grayscale), the analysis's
//! fitting, candidates (quantising every fit and rating it) and pruning (the trial encode and
//! rating again under its contexts, rounding variants), then one encode at 0.25 bpp. Wall time
//! of each stage, one CSV row per image.
//!
//! `cargo run --release -p host-encoder --example stage_times -- IMAGE...`

use host_encoder::{analyse, io, EncoderConfig, Target};
use std::time::Instant;

fn main() {
    println!("image,pixels,fits_s,candidates_s,pruning_s,encode_s");
    for path in std::env::args().skip(1) {
        let plane = io::load_luma(std::path::Path::new(&path)).expect("readable image");
        let pixels = plane.data.len();
        let target = Target::Bpp(0.25);
        let config = EncoderConfig::for_targets(&[target], pixels);
        let analysis = analyse(plane, &config, &|_| {}).expect("an analysis");
        let t = Instant::now();
        analysis.encode(target).expect("an encode");
        let encode = t.elapsed().as_secs_f64();
        let timing = analysis.timing();
        let name = std::path::Path::new(&path)
            .file_name()
            .map_or(path.clone(), |n| n.to_string_lossy().into_owned());
        println!(
            "{name},{pixels},{:.3},{:.3},{:.3},{encode:.3}",
            timing.fits.as_secs_f64(),
            timing.candidates.as_secs_f64(),
            timing.pruning.as_secs_f64()
        );
    }
}
