//! How far a walking Fox's fur lags behind its skin, and how it settles when the Fox stops: the
//! angle between one hair's scale vector (where the physics holds it) and the posed skin normal
//! (where it stands at rest), every step, for each solver given, in the scene
//! `fixtures/scenes/fox_walk_stop.toml`: the Fox plays `Walk` for 2 s, then cross-fades in 0.25 s
//! into `Survey` (it stands and looks round) for 2 s more, under gravity, at the game step of
//! 0.02 s.
//!
//! `cargo run --release -p furbake-runtime --example fur_lag -- [OUT.svg] [SOLVER ...]`
//! (SOLVER: auto, implicit, xpbd, local_global, …, or KIND:N with N iterations; default auto
//! implicit). Prints one CSV
//! row per step (time, then one angle in degrees per solver) and writes the chart to OUT.svg
//! (default `fur_lag.svg`).
//!
//! The hair: the furry skin vertex lowest in the bind pose (a paw of a front leg, where the skin
//! moves fastest). The Fox (fixtures/real/Fox.glb) is baked as `make demo` bakes it (`--preset
//! fur --topology prisms`) into a temporary folder.

#[path = "common/fox.rs"]
mod fox;

use std::fmt::Write as _;
use std::path::PathBuf;

use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_runtime::{Scene, World};
use glam::Vec3;

const STEP_S: f64 = 0.02;
const STEPS: usize = 200;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args.iter().find(|a| a.ends_with(".svg")).map_or_else(|| PathBuf::from("fur_lag.svg"), PathBuf::from);
    let mut solvers: Vec<String> = args.iter().filter(|a| !a.ends_with(".svg")).cloned().collect();
    if solvers.is_empty() {
        solvers = vec!["auto".into(), "implicit".into()];
    }
    let dir = tempfile::tempdir().expect("a temporary folder");
    let fox = fox::bake_fox(dir.path());
    let vertex = lowest_furry_vertex(&fox);
    let mut series: Vec<(String, Vec<f64>)> = Vec::new();
    for solver in &solvers {
        let scene = Scene::from_toml_str(&lag_scene(solver), "fur_lag.toml".as_ref(), dir.path()).expect("valid scene");
        let mut world = World::new(scene).expect("the world builds");
        let mut angles = Vec::with_capacity(STEPS);
        for _ in 0..STEPS {
            world.step().expect("steps");
            let s = Vec3::from(world.fur(0).expect("the Fox's fur").scale_vectors[vertex]);
            let n = Vec3::from(world.animation(0).expect("the Fox's animation").normals()[vertex]);
            angles.push(s.angle_between(n).to_degrees() as f64);
        }
        let name = world.fur(0).and_then(|f| f.simulation).map_or(solver.clone(), |(_, k)| k.name().to_owned());
        let name = match solver.split_once(':') {
            Some((_, n)) => format!("{name} ×{n}"),
            None if solver == "auto" => format!("auto ({name})"),
            None => name,
        };
        series.push((name, angles));
    }
    println!("time_s,{}", series.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(","));
    for k in 0..STEPS {
        let row: Vec<String> = series.iter().map(|(_, a)| format!("{:.3}", a[k])).collect();
        println!("{:.2},{}", (k + 1) as f64 * STEP_S, row.join(","));
    }
    std::fs::write(&out, chart(&series)).expect("the chart is written");
    eprintln!("wrote {} (hair at skin vertex {vertex})", out.display());
}

/// `fixtures/scenes/fox_walk_stop.toml` with `[solver] kind = solver`.
fn lag_scene(solver: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/fox_walk_stop.toml");
    let text = std::fs::read_to_string(&path).expect("the scene fixture");
    // `kind:N` also sets the kind's iteration count.
    let (kind, iterations) = match solver.split_once(':') {
        Some((kind, n)) => (kind, format!("{kind}_iterations = {n}\n")),
        None => (solver, String::new()),
    };
    format!("{text}\n[solver]\nkind = \"{kind}\"\n{iterations}")
}

/// The vertex of a furry triangle with the lowest bind-pose height.
fn lowest_furry_vertex(skin: &SkinMesh) -> usize {
    let furry = skin.triangles.iter().zip(&skin.fur_mask).filter(|(_, m)| **m != 0).flat_map(|(t, _)| *t);
    furry
        .map(|v| v as usize)
        .min_by(|&a, &b| skin.positions[a][1].total_cmp(&skin.positions[b][1]))
        .expect("a furry vertex")
}

/// A line chart of the angles against time (SVG, no dependencies).
fn chart(series: &[(String, Vec<f64>)]) -> String {
    let (w, h, left, top, right, bottom) = (720.0, 320.0, 56.0, 20.0, 170.0, 40.0);
    let max = series.iter().flat_map(|(_, a)| a.iter().copied()).fold(1.0f64, f64::max);
    let top_deg = (max / 10.0).ceil() * 10.0;
    let t_end = STEPS as f64 * STEP_S;
    let x = |t: f64| left + (w - left - right) * t / t_end;
    let y = |d: f64| top + (h - top - bottom) * (1.0 - d / top_deg);
    let colors = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"];
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n"
    );
    for k in 0..=4 {
        let d = top_deg * k as f64 / 4.0;
        let _ = writeln!(
            s,
            "<line x1=\"{left}\" x2=\"{:.1}\" y1=\"{:.1}\" y2=\"{:.1}\" stroke=\"#ddd\"/><text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{d:.0}°</text>",
            w - right,
            y(d),
            y(d),
            left - 6.0,
            y(d) + 4.0
        );
    }
    for t in 0..=(t_end as usize) {
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{t} s</text>",
            x(t as f64),
            h - bottom + 16.0
        );
    }
    let _ = writeln!(
        s,
        "<line x1=\"{0:.1}\" x2=\"{0:.1}\" y1=\"{top}\" y2=\"{1:.1}\" stroke=\"#888\" stroke-dasharray=\"4 3\"/><text x=\"{2:.1}\" y=\"{3:.1}\">stops (Walk → Survey)</text>",
        x(2.0),
        h - bottom,
        x(2.0) + 4.0,
        top + 12.0
    );
    for (i, (name, angles)) in series.iter().enumerate() {
        let c = colors[i % colors.len()];
        let points: Vec<String> =
            angles.iter().enumerate().map(|(k, &d)| format!("{:.1},{:.1}", x((k + 1) as f64 * STEP_S), y(d))).collect();
        let _ = writeln!(
            s,
            "<polyline fill=\"none\" stroke=\"{c}\" stroke-width=\"1.5\" points=\"{}\"/>",
            points.join(" ")
        );
        let ly = top + 14.0 + 18.0 * i as f64;
        let _ = writeln!(
            s,
            "<line x1=\"{0:.1}\" x2=\"{1:.1}\" y1=\"{ly:.1}\" y2=\"{ly:.1}\" stroke=\"{c}\" stroke-width=\"2\"/><text x=\"{2:.1}\" y=\"{3:.1}\">{name}</text>",
            w - right + 10.0,
            w - right + 30.0,
            w - right + 36.0,
            ly + 4.0
        );
    }
    let _ = writeln!(
        s,
        "<text x=\"14\" y=\"{:.1}\" transform=\"rotate(-90 14 {:.1})\" text-anchor=\"middle\">hair lag behind the skin normal</text>\n</svg>",
        top + (h - top - bottom) / 2.0,
        top + (h - top - bottom) / 2.0
    );
    s
}
