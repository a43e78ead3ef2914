//! The world runs only what a scene asks for (docs/design.md "Runtime: scenes and stages", the user's ask 3): stages of
//! undeclared effects are never built and never run, sections only they need are never read, the
//! topology follows `parting`, the solver follows the topology, forces act the way their effect
//! says, and results are bit-identical on 1 and 4 threads.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use furbake_bake::{BakeSettings, BladeSettings, NoProgress, bake};
use furbake_formats::SectionKind;
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_runtime::{Pack, RuntimeError, Scene, ShellVertexLayout, StageKind, World, WorldOptions, WorldPlan};
use furbake_sim::{SolverKind, TopologyKind};

/// Bakes `gltf` into `dir/name` with `topologies` and, when `blades`, a small blade field.
fn bake_pack(dir: &Path, name: &str, gltf: &[u8], topologies: &[&str], blades: Option<BladeSettings>) -> PathBuf {
    let imported = import_gltf_slice(gltf, "mesh.gltf", None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    settings.volume.resolution = 16;
    settings.volume.layers = 4;
    settings.topologies = topologies.iter().map(|t| t.to_string()).collect();
    settings.blades = blades;
    let path = dir.join(name);
    bake(&imported, "mesh.gltf", &settings.plan().unwrap(), &mut NoProgress)
        .unwrap()
        .to_writer()
        .write_atomic(&path)
        .unwrap();
    path
}

/// The thesis's grass patch (13 vertices, 16 triangles, 2 m wide), with a small blade field in
/// 0.5 m clusters when `blades`.
fn patch_pack(dir: &Path, topologies: &[&str], blades: bool) -> PathBuf {
    let blades = blades.then(|| {
        let mut b = BladeSettings::default();
        b.field.density_per_m2 = 20.0;
        b.field.cluster_size_m = 0.5;
        b.keyframes.grid.poses = 40;
        b
    });
    bake_pack(dir, "patch.fbk", &testmesh::grass_patch(2.0).gltf, topologies, blades)
}

fn sphere_pack(dir: &Path, topologies: &[&str]) -> PathBuf {
    bake_pack(dir, "sphere.fbk", &testmesh::uv_sphere(6, 8, 0.5).gltf, topologies, None)
}

fn scene(dir: &Path, pack: &Path, effects: &str) -> Scene {
    let text = format!(
        "time_step_s = 0.02\n[[packs]]\nname = \"p\"\npath = {:?}\n{effects}",
        pack.file_name().unwrap().to_str().unwrap()
    );
    Scene::from_toml_str(&text, Path::new("test.toml"), dir).unwrap()
}

/// Opens the scene's packs ourselves so their read counters can be checked afterwards.
fn world_with_packs(scene: Scene) -> (World, Vec<Arc<Pack>>) {
    let packs: Vec<Arc<Pack>> = scene.packs().iter().map(|p| Arc::new(Pack::open(&p.path).unwrap())).collect();
    (World::with_packs(scene, packs.clone(), WorldOptions::default()).unwrap(), packs)
}

fn stage_names(world: &World) -> Vec<&'static str> {
    world.stages().iter().map(|s| s.kind.name()).collect()
}

fn reads_of(pack: &Pack, kind: SectionKind) -> Vec<u32> {
    pack.read_counts().into_iter().filter(|&(k, _)| k == kind).map(|(_, n)| n).collect()
}

