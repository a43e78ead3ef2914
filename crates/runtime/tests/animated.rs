//! Animated characters in a running [`World`] (the fur thesis's future work, §3.4.1): the bundled
//! Fox plays its clips, its anchored masses sit on the skinned surface, its fur lags behind the
//! moving legs, clip switches (with and without a cross-fade) and every solver stay stable, and a
//! scene that names a clip the pack lacks fails up front.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_formats::sections::spring_topology::NO_MASS;
use furbake_import::{ImportSettings, import_gltf};
use furbake_runtime::{RuntimeError, Scene, StageKind, World, WorldOptions};
use furbake_sim::TopologyKind;
use glam::Vec3;

/// The Fox (fixtures/real, CC-BY 4.0, licence beside it) baked once with three topologies.
fn fox_dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let fox = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
        let imported = import_gltf(&fox, &ImportSettings::default()).unwrap();
        let mut settings = BakeSettings::preset("fur").unwrap();
        (settings.volume.resolution, settings.volume.layers) = (16, 4);
        settings.topologies = vec!["prisms".into(), "separable-spring-sticks".into(), "sticks".into()];
        let baked = bake(&imported, "Fox.glb", &settings.plan().unwrap(), &mut NoProgress).unwrap();
        baked.to_writer().write_atomic(&dir.path().join("fox.fbk")).unwrap();
        dir
    })
    .path()
}

/// A scene of the Fox (modelled in centimetres, placed at scale 0.01): `body` follows its `[[packs]]` entry; a leading `solver = ...` line goes
/// above it, where top-level keys belong.
fn scene(body: &str) -> Scene {
    let (top, body) = match body.strip_prefix("solver") {
        Some(rest) => rest.split_once('\n').map_or((body, ""), |(line, tail)| (line, tail)),
        None => ("", body),
    };
    let top = if top.is_empty() { String::new() } else { format!("solver{top}\n") };
    let text = format!("time_step_s = 0.01\n{top}[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\nscale = 0.01\n{body}");
    Scene::from_toml_str(&text, Path::new("t.toml"), fox_dir()).unwrap()
}

fn world(body: &str) -> World {
    World::with_options(scene(body), WorldOptions { step_statistics: true, ..WorldOptions::default() }).unwrap()
}

fn diagonal(positions: &[[f32; 3]]) -> f32 {
    let lo = positions.iter().fold(Vec3::INFINITY, |a, &p| a.min(Vec3::from(p)));
    let hi = positions.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(Vec3::from(p)));
    lo.distance(hi)
}

/// Steps `w` `n` times, checking after each step: finite state, energy within its budget (the
/// moving skin's work is in the budget), and no scale vector more than the guard's angle from
/// its posed normal (no fur inside the surface). Returns the peak energy.
fn run_checked(w: &mut World, n: usize, what: &str) -> f64 {
    let mut peak = 0.0f64;
    for step in 0..n {
        w.step().unwrap_or_else(|e| panic!("{what}: step {step}: {e}"));
        let fur = w.fur(0).unwrap();
        let e = fur.last_step.energy.total_j();
        peak = peak.max(e);
        let eps = match fur.simulation.map(|s| s.1.name()) {
            Some("explicit" | "stick") => 0.67,
            _ => 0.05,
        };
        assert!(
            e <= fur.last_step.energy_budget_j + eps * peak + 1e-9,
            "{what}: step {step}: energy {e} J over budget"
        );
        let normals = w.animation(0).unwrap().normals();
        let mesh = w.pack(0).skin_mesh().unwrap();
        let corner_normal = |i: usize| match fur.layout {
            furbake_runtime::ShellVertexLayout::PerVertex => normals[i],
            furbake_runtime::ShellVertexLayout::PerCorner => normals[mesh.triangles[i / 3][i % 3] as usize],
        };
        for (i, s) in fur.scale_vectors.iter().enumerate() {
            let s = Vec3::from(*s);
            assert!(s.is_finite() && (s.length() - 1.0).abs() < 1e-3, "{what}: step {step}: scale vector {i} = {s}");
            // The guard's default angle is 80°: n·s ≥ cos 80° ≈ 0.17.
            let d = s.dot(Vec3::from(corner_normal(i)));
            assert!(d >= 0.17, "{what}: step {step}: scale vector {i} is {d} off its posed normal");
        }
    }
    peak
}

