//! The fur part of `docs/accuracy.md` (the user's ask "show what accuracy costs in time"): for
//! each solver × step size × implicit sweep count, the position error after one simulated second
//! against a converged reference (conjugate-gradient backward Euler at a tiny step, Baraff &
//! Witkin 1998; fur thesis eq. 3.20–3.34 and §3.4.1 for the solvers measured), and the measured
//! time per step at the fur thesis's table 4.5 sizes plus 10× and 100× of the largest. Produces
//! the markdown and its two SVG plots (`svg.rs`) as strings.
//!
//! Every number comes from running the solvers in this process: errors are deterministic, times
//! depend on the machine and its load (the report prints the thread count).

use std::fmt::Write as _;
use std::time::Instant;

use furbake_sim::synth::{THESIS_TABLE_4_5, synthetic_topology};
use furbake_sim::{
    ForceSet, SimError, Simulator, SolverKind, SolverSettings, SpringTopology, TopologyKind, TopologyParams, Wind,
    build_topology, meshes,
};

use crate::svg::{error_plot, timing_plot};

/// What the report measures.
#[derive(Clone, Debug)]
pub struct AccuracySettings {
    /// Step sizes to test, seconds. Default 1/30, 1/60, 1/100, 1/300, 1/1000, 1/3000.
    pub step_sizes_s: Vec<f64>,
    /// Implicit sweep counts (the converged case is always added). Default 1, 2, 4.
    pub implicit_iterations: Vec<u32>,
    /// Step of the converged reference run, seconds. Default 1/30000.
    pub reference_dt_s: f64,
    /// Simulated time before the error is taken, seconds. Default 1.
    pub duration_s: f64,
    /// (masses, springs) sizes for timing. Default: table 4.5, then 10× and 100× its largest.
    pub timing_sizes: Vec<(usize, usize)>,
    /// Minimum wall time spent timing one solver at one size, seconds. Default 0.3.
    pub timing_budget_s: f64,
}

impl Default for AccuracySettings {
    fn default() -> Self {
        let (m, s) = THESIS_TABLE_4_5[4];
        let mut timing_sizes = THESIS_TABLE_4_5.to_vec();
        timing_sizes.extend([(m * 10, s * 10), (m * 100, s * 100)]);
        AccuracySettings {
            step_sizes_s: vec![1.0 / 30.0, 1.0 / 60.0, 1.0 / 100.0, 1.0 / 300.0, 1.0 / 1000.0, 1.0 / 3000.0],
            implicit_iterations: vec![1, 2, 4],
            reference_dt_s: 1.0 / 30000.0,
            duration_s: 1.0,
            timing_sizes,
            timing_budget_s: 0.3,
        }
    }
}

/// One error measurement.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ErrorRow {
    /// Topology kind name.
    pub topology: String,
    /// Solver configuration (`explicit`, `implicit×1`, …, `implicit (converged)`, `stick`).
    pub config: String,
    /// Step size, seconds.
    pub dt_s: f64,
    /// Substeps per step the solver took (explicit and stick solvers below their stable step).
    pub substeps: u32,
    /// RMS position error of the free masses after `duration_s`, metres.
    pub rms_error_m: f64,
    /// Largest position error, metres.
    pub max_error_m: f64,
}

/// One timing measurement.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TimingRow {
    /// Solver name.
    pub solver: String,
    /// Masses.
    pub masses: usize,
    /// Springs + sticks.
    pub links: usize,
    /// Mean wall time per step, seconds.
    pub time_per_step_s: f64,
    /// Links updated per second.
    pub links_per_s: f64,
}

/// The generated report.
#[derive(Clone, Debug)]
pub struct AccuracyReport {
    /// `docs/accuracy.md`.
    pub markdown: String,
    /// (file name, SVG text) of the plots the markdown links to.
    pub plots: Vec<(String, String)>,
    /// Raw error rows.
    pub errors: Vec<ErrorRow>,
    /// Raw timing rows.
    pub timings: Vec<TimingRow>,
    /// The reference's own error: RMS difference between the reference at `reference_dt_s` and
    /// at twice that step, metres, per topology.
    pub reference_self_error_m: Vec<(String, f64)>,
}

/// Wind and the restoring force, no gravity: with gravity along the hair, eq. 3.37 cannot hold fur
/// upright (its pull grows with the cube of the tilt, gravity's torque linearly), so which way
/// each hair falls depends on round-off and no step size converges — a poor yardstick.
fn scene_forces() -> ForceSet {
    ForceSet {
        gravity_m_per_s2: [0.0; 3],
        wind: Some(Wind {
            direction: [1.0, 0.0, 0.4],
            force_n: 3e-4,
            gust_amplitude: 0.8,
            gust_frequency_hz: 2.0,
            gust_wavelength_m: 0.05,
        }),
        ..ForceSet::default()
    }
}

fn settings_for(kind: SolverKind, iterations: u32) -> SolverSettings {
    SolverSettings {
        implicit_iterations: iterations,
        max_link_rotation_rad: 0.0,
        max_substeps: 100_000,
        track_energy: false,
        ..SolverSettings::of(kind)
    }
}

