//! Animated inputs end to end (glTF 2.0 specification, "Skins", "Animations"): the Fox bakes with
//! its skeleton, skin weights and clips, `inspect` lists the clips (name, duration, channels,
//! bytes) and the joints, `verify` checks them, and a pack whose clip names a missing joint is
//! refused; `simulate --state-out` poses the skin as an independent implementation of the glTF
//! rules (`tools/gltf_pose.py`) does, on the real skinned, rigid-animated and morphed models.

use furbake_formats::sections::animation_clips::{AnimationClips, ChannelTarget};
use furbake_formats::{Pack, PackWriter};

use crate::common::*;
use crate::inspect_json;

#[test]
fn animation_the_fox_pack_lists_its_clips_and_joints() {
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("fox.fbk");
    let fox = real_fixture("Fox.glb");
    assert_ok(&furbake(&["bake", s(&fox), "-o", s(&pack), "--resolution", "32", "-q"]), "bake the fox");
    let verified = furbake(&["verify", s(&pack)]);
    assert_ok(&verified, "verify the fox");
    assert!(stdout(&verified).contains("9 sections"), "{}", stdout(&verified));
    let json = inspect_json(&pack);
    let kinds: Vec<&str> = json["sections"].as_array().unwrap().iter().map(|s| s["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds[6..], ["skeleton", "skin_weights", "animation_clips"]);
    let clips = json["clips"].as_array().unwrap();
    let names: Vec<&str> = clips.iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["Survey", "Walk", "Run"]);
    for c in clips {
        assert_eq!(c["channels"], 21, "{c}");
        assert!(c["duration_s"].as_f64().unwrap() > 0.5 && c["bytes"].as_u64().unwrap() > 1000, "{c}");
    }
    let joints = json["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 25, "24 skin joints and the scene's root node above them");
    assert_eq!(joints[0]["parent"], serde_json::Value::Null);
    assert_eq!(json["statistics"]["clips"], 3);
    let weights = &json["sections"][7];
    assert_eq!((weights["vertices"].as_u64(), weights["renormalised_vertices"].as_u64()), (Some(290), Some(0)));
    let table = stdout(&furbake(&["inspect", s(&pack)]));
    assert!(table.contains("animation_clips") && table.contains("\"Walk\""), "{table}");

    // A clip that drives a joint the skeleton does not have: verify exits 1 naming it.
    let p = Pack::read(&pack).unwrap();
    let mut w = PackWriter::new();
    for (i, e) in p.sections().iter().enumerate() {
        if e.kind == furbake_formats::SectionKind::ANIMATION_CLIPS {
            let mut clips: AnimationClips = p.decode(i).unwrap();
            clips.clips[1].channels[0].target = ChannelTarget::Rotation(99);
            w.push_section(&clips);
        } else {
            w.push(e.kind, e.version, p.payload(i).unwrap().to_vec());
        }
    }
    let bad = dir.path().join("bad.fbk");
    std::fs::write(&bad, w.to_bytes()).unwrap();
    let out = furbake(&["verify", s(&bad)]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("joint 99 is outside the skeleton's 25"), "{}", stderr(&out));
}

/// Runs the independent implementation of the glTF posing rules (`tools/gltf_pose.py`, Python
/// standard library only, written from the specification) and returns per input vertex its bind
/// position and its posed position.
fn independent_pose(model: &std::path::Path, clip: Option<(&str, f32)>) -> Vec<[f64; 6]> {
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/gltf_pose.py");
    let mut cmd = std::process::Command::new("python3");
    cmd.arg(&script).arg(model);
    if let Some((name, t)) = clip {
        cmd.args(["--animation", name, "--time", &t.to_string()]);
    }
    let out = cmd.output().expect("python3 runs (CI installs it; apt-get install python3)");
    assert!(out.status.success(), "gltf_pose.py failed: {}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    json["vertices"].as_array().unwrap().iter().map(|v| std::array::from_fn(|k| v[k].as_f64().unwrap())).collect()
}

/// `furbake simulate --frames 0 --state-out` of a scene holding `pack` at clip time `t` of
/// `clip` (speed 0), or in its bind pose: the skin vertices, world metres.
fn furbake_skin(dir: &std::path::Path, pack: &std::path::Path, clip: Option<(&str, f32)>) -> Vec<[f64; 3]> {
    let animation = match clip {
        Some((name, t)) => format!("animation = {{ clip = \"{name}\", speed = 0.0, start_s = {t}, loop = false }}\n"),
        None => String::new(),
    };
    let scene = dir.join("pose.toml");
    std::fs::write(&scene, format!("[[packs]]\nname = \"m\"\npath = \"{}\"\n{animation}", s(pack))).unwrap();
    let state = dir.join("state.json");
    let out = furbake(&["simulate", s(&scene), "--frames", "0", "--state-out", s(&state)]);
    assert_ok(&out, "simulate --state-out");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&state).unwrap()).unwrap();
    json["packs"][0]["skin_positions_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| std::array::from_fn(|k| v[k].as_f64().unwrap()))
        .collect()
}

/// Skinned skin vertices from `simulate --state-out` at a chosen clip time must agree with an
/// independent implementation of the glTF rules within 1e-4 of the model's bounding-box diagonal.
/// Welded vertices are matched to the input's by bind position (every input vertex within 1e-6 of
/// the diagonal of a welded one must pose where it does). Returns the largest error relative to the
/// diagonal.
fn check_against_independent(model: &std::path::Path, clip: &str, t: f32) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("m.fbk");
    assert_ok(&furbake(&["bake", s(model), "-o", s(&pack), "--resolution", "16", "--layers", "4", "-q"]), "bake");
    let bind = furbake_skin(dir.path(), &pack, None);
    let posed = furbake_skin(dir.path(), &pack, Some((clip, t)));
    let reference = independent_pose(model, Some((clip, t)));
    let (lo, hi) = bind.iter().fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
        (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
    });
    let diag = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    let dist = |a: &[f64], b: &[f64]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
    let mut worst = 0.0f64;
    let mut moved = 0.0f64;
    for (i, (b, p)) in bind.iter().zip(&posed).enumerate() {
        let matches: Vec<&[f64; 6]> = reference.iter().filter(|r| dist(&r[..3], b) <= 1e-6 * diag).collect();
        assert!(!matches.is_empty(), "{}: welded vertex {i} at {b:?} matches no input vertex", model.display());
        for r in matches {
            worst = worst.max(dist(&r[3..], p) / diag);
        }
        moved = moved.max(dist(b, p) / diag);
    }
    assert!(worst <= 1e-4, "{}: {clip} at {t} s: worst error {worst} of the diagonal", model.display());
    assert!(moved > 1e-3, "{}: {clip} at {t} s moves nothing ({moved})", model.display());
    worst
}

#[test]
fn animation_state_out_agrees_with_an_independent_implementation() {
    for (model, clip, t) in [
        ("Fox.glb", "Walk", 0.37),
        ("Fox.glb", "Run", 0.61),
        ("Quaternius_Wolf.glb", "Gallop", 0.3),
        ("CesiumMilkTruck.glb", "Wheels", 0.9),
    ] {
        let worst = check_against_independent(&real_fixture(model), clip, t);
        eprintln!("{model} {clip} @ {t} s: worst {worst:.2e} of the diagonal");
    }
    // Morph targets (position deltas, a weights channel) and cubic-spline keys: the skinned
    // strip of the import tests, written as a file.
    let dir = tempfile::tempdir().unwrap();
    let strip = dir.path().join("strip.gltf");
    std::fs::write(&strip, furbake_import::testmesh::SkinnedStrip::default().to_gltf()).unwrap();
    for (clip, t) in [("Morph", 0.3), ("Cubic", 0.45), ("Bend", 0.7), ("Step", 1.2)] {
        check_against_independent(&strip, clip, t);
    }
}
