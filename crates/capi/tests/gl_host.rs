//! A host that is not ours: `tests/c/gl_fur.c` (C, OpenGL 4.5 on a headless EGL context —
//! Mesa's llvmpipe here) draws the walking Fox's skin and shells with the GLSL that `furbake
//! shaders` exports and the data the C interface hands out, and its image is compared with
//! furbake's own renderer (`SceneRenderer::render_world`, what `furbake preview SCENE` draws) of
//! the same scene at the same step: same camera, light, ambient, clip time — the host poses the
//! Fox itself from the clip sampler, furbake's world walks it on its own clip player. Two looks: furbake's
//! default (blended shells with stacking exponents, strand shading, level of detail, mip chain;
//! no fins), and alpha-tested shells, every layer, Lambert × self-shadow.

use std::path::Path;
use std::process::Command;

use furbake_render::headless::{HeadlessGpu, RenderTarget, read_back};
use furbake_render::{SceneRenderer, ShaderTarget, export_shaders};
use furbake_runtime::{RenderOptions, Scene, World};

use crate::common::packs;

const W: u32 = 160;
const H: u32 = 120;
const STEPS: u32 = 10;
/// The alpha test's threshold, in the scene and on gl_fur.c's command line.
const THRESHOLD: &str = "0.3";

/// How gl_fur.c draws, and the scene's `[render]` table that has furbake's renderer draw alike.
#[derive(Clone, Copy)]
enum Look {
    /// furbake's default look: the scene sets nothing.
    Furbake,
    /// The host draws furbake's look without its fins (the renderer still draws them).
    FurbakeWithoutFins,
    /// Alpha-tested shells, every layer, strand shading off.
    AlphaTest,
}

impl Look {
    fn argument(self) -> &'static str {
        match self {
            Look::Furbake => "default",
            Look::FurbakeWithoutFins => "default_without_fins",
            Look::AlphaTest => "alpha_test",
        }
    }

    fn render_table(self) -> String {
        match self {
            Look::Furbake | Look::FurbakeWithoutFins => String::new(),
            Look::AlphaTest => format!(
                "[render]\nshell_layers = 4\nblend = \"alpha_test\"\nalpha_threshold = {THRESHOLD}\nlod = false\n\
                 fins = false\nsilhouette_fins = false\nstrand_shading = false\n"
            ),
        }
    }
}

/// The scene gl_fur.c draws (its camera, light and ambient are written there too).
fn scene_text(look: Look) -> String {
    format!(
        r#"
time_step_s = 0.02
[camera]
eye = [1.6, 0.9, 2.0]
target = [0.0, 0.35, 0.0]
fov_y_deg = 40.0
[[lights]]
type = "directional"
direction = [0.4, -0.8, -0.45]
color = [1.0, 0.95, 0.9]
intensity = 1.2
[ambient]
sky = [0.2, 0.22, 0.25]
ground = [0.1, 0.09, 0.08]
{render}
[[packs]]
name = "fox"
path = "fox.fbk"
scale = 0.01
animation = {{ clip = "Walk" }}
[effects.gravity]
"#,
        render = look.render_table()
    )
}

/// furbake's renderer: the scene stepped `STEPS` times, drawn headless (RGBA8 sRGB, top row first).
fn reference(look: Look) -> Vec<u8> {
    let scene = Scene::from_toml_str(&scene_text(look), Path::new("gl_host.toml"), packs()).unwrap();
    let mut world = World::new(scene).unwrap();
    for _ in 0..STEPS {
        world.step().unwrap();
    }
    let gpu = HeadlessGpu::new().unwrap();
    let renderer = SceneRenderer::for_target_with(
        gpu.pipelines(),
        &gpu.queue,
        &world,
        &RenderTarget::desc(),
        &RenderOptions::default(),
    )
    .unwrap();
    let target = RenderTarget::new(&gpu.device, W, H).unwrap();
    renderer.render_world(&gpu.device, &gpu.queue, &target, &world).unwrap();
    read_back(&gpu.device, &gpu.queue, &target).unwrap().into_raw()
}

