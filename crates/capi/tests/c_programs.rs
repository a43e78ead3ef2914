//! C programs built with the system C compiler against the static library and the checked-in
//! header, with warnings as errors and the address and undefined-behaviour sanitizers, run on
//! the shared test packs.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{packs, root};

/// The directory cargo built this test binary's dependencies in, which holds the crate's
/// `libfurbake_capi.a` (cargo builds every crate type of a library it tests).
fn library_dir() -> PathBuf {
    std::env::current_exe().unwrap().parent().unwrap().to_path_buf()
}

/// The C compiler: `$CC`, else `cc`.
fn compiler() -> String {
    std::env::var("CC").unwrap_or_else(|_| "cc".into())
}

/// Installs the header, one of the libraries (`libfurbake_capi.a` or `.so`) and `furbake.pc`
/// (from `furbake.pc.in`, as `make capi` fills it) under `prefix`, as a package would.
pub fn install(prefix: &Path, library: &str) {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    for sub in ["include", "lib/pkgconfig"] {
        std::fs::create_dir_all(prefix.join(sub)).unwrap();
    }
    std::fs::copy(crate_dir.join("include/furbake.h"), prefix.join("include/furbake.h")).unwrap();
    let built = library_dir().join(library);
    assert!(built.is_file(), "{} is missing", built.display());
    std::fs::copy(&built, prefix.join("lib").join(library)).unwrap();
    let template = std::fs::read_to_string(crate_dir.join("furbake.pc.in")).unwrap();
    let pc = template.replace("@PREFIX@", prefix.to_str().unwrap()).replace("@VERSION@", env!("CARGO_PKG_VERSION"));
    std::fs::write(prefix.join("lib/pkgconfig/furbake.pc"), pc).unwrap();
}

/// `pkg-config ARGS furbake` against the package installed under `prefix`, split into words.
fn pkg_config(prefix: &Path, args: &[&str]) -> Vec<String> {
    let output = Command::new("pkg-config")
        .args(args)
        .arg("furbake")
        .env("PKG_CONFIG_PATH", prefix.join("lib/pkgconfig"))
        .output()
        .expect("pkg-config is installed");
    assert!(output.status.success(), "pkg-config {args:?}: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).unwrap().split_whitespace().map(String::from).collect()
}

/// Compiles `source` (under tests/c) into `exe` with the flags pkg-config gives for the package
/// under `prefix` (`--static` for the static library).
fn build(source: &str, prefix: &Path, link_static: bool, exe: &Path) {
    build_with(source, prefix, link_static, exe, &[]);
}

/// [`build`] with more libraries to link (`-lEGL`).
pub fn build_with(source: &str, prefix: &Path, link_static: bool, exe: &Path, libraries: &[&str]) {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut flags = vec!["--cflags", "--libs"];
    if link_static {
        flags.push("--static");
    }
    let output = Command::new(compiler())
        .args(["-std=c11", "-O1", "-g", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-Wshadow", "-Wstrict-prototypes"])
        .args(["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer"])
        .arg(crate_dir.join("tests/c").join(source))
        .args(pkg_config(prefix, &flags))
        .args(libraries)
        .arg("-lm") // the program's own sqrtf
        .arg("-o")
        .arg(exe)
        .output()
        .expect("a C compiler (cc) is installed");
    assert!(
        output.status.success(),
        "{source} does not compile:\n{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Runs `exe` with `args`, sanitizers on; returns its stdout.
fn run(exe: &Path, args: &[PathBuf], library_path: Option<&Path>) -> String {
    let mut command = Command::new(exe);
    command
        .args(args)
        // Leak checks need ptrace, which some containers deny; the address checks stay on.
        .env("ASAN_OPTIONS", "detect_leaks=0")
        .env("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1")
        .current_dir(root());
    if let Some(dir) = library_path {
        command.env("LD_LIBRARY_PATH", dir);
    }
    let output = command.output().unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "{} failed ({}):\n{stdout}\n{stderr}", exe.display(), output.status);
    assert!(!stderr.contains("runtime error"), "undefined behaviour:\n{stderr}");
    stdout.into_owned()
}

/// A C host, built against the installed static and then the shared library through pkg-config,
/// opens the Fox from memory and the grass patch from its file, reads their views, and
/// poses a puppet Fox from the clip sampler as a game's animation system would: its fur equals
/// the walking Fox's bit for bit, with no sanitizer finding.
#[test]
fn a_c_host_walks_the_fox_and_blows_on_the_grass() {
    let dir = tempfile::tempdir().unwrap();
    for (library, link_static) in [("libfurbake_capi.a", true), ("libfurbake_capi.so", false)] {
        let prefix = dir.path().join(library);
        install(&prefix, library);
        let exe = prefix.join("walking_fox");
        build("walking_fox.c", &prefix, link_static, &exe);
        let args = [packs().join("fox.fbk"), packs().join("grass.fbk")];
        let stdout = run(&exe, &args, (!link_static).then(|| prefix.join("lib")).as_deref());
        assert!(stdout.contains("puppet identical to walker"), "{library}: {stdout}");
        assert!(stdout.contains("Fox ") && stdout.contains("grass: "), "{library}: {stdout}");
    }
}

/// Every call of the header that the other C programs leave out, from C: fin atlas and edges (of
/// the plane with a bare centre: the Fox is furry all over and has none), skin
/// weights, morph targets and clips read and checked; a world opened from a scene file, its packs
/// found by name, one moved by its model matrix, a held pose handed back to the clip player (it
/// walks in step with an unheld twin again), and the wind and gravity changed between steps
/// (the grass's push reverses and stops, the hair rises against upward gravity).
#[test]
fn every_call_of_the_header_answers_from_c() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("meadow.toml");
    let text = format!(
        r#"time_step_s = 0.01
[[packs]]
name = "fox"
path = {fox:?}
scale = 0.01
animation = {{ clip = "Walk" }}
[[packs]]
name = "grass"
path = {grass:?}
[effects.gravity]
[effects.wind]
velocity_m_per_s = [3.0, 0.0, 0.0]
"#,
        fox = packs().join("fox.fbk"),
        grass = packs().join("grass.fbk"),
    );
    std::fs::write(&scene, text).unwrap();
    let prefix = dir.path().join("prefix");
    install(&prefix, "libfurbake_capi.a");
    let exe = prefix.join("every_call");
    build("every_call.c", &prefix, true, &exe);
    let stdout =
        run(&exe, &[packs().join("fox.fbk"), packs().join("strip.fbk"), packs().join("plane.fbk"), scene], None);
    print!("{stdout}");
    assert!(stdout.contains("every call answered as documented"), "{stdout}");
}
