//! Confined file access (docs/design.md "Import"): buffer and image URIs may name files only
//! inside the asset roots (the glTF's directory, or also `--asset-root`), only regular files, and
//! only as many bytes as are needed.
//!
//! Regression: the importer checked for an absolute path *before* percent-decoding, joined the
//! decoded URI with the glTF's directory without canonicalising it and read whatever was there
//! with `std::fs::read`, so `../../etc/passwd`, `%2Fetc%2Fpasswd`, `..%2F`, `%2e%2e/` or a
//! symlink beside the glTF read any file of the machine into the pack (e.g. as vertex colours),
//! `/dev/zero` read until memory ran out and a FIFO hung the import forever.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use crate::common::{document, document_of, triangle};
use furbake_import::testmesh::TestPrimitive;
use furbake_import::{
    ExternalRef, ImportError, ImportSettings, ImportedMesh, UriProblem, import_gltf, import_gltf_with_asset_root,
};
use serde_json::{Value, json};

/// A secret outside the glTF's directory that no URI may read.
const SECRET: &[u8] = b"secret bytes that must never reach a pack, 64 bytes long........";

/// A scratch tree: `models/` holds the glTF, `outside/secret.bin` lies beside it.
struct Tree {
    dir: tempfile::TempDir,
}

impl Tree {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("models")).unwrap();
        std::fs::create_dir(dir.path().join("outside")).unwrap();
        std::fs::write(dir.path().join("outside/secret.bin"), SECRET).unwrap();
        Tree { dir }
    }

    fn models(&self) -> PathBuf {
        self.dir.path().join("models")
    }

    fn write_gltf(&self, doc: &Value) -> PathBuf {
        let path = self.models().join("m.gltf");
        std::fs::write(&path, serde_json::to_vec(doc).unwrap()).unwrap();
        path
    }
}

/// A triangle whose document also lists a second, external buffer (`byteLength` bytes at `uri`).
/// Every buffer is loaded, so the external one is read (and hashed) although no accessor uses it.
fn with_external_buffer(uri: &str, byte_length: usize) -> Value {
    let (p, i) = triangle();
    let mut doc = document(p, i);
    doc["buffers"].as_array_mut().unwrap().push(json!({ "byteLength": byte_length, "uri": uri }));
    doc
}

/// A textured triangle whose base colour image is the file at `uri`.
fn with_external_image(uri: &str) -> Value {
    let (p, i) = triangle();
    let mut prim = TestPrimitive::triangles(p, i);
    prim.texcoords = Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    prim.material = Some("fur".to_owned());
    let mut doc = document_of(&[prim]);
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    doc["textures"] = json!([{ "source": 0 }]);
    doc["images"] = json!([{ "uri": uri }]);
    doc
}

/// A 2×2 red PNG.
fn write_png(path: &Path) {
    image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 0, 0, 255])).save(path).unwrap();
}

/// The problem of an [`ImportError::ExternalFile`], after checking it names `referrer` and `uri`
/// (in the error and in its message, with the glTF file).
fn refusal(result: Result<ImportedMesh, ImportError>, referrer: ExternalRef, uri: &str) -> UriProblem {
    let err = match result {
        Ok(_) => panic!("{referrer} uri {uri:?} was read"),
        Err(e) => e,
    };
    let message = err.to_string();
    assert!(message.contains(&format!("{uri:?}")), "the message does not name the URI: {message}");
    assert!(message.contains("m.gltf"), "the message does not name the glTF: {message}");
    assert!(message.contains(&referrer.to_string()), "the message does not name {referrer}: {message}");
    match err {
        ImportError::ExternalFile { referrer: r, uri: u, problem, .. } => {
            assert_eq!((r, &*u), (referrer, uri));
            *problem
        }
        other => panic!("expected ExternalFile, got {other}"),
    }
}

fn kind(problem: &UriProblem) -> &'static str {
    match problem {
        UriProblem::InvalidEscape { .. } => "escape",
        UriProblem::NulByte => "nul",
        UriProblem::Scheme { .. } => "scheme",
        UriProblem::Absolute { .. } => "absolute",
        UriProblem::Backslash { .. } => "backslash",
        UriProblem::OutsideRoot { .. } => "outside",
        UriProblem::NotRegularFile { .. } => "irregular",
        UriProblem::ShorterThanDeclared { .. } => "short",
        UriProblem::TooLarge { .. } => "large",
        other => panic!("unexpected problem {other}"),
    }
}

