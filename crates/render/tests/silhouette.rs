//! Silhouette fins (fur thesis §4.1; `furbake_render::silhouette`) on whatever adapter the machine
//! has (Mesa lavapipe without a GPU; these never skip).
//!
//! - The GPU's selection (edge, fade), read back, equals the CPU reference
//!   [`silhouette_edges`] for several cameras on the baked sphere (`fixtures/generated/sphere.gltf`,
//!   one camera through a rotated, translated, scaled model matrix) and on the Fox
//!   (`fixtures/real/Fox.glb`) at rest and posed by the skinning pass. Order-independent (sorted).
//!   Tolerance: the GPU evaluates the same f32 formula, but the driver's `normalize` and FMAs may
//!   differ by a few ulps, so an edge may differ only when one of its facings n·v is within
//!   [`FACING_TOLERANCE`] of 0 (the sign test) or its min |n·v| within it of the band; fades of
//!   edges both select agree within [`FADE_TOLERANCE`].
//! - The gain: in the outer half of a ring around the sphere's skin silhouette, the summed alpha
//!   with silhouette fins exceeds that without by [`MIN_GAIN`].
//! - A frame with silhouette fins neither submits nor waits inside prepare/render.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, ImportedMesh, import_gltf};
use furbake_render::headless::{RenderTarget, render_image};
use furbake_render::testing::blocking_calls_on_this_thread;
use furbake_render::testing::{SilhouetteEdge, edge_facing, interior_edges, silhouette_edges};
use furbake_render::{FurAsset, FurRenderer, RenderSettings, View};
use furbake_runtime::Pack;
use furbake_runtime::animation::{AnimationPlayer, Pose, joint_world_matrices, skinning_matrices};
use glam::{Mat4, Quat, Vec3};
use image::RgbaImage;

/// An edge may be selected by one side only when a facing is this close to 0 or to the band.
const FACING_TOLERANCE: f32 = 1e-4;
/// Largest difference between the GPU's and the CPU's fade of an edge both select.
const FADE_TOLERANCE: f32 = 1e-3;
/// Summed alpha in the silhouette ring with silhouette fins ÷ without, at least. Fins fade
/// towards the root (docs/design.md "Fin opacity") and add what the outer shells miss: 1.04× on
/// lavapipe (1.10× and more before the fade, which doubled the coat at the roots); without
/// silhouette fins the ratio is 1.
const MIN_GAIN: f64 = 1.02;

fn fixture(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(path)
}

fn out_dir() -> PathBuf {
    let dir = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The baked sphere fixture: 16 layers of 64² shells, fur 0.15 m (the sphere has radius 1).
fn sphere() -> &'static FurAsset {
    static SPHERE: OnceLock<FurAsset> = OnceLock::new();
    SPHERE.get_or_init(|| {
        let imported = import_gltf(&fixture("fixtures/generated/sphere.gltf"), &ImportSettings::default()).unwrap();
        let mut settings = BakeSettings::preset("fur").unwrap();
        settings.volume.layers = 16;
        settings.volume.resolution = 64;
        settings.shells.fur_length_m = Some(0.15);
        let baked = bake(&imported, "sphere", &settings.plan().unwrap(), &mut NoProgress).unwrap();
        let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
        FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), fins).unwrap()
    })
}

fn fox_mesh() -> &'static ImportedMesh {
    static FOX: OnceLock<ImportedMesh> = OnceLock::new();
    FOX.get_or_init(|| import_gltf(&fixture("fixtures/real/Fox.glb"), &ImportSettings::default()).unwrap())
}

/// The Fox baked small (8 layers of 32² shells) into a pack, and that pack opened.
fn fox_pack() -> &'static (tempfile::TempDir, Pack) {
    static PACK: OnceLock<(tempfile::TempDir, Pack)> = OnceLock::new();
    PACK.get_or_init(|| {
        let mut settings = BakeSettings::preset("fur").unwrap();
        settings.volume.layers = 8;
        settings.volume.resolution = 32;
        let baked = bake(fox_mesh(), "fox", &settings.plan().unwrap(), &mut NoProgress).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fox.fbk");
        baked.to_writer().write_atomic(&path).unwrap();
        let pack = Pack::open(&path).unwrap();
        (dir, pack)
    })
}

