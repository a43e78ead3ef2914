//! Solver behaviour: explicit refusal and substepping, NaN detection, convergence of the implicit
//! sweeps to the converged reference, thread-count determinism, the restoring force of eq. 3.37,
//! scale vectors and shell offsets (eq. 3.35–3.36).

use furbake_formats::sections::spring_topology::{TopologyKind, TopologyParams};
use furbake_sim::{
    ForceSet, SimError, Simulator, SolverKind, SolverSettings, build_topology, meshes, restoring_force, shell_offset,
    shell_vertex_position, synth,
};
use glam::{Vec3, Vec3A};

fn prisms() -> (furbake_formats::sections::skin_mesh::SkinMesh, furbake_sim::SpringTopology) {
    let mesh = meshes::grass_patch(0.02);
    let t = build_topology(&mesh, TopologyKind::PRISMS, &TopologyParams::default()).expect("builds");
    (mesh, t)
}

#[test]
fn explicit_substeps_or_refuses() {
    let (_, t) = prisms();
    let mut sim = Simulator::new(&t, SolverSettings::of(SolverKind::Explicit)).expect("valid");
    let stable = sim.stable_step_s();
    assert!(stable > 0.0 && stable < 1.0 / 60.0, "stable step {stable}");
    let st = sim.step(1.0 / 60.0).expect("substeps");
    assert_eq!(st.substeps as f64, (1.0 / 60.0 / stable).ceil());
    let mut strict =
        Simulator::new(&t, SolverSettings { allow_substeps: false, ..SolverSettings::of(SolverKind::Explicit) })
            .expect("valid");
    match strict.step(1.0 / 60.0) {
        Err(SimError::StepTooLarge { needed, allowed: 1, .. }) => assert!(needed > 1),
        other => panic!("expected a refusal, got {other:?}"),
    }
    // A step below the stable step is taken whole.
    assert_eq!(strict.step(stable * 0.5).expect("stable").substeps, 1);
}

#[test]
fn non_finite_state_is_reported_not_propagated() {
    let (_, t) = prisms();
    let mut checked = 0;
    for solver in SolverKind::ALL {
        let mut sim = Simulator::new(&t, SolverSettings::of(solver)).expect("valid");
        let mut pos = sim.positions();
        let vel = sim.velocities();
        // A tip far beyond f32 range once squared: the spring force overflows.
        let tip = t.shell_vertex_masses[0][1] as usize;
        pos[tip] = [3e38, 3e38, 3e38];
        sim.set_state(&pos, &vel).expect("finite input");
        match sim.step(1.0 / 600.0) {
            Err(SimError::NonFinite { .. })
            | Err(SimError::StepTooLarge { .. })
            | Err(SimError::NotConverged { .. }) => {}
            Ok(_) => assert!(sim.positions().iter().flatten().all(|c| c.is_finite()), "{}", solver.name()),
            Err(e) => panic!("{}: unexpected {e}", solver.name()),
        }
        // Whatever happened, no NaN is visible.
        assert!(sim.positions().iter().chain(&sim.velocities()).flatten().all(|c| !c.is_nan()));
        checked += 1;
    }
    assert_eq!(checked, SolverKind::ALL.len());
}

fn run(t: &furbake_sim::SpringTopology, settings: SolverSettings, steps: u32, dt: f64) -> Vec<[f32; 3]> {
    let mut sim = Simulator::new(t, settings).expect("valid");
    sim.set_forces(ForceSet { wind: Some(furbake_sim::WindForce::default()), ..ForceSet::default() }).expect("valid");
    for _ in 0..steps {
        sim.step(dt).expect("stable");
    }
    sim.positions()
}

fn rms(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let s: f64 = a.iter().zip(b).map(|(p, q)| (0..3).map(|i| (p[i] as f64 - q[i] as f64).powi(2)).sum::<f64>()).sum();
    (s / a.len() as f64).sqrt()
}

/// More implicit sweeps approach the converged backward-Euler solution at the same step.
#[test]
fn implicit_sweeps_converge_to_the_reference() {
    let (_, t) = prisms();
    let no_limit =
        |kind, it| SolverSettings { implicit_iterations: it, max_link_rotation_rad: 0.0, ..SolverSettings::of(kind) };
    let reference = run(&t, no_limit(SolverKind::Reference, 1), 30, 1.0 / 60.0);
    let errors: Vec<f64> = [1, 4, 16, 64]
        .iter()
        .map(|&it| rms(&run(&t, no_limit(SolverKind::Implicit, it), 30, 1.0 / 60.0), &reference))
        .collect();
    eprintln!("implicit sweeps 1/4/16/64 vs reference: {errors:?}");
    assert!(errors.windows(2).all(|w| w[1] <= w[0] * 1.0001), "errors must not grow with sweeps: {errors:?}");
    assert!(errors[3] < errors[0] * 0.2, "64 sweeps must be much closer than 1: {errors:?}");
}