fn simulate(t: &SpringTopology, s: SolverSettings, dt: f64, duration: f64) -> Result<(Vec<[f32; 3]>, u32), SimError> {
    let mut sim = Simulator::new(t, s)?;
    sim.set_forces(scene_forces())?;
    let steps = (duration / dt).round().max(1.0) as u64;
    let mut substeps = 1;
    for _ in 0..steps {
        substeps = sim.step(dt)?.substeps;
    }
    Ok((sim.positions(), substeps))
}

fn errors(t: &SpringTopology, a: &[[f32; 3]], b: &[[f32; 3]]) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    for i in 0..a.len() {
        if t.mass_anchored[i] != 0 {
            continue;
        }
        let d2: f64 = (0..3).map(|k| (a[i][k] as f64 - b[i][k] as f64).powi(2)).sum();
        sum += d2;
        max = max.max(d2.sqrt());
        n += 1;
    }
    ((sum / n.max(1) as f64).sqrt(), max)
}

/// Runs every measurement and renders the report.
pub fn accuracy_report(settings: &AccuracySettings) -> Result<AccuracyReport, SimError> {
    let mesh = meshes::grass_patch(0.02);
    let params = TopologyParams::default();
    let mut error_rows = Vec::new();
    let mut self_errors = Vec::new();
    for kind in [TopologyKind::PRISMS, TopologyKind::STICKS] {
        let t = build_topology(&mesh, kind, &params)?;
        let reference_settings =
            SolverSettings { reference_tolerance: 1e-12, ..settings_for(SolverKind::Reference, 1) };
        let (truth, _) = simulate(&t, reference_settings.clone(), settings.reference_dt_s, settings.duration_s)?;
        let (coarse, _) = simulate(&t, reference_settings, 2.0 * settings.reference_dt_s, settings.duration_s)?;
        self_errors.push((kind.to_string(), errors(&t, &truth, &coarse).0));
        let mut configs: Vec<(String, SolverKind, u32)> = vec![("explicit".into(), SolverKind::Explicit, 1)];
        for &it in &settings.implicit_iterations {
            configs.push((format!("implicit×{it}"), SolverKind::Implicit, it));
        }
        configs.push(("implicit (converged)".into(), SolverKind::Reference, 1));
        configs.push(("stick".into(), SolverKind::Stick, 1));
        for (name, solver, it) in configs {
            for &dt in &settings.step_sizes_s {
                let (rms, max, substeps) = match simulate(&t, settings_for(solver, it), dt, settings.duration_s) {
                    Ok((pos, sub)) => {
                        let (r, m) = errors(&t, &pos, &truth);
                        (r, m, sub)
                    }
                    Err(SimError::NonFinite { .. }) => (f64::INFINITY, f64::INFINITY, 0),
                    Err(e) => return Err(e),
                };
                error_rows.push(ErrorRow {
                    topology: kind.to_string(),
                    config: name.clone(),
                    dt_s: dt,
                    substeps,
                    rms_error_m: rms,
                    max_error_m: max,
                });
            }
        }
    }

    let mut timing_rows = Vec::new();
    for &(masses, links) in &settings.timing_sizes {
        for solver in SolverKind::ALL {
            let Some(t) = synthetic_topology(masses, links, solver == SolverKind::Stick, &params) else {
                return Err(SimError::Parameter {
                    name: "timing_sizes",
                    what: format!("{masses} masses / {links} links"),
                });
            };
            let mut probe = Simulator::new(&t, SolverSettings::of(SolverKind::Explicit))?;
            let dt = probe.stable_step_s().min(1.0 / 60.0);
            let mut sim = Simulator::new(&t, SolverSettings { track_energy: false, ..SolverSettings::of(solver) })?;
            sim.set_forces(ForceSet::default())?;
            sim.step(dt)?; // warm-up
            let start = Instant::now();
            let mut steps = 0u32;
            while steps < 3 || start.elapsed().as_secs_f64() < settings.timing_budget_s {
                sim.step(dt)?;
                steps += 1;
            }
            let per = start.elapsed().as_secs_f64() / steps as f64;
            timing_rows.push(TimingRow {
                solver: solver.name().into(),
                masses,
                links,
                time_per_step_s: per,
                links_per_s: links as f64 / per,
            });
        }
    }
    let plots = vec![
        ("accuracy_error.svg".to_owned(), error_plot(&error_rows, "prisms")),
        ("accuracy_time.svg".to_owned(), timing_plot(&timing_rows)),
    ];
    let markdown = render_markdown(settings, &error_rows, &timing_rows, &self_errors);
    Ok(AccuracyReport {
        markdown,
        plots,
        errors: error_rows,
        timings: timing_rows,
        reference_self_error_m: self_errors,
    })
}

fn fmt_err(e: f64) -> String {
    if e.is_finite() { format!("{e:.2e}") } else { "diverged".into() }
}

