//! The fur on an animated skin ([`Simulator::pose_skin`]), for every topology × solver: the hard
//! cases of animation stay stable — a fast swing (a run cycle), a joint scaled to zero and back,
//! non-uniform scale, a mirrored joint (negative determinant), a 10 m jump between frames — with
//! no NaN, energy within its budget (which now books the work the moving skin does), and no scale
//! vector on the wrong side of the posed normal. And the posing itself is exact: at rest the fur
//! stands where the posed skin puts it, and a cut carries it along.

use furbake_formats::sections::spring_topology::{SpringTopology, TopologyKind, TopologyParams};
use furbake_sim::{ForceSet, SimError, Simulator, SkinTransform, SolverKind, SolverSettings, build_topology, meshes};
use glam::{Mat4, Quat, Vec3};

/// The skin positions of every shell vertex (welded vertices, or triangle corners).
fn shell_positions(mesh: &furbake_formats::sections::skin_mesh::SkinMesh, kind: TopologyKind) -> Vec<Vec3> {
    if kind.is_separable() {
        mesh.triangles.iter().flatten().map(|&i| Vec3::from(mesh.positions[i as usize])).collect()
    } else {
        mesh.positions.iter().map(|&p| Vec3::from(p)).collect()
    }
}

/// One animation: the blended matrix of a vertex at bind position `p`, time `t`.
type Motion = fn(Vec3, f32) -> Mat4;

/// A limb swinging ±1 rad at 3 Hz about the z axis, bending more the further along +x.
fn run_cycle(p: Vec3, t: f32) -> Mat4 {
    let a = (std::f32::consts::TAU * 3.0 * t).sin() * (0.5 + 5.0 * p.x);
    Mat4::from_rotation_z(a)
}

/// Scaled to zero at 0.25 s and back to one at 0.5 s.
fn scale_to_zero(_: Vec3, t: f32) -> Mat4 {
    let s = (1.0 - (std::f32::consts::TAU * 2.0 * t).sin().abs()).max(0.0);
    Mat4::from_scale(Vec3::splat(if t < 0.5 { s } else { 1.0 }))
}

fn non_uniform(_: Vec3, t: f32) -> Mat4 {
    let w = (std::f32::consts::TAU * 2.0 * t).sin();
    Mat4::from_scale(Vec3::new(1.0 + 0.8 * w, 1.0, 1.0 - 0.5 * w))
}

/// Mirrored in x and turning: the determinant is negative throughout.
fn mirrored(_: Vec3, t: f32) -> Mat4 {
    Mat4::from_rotation_y(t) * Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0))
}

/// Still, then 10 m away from one frame to the next.
fn jump(_: Vec3, t: f32) -> Mat4 {
    Mat4::from_translation(if t < 0.25 { Vec3::ZERO } else { Vec3::new(10.0, 0.0, 0.0) })
}

const CASES: [(&str, Motion); 5] = [
    ("run cycle", run_cycle),
    ("joint scaled to zero and back", scale_to_zero),
    ("non-uniform scale", non_uniform),
    ("mirrored joint", mirrored),
    ("10 m jump", jump),
];

const CUT_SPEED_M_PER_S: f32 = 50.0;

fn solvers_for(kind: TopologyKind) -> Vec<SolverKind> {
    let mut s = vec![
        SolverKind::Explicit,
        SolverKind::Implicit,
        SolverKind::Reference,
        SolverKind::Xpbd,
        SolverKind::LocalGlobal,
    ];
    if kind.uses_sticks() || kind == TopologyKind::SPRING_STICKS || kind == TopologyKind::SEPARABLE_SPRING_STICKS {
        s.push(SolverKind::Stick);
    }
    s
}

fn epsilon(solver: SolverKind) -> f64 {
    match solver {
        SolverKind::Explicit | SolverKind::Stick => 0.67,
        SolverKind::Implicit | SolverKind::Reference => 0.05,
        SolverKind::Xpbd | SolverKind::LocalGlobal => 0.05,
    }
}

