//! Bake farms under a real Bazel (Debian's `bazel-bootstrap`; `make deps` installs it): a test
//! workspace loads `bazel/furbake.bzl` and bakes bundled fixtures — a glTF with external buffers
//! and textures among them — with `--spawn_strategy=sandboxed`; the packs are byte-identical to
//! `furbake bake` of the same inputs; an action that leaves its textures undeclared fails naming
//! the texture (the rules bake with `--strict-inputs`); changing one texture rebakes one pack;
//! and a second, clean workspace pointed at the same remote cache (Bazel's HTTP cache protocol
//! served by a real nginx with WebDAV on the loopback address, started and stopped here) gets
//! every pack from the cache without running furbake.

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

use super::common::*;

/// Copies what a user's workspace would hold: the rules, the furbake binary as a prebuilt tool,
/// three models (one with an external buffer and three textures) and a BUILD file baking them.
fn workspace(dir: &Path) {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    std::fs::create_dir_all(dir.join("bazel")).unwrap();
    std::fs::copy(repo.join("bazel/furbake.bzl"), dir.join("bazel/furbake.bzl")).unwrap();
    std::fs::write(dir.join("bazel/BUILD"), "").unwrap();
    std::fs::create_dir_all(dir.join("tools")).unwrap();
    std::fs::copy(env!("CARGO_BIN_EXE_furbake"), dir.join("tools/furbake")).unwrap();
    std::fs::write(dir.join("tools/BUILD"), "exports_files([\"furbake\"])\n").unwrap();
    let models = dir.join("models");
    std::fs::create_dir_all(models.join("TwoSidedPlane")).unwrap();
    for name in ["Box.glb", "Fox.glb"] {
        std::fs::copy(real_fixture(name), models.join(name)).unwrap();
    }
    for e in std::fs::read_dir(real_fixture("TwoSidedPlane")).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, models.join("TwoSidedPlane").join(p.file_name().unwrap())).unwrap();
    }
    std::fs::write(dir.join("WORKSPACE"), "workspace(name = \"bake_test\")\n").unwrap();
    std::fs::write(
        models.join("BUILD"),
        r#"load("//bazel:furbake.bzl", "furbake_pack", "furbake_packs")

furbake_packs(
    name = "packs",
    srcs = ["Box.glb", "Fox.glb"],
    furbake = "//tools:furbake",
    topologies = ["prisms"],
    settings = {"volume.resolution": "16", "volume.layers": "4"},
)

furbake_pack(
    name = "plane",
    src = "TwoSidedPlane/TwoSidedPlane.gltf",
    srcs = glob(["TwoSidedPlane/*"], exclude = ["TwoSidedPlane/*.gltf"]),
    furbake = "//tools:furbake",
    settings = {"volume.resolution": "16", "volume.layers": "4"},
)

# The same asset with its textures left undeclared: the sandbox has no such files.
furbake_pack(
    name = "plane_undeclared",
    src = "TwoSidedPlane/TwoSidedPlane.gltf",
    srcs = ["TwoSidedPlane/TwoSidedPlane.bin"],
    furbake = "//tools:furbake",
)
"#,
    )
    .unwrap();
}

/// `bazel build` of every pack in `dir`, sandboxed, one-shot (`--batch`: no server left behind),
/// with its output root under `root`, plus `extra` flags; fails the test unless it succeeded.
fn bazel_build(dir: &Path, root: &Path, extra: &[&str]) -> Output {
    let out = Command::new("bazel")
        .current_dir(dir)
        .arg("--batch")
        .arg(format!("--output_user_root={}", root.display()))
        .args(["build", "//models:packs", "//models:plane", "--spawn_strategy=sandboxed", "--color=no", "--curses=no"])
        .args(extra)
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run bazel ({e}): install it with `make deps` (Debian package bazel-bootstrap)")
        });
    assert!(out.status.success(), "bazel build failed: {}{}", stdout(&out), stderr(&out));
    out
}

/// From Bazel's summary line (`INFO: 4 processes: 3 remote cache hit, 1 internal.`), how many
/// processes ran with `kind` (`linux-sandbox`, `remote cache hit`, `processwrapper-sandbox`, …).
fn processes(out: &Output, kind: &str) -> usize {
    let err = stderr(out);
    let line = err
        .lines()
        .rev()
        .find(|l| l.starts_with("INFO:") && (l.contains(" processes:") || l.contains(" process:")))
        .unwrap_or_else(|| panic!("no process summary in {err}"));
    line.split([':', ','])
        .filter_map(|part| part.trim().trim_end_matches('.').strip_suffix(kind)?.trim().parse::<usize>().ok())
        .sum()
}

/// Bake actions that ran a process on this machine (sandboxed, whichever sandbox Bazel chose).
fn local_bakes(out: &Output) -> usize {
    processes(out, "linux-sandbox") + processes(out, "processwrapper-sandbox")
}

/// A real nginx serving a WebDAV folder on the loopback address (what a team's HTTP cache is:
/// GET and PUT of `/ac/…` and `/cas/…`), one process (`master_process off`: nothing is left
/// running once it is killed), stopped when dropped.
struct CacheServer {
    child: Child,
    url: String,
}