fn render_markdown(
    s: &AccuracySettings,
    errors: &[ErrorRow],
    timings: &[TimingRow],
    self_err: &[(String, f64)],
) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Accuracy vs time of the fur solvers\n");
    let _ = writeln!(
        md,
        "Generated by `furbake report accuracy` (library: `furbake_report::fur::accuracy_report`). \
         Scene: the fur thesis's grass patch (V=13, F=16), 2 cm fur, default topology parameters \
         (tip mass 1e-4 kg, 10 N/m, 0.005 N·s/m), gusty wind (3e-4 N, 80 % gusts at 2 Hz), \
         restoring weight 0.01 N, no gravity (with gravity along the hair eq. 3.37 cannot hold fur \
         upright — its pull grows with the cube of the tilt — so which way each hair falls depends \
         on round-off and no step converges). Error = position error of the free masses after {} s against the \
         converged reference: backward Euler linearised per step and solved by conjugate gradient to a \
         relative residual of 1e-12 at dt = {:.2e} s. The link-rotation limit is off, so every solver \
         runs its raw scheme; the explicit and stick solvers still substep below their stable step \
         (column *substeps*).\n",
        s.duration_s, s.reference_dt_s
    );
    for (topo, e) in self_err {
        let _ = writeln!(md, "- Reference self-check ({topo}): RMS difference between dt and 2·dt runs: {e:.2e} m.");
    }
    let _ = writeln!(md, "\n![position error vs step](accuracy_error.svg)\n");
    for topo in ["prisms", "sticks"] {
        let _ = writeln!(md, "## Position error after {} s — {topo}\n", s.duration_s);
        let mut header = "| solver |".to_owned();
        let mut rule = "|---|".to_owned();
        for dt in &s.step_sizes_s {
            let _ = write!(header, " dt = 1/{:.0} s |", 1.0 / dt);
            rule.push_str("---|");
        }
        let _ = writeln!(md, "{header}\n{rule}");
        let mut configs: Vec<&str> = Vec::new();
        for r in errors.iter().filter(|r| r.topology == topo) {
            if !configs.contains(&r.config.as_str()) {
                configs.push(&r.config);
            }
        }
        for c in configs {
            let mut line = format!("| {c} |");
            for dt in &s.step_sizes_s {
                if let Some(r) = errors.iter().find(|r| r.topology == topo && r.config == c && r.dt_s == *dt) {
                    let sub = if r.substeps > 1 { format!(" ({} substeps)", r.substeps) } else { String::new() };
                    let _ = write!(line, " {} m{sub} |", fmt_err(r.rms_error_m));
                }
            }
            let _ = writeln!(md, "{line}");
        }
        let _ = writeln!(md);
    }
    let _ = writeln!(
        md,
        "## Time per step\n\nSynthetic topologies of exactly the thesis's table 4.5 sizes and 10× / 100× its \
         largest (half the masses anchored roots, one root–tip link each, the rest tip–tip springs; \
         sticks for the stick solver). One step at the explicit solver's stable step, guard on, \
         statistics off, {} rayon threads. Throughput = links (springs + sticks) updated per second.\n",
        rayon::current_num_threads()
    );
    let _ = writeln!(md, "![time per step](accuracy_time.svg)\n");
    let _ =
        writeln!(md, "| masses | links | explicit | implicit×1 | stick | converged (CG) |\n|---|---|---|---|---|---|");
    let mut sizes: Vec<(usize, usize)> = timings.iter().map(|t| (t.masses, t.links)).collect();
    sizes.dedup();
    for (m, l) in sizes {
        let mut line = format!("| {m} | {l} |");
        for solver in ["explicit", "implicit", "stick", "reference"] {
            if let Some(t) = timings.iter().find(|t| t.masses == m && t.links == l && t.solver == solver) {
                let _ = write!(line, " {:.3} ms ({:.1} M/s) |", t.time_per_step_s * 1e3, t.links_per_s / 1e6);
            }
        }
        let _ = writeln!(md, "{line}");
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quick report on small settings: every table row and both plots are produced, errors
    /// shrink with the step for the converged implicit solver, and the markdown names every
    /// configuration.
    #[test]
    fn quick_report_is_complete() {
        let s = AccuracySettings {
            step_sizes_s: vec![1.0 / 30.0, 1.0 / 300.0],
            implicit_iterations: vec![1, 2],
            reference_dt_s: 1.0 / 3000.0,
            duration_s: 0.2,
            timing_sizes: vec![(200, 300)],
            timing_budget_s: 0.0,
        };
        let r = accuracy_report(&s).expect("runs");
        // 2 topologies × (explicit, implicit×1, ×2, converged, stick) × 2 steps.
        assert_eq!(r.errors.len(), 2 * 5 * 2);
        assert_eq!(r.timings.len(), 4);
        assert_eq!(r.plots.len(), 2);
        assert!(r.plots.iter().all(|(_, svg)| svg.starts_with("<svg") && svg.contains("polyline")));
        for c in ["explicit", "implicit×1", "implicit×2", "implicit (converged)", "stick", "| 200 | 300 |"] {
            assert!(r.markdown.contains(c), "markdown lacks {c}");
        }
        let conv: Vec<&ErrorRow> =
            r.errors.iter().filter(|e| e.topology == "prisms" && e.config == "implicit (converged)").collect();
        assert!(conv[1].rms_error_m < conv[0].rms_error_m, "{conv:?}");
    }
}