#[test]
fn a_gravity_only_scene_never_builds_or_runs_wind_or_grass_stages() {
    let dir = tempfile::tempdir().unwrap();
    let pack = patch_pack(dir.path(), &["separable-prisms", "prisms", "sticks"], true);
    let (mut world, packs) = world_with_packs(scene(dir.path(), &pack, "[effects.gravity]\n"));
    assert_eq!(stage_names(&world), ["fur_gravity", "fur_solver", "fur_scale_vectors"]);
    for kind in [StageKind::FurWind, StageKind::GrassForces, StageKind::FurObjectMotion, StageKind::FurInteraction] {
        assert!(!world.has_stage(kind), "{kind} was built");
    }
    assert!(world.grass(0).is_none(), "no grass stage, no force field");
    for _ in 0..25 {
        world.step().unwrap();
    }
    let stats = world.stage_stats();
    assert_eq!(stats.len(), 3);
    for s in &stats {
        assert_eq!((s.runs, s.pack.as_str()), (25, "p"), "{s:?}");
        assert!(s.total > std::time::Duration::ZERO, "{s:?}");
        assert!(!["fur_wind", "grass_forces"].contains(&s.name));
    }
    // Sections: the skin mesh and exactly one topology (prisms, the preferred non-separable
    // kind, which sits second in the table) — no blade field, no keyframes, no atlas.
    let p = &packs[0];
    assert_eq!(p.kinds_read(), vec![SectionKind::SKIN_MESH, SectionKind::SPRING_TOPOLOGY]);
    assert_eq!(reads_of(p, SectionKind::SPRING_TOPOLOGY), vec![0, 1, 0], "only the prisms section is read");
    for kind in [SectionKind::BLADE_FIELD, SectionKind::KEYFRAME_TABLE, SectionKind::SHELL_ATLAS] {
        assert!(p.has(kind), "the pack holds {kind}");
        assert_eq!(reads_of(p, kind), vec![0], "{kind} must stay unread");
    }
    assert!(p.peeked_bytes() > 0 && p.peeked_bytes() <= 3 * 12, "{} bytes peeked", p.peeked_bytes());
    let fur = world.fur(0).unwrap();
    assert_eq!(fur.simulation, Some((TopologyKind::PRISMS, SolverKind::Implicit)));
    assert_eq!(fur.layout, ShellVertexLayout::PerVertex);
    assert_eq!(fur.scale_vectors.len(), 13);
    assert!(fur.scale_vectors.iter().all(|s| (glam::Vec3::from(*s).length() - 1.0).abs() < 1e-4));
}

#[test]
fn wind_builds_the_fur_wind_and_grass_stages_but_never_reads_keyframes() {
    let dir = tempfile::tempdir().unwrap();
    let pack = patch_pack(dir.path(), &["prisms"], true);
    let effects = "[effects.wind]\nvelocity_m_per_s = [3.0, 0.0, 0.0]\n\
                   [[effects.wind_sources]]\nposition = [-2.0, 0.0, 0.0]\npower = 1.0\n";
    let (mut world, packs) = world_with_packs(scene(dir.path(), &pack, effects));
    assert_eq!(stage_names(&world), ["fur_wind", "fur_solver", "fur_scale_vectors", "grass_forces"]);
    for _ in 0..30 {
        world.step().unwrap();
    }
    assert!(world.stage_stats().iter().all(|s| s.runs == 30));
    let grass = world.grass(0).unwrap();
    assert_eq!(grass.corner_forces.len(), grass.grid.corners());
    // Wind along +x (and a source to the −x side): every corner is pushed towards +x.
    assert!(grass.corner_forces.iter().all(|f| f[0] > 2.9 && f[1].abs() < 1.0), "{:?}", grass.corner_forces);
    // The fur leans downwind: every furry vertex's scale vector gains +x.
    let fur = world.fur(0).unwrap();
    let leaning = fur.scale_vectors.iter().filter(|s| s[0] > 1e-4).count();
    assert_eq!(leaning, 13, "{:?}", fur.scale_vectors);
    let p = &packs[0];
    assert_eq!(reads_of(p, SectionKind::BLADE_FIELD), vec![1]);
    assert_eq!(reads_of(p, SectionKind::KEYFRAME_TABLE), vec![0], "keyframes are the renderer's business");
}

#[test]
fn a_point_wind_source_alone_moves_fur_and_grass_away_from_it() {
    let dir = tempfile::tempdir().unwrap();
    let pack = patch_pack(dir.path(), &["prisms"], true);
    // Eq. 4.1 at the origin: ω / |WP|^σ = 9 / 3² = 1 (m/s of wind) along +z.
    let effects = "[[effects.wind_sources]]\nposition = [0.0, 0.0, -3.0]\npower = 9.0\n";
    let (mut world, _packs) = world_with_packs(scene(dir.path(), &pack, effects));
    assert_eq!(stage_names(&world), ["fur_wind", "fur_solver", "fur_scale_vectors", "grass_forces"]);
    assert_eq!(world.stages()[0].effects, [furbake_runtime::Effect::WindSources]);
    for _ in 0..20 {
        world.step().unwrap();
    }
    let fur = world.fur(0).unwrap();
    assert!(fur.scale_vectors.iter().all(|s| s[2] > 1e-4 && s[0].abs() < 1e-3), "{:?}", fur.scale_vectors);
    let grass = world.grass(0).unwrap();
    let pushed = grass.corner_forces.iter().filter(|f| f[1] > 0.3).count();
    assert_eq!(pushed, grass.corner_forces.len(), "{:?}", grass.corner_forces);
}

