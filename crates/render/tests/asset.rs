//! The renderer's inputs: `FurAsset::from_pack` reads only the sections it draws (the bake
//! manifest is never touched, the fin sections only when fins are wanted), inconsistent sections
//! and bad parameters are typed errors, and the end-to-end preview of the bundled Fox fixture
//! is framed and furry. The last test needs an adapter (lavapipe on machines without a GPU).

use std::path::Path;
use std::sync::Arc;

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_formats::SectionKind;
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use furbake_import::{ImportSettings, import_gltf, import_gltf_slice, testmesh};
use furbake_render::headless::{RenderTarget, render_preview};
use furbake_render::{FurAsset, FurRenderer, RenderError, RenderSettings};
use furbake_runtime::Pack;

fn write_pack(gltf_mesh: furbake_import::ImportedMesh, dir: &Path, name: &str, resolution: u32) -> std::path::PathBuf {
    let mut settings = BakeSettings::preset("fur").unwrap();
    settings.volume.resolution = resolution;
    let baked = bake(&gltf_mesh, name, &settings.plan().unwrap(), &mut NoProgress).unwrap();
    let path = dir.join(format!("{name}.fbk"));
    baked.to_writer().write_atomic(&path).unwrap();
    path
}

fn sphere_pack(dir: &Path) -> std::path::PathBuf {
    let gltf = testmesh::uv_sphere(6, 8, 1.0).gltf;
    let imported = import_gltf_slice(&gltf, "sphere.gltf", None, &ImportSettings::default()).unwrap();
    write_pack(imported, dir, "sphere", 16)
}

#[test]
fn from_pack_reads_only_the_sections_it_draws() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere_pack(dir.path());

    let pack = Pack::open(&path).unwrap();
    let asset = FurAsset::from_pack(&pack, false).unwrap();
    assert!(asset.fins().is_none());
    let expected = [SectionKind::SKIN_MESH, SectionKind::SHELL_ATLAS, SectionKind::TRIANGLE_UV_MAP];
    assert_eq!(pack.kinds_read(), expected, "without fins");

    let pack = Pack::open(&path).unwrap();
    let asset = FurAsset::from_pack(&pack, true).unwrap();
    assert!(asset.fins().is_some());
    let read = pack.kinds_read();
    assert_eq!(read.len(), 5, "{read:?}");
    assert!(!read.contains(&SectionKind::BAKE_MANIFEST), "the manifest is never needed to draw");
}

#[test]
fn inconsistent_sections_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let pack = Pack::open(sphere_pack(dir.path())).unwrap();
    let (mesh, shells, uv) = (pack.skin_mesh().unwrap(), pack.shell_atlas().unwrap(), pack.triangle_uv_map().unwrap());
    let short_uv = TriangleUvMap { corners: uv.corners[1..].to_vec(), ..(*uv).clone() };
    let err = FurAsset::new(mesh.clone(), shells.clone(), Arc::new(short_uv), None).unwrap_err();
    assert!(matches!(err, RenderError::InvalidAsset { .. }), "{err}");

    let mut bad_edges = (*pack.fin_edges().unwrap()).clone();
    bad_edges.vertices.push([0, mesh.positions.len() as u32]);
    bad_edges.triangles.push(0);
    bad_edges.kinds.push(furbake_formats::sections::fin_edges::FinEdgeKind::Border);
    let fins = Some((pack.fin_atlas().unwrap(), Arc::new(bad_edges)));
    let err = FurAsset::new(mesh, shells, uv, fins).unwrap_err();
    assert!(err.to_string().contains("fin_edges: vertex"), "{err}");
}

#[test]
fn bad_parameters_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let pack = Pack::open(sphere_pack(dir.path())).unwrap();
    let asset = FurAsset::from_pack(&pack, true).unwrap();
    let g = gpu();
    let mut checked = 0;
    for (w, h) in [(0, 16), (16, 0), (u32::MAX, 16)] {
        assert!(matches!(RenderTarget::new(&g.device, w, h), Err(RenderError::Parameter { .. })), "{w}×{h}");
        checked += 1;
    }
    for settings in [
        RenderSettings { alpha_threshold: 1.0, ..Default::default() },
        RenderSettings { shear_exponent: 0.0, ..Default::default() },
        RenderSettings { tint: [f32::NAN, 1.0, 1.0], ..Default::default() },
    ] {
        assert!(matches!(
            FurRenderer::new(g.pipelines(), &g.queue, &asset, &settings, &RenderTarget::desc()),
            Err(RenderError::Parameter { .. })
        ));
        checked += 1;
    }
    let renderer =
        FurRenderer::new(g.pipelines(), &g.queue, &asset, &RenderSettings::default(), &RenderTarget::desc()).unwrap();
    let n = asset.mesh().positions.len();
    assert!(renderer.set_scale_vectors(&g.queue, &vec![[0.0, 1.0, 0.0]; n - 1]).is_err(), "wrong count");
    assert!(renderer.set_scale_vectors(&g.queue, &vec![[f32::NAN, 1.0, 0.0]; n]).is_err(), "NaN");
    assert!(renderer.set_scale_vectors(&g.queue, &vec![[0.0, 1.0, 0.0]; n]).is_ok());
    checked += 3;
    assert_eq!(checked, 9);
}

#[test]
fn preview_of_the_fox_is_framed_and_furry() {
    let fox = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let dir = tempfile::tempdir().unwrap();
    let path = write_pack(import_gltf(&fox, &ImportSettings::default()).unwrap(), dir.path(), "fox", 64);
    let (w, h) = (192, 128);
    let image = render_preview(&furbake_runtime::Pack::open(&path).unwrap(), w, h, &Default::default()).unwrap();
    image.save(std::env::temp_dir().join("furbake_fox_preview_test.png")).unwrap();
    let bg = image.get_pixel(0, 0).0;
    let drawn: Vec<(u32, u32)> =
        image.enumerate_pixels().filter(|(_, _, p)| p.0 != bg).map(|(x, y, _)| (x, y)).collect();
    assert!(drawn.len() > (w * h / 8) as usize, "only {} pixels drawn", drawn.len());
    // The automatic camera fits the fox with a small margin: the drawn box reaches close to two
    // opposite borders and stays clear of all four.
    let (x0, x1) = (drawn.iter().map(|p| p.0).min().unwrap(), drawn.iter().map(|p| p.0).max().unwrap());
    let (y0, y1) = (drawn.iter().map(|p| p.1).min().unwrap(), drawn.iter().map(|p| p.1).max().unwrap());
    assert!(x0 > 0 && y0 > 0 && x1 < w - 1 && y1 < h - 1, "clipped: x {x0}..{x1}, y {y0}..{y1}");
    let fills_width = (x1 - x0) as f32 > 0.8 * w as f32;
    let fills_height = (y1 - y0) as f32 > 0.8 * h as f32;
    assert!(fills_width || fills_height, "loose framing: x {x0}..{x1}, y {y0}..{y1} of {w}×{h}");
}

#[test]
fn shearing_is_compiled_in_only_for_scenes_with_physics() {
    let parse = |extra: &str| {
        let text = format!("[[packs]]\nname = \"a\"\npath = \"a.fbk\"\n{extra}");
        furbake_runtime::Scene::from_toml_str(&text, Path::new("s.toml"), Path::new("/")).unwrap()
    };
    assert!(!RenderSettings::for_scene(&parse("")).shearing, "a static scene has no shear");
    assert!(RenderSettings::for_scene(&parse("[effects.gravity]\n")).shearing);
    assert!(RenderSettings::for_scene(&parse("[effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.0]\n")).shearing);
}
