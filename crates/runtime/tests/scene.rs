//! Scene parsing and validation: the example scenes parse into the effects they declare, unknown
//! keys and out-of-range values are rejected with the offending key's dotted path.

use std::path::Path;

use furbake_runtime::scene::{Collider, Gravity, PackAnimation, SolverChoice};
use furbake_runtime::{Effect, Effects, Event, GrassCulling, Scene, SceneError, ScenePack, Solver};

fn scenes_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/scenes"))
}

fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::from_toml_str(text, Path::new("test.toml"), Path::new("/base"))
}

const MINIMAL: &str = "[[packs]]\nname = \"a\"\npath = \"a.fbk\"\n";

#[test]
fn fox_scene_declares_only_its_effects() {
    let scene = Scene::load(scenes_dir().join("runtime_fox_in_wind.toml")).unwrap();
    assert_eq!(
        scene.effects().enabled(),
        vec![Effect::Gravity, Effect::Wind, Effect::WindSources, Effect::ObjectMotion, Effect::WrongSideGuard]
    );
    assert!(!scene.effects().has(Effect::Parting));
    assert_eq!(scene.packs().len(), 1);
    assert_eq!(scene.packs()[0].path, scenes_dir().join("fox.fbk"), "relative paths resolve against the file");
    assert_eq!(scene.packs()[0].motion.len(), 2);
    assert_eq!(scene.effects().gravity.unwrap().acceleration_m_per_s2, [0.0, -9.81, 0.0], "default gravity");
    assert_eq!(scene.effects().wind_sources[0].falloff_exponent, 2.0);
    let guard = scene.effects().wrong_side_guard.unwrap();
    assert_eq!((guard.restoring_weight_n, guard.max_angle_deg, guard.impulse_m_per_s), (0.02, 75.0, 0.05));
    // The transform places the origin at the translation and scales uniformly.
    let m = scene.packs()[0].motion[1].transform().to_mat4();
    assert_eq!(m.transform_point3(glam::Vec3::ZERO), glam::Vec3::new(0.5, 0.0, 0.0));
}

#[test]
fn every_effect_parses() {
    let scene = Scene::load(scenes_dir().join("runtime_everything.toml")).unwrap();
    let all = [
        Effect::Gravity,
        Effect::Wind,
        Effect::WindSources,
        Effect::ObjectMotion,
        Effect::Interaction,
        Effect::Collisions,
        Effect::WindlessAreas,
        Effect::Parting,
        Effect::WrongSideGuard,
    ];
    assert_eq!(scene.effects().enabled(), all.to_vec());
    assert_eq!(scene.packs()[0].path, scenes_dir().join("grass-patch.fbk"));
    let absolute = parse("[[packs]]\nname = \"a\"\npath = \"/abs/a.fbk\"\n").unwrap();
    assert_eq!(absolute.packs()[0].path, Path::new("/abs/a.fbk"), "absolute paths are kept");
    assert_eq!(scene.effects().collisions.len(), 2);
    assert!(matches!(scene.effects().collisions[1], Collider::Ellipsoid { radii_m: [0.3, 0.1, 0.2], .. }));
    assert!(scene.effects().wind_sources[0].delayed_attenuation);
    assert_eq!(scene.effects().interaction.unwrap().position, Some([0.0, 0.3, 0.0]));
    assert_eq!(scene.effects().wrong_side_guard.unwrap().impulse_m_per_s, 0.1);
    let culling = scene.grass_culling();
    assert_eq!((culling.max_distance_m, culling.lod_distances_m, culling.min_density), (60.0, [4.0, 12.0], 0.5));
    assert_eq!(culling.thinning_start_m, GrassCulling::default().thinning_start_m, "unset keys keep their defaults");
}