#[test]
fn a_grass_pack_without_topology_gets_grass_forces_and_static_shells() {
    let dir = tempfile::tempdir().unwrap();
    let pack = patch_pack(dir.path(), &[], true);
    let effects = "[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.0]\n";
    let (mut world, packs) = world_with_packs(scene(dir.path(), &pack, effects));
    assert_eq!(stage_names(&world), ["grass_forces"]);
    world.step().unwrap();
    assert_eq!(world.fur(0).unwrap().simulation, None);
    assert_eq!(world.fur(0).unwrap().scale_vectors, packs[0].skin_mesh().unwrap().normals.as_slice());
    assert!(world.grass(0).unwrap().corner_forces.iter().all(|f| f[0] == 1.0 && f[1] == 0.0));
}

#[test]
fn a_scene_without_effects_has_no_stage_and_keeps_fur_at_rest() {
    let dir = tempfile::tempdir().unwrap();
    let pack = patch_pack(dir.path(), &["prisms"], true);
    let (mut world, packs) = world_with_packs(scene(dir.path(), &pack, ""));
    assert!(world.stages().is_empty());
    for _ in 0..5 {
        world.step().unwrap();
    }
    assert!(world.stage_stats().is_empty());
    assert_eq!(world.time_s(), 5.0 * 0.02f32 as f64);
    let fur = world.fur(0).unwrap();
    assert_eq!(fur.simulation, None);
    let mesh = packs[0].skin_mesh().unwrap();
    assert_eq!(fur.scale_vectors, mesh.normals.as_slice(), "s = n at rest");
    assert_eq!(packs[0].kinds_read(), vec![SectionKind::SKIN_MESH], "no topology, no blades");
    assert_eq!(packs[0].peeked_bytes(), 0);
}

#[test]
fn parting_uses_a_separable_topology_and_its_absence_is_a_typed_error() {
    let dir = tempfile::tempdir().unwrap();
    let pack = patch_pack(dir.path(), &["prisms", "separable-spring-sticks", "separable-sticks"], false);
    let (mut world, packs) = world_with_packs(scene(dir.path(), &pack, "[effects.gravity]\n[effects.parting]\n"));
    world.step().unwrap();
    let fur = world.fur(0).unwrap();
    assert_eq!(fur.simulation, Some((TopologyKind::SEPARABLE_SPRING_STICKS, SolverKind::Implicit)));
    assert_eq!(fur.layout, ShellVertexLayout::PerCorner);
    assert_eq!(fur.scale_vectors.len(), 3 * 16, "one per triangle corner");
    assert_eq!(reads_of(&packs[0], SectionKind::SPRING_TOPOLOGY), vec![0, 1, 0]);

    // Without parting the same pack simulates prisms and never decodes a separable section.
    let (_world, packs) = world_with_packs(scene(dir.path(), &pack, "[effects.gravity]\n"));
    assert_eq!(reads_of(&packs[0], SectionKind::SPRING_TOPOLOGY), vec![1, 0, 0]);

    // A pack with only non-separable kinds cannot part; one with none cannot move at all.
    let mut checked = 0;
    for (topologies, effects, needs) in [
        (&["prisms"][..], "[effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.0]\n[effects.parting]\n", "separable"),
        (&[][..], "[effects.wrong_side_guard]\n", "non-separable"),
    ] {
        let sub = dir.path().join(format!("case{checked}"));
        std::fs::create_dir(&sub).unwrap();
        let pack = patch_pack(&sub, topologies, false);
        match World::new(scene(&sub, &pack, effects)) {
            Err(e @ RuntimeError::MissingTopology { .. }) => {
                let msg = e.to_string();
                assert!(msg.contains(&pack.display().to_string()), "names the file: {msg}");
                assert!(msg.contains(&format!("a {needs} spring topology")), "{msg}");
                assert!(msg.contains("--topology"), "says how to fix it: {msg}");
            }
            other => panic!("expected MissingTopology, got {other:?}"),
        }
        checked += 1;
    }
    assert_eq!(checked, 2);
}

