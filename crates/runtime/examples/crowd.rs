//! CPU cost of a crowd of walking Foxes: per-step wall time of `World::step` for 1, 10 and 100
//! Foxes (or the counts given), each playing Walk with its own start time, under gravity, on one
//! worker and on every core (the world steps its packs side by side on rayon's workers).
//!
//! `cargo run --release -p furbake-runtime --example crowd -- [SOLVER] [STEPS] [N ...]`
//! (SOLVER: implicit, xpbd, local_global, …; default implicit, 100 steps, 1 10 100 Foxes).
//!
//! The Fox (fixtures/real/Fox.glb) is baked as `make demo` bakes it (`--preset fur --topology
//! prisms`) into a temporary folder; every Fox reads the same pack. Steps of 0.02 s; the first 10
//! steps warm up and are not timed. Statistics off (`WorldOptions::step_statistics = false`, as a
//! game runs). Prints, per crowd and thread count: mean and 90th-percentile step time, time per
//! Fox, the speed-up over one worker, and the median substeps of the last step over the Foxes.

#[path = "common/fox.rs"]
mod fox;

use std::time::Instant;

use furbake_runtime::{Scene, World, WorldOptions};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let solver = args.first().cloned().unwrap_or_else(|| "implicit".into());
    let steps: usize = args.get(1).map_or(100, |s| s.parse().expect("STEPS is a number"));
    let counts: Vec<usize> = if args.len() > 2 {
        args[2..].iter().map(|s| s.parse().expect("N is a number")).collect()
    } else {
        vec![1, 10, 100]
    };
    let dir = tempfile::tempdir().expect("a temporary folder");
    fox::bake_fox(dir.path());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("solver {solver}, {steps} steps of 0.02 s after 10 warm-up steps, {cores} cores");
    println!("foxes threads  mean ms/step  p90 ms/step  µs per fox  speed-up  substeps (median)");
    for &n in &counts {
        let mut one_worker = None;
        let mut threads = vec![1];
        if cores > 1 {
            threads.push(cores);
        }
        for &t in &threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().expect("a thread pool");
            let mut world = World::with_options(
                Scene::from_toml_str(&crowd_scene(n, &solver), "crowd.toml".as_ref(), dir.path()).expect("valid scene"),
                WorldOptions { step_statistics: false, ..WorldOptions::default() },
            )
            .expect("the world builds");
            let mut times = pool.install(|| {
                for _ in 0..10 {
                    world.step().expect("steps");
                }
                (0..steps)
                    .map(|_| {
                        let started = Instant::now();
                        world.step().expect("steps");
                        started.elapsed().as_secs_f64() * 1e3
                    })
                    .collect::<Vec<f64>>()
            });
            times.sort_by(f64::total_cmp);
            let mean = times.iter().sum::<f64>() / times.len() as f64;
            let p90 = times[(times.len() * 9 / 10).min(times.len() - 1)];
            let base = *one_worker.get_or_insert(mean);
            let mut substeps: Vec<u32> = (0..n).map(|i| world.fur(i).expect("a fox").last_step.substeps).collect();
            substeps.sort_unstable();
            println!(
                "{n:5} {t:7}  {mean:12.3}  {p90:11.3}  {:10.1}  {:8.2}  {}",
                mean * 1e3 / n as f64,
                base / mean,
                substeps[n / 2]
            );
        }
    }
}

/// `n` Foxes (centimetres, placed at scale 0.01) on a grid 1.5 m apart, each walking with its
/// own start time, under gravity.
fn crowd_scene(n: usize, solver: &str) -> String {
    let mut s = format!("time_step_s = 0.02\n[solver]\nkind = \"{solver}\"\n[effects.gravity]\n");
    let side = (n as f64).sqrt().ceil() as usize;
    for i in 0..n {
        let (x, z) = ((i % side) as f32 * 1.5, (i / side) as f32 * 1.5);
        s += &format!(
            "[[packs]]\nname = \"fox{i}\"\npath = \"fox.fbk\"\nscale = 0.01\ntranslation = [{x}, 0.0, {z}]\n\
             animation = {{ clip = \"Walk\", start_s = {:.3} }}\n",
            (i as f32 * 0.137) % 1.0
        );
    }
    s
}
