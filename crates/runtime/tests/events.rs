//! What the one scene format took over from the retired furbake-sim scene runner: timed events
//! (teleports, forces switched off and on), the reference solver and the implicit iteration
//! count, per-step statistics, and a pack's state in world space.

use std::path::Path;

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_runtime::{Effect, Scene, World, WorldOptions};
use furbake_sim::{SolverKind, TopologyKind};
use glam::{Mat4, Vec3};

/// A furry sphere (radius 0.5 m) with a prisms topology, baked into `dir/ball.fbk`.
fn ball(dir: &Path) {
    let imported =
        import_gltf_slice(&testmesh::uv_sphere(6, 8, 0.5).gltf, "ball.gltf", None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    (settings.volume.resolution, settings.volume.layers) = (16, 4);
    settings.topologies = vec!["prisms".into()];
    let baked = bake(&imported, "ball.gltf", &settings.plan().unwrap(), &mut NoProgress).unwrap();
    baked.to_writer().write_atomic(&dir.join("ball.fbk")).unwrap();
}

fn world(dir: &Path, body: &str, options: WorldOptions) -> World {
    let text = format!("time_step_s = 0.01\n[[packs]]\nname = \"ball\"\npath = \"ball.fbk\"\n{body}");
    World::with_options(Scene::from_toml_str(&text, Path::new("t.toml"), dir).unwrap(), options).unwrap()
}

/// Mean deviation of the scale vectors from the first world's rest pose.
fn mean_lean(world: &World, rest: &[[f32; 3]]) -> Vec3 {
    let s = world.fur(0).unwrap().scale_vectors;
    s.iter().zip(rest).map(|(a, b)| Vec3::from(*a) - Vec3::from(*b)).sum::<Vec3>() / s.len() as f32
}

#[test]
fn a_teleport_moves_the_pack_and_leaves_its_fur_behind() {
    let dir = tempfile::tempdir().unwrap();
    ball(dir.path());
    let events = "[effects.wrong_side_guard]\n[[events]]\nkind = \"teleport\"\nat_s = 0.05\npack = \"ball\"\n\
                  offset_m = [0.01, 0.0, 0.0]\n";
    let mut w = world(dir.path(), events, WorldOptions { step_statistics: true, ..WorldOptions::default() });
    let rest = w.fur(0).unwrap().scale_vectors.to_vec();
    for _ in 0..5 {
        w.step().unwrap();
    }
    assert_eq!(w.model_matrix(0), Mat4::IDENTITY, "not yet teleported at {} s", w.time_s());
    assert!(mean_lean(&w, &rest).length() < 1e-6, "fur at rest before the jump");
    let budget_before = w.fur(0).unwrap().last_step.energy_budget_j;
    w.step().unwrap();
    assert_eq!(w.model_matrix(0).transform_point3(Vec3::ZERO), Vec3::new(0.01, 0.0, 0.0));
    let lean = mean_lean(&w, &rest);
    assert!(lean.x < -0.01, "the free masses stayed behind in the world: mean Δs = {lean}");
    let step = w.fur(0).unwrap().last_step;
    assert!(
        step.energy_budget_j > budget_before,
        "the jump's energy is booked: {budget_before} → {}",
        step.energy_budget_j
    );
    for _ in 0..200 {
        w.step().unwrap();
    }
    let settled = mean_lean(&w, &rest);
    assert!(settled.length() < lean.length() * 0.5, "the springs pull the fur back: {lean} → {settled}");
}

#[test]
fn forces_off_stops_gravity_and_the_fur_recovers() {
    let dir = tempfile::tempdir().unwrap();
    ball(dir.path());
    let gravity = "[effects.gravity]\nacceleration_m_per_s2 = [9.81, 0.0, 0.0]\n";
    let off = format!("{gravity}[[events]]\nkind = \"forces_off\"\nat_s = 0.3\neffects = [\"gravity\"]\n");
    let mut on_world = world(dir.path(), gravity, WorldOptions::default());
    let mut off_world = world(dir.path(), &off, WorldOptions::default());
    let rest = on_world.fur(0).unwrap().scale_vectors.to_vec();
    let mut at_switch = Vec3::ZERO;
    for step in 0..150 {
        on_world.step().unwrap();
        off_world.step().unwrap();
        if step == 29 {
            at_switch = mean_lean(&off_world, &rest);
            assert_eq!(at_switch, mean_lean(&on_world, &rest), "identical until the event");
            assert!(off_world.force_is_on(Effect::Gravity));
        }
    }
    assert!(!off_world.force_is_on(Effect::Gravity) && on_world.force_is_on(Effect::Gravity));
    let (on, off) = (mean_lean(&on_world, &rest), mean_lean(&off_world, &rest));
    assert!(at_switch.x > 0.01, "gravity along +x leans the fur: {at_switch}");
    assert!(on.x > 0.01, "with gravity on it keeps leaning: {on}");
    assert!(off.x < at_switch.x * 0.5, "with gravity off the fur recovers: {at_switch} → {off}");
}

#[test]
fn the_scene_picks_the_reference_solver_and_implicit_iterations() {
    let dir = tempfile::tempdir().unwrap();
    ball(dir.path());
    let mut checked = 0;
    for (solver, kind) in [
        ("[solver]\nkind = \"reference\"\n", SolverKind::Reference),
        ("[solver]\nkind = \"implicit\"\nimplicit_iterations = 4\n", SolverKind::Implicit),
    ] {
        let text =
            format!("time_step_s = 0.01\n{solver}[[packs]]\nname = \"ball\"\npath = \"ball.fbk\"\n[effects.gravity]\n");
        let scene = Scene::from_toml_str(&text, Path::new("t.toml"), dir.path()).unwrap();
        let mut w =
            World::with_options(scene, WorldOptions { step_statistics: true, ..WorldOptions::default() }).unwrap();
        for _ in 0..5 {
            w.step().unwrap();
        }
        let fur = w.fur(0).unwrap();
        assert_eq!(fur.simulation, Some((TopologyKind::PRISMS, kind)));
        assert!(fur.last_step.energy.total_j() > 0.0, "statistics are on");
        if kind == SolverKind::Reference {
            assert!(fur.last_step.cg_iterations > 0, "the reference solver iterates CG");
        }
        checked += 1;
    }
    assert_eq!(checked, 2);
    // Without statistics the energies are not computed.
    let mut w = world(dir.path(), "[effects.gravity]\n", WorldOptions::default());
    w.step().unwrap();
    assert_eq!(w.fur(0).unwrap().last_step.energy.total_j(), 0.0);
}

#[test]
fn pack_state_is_in_world_space() {
    // The ball slides along +x at 1 m/s, placed 2 m up and scaled ×2: the state reports world
    // metres, and every mass moves with the frame (no inertial force is declared).
    let dir = tempfile::tempdir().unwrap();
    ball(dir.path());
    let text = "time_step_s = 0.01\n[[packs]]\nname = \"ball\"\npath = \"ball.fbk\"\ntranslation = [0.0, 2.0, 0.0]\n\
                scale = 2.0\n[[packs.motion]]\ntime_s = 0.0\n[[packs.motion]]\ntime_s = 1.0\ntranslation = [1.0, 0.0, 0.0]\n\
                [effects.wrong_side_guard]\n";
    let mut w = World::new(Scene::from_toml_str(text, Path::new("t.toml"), dir.path()).unwrap()).unwrap();
    for _ in 0..50 {
        w.step().unwrap();
    }
    let state = w.pack_state(0).unwrap();
    let mesh = w.pack(0).skin_mesh().unwrap();
    assert_eq!(state.name, "ball");
    assert_eq!(state.topology.as_deref(), Some("prisms"));
    assert_eq!(state.skin_positions_m.len(), mesh.positions.len());
    let model = w.model_matrix(0);
    for (world_p, mesh_p) in state.skin_positions_m.iter().zip(&mesh.positions) {
        assert!((Vec3::from(*world_p) - model.transform_point3(Vec3::from(*mesh_p))).length() < 1e-5);
    }
    let centre = state.skin_positions_m.iter().map(|p| Vec3::from(*p)).sum::<Vec3>() / mesh.positions.len() as f32;
    assert!((centre - Vec3::new(0.5, 2.0, 0.0)).length() < 0.05, "centre {centre}");
    let topology = w.pack(0).spring_topology(TopologyKind::PRISMS).unwrap();
    assert_eq!(state.mass_positions_m.len(), topology.mass_kg.len());
    assert_eq!(state.mass_velocities_m_per_s.len(), topology.mass_kg.len());
    for v in &state.mass_velocities_m_per_s {
        assert!((Vec3::from(*v) - Vec3::X).length() < 0.05, "mass velocity {v:?} should be the frame's 1 m/s");
    }
    let radius = state.mass_positions_m.iter().map(|p| (Vec3::from(*p) - centre).length()).fold(0.0, f32::max);
    assert!(radius > 0.9 && radius < 1.3, "a 0.5 m ball scaled ×2 plus its fur: {radius} m");
    assert_eq!(state.scale_vectors.len(), mesh.positions.len());
    assert!(state.scale_vectors.iter().all(|s| (Vec3::from(*s).length() - 1.0).abs() < 1e-4));
}

#[test]
fn entries_naming_the_same_file_share_one_opened_pack() {
    let dir = tempfile::tempdir().unwrap();
    ball(dir.path());
    let mut text = String::from("time_step_s = 0.01\n");
    for i in 0..50 {
        text += &format!("[[packs]]\nname = \"ball{i}\"\npath = \"ball.fbk\"\ntranslation = [{i}.0, 0.0, 0.0]\n");
    }
    text += "[effects.gravity]\n";
    let mut w = World::new(Scene::from_toml_str(&text, Path::new("t.toml"), dir.path()).unwrap()).unwrap();
    w.step().unwrap();
    assert!((1..50).all(|i| std::sync::Arc::ptr_eq(w.pack(0), w.pack(i))), "one opened pack for one file");
    // Its skin mesh and topology were read once for all fifty entries.
    let reads: u32 = w.pack(0).read_counts().iter().map(|&(_, n)| n).sum();
    assert_eq!(reads, 2, "{:?}", w.pack(0).read_counts());
    // Each entry still simulates on its own.
    assert_eq!(w.stage_stats().iter().filter(|s| s.name == "fur_solver").count(), 50);
}