/// Every encoding of an escape, for buffers and images: `(uri, expected problem)`.
const ESCAPES: [(&str, &str); 13] = [
    ("../../../../../../../../etc/passwd", "outside"),
    ("../outside/secret.bin", "outside"),
    ("%2Fetc%2Fpasswd", "absolute"),
    ("..%2F..%2F..%2F..%2F..%2F..%2F..%2F..%2Fetc%2Fpasswd", "outside"),
    ("..%2Foutside%2Fsecret.bin", "outside"),
    ("%2e%2e/outside/secret.bin", "outside"),
    ("%2E%2E%5Coutside%5Csecret.bin", "backslash"),
    ("/etc/passwd", "absolute"),
    ("file:///etc/passwd", "scheme"),
    ("file%3A%2F%2F%2Fetc%2Fpasswd", "scheme"),
    ("C:%2FWindows%2Fwin.ini", "absolute"),
    ("secret%00.bin", "nul"),
    ("secret%2.bin", "escape"),
];

#[test]
fn every_encoding_of_an_escape_is_refused_for_buffers() {
    let tree = Tree::new();
    let mut checked = 0;
    for (uri, want) in ESCAPES {
        let gltf = tree.write_gltf(&with_external_buffer(uri, SECRET.len()));
        let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), ExternalRef::Buffer(1), uri);
        assert_eq!(kind(&problem), want, "{uri}: {problem}");
        checked += 1;
    }
    assert_eq!(checked, ESCAPES.len());
}

#[test]
fn every_encoding_of_an_escape_is_refused_for_images() {
    // Images were only ever warnings ("not used"), but a readable secret decoded as an image
    // still became vertex colours; a refusal is now an error like a buffer's.
    let tree = Tree::new();
    write_png(&tree.dir.path().join("outside/secret.png"));
    let mut checked = 0;
    let image_escapes = ESCAPES.iter().copied().chain([("%2e%2e/outside/secret.png", "outside")]);
    for (uri, want) in image_escapes {
        let gltf = tree.write_gltf(&with_external_image(uri));
        let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), ExternalRef::Image(0), uri);
        assert_eq!(kind(&problem), want, "{uri}: {problem}");
        checked += 1;
    }
    assert_eq!(checked, ESCAPES.len() + 1);
}

#[test]
fn a_buffer_file_inside_the_root_is_read_up_to_its_byte_length_and_hashed() {
    let tree = Tree::new();
    std::fs::create_dir(tree.models().join("sub")).unwrap();
    // 100 bytes on disk, 64 declared: the spec allows a longer file; only 64 bytes are read.
    std::fs::write(tree.models().join("sub/extra data.bin"), [7u8; 100]).unwrap();
    let gltf = tree.write_gltf(&with_external_buffer("./sub/../sub/extra%20data.bin", 64));
    let mesh = import_gltf(&gltf, &ImportSettings::default()).unwrap();
    let main_len = std::fs::metadata(&gltf).unwrap().len();
    assert_eq!(mesh.input_bytes, main_len + 64);
}

#[test]
fn a_buffer_file_shorter_than_its_byte_length_is_refused() {
    let tree = Tree::new();
    std::fs::write(tree.models().join("short.bin"), [1u8; 10]).unwrap();
    let gltf = tree.write_gltf(&with_external_buffer("short.bin", 64));
    let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), ExternalRef::Buffer(1), "short.bin");
    assert!(matches!(problem, UriProblem::ShorterThanDeclared { len: 10, declared: 64, .. }), "{problem}");
    assert!(problem.to_string().contains("holds 10 bytes but the buffer declares byteLength 64"), "{problem}");
}

#[test]
fn a_directory_named_as_a_uri_is_refused() {
    let tree = Tree::new();
    std::fs::create_dir(tree.models().join("dir.bin")).unwrap();
    let mut checked = 0;
    for (doc, referrer) in [
        (with_external_buffer("dir.bin", 4), ExternalRef::Buffer(1)),
        (with_external_image("dir.bin"), ExternalRef::Image(0)),
    ] {
        let gltf = tree.write_gltf(&doc);
        let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), referrer, "dir.bin");
        assert!(matches!(problem, UriProblem::NotRegularFile { kind: "a directory", .. }), "{problem}");
        checked += 1;
    }
    assert_eq!(checked, 2);
}

#[test]
fn an_image_larger_than_the_limit_is_refused_before_it_is_read() {
    let tree = Tree::new();
    // A sparse file: 3 GiB long, no disk used; reading it would take 3 GiB of memory.
    let big = std::fs::File::create(tree.models().join("huge.png")).unwrap();
    big.set_len(3 << 30).unwrap();
    let gltf = tree.write_gltf(&with_external_image("huge.png"));
    let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), ExternalRef::Image(0), "huge.png");
    assert!(matches!(problem, UriProblem::TooLarge { len, .. } if len == 3 << 30), "{problem}");
}

