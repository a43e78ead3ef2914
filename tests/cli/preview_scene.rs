//! `furbake preview SCENE.toml`: a runtime scene (a furry fox on a grass patch, both baked here)
//! renders as a still (`-o`) or as numbered frames (`--frames N --out-dir DIR`); frames show fur
//! and grass and change from one to the next when the scene declares wind, and not at all when
//! it declares nothing that moves; a scene with `parting` renders its separable topology's
//! per-corner scale vectors; a scene naming a missing pack exits 1 naming it and leaves no PNG;
//! bad flag combinations are usage errors (exit 2) that write nothing.

use std::path::{Path, PathBuf};

use image::RgbaImage;

use super::common::*;

/// Bakes the fox (fur) and the thesis's grass patch (400 blades/m²), each with the prisms and
/// separable-prisms topologies (`parting` needs the latter in every fur pack), into `dir` as
/// `fox.fbk` and `grass.fbk`, with small shell atlases.
fn bake_packs(dir: &Path) {
    let fox = dir.join("fox.fbk");
    let mesh = real_fixture("Fox.glb");
    let args = [
        "bake",
        s(&mesh),
        "-o",
        s(&fox),
        "--resolution",
        "64",
        "--topology",
        "prisms",
        "--topology",
        "separable-prisms",
        "-q",
    ];
    assert_ok(&furbake(&args), "bake fox");
    let patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let grass = dir.join("grass.fbk");
    let args = [
        "bake",
        s(&patch),
        "-o",
        s(&grass),
        "--preset",
        "grass",
        "--resolution",
        "16",
        "--blades",
        "400",
        "--set",
        "blades.keyframes.grid.poses=200",
        "--topology",
        "prisms",
        "--topology",
        "separable-prisms",
        "-q",
    ];
    assert_ok(&furbake(&args), "bake grass");
}

/// Writes `dir/name`: the fox (scaled to metres) standing on the grass patch (4 m, scaled to
/// 2 m), seen from the front-right and above, with `effects` appended.
fn write_scene(dir: &Path, name: &str, grass_path: &str, effects: &str) -> PathBuf {
    let text = format!(
        r#"time_step_s = 0.02

[camera]
eye = [1.6, 1.0, 2.2]
target = [0.0, 0.3, 0.0]
fov_y_deg = 40.0

[[packs]]
name = "fox"
path = "fox.fbk"
rotation_deg = [0.0, 30.0, 0.0]
scale = 0.01

[[packs]]
name = "grass"
path = "{grass_path}"
scale = 0.5
{effects}"#
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

const WIND: &str = "[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [2.0, 0.0, 0.5]\ngust_amplitude = 0.5\n";

/// Orange-brown fox fur: red well above green and blue.
fn is_fur(p: &image::Rgba<u8>) -> bool {
    p[0] as i32 > p[1] as i32 + 25 && p[0] as i32 > p[2] as i32 + 25
}

/// Grass blades: green well above red and blue.
fn is_grass(p: &image::Rgba<u8>) -> bool {
    p[1] as i32 > p[0] as i32 + 20 && p[1] as i32 > p[2] as i32 + 20
}

fn count(img: &RgbaImage, keep: fn(&image::Rgba<u8>) -> bool) -> usize {
    img.pixels().filter(|p| keep(p)).count()
}

fn differing(a: &RgbaImage, b: &RgbaImage) -> usize {
    a.pixels().zip(b.pixels()).filter(|(x, y)| x != y).count()
}

/// PNG files in `dir` (sorted), and whether anything else is there.
fn pngs_in(dir: &Path) -> (Vec<String>, Vec<String>) {
    let mut pngs = Vec::new();
    let mut other = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.ends_with(".png") { pngs.push(name) } else { other.push(name) }
        }
    }
    pngs.sort();
    (pngs, other)
}

