//! Render options from scenes and commands (`furbake_runtime::RenderOptions`: `[render]`,
//! `[packs.render]`, and the overrides of `furbake preview` / `furbake view` flags) reach the
//! renderers: each level overrides the one below key by key, bad values are refused naming the
//! key, and the options change what is drawn.

use std::path::Path;

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_render::headless::{HeadlessGpu, RenderTarget};
use furbake_render::{RenderSettings, SceneRenderer, ShellBlend};
use furbake_runtime::{RenderOptions, Scene, SceneError, ShellBlendMode, World};

fn sphere_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let gltf = testmesh::uv_sphere(8, 12, 1.0).gltf;
    let imported = import_gltf_slice(&gltf, "sphere.gltf", None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    (settings.volume.layers, settings.volume.resolution) = (16, 32);
    let baked = bake(&imported, "sphere", &settings.plan().unwrap(), &mut NoProgress).unwrap();
    baked.to_writer().write_atomic(&dir.path().join("sphere.fbk")).unwrap();
    dir
}

fn scene(dir: &Path, text: &str) -> Result<Scene, SceneError> {
    Scene::from_toml_str(text, Path::new("render.toml"), dir)
}

const TWO_PACKS: &str = "[render]\nshell_layers = 4\nblend = \"alpha_test\"\n\
    [[packs]]\nname = \"a\"\npath = \"sphere.fbk\"\n\
    [[packs]]\nname = \"b\"\npath = \"sphere.fbk\"\ntranslation = [3.0, 0.0, 0.0]\n\
    [packs.render]\nshell_layers = 8\nfins = false\n";

#[test]
fn scene_pack_and_command_options_override_key_by_key() {
    let dir = sphere_dir();
    let world = World::new(scene(dir.path(), TWO_PACKS).unwrap()).unwrap();
    let gpu = HeadlessGpu::new().unwrap();
    let drawn = |overrides: &RenderOptions| {
        let renderer =
            SceneRenderer::for_target_with(gpu.pipelines(), &gpu.queue, &world, &RenderTarget::desc(), overrides)
                .unwrap();
        renderer
            .packs()
            .iter()
            .map(|p| {
                let fur = p.fur.as_ref().unwrap();
                (fur.drawn_layers(), fur.settings().fins, fur.settings().blend, fur.settings().alpha_threshold)
            })
            .collect::<Vec<_>>()
    };
    let test = furbake_render::RenderSettings::ALPHA_TEST_THRESHOLD;
    // The scene's [render] for pack a; pack b's own shell count and fins, the scene's blending.
    assert_eq!(
        drawn(&RenderOptions::default()),
        [(4, true, ShellBlend::AlphaTest, test), (8, false, ShellBlend::AlphaTest, test)]
    );
    // A command's options win over both.
    let flags = RenderOptions { shell_layers: Some(2), blend: Some(ShellBlendMode::AlphaBlend), ..Default::default() };
    let blend = RenderSettings::default().alpha_threshold;
    assert_eq!(drawn(&flags), [(2, true, ShellBlend::AlphaBlend, blend), (2, false, ShellBlend::AlphaBlend, blend)]);
    // No options anywhere: the renderer's defaults (one shell per atlas slice).
    let plain = World::new(scene(dir.path(), "[[packs]]\nname = \"a\"\npath = \"sphere.fbk\"\n").unwrap()).unwrap();
    let renderer = SceneRenderer::new(&gpu.device, &gpu.queue, &plain).unwrap();
    let fur = renderer.packs()[0].fur.as_ref().unwrap();
    assert_eq!((fur.drawn_layers(), fur.settings().fins, fur.settings().blend), (16, true, ShellBlend::AlphaBlend));
    // Bad overrides are refused before anything is built.
    let bad = RenderOptions { silhouette_band: Some(2.0), ..Default::default() };
    let refused = SceneRenderer::for_target_with(gpu.pipelines(), &gpu.queue, &world, &RenderTarget::desc(), &bad);
    assert!(
        matches!(refused, Err(furbake_render::RenderError::Parameter { what }) if what.contains("silhouette_band"))
    );
}

#[test]
fn bad_render_keys_name_their_key() {
    let dir = sphere_dir();
    let pack = "[[packs]]\nname = \"a\"\npath = \"sphere.fbk\"\n";
    for (text, field) in [
        (format!("[render]\nshell_layers = 5000\n{pack}"), "render.shell_layers"),
        (format!("[render]\nsilhouette_band = 1.5\n{pack}"), "render.silhouette_band"),
        (format!("[render]\nalpha_threshold = 1.0\n{pack}"), "render.alpha_threshold"),
        (format!("{pack}[packs.render]\nalpha_threshold = nan\n"), "packs[0].render.alpha_threshold"),
        (format!("[render]\nanisotropy = 3\n{pack}"), "render.anisotropy"),
        (format!("{pack}[packs.render]\nanisotropy = 32\n"), "packs[0].render.anisotropy"),
    ] {
        match scene(dir.path(), &text) {
            Err(SceneError::Invalid { field: f, .. }) => assert_eq!(f, field, "{text}"),
            other => panic!("{text}: {other:?}"),
        }
    }
    for text in [format!("[render]\nblend = \"additive\"\n{pack}"), format!("[render]\nshells = 4\n{pack}")] {
        assert!(matches!(scene(dir.path(), &text), Err(SceneError::Parse { .. })), "{text}");
    }
}

