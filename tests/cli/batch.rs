//! `furbake batch`: every real fixture baked from one file, a second run skips them all, a
//! changed texture or setting rebakes only its asset, packs do not depend on `-j`, a failing
//! asset fails the batch without stopping the others, a bad setting anywhere stops the batch
//! before anything is baked, and the shards of a batch together bake exactly the whole batch.

use std::path::{Path, PathBuf};

use super::common::*;

/// Copies every real fixture (TwoSidedPlane with its folder) into `dir`; returns the glTF paths
/// relative to `dir`.
fn copy_fixtures(dir: &Path) -> Vec<String> {
    let mut inputs = Vec::new();
    for src in real_fixtures() {
        let rel = src.strip_prefix(real_dir()).unwrap().to_path_buf();
        let dst = dir.join(&rel);
        std::fs::create_dir_all(dst.parent().unwrap()).unwrap();
        for e in std::fs::read_dir(src.parent().unwrap()).unwrap() {
            let p = e.unwrap().path();
            let stem = src.file_stem().unwrap().to_string_lossy().into_owned();
            if p.is_file() && p.file_name().unwrap().to_string_lossy().starts_with(&stem) {
                std::fs::copy(&p, dst.parent().unwrap().join(p.file_name().unwrap())).unwrap();
            }
        }
        inputs.push(rel.to_string_lossy().into_owned());
    }
    inputs
}