/// The skinning matrices and morph weights of the Fox playing `clip` at `time_s`.
fn pose_of(mesh: &ImportedMesh, clip: &str, time_s: f32) -> (Vec<Mat4>, Vec<f32>) {
    let a = &mesh.animation;
    let (skeleton, morphs, clips) = (a.skeleton.as_ref().unwrap(), a.morph_targets.as_ref(), a.clips.as_ref().unwrap());
    let mut player = AnimationPlayer::new(clips, clip, 1.0, true, Some(skeleton), morphs).unwrap();
    player.seek(clips, time_s);
    let mut pose = Pose::rest(Some(skeleton), morphs);
    let groups = morphs.map_or(&[][..], |m| &m.groups[..]);
    player.pose(clips, groups, &mut pose).unwrap();
    let mut world = vec![Mat4::IDENTITY; skeleton.joint_count()];
    let mut palette = vec![Mat4::IDENTITY; skeleton.bind_count()];
    joint_world_matrices(skeleton, &pose, &mut world).unwrap();
    skinning_matrices(skeleton, &world, &mut palette).unwrap();
    (palette, pose.morph_weights)
}

/// Compares the GPU selection with the CPU reference; returns (selected by both, differing).
fn compare(
    what: &str,
    gpu_sel: &[(u32, f32)],
    positions: &[[f32; 3]],
    edges: &[SilhouetteEdge],
    camera_obj: Vec3,
    band: f32,
) -> (usize, usize) {
    let cpu_sel = silhouette_edges(positions, edges, camera_obj.to_array(), band);
    let mut sorted = gpu_sel.to_vec();
    sorted.sort_by_key(|e| e.0);
    let gpu_map: std::collections::HashMap<u32, f32> = sorted.iter().copied().collect();
    assert_eq!(gpu_map.len(), sorted.len(), "{what}: an edge was appended twice");
    let cpu_map: std::collections::HashMap<u32, f32> = cpu_sel.iter().copied().collect();
    let (mut both, mut differing) = (0, 0);
    let mut worst_fade = 0.0f32;
    for e in gpu_map.keys().chain(cpu_map.keys().filter(|e| !gpu_map.contains_key(*e))) {
        match (gpu_map.get(e), cpu_map.get(e)) {
            (Some(g), Some(c)) => {
                both += 1;
                worst_fade = worst_fade.max((g - c).abs());
                assert!((g - c).abs() <= FADE_TOLERANCE, "{what}: edge {e} fades {g} on the GPU, {c} on the CPU");
            }
            (g, c) => {
                differing += 1;
                let (d0, d1) = edge_facing(positions, &edges[*e as usize], camera_obj.to_array()).unwrap_or((0.0, 0.0));
                let m = d0.abs().min(d1.abs());
                let ambiguous =
                    d0.abs() < FACING_TOLERANCE || d1.abs() < FACING_TOLERANCE || (m - band).abs() < FACING_TOLERANCE;
                assert!(ambiguous, "{what}: edge {e} selected by GPU {g:?} / CPU {c:?} with facings {d0}, {d1}");
            }
        }
    }
    println!(
        "{what}: GPU {} CPU {} edges, {both} agree, {differing} differ (at the tolerance), worst fade Δ {worst_fade:e}",
        sorted.len(),
        cpu_sel.len()
    );
    assert!(both > 0, "{what}: nothing selected");
    (both, differing)
}

fn framing(asset: &FurAsset, dir: Vec3) -> View {
    let (center, radius) = asset.bounding_sphere();
    let mut view = View::framing(center, radius);
    let distance = Vec3::from(view.camera.eye).distance(Vec3::from(center));
    view.camera.eye = (Vec3::from(center) + dir.normalize() * distance).to_array();
    view
}