impl CacheServer {
    fn start(dir: &Path) -> CacheServer {
        let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let store = dir.join("store");
        std::fs::create_dir_all(&store).unwrap();
        std::fs::create_dir_all(dir.join("logs")).unwrap();
        // nginx's workers may run as another user: the store must be theirs to write.
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&store, std::fs::Permissions::from_mode(0o777)).unwrap();
        let conf = dir.join("nginx.conf");
        std::fs::write(
            &conf,
            format!(
                "daemon off;\nmaster_process off;\npid {d}/nginx.pid;\nerror_log {d}/logs/error.log;\nevents {{}}\nhttp {{\n\
                 access_log off;\nclient_body_temp_path {d}/body;\nproxy_temp_path {d}/proxy;\n\
                 fastcgi_temp_path {d}/fastcgi;\nuwsgi_temp_path {d}/uwsgi;\nscgi_temp_path {d}/scgi;\n\
                 server {{\nlisten 127.0.0.1:{port};\nroot {store};\nclient_max_body_size 0;\n\
                 location / {{ dav_methods PUT; create_full_put_path on; dav_access user:rw group:rw all:rw; }}\n}}\n}}\n",
                d = dir.display(),
                store = store.display()
            ),
        )
        .unwrap();
        let mut child = Command::new("nginx")
            .arg("-c")
            .arg(&conf)
            .arg("-p")
            .arg(dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| {
                panic!("cannot run nginx ({e}): install it with `make deps` (Debian package nginx-light)")
            });
        let url = format!("http://127.0.0.1:{port}");
        let addr = format!("127.0.0.1:{port}");
        for _ in 0..100 {
            if std::net::TcpStream::connect(&addr).is_ok() {
                return CacheServer { child, url };
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        let _ = child.kill();
        let _ = child.wait();
        panic!(
            "nginx did not listen on {addr}: {}",
            std::fs::read_to_string(dir.join("logs/error.log")).unwrap_or_default()
        );
    }
}

impl Drop for CacheServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn pack(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join("bazel-bin/models").join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn bazel_bakes_sandboxed_packs_rebakes_one_texture_and_shares_them_through_a_remote_cache() {
    let tmp = tempfile::tempdir().unwrap();
    let (first, root) = (tmp.path().join("first"), tmp.path().join("root"));
    workspace(&first);
    let cache = CacheServer::start(&tmp.path().join("cache"));
    let remote = format!("--remote_cache={}", cache.url);

    // Sandboxed: each action sees its declared inputs only, and bakes what `furbake bake` bakes.
    let built = bazel_build(&first, &root, &[&remote]);
    assert_eq!(local_bakes(&built), 3, "{}", stderr(&built));
    let direct = tmp.path().join("direct");
    std::fs::create_dir_all(&direct).unwrap();
    let settings = ["--quiet", "--set", "volume.layers=4", "--set", "volume.resolution=16"];
    for (model, name, topology) in [
        ("Box.glb", "Box.fbk", true),
        ("Fox.glb", "Fox.fbk", true),
        ("TwoSidedPlane/TwoSidedPlane.gltf", "plane.fbk", false),
    ] {
        let out = direct.join(name);
        let src = first.join("models").join(model);
        let mut args = vec!["bake", s(&src), "-o", s(&out), "--preset", "fur"];
        if topology {
            args.extend(["--topology", "prisms"]);
        }
        args.extend(settings);
        assert_ok(&furbake(&args), "furbake bake");
        assert!(pack(&first, name) == std::fs::read(&out).unwrap(), "{name}: Bazel's pack differs from furbake bake's");
    }

    // An action that reads a file it did not declare fails in the sandbox.
    let undeclared = Command::new("bazel")
        .current_dir(&first)
        .arg("--batch")
        .arg(format!("--output_user_root={}", root.display()))
        .args(["build", "//models:plane_undeclared", "--spawn_strategy=sandboxed", "--color=no", "--curses=no"])
        .output()
        .unwrap();
    assert!(!undeclared.status.success(), "an undeclared buffer was read: {}", stderr(&undeclared));
    assert!(stderr(&undeclared).contains("\"TwoSidedPlane_BaseColor.png\""), "{}", stderr(&undeclared));

    // Nothing changed: nothing runs. One texture changed: only its pack is baked again.
    let again = bazel_build(&first, &root, &[&remote]);
    assert_eq!(local_bakes(&again), 0, "{}", stderr(&again));
    let texture = first.join("models/TwoSidedPlane/TwoSidedPlane_BaseColor.png");
    let mut img = image::open(&texture).unwrap().to_rgba8();
    img.pixels_mut().for_each(|p| p.0[0] = 255 - p.0[0]);
    img.save(&texture).unwrap();
    let before = (pack(&first, "Box.fbk"), pack(&first, "plane.fbk"));
    let touched = bazel_build(&first, &root, &[&remote]);
    assert_eq!(local_bakes(&touched), 1, "{}", stderr(&touched));
    assert!(pack(&first, "Box.fbk") == before.0 && pack(&first, "plane.fbk") != before.1);

    // A clean workspace elsewhere, with its own output root, on the same cache: every pack comes
    // from the cache, furbake never runs, and the packs are the same bytes.
    let (second, root2) = (tmp.path().join("second"), tmp.path().join("root2"));
    workspace(&second);
    std::fs::copy(&texture, second.join("models/TwoSidedPlane/TwoSidedPlane_BaseColor.png")).unwrap();
    let cached = bazel_build(&second, &root2, &[&remote]);
    assert_eq!(local_bakes(&cached), 0, "{}", stderr(&cached));
    assert_eq!(processes(&cached, "remote cache hit"), 3, "{}", stderr(&cached));
    for name in ["Box.fbk", "Fox.fbk", "plane.fbk"] {
        assert!(pack(&first, name) == pack(&second, name), "{name} differs between the workspaces");
    }
    drop(cache);
    let _ = std::fs::remove_dir_all(PathBuf::from(&root));
}