#[test]
fn minimal_scene_has_no_effects_and_defaults() {
    let scene = parse(MINIMAL).unwrap();
    assert!(scene.effects().enabled().is_empty());
    assert_eq!(scene.solver(), Solver { kind: SolverChoice::Auto, implicit_iterations: 1, ..Solver::default() });
    assert!(scene.events().is_empty() && scene.duration_s().is_none());
    assert!(scene.camera().is_none());
    assert_eq!(scene.grass_culling(), GrassCulling::default());
    assert!((scene.time_step_s() - 1.0 / 60.0).abs() < 1e-9);
    assert_eq!(scene.packs()[0].path, Path::new("/base/a.fbk"));
}

#[test]
fn unknown_keys_and_wrong_types_are_parse_errors() {
    let cases = [
        format!("{MINIMAL}[effects.wnid]\n"),
        format!("{MINIMAL}[effects.wind]\nvelocity = [1.0, 0.0, 0.0]\n"),
        format!("{MINIMAL}[[effects.collisions]]\nshape = \"cube\"\ncenter = [0.0, 0.0, 0.0]\n"),
        format!("{MINIMAL}solver = \"magic\"\n"),
        format!("{MINIMAL}time_step_s = \"fast\"\n"),
        "[[packs]]\nname = \"a\"\n".to_owned(),
        "packs = 3".to_owned(),
    ];
    for text in &cases {
        match parse(text) {
            Err(SceneError::Parse { .. }) => {}
            other => panic!("expected a parse error for {text:?}, got {other:?}"),
        }
    }
    assert_eq!(cases.len(), 7);
}

#[test]
fn an_effect_written_as_a_value_is_answered_with_the_table_to_write() {
    // An array (serde's derived structs would read it as the fields in order and fail on the
    // first number), a number and a boolean where an effect's table belongs.
    let cases = [
        ("gravity = [0.0, -9.81, 0.0]", "gravity = { acceleration_m_per_s2 = [0.0, -9.81, 0.0] }"),
        ("wind = [2.0, 0.0, 0.0]", "wind = { velocity_m_per_s = [2.0, 0.0, 0.0]"),
        ("object_motion = true", "object_motion = { inertia_scale = 1.0 }"),
        ("interaction = 0.3", "interaction = { position = [0.0, 0.3, 0.0]"),
        ("parting = true", "parting = {}"),
        ("wrong_side_guard = 75.0", "wrong_side_guard = { max_angle_deg = 75.0 }"),
    ];
    for (line, example) in cases {
        let text = format!("{MINIMAL}[effects]\n{line}\n");
        match parse(&text) {
            Err(SceneError::Parse { message, .. }) => {
                assert!(message.contains("expected a table"), "{line}: {message}");
                assert!(message.contains(example), "{line}: {message}");
                assert!(!message.contains("array of length"), "{line}: {message}");
                let key = line.split(' ').next().unwrap();
                assert!(
                    message.starts_with(&format!("effects.{key}: ")),
                    "{line}: the message names the key: {message}"
                );
                assert!(message.contains("(line 5, column "), "{line}: the message says where: {message}");
            }
            other => panic!("expected a parse error for {line:?}, got {other:?}"),
        }
    }
    // The table forms still parse, inline or as a section, and mean the same.
    let inline =
        parse(&format!("{MINIMAL}[effects]\ngravity = {{ acceleration_m_per_s2 = [0.0, -3.0, 0.0] }}\n")).unwrap();
    let section = parse(&format!("{MINIMAL}[effects.gravity]\nacceleration_m_per_s2 = [0.0, -3.0, 0.0]\n")).unwrap();
    assert_eq!(inline.effects().gravity.unwrap().acceleration_m_per_s2, [0.0, -3.0, 0.0]);
    assert_eq!(inline.effects(), section.effects());
    // A key inside the table keeps its own error.
    let err = parse(&format!("{MINIMAL}[effects.gravity]\nacceleration = [0.0, -3.0, 0.0]\n")).unwrap_err();
    assert!(err.to_string().contains("acceleration"), "{err}");
}