/// The GLSL binding manifest.json gives resource `name` in `file`.
fn glsl_binding(manifest: &serde_json::Value, file: &str, name: &str) -> Option<u64> {
    let files = manifest["files"].as_array().unwrap();
    let file = files.iter().find(|f| f["file"] == file).unwrap_or_else(|| panic!("{file} is exported"));
    let b = file["bindings"].as_array().unwrap().iter().find(|b| b["name"] == name)?;
    b["glsl_binding"]["binding"].as_u64()
}

/// The programs gl_fur.c links: skin and shells in both looks, the fins and the silhouette
/// selection.
const PROGRAMS: [&str; 11] = [
    "skin.vs_skin.none.vert",
    "skin.fs_skin.lambert-shadow.light_slots1.frag",
    "skin.fs_skin.lambert-shadow-strand.light_slots1.frag",
    "shell.vs_shell.shear.vert",
    "shell.fs_shell.lambert-shadow.light_slots1.frag",
    "shell.vs_shell.shear-strand.vert",
    "shell.fs_shell.alpha_blend-lambert-shadow-strand.light_slots1.frag",
    "fin.vs_fin.shear-strand.vert",
    "fin.vs_silhouette_fin.shear-strand.vert",
    "fin.fs_fin.alpha_blend-lambert-shadow-strand.light_slots1.frag",
    "silhouette.cs_silhouette.comp",
];
/// The resources it binds, each at the one binding every program that reads it gives it (it
/// binds a number again before a program whose other resources took it over).
const RESOURCES: [&str; 16] = [
    "frame",
    "fur",
    "scale_vectors",
    "shadow",
    "shell_alpha",
    "stacking",
    "fin_alpha",
    "sil_edges",
    "sil_instances",
    "sil_vertices",
    "sil_colors",
    "params",
    "edges",
    "vertices",
    "instances",
    "args",
];

/// gl_fur.c's frame in `look` (RGBA8, top row first), built with the sanitizers.
fn opengl_host(look: Look) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let shaders = dir.path().join("glsl");
    std::fs::create_dir_all(&shaders).unwrap();
    let export = export_shaders(ShaderTarget::Glsl).unwrap();
    for f in &export.files {
        std::fs::write(shaders.join(&f.file), &f.bytes).unwrap();
    }
    // Each resource has one binding in every file that uses it (the host binds it once).
    let bindings: Vec<String> = RESOURCES
        .iter()
        .map(|name| {
            let numbers: Vec<u64> = PROGRAMS.iter().filter_map(|f| glsl_binding(&export.manifest, f, name)).collect();
            assert!(!numbers.is_empty() && numbers.iter().all(|&n| n == numbers[0]), "{name}: {numbers:?}");
            format!("{name}={}", numbers[0])
        })
        .collect();

    let prefix = dir.path().join("prefix");
    crate::c_programs::install(&prefix, "libfurbake_capi.a");
    let exe = dir.path().join("gl_fur");
    crate::c_programs::build_with("gl_fur.c", &prefix, true, &exe, &["-lEGL", "-lOpenGL"]);
    let image = dir.path().join("gl.rgba");
    let out = Command::new(&exe)
        .arg(packs().join("fox.fbk"))
        .arg(&shaders)
        .arg(&image)
        .args([W, H, STEPS].map(|v| v.to_string()))
        .arg(look.argument())
        .arg(THRESHOLD)
        .args(&bindings)
        // Leak checks need ptrace (often denied in containers), and the OpenGL driver's own
        // allocations are not ours to judge; address and UB checks stay on.
        .env("ASAN_OPTIONS", "detect_leaks=0")
        .env("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1")
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "gl_fur failed ({}):\n{stdout}\n{stderr}", out.status);
    eprintln!("{stdout}{stderr}");
    std::fs::read(&image).unwrap()
}

