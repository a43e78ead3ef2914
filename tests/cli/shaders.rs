//! `furbake shaders`: every target's files are what the manifest lists, byte-identical run to
//! run; the SPIR-V passes `spirv-val` (Vulkan 1.0) and the GLSL `glslangValidator` (Debian's
//! spirv-tools and glslang-tools, which `.ci/run` installs), file by file; HLSL and MSL are held
//! to committed snapshots of representative entry points (`FURBAKE_BLESS=1` rewrites them).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::*;

fn export(target: &str, dir: &Path) -> serde_json::Value {
    let out = furbake(&["shaders", "--target", target, "-o", s(dir)]);
    assert_ok(&out, "furbake shaders");
    assert!(stdout(&out).contains(&format!("{target} shaders and manifest.json")), "{}", stdout(&out));
    serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap()
}

fn files_in(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect()
}

/// Runs `tool` on every file of `dir` ending in one of `extensions`; returns how many passed.
fn validate_all(tool: &str, args: &[&str], dir: &Path, extensions: &[&str]) -> usize {
    let mut count = 0;
    for name in files_in(dir) {
        if !extensions.iter().any(|e| name.ends_with(e)) {
            continue;
        }
        let out = Command::new(tool)
            .args(args)
            .arg(dir.join(&name))
            .output()
            .unwrap_or_else(|e| panic!("{tool} is needed (apt-get install spirv-tools glslang-tools): {e}"));
        assert!(
            out.status.success(),
            "{tool} refuses {name}:\n{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        count += 1;
    }
    count
}

#[test]
fn every_target_writes_what_its_manifest_lists_the_same_every_run() {
    let tmp = tempfile::tempdir().unwrap();
    for target in ["spirv", "glsl", "hlsl", "msl"] {
        let (a, b) = (tmp.path().join(format!("{target}-a")), tmp.path().join(format!("{target}-b")));
        let manifest = export(target, &a);
        export(target, &b);
        let listed: BTreeSet<String> =
            manifest["files"].as_array().unwrap().iter().map(|f| f["file"].as_str().unwrap().to_string()).collect();
        let mut written = files_in(&a);
        assert!(written.remove("manifest.json"));
        assert_eq!(listed, written, "{target}: the manifest lists exactly the files written");
        for name in files_in(&a) {
            assert_eq!(
                std::fs::read(a.join(&name)).unwrap(),
                std::fs::read(b.join(&name)).unwrap(),
                "{target}: {name} differs run to run"
            );
        }
        // Every module's entry points are there, each switch combination once.
        for entry in [
            "vs_skin",
            "fs_skin",
            "vs_shell",
            "fs_shell",
            "vs_fin",
            "vs_silhouette_fin",
            "fs_fin",
            "cs_skin",
            "cs_silhouette",
            "vs_blade",
            "fs_blade",
            "cs_cull_clusters",
            "cs_compact",
            "cs_step",
            "cs_xpbd_step",
            "cs_pose_rest",
            "cs_guard",
            "cs_depth_copy",
            "cs_depth_reduce",
        ] {
            assert!(
                manifest["files"].as_array().unwrap().iter().any(|f| f["entry_point"] == entry),
                "{target}: {entry}"
            );
        }
        let shells: Vec<_> =
            manifest["files"].as_array().unwrap().iter().filter(|f| f["entry_point"] == "fs_shell").collect();
        assert!(
            shells
                .iter()
                .all(|f| !(f["constants"]["ALPHA_TO_COVERAGE"] == 1.0 && f["constants"]["ALPHA_BLEND"] == 1.0)),
            "never built together"
        );
        let lights: BTreeSet<u64> =
            shells.iter().map(|f| f["constants"]["LIGHT_SLOTS"].as_f64().unwrap() as u64).collect();
        assert_eq!(lights, BTreeSet::from([1, 2, 3, 4]));
        // The shells read the scale vectors the C interface hands out each frame.
        let vs = manifest["files"].as_array().unwrap().iter().find(|f| f["entry_point"] == "vs_shell").unwrap();
        let scale = vs["bindings"].as_array().unwrap().iter().find(|b| b["name"] == "scale_vectors").unwrap();
        assert!(scale["source"].as_str().unwrap().contains("furbake_world_fur_frame"), "{scale}");
        assert_eq!(scale["stride"], 16);
        assert_eq!(manifest["structs"]["Frame"]["members"][0]["name"], "view_proj");
        if target == "glsl" {
            // OpenGL binding points are shared by a program's stages: within a module each WGSL
            // resource has one GLSL binding in every file.
            let mut seen = std::collections::BTreeMap::new();
            for f in manifest["files"].as_array().unwrap() {
                for b in f["bindings"].as_array().unwrap() {
                    let key = (f["module"].to_string(), b["group"].as_u64(), b["binding"].as_u64());
                    let glsl = b["glsl_binding"].clone();
                    let first = seen.entry(key.clone()).or_insert_with(|| glsl.clone());
                    assert_eq!(*first, glsl, "{key:?} in {}", f["file"]);
                }
            }
        }
    }
}

#[test]
fn spirv_and_glsl_pass_the_khronos_validators() {
    let tmp = tempfile::tempdir().unwrap();
    let (spirv, glsl) = (tmp.path().join("spirv"), tmp.path().join("glsl"));
    export("spirv", &spirv);
    export("glsl", &glsl);
    let n = validate_all("spirv-val", &["--target-env", "vulkan1.0"], &spirv, &[".spv"]);
    assert!(n > 200, "{n} SPIR-V files");
    let m = validate_all("glslangValidator", &[], &glsl, &[".vert", ".frag", ".comp"]);
    assert_eq!(n, m, "one GLSL file per SPIR-V file");
}

/// Representative entry points: a sheared, skinned shell vertex; a strand-lit blended shell
/// fragment with two lights; the blade vertex; the skinning compute pass.
const SNAPSHOTS: [&str; 4] = [
    "shell.vs_shell.shear-skinned-strand",
    "shell.fs_shell.alpha_blend-lambert-shadow-strand.light_slots2",
    "blades.vs_blade",
    "skinning.cs_skin.morph-morph_normals-skin",
];

#[test]
fn hlsl_and_msl_match_their_snapshots() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/cli/reference/shaders");
    for (target, ext) in [("hlsl", "hlsl"), ("msl", "metal")] {
        let dir = tmp.path().join(target);
        export(target, &dir);
        for stem in SNAPSHOTS {
            let name = format!("{stem}.{ext}");
            let made = std::fs::read_to_string(dir.join(&name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            let path = reference.join(&name);
            if std::env::var_os("FURBAKE_BLESS").is_some() {
                std::fs::write(&path, &made).unwrap();
                continue;
            }
            let committed = std::fs::read_to_string(&path).unwrap_or_default();
            assert!(committed == made, "{name} differs from {} (an intended change: FURBAKE_BLESS=1)", path.display());
        }
    }
}

#[test]
fn an_output_that_is_a_file_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("taken");
    std::fs::write(&file, "x").unwrap();
    let out = furbake(&["shaders", "--target", "glsl", "-o", s(&file)]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("taken"), "{}", stderr(&out));
    let out = furbake(&["shaders", "--target", "wgsl", "-o", s(tmp.path())]);
    assert_eq!(out.status.code(), Some(2), "an unknown target is a usage error");
}
