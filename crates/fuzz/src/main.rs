//! `furbake-fuzz`: the fuzzing campaign's command line (the work is in the library).
//!
//! ```text
//! furbake-fuzz [--packs N] [--gltf N] [--scenes N] [--pipelines N] [--canary N] [--seed S] [--out DIR]
//!              [--slow-ms MS] [--hang-s S] [--max-memory-mib MIB] [--steps N]
//!              [--cli PATH/TO/furbake] [--cli-every K]
//! furbake-fuzz replay TARGET FILE [...]      # one reproducer, in-process, panics shown
//! furbake-fuzz worker TARGET FROM TO [...]   # what the supervisor runs
//! ```
//!
//! `--pipelines N` runs the `furbake` binary that `--cli` names in hostile build pipelines
//! (`furbake_fuzz::pipelines`); it needs `--cli`, GNU make and ninja.
//!
//! Prints per target the cases run, their outcomes, the slowest case and the wall time, and
//! every failure with its seed and case; exits 1 when any case failed, 2 on bad usage.

use std::path::PathBuf;
use std::time::Duration;

use furbake_fuzz::campaign::{self, Config, Corpus, Target};

fn usage(msg: &str) -> ! {
    eprintln!("furbake-fuzz: {msg}");
    std::process::exit(2)
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut config = Config {
        seed: 1,
        slow: Duration::from_secs(5),
        hang: Duration::from_secs(60),
        max_memory_mib: 4096,
        cli: None,
        cli_every: 10,
        steps: 3,
        out_dir: PathBuf::from("target/fuzz-reproducers"),
    };
    let mut counts: Vec<(Target, u64)> = Vec::new();
    let mut positional = Vec::new();
    let mut i = 0;
    while i < args.len() {
        let flag = args[i].clone();
        if !flag.starts_with("--") {
            positional.push(flag);
            i += 1;
            continue;
        }
        let value = args.get(i + 1).cloned().unwrap_or_else(|| usage(&format!("{flag} needs a value")));
        let number = || value.parse::<u64>().unwrap_or_else(|_| usage(&format!("{flag} {value}: not a number")));
        match flag.as_str() {
            "--seed" => config.seed = number(),
            "--slow-ms" => config.slow = Duration::from_millis(number()),
            "--hang-s" => config.hang = Duration::from_secs(number().max(1)),
            "--max-memory-mib" => config.max_memory_mib = number(),
            "--steps" => config.steps = number() as u32,
            "--cli-every" => config.cli_every = number().max(1),
            // Absolute: the binary runs in a fresh directory per case.
            "--cli" => {
                config.cli =
                    Some(std::fs::canonicalize(&value).unwrap_or_else(|e| usage(&format!("--cli {value}: {e}"))))
            }
            "--out" => config.out_dir = PathBuf::from(&value),
            _ => match Target::from_name(flag.trim_start_matches("--")) {
                Some(t) => counts.push((t, number())),
                None => usage(&format!("unknown flag {flag}")),
            },
        }
        i += 2;
    }
    args.clear();
    match positional.first().map(String::as_str) {
        Some("worker") => {
            let [_, target, from, to] = &positional[..] else { usage("worker TARGET FROM TO") };
            let target = Target::from_name(target).unwrap_or_else(|| usage("unknown target"));
            let (from, to) = (from.parse().unwrap_or(0), to.parse().unwrap_or(0));
            if let Err(e) = campaign::worker(target, &config, from, to) {
                eprintln!("furbake-fuzz worker: {e}");
                std::process::exit(3);
            }
        }
        Some("replay") => {
            let [_, target, file] = &positional[..] else { usage("replay TARGET FILE") };
            let target = Target::from_name(target).unwrap_or_else(|| usage("unknown target"));
            let bytes = std::fs::read(file).unwrap_or_else(|e| usage(&format!("{file}: {e}")));
            let ext = file.rsplit('.').next().unwrap_or("bin").to_owned();
            let corpus = Corpus::new(target).unwrap_or_else(|e| usage(&e));
            let started = std::time::Instant::now();
            // Pack cases run in a scene chosen per case: replay every scene variant.
            for case in 0..if target == Target::Packs { 16 } else { 1 } {
                let r = corpus.run(target, &config, config.seed, case, &bytes, &ext);
                println!("{r:?} ({:?})", started.elapsed());
            }
        }
        Some(other) => usage(&format!("unknown command {other}")),
        None => {
            if counts.is_empty() {
                usage("nothing to do: give --packs N, --gltf N, --scenes N, --pipelines N");
            }
            if counts.iter().any(|(t, _)| *t == Target::Pipelines) && config.cli.is_none() {
                usage("--pipelines needs --cli PATH/TO/furbake");
            }
            let exe = std::env::current_exe().unwrap_or_else(|e| usage(&format!("own path: {e}")));
            let mut failed = 0;
            for (target, n) in counts {
                let report = campaign::supervise(&exe, target, &config, n, true).unwrap_or_else(|e| {
                    eprintln!("furbake-fuzz: {e}");
                    std::process::exit(3)
                });
                println!(
                    "{}: {} cases, {} failures, seed {}, slowest {} ms, {:.1} s",
                    target.name(),
                    report.cases,
                    report.failures.len(),
                    config.seed,
                    report.slowest_ms,
                    report.wall.as_secs_f64()
                );
                for (outcome, n) in &report.outcomes {
                    println!("  {outcome}: {n}");
                }
                for f in &report.failures {
                    println!("  FAILED case {} ({}): {}", f.case, f.kind, f.message);
                }
                failed += report.failures.len();
            }
            if failed > 0 {
                println!("{failed} failures; reproducers in {}", config.out_dir.display());
                std::process::exit(1);
            }
        }
    }
}