#[test]
fn the_solver_follows_the_topology_unless_the_scene_overrides_it() {
    let dir = tempfile::tempdir().unwrap();
    patch_pack(dir.path(), &["sticks"], false);
    let mut checked = 0;
    for (solver, expected) in [
        ("", SolverKind::Stick),
        ("solver = \"explicit\"\n", SolverKind::Explicit),
        ("solver = \"implicit\"\n", SolverKind::Implicit),
    ] {
        let text =
            format!("{solver}time_step_s = 0.02\n[[packs]]\nname = \"p\"\npath = \"patch.fbk\"\n[effects.gravity]\n");
        let mut world = World::new(Scene::from_toml_str(&text, Path::new("t.toml"), dir.path()).unwrap()).unwrap();
        world.step().unwrap();
        let fur = world.fur(0).unwrap();
        assert_eq!(fur.simulation, Some((TopologyKind::STICKS, expected)));
        assert!(fur.scale_vectors.iter().flatten().all(|c| c.is_finite()));
        checked += 1;
    }
    assert_eq!(checked, 3);
}

#[test]
fn object_motion_makes_fur_lag_behind_the_acceleration() {
    // The pack accelerates towards +x at the first key: in its frame an inertial force pushes
    // the fur towards −x, so the scale vectors lean −x on average; a static copy does not lean.
    let dir = tempfile::tempdir().unwrap();
    sphere_pack(dir.path(), &["prisms"]);
    let lean = |motion: &str| {
        let text = format!(
            "time_step_s = 0.01\n[[packs]]\nname = \"p\"\npath = \"sphere.fbk\"\n{motion}\
             [effects.object_motion]\n[effects.wrong_side_guard]\n"
        );
        let mut world = World::new(Scene::from_toml_str(&text, Path::new("t.toml"), dir.path()).unwrap()).unwrap();
        let moving = world.has_stage(StageKind::FurObjectMotion);
        let rest: Vec<[f32; 3]> = world.fur(0).unwrap().scale_vectors.to_vec();
        for _ in 0..3 {
            world.step().unwrap();
        }
        let fur = world.fur(0).unwrap();
        let n = fur.scale_vectors.len() as f32;
        let mean_dx: f32 = fur.scale_vectors.iter().zip(&rest).map(|(s, r)| s[0] - r[0]).sum::<f32>() / n;
        (moving, mean_dx)
    };
    let (moving, dx) =
        lean("[[packs.motion]]\ntime_s = 0.0\n[[packs.motion]]\ntime_s = 0.1\ntranslation = [0.2, 0.0, 0.0]\n");
    assert!(moving, "a pack with motion keys gets the object-motion stage");
    assert!(dx < -0.01, "fur lags behind a +x acceleration: mean Δs.x = {dx}");
    let (moving, dx) = lean("");
    assert!(!moving, "a static pack gets no object-motion stage");
    assert!(dx.abs() < 1e-6, "static fur under the guard alone stays put: {dx}");
}

#[test]
fn topology_kinds_are_peeked_without_reading_sections() {
    let dir = tempfile::tempdir().unwrap();
    let order = ["chain", "separable-prisms", "spring-sticks"];
    let pack = Pack::open(patch_pack(dir.path(), &order, false)).unwrap();
    let kinds: Vec<String> = pack.topology_kinds().unwrap().into_iter().map(|(_, k)| k.to_string()).collect();
    assert_eq!(kinds, order);
    assert!(pack.kinds_read().is_empty(), "peeking is not reading");
    let t = pack.spring_topology(TopologyKind::SEPARABLE_PRISMS).unwrap();
    assert_eq!(t.mass_kg.len(), 96);
    assert_eq!(reads_of(&pack, SectionKind::SPRING_TOPOLOGY), vec![0, 1, 0]);
    match pack.spring_topology(TopologyKind::PRISMS) {
        Err(furbake_formats::FormatError::MissingSection { kind, .. }) => {
            assert_eq!(kind, SectionKind::SPRING_TOPOLOGY)
        }
        other => panic!("expected MissingSection, got {other:?}"),
    }
}

