//! Hostile pipelines (docs/design.md "Safe outputs", "Bounded reads"): outputs that are devices,
//! FIFOs, directories, inputs or each other are refused before anything is written; special
//! files and oversized files as main inputs are refused at once, never read or waited on; a
//! planted manifest cannot make `batch` read outside the asset roots or hang on a FIFO;
//! non-finite TOML numbers are refused by key.
//!
//! Every command runs under a watchdog ([`run_within`]): a regression that blocks on a FIFO
//! fails the test instead of hanging it.

use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use super::common::*;

/// Runs furbake with `args`, killing it (and failing) after `limit`.
fn run_within(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_furbake"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the furbake binary runs");
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            let out = child.wait_with_output().unwrap();
            panic!("furbake {args:?} still ran after {limit:?} (blocked?): {}", stderr(&out));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn quick(args: &[&str]) -> Output {
    run_within(args, Duration::from_secs(60))
}

fn mkfifo(path: &Path) {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo keeps nothing.
    assert_eq!(unsafe { libc_mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", path.display());
}

unsafe extern "C" {
    #[link_name = "mkfifo"]
    fn libc_mkfifo(path: *const std::ffi::c_char, mode: u32) -> i32;
    #[link_name = "mknod"]
    fn libc_mknod(path: *const std::ffi::c_char, mode: u32, dev: u64) -> i32;
}

/// A character device in the test's own directory: a private copy of `/dev/null` (major 1,
/// minor 3) made with mknod where this process may (root, as CI containers run), else a symlink
/// to `/dev/null` — either way nothing outside the directory can be replaced if a check fails.
fn private_device(path: &Path) -> &'static str {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    const S_IFCHR: u32 = 0o020000;
    // SAFETY: a valid NUL-terminated path; mknod keeps nothing. makedev(1, 3) = 0x103.
    if unsafe { libc_mknod(c.as_ptr(), S_IFCHR | 0o666, 0x103) } == 0 {
        return "a private device node";
    }
    std::os::unix::fs::symlink("/dev/null", path).unwrap();
    "a symlink to /dev/null"
}

/// Copies the real `TwoSidedPlane` (a .gltf with an external buffer and textures) into the new
/// directory `dir`.
fn copy_plane(dir: &Path) {
    std::fs::create_dir(dir).unwrap();
    for e in std::fs::read_dir(real_fixture("TwoSidedPlane")).unwrap() {
        let e = e.unwrap().path();
        std::fs::copy(&e, dir.join(e.file_name().unwrap())).unwrap();
    }
}

fn is_fifo(p: &Path) -> bool {
    std::fs::symlink_metadata(p).unwrap().file_type().is_fifo()
}

fn is_device_or_link(p: &Path) -> bool {
    let t = std::fs::symlink_metadata(p).unwrap().file_type();
    t.is_char_device() || t.is_symlink()
}

/// No file but `keep` in `dir` (nothing half-written, no temporary file).
fn only(dir: &Path, keep: &[&str]) {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    let mut want: Vec<String> = keep.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(names, want);
}

#[test]
fn outputs_over_devices_fifos_and_directories_are_refused_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = d.join("box.glb");
    std::fs::copy(real_fixture("Box.glb"), &mesh).unwrap();
    let fifo = d.join("fifo");
    mkfifo(&fifo);
    let device = d.join("null");
    let made = private_device(&device);
    std::fs::create_dir(d.join("sub")).unwrap();
    let pack = d.join("box.fbk");
    let sub_dir = d.join("sub");
    let (m, p, f, n, sub) = (s(&mesh), s(&pack), s(&fifo), s(&device), s(&sub_dir));
    let mut cases = 0;
    for (args, flag, kind) in [
        (vec!["bake", m, "-o", f], "--output", "a FIFO"),
        (vec!["bake", m, "-o", n], "--output", "a character device"),
        (vec!["bake", m, "-o", p, "--depfile", f], "--depfile", "a FIFO"),
        (vec!["bake", m, "-o", p, "--report", n], "--report", "a character device"),
        (vec!["bake", m, "-o", p, "--depfile", sub], "--depfile", "a directory"),
    ] {
        let out = quick(&[&args[..], &["-q", "--resolution", "8"]].concat());
        assert_eq!(out.status.code(), Some(2), "{args:?} ({made}): {}", stderr(&out));
        let err = stderr(&out);
        assert!(err.contains(flag) && err.contains(kind), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        cases += 1;
    }
    assert_eq!(cases, 5);
    assert!(is_fifo(&fifo) && is_device_or_link(&device), "the special files are still what they were");
    only(d, &["box.glb", "fifo", "null", "sub"]);
}

#[test]
fn outputs_equal_to_inputs_or_to_each_other_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("o")).unwrap();
    let mesh = d.join("box.glb");
    std::fs::copy(real_fixture("Box.glb"), &mesh).unwrap();
    let before = std::fs::read(&mesh).unwrap();
    std::os::unix::fs::symlink(&mesh, d.join("link.glb")).unwrap();
    let cfg = d.join("bake.toml");
    std::fs::write(&cfg, "seed = 3\n").unwrap();
    let pack_path = d.join("o/x.fbk");
    let (m, pack, dotted) = (s(&mesh), s(&pack_path), d.join("o/../o/x.fbk"));
    let mut cases = 0;
    for (args, want) in [
        (vec!["bake", m, "-o", m], "--output"),
        (vec!["bake", m, "-o", s(&d.join("link.glb"))], "--output"),
        (vec!["bake", m, "-o", s(&d.join("./o/../box.glb"))], "--output"),
        (vec!["bake", m, "-o", pack, "--depfile", s(&dotted)], "--depfile"),
        (vec!["bake", m, "-o", pack, "--report", pack], "--report"),
        (vec!["bake", m, "-o", pack, "--config", s(&cfg), "--report", s(&cfg)], "--report"),
    ] {
        let out = quick(&[&args[..], &["-q", "--resolution", "8"]].concat());
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(stderr(&out).contains(want), "{args:?}: {}", stderr(&out));
        cases += 1;
    }
    assert_eq!(cases, 6);
    assert_eq!(std::fs::read(&mesh).unwrap(), before, "the input is untouched");
    assert!(!d.join("o/x.fbk").exists());
    // A file the glTF names (its external buffer) is an input too, known once it is read.
    let plane = d.join("plane");
    copy_plane(&plane);
    let bin = plane.join("TwoSidedPlane.bin");
    let bin_bytes = std::fs::read(&bin).unwrap();
    let out = quick(&["bake", s(&plane.join("TwoSidedPlane.gltf")), "-o", s(&bin), "-q", "--resolution", "8"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("is the input") && stderr(&out).contains("TwoSidedPlane.bin"), "{}", stderr(&out));
    assert_eq!(std::fs::read(&bin).unwrap(), bin_bytes);
}