#[test]
fn a_missing_image_stays_a_warning_and_an_image_inside_the_root_colours_the_fur() {
    let tree = Tree::new();
    let gltf = tree.write_gltf(&with_external_image("missing.png"));
    let mesh = import_gltf(&gltf, &ImportSettings::default()).unwrap();
    assert!(mesh.warnings.iter().any(|w| w.contains("missing.png")), "{:?}", mesh.warnings);
    write_png(&tree.models().join("red.png"));
    let gltf = tree.write_gltf(&with_external_image("red.png"));
    let mesh = import_gltf(&gltf, &ImportSettings::default()).unwrap();
    assert!(mesh.mesh.colors.iter().all(|c| c[0] > 0.9 && c[1] < 0.1), "{:?}", mesh.mesh.colors);
}

#[test]
fn the_asset_root_widens_the_confinement_to_a_shared_folder() {
    // project/models/m.gltf uses ../textures/fur.png: refused by default, read with the project
    // folder as asset root; escaping the project folder stays refused.
    let tree = Tree::new();
    let shared = tree.dir.path().join("textures");
    std::fs::create_dir(&shared).unwrap();
    write_png(&shared.join("fur.png"));
    let uri = "../textures/fur.png";
    let gltf = tree.write_gltf(&with_external_image(uri));
    let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), ExternalRef::Image(0), uri);
    assert_eq!(kind(&problem), "outside");
    let root = tree.dir.path();
    let mesh = import_gltf_with_asset_root(&gltf, root, &ImportSettings::default()).unwrap();
    assert!(mesh.mesh.colors.iter().all(|c| c[0] > 0.9 && c[1] < 0.1), "the shared texture was sampled");
    // Lexically outside the project folder (refused whether or not the file exists).
    let escape = "../../secret.bin";
    let gltf = tree.write_gltf(&with_external_buffer(escape, SECRET.len()));
    let problem =
        refusal(import_gltf_with_asset_root(&gltf, root, &ImportSettings::default()), ExternalRef::Buffer(1), escape);
    assert_eq!(kind(&problem), "outside");
    // The asset root must be an existing directory.
    for bad in [root.join("nope"), root.join("outside/secret.bin")] {
        let err = import_gltf_with_asset_root(&gltf, &bad, &ImportSettings::default()).unwrap_err();
        assert!(matches!(err, ImportError::AssetRoot { .. }), "{err}");
    }
}

#[cfg(unix)]
mod unix {
    use std::os::unix::fs::symlink;

    use super::*;

