//! A short run of the pipelines fuzzer (`crates/fuzz/src/pipelines.rs`) through the `furbake`
//! binary itself, with a fixed seed: hostile outputs (devices, FIFOs, directories, inputs and
//! other outputs, spelled every way), hostile depfile names driven through the real GNU make and
//! ninja, planted manifests under `batch`, and special files as every input (docs/design.md
//! "Safe outputs", "Depfiles" and "Bounded reads"). No case may fail, and the outcome counts
//! prove each surface reached what it is meant to exercise. `make fuzz` runs a longer campaign
//! (`furbake-fuzz --pipelines N --cli target/debug/furbake`).

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use furbake_fuzz::pipelines::{Fixture, Limits, OPEN_FINDINGS, PipelineCase, run_case};

const SEED: u64 = 20261201;
const CASES: u64 = 150;

fn sum(outcomes: &BTreeMap<String, u32>, prefix: &str, suffix: &str) -> u32 {
    outcomes.iter().filter(|(k, _)| k.starts_with(prefix) && k.ends_with(suffix)).map(|(_, n)| n).sum()
}

#[test]
fn hostile_pipelines_are_refused_or_read_back_exactly() {
    let furbake = Path::new(env!("CARGO_BIN_EXE_furbake"));
    let fixture = Fixture::new().expect("the fuzzer's mesh");
    // Generous: this is the debug build on a shared 2-core machine; a hang still fails.
    let limits = Limits { max_memory_mib: 2048, command: Duration::from_secs(30) };
    let mut outcomes: BTreeMap<String, u32> = BTreeMap::new();
    let mut failures = Vec::new();
    for case in 0..CASES {
        let c = PipelineCase::generate(SEED, case);
        match run_case(furbake, &fixture, &c, &limits) {
            Ok(label) => *outcomes.entry(label).or_default() += 1,
            Err(e) => failures.push(format!("{}{e}", c.describe())),
        }
    }
    eprintln!("{outcomes:#?}");
    assert!(failures.is_empty(), "{} of {CASES} cases failed:\n{}", failures.len(), failures.join("\n\n"));
    // A known breach still to be fixed is counted, never hidden: only those listed.
    for label in outcomes.keys().filter_map(|k| k.split_once("/open:")) {
        assert!(OPEN_FINDINGS.contains(&label.1), "{label:?}");
    }
    // Every command's outputs were refused, the bake's buffer only once the glTF was read.
    for command in ["bake", "batch", "simulate", "preview", "export", "keyframes"] {
        assert!(sum(&outcomes, &format!("outputs/{command}/"), "/exit-2") >= 1, "outputs of {command}: {outcomes:?}");
    }
    assert!(sum(&outcomes, "outputs/", "/exit-2") >= 20, "{outcomes:?}");
    assert!(sum(&outcomes, "outputs/bake/buffer/", "/exit-1") >= 1, "{outcomes:?}");
    // Depfile names both refused and read back by make and ninja, as buffer and as output.
    for role in ["buffer", "output"] {
        assert!(sum(&outcomes, &format!("depfiles/{role}/"), "/refused") >= 3, "{outcomes:?}");
        assert!(sum(&outcomes, &format!("depfiles/{role}/"), "/read-back") >= 3, "{outcomes:?}");
    }
    // Planted manifests warned about and rebaked; the control (a regular file inside the asset
    // roots) skipped, so the planting works.
    assert!(sum(&outcomes, "manifests/outside/", "/warned-rebaked") >= 5, "{outcomes:?}");
    assert!(sum(&outcomes, "manifests/special/", "/warned-rebaked") >= 2, "{outcomes:?}");
    assert!(sum(&outcomes, "manifests/inside/", "/skipped") >= 2, "{outcomes:?}");
    // Special files refused as many kinds of input.
    let slots = outcomes.keys().filter(|k| k.starts_with("inputs/") && k.ends_with("/exit-1")).count();
    assert!(slots >= 10, "only {slots} input slots reached: {outcomes:?}");
}