/// Results are bit-identical whatever the rayon thread count (sizes above the parallel cut-off).
#[test]
fn deterministic_across_thread_counts() {
    let t = synth::synthetic_topology(12_000, 12_000, false, &TopologyParams::default()).expect("valid size");
    let mut checked = 0;
    for solver in SolverKind::ALL {
        let settings = SolverSettings { implicit_iterations: 2, ..SolverSettings::of(solver) };
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
        let three = rayon::ThreadPoolBuilder::new().num_threads(3).build().expect("pool");
        let a = one.install(|| run(&t, settings.clone(), 3, 1.0 / 240.0));
        let b = three.install(|| run(&t, settings.clone(), 3, 1.0 / 240.0));
        assert!(a.iter().zip(&b).all(|(p, q)| p.map(f32::to_bits) == q.map(f32::to_bits)), "{}", solver.name());
        checked += 1;
    }
    assert_eq!(checked, SolverKind::ALL.len());
}

#[test]
fn restoring_force_matches_eq_3_37() {
    let n = Vec3A::Y;
    // At rest: no force.
    assert_eq!(restoring_force(Vec3A::ZERO, Vec3A::new(0.0, 0.02, 0.0), n, 0.01), Vec3A::ZERO);
    // Tilted 90°: s = x, F = (n − s)(1 − 0)·w.
    let f = restoring_force(Vec3A::ZERO, Vec3A::new(0.02, 0.0, 0.0), n, 0.01);
    assert!((f - Vec3A::new(-0.01, 0.01, 0.0)).length() < 1e-7, "{f:?}");
    // Upside down: F = 2n·2·w.
    let f = restoring_force(Vec3A::ZERO, Vec3A::new(0.0, -0.02, 0.0), n, 0.01);
    assert!((f - Vec3A::new(0.0, 0.04, 0.0)).length() < 1e-7, "{f:?}");
    // Tip on its root: undefined direction, no force.
    assert_eq!(restoring_force(Vec3A::ONE, Vec3A::ONE, n, 0.01), Vec3A::ZERO);
}

#[test]
fn shell_shearing_matches_eq_3_36() {
    let (n, s) = (Vec3::Y, Vec3::new(0.6, 0.8, 0.0));
    assert_eq!(shell_offset(0, 16, 2.0, s, n), Vec3::ZERO);
    assert!((shell_offset(16, 16, 2.0, s, n) - (s - n)).length() < 1e-6);
    assert!((shell_offset(8, 16, 2.0, s, n) - 0.25 * (s - n)).length() < 1e-6);
    // The outermost shell vertex ends at skin + s · fur length.
    let top = shell_vertex_position(Vec3::ONE, n, s, 16, 16, 0.02, 2.0);
    assert!((top - (Vec3::ONE + s * 0.02)).length() < 1e-6);
    // A scale vector into the surface (§3.4.3): no layer goes below the skin's tangent plane;
    // the outer layers lie flat (s = −n: every layer on the skin), tangential shear kept.
    let mut below = 0;
    for s in [-n, Vec3::new(0.6, -0.8, 0.0), Vec3::new(-0.8, -0.6, 0.0)] {
        for layer in 0..=16 {
            let p = shell_vertex_position(Vec3::ONE, n, s, layer, 16, 0.02, 2.0);
            below += usize::from((p - Vec3::ONE).dot(n) < -1e-7);
        }
        let top = shell_vertex_position(Vec3::ONE, n, s, 16, 16, 0.02, 2.0);
        let tangential = (s - s.dot(n) * n) * 0.02;
        assert!((top - Vec3::ONE - tangential).length() < 1e-6, "{s}: outer layer {top}");
    }
    assert_eq!(below, 0);
}

/// `furbake simulate` output can be checked by an independent integrator: one explicit step of a
/// single spring–stick tip under gravity, integrated here by hand, matches the report.
#[test]
fn explicit_step_matches_an_independent_integrator() {
    let mesh = meshes::grid(2, 2, 0.02);
    let p = TopologyParams::default();
    let t = build_topology(&mesh, TopologyKind::SPRING_STICKS, &p).expect("builds");
    let mut sim = Simulator::new(&t, SolverSettings::of(SolverKind::Explicit)).expect("valid");
    sim.set_forces(ForceSet { restoring_weight_n: 0.0, ..ForceSet::default() }).expect("valid");
    let h = sim.stable_step_s() * 0.5;
    sim.step(h).expect("one substep");
    // Hand integration (eq. 3.20–3.25): at rest the spring force is zero, so v = h g, x += h v.
    let tip = t.shell_vertex_masses[0][1] as usize;
    let v = sim.velocities()[tip];
    let x = sim.positions()[tip];
    let rest = t.mass_rest_positions[tip];
    assert!((v[1] as f64 - (-9.81 * h)).abs() < 1e-6, "{v:?}");
    assert!((x[1] as f64 - (rest[1] as f64 - 9.81 * h * h)).abs() < 1e-7, "{x:?}");
}