#[test]
fn out_of_range_values_name_their_key() {
    let cases = [
        (format!("time_step_s = 0.0\n{MINIMAL}"), "time_step_s"),
        (format!("{MINIMAL}scale = -1.0\n"), "packs[0].scale"),
        ("packs = []\n".to_owned(), "packs"),
        (format!("{MINIMAL}{}", MINIMAL), "packs[1].name"),
        (format!("[camera]\neye = [0.0, 0.0, 1.0]\ntarget = [0.0, 0.0, 1.0]\n{MINIMAL}"), "camera.target"),
        (format!("[camera]\neye = [0.0, 1.0, 0.0]\ntarget = [0.0, 0.0, 0.0]\n{MINIMAL}"), "camera.up"),
        (format!("[light]\ndirection = [0.0, 0.0, 0.0]\n{MINIMAL}"), "light.direction"),
        (format!("[light]\n[ambient]\n{MINIMAL}"), "light"),
        (format!("[[lights]]\ntype = \"directional\"\ndirection = [0.0, 0.0, 0.0]\n{MINIMAL}"), "lights[0].direction"),
        (
            format!("[[lights]]\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = -1.0\n{MINIMAL}"),
            "lights[0].intensity",
        ),
        (
            format!("[[lights]]\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nrange_m = nan\n{MINIMAL}"),
            "lights[0].range_m",
        ),
        (
            format!("{}{MINIMAL}", "[[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, 0.0]\n".repeat(5)),
            "lights",
        ),
        (format!("[ambient]\nsky = [0.1, -0.1, 0.1]\n{MINIMAL}"), "ambient.sky"),
        (format!("{MINIMAL}[effects.wind]\nvelocity_m_per_s = [nan, 0.0, 0.0]\n"), "effects.wind.velocity_m_per_s"),
        (
            format!("{MINIMAL}[[effects.wind_sources]]\nposition = [0.0, 0.0, 0.0]\npower = -1.0\n"),
            "effects.wind_sources[0].power",
        ),
        (
            format!("{MINIMAL}[[effects.collisions]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius_m = 0.0\n"),
            "effects.collisions[0].radius_m",
        ),
        (
            format!("{MINIMAL}[[effects.windless_areas]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, -1.0, 1.0]\n"),
            "effects.windless_areas[0].max",
        ),
        (
            format!("{MINIMAL}[effects.wrong_side_guard]\nmax_angle_deg = 120.0\n"),
            "effects.wrong_side_guard.max_angle_deg",
        ),
        (
            // furbake-sim's guard needs α < 90°: at 90° every tangential scale vector would pass.
            format!("{MINIMAL}[effects.wrong_side_guard]\nmax_angle_deg = 90.0\n"),
            "effects.wrong_side_guard.max_angle_deg",
        ),
        (
            format!("{MINIMAL}[effects.interaction]\nposition = [0.0, inf, 0.0]\nradius_m = 1.0\nstrength_n = 1.0\n"),
            "effects.interaction.position",
        ),
        (
            format!("{MINIMAL}[[packs.motion]]\ntime_s = 1.0\n[[packs.motion]]\ntime_s = 1.0\n"),
            "packs[0].motion[1].time_s",
        ),
        (format!("{MINIMAL}[grass_culling]\nmin_density = 0.0\n"), "grass_culling.min_density"),
        (format!("{MINIMAL}[grass_culling]\nlod_distances_m = [30.0, 10.0]\n"), "grass_culling.lod_distances_m"),
        (format!("{MINIMAL}[grass_culling]\nmax_distance_m = -5.0\n"), "grass_culling.max_distance_m"),
        (format!("{MINIMAL}[grass_culling]\nmin_visible_width = 1.0\n"), "grass_culling.min_visible_width"),
        (format!("{MINIMAL}[grass_culling]\nlod_transition = nan\n"), "grass_culling.lod_transition"),
    ];
    for (text, key) in &cases {
        match parse(text) {
            Err(SceneError::Invalid { field, .. }) => assert_eq!(&field, key, "for {text:?}"),
            other => panic!("expected {key} to be rejected in {text:?}, got {other:?}"),
        }
    }
    assert_eq!(cases.len(), 26);
}

