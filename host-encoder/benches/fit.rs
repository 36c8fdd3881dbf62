//! The fitting kernel: a model fitted to one block, per model and block size (the default-weight
//! least-squares projection, and the Levenberg-Marquardt fit of the weights), on a textured
//! synthetic image. `cargo bench -p host-encoder --bench fit`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use decoder_core::internal::syntax::models_for_block;
use decoder_core::Node;
use host_encoder::encoder::fit::{fit_default, fit_weighted};
use host_encoder::Plane;
use std::hint::black_box;

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

fn bench_fits(c: &mut Criterion) {
    let plane = textured(512);
    let mut group = c.benchmark_group("fit");
    for log2 in [3u8, 4, 5, 6] {
        // An interior block, away from the image's edges.
        let node = Node {
            x: 128,
            y: 128,
            log2,
        };
        let (models, count) = models_for_block(log2);
        for &m in &models[..count] {
            let id = format!("model{m}/{}px", 1 << log2);
            group.bench_function(BenchmarkId::new("default", &id), |b| {
                b.iter(|| fit_default(black_box(&plane), &node, m))
            });
            let plain = fit_default(&plane, &node, m);
            if fit_weighted(&plane, &node, &plain).is_some() {
                group.bench_function(BenchmarkId::new("weighted", &id), |b| {
                    b.iter(|| fit_weighted(black_box(&plane), &node, &plain))
                });
            }
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench_fits
}
criterion_main!(benches);
