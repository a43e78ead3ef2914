//! The short fuzzing run CI does (`make fuzz` runs the long one): every target through the
//! `furbake-fuzz` supervisor with a fixed seed, zero failures expected, and outcome counts that
//! prove each target reached what it is meant to exercise (packs that pass the checksums and fail
//! semantically, packs that verify and step; glTF files that import and bake; scenes that step). A
//! canary run first proves the supervisor sees panics, aborts, exhausted memory and hangs,
//! attributes them to their cases and saves reproducers.

use std::collections::BTreeMap;
use std::process::Command;

const SEED: &str = "20261130";

/// One target's line of the report: cases, failures, outcome counts.
type TargetReport = (u64, u64, BTreeMap<String, u64>);

/// Runs the binary; returns its exit code and its report by target.
fn fuzz(args: &[&str]) -> (i32, BTreeMap<String, TargetReport>) {
    let out = Command::new(env!("CARGO_BIN_EXE_furbake-fuzz")).args(args).output().expect("furbake-fuzz runs");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let mut report = BTreeMap::new();
    let mut current = String::new();
    for line in stdout.lines() {
        if let Some((target, rest)) = line.split_once(": ").filter(|_| !line.starts_with(' ')) {
            let n = |k: usize| rest.split(' ').nth(k).and_then(|x| x.trim_end_matches(',').parse().ok()).unwrap_or(0);
            current = target.to_owned();
            report.insert(current.clone(), (n(0), n(2), BTreeMap::new()));
        } else if let Some((outcome, n)) = line.trim().split_once(": ") {
            if let (Some(entry), Ok(n)) = (report.get_mut(&current), n.parse::<u64>()) {
                entry.2.insert(outcome.to_owned(), n);
            }
        }
    }
    eprintln!("{stdout}{}", String::from_utf8_lossy(&out.stderr));
    (out.status.code().unwrap_or(-1), report)
}

fn sum(outcomes: &BTreeMap<String, u64>, pattern: &str) -> u64 {
    outcomes.iter().filter(|(k, _)| k.contains(pattern)).map(|(_, n)| n).sum()
}

#[test]
fn the_supervisor_catches_panics_aborts_memory_and_hangs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let args = ["--canary", "10", "--hang-s", "2", "--max-memory-mib", "1024", "--out", out, "--seed", SEED];
    let (code, report) = fuzz(&args);
    assert_eq!(code, 1, "failures exit 1");
    let (cases, failures, outcomes) = &report["canary"];
    assert_eq!((*cases, *failures), (10, 8), "cases 1–4 and 6–9 fail");
    assert_eq!(outcomes.get("fine"), Some(&2));
    let saved = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "bin"))
        .count();
    assert_eq!(saved, 8, "one reproducer per failure");
}

#[test]
fn a_short_campaign_of_every_target_finds_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    // Generous per-case budgets: this is the debug profile on a shared 2-core machine.
    let args =
        ["--packs", "10000", "--gltf", "400", "--scenes", "400", "--seed", SEED, "--out", out, "--slow-ms", "20000"];
    let (code, report) = fuzz(&args);
    assert_eq!(code, 0, "no case may fail");
    let (packs, gltf, scenes) = (&report["packs"], &report["gltf"], &report["scenes"]);
    assert_eq!((packs.0, packs.1), (10000, 0));
    assert_eq!((gltf.0, gltf.1), (400, 0));
    assert_eq!((scenes.0, scenes.1), (400, 0));
    // Each level of the pack checks was reached, and verified mutants ran in a world.
    for outcome in ["ContainerRejected", "SectionRejected", "Inconsistent", "Verified", "/Stepped"] {
        assert!(sum(&packs.2, outcome) >= 10, "packs: too few {outcome}: {:?}", packs.2);
    }
    for outcome in ["ImportRejected", "BakedAndVerified"] {
        assert!(sum(&gltf.2, outcome) >= 10, "gltf: too few {outcome}: {:?}", gltf.2);
    }
    for outcome in ["SceneRejected", "Stepped"] {
        assert!(sum(&scenes.2, outcome) >= 10, "scenes: too few {outcome}: {:?}", scenes.2);
    }
}
