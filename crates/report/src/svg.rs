//! Hand-written SVG plots for `docs/accuracy.md`: a log–log line plot with a grid, axis labels
//! and a legend, and the two plots of the fur report built on it (error against step size,
//! time per step against size). No dependencies: the report's plots are plain text in the repo.

use std::fmt::Write as _;

use crate::fur::{ErrorRow, TimingRow};

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

pub(crate) fn error_plot(rows: &[ErrorRow], topology: &str) -> String {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for r in rows.iter().filter(|r| r.topology == topology) {
        match series.iter_mut().find(|s| s.0 == r.config) {
            Some(s) => s.1.push((r.dt_s, r.rms_error_m)),
            None => series.push((r.config.clone(), vec![(r.dt_s, r.rms_error_m)])),
        }
    }
    loglog(&format!("RMS position error after 1 s ({topology})"), "step size (s)", "error (m)", &series)
}

pub(crate) fn timing_plot(rows: &[TimingRow]) -> String {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for r in rows {
        match series.iter_mut().find(|s| s.0 == r.solver) {
            Some(s) => s.1.push((r.links as f64, r.time_per_step_s)),
            None => series.push((r.solver.clone(), vec![(r.links as f64, r.time_per_step_s)])),
        }
    }
    loglog("Time per step", "springs + sticks", "seconds per step", &series)
}