#[test]
fn batch_outputs_never_replace_inputs_the_batch_file_or_each_other() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("o")).unwrap();
    for name in ["a.glb", "b.glb"] {
        std::fs::copy(real_fixture("Box.glb"), d.join(name)).unwrap();
    }
    let batch = d.join("assets.toml");
    let mut cases = 0;
    for (assets, want) in [
        ("[[asset]]\ninput = \"a.glb\"\noutput = \"a.glb\"\n", "is the input"),
        ("[[asset]]\ninput = \"a.glb\"\noutput = \"b.glb\"\n[[asset]]\ninput = \"b.glb\"\n", "is the input"),
        ("[[asset]]\ninput = \"a.glb\"\noutput = \"assets.toml\"\n", "is the input"),
        (
            "[[asset]]\ninput = \"a.glb\"\noutput = \"o/x.fbk\"\n[[asset]]\ninput = \"b.glb\"\noutput = \"o/../o/x.fbk\"\n",
            "is the same file as",
        ),
        (
            "[defaults]\ndepfile = true\n[[asset]]\ninput = \"a.glb\"\noutput = \"o/x\"\n[[asset]]\ninput = \"b.glb\"\noutput = \"o/x.d\"\n",
            "is the same file as",
        ),
    ] {
        std::fs::write(&batch, assets).unwrap();
        let out = quick(&["batch", s(&batch), "-q"]);
        assert_eq!(out.status.code(), Some(2), "{assets}: {}", stderr(&out));
        assert!(stderr(&out).contains(want), "{assets}: {}", stderr(&out));
        cases += 1;
    }
    assert_eq!(cases, 5);
    let box_bytes = std::fs::read(real_fixture("Box.glb")).unwrap();
    for name in ["a.glb", "b.glb"] {
        assert_eq!(std::fs::read(d.join(name)).unwrap(), box_bytes, "{name} untouched");
    }
    only(&d.join("o"), &[]);
}