#[test]
fn the_walk_drives_the_anchored_masses_and_the_fur_lags_behind() {
    let mut w = world("[packs.animation]\nclip = \"Walk\"\n[effects.wrong_side_guard]\n");
    assert_eq!(w.stages()[0].kind, StageKind::Animation);
    assert!(w.has_stage(StageKind::FurSolver), "an animated skin moves its fur without any force");
    let bind = w.pack(0).skin_mesh().unwrap().positions.clone();
    let diag = diagonal(&bind);
    run_checked(&mut w, 50, "walk");
    let skin = w.fur(0).unwrap().skin_move;
    assert!(!skin.cut && skin.max_anchor_speed_m_per_s > 0.0, "a walk is no cut: {skin:?}");
    let anim = w.animation(0).unwrap();
    assert_eq!(anim.clip_name(anim.playback().clip), "Walk");
    assert!((anim.playback().time_s - 0.5).abs() < 1e-4, "clip time {}", anim.playback().time_s);

    // The skin: what pack_state reports is the skinned mesh, and the legs moved.
    let state = w.pack_state(0).unwrap();
    let model = w.model_matrix(0);
    let world = |p: Vec3| model.transform_point3(p);
    for (got, p) in state.skin_positions_m.iter().zip(anim.positions()) {
        assert!(Vec3::from(*got).distance(world(Vec3::from(*p))) < 1e-6, "pack_state reports the skinned skin");
    }
    let moved = bind.iter().zip(anim.positions()).map(|(a, b)| Vec3::from(*a).distance(Vec3::from(*b)));
    assert!(moved.fold(0.0, f32::max) > 0.05 * diag, "the walk moves the legs");

    // Every anchored mass sits where the skin's transform puts its rest position.
    let topo = w.pack(0).spring_topology(TopologyKind::PRISMS).unwrap();
    let mut anchors = 0;
    for (v, &[root, _]) in topo.shell_vertex_masses.iter().enumerate() {
        if root == NO_MASS || topo.mass_anchored[root as usize] == 0 {
            continue;
        }
        let t = anim.transforms()[v];
        let want = t.matrix.transform_point3(Vec3::from(topo.mass_rest_positions[root as usize]) + t.morph_offset_m);
        let got = Vec3::from(state.mass_positions_m[root as usize]);
        assert!(got.distance(world(want)) < 1e-6 * diag, "anchor {root}: {got} vs {}", world(want));
        anchors += 1;
    }
    assert!(anchors > 100, "{anchors} anchors checked");

    // The fur lags: some tip is well away from where the posed skin would hold it at rest.
    let mut lag = 0.0f32;
    for (v, &[_, tip]) in topo.shell_vertex_masses.iter().enumerate() {
        if tip == NO_MASS {
            continue;
        }
        let t = anim.transforms()[v];
        let rest = t.matrix.transform_point3(Vec3::from(topo.mass_rest_positions[tip as usize]) + t.morph_offset_m);
        lag = lag.max(world(rest).distance(Vec3::from(state.mass_positions_m[tip as usize])) / 0.01);
    }
    let fur_length = topo.params.fur_length_m;
    assert!(lag > 0.05 * fur_length, "the fur follows the legs with a lag: largest {lag} m of {fur_length} m fur");
}

/// The cut speed is in world metres per second: the Fox is modelled in centimetres, and at a scene
/// scale of 0.01 its walk (under 2 m/s at the feet) is no cut, while a 1 m/s cut speed is.
#[test]
fn the_cut_speed_is_in_world_units() {
    let at = |cut: f32| {
        let text = format!(
            "time_step_s = 0.01\n[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\nscale = 0.01\n\
             animation = {{ clip = \"Run\", cut_speed_m_per_s = {cut} }}\n"
        );
        let mut w = World::new(Scene::from_toml_str(&text, Path::new("t.toml"), fox_dir()).unwrap()).unwrap();
        let mut cuts = 0;
        for _ in 0..30 {
            w.step().unwrap();
            cuts += u32::from(w.fur(0).unwrap().skin_move.cut);
        }
        (cuts, w.fur(0).unwrap().skin_move.max_anchor_speed_m_per_s)
    };
    let (cuts, mesh_speed) = at(50.0);
    assert_eq!(cuts, 0, "running is no cut at 50 m/s (fastest anchor {mesh_speed} cm/s)");
    assert!(mesh_speed > 100.0, "the feet move over 1 m/s: {mesh_speed} cm/s");
    assert!(at(1.0).0 > 0, "at a 1 m/s cut speed some steps of the run are cuts");
}