/// Runs one case (XPBD with `xpbd_iterations` when given); false when an explicit or stick step
/// was refused up front (`StepTooLarge`).
fn run(
    topo: &SpringTopology,
    base: &[Vec3],
    solver: SolverKind,
    xpbd_iterations: Option<u32>,
    motion: Motion,
    what: &str,
) -> bool {
    let mut settings = SolverSettings { max_substeps: 2_000, ..SolverSettings::of(solver) };
    if let Some(n) = xpbd_iterations {
        settings.xpbd_iterations = n;
    }
    let cos_a = settings.guard.max_angle_deg.to_radians().cos();
    let mut sim = Simulator::new(topo, settings).expect("built topologies simulate");
    sim.set_forces(ForceSet::default()).expect("default forces are valid");
    let dt = 1.0 / 60.0;
    let mut transforms = vec![SkinTransform::IDENTITY; sim.shell_vertex_count()];
    let mut e_peak = 0.0f64;
    let mut cuts = 0;
    for step in 0..60 {
        let t = (step + 1) as f32 * dt as f32;
        for (tr, &p) in transforms.iter_mut().zip(base) {
            *tr = SkinTransform::new(motion(p, t), Vec3::ZERO);
        }
        // The first pose is always a cut (the fur starts in the bind pose).
        let cut_speed = if step == 0 { 0.0 } else { CUT_SPEED_M_PER_S };
        let moved = sim.pose_skin(&transforms, dt, cut_speed).expect("finite transforms");
        cuts += u32::from(moved.cut && step > 0);
        let st = match sim.step(dt) {
            Ok(st) => st,
            Err(SimError::StepTooLarge { .. }) if matches!(solver, SolverKind::Explicit | SolverKind::Stick) => {
                return false;
            }
            Err(e) => panic!("{what}: step {step}: {e}"),
        };
        assert!(sim.positions().iter().flatten().all(|c| c.is_finite()), "{what}: step {step}: non-finite");
        let e = st.energy.total_j();
        e_peak = e_peak.max(e);
        assert!(
            // XPBD: not asserted (see hard_cases.rs: its unresolved constraint error on stiff links).
            solver == SolverKind::Xpbd || e <= st.energy_budget_j + epsilon(solver) * e_peak + 1e-9,
            "{what}: step {step}: energy {e} J above budget {} J (peak {e_peak} J)",
            st.energy_budget_j
        );
        for (s, n) in sim.scale_vectors().iter().zip(sim.shell_normals()) {
            if n != [0.0; 3] {
                let d = Vec3::from(*s).dot(Vec3::from(n));
                assert!(d >= cos_a - 1e-3, "{what}: step {step}: scale vector {s:?} behind posed normal {n:?}");
            }
        }
    }
    if what.starts_with("10 m jump") {
        assert_eq!(cuts, 1, "{what}: the 10 m jump is one cut");
    }
    true
}

#[test]
fn animated_skins_stay_stable_for_every_topology_and_solver() {
    let mesh = meshes::icosphere(1, 0.1);
    let params = TopologyParams { chain_layers: 4, ..TopologyParams::default() };
    let (mut ran, mut refused) = (0, Vec::new());
    for kind in TopologyKind::KNOWN {
        let topo = build_topology(&mesh, kind, &params).expect("icosphere builds");
        let base = shell_positions(&mesh, kind);
        // XPBD also at one iteration: what a scene's automatic solver runs on an animated skin.
        let iterations = solvers_for(kind).into_iter().map(|s| (s, None)).chain([(SolverKind::Xpbd, Some(1))]);
        for (solver, xpbd_iterations) in iterations {
            for (name, motion) in CASES {
                let what = format!("{name} / {kind} / {} ×{xpbd_iterations:?}", solver.name());
                if run(&topo, &base, solver, xpbd_iterations, motion, &what) {
                    ran += 1;
                } else {
                    refused.push(what);
                }
            }
        }
    }
    println!("{ran} runs completed; refused up front: {refused:?}");
    // Refusal is allowed only where the stable step is the solver's own limit; with default
    // stiffness every run completes.
    assert!(refused.is_empty(), "refused: {refused:?}");
}

/// Under a rigid motion held still, the fur settles where the posed skin puts it: every mass at
/// the posed image of its rest position.
#[test]
fn fur_settles_on_the_posed_skin() {
    let mesh = meshes::icosphere(1, 0.1);
    let motion = Mat4::from_rotation_translation(Quat::from_rotation_x(1.2), Vec3::new(0.3, -0.2, 0.1));
    for kind in [TopologyKind::PRISMS, TopologyKind::SEPARABLE_SPRING_STICKS, TopologyKind::CHAIN] {
        let topo = build_topology(&mesh, kind, &TopologyParams::default()).expect("icosphere builds");
        let mut sim = Simulator::new(&topo, SolverSettings::of(SolverKind::Implicit)).expect("simulates");
        sim.set_forces(ForceSet::none()).expect("valid");
        let transforms = vec![SkinTransform::new(motion, Vec3::ZERO); sim.shell_vertex_count()];
        // Turned over a second, then held.
        for step in 0..240 {
            let f = ((step + 1) as f32 / 60.0).min(1.0);
            let partial =
                Mat4::from_rotation_translation(Quat::from_rotation_x(1.2 * f), Vec3::new(0.3, -0.2, 0.1) * f);
            let tr = if step < 60 {
                vec![SkinTransform::new(partial, Vec3::ZERO); transforms.len()]
            } else {
                transforms.clone()
            };
            sim.pose_skin(&tr, 1.0 / 60.0, f32::INFINITY).expect("finite");
            sim.step(1.0 / 60.0).expect("stable");
        }
        let worst = sim
            .positions()
            .iter()
            .zip(&topo.mass_rest_positions)
            .map(|(x, r)| Vec3::from(*x).distance(motion.transform_point3(Vec3::from(*r))))
            .fold(0.0f32, f32::max);
        assert!(worst < 0.15 * topo.params.fur_length_m, "{kind}: a mass is {worst} m from its posed rest");
        // Scale vectors follow the rotated normals.
        for (s, n) in sim.scale_vectors().iter().zip(sim.shell_normals()) {
            if n != [0.0; 3] {
                assert!(Vec3::from(*s).dot(Vec3::from(n)) > 0.95, "{kind}: {s:?} vs {n:?}");
            }
        }
    }
}