    #[test]
    fn a_symlink_pointing_outside_is_refused_and_one_pointing_inside_is_read() {
        let tree = Tree::new();
        symlink(tree.dir.path().join("outside/secret.bin"), tree.models().join("evil.bin")).unwrap();
        symlink("../outside/secret.bin", tree.models().join("evil-relative.bin")).unwrap();
        let mut checked = 0;
        for uri in ["evil.bin", "evil-relative.bin"] {
            let gltf = tree.write_gltf(&with_external_buffer(uri, SECRET.len()));
            let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), ExternalRef::Buffer(1), uri);
            assert!(
                matches!(&problem, UriProblem::OutsideRoot { resolved, .. } if resolved.ends_with("outside/secret.bin")),
                "{problem}"
            );
            checked += 1;
        }
        write_png(&tree.dir.path().join("outside/secret.png"));
        symlink(tree.dir.path().join("outside/secret.png"), tree.models().join("evil.png")).unwrap();
        let gltf = tree.write_gltf(&with_external_image("evil.png"));
        let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), ExternalRef::Image(0), "evil.png");
        assert_eq!(kind(&problem), "outside");
        // Inside the root, through a symlinked directory and a symlinked file: read.
        std::fs::create_dir(tree.models().join("real")).unwrap();
        std::fs::write(tree.models().join("real/data.bin"), SECRET).unwrap();
        symlink("real", tree.models().join("alias")).unwrap();
        symlink("alias/data.bin", tree.models().join("good.bin")).unwrap();
        for uri in ["good.bin", "alias/data.bin"] {
            let gltf = tree.write_gltf(&with_external_buffer(uri, SECRET.len()));
            let mesh = import_gltf(&gltf, &ImportSettings::default()).unwrap();
            assert_eq!(mesh.input_bytes, std::fs::metadata(&gltf).unwrap().len() + SECRET.len() as u64);
            checked += 1;
        }
        assert_eq!(checked, 4);
    }

    /// A build sandbox (Bazel's `linux-sandbox`) links every declared input into a directory of
    /// its own: a glTF reached through a symlink also reads the files beside the glTF it really
    /// is, and still nothing else — not a symlink beside either of them that points elsewhere.
    #[test]
    fn a_symlinked_gltf_reads_the_files_beside_the_real_one_and_nothing_else() {
        let tree = Tree::new();
        std::fs::write(tree.models().join("data.bin"), SECRET).unwrap();
        let real = tree.write_gltf(&with_external_buffer("data.bin", SECRET.len()));
        let sandbox = tree.dir.path().join("sandbox");
        std::fs::create_dir(&sandbox).unwrap();
        symlink(&real, sandbox.join("m.gltf")).unwrap();
        symlink(tree.models().join("data.bin"), sandbox.join("data.bin")).unwrap();
        let mesh = import_gltf(&sandbox.join("m.gltf"), &ImportSettings::default()).unwrap();
        assert_eq!(mesh.input_bytes, std::fs::metadata(&real).unwrap().len() + SECRET.len() as u64);
        // The same glTF copied (not linked) into the sandbox: its buffer's link points outside.
        std::fs::remove_file(sandbox.join("m.gltf")).unwrap();
        std::fs::copy(&real, sandbox.join("m.gltf")).unwrap();
        let problem = refusal(
            import_gltf(&sandbox.join("m.gltf"), &ImportSettings::default()),
            ExternalRef::Buffer(1),
            "data.bin",
        );
        assert_eq!(kind(&problem), "outside");
        // A linked glTF whose buffer's link leaves both directories: refused.
        std::fs::remove_file(sandbox.join("m.gltf")).unwrap();
        symlink(&real, sandbox.join("m.gltf")).unwrap();
        std::fs::remove_file(sandbox.join("data.bin")).unwrap();
        symlink(tree.dir.path().join("outside/secret.bin"), sandbox.join("data.bin")).unwrap();
        let problem = refusal(
            import_gltf(&sandbox.join("m.gltf"), &ImportSettings::default()),
            ExternalRef::Buffer(1),
            "data.bin",
        );
        assert!(
            matches!(&problem, UriProblem::OutsideRoot { resolved, .. } if resolved.ends_with("outside/secret.bin")),
            "{problem}"
        );
    }

    #[test]
    fn dev_zero_through_a_symlink_is_refused_even_inside_a_root() {
        let tree = Tree::new();
        symlink("/dev/zero", tree.models().join("zero.bin")).unwrap();
        let gltf = tree.write_gltf(&with_external_buffer("zero.bin", 1024));
        // Outside the glTF's directory: refused before it is opened.
        let problem = refusal(import_gltf(&gltf, &ImportSettings::default()), ExternalRef::Buffer(1), "zero.bin");
        assert!(matches!(&problem, UriProblem::OutsideRoot { resolved, .. } if resolved == Path::new("/dev/zero")));
        // With /dev as asset root it is inside, and refused as a device.
        let result = import_gltf_with_asset_root(&gltf, Path::new("/dev"), &ImportSettings::default());
        let problem = refusal(result, ExternalRef::Buffer(1), "zero.bin");
        assert!(matches!(problem, UriProblem::NotRegularFile { kind: "a character device", .. }), "{problem}");
    }

    #[test]
    fn a_fifo_is_refused_promptly() {
        let tree = Tree::new();
        let fifo = tree.models().join("pipe.bin");
        let c_path = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: `c_path` is a valid NUL-terminated path; mkfifo only creates a directory entry.
        assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0, "mkfifo failed");
        let mut checked = 0;
        for (doc, referrer) in [
            (with_external_buffer("pipe.bin", 4), ExternalRef::Buffer(1)),
            (with_external_image("pipe.bin"), ExternalRef::Image(0)),
        ] {
            let gltf = tree.write_gltf(&doc);
            let (send, receive) = mpsc::channel();
            // Nobody ever writes to the FIFO: a blocking open would wait forever.
            std::thread::spawn(move || send.send(import_gltf(&gltf, &ImportSettings::default())).ok());
            let result = receive.recv_timeout(Duration::from_secs(10)).expect("the import returned within 10 s");
            let problem = refusal(result, referrer, "pipe.bin");
            assert!(matches!(problem, UriProblem::NotRegularFile { kind: "a FIFO", .. }), "{problem}");
            checked += 1;
        }
        assert_eq!(checked, 2);
    }
}