#[test]
fn preview_scene_writes_frames_with_fur_and_grass_that_move_in_the_wind() {
    let dir = tempfile::tempdir().unwrap();
    bake_packs(dir.path());
    let windy = write_scene(dir.path(), "windy.toml", "grass.fbk", WIND);
    let frames_dir = dir.path().join("frames");
    let out = furbake(&["preview", s(&windy), "--frames", "3", "--out-dir", s(&frames_dir), "--size", "128x128"]);
    assert_ok(&out, "preview --frames 3");
    assert!(stderr(&out).contains("3 frames"), "{}", stderr(&out));
    let (pngs, other) = pngs_in(&frames_dir);
    assert_eq!(pngs, ["frame_0000.png", "frame_0001.png", "frame_0002.png"]);
    assert!(other.is_empty(), "left behind: {other:?}");
    let frames: Vec<RgbaImage> = pngs.iter().map(|n| image::open(frames_dir.join(n)).unwrap().to_rgba8()).collect();
    let mut checked = 0;
    for (name, img) in pngs.iter().zip(&frames) {
        assert_eq!(img.dimensions(), (128, 128), "{name}");
        // The top-left corner is sky (background): the patch and the fox are below and right.
        let bg = *img.get_pixel(0, 0);
        let covered = img.pixels().filter(|p| **p != bg).count();
        let (fur, grass) = (count(img, is_fur), count(img, is_grass));
        println!("{name}: {covered} covered, {fur} fur, {grass} grass pixels");
        assert!(covered > 128 * 128 / 5, "{name}: only {covered} pixels differ from the background");
        assert!(fur > 150, "{name}: only {fur} fox-fur pixels");
        assert!(grass > 500, "{name}: only {grass} grass pixels");
        checked += 1;
    }
    assert_eq!(checked, 3);
    // Wind moves the fur and the blades between steps.
    for (i, pair) in frames.windows(2).enumerate() {
        let d = differing(&pair[0], &pair[1]);
        println!("frames {i}→{}: {d} pixels differ", i + 1);
        assert!(d > 30, "frames {i} and {} differ in only {d} pixels under wind", i + 1);
    }

    // Control: a scene with no effect moves nothing, so its frames are identical; the change
    // above comes from the physics, not from the renderer.
    let still = write_scene(dir.path(), "still.toml", "grass.fbk", "");
    let still_dir = dir.path().join("still-frames");
    let out = furbake(&["preview", s(&still), "--frames", "2", "--out-dir", s(&still_dir), "--size", "128x128", "-q"]);
    assert_ok(&out, "preview of a static scene");
    assert!(stderr(&out).is_empty(), "-q prints nothing: {}", stderr(&out));
    let a = image::open(still_dir.join("frame_0000.png")).unwrap().to_rgba8();
    let b = image::open(still_dir.join("frame_0001.png")).unwrap().to_rgba8();
    assert_eq!(differing(&a, &b), 0, "a scene without effects changed between frames");

    // A still (-o) of the windy scene after the default settle time.
    let png = dir.path().join("still.png");
    let out = furbake(&["preview", s(&windy), "-o", s(&png), "--size", "96x64"]);
    assert_ok(&out, "preview -o");
    assert!(stderr(&out).contains("0.5"), "the still's scene time is reported: {}", stderr(&out));
    let img = image::open(&png).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (96, 64));
    assert!(count(&img, is_grass) > 100 && count(&img, is_fur) > 30, "the still shows no fox or grass");
}

#[test]
fn preview_scene_with_parting_renders_the_separable_topology() {
    // `parting` makes the world simulate the separable prisms (one scale vector per triangle
    // corner), which the renderer must take as they are.
    let dir = tempfile::tempdir().unwrap();
    bake_packs(dir.path());
    let parted = write_scene(dir.path(), "parted.toml", "grass.fbk", &format!("{WIND}[effects.parting]\n"));
    let sim = furbake(&["simulate", s(&parted), "--frames", "2", "--json", "-q"]);
    assert_ok(&sim, "simulate parted");
    let report: serde_json::Value = serde_json::from_slice(&sim.stdout).unwrap();
    assert_eq!(report["packs"][0]["topology"], "separable-prisms", "{report}");
    assert_eq!(report["packs"][1]["topology"], "separable-prisms", "{report}");
    let png = dir.path().join("parted.png");
    let out = furbake(&["preview", s(&parted), "-o", s(&png), "--size", "128x128", "--settle", "0.2", "-q"]);
    assert_ok(&out, "preview parted");
    let img = image::open(&png).unwrap().to_rgba8();
    let (fur, grass) = (count(&img, is_fur), count(&img, is_grass));
    println!("parted: {fur} fur, {grass} grass pixels");
    assert!(fur > 150 && grass > 500, "parted scene: {fur} fur and {grass} grass pixels");
}

#[test]
fn preview_scene_naming_a_missing_pack_exits_1_and_leaves_no_png() {
    let dir = tempfile::tempdir().unwrap();
    bake_packs(dir.path());
    let scene = write_scene(dir.path(), "broken.toml", "no-such-grass.fbk", WIND);
    let frames_dir = dir.path().join("frames");
    let png = dir.path().join("broken.png");
    let mut cases = 0;
    for args in [
        vec!["preview", s(&scene), "--frames", "3", "--out-dir", s(&frames_dir), "--size", "64x64"],
        vec!["preview", s(&scene), "-o", s(&png), "--size", "64x64"],
    ] {
        let out = furbake(&args);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", stderr(&out));
        let err = stderr(&out);
        assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
        assert!(err.contains("no-such-grass.fbk"), "the message does not name the missing pack: {err}");
        cases += 1;
    }
    assert_eq!(cases, 2);
    assert!(!png.exists(), "a failed still left {png:?}");
    let (pngs, other) = pngs_in(&frames_dir);
    assert!(pngs.is_empty() && other.is_empty(), "a failed animation left {pngs:?} {other:?}");
    // A scene file that does not parse is bad input too, naming the scene.
    let garbled = dir.path().join("garbled.toml");
    std::fs::write(&garbled, "[[packs]\nname = ").unwrap();
    let out = furbake(&["preview", s(&garbled), "-o", s(&png)]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("garbled.toml"), "{}", stderr(&out));
    assert!(!png.exists());
}