/// The hard cases of an animated skin on the real Fox, for every solver: the Run clip at full
/// speed, a switch to another clip without a cross-fade, back with one, and a separable topology.
#[test]
fn run_and_clip_switches_stay_stable_for_every_solver() {
    let events = "[[events]]\nkind = \"play_clip\"\nat_s = 0.2\npack = \"fox\"\nclip = \"Survey\"\n\
                  [[events]]\nkind = \"play_clip\"\nat_s = 0.35\npack = \"fox\"\nclip = \"Run\"\nfade_s = 0.1\n";
    for (solver, extra) in [
        ("auto", ""),
        ("explicit", ""),
        ("implicit", ""),
        ("reference", ""),
        ("implicit", "[effects.parting]\n"),
        ("stick", "[effects.parting]\n"),
    ] {
        let body = format!(
            "solver = \"{solver}\"\n[packs.animation]\nclip = \"Run\"\n[effects.wrong_side_guard]\n[effects.gravity]\n{extra}{events}"
        );
        let mut w = world(&body);
        let what = format!("{solver} {extra}");
        run_checked(&mut w, 50, &what);
        let anim = w.animation(0).unwrap();
        assert_eq!(anim.clip_name(anim.playback().clip), "Run", "{what}");
        assert!((anim.playback().time_s - 0.15).abs() < 1e-4, "{what}: Run restarted at 0.35 s");
    }
}

/// The automatic solver of an animated pack with a spring topology is XPBD (one iteration; the
/// accuracy report's walking Fox says why), of the same pack standing still implicit Euler, and
/// a solver the scene names is the one it gets.
#[test]
fn the_automatic_solver_of_an_animated_pack_is_xpbd() {
    let kind = |body: &str| world(body).fur(0).unwrap().simulation.map(|(t, k)| (t, k.name()));
    let walk = "[packs.animation]\nclip = \"Walk\"\n[effects.gravity]\n";
    assert_eq!(kind(walk), Some((TopologyKind::PRISMS, "xpbd")));
    assert_eq!(kind("[effects.gravity]\n"), Some((TopologyKind::PRISMS, "implicit")));
    assert_eq!(kind(&format!("solver = \"implicit\"\n{walk}")), Some((TopologyKind::PRISMS, "implicit")));
    assert_eq!(kind(&format!("{walk}[effects.parting]\n")).map(|(_, k)| k), Some("xpbd"));
    // One step of the walk: one substep, where implicit Euler's rotation limit splits it.
    let mut w = world(walk);
    w.step().unwrap();
    assert_eq!(w.fur(0).unwrap().last_step.substeps, 1);
}