#[test]
fn special_files_as_main_inputs_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = d.join("in.fifo");
    mkfifo(&fifo);
    let mesh = real_fixture("Box.glb");
    let (out_path, png_path) = (d.join("out"), d.join("p.png"));
    let (f, z, out, png) = (s(&fifo), "/dev/zero", s(&out_path), s(&png_path));
    let mut cases = 0;
    for (args, kind) in [
        (vec!["bake", f, "-o", out], "a FIFO"),
        (vec!["bake", z, "-o", out], "a character device"),
        (vec!["bake", s(&mesh), "-o", out, "--config", f], "a FIFO"),
        (vec!["verify", f], "a FIFO"),
        (vec!["verify", z], "a character device"),
        (vec!["inspect", z], "a character device"),
        (vec!["simulate", f], "a FIFO"),
        (vec!["simulate", z], "a character device"),
        (vec!["preview", f, "-o", png], "a FIFO"),
        (vec!["batch", f], "a FIFO"),
        (vec!["export", z, "-o", out], "a character device"),
    ] {
        let o = run_within(&args, Duration::from_secs(20));
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(kind), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        cases += 1;
    }
    assert_eq!(cases, 11);
    assert!(is_fifo(&fifo));
    only(d, &["in.fifo"]);
}

#[test]
fn sparse_3_gib_scenes_configs_batch_files_and_packs_are_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let big = |name: &str| -> PathBuf {
        let p = d.join(name);
        std::fs::File::create(&p).unwrap().set_len(3 << 30).unwrap();
        p
    };
    let (scene, config, batch, pack) = (big("scene.toml"), big("bake.toml"), big("assets.toml"), big("x.fbk"));
    let mesh = real_fixture("Box.glb");
    let out = d.join("o.fbk");
    let mut cases = 0;
    for (args, want) in [
        (vec!["simulate", s(&scene)], "limit of 16 MiB"),
        (vec!["preview", s(&scene), "-o", s(&d.join("p.png"))], "limit of 16 MiB"),
        (vec!["bake", s(&mesh), "-o", s(&out), "--config", s(&config)], "limit of 16 MiB"),
        (vec!["batch", s(&batch)], "limit of 16 MiB"),
        // A pack's header is checked against the file's length before its body is read.
        (vec!["verify", s(&pack)], "x.fbk"),
    ] {
        // Bounded by the check, not by reading 3 GiB: well under the watchdog.
        let o = run_within(&args, Duration::from_secs(20));
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        cases += 1;
    }
    assert_eq!(cases, 5);
    assert!(!out.exists());
}

#[test]
fn non_finite_numbers_in_toml_settings_are_refused_by_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(real_fixture("Box.glb"), d.join("a.glb")).unwrap();
    let cfg = d.join("bake.toml");
    let mut cases = 0;
    for (text, key) in [
        ("[shells]\nfur_length_m = nan\n", "shells.fur_length_m"),
        ("[uv]\nrepeat_m = inf\n", "uv.repeat_m"),
        ("[volume.coat]\ndensity = -inf\n", "volume.coat.density"),
    ] {
        std::fs::write(&cfg, text).unwrap();
        let out = quick(&["bake", s(&d.join("a.glb")), "-o", s(&d.join("a.fbk")), "--config", s(&cfg), "-q"]);
        assert_eq!(out.status.code(), Some(2), "{text}: {}", stderr(&out));
        assert!(stderr(&out).contains(key) && stderr(&out).contains("bake.toml"), "{text}: {}", stderr(&out));
        let batch = d.join("assets.toml");
        let settings = text
            .replace("[", "[asset.settings.")
            .replace("[asset.settings.", "[[asset]]\ninput = \"a.glb\"\n[asset.settings.");
        std::fs::write(&batch, settings).unwrap();
        let out = quick(&["batch", s(&batch), "-q"]);
        assert_eq!(out.status.code(), Some(2), "{text}: {}", stderr(&out));
        assert!(stderr(&out).contains(key), "batch {text}: {}", stderr(&out));
        cases += 1;
    }
    assert_eq!(cases, 3);
    assert!(!d.join("a.fbk").exists());
}

