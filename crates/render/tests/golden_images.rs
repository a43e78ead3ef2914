//! Golden images: what furbake draws, compared with committed references
//! (`tests/reference/golden_*.png`, made on lavapipe) by NVIDIA FLIP (`nv-flip`, the metric
//! wgpu's own image tests use), on whatever adapter the machine has:
//! - a furry sphere (strand shading, silhouette fins),
//! - the bundled Fox as `furbake preview` draws it,
//! - a grass patch at eye height, lit from the front and from behind, and seen from above.
//!
//! Each case passes when the FLIP mean and its 99th percentile stay within the thresholds beside
//! it. lavapipe draws the same pixels run after run, so on it both are 0; the thresholds leave
//! room for another adapter's rasterisation and filtering (tens of pixels along edges, small
//! differences of tone), while a shading change a user would notice fails them (checked below
//! with the strand shading off and the light turned). On failure the new image and the FLIP
//! error map (magma colours) are written to `target/golden-diff/` and the message names them.
//! References are regenerated only on request: `FURBAKE_BLESS=1 cargo test -p furbake-render
//! --test render golden_images::` (also run by `make golden`), never because one is missing.

use crate::common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_grass::{ForceField, ForceScene};
use furbake_import::{ImportSettings, import_gltf};
use furbake_render::headless::{RenderTarget, read_back, render_image};
use furbake_render::{BladeRenderSettings, BladeRenderer, FurAsset, FurShading, RenderSettings, View};
use furbake_runtime::{Camera, Light};
use image::RgbaImage;

/// The FLIP thresholds of one case: mean and 99th percentile (weighted, as `nv-flip`'s pool
/// reports it), each in [0, 1].
#[derive(Clone, Copy, Debug)]
struct Thresholds {
    mean: f32,
    p99: f32,
}

/// Fur: fine strands, so another rasteriser moves many edge pixels a little.
const FUR: Thresholds = Thresholds { mean: 0.03, p99: 0.35 };
/// Grass: opaque blades with hard edges.
const GRASS: Thresholds = Thresholds { mean: 0.03, p99: 0.4 };

fn reference_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("tests/reference/golden_{name}.png"))
}

/// FLIP of `test` against `reference`: the error map and its (mean, weighted 99th percentile).
fn flip(reference: &RgbaImage, test: &RgbaImage) -> (nv_flip::FlipImageFloat, f32, f32) {
    let rgb = |image: &RgbaImage| {
        let data: Vec<u8> = image.pixels().flat_map(|p| [p[0], p[1], p[2]]).collect();
        nv_flip::FlipImageRgb8::with_data(image.width(), image.height(), &data)
    };
    let error = nv_flip::flip(rgb(reference), rgb(test), nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let mut pool = nv_flip::FlipPool::from_image(&error);
    let (mean, p99) = (pool.mean(), pool.get_percentile(0.99, true));
    (error, mean, p99)
}

/// Compares `image` with the committed reference `name` (or writes it, with `FURBAKE_BLESS`).
fn check(name: &str, image: &RgbaImage, limit: Thresholds) {
    let path = reference_path(name);
    if std::env::var_os("FURBAKE_BLESS").is_some() {
        image.save(&path).unwrap();
        eprintln!("wrote {}", path.display());
        return;
    }
    let reference = image::open(&path)
        .unwrap_or_else(|e| {
            panic!("{}: {e}; regenerate on purpose with FURBAKE_BLESS=1 (never done silently)", path.display())
        })
        .to_rgba8();
    assert_eq!(reference.dimensions(), image.dimensions(), "{name}: size");
    let (error, mean, p99) = flip(&reference, image);
    eprintln!("{name}: FLIP mean {mean:.4} (limit {}), 99th percentile {p99:.4} (limit {})", limit.mean, limit.p99);
    if mean > limit.mean || p99 > limit.p99 {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/golden-diff");
        std::fs::create_dir_all(&dir).unwrap();
        let (new, map) = (dir.join(format!("{name}.png")), dir.join(format!("{name}-flip.png")));
        image.save(&new).unwrap();
        let colours = error.apply_color_lut(&nv_flip::magma_lut());
        image::RgbImage::from_raw(colours.width(), colours.height(), colours.to_vec()).unwrap().save(&map).unwrap();
        panic!(
            "{name}: FLIP mean {mean:.4} (limit {}) or 99th percentile {p99:.4} (limit {}) against {}; new image {}, \
             error map {}",
            limit.mean,
            limit.p99,
            path.display(),
            new.display(),
            map.display()
        );
    }
}

fn sphere() -> &'static FurAsset {
    static SPHERE: OnceLock<FurAsset> = OnceLock::new();
    SPHERE.get_or_init(|| common::furry_sphere(16, 24, 16, 64, 0.15))
}

