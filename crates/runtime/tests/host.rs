//! Host-driven frames (docs/design.md "Runtime: scenes and stages"): a game places packs frame by
//! frame, changes wind, wind sources and colliders, drives the animation and the interaction point
//! — the TOML scene is one way to fill those inputs, not the only one. A host that feeds a pack the
//! placements of a scene's motion path gets bit-identical physics to the path itself.

use std::path::{Path, PathBuf};

use furbake_bake::{BakeSettings, BladeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_runtime::scene::Collider;
use furbake_runtime::{RuntimeError, Scene, StageKind, World, WorldOptions};
use glam::{Mat4, Quat, Vec3};

fn bake_pack(dir: &Path, name: &str, gltf: &[u8], blades: bool) -> PathBuf {
    let imported = import_gltf_slice(gltf, "mesh.gltf", None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    (settings.volume.resolution, settings.volume.layers) = (16, 4);
    settings.topologies = vec!["prisms".into()];
    settings.blades = blades.then(|| {
        let mut b = BladeSettings::default();
        b.field.density_per_m2 = 20.0;
        b.field.cluster_size_m = 0.5;
        b.keyframes.grid.poses = 40;
        b
    });
    let path = dir.join(name);
    bake(&imported, "mesh.gltf", &settings.plan().unwrap(), &mut NoProgress)
        .unwrap()
        .to_writer()
        .write_atomic(&path)
        .unwrap();
    path
}

fn world(dir: &Path, text: &str, options: WorldOptions) -> World {
    World::with_options(Scene::from_toml_str(text, Path::new("host.toml"), dir).unwrap(), options).unwrap()
}

/// The same sphere twice: `path` follows a motion path from the scene, `host` is placed by the
/// host at every step with that path's placements. Their fur must agree bit for bit.
#[test]
fn host_placements_give_the_motion_paths_physics() {
    let dir = tempfile::tempdir().unwrap();
    bake_pack(dir.path(), "ball.fbk", &testmesh::uv_sphere(6, 8, 0.5).gltf, false);
    let text = "time_step_s = 0.01\n\
        [[packs]]\nname = \"path\"\npath = \"ball.fbk\"\n\
        [[packs.motion]]\ntime_s = 0.0\n\
        [[packs.motion]]\ntime_s = 0.1\ntranslation = [0.3, 0.0, 0.0]\nrotation_deg = [0.0, 40.0, 0.0]\n\
        [[packs.motion]]\ntime_s = 0.2\ntranslation = [0.3, 0.2, 0.0]\n\
        [[packs]]\nname = \"host\"\npath = \"ball.fbk\"\n\
        [effects.gravity]\n[effects.object_motion]\n[effects.wrong_side_guard]\n";
    let mut w = world(dir.path(), text, WorldOptions { host_placement: true, ..WorldOptions::default() });
    assert_eq!(
        w.stages().iter().filter(|s| s.kind == StageKind::FurObjectMotion).count(),
        2,
        "with host placement every fur pack has its inertial-force stage"
    );
    let path_of = w.scene().packs()[0].clone();
    for step in 0..40 {
        let t_next = (step + 1) as f64 * 0.01f32 as f64;
        w.set_model_matrix(1, path_of.model_at(t_next)).unwrap();
        w.step().unwrap();
    }
    assert_eq!(w.model_matrix(0), w.model_matrix(1));
    let (a, b) = (w.pack_state(0).unwrap(), w.pack_state(1).unwrap());
    assert_eq!(a.mass_positions_m, b.mass_positions_m);
    assert_eq!(a.mass_velocities_m_per_s, b.mass_velocities_m_per_s);
    assert_eq!(a.scale_vectors, b.scale_vectors);
    let moved = a.mass_velocities_m_per_s.iter().map(|v| Vec3::from(*v).length()).fold(0.0, f32::max);
    assert!(moved > 0.0, "the path moved the fur");
}

#[test]
fn bad_placements_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    bake_pack(dir.path(), "ball.fbk", &testmesh::uv_sphere(6, 8, 0.5).gltf, false);
    let mut w = world(dir.path(), "[[packs]]\nname = \"b\"\npath = \"ball.fbk\"\n", WorldOptions::default());
    for bad in [
        Mat4::from_scale(Vec3::new(1.0, 2.0, 1.0)),
        Mat4::from_scale(Vec3::splat(-1.0)),
        Mat4::from_translation(Vec3::splat(f32::NAN)),
        Mat4::ZERO,
    ] {
        let err = w.set_model_matrix(0, bad).unwrap_err();
        assert!(matches!(err, RuntimeError::Parameter { .. }), "{bad}: {err}");
    }
    assert!(w.set_model_matrix(3, Mat4::IDENTITY).is_err(), "no pack 3");
    let ok = Mat4::from_scale_rotation_translation(Vec3::splat(2.0), Quat::from_rotation_y(1.0), Vec3::ONE);
    w.set_model_matrix(0, ok).unwrap();
    w.step().unwrap();
    assert!(w.model_matrix(0).abs_diff_eq(ok, 1e-6));
}

/// The host moves a collider through the grass and turns the wind; a refused edit keeps the
/// previous effects, and an edit cannot declare an effect the scene did not.
#[test]
fn the_host_drives_wind_and_colliders() {
    let dir = tempfile::tempdir().unwrap();
    bake_pack(dir.path(), "patch.fbk", &testmesh::grass_patch(2.0).gltf, true);
    let text = "time_step_s = 0.02\n[[packs]]\nname = \"lawn\"\npath = \"patch.fbk\"\n\
        [effects.wind]\nvelocity_m_per_s = [0.0, 0.0, 0.0]\n\
        [[effects.collisions]]\nshape = \"sphere\"\ncenter = [-5.0, 0.0, 0.0]\nradius_m = 0.4\n";
    let mut w = world(dir.path(), text, WorldOptions::default());
    let corner_sum = |w: &World| w.grass(0).unwrap().corner_forces.iter().map(|f| f[0].abs() + f[1].abs()).sum::<f32>();
    w.step().unwrap();
    let calm = corner_sum(&w);
    assert!(calm < 1e-6, "no wind, collider far away: {calm}");
    // The collider rolls into the lawn.
    w.update_effects(|e| {
        if let Collider::Sphere { center, .. } = &mut e.collisions[0] {
            *center = [0.2, 0.0, 0.1];
        }
    })
    .unwrap();
    w.step().unwrap();
    let pushed = corner_sum(&w);
    assert!(pushed > calm + 0.1, "the collider pushes the grass: {pushed}");
    // The wind rises.
    w.update_effects(|e| e.wind.as_mut().unwrap().velocity_m_per_s = [3.0, 0.0, 0.0]).unwrap();
    w.step().unwrap();
    assert!(corner_sum(&w) > pushed, "wind adds to the push");
    // A NaN wind is refused and the previous wind stays.
    let err = w.update_effects(|e| e.wind.as_mut().unwrap().velocity_m_per_s = [f32::NAN, 0.0, 0.0]).unwrap_err();
    assert!(err.to_string().contains("effects.wind.velocity_m_per_s"), "{err}");
    assert_eq!(w.effects().wind.unwrap().velocity_m_per_s, [3.0, 0.0, 0.0]);
    // Gravity was not declared: the host cannot switch it on (the plan has no stage for it).
    let err = w
        .update_effects(|e| {
            e.gravity = Some(furbake_runtime::scene::Gravity { acceleration_m_per_s2: [0.0, -9.81, 0.0] })
        })
        .unwrap_err();
    assert!(err.to_string().contains("not which effects are declared"), "{err}");
    assert!(w.effects().gravity.is_none());
}