#[test]
fn preview_flag_misuse_is_a_usage_error_that_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    // No bake needed: usage is checked before any pack is opened.
    let scene = write_scene(dir.path(), "scene.toml", "grass.fbk", WIND);
    let pack = dir.path().join("fox.fbk");
    std::fs::write(&pack, furbake_formats::MAGIC).unwrap();
    let junk = dir.path().join("notes.txt");
    std::fs::write(&junk, "neither a pack nor a scene\n").unwrap();
    let frames_dir = dir.path().join("frames");
    let png = dir.path().join("x.png");
    let cases: Vec<Vec<&str>> = vec![
        vec!["preview", s(&scene), "--frames", "0", "--out-dir", s(&frames_dir)],
        vec!["preview", s(&scene), "--frames", "3"],
        vec!["preview", s(&scene), "--out-dir", s(&frames_dir)],
        vec!["preview", s(&scene), "--frames", "3", "--out-dir", s(&frames_dir), "-o", s(&png)],
        vec!["preview", s(&scene)],
        vec!["preview", s(&scene), "-o", s(&png), "--settle", "1e9"],
        vec!["preview", s(&pack), "--frames", "3", "--out-dir", s(&frames_dir)],
        vec!["preview", s(&pack), "-o", s(&png), "--settle", "1"],
        vec!["preview", s(&junk), "-o", s(&png)],
        vec!["preview", s(&scene), "-o", s(&png), "--silhouette-band", "2"],
        vec!["preview", s(&pack), "-o", s(&png), "--alpha-threshold", "1"],
        vec!["preview", s(&pack), "-o", s(&png), "--shells", "2000"],
        vec!["preview", s(&pack), "-o", s(&png), "--blend", "additive"],
        vec!["preview", s(&pack), "-o", s(&png), "--anisotropy", "3"],
    ];
    let mut checked = 0;
    for args in &cases {
        let out = furbake(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(!png.exists() && !frames_dir.exists(), "{args:?} wrote output");
        checked += 1;
    }
    assert_eq!(checked, cases.len());
    let err = stderr(&furbake(&["preview", s(&scene), "-o", s(&png), "--silhouette-band", "2"]));
    assert!(err.contains("--silhouette-band") && err.contains("[0, 1]"), "{err}");
    let err = stderr(&furbake(&["preview", s(&junk), "-o", s(&png)]));
    assert!(err.contains("notes.txt") && err.contains("SCENE.toml"), "{err}");
    let err = stderr(&furbake(&["preview", s(&pack), "-o", s(&png), "--anisotropy", "3"]));
    assert!(err.contains("--anisotropy") && err.contains("1, 2, 4, 8 or 16"), "{err}");
}

#[test]
fn a_scene_over_the_gpu_memory_budget_is_refused_before_anything_is_created() {
    // Cause: `preview` of a scene with 500 entries of the same two packs needed 3.5 GB and, under
    // a memory limit, panicked inside wgpu or segfaulted. Entries of one pack now share its
    // uploaded data (that scene renders in 585 MB resident, under the default 2 GiB budget); the
    // renderers' memory is estimated from the packs first and a scene above `--max-memory` exits
    // 2 before anything is created.
    let dir = tempfile::tempdir().unwrap();
    bake_packs(dir.path());
    let mut text = String::from("time_step_s = 0.02\n");
    for i in 0..500 {
        for pack in ["fox", "grass"] {
            text += &format!("[[packs]]\nname = \"{pack}{i}\"\npath = \"{pack}.fbk\"\nscale = 0.01\n");
        }
    }
    text += "[effects.gravity]\n";
    let big = dir.path().join("big.toml");
    std::fs::write(&big, text).unwrap();
    let png = dir.path().join("big.png");
    let started = std::time::Instant::now();
    let out = furbake(&["preview", s(&big), "-o", s(&png), "--size", "64x64", "--max-memory", "512M"]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("1000 pack entries") && err.contains("--max-memory 512 MiB"), "{err}");
    // Shared uploads: the estimate is far below what 1000 separate uploads would need.
    let mib: u64 = err.split("need about ").nth(1).and_then(|t| t.split(' ').next()).unwrap().parse().unwrap();
    assert!(mib < 2048, "the 1000-entry scene fits the default budget now: {mib} MiB");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(!png.exists());
    println!("refused in {:.2} s: {err}", started.elapsed().as_secs_f64());
    // The same budget check on a small scene: a tiny budget refuses it, an ordinary one renders.
    let small = write_scene(dir.path(), "small.toml", "grass.fbk", "");
    let out = furbake(&["preview", s(&small), "-o", s(&png), "--size", "64x64", "--max-memory", "1M"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(!png.exists());
    let out = furbake(&["preview", s(&small), "-o", s(&png), "--size", "64x64", "--max-memory", "64M", "-q"]);
    assert_ok(&out, "small scene within 64 MiB");
    assert!(png.exists());
    let out = furbake(&["preview", s(&small), "-o", s(&png), "--max-memory", "lots"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}
