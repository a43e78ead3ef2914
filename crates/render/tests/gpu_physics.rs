//! Fur physics in compute (`GpuFurPhysics`, `shaders/fur_physics.wgsl`) against the CPU solvers
//! it ports (furbake-sim's lane-group kernel and XPBD): a furry sphere's prisms (explicit and
//! XPBD solvers) and sticks (stick solver) topologies, stepped 1 s at 60 Hz on both under gravity, a gusting wind,
//! a spinning and accelerating frame and a local push, agree per mass within f32 rounding, the
//! guard's scale vectors agree, the renderer's shell shader draws the GPU's scale vectors, and
//! two GPU runs are bit-identical. Runs on whatever adapter the machine has (lavapipe without a
//! GPU) and never skips.

use std::sync::Arc;

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_render::headless::RenderTarget;
use furbake_render::{FurAsset, FurRenderer, GpuFurPhysics, RenderSettings};
use furbake_sim::{
    ForceSet, FrameMotion, LocalForce, Simulator, SolverKind, SolverSettings, SpringTopology, WindForce,
};

/// A unit sphere with 0.15 m fur and the named topology.
fn sphere(topology: &str) -> (FurAsset, SpringTopology) {
    let gltf = testmesh::uv_sphere(12, 16, 1.0).gltf;
    let imported = import_gltf_slice(&gltf, "sphere.gltf", None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    settings.volume.layers = 8;
    settings.volume.resolution = 32;
    settings.shells.fur_length_m = Some(0.15);
    settings.topologies = vec![topology.into()];
    let mut baked = bake(&imported, "sphere.gltf", &settings.plan().unwrap(), &mut NoProgress).unwrap();
    let topology = baked.topologies.pop().expect("the topology was asked for");
    let asset = FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), None).unwrap();
    (asset, topology)
}

/// Every force the GPU applies: gravity, a gusting wind, a spinning and accelerating frame, a
/// local push into the fur.
fn forces(push_n: f32) -> ForceSet {
    ForceSet {
        wind: Some(WindForce { direction: [1.0, 0.2, 0.0], force_n: 2e-4, ..WindForce::default() }),
        motion: FrameMotion {
            linear_accel_m_per_s2: [0.0, 0.0, 3.0],
            angular_velocity_rad_per_s: [0.0, 2.0, 0.0],
            angular_accel_rad_per_s2: [0.5, 0.0, 0.0],
        },
        local: vec![LocalForce { point_m: [0.0, 1.1, 0.0], radius_m: 0.4, strength_n: push_n }],
        ..ForceSet::default()
    }
}

/// Largest distance between two position lists, metres.
fn worst(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt())
        .fold(0.0, f32::max)
}

struct Run {
    cpu_positions: Vec<[f32; 3]>,
    cpu_scale: Vec<[f32; 3]>,
    gpu: furbake_render::PhysicsReadback,
    gpu_scale: Vec<[f32; 3]>,
    substeps: (u32, u32),
    /// The CPU guard's triggers in the last step and frozen tips after it.
    guard: (u32, u32),
    moved_m: f32,
}

/// Steps the CPU simulator and the GPU physics side by side for `steps` frames of 1/60 s.
fn run(topology: &str, kind: SolverKind, steps: u32, push_n: f32) -> Run {
    let g = gpu();
    let (asset, topo) = sphere(topology);
    let renderer =
        FurRenderer::new(g.pipelines(), &g.queue, &asset, &RenderSettings::default(), &RenderTarget::desc()).unwrap();
    let mut sim = Simulator::new(&topo, SolverSettings::of(kind)).unwrap();
    sim.set_forces(forces(push_n)).unwrap();
    let rest = sim.positions();
    let model = sim.compute_model().unwrap();
    let stable = sim.stable_step_s();
    let mut physics: GpuFurPhysics = renderer
        .gpu_physics(&g.device, &g.queue, &model, &forces(push_n), stable, sim.settings().max_substeps)
        .unwrap();
    let mut substeps = (0, 0);
    let (mut triggers, mut frozen) = (0, 0);
    for _ in 0..steps {
        let stats = sim.step(1.0 / 60.0).unwrap();
        substeps.0 += stats.substeps;
        (triggers, frozen) = (stats.guard_triggers, stats.frozen_scale_vectors);
        let mut encoder = g.device.create_command_encoder(&Default::default());
        substeps.1 += physics.record(&g.device, &g.queue, &mut encoder, 1.0 / 60.0).unwrap();
        g.queue.submit([encoder.finish()]);
    }
    let readback = physics.read_back(&g.device, &g.queue).unwrap();
    let gpu_scale = renderer.shell_scale_vectors(&g.device, &g.queue).unwrap();
    Run {
        moved_m: worst(&sim.positions(), &rest),
        cpu_positions: sim.positions(),
        cpu_scale: sim.scale_vectors(),
        gpu: readback,
        gpu_scale,
        substeps,
        guard: (triggers, frozen),
    }
}

