//! A sample of mutated glTF files through the `furbake bake` binary itself: under a 2 GiB
//! address-space limit and a time limit, every run exits 0, 1 or 2 without a panic message, a
//! failed bake leaves no output and no temporary file, and a bake that exits 0 writes a pack that
//! `furbake verify` accepts. `make fuzz` runs a larger sample
//! (`furbake-fuzz --cli target/debug/furbake`).

use std::path::Path;
use std::time::Duration;

use furbake_fuzz::corpus::{glb_seeds, gltf_json_seeds};
use furbake_fuzz::gltf::{mutate_gltf, run_cli_bake};
use furbake_fuzz::rng::Rng;

#[test]
fn mutated_gltf_files_get_exit_codes_not_crashes_or_leftovers() {
    let furbake = Path::new(env!("CARGO_BIN_EXE_furbake"));
    let mut seeds = gltf_json_seeds();
    seeds.extend(glb_seeds().expect("the bundled .glb fixtures"));
    let mut codes = [0u32; 3];
    for case in 0..60u64 {
        let mut rng = Rng::for_case(20261130, case);
        let seed = rng.pick(&seeds).clone();
        let bytes = mutate_gltf(&mut rng, &seed.bytes);
        let input = if seed.name.ends_with(".glb") { "in.glb" } else { "in.gltf" };
        match run_cli_bake(furbake, &bytes, input, 2048, Duration::from_secs(120)) {
            Ok(o) => codes[o.code as usize] += 1,
            Err(e) => panic!("case {case} of {}: {e}", seed.name),
        }
    }
    assert_eq!(codes.iter().sum::<u32>(), 60);
    assert!(codes[0] > 0 && codes[1] > 0, "both accepted and refused mutants: {codes:?}");
}
