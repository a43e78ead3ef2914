//! `furbake bake` reads external buffers and images only from inside the asset roots (the
//! glTF's directory, plus `--asset-root DIR`), only regular files, and never hangs on one.
//!
//! Regression: the importer checked for an absolute path before percent-decoding and read the
//! joined path without canonicalising it, so `../../etc/passwd`, `%2Fetc%2Fpasswd`, `..%2F`,
//! `%2e%2e/` or a symlink beside the glTF put any file of the machine into the pack, a URI naming
//! `/dev/zero` read until memory ran out and one naming a FIFO hung the bake forever. Every case
//! here asserts exit 1, a one-line message naming the URI, and that no pack (nor temporary file)
//! was written.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use furbake_import::testmesh::{TestPrimitive, gltf_json};
use serde_json::{Value, json};

use crate::common::*;

/// Runs `furbake` and fails the test if it has not exited after `limit` (it is then killed).
fn furbake_within(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_furbake"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the furbake binary runs");
    let start = Instant::now();
    while child.try_wait().expect("waiting on furbake").is_none() {
        if start.elapsed() > limit {
            child.kill().ok();
            child.wait().ok();
            panic!("furbake {args:?} did not exit within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().expect("furbake's output")
}

/// A scratch tree: `models/m.gltf` is baked, `outside/secret.bin` lies beside `models/`.
struct Tree {
    dir: tempfile::TempDir,
}

impl Tree {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("models")).unwrap();
        std::fs::create_dir(dir.path().join("outside")).unwrap();
        std::fs::write(dir.path().join("outside/secret.bin"), [0x5au8; 64]).unwrap();
        Tree { dir }
    }

    fn models(&self) -> PathBuf {
        self.dir.path().join("models")
    }

    fn pack(&self) -> PathBuf {
        self.dir.path().join("out.fbk")
    }

    /// Bakes `doc` as `models/m.gltf` into `out.fbk` with `extra` flags.
    fn bake(&self, doc: &Value, extra: &[&str]) -> Output {
        let gltf = self.models().join("m.gltf");
        std::fs::write(&gltf, serde_json::to_vec(doc).unwrap()).unwrap();
        let pack = self.pack();
        let mut args = vec!["bake", s(&gltf), "-o", s(&pack), "--resolution", "8", "--layers", "2", "-q"];
        args.extend(extra);
        furbake_within(&args, Duration::from_secs(30))
    }

    /// Asserts a refusal: exit 1, one line naming the glTF and `uri`, no pack, no temporary file.
    fn assert_refused(&self, out: &Output, uri: &str) {
        let err = stderr(out);
        assert_eq!(out.status.code(), Some(1), "{uri}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{uri}: not one line: {err}");
        assert!(err.contains(&format!("{uri:?}")), "the message does not name the URI {uri}: {err}");
        assert!(err.contains("m.gltf"), "the message does not name the glTF: {err}");
        assert!(!self.pack().exists(), "{uri}: a refused bake wrote a pack");
        let leftovers: Vec<String> = std::fs::read_dir(self.dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect();
        assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    }
}

fn triangle() -> TestPrimitive {
    let mut p = TestPrimitive::triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![0, 1, 2]);
    p.texcoords = Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    p.material = Some("fur".to_owned());
    p
}

/// A triangle that also lists an external buffer (every buffer is loaded, used or not).
fn with_buffer(uri: &str, byte_length: usize) -> Value {
    let mut doc: Value = serde_json::from_slice(&gltf_json(&[triangle()], None)).unwrap();
    doc["buffers"].as_array_mut().unwrap().push(json!({ "byteLength": byte_length, "uri": uri }));
    doc
}

/// A triangle whose base colour texture is the image at `uri`.
fn with_image(uri: &str) -> Value {
    let mut doc: Value = serde_json::from_slice(&gltf_json(&[triangle()], None)).unwrap();
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    doc["textures"] = json!([{ "source": 0 }]);
    doc["images"] = json!([{ "uri": uri }]);
    doc
}

fn write_png(path: &Path) {
    image::RgbaImage::from_pixel(2, 2, image::Rgba([200, 90, 20, 255])).save(path).unwrap();
}

#[test]
fn every_encoding_of_an_escape_exits_1_naming_the_uri_for_buffers_and_images() {
    let tree = Tree::new();
    write_png(&tree.dir.path().join("outside/secret.png"));
    let uris = [
        "../../../../../../../../etc/passwd",
        "%2Fetc%2Fpasswd",
        "..%2F..%2F..%2F..%2F..%2F..%2F..%2F..%2Fetc%2Fpasswd",
        "%2e%2e/outside/secret.bin",
        "%2E%2E%5Coutside%5Csecret.bin",
        "/etc/passwd",
        "file:///etc/passwd",
        "../outside/secret.bin",
    ];
    let mut checked = 0;
    for uri in uris {
        tree.assert_refused(&tree.bake(&with_buffer(uri, 64), &[]), uri);
        let image_uri = uri.replace("secret.bin", "secret.png");
        tree.assert_refused(&tree.bake(&with_image(&image_uri), &[]), &image_uri);
        checked += 2;
    }
    assert_eq!(checked, 16);
}