#[test]
fn the_gpu_selects_the_cpu_reference_edges_on_the_sphere() {
    let g = gpu();
    let asset = sphere();
    let settings = RenderSettings::default();
    let edges = interior_edges(asset.mesh(), asset.fins().map(|f| f.1));
    assert!(edges.len() > 500, "{} interior edges", edges.len());
    let positions = &asset.mesh().positions;
    let model = Mat4::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Quat::from_rotation_y(0.7) * Quat::from_rotation_x(-0.3),
        Vec3::new(3.0, -1.0, 0.5),
    );
    let cases = [
        ("front-right", Vec3::new(0.75, 0.35, 1.0), Mat4::IDENTITY, settings.silhouette_band),
        ("above", Vec3::new(0.1, 1.0, 0.05), Mat4::IDENTITY, settings.silhouette_band),
        ("behind-left, band 0", Vec3::new(-1.0, -0.2, -0.6), Mat4::IDENTITY, 0.0),
        ("placed by a model matrix, band 0.5", Vec3::new(0.3, 0.2, 1.0), model, 0.5),
    ];
    let mut checked = 0;
    for (what, dir, model, band) in cases {
        let s = RenderSettings { silhouette_band: band, ..settings };
        let renderer = FurRenderer::new(g.pipelines(), &g.queue, asset, &s, &RenderTarget::desc()).unwrap();
        assert!(renderer.has_silhouette_fins());
        // The view of the object frame, carried into the world by `model`: the eye the renderer
        // gets is in the world, and the selection must bring it back.
        let view = framing(asset, dir);
        let eye_world = model.transform_point3(Vec3::from(view.camera.eye));
        let frame = furbake_render::FrameUniforms::new(view.view_proj(1.0), eye_world, view.lighting, model);
        let sel = renderer.silhouette_selection(&g.device, &g.queue, &frame).unwrap();
        let camera_obj = model.inverse().transform_point3(eye_world);
        compare(what, &sel, positions, &edges, camera_obj, band);
        checked += 1;
    }
    assert_eq!(checked, 4);
    g.check().unwrap();
}