#[test]
fn lights_and_ambient_parse_into_the_lighting() {
    use furbake_runtime::{Ambient, Light, LightSource, Lighting};
    let text = format!(
        "[[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, 0.0]\n\
         [[lights]]\ntype = \"point\"\nposition = [1.0, 2.0, 3.0]\ncolor = [1.0, 0.5, 0.25]\nintensity = 3.0\nrange_m = 10.0\n\
         [ambient]\nsky = [0.2, 0.3, 0.4]\n{MINIMAL}"
    );
    let lighting = parse(&text).unwrap().lighting();
    assert_eq!(
        lighting.sources(),
        [
            LightSource::Directional { direction: [0.0, -1.0, 0.0], color: [1.0; 3], intensity: 1.0 },
            LightSource::Point { position: [1.0, 2.0, 3.0], color: [1.0, 0.5, 0.25], intensity: 3.0, range_m: 10.0 },
        ]
    );
    assert_eq!(lighting.ambient, Ambient { sky: [0.2, 0.3, 0.4], ground: Ambient::default().ground });
    assert_eq!(parse(MINIMAL).unwrap().lighting(), Lighting::default());
    assert_ne!(Lighting::default(), Lighting::from(Light::default()), "no light keys: the studio lights");
    let unknown = parse(&format!("[[lights]]\ntype = \"spot\"\ndirection = [0.0, -1.0, 0.0]\n{MINIMAL}"));
    assert!(matches!(unknown, Err(SceneError::Parse { .. })), "{unknown:?}");
    assert!(
        Lighting::new(
            &[LightSource::Directional { direction: [0.0, -1.0, 0.0], color: [1.0; 3], intensity: 1.0 }; 5],
            Ambient::default()
        )
        .is_err()
    );
}

#[test]
fn missing_file_is_an_io_error() {
    let err = Scene::load("/definitely/not/here.toml").unwrap_err();
    assert!(matches!(err, SceneError::Io { .. }), "{err}");
    assert!(err.to_string().contains("/definitely/not/here.toml"));
}