#[test]
fn a_directory_and_a_short_buffer_file_exit_1() {
    let tree = Tree::new();
    std::fs::create_dir(tree.models().join("dir.bin")).unwrap();
    std::fs::write(tree.models().join("short.bin"), [1u8; 10]).unwrap();
    let out = tree.bake(&with_buffer("dir.bin", 4), &[]);
    tree.assert_refused(&out, "dir.bin");
    assert!(stderr(&out).contains("is a directory, not a regular file"), "{}", stderr(&out));
    tree.assert_refused(&tree.bake(&with_image("dir.bin"), &[]), "dir.bin");
    let out = tree.bake(&with_buffer("short.bin", 64), &[]);
    tree.assert_refused(&out, "short.bin");
    assert!(stderr(&out).contains("holds 10 bytes but the buffer declares byteLength 64"), "{}", stderr(&out));
}

/// A missing texture is a warning and a pack without it — unless `--strict-inputs` asks for
/// every named file (build systems): then exit 1 naming the file, and no pack. A texture that is
/// there bakes the same pack with and without the flag.
#[test]
fn strict_inputs_makes_a_missing_texture_an_error_and_changes_no_pack() {
    let tree = Tree::new();
    let doc = with_image("fur.png");
    let lenient = tree.bake(&doc, &[]);
    assert_ok(&lenient, "bake with a missing texture");
    std::fs::remove_file(tree.pack()).unwrap();
    let strict = tree.bake(&doc, &["--strict-inputs"]);
    tree.assert_refused(&strict, "fur.png");
    write_png(&tree.models().join("fur.png"));
    assert_ok(&tree.bake(&doc, &[]), "bake with the texture");
    let plain = std::fs::read(tree.pack()).unwrap();
    assert_ok(&tree.bake(&doc, &["--strict-inputs"]), "strict bake with the texture");
    assert!(std::fs::read(tree.pack()).unwrap() == plain, "--strict-inputs changed the pack");
}

#[test]
fn asset_root_reads_a_texture_from_a_sibling_shared_folder() {
    let tree = Tree::new();
    let shared = tree.dir.path().join("textures");
    std::fs::create_dir(&shared).unwrap();
    write_png(&shared.join("fur.png"));
    let doc = with_image("../textures/fur.png");
    tree.assert_refused(&tree.bake(&doc, &[]), "../textures/fur.png");
    let root = tree.dir.path().to_str().unwrap().to_owned();
    assert_ok(&tree.bake(&doc, &["--asset-root", &root]), "bake with --asset-root");
    assert!(tree.pack().exists());
    std::fs::remove_file(tree.pack()).unwrap();
    // Still confined: the project folder is the limit.
    let escape = "../../elsewhere.bin";
    tree.assert_refused(&tree.bake(&with_buffer(escape, 4), &["--asset-root", &root]), escape);
    // A root that is not an existing directory is a usage error, found before the input is read.
    for bad in [format!("{root}/missing"), format!("{root}/outside/secret.bin")] {
        let out = tree.bake(&doc, &["--asset-root", &bad]);
        assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
        assert!(stderr(&out).contains("--asset-root"), "{}", stderr(&out));
        assert!(!tree.pack().exists());
    }
}

#[cfg(unix)]
#[test]
fn symlinks_dev_zero_and_fifos_beside_the_gltf() {
    use std::os::unix::fs::symlink;
    let tree = Tree::new();
    symlink(tree.dir.path().join("outside/secret.bin"), tree.models().join("evil.bin")).unwrap();
    let out = tree.bake(&with_buffer("evil.bin", 64), &[]);
    tree.assert_refused(&out, "evil.bin");
    assert!(stderr(&out).contains("outside the asset root"), "{}", stderr(&out));
    symlink("/dev/zero", tree.models().join("zero.bin")).unwrap();
    tree.assert_refused(&tree.bake(&with_buffer("zero.bin", 1 << 20), &[]), "zero.bin");
    tree.assert_refused(&tree.bake(&with_image("zero.bin"), &[]), "zero.bin");
    // Nobody writes to the FIFO: a blocking open would hang (`bake` is given 30 s in all).
    let status = Command::new("mkfifo").arg(tree.models().join("pipe.bin")).status().expect("mkfifo runs");
    assert!(status.success());
    let out = tree.bake(&with_buffer("pipe.bin", 4), &[]);
    tree.assert_refused(&out, "pipe.bin");
    assert!(stderr(&out).contains("is a FIFO"), "{}", stderr(&out));
    tree.assert_refused(&tree.bake(&with_image("pipe.bin"), &[]), "pipe.bin");
    // A symlink inside the root to a file inside the root is fine.
    std::fs::write(tree.models().join("real.bin"), [3u8; 64]).unwrap();
    symlink("real.bin", tree.models().join("alias.bin")).unwrap();
    assert_ok(&tree.bake(&with_buffer("alias.bin", 64), &[]), "bake through an inside symlink");
    assert!(tree.pack().exists());
}
