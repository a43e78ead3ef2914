//! The reference solver is backward Euler, checked against integrators written independently here
//! (`common::Net`, f64) on the stiff net (springs, damping, gravity, gusty wind) and on
//! spring–stick tips with the restoring force of eq. 3.37 (wind, gravity):
//!
//! - against classic RK4 at 1e-6 s over 0.1 s: its error falls by ≈ 2 for every halving of the
//!   step from 1e-3 to 6.25e-5 s (first order: every ratio within [1.7, 2.2], the last within
//!   [1.9, 2.1]), stays below a stated bound at the smallest step, and the Richardson combination
//!   `2 x(h/2) − x(h)` of the two smallest steps is ten times closer still (so the error is the
//!   method's own first-order term, nothing else);
//! - against linearised backward Euler with the exact Jacobian and a dense solve, at the accuracy
//!   report's steps over one second: the same trajectory to 2e-9 m (1.5e-5 m on the stiff net at
//!   1/30 s, where the compression floor acts) — below the f32 floor, read
//!   through `Simulator::positions_f64`. (A wrong Jacobian also converges at first order; this
//!   is the check that the reference's is exact.)

use crate::common::{Net, flat};
use furbake_formats::sections::spring_topology::{TopologyKind, TopologyParams};
use furbake_sim::{
    ForceSet, GuardSettings, Simulator, SolverKind, SolverSettings, SpringTopology, WindForce, build_topology, meshes,
    synth,
};

const DURATION: f64 = 0.1;

fn reference_positions(t: &SpringTopology, f: &ForceSet, dt: f64, duration: f64) -> (Vec<f64>, Vec<f64>) {
    let settings = SolverSettings {
        max_link_rotation_rad: 0.0,
        track_energy: false,
        reference_tolerance: 1e-12,
        guard: GuardSettings { enabled: false, ..GuardSettings::default() },
        ..SolverSettings::of(SolverKind::Reference)
    };
    let mut sim = Simulator::new(t, settings).expect("valid settings");
    sim.set_forces(f.clone()).expect("valid forces");
    for _ in 0..(duration / dt).round() as usize {
        sim.step(dt).expect("the reference converges");
    }
    let x64: Vec<f64> =
        sim.positions_f64().expect("the reference keeps f64 positions").iter().flatten().copied().collect();
    (x64, flat(&sim.positions()))
}

/// Errors against RK4 at 1e-6 s for steps 1e-3 s halved four times; asserts first order and
/// `bound` at the smallest step.
fn check_first_order(name: &str, t: &SpringTopology, f: &ForceSet, bound: f64) {
    let net = Net::new(t, f);
    let truth = net.rk4(1e-6, DURATION);
    let truth_error = net.rms(&truth, &net.rk4(2e-6, DURATION));
    assert!(truth_error < 1e-12, "{name}: RK4 is accurate ({truth_error:e})");
    let steps = [1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5];
    let mut errors = Vec::new();
    let mut last_two: Vec<Vec<f64>> = Vec::new();
    for dt in steps {
        let (x64, x32) = reference_positions(t, f, dt, DURATION);
        let (e, e32) = (net.rms(&x64, &truth), net.rms(&x32, &truth));
        eprintln!("{name}: dt {dt:.3e} s: error {e:.3e} m (f32 positions {e32:.3e} m)");
        errors.push(e);
        last_two.push(x64);
    }
    let n = last_two.len();
    let richardson: Vec<f64> = last_two[n - 1].iter().zip(&last_two[n - 2]).map(|(a, b)| 2.0 * a - b).collect();
    let extrapolated = net.rms(&richardson, &truth);
    eprintln!("{name}: Richardson 2 x(h/2) − x(h) error {extrapolated:.3e} m");
    let ratios: Vec<f64> = errors.windows(2).map(|w| w[0] / w[1]).collect();
    eprintln!("{name}: ratios {ratios:.3?}");
    assert!(ratios.iter().all(|r| (1.7..=2.2).contains(r)), "{name}: not first order: {ratios:?} ({errors:?})");
    assert!((1.9..=2.1).contains(&ratios[3]), "{name}: not first order: {ratios:?}");
    let last = *errors.last().expect("five steps");
    assert!(last < bound, "{name}: error {last:e} m at the smallest step, bound {bound:e} m");
    assert!(extrapolated < 0.1 * last, "{name}: Richardson error {extrapolated:e} m vs {last:e} m");
}

/// The reference against linearised backward Euler written here, over one second, at 1/30 s
/// (within `bound_30`) and 1/300 s (within 2e-9 m: the f32 inputs — wind direction, masses —
/// set a floor near 1e-9 m).
fn check_against_backward_euler(name: &str, t: &SpringTopology, f: &ForceSet, bound_30: f64) {
    let net = Net::new(t, f);
    for (dt, bound) in [(1.0f64 / 30.0, bound_30), (1.0 / 300.0, 2e-9)] {
        let be = net.backward_euler(dt, 1.0, false);
        let (x64, x32) = reference_positions(t, f, dt, 1.0);
        let (d, d32) = (net.rms(&x64, &be), net.rms(&x32, &be));
        eprintln!(
            "{name}: 1/{} s: reference to backward Euler {d:.3e} m (f32 positions {d32:.3e} m)",
            (1.0 / dt).round()
        );
        assert!(d < bound, "{name}: 1/{}: the reference is {d:e} m from backward Euler", (1.0 / dt).round());
    }
}

#[test]
fn the_reference_converges_at_first_order_to_rk4_on_the_stiff_net() {
    check_first_order("stiff net", &synth::stiff_net(), &synth::stiff_net_forces(), 1.5e-5);
    // At 1/30 s (h²k/m = 111) the strongest compressions exceed the reference's compression
    // floor (`h² k (L/l − 1) > m/2`, 0.45 % here): 1.5e-5 m over the second, 0.35 % of backward
    // Euler's own error (4.4e-3 m).
    check_against_backward_euler("stiff net", &synth::stiff_net(), &synth::stiff_net_forces(), 2e-5);
}

#[test]
fn the_reference_converges_at_first_order_to_rk4_with_the_restoring_force() {
    let t = build_topology(&meshes::grid(3, 3, 0.02), TopologyKind::SPRING_STICKS, &TopologyParams::default())
        .expect("builds");
    let f = ForceSet {
        wind: Some(WindForce {
            direction: [1.0, 0.0, 0.4],
            force_n: 2e-3,
            gust_amplitude: 0.8,
            gust_frequency_hz: 5.0,
            gust_wavelength_m: 0.05,
        }),
        ..ForceSet::default()
    };
    check_first_order("spring–stick tips", &t, &f, 2e-5);
    check_against_backward_euler("spring–stick tips", &t, &f, 2e-9);
}