/// A cut moves the fur with the skin: after a 10 m jump nothing lags behind.
#[test]
fn a_cut_carries_the_fur_along() {
    let mesh = meshes::icosphere(1, 0.1);
    let topo = build_topology(&mesh, TopologyKind::PRISMS, &TopologyParams::default()).expect("builds");
    let mut sim = Simulator::new(&topo, SolverSettings::of(SolverKind::Implicit)).expect("simulates");
    let n = sim.shell_vertex_count();
    let jump = vec![SkinTransform::new(Mat4::from_translation(Vec3::new(10.0, 0.0, 0.0)), Vec3::ZERO); n];
    let moved = sim.pose_skin(&jump, 1.0 / 60.0, 50.0).expect("finite");
    assert!(moved.cut && moved.max_anchor_speed_m_per_s > 500.0, "{moved:?}");
    assert!(sim.velocities().iter().all(|v| *v == [0.0; 3]), "a cut gives the anchors no velocity");
    for (x, r) in sim.positions().iter().zip(&topo.mass_rest_positions) {
        assert!((Vec3::from(*x) - Vec3::from(*r) - Vec3::new(10.0, 0.0, 0.0)).length() < 1e-5);
    }
    // Without a cut the same jump leaves the fur behind (the springs then pull it).
    let mut sim = Simulator::new(&topo, SolverSettings::of(SolverKind::Implicit)).expect("simulates");
    let moved = sim.pose_skin(&jump, 1.0 / 60.0, f32::INFINITY).expect("finite");
    assert!(!moved.cut);
    assert!(sim.max_displacement_m() > 9.9, "free masses stayed where they were");
}

/// The links between hairs (prism edges) stretch with the skin between their ends: a skin
/// stretched half as long again leaves every hair standing along its normal, where links of
/// bind length would pull the tips towards each other and lay the fur down.
#[test]
fn links_between_hairs_follow_a_stretching_skin() {
    let mesh = meshes::icosphere(1, 0.1);
    for kind in [TopologyKind::PRISMS, TopologyKind::CHAIN] {
        let params = TopologyParams { chain_layers: 3, ..TopologyParams::default() };
        let topo = build_topology(&mesh, kind, &params).expect("builds");
        let base = shell_positions(&mesh, kind);
        for solver in [SolverKind::Implicit, SolverKind::Xpbd, SolverKind::LocalGlobal, SolverKind::Reference] {
            let mut sim = Simulator::new(&topo, SolverSettings::of(solver)).expect("simulates");
            sim.set_forces(ForceSet::none()).expect("valid");
            // Every shell vertex moves by half its x: the skin is 1.5 times as long along x.
            let tr: Vec<SkinTransform> = base
                .iter()
                .map(|p| SkinTransform::new(Mat4::from_translation(Vec3::new(0.5 * p.x, 0.0, 0.0)), Vec3::ZERO))
                .collect();
            sim.pose_skin(&tr, 1.0 / 60.0, 0.0).expect("finite"); // a cut: the fur is carried
            for _ in 0..60 {
                sim.pose_skin(&tr, 1.0 / 60.0, f32::INFINITY).expect("finite");
                sim.step(1.0 / 60.0).expect("stable");
            }
            for (s, nrm) in sim.scale_vectors().iter().zip(sim.shell_normals()) {
                if nrm != [0.0; 3] {
                    let c = Vec3::from(*s).normalize().dot(Vec3::from(nrm));
                    assert!(
                        c > 0.9995,
                        "{kind} / {}: a hair leans {:.2}° off its normal",
                        solver.name(),
                        c.acos().to_degrees()
                    );
                }
            }
        }
    }
}

#[test]
fn bad_poses_are_refused_and_change_nothing() {
    let mesh = meshes::icosphere(1, 0.1);
    let topo = build_topology(&mesh, TopologyKind::PRISMS, &TopologyParams::default()).expect("builds");
    let mut sim = Simulator::new(&topo, SolverSettings::of(SolverKind::Implicit)).expect("simulates");
    let before = sim.positions();
    let n = sim.shell_vertex_count();
    let short = vec![SkinTransform::IDENTITY; n - 1];
    assert!(matches!(sim.pose_skin(&short, 0.01, 50.0), Err(SimError::Parameter { name: "transforms", .. })));
    let mut nan = vec![SkinTransform::IDENTITY; n];
    nan[3].morph_offset_m.x = f32::NAN;
    let err = sim.pose_skin(&nan, 0.01, 50.0).expect_err("NaN refused").to_string();
    assert!(err.contains("shell vertex 3"), "{err}");
    assert!(sim.pose_skin(&vec![SkinTransform::IDENTITY; n], 0.0, 50.0).is_err());
    assert!(sim.pose_skin(&vec![SkinTransform::IDENTITY; n], 0.01, f32::NAN).is_err());
    assert_eq!(sim.positions(), before);
}
