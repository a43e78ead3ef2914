//! Time per step of the implicit (1 sweep), XPBD and local/global solvers on the fur thesis's
//! largest table 4.5 size (18,152 masses / 36,292 springs), same run, same step (1/60 s),
//! guard on, energy tracking off. `cargo run -p furbake-sim --example peers_timing [--release]`.

use std::time::Instant;

use furbake_formats::sections::spring_topology::TopologyParams;
use furbake_sim::synth::synthetic_topology;
use furbake_sim::{ForceSet, SimError, Simulator, SolverKind, SolverSettings};

fn main() -> Result<(), SimError> {
    let (masses, links) = (18_152, 36_292);
    let t = synthetic_topology(masses, links, false, &TopologyParams::default())
        .ok_or(SimError::InvalidInput("size".into()))?;
    for kind in [SolverKind::Implicit, SolverKind::Xpbd, SolverKind::LocalGlobal] {
        let built = Instant::now();
        let mut sim = Simulator::new(&t, SolverSettings { track_energy: false, ..SolverSettings::of(kind) })?;
        let build_s = built.elapsed().as_secs_f64();
        sim.set_forces(ForceSet::default())?;
        let first = Instant::now();
        sim.step(1.0 / 60.0)?; // the local/global solver factors here
        let first_s = first.elapsed().as_secs_f64();
        let start = Instant::now();
        let mut steps = 0;
        while steps < 5 || start.elapsed().as_secs_f64() < 2.0 {
            sim.step(1.0 / 60.0)?;
            steps += 1;
        }
        let per = start.elapsed().as_secs_f64() / steps as f64;
        println!(
            "{masses} masses / {links} springs  {:13} build {:8.1} ms  first step {:8.2} ms  step {:8.3} ms ({steps} steps)",
            kind.name(),
            build_s * 1e3,
            first_s * 1e3,
            per * 1e3
        );
    }
    Ok(())
}