fn batch_file(dir: &Path, inputs: &[String], extra: &str) -> PathBuf {
    let mut text = String::from(
        "[defaults]\nout_dir = \"packs\"\n[defaults.settings]\nvolume.resolution = 16\nvolume.layers = 4\n\n",
    );
    for i in inputs {
        text.push_str(&format!("[[asset]]\ninput = \"{i}\"\n"));
    }
    text.push_str(extra);
    let path = dir.join("assets.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// (baked, skipped, failed) from the summary line.
fn counts(err: &str) -> (usize, usize, usize) {
    let line = err.lines().find(|l| l.contains(" baked, ")).unwrap_or_else(|| panic!("no summary in {err}"));
    let n = |word: &str| -> usize {
        let before = line.split(&format!(" {word}")).next().unwrap();
        before.rsplit([' ', ':']).next().unwrap().parse().unwrap()
    };
    (n("baked"), n("skipped"), n("failed"))
}

fn packs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir.join("packs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "fbk"))
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect();
    out.sort();
    out
}

#[test]
fn batch_bakes_every_real_fixture_then_skips_what_is_up_to_date() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = copy_fixtures(dir.path());
    assert!(inputs.len() >= 6, "{inputs:?}");
    let file = batch_file(dir.path(), &inputs, "");
    let first = furbake(&["batch", s(&file), "-j", "2"]);
    assert_ok(&first, "batch");
    assert_eq!(counts(&stderr(&first)), (inputs.len(), 0, 0), "{}", stderr(&first));
    let baked = packs(dir.path());
    assert_eq!(baked.len(), inputs.len());
    for (name, bytes) in &baked {
        let pack = furbake_formats::Pack::from_bytes(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(!pack.manifest().unwrap().inputs.is_empty(), "{name}");
    }
    let second = furbake(&["batch", s(&file)]);
    assert_ok(&second, "batch again");
    assert_eq!(counts(&stderr(&second)), (0, inputs.len(), 0), "{}", stderr(&second));
    // A texture the bake sampled changes: only that asset is rebaked.
    let texture = dir.path().join("TwoSidedPlane/TwoSidedPlane_BaseColor.png");
    let mut img = image::open(&texture).unwrap().to_rgba8();
    img.pixels_mut().for_each(|p| p.0[0] = 255 - p.0[0]);
    img.save(&texture).unwrap();
    let third = furbake(&["batch", s(&file), "-q"]);
    assert_ok(&third, "batch after a texture change");
    let after = packs(dir.path());
    let changed: Vec<&str> = baked.iter().zip(&after).filter(|(a, b)| a.1 != b.1).map(|(a, _)| a.0.as_str()).collect();
    assert_eq!(changed, ["TwoSidedPlane.fbk"]);
    // A setting of one asset changes: only that asset is rebaked.
    let extra = "[[asset]]\ninput = \"Box.glb\"\noutput = \"packs/box-grass.fbk\"\npreset = \"grass\"\n";
    let file = batch_file(dir.path(), &inputs, extra);
    let fourth = furbake(&["batch", s(&file)]);
    assert_ok(&fourth, "batch with one more asset");
    assert_eq!(counts(&stderr(&fourth)), (1, inputs.len(), 0), "{}", stderr(&fourth));
}

#[test]
fn batch_output_does_not_depend_on_jobs_and_a_failure_does_not_stop_the_others() {
    let (one, three) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let mut results = Vec::new();
    for (dir, jobs) in [(one.path(), "1"), (three.path(), "3")] {
        let inputs = copy_fixtures(dir);
        std::fs::write(dir.join("broken.gltf"), "{ not json").unwrap();
        let mut all = inputs.clone();
        all.insert(1, "broken.gltf".into());
        let file = batch_file(dir, &all, "");
        let out = furbake(&["batch", s(&file), "-j", jobs]);
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        let err = stderr(&out);
        assert_eq!(counts(&err), (inputs.len(), 0, 1), "{err}");
        assert!(err.lines().any(|l| l.starts_with("failed") && l.contains("broken.gltf")), "{err}");
        let written = packs(dir);
        assert_eq!(written.len(), inputs.len(), "every other asset is written");
        results.push(written);
    }
    assert!(results[0] == results[1], "packs differ between -j 1 and -j 3");
}

#[test]
fn a_bad_setting_anywhere_stops_the_batch_before_any_bake() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = copy_fixtures(dir.path());
    let extra = "[[asset]]\ninput = \"Box.glb\"\noutput = \"packs/bad.fbk\"\n[asset.settings]\nvolume.layers = 0\n";
    let file = batch_file(dir.path(), &inputs, extra);
    let out = furbake(&["batch", s(&file)]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("asset") && err.contains("layers"), "{err}");
    assert!(!dir.path().join("packs").exists(), "nothing is baked");
    // Two assets writing one pack is a usage error too.
    let twice = "[[asset]]\ninput = \"Box.glb\"\n";
    let out = furbake(&["batch", s(&batch_file(dir.path(), &inputs, twice))]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    // An unknown key is a bad batch file (exit 1), naming the file.
    std::fs::write(dir.path().join("typo.toml"), "[[asset]]\ninptu = \"Box.glb\"\n").unwrap();
    let out = furbake(&["batch", s(&dir.path().join("typo.toml"))]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("typo.toml"), "{}", stderr(&out));
}

/// `--shard K/N`: the shards of a batch bake disjoint slices whose union is byte for byte the
/// whole batch; an asset keeps its shard when the batch file lists its assets in another order
/// (and with other assets around it); bad slices are usage errors.
#[test]
fn shards_bake_disjoint_slices_whose_union_is_the_whole_batch() {
    let whole = tempfile::tempdir().unwrap();
    let inputs = copy_fixtures(whole.path());
    let file = batch_file(whole.path(), &inputs, "");
    assert_ok(&furbake(&["batch", s(&file), "-q"]), "the whole batch");
    let all = packs(whole.path());
    let mut union: Vec<(String, Vec<u8>)> = Vec::new();
    let mut shard_of = std::collections::BTreeMap::new();
    for k in 1..=3 {
        let dir = tempfile::tempdir().unwrap();
        copy_fixtures(dir.path());
        let file = batch_file(dir.path(), &inputs, "");
        let out = furbake(&["batch", s(&file), "--shard", &format!("{k}/3")]);
        assert_ok(&out, "a shard");
        assert!(stderr(&out).contains(&format!("(shard {k}/3 of {})", inputs.len())), "{}", stderr(&out));
        std::fs::create_dir_all(dir.path().join("packs")).unwrap();
        for (name, bytes) in packs(dir.path()) {
            assert!(shard_of.insert(name.clone(), k).is_none(), "{name} baked by two shards");
            union.push((name, bytes));
        }
    }
    union.sort();
    assert_eq!(union.len(), all.len(), "every asset is in one shard");
    assert!(union == all, "the shards' packs differ from the whole batch's");
    assert!(shard_of.values().collect::<std::collections::BTreeSet<_>>().len() > 1, "one shard took everything");
    // Reversed order, one asset dropped and another added: the remaining assets keep their shard.
    let dir = tempfile::tempdir().unwrap();
    copy_fixtures(dir.path());
    let mut other: Vec<String> = inputs[1..].iter().rev().cloned().collect();
    std::fs::copy(dir.path().join("Box.glb"), dir.path().join("extra.glb")).unwrap();
    other.insert(2, "extra.glb".into());
    let file = batch_file(dir.path(), &other, "");
    for k in 1..=3 {
        let _ = std::fs::remove_dir_all(dir.path().join("packs"));
        assert_ok(&furbake(&["batch", s(&file), "-q", "--shard", &format!("{k}/3")]), "a shard of the reordered batch");
        std::fs::create_dir_all(dir.path().join("packs")).unwrap();
        for (name, _) in packs(dir.path()) {
            if let Some(&was) = shard_of.get(&name) {
                assert_eq!(was, k, "{name} moved from shard {was} to {k}");
            }
        }
    }
    for bad in ["0/3", "4/3", "1/0", "2", "a/b", "-1/3"] {
        let out = furbake(&["batch", s(&file), "--shard", bad]);
        assert_eq!(out.status.code(), Some(2), "--shard {bad}: {}", stderr(&out));
    }
}
