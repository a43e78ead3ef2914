//! `bake --depfile` against hostile file names (docs/design.md "Depfiles"), as an external
//! buffer's name and as the output's: each name either makes the bake refuse (exit 1, one line
//! naming the file, neither pack nor depfile written), or gives a depfile that the real GNU make
//! and ninja read back exactly: driven through both, no marker command in a name ever runs, and
//! touching the hostile-named file rebakes the pack.

use std::path::Path;
use std::process::{Command, Output};

use super::common::*;

/// Names no depfile can hold: what GNU make or Ninja would read instead is in
/// `cli/src/bake_files.rs` (`spelling`). `a\b.bin` as a buffer's URI is already refused by the
/// importer (a backslash separator), with the same exit code and the same promise.
const REFUSED: &[&str] = &[
    "a;touch${IFS}PWNED.bin",
    "a|b.bin",
    "a\tb.bin",
    "1:x.bin",
    "a=b.bin",
    "a%b.bin",
    "a*b.bin",
    "a?b.bin",
    "a[b].bin",
    "~x.bin",
    "a\\b.bin",
    "a\nb.bin",
    "a\rb.bin",
    "a\"b.bin",
    "a'b.bin",
    "a&b.bin",
    "a<b>.bin",
    "a^b.bin",
    "a`touch PWNED`.bin",
    "a\u{1b}b.bin",
    "a\u{7f}b.bin",
    "x.bin ",
    "lib(x.bin)",
];

/// Names a depfile holds, escaped (space, `#`, `$`) or as they are.
const WRITTEN: &[&str] = &[
    "a b.bin",
    "a#b.bin",
    "#x.bin",
    "a$b.bin",
    "$(shell touch PWNED).bin",
    " lead.bin",
    "a!b+c,d@e-f_g{h}(i)j~k].bin",
    "é ü 日本.bin",
    "a\u{a0}b.bin",
];

/// Percent-encodes a file name for a glTF URI (everything but ASCII letters, digits, `-._~`).
fn uri(name: &str) -> String {
    name.bytes()
        .map(|b| match b {
            b'a'..=b'z' | b'A'..=b'Z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' => (b as char).to_string(),
            b => format!("%{b:02X}"),
        })
        .collect()
}

/// The real TwoSidedPlane copied into `dir` as `plane.gltf`, its external buffer renamed to
/// `buffer` (its textures keep their names).
fn plane_with_buffer(dir: &Path, buffer: &str) {
    std::fs::create_dir_all(dir).unwrap();
    let src = real_fixture("TwoSidedPlane");
    for entry in std::fs::read_dir(&src).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "png") {
            std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
        }
    }
    let mut gltf: serde_json::Value =
        serde_json::from_slice(&std::fs::read(src.join("TwoSidedPlane.gltf")).unwrap()).unwrap();
    gltf["buffers"][0]["uri"] = uri(buffer).into();
    std::fs::write(dir.join("plane.gltf"), serde_json::to_vec(&gltf).unwrap()).unwrap();
    std::fs::copy(src.join("TwoSidedPlane.bin"), dir.join(buffer)).unwrap();
}

/// `furbake bake plane.gltf -o PACK --depfile pack.d`, run inside `dir` (relative names, as a
/// build system runs it).
fn bake_in(dir: &Path, pack: &str) -> Output {
    Command::new(env!("CARGO_BIN_EXE_furbake"))
        .current_dir(dir)
        .args(["bake", "plane.gltf", "-o", pack, "--resolution", "16", "-q", "--depfile", "pack.d"])
        .output()
        .expect("the furbake binary runs")
}

/// Every file and folder name under `dir`.
fn names_under(dir: &Path) -> Vec<String> {
    let mut names = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            names.push(p.file_name().unwrap().to_string_lossy().into_owned());
            if p.is_dir() {
                stack.push(p);
            }
        }
    }
    names.sort();
    names
}

/// Fails if a marker command from a name (`touch PWNED`, `touch PWNED.bin`) ran.
fn assert_no_marker(dir: &Path, what: &str) {
    let names = names_under(dir);
    assert!(!names.iter().any(|n| n == "PWNED" || n == "PWNED.bin"), "{what}: a marker command ran: {names:?}");
}