/// Rewrites the pack at `path` with its manifest's inputs passed through `edit`.
fn plant_manifest(path: &Path, mut edit: impl FnMut(&mut Vec<furbake_formats::sections::manifest::ManifestInput>)) {
    use furbake_formats::sections::manifest::BakeManifest;
    use furbake_formats::{Pack, PackWriter, Section, SectionKind};
    let pack = Pack::read(path).unwrap();
    let mut writer = PackWriter::new();
    for (i, e) in pack.sections().iter().enumerate() {
        if e.kind == SectionKind::BAKE_MANIFEST {
            let mut m: BakeManifest = pack.decode(i).unwrap();
            edit(&mut m.inputs);
            writer.push(e.kind, e.version, m.encode());
        } else {
            writer.push(e.kind, e.version, pack.payload(i).unwrap().to_vec());
        }
    }
    writer.write_atomic(path).unwrap();
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn a_planted_manifest_cannot_make_batch_read_outside_the_asset_root_or_wait_on_a_fifo() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let assets = d.join("assets");
    copy_plane(&assets);
    let secret = d.join("secret.txt");
    std::fs::write(&secret, b"the build machine's secret").unwrap();
    let batch = assets.join("assets.toml");
    std::fs::write(&batch, "[defaults.settings]\nvolume.resolution = 8\n[[asset]]\ninput = \"TwoSidedPlane.gltf\"\n")
        .unwrap();
    let pack = assets.join("TwoSidedPlane.fbk");
    assert_ok(&quick(&["batch", s(&batch)]), "first batch");
    assert!(stderr(&quick(&["batch", s(&batch)])).contains("skipped"), "a second run is up to date");
    // The manifest now also names the secret, with its true size and hash: the old check opened
    // it, found it unchanged and said "up to date" — a yes/no oracle on any readable file.
    let secret_bytes = std::fs::read(&secret).unwrap();
    for name in ["../secret.txt", "/tmp/../secret.txt"] {
        let entry = furbake_formats::sections::manifest::ManifestInput {
            name: name.to_owned(),
            bytes: secret_bytes.len() as u64,
            sha256: sha256_hex(&secret_bytes),
        };
        plant_manifest(&pack, |inputs| inputs.push(entry.clone()));
        let out = quick(&["batch", s(&batch)]);
        assert_ok(&out, "batch over a planted manifest");
        let err = stderr(&out);
        assert!(err.contains("warning") && err.contains("not up to date") && err.contains(name), "{err}");
        assert!(err.contains("1 baked"), "rebaked, not skipped: {err}");
    }
    // A recorded input replaced by a FIFO: batch must neither wait on it nor skip the asset.
    let bin = assets.join("TwoSidedPlane.bin");
    std::fs::remove_file(&bin).unwrap();
    mkfifo(&bin);
    let out = run_within(&["batch", s(&batch)], Duration::from_secs(30));
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("a FIFO"), "{}", stderr(&out));
}

#[test]
fn tiny_time_steps_are_refused_by_preview_and_simulate_alike() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pack = d.join("box.fbk");
    assert_ok(&furbake(&["bake", s(&real_fixture("Box.glb")), "-o", s(&pack), "--resolution", "8", "-q"]), "bake");
    let scene = d.join("tiny.toml");
    std::fs::write(&scene, "time_step_s = 1e-7\n[[packs]]\nname = \"box\"\npath = \"box.fbk\"\n").unwrap();
    let png = d.join("p.png");
    // Half a second of settling is 5,000,000 steps: refused before the first one, not run.
    let out = run_within(&["preview", s(&scene), "-o", s(&png), "--size", "32x32"], Duration::from_secs(60));
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("5000001 steps, above 1000000"), "{}", stderr(&out));
    let out = run_within(&["simulate", s(&scene)], Duration::from_secs(60));
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("above 1000000"), "{}", stderr(&out));
    assert!(!png.exists());
}

