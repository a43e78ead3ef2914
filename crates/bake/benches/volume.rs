//! Benchmarks of the hair volume stage (fur thesis §3.1): the whole fur preset (16 × 128² with
//! undercoat, fins 20 × 64), the grass preset (64 × 64², fins 20 × 128), and the fur preset's
//! steps on their own. Run: `cargo bench -p furbake-bake --bench volume`.

use criterion::{Criterion, criterion_group, criterion_main};
use furbake_bake::volume::{bake_volume, compose_fin_atlas, fur_preset, grass_preset, grow_hairs, slice_shell_atlas};
use std::hint::black_box;

fn volume(c: &mut Criterion) {
    let fur = fur_preset();
    let grass = grass_preset();
    c.bench_function("bake_volume/fur_preset", |b| b.iter(|| bake_volume(black_box(&fur), 7, 0.02).unwrap()));
    c.bench_function("bake_volume/grass_preset", |b| b.iter(|| bake_volume(black_box(&grass), 7, 0.05).unwrap()));
    let hairs = grow_hairs(&fur, 7);
    c.bench_function("fur/grow_hairs", |b| b.iter(|| grow_hairs(black_box(&fur), 7)));
    c.bench_function("fur/slice_shell_atlas", |b| b.iter(|| slice_shell_atlas(black_box(&fur), &hairs, 7, 0.02)));
    c.bench_function("fur/compose_fin_atlas", |b| b.iter(|| compose_fin_atlas(black_box(&fur), &hairs)));
}

criterion_group!(benches, volume);
criterion_main!(benches);