/// A host that animates the character itself hands the World its joint matrices: given the
/// matrices the World's own clip player makes, the fur's state is bit-identical, step after step
/// (the host's World holds its clip still, so only the host's matrices move it); bad matrices
/// are refused, changing nothing; the clips take over again when released; and a pack animated
/// with no clip at all (`animation = {}`) stands at rest until the host poses it, its skin then
/// exactly the clip player's.
#[test]
fn host_joint_matrices_pose_the_skin_as_the_clips_do() {
    let body = "[packs.animation]\nclip = \"Walk\"\n[effects.gravity]\n[effects.wrong_side_guard]\n";
    let (mut clips, mut host) = (world(body), world(body));
    host.animation_mut(0).unwrap().set_speed(0.0).unwrap();
    let mut no_clip = world("animation = {}\n[effects.gravity]\n[effects.wrong_side_guard]\n");
    assert!(!no_clip.animation(0).unwrap().is_host_posed());
    let bits = |v: &[[f32; 3]]| v.iter().flatten().map(|c| c.to_bits()).collect::<Vec<_>>();
    let rest = no_clip.animation(0).unwrap().positions().to_vec();
    assert_ne!(bits(&rest), bits(clips.animation(0).unwrap().positions()), "the rest pose is not Walk's");
    for step in 0..40 {
        clips.step().unwrap();
        let anim = clips.animation(0).unwrap();
        let (joints, weights) = (anim.joint_matrices().to_vec(), anim.morph_weights().to_vec());
        assert!(!joints.is_empty(), "the Fox has a skeleton");
        for w in [&mut host, &mut no_clip] {
            w.animation_mut(0).unwrap().set_joint_matrices(&joints, &weights).unwrap();
            w.step().unwrap();
        }
        let (a, b) = (clips.fur(0).unwrap(), host.fur(0).unwrap());
        assert_eq!(bits(a.scale_vectors), bits(b.scale_vectors), "step {step}: scale vectors");
        let (sa, sb) = (clips.pack_state(0).unwrap(), host.pack_state(0).unwrap());
        assert_eq!(bits(&sa.skin_positions_m), bits(&sb.skin_positions_m), "step {step}: skin");
        assert_eq!(clips.animation(0).unwrap().skinning_matrices(), host.animation(0).unwrap().skinning_matrices());
        let posed = no_clip.animation(0).unwrap().positions();
        assert_eq!(bits(posed), bits(clips.animation(0).unwrap().positions()), "step {step}: clipless skin");
    }
    let a = host.animation_mut(0).unwrap();
    assert!(a.is_host_posed());
    // An engine maps its joints by glTF node: every joint names its node, and back.
    assert_eq!(a.joint_nodes().len(), a.joint_matrices().len());
    assert_eq!(a.joint_names().len(), a.joint_matrices().len());
    assert!(a.joint_nodes().iter().enumerate().all(|(j, &n)| a.joint_of_node(n) == Some(j)));
    assert_eq!(a.joint_of_node(u32::MAX), None);
    let n = a.joint_matrices().len();
    let before = a.joint_matrices().to_vec();
    let mut nan = before.clone();
    nan[3].x_axis.y = f32::NAN;
    assert!(a.set_joint_matrices(&before[..n - 1], &[]).is_err(), "too few joint matrices");
    assert!(a.set_joint_matrices(&nan, &[]).is_err(), "a NaN joint matrix");
    assert!(a.set_joint_matrices(&before, &[0.5]).is_err(), "a weight for a morph target the Fox lacks");
    assert_eq!(a.joint_matrices(), &before[..], "a refused pose changes nothing");
    // Released, the clip player (Walk, held at its start) poses the skin again.
    a.resume_clips();
    host.step().unwrap();
    assert_ne!(host.animation(0).unwrap().joint_matrices(), &before[..]);
    // Released with no clip: back to the rest pose.
    no_clip.animation_mut(0).unwrap().resume_clips();
    no_clip.step().unwrap();
    assert_eq!(bits(no_clip.animation(0).unwrap().positions()), bits(&rest));
}

#[test]
fn clip_time_speed_and_start_are_the_scenes() {
    // Speed 0 holds the clip at start_s: the pose of a chosen clip time.
    let mut w = world("[packs.animation]\nclip = \"Walk\"\nspeed = 0.0\nstart_s = 0.4\n[effects.gravity]\n");
    let at_start = w.animation(0).unwrap().positions().to_vec();
    for _ in 0..5 {
        w.step().unwrap();
    }
    assert_eq!(w.animation(0).unwrap().positions(), &at_start[..]);
    assert_eq!(w.animation(0).unwrap().playback().time_s, 0.4);
    // Looping off clamps at the end; looping on wraps.
    let duration = w.pack(0).animation_clips().unwrap().unwrap().by_name("Walk").unwrap().duration_s;
    let mut once = world(&format!("[packs.animation]\nclip = \"Walk\"\nloop = false\nstart_s = {}\n", duration - 0.02));
    let mut looped = world(&format!("[packs.animation]\nclip = \"Walk\"\nstart_s = {}\n", duration - 0.02));
    for _ in 0..5 {
        once.step().unwrap();
        looped.step().unwrap();
    }
    assert_eq!(once.animation(0).unwrap().playback().time_s, duration);
    assert!((looped.animation(0).unwrap().playback().time_s - 0.03).abs() < 1e-4);
}

