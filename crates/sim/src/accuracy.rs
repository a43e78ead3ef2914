//! The accuracy-vs-time report (the user's ask "show what accuracy costs in time"): for each
//! solver × step size × implicit sweep count, the position error after one simulated second
//! against a converged reference (conjugate-gradient backward Euler at a tiny step, Baraff &
//! Witkin 1998), and the measured time per step at the fur thesis's table 4.5 sizes plus 10× and
//! 100× of the largest. Produces `docs/accuracy.md` content and hand-written SVG plots as strings;
//! the CLI (`furbake report accuracy`) writes them.
//!
//! Every number comes from running the solvers in this process: errors are deterministic, times
//! depend on the machine and its load (the report prints the thread count).

use std::fmt::Write as _;
use std::time::Instant;

use furbake_formats::sections::spring_topology::{SpringTopology, TopologyKind, TopologyParams};

use crate::forces::{ForceSet, Wind};
use crate::simulator::{Simulator, SolverKind, SolverSettings};
use crate::synth::{THESIS_TABLE_4_5, synthetic_topology};
use crate::{SimError, build_topology, meshes};

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
        "Generated by `furbake report accuracy` (library: `furbake_sim::accuracy::accuracy_report`). \
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

const W: f64 = 640.0;
const H: f64 = 400.0;
const M: f64 = 60.0;
const COLORS: [&str; 8] = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"];

/// A log–log line plot: series of (label, points).
fn loglog(title: &str, xlabel: &str, ylabel: &str, series: &[(String, Vec<(f64, f64)>)]) -> String {
    let pts = series.iter().flat_map(|s| s.1.iter()).filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.1.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        x0 = x0.min(x.log10());
        x1 = x1.max(x.log10());
        y0 = y0.min(y.log10());
        y1 = y1.max(y.log10());
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let (x0, x1, y0, y1) = (x0.floor(), x1.ceil().max(x0.floor() + 1.0), y0.floor(), y1.ceil().max(y0.floor() + 1.0));
    let px = |x: f64| M + (x.log10() - x0) / (x1 - x0) * (W - 2.0 * M);
    let py = |y: f64| H - M - (y.log10() - y0) / (y1 - y0) * (H - 2.0 * M);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" font-family=\"sans-serif\" font-size=\"11\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{}\" y=\"20\" text-anchor=\"middle\" font-size=\"14\">{title}</text>\n",
        W / 2.0
    );
    for e in x0 as i32..=x1 as i32 {
        let x = M + (e as f64 - x0) / (x1 - x0) * (W - 2.0 * M);
        let _ = writeln!(
            s,
            "<line x1=\"{x:.1}\" y1=\"{M}\" x2=\"{x:.1}\" y2=\"{}\" stroke=\"#ddd\"/><text x=\"{x:.1}\" y=\"{}\" text-anchor=\"middle\">1e{e}</text>",
            H - M,
            H - M + 15.0
        );
    }
    for e in y0 as i32..=y1 as i32 {
        let y = H - M - (e as f64 - y0) / (y1 - y0) * (H - 2.0 * M);
        let _ = writeln!(
            s,
            "<line x1=\"{M}\" y1=\"{y:.1}\" x2=\"{}\" y2=\"{y:.1}\" stroke=\"#ddd\"/><text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">1e{e}</text>",
            W - M,
            M - 4.0,
            y + 4.0
        );
    }
    let _ = writeln!(s, "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{xlabel}</text>", W / 2.0, H - 15.0);
    let _ = writeln!(
        s,
        "<text x=\"15\" y=\"{}\" transform=\"rotate(-90 15 {})\" text-anchor=\"middle\">{ylabel}</text>",
        H / 2.0,
        H / 2.0
    );
    for (i, (label, points)) in series.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        let line: Vec<String> = points
            .iter()
            .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.1.is_finite())
            .map(|&(x, y)| format!("{:.1},{:.1}", px(x), py(y)))
            .collect();
        let _ =
            writeln!(s, "<polyline points=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"2\"/>", line.join(" "));
        for p in &line {
            let (x, y) = p.split_once(',').unwrap_or(("0", "0"));
            let _ = writeln!(s, "<circle cx=\"{x}\" cy=\"{y}\" r=\"3\" fill=\"{c}\"/>");
        }
        let ly = M + 14.0 * i as f64;
        let _ = writeln!(
            s,
            "<rect x=\"{}\" y=\"{}\" width=\"10\" height=\"10\" fill=\"{c}\"/><text x=\"{}\" y=\"{}\">{label}</text>",
            W - M - 150.0,
            ly,
            W - M - 135.0,
            ly + 9.0
        );
    }
    s.push_str("</svg>\n");
    s
}

fn error_plot(rows: &[ErrorRow], topology: &str) -> String {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for r in rows.iter().filter(|r| r.topology == topology) {
        match series.iter_mut().find(|s| s.0 == r.config) {
            Some(s) => s.1.push((r.dt_s, r.rms_error_m)),
            None => series.push((r.config.clone(), vec![(r.dt_s, r.rms_error_m)])),
        }
    }
    loglog(&format!("RMS position error after 1 s ({topology})"), "step size (s)", "error (m)", &series)
}

fn timing_plot(rows: &[TimingRow]) -> String {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for r in rows {
        match series.iter_mut().find(|s| s.0 == r.solver) {
            Some(s) => s.1.push((r.links as f64, r.time_per_step_s)),
            None => series.push((r.solver.clone(), vec![(r.links as f64, r.time_per_step_s)])),
        }
    }
    loglog("Time per step", "springs + sticks", "seconds per step", &series)
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