fn check_agreement(topology: &str, kind: SolverKind, push_n: f32) -> Run {
    let r = run(topology, kind, 60, push_n);
    assert_eq!(r.substeps.0, r.substeps.1, "{topology}: the GPU takes the CPU's substeps");
    assert_eq!(r.gpu.counters[0], 0, "{topology}: no non-finite mass on the GPU");
    // The fur really moved (the forces bend it by centimetres), and the two states agree to f32
    // rounding: 1e-4 of the fur's length, far below a texel of the shell atlas.
    assert!(r.moved_m > 0.005, "{topology}: the fur moved {} m", r.moved_m);
    let d = worst(&r.cpu_positions, &r.gpu.positions);
    assert!(d <= 1e-5, "{topology}: GPU and CPU positions differ by {d} m after 1 s ({} substeps)", r.substeps.0);
    let s = worst(&r.cpu_scale, &r.gpu_scale);
    assert!(s <= 2e-5, "{topology}: the shell shader's scale vectors differ from the CPU's by {s}");
    assert_eq!(r.gpu.counters[2], r.guard.1, "{topology}: frozen tips");
    eprintln!(
        "{topology}: moved {:.4} m, GPU−CPU {d:.2e} m, scale vectors {s:.2e}, {} substeps, {} frozen",
        r.moved_m, r.substeps.0, r.guard.1
    );
    r
}

#[test]
fn explicit_solver_agrees_with_the_cpu() {
    check_agreement("prisms", SolverKind::Explicit, 5e-3);
}

#[test]
fn stick_solver_agrees_with_the_cpu() {
    check_agreement("sticks", SolverKind::Stick, 5e-3);
}

#[test]
fn xpbd_solver_agrees_with_the_cpu() {
    check_agreement("prisms", SolverKind::Xpbd, 5e-3);
    check_agreement("sticks", SolverKind::Xpbd, 5e-3);
}

#[test]
fn the_guard_freezes_the_same_tips_on_both() {
    // A hard push from above the pole flattens the fur there past the guard's 80°.
    let r = check_agreement("sticks", SolverKind::Stick, 0.5);
    assert!(r.guard.1 > 0, "the push froze no tip");
}

#[test]
fn gpu_physics_is_deterministic() {
    let (a, b) = (run("prisms", SolverKind::Explicit, 20, 5e-3), run("prisms", SolverKind::Explicit, 20, 5e-3));
    assert_eq!(a.gpu.positions, b.gpu.positions);
    assert_eq!(a.gpu.velocities, b.gpu.velocities);
    assert_eq!(a.gpu_scale, b.gpu_scale);
}

#[test]
fn solvers_without_a_compute_form_are_refused() {
    let (_, topo) = sphere("prisms");
    let sim = Simulator::new(&topo, SolverSettings::of(SolverKind::Implicit)).unwrap();
    let e = sim.compute_model().unwrap_err().to_string();
    assert!(e.contains("implicit") && e.contains("no compute form"), "{e}");
}

#[test]
fn several_steps_in_one_record_are_the_steps_one_by_one() {
    // A world that stepped three times since the last frame hands its three force sets over at
    // once: the same state as three records (XPBD resets its multipliers per step; the guard
    // runs after each).
    let g = gpu();
    let (asset, topo) = sphere("prisms");
    let renderer =
        FurRenderer::new(g.pipelines(), &g.queue, &asset, &RenderSettings::default(), &RenderTarget::desc()).unwrap();
    let mut sim = Simulator::new(&topo, SolverSettings::of(SolverKind::Xpbd)).unwrap();
    sim.set_forces(forces(5e-3)).unwrap();
    let model = sim.compute_model().unwrap();
    let stable = sim.stable_step_s();
    let build = || renderer.gpu_physics(&g.device, &g.queue, &model, &forces(5e-3), stable, 100).unwrap();
    let (mut one, mut three) = (build(), build());
    let f = forces(5e-3);
    for _ in 0..4 {
        for _ in 0..3 {
            let mut encoder = g.device.create_command_encoder(&Default::default());
            one.record(&g.device, &g.queue, &mut encoder, 1.0 / 60.0).unwrap();
            g.queue.submit([encoder.finish()]);
        }
        let mut encoder = g.device.create_command_encoder(&Default::default());
        three.record_steps(&g.device, &g.queue, &mut encoder, 1.0 / 60.0, &[&f, &f, &f]).unwrap();
        g.queue.submit([encoder.finish()]);
    }
    let (a, b) = (one.read_back(&g.device, &g.queue).unwrap(), three.read_back(&g.device, &g.queue).unwrap());
    assert_eq!(a.positions, b.positions);
    assert_eq!(a.velocities, b.velocities);
    assert_eq!(one.time_s(), three.time_s());
}