/// Compares the two frames; returns (Fox pixels, pixels differing by more than 8/255, mean
/// difference).
fn compare(look: Look, ours: &[u8], theirs: &[u8]) -> (usize, usize, f64) {
    if let Some(dir) = std::env::var_os("FURBAKE_GL_HOST_IMAGES") {
        let (dir, name) = (Path::new(&dir), look.argument());
        image::save_buffer(dir.join(format!("gl_host_{name}.png")), ours, W, H, image::ColorType::Rgba8).unwrap();
        image::save_buffer(dir.join(format!("furbake_{name}.png")), theirs, W, H, image::ColorType::Rgba8).unwrap();
    }
    assert_eq!(ours.len(), theirs.len());
    let background = [theirs[0], theirs[1], theirs[2]]; // the top-left corner is the clear colour
    let fox_pixels = theirs.chunks(4).filter(|p| p[..3].iter().zip(background).any(|(a, b)| a.abs_diff(b) > 4)).count();
    let diffs: Vec<u8> =
        ours.chunks(4).zip(theirs.chunks(4)).map(|(a, b)| (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap()).collect();
    let over = |t: u8| diffs.iter().filter(|&&d| d > t).count();
    let mean = diffs.iter().map(|&d| d as f64).sum::<f64>() / diffs.len() as f64;
    eprintln!(
        "OpenGL host vs furbake: {fox_pixels} fox pixels of {}; max {}, mean {mean:.3}; > 2: {}, > 8: {}, > 32: {}",
        diffs.len(),
        diffs.iter().max().unwrap(),
        over(2),
        over(8),
        over(32)
    );
    assert!(
        fox_pixels > (W * H / 20) as usize && fox_pixels < (W * H / 2) as usize,
        "the Fox fills part of the frame ({fox_pixels} pixels)"
    );
    (fox_pixels, over(8), mean)
}

/// furbake's look, as `furbake preview` draws the scene: blended shells with the stacking
/// exponents, strand shading, the level of detail's shell count and the atlas's mip chain (back
/// faces first, then front faces; without the back faces' draw 161 Fox pixels differ by more
/// than 8/255 and this fails), then
/// the silhouette fins the exported compute pass selects for this view, all from the C
/// interface's draw views. Without its fins the host's frame is visibly off (the comparison sees
/// them).
#[test]
fn an_opengl_host_draws_the_walking_fox_in_furbakes_look() {
    let theirs = reference(Look::Furbake);
    let ours = opengl_host(Look::Furbake);
    let (fox, over, mean) = compare(Look::Furbake, &ours, &theirs);
    assert!(over * 100 <= fox, "{over} of the Fox's {fox} pixels differ by more than 8/255 (1 % allowed)");
    assert!(mean < 0.5, "mean difference {mean}");
    let finless = opengl_host(Look::FurbakeWithoutFins);
    let (_, over, _) = compare(Look::FurbakeWithoutFins, &finless, &theirs);
    // Fins stand only where the skin turns beyond the shells' 80° (fin.wgsl): 69 of 1,718 Fox
    // pixels (4.0 %) differ without them, twice the share the comparison above allows.
    assert!(over * 100 > 2 * fox, "without fins only {over} of {fox} pixels differ by more than 8/255");
}

/// Alpha-tested shells, every layer, Lambert × self-shadow.
#[test]
fn an_opengl_host_draws_the_walking_fox_skin_and_alpha_tested_shells_as_furbake_does() {
    let (ours, theirs) = (opengl_host(Look::AlphaTest), reference(Look::AlphaTest));
    let (fox, over, mean) = compare(Look::AlphaTest, &ours, &theirs);
    assert!(over * 100 <= fox, "{over} of the Fox's {fox} pixels differ by more than 8/255 (1 % allowed)");
    assert!(mean < 0.5, "mean difference {mean}");
}