#[test]
fn a_clip_the_pack_lacks_fails_before_the_first_step() {
    let err = World::new(scene("[packs.animation]\nclip = \"Dance\"\n")).unwrap_err();
    assert!(matches!(err, RuntimeError::Animation { .. }), "{err}");
    let msg = err.to_string();
    assert!(msg.contains("fox.fbk") && msg.contains("Dance") && msg.contains("Walk"), "{msg}");
    let event = "[packs.animation]\nclip = \"Walk\"\n[[events]]\nkind = \"play_clip\"\nat_s = 1.0\npack = \"fox\"\nclip = \"Jump\"\n";
    let msg = World::new(scene(event)).unwrap_err().to_string();
    assert!(msg.contains("Jump"), "{msg}");
    // Switching clips needs an animation to switch from; bad values name their key.
    let text = "[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\n[[events]]\nkind = \"play_clip\"\nat_s = 1.0\npack = \"fox\"\nclip = \"Run\"\n";
    let msg = Scene::from_toml_str(text, Path::new("t.toml"), fox_dir()).unwrap_err().to_string();
    assert!(msg.contains("events[0].pack") && msg.contains("animation"), "{msg}");
    let text = "[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\nanimation = { clip = \"Run\", speed = 1e9 }\n";
    let msg = Scene::from_toml_str(text, Path::new("t.toml"), fox_dir()).unwrap_err().to_string();
    assert!(msg.contains("packs[0].animation.speed"), "{msg}");
}

/// A host drives the animation directly: switch clip, seek, change speed; bad values are typed
/// errors that change nothing.
#[test]
fn the_host_drives_the_animation() {
    let mut w = world("[packs.animation]\nclip = \"Walk\"\n");
    let a = w.animation_mut(0).unwrap();
    a.play("Run", 0.0).unwrap();
    a.seek(0.25).unwrap();
    a.set_speed(0.0).unwrap();
    assert!(a.set_speed(f32::NAN).is_err() && a.set_speed(1e3).is_err() && a.seek(f32::INFINITY).is_err());
    assert!(a.play("Dance", 0.0).is_err());
    w.step().unwrap();
    let anim = w.animation(0).unwrap();
    assert_eq!(anim.clip_name(anim.playback().clip), "Run");
    assert_eq!(anim.playback().time_s, 0.25);
}

/// Fur physics on the GPU blends the skin from the matrices there: the world's steps pose no
/// vertex on the CPU (the per-vertex blend grows with every character of a crowd), the matrices
/// still move, and a host that turns vertex posing back on reads the same skin as a CPU world.
#[test]
fn a_gpu_physics_pack_poses_matrices_not_vertices() {
    let body = "[solver]\ndevice = \"gpu\"\n[packs.animation]\nclip = \"Walk\"\n[effects.gravity]\n";
    let mut gpu = world(body);
    let mut cpu = world("[packs.animation]\nclip = \"Walk\"\n[effects.gravity]\n");
    assert!(!gpu.animation(0).unwrap().is_vertex_posing() && cpu.animation(0).unwrap().is_vertex_posing());
    let first = gpu.animation(0).unwrap().positions().to_vec();
    let matrices = gpu.animation(0).unwrap().skinning_matrices().to_vec();
    for _ in 0..10 {
        gpu.step().unwrap();
        cpu.step().unwrap();
    }
    let anim = gpu.animation(0).unwrap();
    assert_eq!(anim.positions(), &first[..], "no vertex posed while posing is off");
    assert_ne!(anim.skinning_matrices(), &matrices[..], "the skeleton walks");
    assert_eq!(anim.skinning_matrices(), cpu.animation(0).unwrap().skinning_matrices());
    let msg = gpu.pack_state(0).unwrap_err().to_string();
    assert!(msg.contains("GPU"), "{msg}");
    let a = gpu.animation_mut(0).unwrap();
    a.set_vertex_posing(true);
    a.update().unwrap();
    assert_eq!(a.positions(), cpu.animation(0).unwrap().positions());
    assert_eq!(a.normals(), cpu.animation(0).unwrap().normals());
}
