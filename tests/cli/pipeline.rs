//! Build pipelines: `bake --depfile` driven by the real `ninja` (a second run does nothing,
//! touching one asset's texture rebakes only that pack), the depfile's contents, and the
//! machine-readable `bake --report`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use super::common::*;

/// Copies the real `TwoSidedPlane` (a .gltf with an external buffer and textures) into `dir`.
fn copy_plane(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    for entry in std::fs::read_dir(real_fixture("TwoSidedPlane")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
    }
}

fn ninja(dir: &Path) -> Output {
    let out =
        Command::new("ninja").arg("-C").arg(dir).output().unwrap_or_else(|e| {
            panic!("cannot run ninja ({e}): install it with `make deps` (Debian package ninja-build)")
        });
    assert!(out.status.success(), "ninja failed: {}{}", stdout(&out), stderr(&out));
    out
}

/// The packs a ninja run baked, from its `[i/n] furbake bake …` status lines.
fn baked(out: &Output) -> Vec<String> {
    let mut packs: Vec<String> =
        stdout(out).lines().filter_map(|l| l.split_once("BAKE ").map(|(_, pack)| pack.trim().to_owned())).collect();
    packs.sort();
    packs
}

#[test]
fn ninja_rebakes_only_the_pack_whose_texture_changed() {
    let dir = tempfile::tempdir().unwrap();
    for asset in ["a", "b", "c"] {
        copy_plane(&dir.path().join(asset));
    }
    let build = format!(
        "rule bake\n  command = {} bake $in -o $out --resolution 16 -q --depfile $out.d\n  depfile = $out.d\n  \
         deps = gcc\n  description = BAKE $out\n\n\
         build a.fbk: bake a/TwoSidedPlane.gltf\nbuild b.fbk: bake b/TwoSidedPlane.gltf\n\
         build c.fbk: bake c/TwoSidedPlane.gltf\n",
        env!("CARGO_BIN_EXE_furbake")
    );
    std::fs::write(dir.path().join("build.ninja"), build).unwrap();
    assert_eq!(baked(&ninja(dir.path())), ["a.fbk", "b.fbk", "c.fbk"]);
    let again = ninja(dir.path());
    assert!(baked(&again).is_empty() && stdout(&again).contains("no work to do"), "{}", stdout(&again));
    // The base colour texture is only named by the glTF: ninja knows it from the depfile.
    let texture = dir.path().join("b/TwoSidedPlane_BaseColor.png");
    // "Touch": now is later than every pack (ninja compares nanosecond mtimes); a time in the
    // future would keep the rebaked pack older than its input.
    let touch = |p: &Path| {
        std::fs::File::options().append(true).open(p).unwrap().set_modified(std::time::SystemTime::now()).unwrap()
    };
    touch(&texture);
    assert_eq!(baked(&ninja(dir.path())), ["b.fbk"]);
    // So is the external buffer.
    let buffer = dir.path().join("c/TwoSidedPlane.bin");
    touch(&buffer);
    assert_eq!(baked(&ninja(dir.path())), ["c.fbk"]);
    assert!(baked(&ninja(dir.path())).is_empty());
}

/// The inputs a depfile lists (unescaped), after its `target:`.
fn depfile_inputs(text: &str) -> (String, Vec<String>) {
    let joined = text.replace("\\\n", " ");
    let (target, rest) = joined.split_once(": ").expect("target: inputs");
    let mut inputs = Vec::new();
    let mut cur = String::new();
    let mut chars = rest.trim_end().chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if matches!(chars.peek(), Some(' ' | '#')) => cur.push(chars.next().unwrap()),
            '$' if chars.peek() == Some(&'$') => {
                chars.next();
                cur.push('$');
            }
            ' ' => {
                if !cur.is_empty() {
                    inputs.push(std::mem::take(&mut cur));
                }
            }
            c => cur.push(c),
        }
    }
    if !cur.is_empty() {
        inputs.push(cur);
    }
    (target.to_owned(), inputs)
}