#[test]
fn the_gpu_selects_the_cpu_reference_edges_on_the_fox_at_rest_and_posed() {
    let g = gpu();
    let asset = FurAsset::from_pack(&fox_pack().1, true).unwrap();
    assert!(asset.is_animated());
    let settings = RenderSettings::default();
    let renderer = FurRenderer::new(g.pipelines(), &g.queue, &asset, &settings, &RenderTarget::desc()).unwrap();
    assert!(renderer.has_silhouette_fins());
    let edges = interior_edges(asset.mesh(), asset.fins().map(|f| f.1));
    let band = settings.silhouette_band;
    let mut checked = 0;
    for (what, pose) in
        [("rest", None), ("Run at 0.3 s", Some(("Run", 0.3))), ("Survey at 1.1 s", Some(("Survey", 1.1)))]
    {
        if let Some((clip, t)) = pose {
            let (palette, weights) = pose_of(fox_mesh(), clip, t);
            renderer.set_pose(&g.queue, &palette, &weights).unwrap();
        }
        for dir in [Vec3::new(0.75, 0.35, 1.0), Vec3::new(-1.0, 0.5, -0.3), Vec3::new(0.0, -0.4, 1.0)] {
            let view = framing(&asset, dir);
            let frame = view.uniforms(1, 1);
            let sel = renderer.silhouette_selection(&g.device, &g.queue, &frame).unwrap();
            // The surface the selection saw: the skinning pass's output of the same submission.
            let posed = renderer.skinning().unwrap().read_back(&g.device, &g.queue).unwrap();
            compare(
                &format!("Fox {what}, from {dir}"),
                &sel,
                &posed.positions,
                &edges,
                Vec3::from(view.camera.eye),
                band,
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 9);
    g.check().unwrap();
}

/// Summed alpha (0–1 per pixel) of `image` over the pixels of `mask`.
fn alpha_in(image: &RgbaImage, mask: &[bool]) -> f64 {
    image.pixels().zip(mask).filter(|(_, m)| **m).map(|(p, _)| f64::from(p[3]) / 255.0).sum()
}

#[test]
fn silhouette_fins_cover_more_of_the_silhouette_band() {
    const SIZE: u32 = 128;
    const RING_PX: i64 = 6;
    let g = gpu();
    let asset = sphere();
    let view = framing(asset, Vec3::new(0.75, 0.35, 1.0));
    // Without the stacking exponents: at grazing views they make the shells themselves nearly
    // opaque in this band, which would hide what the fins add (docs/design.md "Shell opacity").
    let base = RenderSettings { background: [0.0; 4], stacking_correction: false, ..Default::default() };
    let render = |settings: &RenderSettings| render_image(g, asset, settings, &view, SIZE, SIZE).unwrap();
    let bare = render(&RenderSettings { shell_layers: Some(0), ..base });
    let without = render(&RenderSettings { silhouette_fins: false, ..base });
    let with = render(&base);
    for (name, image) in [("bare", &bare), ("without", &without), ("with", &with)] {
        image.save(out_dir().join(format!("sphere_silhouette_{name}.png"))).unwrap();
    }
    // The ring: pixels outside the bare skin's disc farther than RING_PX / 2 from it and within
    // RING_PX (the fur's 0.15 m projects to about 6 px here): the outer half of the fur's
    // profile, where the fins' tips stand (fins fade towards the root, docs/design.md "Fin
    // opacity").
    let skin: Vec<bool> = bare.pixels().map(|p| p[3] > 0).collect();
    let at =
        |x: i64, y: i64| x >= 0 && y >= 0 && x < SIZE as i64 && y < SIZE as i64 && skin[(y * SIZE as i64 + x) as usize];
    let near =
        |x: i64, y: i64, r: i64| (-r..=r).any(|dy| (-r..=r).any(|dx| dx * dx + dy * dy <= r * r && at(x + dx, y + dy)));
    let ring: Vec<bool> = (0..(SIZE * SIZE) as i64)
        .map(|i| {
            let (x, y) = (i % SIZE as i64, i / SIZE as i64);
            !near(x, y, RING_PX / 2) && near(x, y, RING_PX)
        })
        .collect();
    let ring_pixels = ring.iter().filter(|r| **r).count();
    let (a_without, a_with) = (alpha_in(&without, &ring), alpha_in(&with, &ring));
    println!(
        "silhouette ring of {ring_pixels} px: summed alpha {a_without:.1} without silhouette fins, {a_with:.1} with ({:.2}×)",
        a_with / a_without
    );
    assert!(ring_pixels > 250, "ring of {ring_pixels} pixels");
    assert!(a_with >= a_without * MIN_GAIN, "{a_with:.1} with vs {a_without:.1} without silhouette fins");
    // Nothing the skin covered is lost.
    let lost = with.pixels().zip(&skin).filter(|(p, s)| **s && p[3] == 0).count();
    assert_eq!(lost, 0);
}

#[test]
fn a_frame_with_silhouette_fins_neither_submits_nor_waits() {
    let g = gpu();
    let asset = sphere();
    let renderer =
        FurRenderer::new(g.pipelines(), &g.queue, asset, &RenderSettings::default(), &RenderTarget::desc()).unwrap();
    assert!(renderer.has_silhouette_fins());
    let target = RenderTarget::new(&g.device, 64, 64).unwrap();
    let (center, radius) = asset.bounding_sphere();
    let frame = View::framing(center, radius).uniforms(64, 64);
    let calls = blocking_calls_on_this_thread();
    let mut encoder = g.device.create_command_encoder(&Default::default());
    renderer.prepare(&g.queue, &mut encoder, &frame);
    {
        let mut pass = target.begin_pass(&mut encoder, "silhouette test", Some([0.0; 4]));
        renderer.render(&mut pass);
    }
    assert_eq!(blocking_calls_on_this_thread(), calls, "prepare/render submitted or waited");
    g.queue.submit([encoder.finish()]);
    g.check().unwrap();
}