#[test]
fn results_are_bit_identical_on_one_and_four_threads() {
    // Sizes above the parallel thresholds of furbake-sim (4,096 free masses) and of the grass
    // force field (16,384 corners), so 4 threads really split the work.
    let dir = tempfile::tempdir().unwrap();
    bake_pack(dir.path(), "ball.fbk", &testmesh::uv_sphere(64, 72, 0.5).gltf, &["prisms"], None);
    let lawn_blades = BladeSettings {
        field: furbake_grass::BladeFieldSettings { density_per_m2: 20.0, cluster_size_m: 0.015, ..Default::default() },
        keyframes: furbake_grass::KeyframeSettings {
            grid: furbake_grass::PoseGridSettings { poses: 40, ..Default::default() },
            ..Default::default()
        },
    };
    bake_pack(dir.path(), "lawn.fbk", &testmesh::grass_patch(2.0).gltf, &["prisms"], Some(lawn_blades));
    let text = r#"
time_step_s = 0.02
[[packs]]
name = "ball"
path = "ball.fbk"
rotation_deg = [0.0, 20.0, 0.0]
[[packs.motion]]
time_s = 0.0
[[packs.motion]]
time_s = 0.1
translation = [0.3, 0.0, 0.1]
rotation_deg = [0.0, 40.0, 10.0]
[[packs]]
name = "lawn"
path = "lawn.fbk"
rotation_deg = [0.0, 30.0, 0.0]
[effects.gravity]
[effects.wind]
velocity_m_per_s = [1.5, 0.0, 0.5]
gust_amplitude = 0.5
[[effects.wind_sources]]
position = [-1.0, 0.2, 0.0]
power = 2.0
[[effects.wind_sources]]
position = [1.0, 0.2, 1.0]
power = 1.0
delayed_attenuation = true
[effects.object_motion]
[effects.interaction]
position = [0.4, 0.2, 0.0]
radius_m = 0.3
strength_n = 0.001
[[effects.collisions]]
shape = "sphere"
center = [0.5, 0.0, 0.5]
radius_m = 0.3
[[effects.windless_areas]]
min = [-1.0, -1.0, 0.5]
max = [-0.5, 1.0, 1.0]
[effects.wrong_side_guard]
"#;
    let bits = |v: &[[f32; 3]]| v.iter().flatten().map(|c| c.to_bits()).collect::<Vec<u32>>();
    let run = |threads: usize, steps: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let scene = Scene::from_toml_str(text, Path::new("t.toml"), dir.path()).unwrap();
            let mut world = World::new(scene).unwrap();
            // The ball: all 6 fur stages (it moves); the lawn: 5 (it does not) and grass_forces.
            assert_eq!(world.stages().len(), 12, "{:?}", world.stages());
            for _ in 0..steps {
                world.step().unwrap();
            }
            let ball = bits(world.fur(0).unwrap().scale_vectors);
            let lawn = bits(world.fur(1).unwrap().scale_vectors);
            let grass: Vec<u32> = world.grass(1).unwrap().corner_forces.iter().flatten().map(|c| c.to_bits()).collect();
            (ball, lawn, grass)
        })
    };
    let one = run(1, 8);
    let four = run(4, 8);
    assert!(one.0.len() >= 3 * 4096, "{} ball vertices", one.0.len() / 3);
    assert!(one.2.len() >= 2 * 16_384, "{} grass corners", one.2.len() / 2);
    assert!(one.0 == four.0, "ball scale vectors differ between 1 and 4 threads");
    assert!(one.1 == four.1, "lawn scale vectors differ between 1 and 4 threads");
    assert!(one.2 == four.2, "corner forces differ between 1 and 4 threads");
    // The run did something: the fur left its rest pose and the grass is pushed.
    let rest = run(1, 0);
    assert!(one.0 != rest.0 && one.1 != rest.1);
    assert!(one.2.iter().any(|&b| f32::from_bits(b) != 0.0));
}