#[test]
fn simulate_preview_and_export_outputs_follow_the_same_rules_and_dash_is_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pack = d.join("box.fbk");
    assert_ok(&furbake(&["bake", s(&real_fixture("Box.glb")), "-o", s(&pack), "--resolution", "8", "-q"]), "bake");
    let scene = d.join("scene.toml");
    std::fs::write(
        &scene,
        "time_step_s = 0.03125\nduration_s = 0.125\n[[packs]]\nname = \"box\"\npath = \"box.fbk\"\n",
    )
    .unwrap();
    let fifo = d.join("fifo");
    mkfifo(&fifo);
    let pack_bytes = std::fs::read(&pack).unwrap();
    let (p, sc, f) = (s(&pack), s(&scene), s(&fifo));
    let png = d.join("p.png");
    let mut cases = 0;
    for (args, want) in [
        (vec!["simulate", sc, "-o", sc], "--output"),
        (vec!["simulate", sc, "--state-out", p], "--state-out"),
        (vec!["simulate", sc, "-o", f], "a FIFO"),
        (vec!["simulate", sc, "-o", s(&png), "--state-out", s(&d.join("./p.png"))], "is the same file as"),
        (vec!["simulate", sc, "--json", "-o", "-"], "stdout"),
        (vec!["preview", p, "-o", p], "--output"),
        (vec!["preview", sc, "-o", p], "--output"),
        (vec!["preview", sc, "-o", f], "a FIFO"),
        (vec!["export", p, "-o", p], "--output"),
        (vec!["export", p, "-o", f], "a FIFO"),
        (vec!["keyframes", "-o", f], "a FIFO"),
    ] {
        let out = quick(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(stderr(&out).contains(want), "{args:?}: {}", stderr(&out));
        cases += 1;
    }
    assert_eq!(cases, 11);
    assert_eq!(std::fs::read(&pack).unwrap(), pack_bytes);
    assert!(is_fifo(&fifo));
    only(d, &["box.fbk", "fifo", "scene.toml"]);
    // `-` streams to stdout: what a pipe reads is the file the command would have written.
    let stdout_of = |args: &[&str]| -> Vec<u8> {
        let out = quick(args);
        assert_ok(&out, &format!("{args:?}"));
        out.stdout
    };
    assert!(stdout_of(&["export", p, "-o", "-", "-q"]).starts_with(b"glTF"));
    assert!(stdout_of(&["preview", p, "-o", "-", "--size", "32x32", "-q"]).starts_with(b"\x89PNG"));
    let report: serde_json::Value = serde_json::from_slice(&stdout_of(&["simulate", sc, "-o", "-", "-q"])).unwrap();
    assert_eq!(report["frames"], 4, "0.125 s in steps of 0.03125 s");
    let state: serde_json::Value =
        serde_json::from_slice(&stdout_of(&["simulate", sc, "--state-out", "-", "-q"])).unwrap();
    assert_eq!(state["packs"][0]["name"], "box");
    let streamed = stdout_of(&["bake", s(&real_fixture("Box.glb")), "-o", "-", "--resolution", "8", "-q"]);
    assert_eq!(streamed, pack_bytes, "bake -o - writes the same pack");
}

#[test]
fn a_batch_output_never_lands_on_another_assets_buffer() {
    // Found by the pipelines fuzzer: the buffers of asset 1 were checked only when asset 1 was
    // read, after asset 2 had written its pack over one of them.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    copy_plane(&d.join("a"));
    copy_plane(&d.join("b"));
    let bin = d.join("a/TwoSidedPlane.bin");
    let before = std::fs::read(&bin).unwrap();
    let batch = d.join("assets.toml");
    std::fs::write(
        &batch,
        "[defaults.settings]\nvolume.resolution = 8\n[[asset]]\ninput = \"a/TwoSidedPlane.gltf\"\n\
         [[asset]]\ninput = \"b/TwoSidedPlane.gltf\"\noutput = \"a/TwoSidedPlane.bin\"\n",
    )
    .unwrap();
    for jobs in ["1", "2"] {
        let out = quick(&["batch", s(&batch), "-j", jobs, "-q"]);
        assert_eq!(out.status.code(), Some(2), "-j {jobs}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("is the input") && stderr(&out).contains("TwoSidedPlane.bin"),
            "{}",
            stderr(&out)
        );
        assert_eq!(std::fs::read(&bin).unwrap(), before, "-j {jobs}: the buffer is untouched");
    }
}