/// The sphere from the front-right and above, lit from the upper left (the highlight's rim and
/// the terminator both in view).
fn sphere_view(light: [f32; 3]) -> View {
    View {
        camera: Camera { eye: [2.1, 1.6, 3.4], target: [0.0; 3], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 },
        lighting: Light { direction: light, ..Light::default() }.into(),
        bounds_center: [0.0; 3],
        bounds_radius: 1.15,
    }
}

const SPHERE_LIGHT: [f32; 3] = [0.8, -0.6, -0.4];

fn render_sphere(shading: FurShading, light: [f32; 3]) -> RgbaImage {
    let settings = RenderSettings { shading, ..Default::default() };
    render_image(gpu(), sphere(), &settings, &sphere_view(light), 128, 128).unwrap()
}

#[test]
fn furry_sphere() {
    let image = render_sphere(FurShading::default(), SPHERE_LIGHT);
    check("sphere", &image, FUR);
    if std::env::var_os("FURBAKE_BLESS").is_some() {
        return;
    }
    // The thresholds catch a change a user would see: the strand shading off, or the light
    // turned by 30° about the vertical.
    let reference = image::open(reference_path("sphere")).unwrap().to_rgba8();
    let flat = render_sphere(FurShading { enabled: false, ..FurShading::default() }, SPHERE_LIGHT);
    let turned = glam::Quat::from_rotation_y(30f32.to_radians()) * glam::Vec3::from(SPHERE_LIGHT);
    let turned = render_sphere(FurShading::default(), turned.to_array());
    for (what, image) in [("strand shading off", flat), ("light turned 30°", turned)] {
        let (_, mean, p99) = flip(&reference, &image);
        assert!(mean > FUR.mean || p99 > FUR.p99, "{what} passes as the reference: FLIP mean {mean:.4}, p99 {p99:.4}");
    }
}

#[test]
fn fox_preview() {
    let fox = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let imported = import_gltf(&fox, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    (settings.volume.layers, settings.volume.resolution) = (16, 64);
    let baked = bake(&imported, "fox", &settings.plan().unwrap(), &mut NoProgress).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fox.fbk");
    baked.to_writer().write_atomic(&path).unwrap();
    let image = furbake_render::headless::render_preview(
        &furbake_runtime::Pack::open(&path).unwrap(),
        160,
        120,
        &Default::default(),
    )
    .unwrap();
    check("fox", &image, FUR);
}

fn render_grass(eye: [f32; 3], light: [f32; 3]) -> RgbaImage {
    let g = gpu();
    let blades = BladeRenderer::new(
        g.pipelines(),
        &g.queue,
        common::default_blade_patch(),
        common::default_blade_table(),
        &BladeRenderSettings::default(),
        &RenderTarget::desc(),
    )
    .unwrap();
    let mut forces = ForceField::new(common::default_blade_patch().grid);
    forces.update(&ForceScene::default());
    blades.set_force_field(&g.queue, &forces).unwrap();
    let view = View {
        camera: Camera { eye, target: [0.0, 0.1, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 35.0 },
        lighting: Light { direction: light, ..Light::default() }.into(),
        bounds_center: [0.0, 0.12, 0.0],
        bounds_radius: 1.2,
    };
    let target = RenderTarget::new(&g.device, 128, 128).unwrap();
    blades.render_to(&g.device, &g.queue, &target, &view, Some([0.05, 0.05, 0.06, 1.0])).unwrap();
    read_back(&g.device, &g.queue, &target).unwrap()
}

#[test]
fn grass_at_eye_height_front_and_back_lit() {
    check("grass_front", &render_grass([0.0, 0.35, 1.6], [0.2, -0.5, -1.0]), GRASS);
    check("grass_back", &render_grass([0.0, 0.35, 1.6], [-0.2, -0.5, 1.0]), GRASS);
}

#[test]
fn grass_from_above() {
    // Not straight down (the blades' tips would point at the camera): 70° below the horizon.
    check("grass_above", &render_grass([0.0, 2.2, 0.8], [-0.4, -1.0, -0.6]), GRASS);
}
