//! Criterion benchmarks of the grass crate (grass thesis §3.3, §4.5, table 6.2 scale): keyframe
//! table bake (1000 poses, 8 segments), CPU reference decode of 1 M blades per frame, and the
//! cluster force field update for 10,000 clusters with 3 sources.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use furbake_grass::decode::decode_nearest_batch;
use furbake_grass::{
    BladeCollider, BladeFieldSettings, BladeSoa, BladeWindSource, ForceField, ForceScene, KeyframeDecoder,
    KeyframeSettings, bake_keyframe_table, ground_grid_mesh, scatter_blades,
};
use glam::{Vec2, Vec3};
use std::hint::black_box;

fn scene() -> ForceScene {
    ForceScene {
        global_wind: Vec2::new(0.8, 0.3),
        sources: vec![
            BladeWindSource {
                position_m: Vec3::new(10.0, 1.0, -5.0),
                power: 6.0,
                falloff_exponent: 1.5,
                delayed: false,
            },
            BladeWindSource {
                position_m: Vec3::new(-20.0, 2.0, 15.0),
                power: 9.0,
                falloff_exponent: 1.0,
                delayed: false,
            },
        ],
        colliders: vec![BladeCollider::Sphere {
            center_m: Vec3::new(3.0, 0.3, 3.0),
            radius_m: 0.5,
            strength: 3.0,
            falloff_m: 0.5,
        }],
        ..ForceScene::default()
    }
}

fn benches(c: &mut Criterion) {
    let mut g = c.benchmark_group("grass");
    g.sample_size(10);
    g.measurement_time(std::time::Duration::from_secs(8));
    let settings = KeyframeSettings::thesis();
    g.bench_function("keyframe_table_bake_1000_poses_8_segments", |b| {
        b.iter(|| black_box(bake_keyframe_table(black_box(&settings)).expect("bakes")))
    });
    let table = bake_keyframe_table(&settings).expect("bakes");
    let decoder = KeyframeDecoder::new(&table).expect("decodes");
    // 1 M blades on a 100 m × 100 m ground (100 blades/m²), 1 m clusters ⇒ 10,000 clusters.
    let mesh = ground_grid_mesh([100.0, 100.0], [10, 10]);
    let field =
        scatter_blades(&mesh, &BladeFieldSettings { density_per_m2: 100.0, ..Default::default() }).expect("scatters");
    let blades = BladeSoa::from_field(&field);
    let mut forces = ForceField::new(field.grid);
    let scene = scene();
    g.throughput(Throughput::Elements(field.grid.clusters() as u64));
    g.bench_function("force_field_update_10k_clusters_3_sources", |b| b.iter(|| forces.update(black_box(&scene))));
    forces.update(&scene);
    let mut out = vec![0u32; blades.len()];
    g.throughput(Throughput::Elements(blades.len() as u64));
    g.bench_function("cpu_decode_nearest_1m_blades", |b| {
        b.iter(|| decode_nearest_batch(&decoder, &forces, black_box(&blades), &mut out))
    });
    g.finish();
}

criterion_group!(grass, benches);
criterion_main!(grass);