#[test]
fn the_depfile_lists_every_file_the_bake_read_and_the_config() {
    let dir = tempfile::tempdir().unwrap();
    // A folder name that needs escaping in a depfile.
    let assets = dir.path().join("my assets");
    copy_plane(&assets);
    let config = dir.path().join("fur $1.toml");
    std::fs::write(&config, "seed = 3\n").unwrap();
    let (pack, dep) = (dir.path().join("plane.fbk"), dir.path().join("plane.d"));
    let gltf = assets.join("TwoSidedPlane.gltf");
    let args =
        ["bake", s(&gltf), "-o", s(&pack), "--resolution", "16", "-q", "--config", s(&config), "--depfile", s(&dep)];
    assert_ok(&furbake(&args), "bake --depfile");
    let (target, inputs) = depfile_inputs(&std::fs::read_to_string(&dep).unwrap());
    assert_eq!(target, s(&pack).replace(' ', "\\ "));
    let expect: Vec<PathBuf> = vec![
        gltf.clone(),
        assets.join("TwoSidedPlane.bin"),
        assets.join("TwoSidedPlane_BaseColor.png"),
        config.clone(),
    ];
    let got: Vec<PathBuf> = inputs.iter().map(PathBuf::from).collect();
    assert_eq!(got, expect, "the glTF, its buffer, the one image it samples, the config");
    // The manifest records the same files by name relative to the glTF, with their hashes.
    let json: serde_json::Value = serde_json::from_slice(&furbake(&["inspect", "--json", s(&pack)]).stdout).unwrap();
    let manifest = json["sections"].as_array().unwrap().iter().find(|s| s["kind"] == "bake_manifest").unwrap();
    let names: Vec<&str> = manifest["inputs"].as_array().unwrap().iter().map(|i| i["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["TwoSidedPlane.gltf", "TwoSidedPlane.bin", "TwoSidedPlane_BaseColor.png"]);
    for i in manifest["inputs"].as_array().unwrap() {
        let bytes = std::fs::read(assets.join(i["name"].as_str().unwrap())).unwrap();
        assert_eq!(i["bytes"].as_u64().unwrap(), bytes.len() as u64, "{i}");
        assert_eq!(i["sha256"].as_str().unwrap().len(), 64, "{i}");
    }
    // A failed bake writes neither the pack nor the depfile.
    let (bad_pack, bad_dep) = (dir.path().join("bad.fbk"), dir.path().join("bad.d"));
    std::fs::write(assets.join("broken.gltf"), "{ not json").unwrap();
    let out = furbake(&["bake", s(&assets.join("broken.gltf")), "-o", s(&bad_pack), "--depfile", s(&bad_dep), "-q"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(!bad_pack.exists() && !bad_dep.exists());
}

#[test]
fn the_bake_report_has_stage_times_sections_hashes_and_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let (pack, report) = (dir.path().join("fox.fbk"), dir.path().join("fox.json"));
    let fox = real_fixture("Fox.glb");
    let args =
        ["bake", s(&fox), "-o", s(&pack), "--resolution", "32", "--topology", "prisms", "-q", "--report", s(&report)];
    assert_ok(&furbake(&args), "bake --report");
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(r["schema"], "furbake-bake-report/1");
    assert_eq!(r["tool"], "furbake");
    let bytes = std::fs::read(&pack).unwrap();
    assert_eq!(r["pack_bytes"].as_u64().unwrap(), bytes.len() as u64);
    use sha2::Digest;
    let hash: String = sha2::Sha256::digest(&bytes).iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(r["pack_sha256"], hash.as_str());
    let stages: Vec<&str> = r["stages"].as_array().unwrap().iter().map(|s| s["stage"].as_str().unwrap()).collect();
    assert_eq!(stages, ["import", "volume", "uv_map", "fin_edges", "topologies", "write"]);
    let sum: f64 = r["stages"].as_array().unwrap().iter().map(|s| s["wall_s"].as_f64().unwrap()).sum();
    let total = r["total_wall_s"].as_f64().unwrap();
    assert!(sum > 0.0 && (sum - total).abs() <= 1e-6 * total.max(1.0) + 1e-9, "stages {sum} s vs total {total} s");
    let sections = r["sections"].as_array().unwrap();
    let kinds: Vec<&str> = sections.iter().map(|s| s["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds[0], "bake_manifest");
    assert!(kinds.contains(&"spring_topology") && kinds.contains(&"skeleton"), "{kinds:?}");
    let payload: u64 = sections.iter().map(|s| s["bytes"].as_u64().unwrap()).sum();
    assert!(payload > 0 && payload < bytes.len() as u64);
    assert_eq!(r["inputs"][0]["name"], "Fox.glb");
    assert_eq!(r["mesh"]["vertices"], 290);
    // The settings hash names the resolved plan: the same plan spelled with --set hashes equal,
    // another resolution does not.
    let same = dir.path().join("same.json");
    let same_pack = dir.path().join("same.fbk");
    let args = ["bake", s(&fox), "-o", s(&same_pack), "--set", "volume.resolution=32"];
    assert_ok(&furbake(&[&args[..], &["--topology", "prisms", "-q", "--report", s(&same)]].concat()), "bake --set");
    let other = dir.path().join("other.json");
    let other_pack = dir.path().join("other.fbk");
    let args = ["bake", s(&fox), "-o", s(&other_pack), "--resolution", "16", "--topology", "prisms"];
    assert_ok(&furbake(&[&args[..], &["-q", "--report", s(&other)]].concat()), "bake other");
    let read = |p: &Path| -> serde_json::Value { serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap() };
    assert_eq!(read(&same)["settings_sha256"], r["settings_sha256"]);
    assert_eq!(read(&same)["pack_sha256"], r["pack_sha256"], "same plan, same bytes");
    assert_ne!(read(&other)["settings_sha256"], r["settings_sha256"]);
}