#[test]
fn each_effect_alone_plans_exactly_its_stages() {
    use furbake_runtime::stages::{PackRole, plan_stages};
    let fur_and_grass = PackRole { fur: true, grass: true, moving: true, topology: true, animated: false };
    let base = "[[packs]]\nname = \"p\"\npath = \"p.fbk\"\n";
    let solver = ["fur_solver", "fur_scale_vectors"];
    let cases: [(&str, &[&str]); 10] = [
        ("", &[]),
        ("[effects.gravity]\n", &["fur_gravity", solver[0], solver[1]]),
        ("[effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.0]\n", &["fur_wind", solver[0], solver[1], "grass_forces"]),
        (
            "[[effects.wind_sources]]\nposition = [0.0, 0.0, 0.0]\npower = 1.0\n",
            &["fur_wind", solver[0], solver[1], "grass_forces"],
        ),
        ("[effects.object_motion]\n", &["fur_object_motion", solver[0], solver[1]]),
        ("[effects.interaction]\nradius_m = 1.0\nstrength_n = 1.0\n", &["fur_interaction", solver[0], solver[1]]),
        ("[[effects.collisions]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius_m = 1.0\n", &["grass_forces"]),
        ("[[effects.windless_areas]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\n", &["grass_forces"]),
        ("[effects.parting]\n", &[]),
        ("[effects.wrong_side_guard]\n", &solver),
    ];
    for (effects, expected) in &cases {
        let scene = Scene::from_toml_str(&format!("{base}{effects}"), Path::new("t.toml"), Path::new("/")).unwrap();
        let plan = plan_stages(scene.effects(), &[fur_and_grass]);
        let names: Vec<&str> = plan.iter().map(|s| s.kind.name()).collect();
        assert_eq!(&names, expected, "for {effects:?}");
        // Every stage serves only declared effects.
        let declared = scene.effects().enabled();
        assert!(plan.iter().flat_map(|s| &s.effects).all(|e| declared.contains(e)), "{effects:?}: {plan:?}");
    }
    // A static pack gets no object-motion stage; a pack without fur or blades gets nothing.
    let motion =
        Scene::from_toml_str(&format!("{base}[effects.object_motion]\n"), Path::new("t"), Path::new("/")).unwrap();
    assert!(plan_stages(motion.effects(), &[PackRole { moving: false, ..fur_and_grass }]).is_empty());
    let all = Scene::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/runtime_everything.toml"))
        .unwrap();
    assert!(plan_stages(all.effects(), &[PackRole::default()]).is_empty());
    assert_eq!(plan_stages(all.effects(), &[fur_and_grass]).len(), 7, "every stage kind once");
}

#[test]
fn a_lying_topology_head_is_a_typed_error_not_a_panic() {
    // The peek trusts nothing it reads: an array count that puts the metadata past the section's
    // end must fail with an error naming the file, before any allocation.
    let dir = tempfile::tempdir().unwrap();
    let path = patch_pack(dir.path(), &["prisms"], false);
    let mut bytes = std::fs::read(&path).unwrap();
    let probe = furbake_formats::Pack::from_bytes(&bytes).unwrap();
    let entry = probe.sections()[probe.find(SectionKind::SPRING_TOPOLOGY).next().unwrap()];
    let mut checked = 0;
    for (at, value) in [(4usize, u32::MAX), (4, 1 << 20), (0, 2)] {
        let mut damaged = bytes.clone();
        let o = entry.offset as usize + at;
        damaged[o..o + 4].copy_from_slice(&value.to_le_bytes());
        let bad = dir.path().join("lying.fbk");
        std::fs::write(&bad, &damaged).unwrap();
        let pack = Pack::open(&bad).unwrap();
        match pack.topology_kinds() {
            Err(e) => assert!(e.to_string().contains("lying.fbk"), "{e}"),
            other => panic!("head ({at}, {value}): expected a format error, got {other:?}"),
        }
        let err = World::new(scene(dir.path(), &bad, "[effects.gravity]\n")).unwrap_err();
        assert!(err.to_string().contains("lying.fbk"), "{err}");
        checked += 1;
    }
    assert_eq!(checked, 3);
    // An intact head over a corrupt payload peeks fine; the checksum catches it on decode.
    let last = entry.offset as usize + entry.length as usize - 1;
    bytes[last] ^= 0x5a;
    std::fs::write(dir.path().join("corrupt.fbk"), &bytes).unwrap();
    let pack = Pack::open(dir.path().join("corrupt.fbk")).unwrap();
    assert_eq!(pack.topology_kinds().unwrap().len(), 1);
    assert!(matches!(pack.spring_topology(TopologyKind::PRISMS), Err(e) if e.is_bad_file()));
}

