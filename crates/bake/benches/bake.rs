//! Benchmark of the whole bake (the target: a ~3,000-triangle mesh with the `fur` preset in under
//! 0.5 s on the 2-core reference machine): import from glTF bytes, then every stage, then the
//! container image. Run with `cargo bench -p furbake-bake --bench bake`.

use criterion::{Criterion, criterion_group, criterion_main};
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{import_gltf_slice, testmesh};

fn bench_bake(c: &mut Criterion) {
    // 40 rings × 38 segments: 2·38·39 = 2,964 triangles.
    let sphere = testmesh::uv_sphere(40, 38, 0.5);
    let settings = BakeSettings::preset("fur").expect("built-in preset").plan().expect("the preset is valid");
    let mut group = c.benchmark_group("bake");
    group.sample_size(20);
    group.bench_function(format!("fur_preset_sphere_{}_triangles", sphere.triangles), |b| {
        b.iter(|| {
            let imported = import_gltf_slice(&sphere.gltf, "sphere.gltf", None, &settings.import).expect("imports");
            let baked = bake(&imported, "sphere.gltf", &settings, &mut NoProgress).expect("bakes");
            baked.to_writer().to_bytes()
        })
    });
    let fox = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/real/Fox.glb")).expect("bundled Fox");
    group.bench_function("fur_preset_fox_576_triangles", |b| {
        b.iter(|| {
            let imported = import_gltf_slice(&fox, "Fox.glb", None, &settings.import).expect("imports");
            let baked = bake(&imported, "Fox.glb", &settings, &mut NoProgress).expect("bakes");
            baked.to_writer().to_bytes()
        })
    });
    group.finish();
}

criterion_group!(benches, bench_bake);
criterion_main!(benches);