#[test]
fn options_change_the_preview() {
    let dir = sphere_dir();
    let pack = furbake_runtime::Pack::open(dir.path().join("sphere.fbk")).unwrap();
    let render = |options: &RenderOptions| furbake_render::headless::render_preview(&pack, 96, 96, options).unwrap();
    let default = render(&RenderOptions::default());
    assert_eq!(
        default,
        furbake_render::headless::render_preview(&pack, 96, 96, &Default::default()).unwrap(),
        "no options: the default preview"
    );
    let software = HeadlessGpu::new().unwrap().info.device_type == wgpu::DeviceType::Cpu;
    let other_anisotropy = if software { 16 } else { 1 };
    let differ =
        |a: &image::RgbaImage, b: &image::RgbaImage| a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
    for (what, options) in [
        ("bare skin", RenderOptions { shell_layers: Some(0), ..Default::default() }),
        ("flat", RenderOptions { strand_shading: Some(false), blade_shading: Some(false), ..Default::default() }),
        ("alpha test", RenderOptions { blend: Some(ShellBlendMode::AlphaTest), ..Default::default() }),
        ("no fins", RenderOptions { fins: Some(false), silhouette_fins: Some(false), ..Default::default() }),
        // The other filtering than this adapter's default (`options_for_adapter`).
        ("other atlas filtering", RenderOptions { anisotropy: Some(other_anisotropy), ..Default::default() }),
    ] {
        let changed = differ(&default, &render(&options));
        assert!(changed > 50, "{what}: only {changed} pixels changed");
    }
}

#[test]
fn the_anisotropy_key_reaches_the_settings_and_bad_ratios_are_refused() {
    assert_eq!(RenderSettings::default().anisotropy, 16);
    let two = RenderSettings::default().with_options(&RenderOptions { anisotropy: Some(2), ..Default::default() });
    assert_eq!(two.anisotropy, 2);
    assert_eq!(two.with_options(&RenderOptions::default()).anisotropy, 2, "a key left out keeps the setting");
    let dir = sphere_dir();
    let scene =
        scene(dir.path(), "[render]\nanisotropy = 4\n[[packs]]\nname = \"a\"\npath = \"sphere.fbk\"\n").unwrap();
    assert_eq!(scene.render().anisotropy, Some(4));
    let gpu = HeadlessGpu::new().unwrap();
    let world = World::new(scene).unwrap();
    let renderer = SceneRenderer::new(&gpu.device, &gpu.queue, &world).unwrap();
    assert_eq!(renderer.packs()[0].fur.as_ref().unwrap().settings().anisotropy, 4);
    // The renderer refuses what the scene would have (a ratio the samplers do not take).
    let pack = furbake_runtime::Pack::open(dir.path().join("sphere.fbk")).unwrap();
    let asset = furbake_render::FurAsset::from_pack(&pack, true).unwrap();
    let bad = RenderSettings { anisotropy: 3, ..Default::default() };
    let refused = furbake_render::FurRenderer::new(gpu.pipelines(), &gpu.queue, &asset, &bad, &RenderTarget::desc());
    assert!(matches!(refused, Err(furbake_render::RenderError::Parameter { what }) if what.contains("anisotropy")));
}

#[test]
fn previews_on_a_software_adapter_filter_isotropically_unless_asked() {
    use furbake_render::headless::options_for_adapter;
    let gpu = HeadlessGpu::new().unwrap();
    let (mut software, mut hardware) = (gpu.info.clone(), gpu.info.clone());
    software.device_type = wgpu::DeviceType::Cpu;
    hardware.device_type = wgpu::DeviceType::DiscreteGpu;
    let none = RenderOptions::default();
    assert_eq!(options_for_adapter(&none, &software, None).anisotropy, Some(1));
    assert_eq!(options_for_adapter(&none, &hardware, None), none, "a GPU keeps the renderer's default");
    let flags = RenderOptions { anisotropy: Some(8), shell_layers: Some(4), ..Default::default() };
    assert_eq!(options_for_adapter(&flags, &software, None), flags, "a flag wins");
    // A scene that chooses an anisotropy anywhere (here one pack's key) keeps its choice.
    let dir = sphere_dir();
    let pack = "[[packs]]\nname = \"a\"\npath = \"sphere.fbk\"\n";
    let other = "[[packs]]\nname = \"b\"\npath = \"sphere.fbk\"\n";
    let keyed = scene(dir.path(), &format!("{pack}{other}[packs.render]\nanisotropy = 16\n")).unwrap();
    assert_eq!(options_for_adapter(&none, &software, Some(&keyed)), none);
    let plain = scene(dir.path(), pack).unwrap();
    assert_eq!(options_for_adapter(&none, &software, Some(&plain)).anisotropy, Some(1));
}

#[test]
fn the_lod_key_switches_the_shell_level_of_detail() {
    let on = RenderSettings::default();
    assert!(on.lod.is_some(), "the level of detail is on by default");
    let off = on.with_options(&RenderOptions { lod: Some(false), ..Default::default() });
    assert_eq!(off.lod, None);
    let back = off.with_options(&RenderOptions { lod: Some(true), ..Default::default() });
    assert_eq!(back.lod, on.lod);
    // A key left out keeps what the settings had.
    assert_eq!(off.with_options(&RenderOptions::default()).lod, None);
    // From a scene's [render] table.
    let dir = sphere_dir();
    let scene = scene(dir.path(), "[render]\nlod = false\n[[packs]]\nname = \"a\"\npath = \"sphere.fbk\"\n").unwrap();
    assert_eq!(scene.render().lod, Some(false));
}