#[test]
fn a_step_of_a_large_topology_under_absurd_gravity_is_refused_not_run_for_seconds() {
    // Cause: the solvers may split a step into up to 10,000 substeps whatever the topology's
    // size, so a scene with a gravity of 1e9 m/s² on the Fox's separable prisms (3,456 masses)
    // ran 2 s per three steps in a release build (found by furbake-fuzz, scenes seed 1 case
    // 2876). The world now gives each pack at most MAX_MASS_UPDATES_PER_STEP mass updates.
    let dir = tempfile::tempdir().unwrap();
    let pack = bake_pack(dir.path(), "ball.fbk", &testmesh::uv_sphere(40, 40, 0.5).gltf, &["prisms"], None);
    let masses = Pack::open(&pack).unwrap().spring_topology(TopologyKind::PRISMS).unwrap().mass_kg.len();
    let allowed = furbake_runtime::MAX_MASS_UPDATES_PER_STEP / masses as u64;
    assert!(allowed < 10_000, "{masses} masses must make the budget bind");
    let mut world =
        World::new(scene(dir.path(), &pack, "[effects.gravity]\nacceleration_m_per_s2 = [1e9, 0.0, 0.0]\n")).unwrap();
    let started = std::time::Instant::now();
    let err = world.step().expect_err("the step needs more substeps than the budget allows").to_string();
    assert!(err.contains(&format!("(allowed: {allowed})")), "{err}");
    assert!(started.elapsed().as_secs() < 10, "refused after {:?}", started.elapsed());
    // Ordinary gravity still steps.
    let mut world = World::new(scene(dir.path(), &pack, "[effects.gravity]\n")).unwrap();
    world.step().unwrap();
}

#[test]
fn a_world_plan_opens_each_file_once_reads_only_what_its_world_reads_and_counts_shared_sections_once() {
    // Two entries of one furry patch (simulated, with grass forces) and one of a sphere:
    // the plan is what the world runs, reads nothing the world would not, and counts the
    // patch's decoded sections for its first entry only.
    let dir = tempfile::tempdir().unwrap();
    let patch = patch_pack(dir.path(), &["prisms"], true);
    let sphere = sphere_pack(dir.path(), &["prisms"]);
    let text = format!(
        "time_step_s = 0.02\n\
         [[packs]]\nname = \"a\"\npath = {:?}\n\
         [[packs]]\nname = \"b\"\npath = {:?}\ntranslation = [3.0, 0.0, 0.0]\n\
         [[packs]]\nname = \"ball\"\npath = {:?}\n\
         [effects.wind]\nvelocity_m_per_s = [2.0, 0.0, 0.0]\n",
        patch.file_name().unwrap().to_str().unwrap(),
        patch.file_name().unwrap().to_str().unwrap(),
        sphere.file_name().unwrap().to_str().unwrap(),
    );
    let scene = Scene::from_toml_str(&text, Path::new("test.toml"), dir.path()).unwrap();
    let plan = WorldPlan::new(scene, WorldOptions::default()).unwrap();
    let packs = plan.packs().to_vec();
    assert!(Arc::ptr_eq(&packs[0], &packs[1]), "entries naming one file share one opened pack");
    assert!(!Arc::ptr_eq(&packs[0], &packs[2]));
    let planned = plan.stages().to_vec();
    let memory = plan.memory().to_vec();
    let reads_after_plan: Vec<_> = packs.iter().map(|p| p.read_counts()).collect();

    // What the plan read is what the world reads: building it reads nothing more.
    let world = plan.build().unwrap();
    assert_eq!(world.stages(), planned.as_slice());
    let reads_after_build: Vec<_> = packs.iter().map(|p| p.read_counts()).collect();
    assert_eq!(reads_after_plan, reads_after_build);
    assert_eq!(reads_of(&packs[0], SectionKind::KEYFRAME_TABLE), vec![0]);
    assert_eq!(reads_of(&packs[0], SectionKind::SHELL_ATLAS), vec![0]);

    // The entries' counts are the decoded sections' own.
    let mesh = packs[0].skin_mesh().unwrap();
    let topology = packs[0].spring_topology(TopologyKind::PRISMS).unwrap();
    for m in &memory[..2] {
        assert_eq!((m.vertices, m.triangles), (mesh.positions.len() as u64, mesh.triangles.len() as u64));
        assert_eq!(m.masses, topology.mass_kg.len() as u64);
        assert_eq!(m.state_vectors, 2 * m.masses + topology.shell_vertex_masses.len() as u64);
    }
    let ball = packs[2].spring_topology(TopologyKind::PRISMS).unwrap();
    assert_eq!(memory[2].masses, ball.mass_kg.len() as u64);
    // The patch's decoded sections are counted once, for entry `a`.
    let held: u64 = packs[0]
        .sections()
        .iter()
        .zip(packs[0].read_counts())
        .filter(|(_, (_, n))| *n > 0)
        .map(|(e, _)| e.length)
        .sum();
    assert_eq!(memory[0].bytes - memory[1].bytes, held);
}