#[test]
fn the_solver_is_a_table_or_its_kind_alone() {
    let table = parse(&format!("[solver]\nkind = \"reference\"\nimplicit_iterations = 8\n{MINIMAL}")).unwrap();
    assert_eq!(table.solver(), Solver { kind: SolverChoice::Reference, implicit_iterations: 8, ..Solver::default() });
    let short = parse(&format!("solver = \"explicit\"\n{MINIMAL}")).unwrap();
    assert_eq!(short.solver(), Solver { kind: SolverChoice::Explicit, implicit_iterations: 1, ..Solver::default() });
    for bad in ["solver = \"rk4\"\n", "[solver]\nkind = \"implicit\"\nsweeps = 3\n"] {
        assert!(matches!(parse(&format!("{bad}{MINIMAL}")), Err(SceneError::Parse { .. })), "{bad}");
    }
    match parse(&format!("[solver]\nimplicit_iterations = 0\n{MINIMAL}")) {
        Err(SceneError::Invalid { field, .. }) => assert_eq!(field, "solver.implicit_iterations"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn events_parse_in_file_order_and_are_validated() {
    let events = "[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.0]\n\
        [[events]]\nkind = \"teleport\"\nat_s = 0.5\npack = \"a\"\noffset_m = [0.1, 0.0, 0.0]\n\
        [[events]]\nkind = \"forces_off\"\nat_s = 1.0\neffects = [\"wind\"]\n\
        [[events]]\nkind = \"forces_on\"\nat_s = 2.0\n";
    let scene = parse(&format!("{MINIMAL}{events}")).unwrap();
    assert_eq!(
        scene.events(),
        vec![
            Event::Teleport { at_s: 0.5, pack: "a".into(), offset_m: [0.1, 0.0, 0.0] },
            Event::ForcesOff { at_s: 1.0, effects: vec![Effect::Wind] },
            Event::ForcesOn { at_s: 2.0, effects: vec![] },
        ]
    );
    let cases = [
        ("[[events]]\nkind = \"teleport\"\nat_s = 0.5\npack = \"b\"\noffset_m = [0.0, 0.0, 0.0]\n", "events[0].pack"),
        ("[[events]]\nkind = \"teleport\"\nat_s = -1.0\npack = \"a\"\noffset_m = [0.0, 0.0, 0.0]\n", "events[0].at_s"),
        (
            "[[events]]\nkind = \"teleport\"\nat_s = 1.0\npack = \"a\"\noffset_m = [nan, 0.0, 0.0]\n",
            "events[0].offset_m",
        ),
        ("[[events]]\nkind = \"forces_off\"\nat_s = 1.0\neffects = [\"gravity\"]\n", "events[0].effects"),
        (
            "[effects.parting]\n[[events]]\nkind = \"forces_off\"\nat_s = 1.0\neffects = [\"parting\"]\n",
            "events[0].effects",
        ),
    ];
    for (text, key) in cases {
        match parse(&format!("{MINIMAL}{text}")) {
            Err(SceneError::Invalid { field, .. }) => assert_eq!(field, key, "for {text:?}"),
            other => panic!("expected {key} to be rejected in {text:?}, got {other:?}"),
        }
    }
    assert!(matches!(
        parse(&format!("{MINIMAL}[[events]]\nkind = \"explode\"\nat_s = 1.0\n")),
        Err(SceneError::Parse { .. })
    ));
    match parse(&format!("duration_s = 0.0\n{MINIMAL}")) {
        Err(SceneError::Invalid { field, .. }) => assert_eq!(field, "duration_s"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn retired_keys_name_what_to_write_now() {
    let cases = [
        (format!("dt_s = 0.01\n{MINIMAL}"), "dt_s", "time_step_s"),
        (
            format!("{MINIMAL}[effects.gravity]\nacceleration_m_s2 = [0.0, -1.0, 0.0]\n"),
            "effects.gravity.acceleration_m_s2",
            "acceleration_m_per_s2",
        ),
        (
            format!("{MINIMAL}[effects.wind]\nvelocity_m_s = [1.0, 0.0, 0.0]\n"),
            "effects.wind.velocity_m_s",
            "velocity_m_per_s",
        ),
        (
            format!(
                "{MINIMAL}[[effects.wind_sources]]\nposition = [0.0, 0.0, 0.0]\npower = 1.0\n[[effects.wind_sources]]\nposition = [0.0, 0.0, 0.0]\npower = 1.0\npropagation_m_s = 3.0\n"
            ),
            "effects.wind_sources[1].propagation_m_s",
            "delayed_attenuation = true",
        ),
        (
            format!("{MINIMAL}[effects.wrong_side_guard]\nimpulse_m_s = 0.1\n"),
            "effects.wrong_side_guard.impulse_m_s",
            "impulse_m_per_s",
        ),
        (format!("forces_stop_s = 1.0\n{MINIMAL}"), "forces_stop_s", "forces_off"),
        // A whole furbake-sim scene (the retired `simulate PACK --scene` dialect).
        (
            "dt_s = 0.01\nduration_s = 1.0\n[forces]\ngravity_m_per_s2 = [0.0, -9.81, 0.0]\n".to_owned(),
            "dt_s",
            "runtime scene",
        ),
    ];
    for (text, key, hint) in &cases {
        match parse(text) {
            Err(e @ SceneError::Outdated { .. }) => {
                let SceneError::Outdated { field, what, .. } = &e else { unreachable!() };
                assert_eq!(field, key, "for {text:?}");
                assert!(what.contains(hint), "{e} should mention {hint}");
                assert!(!e.to_string().contains('\n'), "one line: {e}");
            }
            other => panic!("expected {key} to be reported as retired in {text:?}, got {other:?}"),
        }
    }
    assert_eq!(cases.len(), 7);
}

#[test]
fn a_scene_built_in_code_is_the_scene_its_file_reads_as_and_is_validated_the_same_way() {
    let text = "time_step_s = 0.01\n[[packs]]\nname = \"fox\"\npath = \"/abs/fox.fbk\"\n\
                animation = { clip = \"Walk\" }\n[effects.gravity]\n";
    let read = parse(text).unwrap();
    let mut fox = ScenePack::new("fox", "/abs/fox.fbk");
    fox.animation = Some(PackAnimation::new("Walk"));
    let built = Scene::builder(vec![fox])
        .time_step_s(0.01)
        .effects(Effects { gravity: Some(Gravity::default()), ..Effects::default() })
        .build()
        .unwrap();
    assert_eq!(built, read);

    // The builder refuses what the file reader refuses, naming the same dotted key.
    let invalid_field = |r: Result<Scene, SceneError>| match r {
        Err(SceneError::Invalid { field, .. }) => field,
        other => panic!("expected an invalid value, got {other:?}"),
    };
    let twice = Scene::builder(vec![ScenePack::new("a", "a.fbk"), ScenePack::new("a", "b.fbk")]).build();
    assert_eq!(invalid_field(twice), "packs[1].name");
    assert_eq!(invalid_field(Scene::builder(Vec::new()).build()), "packs");
    let shrunk = read.clone().into_builder().edit_pack("fox", |p| p.scale = 0.0).build();
    assert_eq!(invalid_field(shrunk), "packs[0].scale");
    let slow = read.clone().into_builder().time_step_s(f32::NAN).build();
    assert_eq!(invalid_field(slow), "time_step_s");
    let from_nowhere = read.into_builder().events(vec![Event::PlayClip {
        at_s: 1.0,
        pack: "cat".into(),
        clip: "Run".into(),
        fade_s: 0.2,
    }]);
    assert_eq!(invalid_field(from_nowhere.build()), "events[0].pack");
}

/// A host's settings without `[[packs]]` read into a builder (the C interface's world settings):
/// errors keep the text's own lines and name the key; packs added afterwards make a valid scene.
#[test]
fn settings_without_packs_read_into_a_builder() {
    use furbake_runtime::SceneBuilder;
    let name = Path::new("game/fur.toml");
    let text = "time_step_s = 0.01\n[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [2.0, 0.0, 0.0]\n";
    let builder = SceneBuilder::from_toml_str(text, name).unwrap();
    assert!(builder.packs().is_empty());
    let scene = builder.pack(ScenePack::new("fox", "fox.fbk")).build().unwrap();
    assert_eq!(scene.time_step_s(), 0.01);
    assert_eq!(scene.effects().wind.unwrap().velocity_m_per_s, [2.0, 0.0, 0.0]);
    let bad = "time_step_s = 0.01\n[effects.wind]\nvelocity_m_per_s = \"east\"\n";
    let message = SceneBuilder::from_toml_str(bad, name).unwrap_err().to_string();
    assert!(message.contains("game/fur.toml") && message.contains("effects.wind.velocity_m_per_s"), "{message}");
    assert!(message.contains("line 3"), "the text's own line: {message}");
    // Without packs the builder refuses to build; a text with packs keeps them.
    assert!(SceneBuilder::from_toml_str(text, name).unwrap().build().is_err());
    let with = format!("{text}[[packs]]\nname = \"a\"\npath = \"a.fbk\"\n");
    assert_eq!(SceneBuilder::from_toml_str(&with, name).unwrap().packs().len(), 1);
}
