//! A skinned pack previewed on its own is drawn in its rest pose — the skeleton's node
//! transforms, as a glTF viewer shows the file — not in raw bind space (docs/design.md
//! "Rendering"). Many exports put the up-axis rotation on the skeleton's root: here the strip
//! fixture's root joint turns it 90° about x, so at rest it lies along +z while its bind-space
//! vertices stand along +y. Its preview must cover what a static strip with the rotated
//! vertices covers, not what the upright bind-space strip covers.

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::testmesh::{SkinnedStrip, TestPrimitive, gltf_json};
use furbake_import::{ImportSettings, import_gltf_slice};
use furbake_render::RenderSettings;
use furbake_render::headless::render_pack;
use furbake_runtime::Pack;
use image::RgbaImage;

const W: u32 = 160;
const H: u32 = 120;

fn preview(gltf: &[u8], name: &str) -> RgbaImage {
    let imported = import_gltf_slice(gltf, name, None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    settings.volume.layers = 8;
    settings.volume.resolution = 16;
    let baked = bake(&imported, name, &settings.plan().unwrap(), &mut NoProgress).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("{name}.fbk"));
    baked.to_writer().write_atomic(&path).unwrap();
    let image = render_pack(&Pack::open(&path).unwrap(), W, H, None, &RenderSettings::default()).unwrap();
    let out = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&out).unwrap();
    image.save(out.join(format!("rest_pose_{name}.png"))).unwrap();
    image
}

/// Pixels that differ from the background (the top-left pixel).
fn mask(image: &RgbaImage) -> Vec<bool> {
    let bg = *image.get_pixel(0, 0);
    image.pixels().map(|p| p.0.iter().zip(bg.0).any(|(a, b)| a.abs_diff(b) > 12)).collect()
}

fn iou(a: &[bool], b: &[bool]) -> f64 {
    let both = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let either = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    both as f64 / either.max(1) as f64
}

#[test]
fn a_skinned_pack_alone_is_previewed_in_its_rest_pose() {
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let strip = SkinnedStrip::default();
    let upright = strip.to_gltf();
    let mut doc = strip.to_json();
    doc["nodes"][0]["rotation"] = serde_json::json!([s, 0.0, 0.0, s]);
    let turned = serde_json::to_vec(&doc).unwrap();
    // The same strip with the rotation applied to its vertices, static: (x, y, z) → (x, −z, y).
    let rotated: Vec<[f32; 3]> = strip.positions.iter().map(|p| [p[0], -p[2], p[1]]).collect();
    let static_strip = TestPrimitive {
        normals: Some(vec![[0.0, -1.0, 0.0]; rotated.len()]),
        ..TestPrimitive::triangles(rotated, vec![0, 1, 3, 0, 3, 2, 2, 3, 5, 2, 5, 4])
    };
    let reference = gltf_json(&[static_strip], None);
    let (turned, reference, upright) =
        (mask(&preview(&turned, "turned")), mask(&preview(&reference, "static")), mask(&preview(&upright, "upright")));
    let (rest, bind) = (iou(&turned, &reference), iou(&turned, &upright));
    println!("coverage IoU with the rotated static strip {rest:.3}, with the upright bind-space strip {bind:.3}");
    assert!(turned.iter().filter(|&&m| m).count() > 500, "the strip is drawn");
    assert!(rest > 0.8, "the preview is not the rest pose: IoU {rest:.3} with the rotated static strip");
    assert!(bind < 0.5, "the preview still draws bind space: IoU {bind:.3} with the upright strip");
}