/// The bake with `buffer` and `pack` refuses: exit 1, one line naming `hostile`, nothing written.
fn assert_refused(buffer: &str, pack: &str, hostile: &str) {
    let dir = tempfile::tempdir().unwrap();
    plane_with_buffer(dir.path(), buffer);
    let before = names_under(dir.path());
    let out = bake_in(dir.path(), pack);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{hostile:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{hostile:?}: not one line: {err}");
    let quoted = format!("{hostile:?}");
    assert!(err.contains(quoted.trim_matches('"')), "{hostile:?}: the message does not name the file: {err}");
    assert_eq!(names_under(dir.path()), before, "{hostile:?}: a refused bake wrote something ({err})");
    assert_no_marker(dir.path(), hostile);
}

#[test]
fn hostile_buffer_names_are_refused_before_anything_is_written() {
    for name in REFUSED {
        assert_refused(name, "pack.fbk", name);
    }
}

#[test]
fn hostile_output_names_are_refused_before_anything_is_written() {
    for name in REFUSED {
        assert_refused("TwoSidedPlane.bin", name, name);
    }
}

/// `name` in GNU make's rule syntax (for the Makefile's own rule; the same escapes as a depfile).
fn make_escaped(name: &str) -> String {
    name.replace('$', "$$").replace('#', "\\#").replace(' ', "\\ ")
}

/// `name` as a ninja variable's value.
fn ninja_escaped(name: &str) -> String {
    name.replace('$', "$$").replace(' ', "$ ")
}

/// Runs `tool` in `dir`, failing with its output unless it succeeds.
fn run_tool(tool: &str, args: &[&str], dir: &Path, what: &str) -> String {
    let out = Command::new(tool)
        .args(args)
        .current_dir(dir)
        // A `make test` around cargo must not hand its jobserver or flags to this make.
        .env_remove("MAKEFLAGS")
        .env_remove("MFLAGS")
        .env_remove("MAKELEVEL")
        .output()
        .unwrap_or_else(|e| panic!("cannot run {tool} ({e}): install GNU make and ninja (Debian: make, ninja-build)"));
    assert!(out.status.success(), "{what}: {tool} failed: {}{}", stdout(&out), stderr(&out));
    stdout(&out)
}

/// "Touch": now is later than the pack (both tools compare nanosecond mtimes).
fn touch(p: &Path) {
    std::fs::File::options().append(true).open(p).unwrap().set_modified(std::time::SystemTime::now()).unwrap();
}

/// Bakes with `buffer` and `pack` through GNU make (a Makefile that includes the depfile and
/// rebakes) and ninja (`deps = gcc`): a second run does nothing, touching the buffer rebakes,
/// ninja records exactly the files read, and no marker command runs.
fn assert_read_back_exactly(buffer: &str, pack: &str, what: &str) {
    let dir = tempfile::tempdir().unwrap();
    let furbake = env!("CARGO_BIN_EXE_furbake");

    let m = dir.path().join("make");
    plane_with_buffer(&m, buffer);
    let makefile = format!(
        "FURBAKE := {}\n{}: plane.gltf\n\t@echo BAKED\n\t@'$(FURBAKE)' bake plane.gltf -o '$@' --resolution 16 -q \
         --depfile pack.d\n-include pack.d\n",
        furbake.replace('$', "$$"),
        make_escaped(pack)
    );
    std::fs::write(m.join("Makefile"), makefile).unwrap();
    let make = |step: &str| run_tool("make", &["-r", "--no-print-directory"], &m, &format!("{what}: {step}"));
    let baked = |out: &str| out.lines().filter(|l| *l == "BAKED").count();
    assert_eq!(baked(&make("first make")), 1, "{what}: the first make bakes");
    assert!(m.join(pack).is_file() && m.join("pack.d").is_file(), "{what}: {:?}", names_under(&m));
    let again = make("second make");
    assert_eq!(baked(&again), 0, "{what}: make read the depfile and found the pack up to date: {again}");
    touch(&m.join(buffer));
    let after = make("make after touching the buffer");
    assert_eq!(baked(&after), 1, "{what}: make rebakes when the buffer named in the depfile changes: {after}");

    let n = dir.path().join("ninja");
    plane_with_buffer(&n, buffer);
    let build = format!(
        "pack = {}\nrule bake\n  command = '{}' bake $in -o $out --resolution 16 -q --depfile pack.d\n  \
         depfile = pack.d\n  deps = gcc\n  description = BAKE\n\nbuild $pack: bake plane.gltf\n",
        ninja_escaped(pack),
        furbake.replace('$', "$$")
    );
    std::fs::write(n.join("build.ninja"), build).unwrap();
    let ninja = |step: &str| run_tool("ninja", &[], &n, &format!("{what}: {step}"));
    let baked = |out: &str| out.lines().filter(|l| l.ends_with("BAKE")).count();
    assert_eq!(baked(&ninja("first ninja")), 1, "{what}: the first ninja bakes");
    let deps = run_tool("ninja", &["-t", "deps", pack], &n, &format!("{what}: ninja -t deps"));
    let recorded: Vec<&str> = deps.lines().filter_map(|l| l.strip_prefix("    ")).collect();
    assert_eq!(recorded, ["plane.gltf", buffer, "TwoSidedPlane_BaseColor.png"], "{what}: ninja -t deps: {deps}");
    let again = ninja("second ninja");
    assert!(baked(&again) == 0 && again.contains("no work to do"), "{what}: {again}");
    touch(&n.join(buffer));
    assert_eq!(baked(&ninja("ninja after touching the buffer")), 1, "{what}: ninja rebakes");

    assert_no_marker(dir.path(), what);
}

#[test]
fn escaped_buffer_names_are_read_back_exactly_by_make_and_ninja() {
    for name in WRITTEN {
        assert_read_back_exactly(name, "pack.fbk", &format!("buffer {name:?}"));
    }
}

#[test]
fn escaped_output_names_are_read_back_exactly_by_make_and_ninja() {
    for name in WRITTEN {
        assert_read_back_exactly("TwoSidedPlane.bin", name, &format!("output {name:?}"));
    }
}
