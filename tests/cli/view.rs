//! `furbake view`: the demo scene — the Fox walking on the grass patch in a gusty breeze, its packs
//! baked here as `make demo` bakes them (smaller) — shown in a real window on a virtual X server
//! (Xvfb) for 30 frames, its last frame written with `--screenshot`. The screenshot must show the
//! Fox: it has the requested size, a good share of its pixels have the Fox's orange, and it matches
//! `furbake preview`'s frame of the same scene at the same scene time (both draw the same world
//! with the same renderer; only the host differs). Without a display the viewer exits 1 naming
//! DISPLAY and `xvfb-run`. Needs `xvfb-run` on PATH (`.ci/run` installs xvfb): without it the test
//! fails, it is never skipped.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use image::RgbaImage;

use super::common::*;

/// The repository's root.
fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `xvfb-run` from PATH; fails the test when it is missing.
fn xvfb_run() -> PathBuf {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path).map(|dir| dir.join("xvfb-run")).find(|p| p.is_file()).unwrap_or_else(|| {
        panic!(
            "xvfb-run is not on PATH: install xvfb (Debian/Ubuntu: apt-get install xvfb xauth; .ci/run does) — \
             this test opens a real window on a virtual X server and is never skipped"
        )
    })
}

/// Runs `furbake ARGS` inside a fresh virtual X server with a 640×480 screen (`xvfb` is
/// [`xvfb_run`]'s answer, asked first so that a machine without it fails before baking).
fn furbake_under_xvfb(xvfb: &Path, args: &[&str]) -> Output {
    Command::new(xvfb)
        .args(["-a", "-s", "-screen 0 640x480x24", env!("CARGO_BIN_EXE_furbake")])
        .args(args)
        .output()
        .expect("xvfb-run runs")
}

/// Bakes the demo scene's packs into `dir` (the Makefile's `make demo` settings, smaller shell
/// atlases and fewer blade poses) and copies the scene beside them. Returns the scene's path.
fn bake_demo(dir: &Path) -> PathBuf {
    let fox = dir.join("fox.fbk");
    let mesh = repo().join("fixtures/real/Fox.glb");
    let args = ["bake", s(&mesh), "-o", s(&fox), "--preset", "fur", "--topology", "prisms", "--resolution", "32", "-q"];
    assert_ok(&furbake(&args), "bake the fox");
    let patch = repo().join("fixtures/generated/grass_patch.gltf");
    let grass = dir.join("grass-patch.fbk");
    let args = [
        "bake",
        s(&patch),
        "-o",
        s(&grass),
        "--preset",
        "grass",
        "--blades",
        "400",
        "--topology",
        "prisms",
        "--resolution",
        "16",
        "--set",
        "blades.keyframes.grid.poses=200",
        "-q",
    ];
    assert_ok(&furbake(&args), "bake the grass patch");
    let scene = dir.join("fox_and_grass.toml");
    std::fs::copy(repo().join("fixtures/scenes/demo_fox_and_grass.toml"), &scene).unwrap();
    scene
}

/// Pixels of the Fox's orange-red fur: red well above green, green above blue. The scene's
/// background (a grey-blue) and the grass (green) have none.
fn fox_pixels(img: &RgbaImage) -> usize {
    img.pixels()
        .filter(|p| {
            let [r, g, b, _] = p.0.map(i32::from);
            r > g + 40 && g > b && r > 100
        })
        .count()
}

#[test]
fn view_screenshots_the_fox_in_the_demo_scene_under_xvfb() {
    let xvfb = xvfb_run();
    let dir = tempfile::tempdir().unwrap();
    let scene = bake_demo(dir.path());
    let shot = dir.path().join("shot.png");
    let out = furbake_under_xvfb(
        &xvfb,
        &["view", s(&scene), "--frames", "30", "--screenshot", s(&shot), "--size", "320x240"],
    );
    assert_ok(&out, "furbake view under xvfb-run");
    let img = image::open(&shot).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (320, 240), "the screenshot has the requested size");
    let fox = fox_pixels(&img);
    assert!(fox > 320 * 240 / 50, "only {fox} fox-coloured pixels in the screenshot");

    // `furbake preview`'s 30th frame is the world after the same 30 steps, drawn by the same
    // renderer into a headless target of the same format: the window's frame matches it
    // (measured: bit-identical on lavapipe, the Fox covering 4.6 % of the frame). The tolerance
    // leaves room for an adapter that rounds blended shell layers differently between two
    // devices; a frame of another scene time or camera misses it by far.
    let frames = dir.path().join("frames");
    let args = ["preview", s(&scene), "--frames", "30", "--out-dir", s(&frames), "--size", "320x240", "-q"];
    assert_ok(&furbake(&args), "preview the same frames");
    let still = image::open(frames.join("frame_0029.png")).unwrap().to_rgba8();
    let close =
        img.pixels().zip(still.pixels()).filter(|(a, b)| a.0.iter().zip(b.0).all(|(x, y)| x.abs_diff(y) <= 2)).count();
    let total = (320 * 240) as usize;
    assert!(close * 100 >= total * 99, "only {close} of {total} pixels match preview's frame of the same time");
    assert!(stdout(&out).is_empty(), "view prints nothing on stdout: {}", stdout(&out));
    assert!(stderr(&out).contains("30 frames"), "the summary names the frames: {}", stderr(&out));
}

#[test]
fn view_shows_a_pack_alone_and_refuses_without_a_display() {
    let xvfb = xvfb_run();
    let dir = tempfile::tempdir().unwrap();
    let fox = dir.path().join("fox.fbk");
    let mesh = repo().join("fixtures/real/Fox.glb");
    assert_ok(&furbake(&["bake", s(&mesh), "-o", s(&fox), "--resolution", "32", "-q"]), "bake the fox");

    // A pack gets a default scene: framed tightly like `furbake preview PACK`, so the Fox fills
    // much of the frame (measured: 14 % of its pixels are the Fox's orange on lavapipe).
    let shot = dir.path().join("pack.png");
    let out =
        furbake_under_xvfb(&xvfb, &["view", s(&fox), "--frames", "3", "--screenshot", s(&shot), "--size", "160x120"]);
    assert_ok(&out, "furbake view PACK");
    let img = image::open(&shot).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (160, 120));
    let covered = fox_pixels(&img);
    assert!(covered > 160 * 120 / 16, "only {covered} fox-coloured pixels");

    // No display: exit 1, one line naming the variables and the way out; nothing written.
    let none = dir.path().join("none.png");
    let out = Command::new(env!("CARGO_BIN_EXE_furbake"))
        .args(["view", s(&fox), "--frames", "1", "--screenshot", s(&none)])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let err = stderr(&out);
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    for needle in ["DISPLAY", "WAYLAND_DISPLAY", "xvfb-run"] {
        assert!(err.contains(needle), "the message does not name {needle}: {err}");
    }
    assert!(!none.exists());

    // Usage errors exit 2 before any window opens.
    let mut usage = 0;
    for args in [
        vec!["view", s(&fox), "--screenshot", s(&none)],
        vec!["view", s(&fox), "--frames", "0"],
        vec!["view", s(&fox), "--size", "0x10"],
    ] {
        let out = furbake(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        usage += 1;
    }
    assert_eq!(usage, 3);
    // A missing input is bad input, named.
    let missing = furbake(&["view", s(&dir.path().join("nope.fbk")), "--frames", "1"]);
    assert_eq!(missing.status.code(), Some(1), "{}", stderr(&missing));
    assert!(stderr(&missing).contains("nope.fbk"));
}
