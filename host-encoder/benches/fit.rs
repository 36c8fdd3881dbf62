//! The analysis through the public API, on a textured synthetic image: the fitting stage alone
//! (every model fitted at every node, as [`host_encoder::AnalysisTiming::fits`] times it), and
//! the whole analysis.
//! `cargo bench -p host-encoder --bench fit`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use host_encoder::{analyse, Analysis, EncoderConfig, Plane};
use std::hint::black_box;
use std::time::Duration;

fn textured(size: u32) -> Plane {
    let data = (0..size * size)
        .map(|i| {
            let (x, y) = (f64::from(i % size), f64::from(i / size));
            (128.0
                + 60.0 * (x * 0.21).sin() * (y * 0.13).cos()
                + 20.0 * ((x + 2.0 * y) * 0.7).sin()) as u8
        })
        .collect();
    Plane::new(size, size, data)
}

fn analysis_of(plane: &Plane, config: &EncoderConfig) -> Analysis {
    analyse(black_box(plane.clone()), config, &|_| {}).expect("an analysable image")
}

fn bench_fits(c: &mut Criterion) {
    let mut group = c.benchmark_group("fit");
    let config = EncoderConfig::default();
    let size = 256;
    let plane = textured(size);
    // The fitting stage's own time, from each analysis's timing.
    group.bench_function(BenchmarkId::new("default", format!("{size}px")), |b| {
        b.iter_custom(|iters| {
            (0..iters)
                .map(|_| analysis_of(&plane, &config).timing().fits)
                .sum::<Duration>()
        })
    });
    group.finish();
}

fn bench_analysis(c: &mut Criterion) {
    let mut group = c.benchmark_group("analysis");
    let plane = textured(256);
    let config = EncoderConfig::default();
    group.bench_function("256px", |b| b.iter(|| analysis_of(&plane, &config)));
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench_fits, bench_analysis
}
criterion_main!(benches);
