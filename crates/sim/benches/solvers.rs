//! Steps/s and spring updates/s of every solver at the fur thesis's table 4.5 sizes (3,744
//! masses / 1,872 springs … 18,152 / 36,292) and at 10× and 100× the largest. Throughput is in
//! links (springs + sticks) per second, i.e. spring updates/s; one "step" is one solver step at
//! the explicit solver's stable step (no substeps), guard on, energy tracking off.
//!
//! `cargo bench -p furbake-sim` (filter with e.g. `-- explicit/18152`).

use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use furbake_formats::sections::spring_topology::TopologyParams;
use furbake_sim::synth::{THESIS_TABLE_4_5, synthetic_topology};
use furbake_sim::{ForceSet, Simulator, SolverKind, SolverSettings};

fn sizes() -> Vec<(usize, usize)> {
    let mut s = THESIS_TABLE_4_5.to_vec();
    let (m, k) = THESIS_TABLE_4_5[4];
    s.push((m * 10, k * 10));
    s.push((m * 100, k * 100));
    s
}

fn bench(c: &mut Criterion) {
    let params = TopologyParams::default();
    for (masses, links) in sizes() {
        let mut group = c.benchmark_group(format!("{masses}m_{links}s"));
        group.sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(2));
        group.throughput(Throughput::Elements(links as u64));
        for solver in SolverKind::ALL {
            // Built on the first call only: criterion calls the routine only for benchmarks that
            // match the command line's filter, so filtered-out sizes cost no setup.
            let mut state: Option<(Simulator, f64)> = None;
            group.bench_function(solver.name(), |b| {
                let (sim, dt) = state.get_or_insert_with(|| {
                    let topo =
                        synthetic_topology(masses, links, solver == SolverKind::Stick, &params).expect("valid size");
                    let settings = SolverSettings { track_energy: false, ..SolverSettings::of(solver) };
                    let mut sim = Simulator::new(&topo, settings).expect("valid topology");
                    sim.set_forces(ForceSet::default()).expect("valid forces");
                    // One step at the explicit solver's stable step, so nobody substeps.
                    let mut probe =
                        Simulator::new(&topo, SolverSettings::of(SolverKind::Explicit)).expect("valid topology");
                    let dt = probe.stable_step_s().min(1.0 / 60.0);
                    (sim, dt)
                });
                let dt = *dt;
                b.iter(|| sim.step(dt).expect("stable step"))
            });
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