/// Fur in a centimetre mesh placed at scale 0.01 moves as the same fur in metres does
/// (docs/design.md "Runtime: scenes and stages": forces, accelerations and speeds are brought
/// into the mesh's units): gravity bends it against the restoring force, and the guard pushes
/// back the hairs that fall past its angle, alike in both.
#[test]
fn fur_in_centimetres_moves_as_the_same_fur_in_metres() {
    let dir = tempfile::tempdir().unwrap();
    let metres = bake_pack(dir.path(), "m.fbk", &testmesh::uv_sphere(6, 8, 0.5).gltf, &["sticks"], None);
    let centimetres = bake_pack(dir.path(), "cm.fbk", &testmesh::uv_sphere(6, 8, 50.0).gltf, &["sticks"], None);
    // Sticks bend against the restoring force alone; a weak one lets gravity lay the fur down,
    // past the guard's angle below the equator.
    let effects = "[effects.gravity]\n[effects.wrong_side_guard]\nrestoring_weight_n = 0.0001\nmax_angle_deg = 45.0\n";
    let run = |pack: &Path, scale: f32| {
        let text = format!(
            "time_step_s = 0.02\n[[packs]]\nname = \"p\"\npath = {:?}\nscale = {scale}\n{effects}",
            pack.file_name().unwrap().to_str().unwrap()
        );
        let mut world = World::new(Scene::from_toml_str(&text, Path::new("units.toml"), dir.path()).unwrap()).unwrap();
        let rest = world.fur(0).unwrap().scale_vectors.to_vec();
        let mut triggers = 0;
        for _ in 0..25 {
            world.step().unwrap();
            triggers += world.fur(0).unwrap().last_step.guard_triggers;
        }
        (rest, world.fur(0).unwrap().scale_vectors.to_vec(), triggers)
    };
    let distance = |a: &[f32; 3], b: &[f32; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f32>().sqrt();
    let worst = |a: &[[f32; 3]], b: &[[f32; 3]]| a.iter().zip(b).map(|(p, q)| distance(p, q)).fold(0.0f32, f32::max);
    let (rest, m, m_triggers) = run(&metres, 1.0);
    let (_, cm, cm_triggers) = run(&centimetres, 0.01);
    assert!(worst(&rest, &m) > 0.3, "gravity bends the fur in metres: {}", worst(&rest, &m));
    assert!(m_triggers > 0, "the guard acts in metres");
    assert_eq!(cm_triggers, m_triggers, "the guard acts alike");
    assert!(worst(&m, &cm) < 1e-3, "centimetres and metres differ by {}", worst(&m, &cm));
}
