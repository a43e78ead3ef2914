//! furbake-fuzz: one job — throw hostile inputs at furbake and prove it answers every one with
//! a result or an error: never a panic, an abort, a hang or unbounded memory
//! (docs/design.md "Determinism and errors"). Stable Rust, no libFuzzer: deterministic,
//! structure-aware mutators seeded per case, and a supervisor that runs the cases in a worker
//! process so that even an abort or a hang is caught, attributed to its case and saved.
//!
//! Four targets, the first three mutating real inputs made in-process ([`corpus`]):
//! - [`packs`]: packs baked from the test meshes and the Fox, mutated at the record, section and
//!   container level with checksums recomputed; run through [`furbake_formats::Pack`], every
//!   section decoder, `check_consistency` and a stepped `furbake_runtime::World`;
//! - [`gltf`]: glTF JSON and `.glb` mutants through the importer, a tiny bake whose pack must
//!   verify, and (a sample) the `furbake bake` binary under a memory limit, checking exit codes
//!   and leftover files;
//! - [`scenes`]: fixture scenes mutated as TOML, parsed and stepped;
//! - [`pipelines`]: the `furbake` binary in hostile build pipelines (needs `--cli`): outputs
//!   that are devices, FIFOs, directories, inputs or each other; hostile file names driven
//!   through real GNU make and ninja as depfiles; planted manifests under `batch`; special
//!   files as every input.
//!
//! [`campaign`] holds the case runner (in-process, under `catch_unwind`, timed) and the
//! supervisor; `src/main.rs` is the `furbake-fuzz` binary (`make fuzz` runs the long campaign,
//! the crate's test a short one). Case `i` of seed `s` is the same mutant everywhere, so a
//! failure is reproduced from `(target, s, i)` or from the file saved for it.
//!
//! ```
//! use furbake_fuzz::{packs, rng::Rng};
//! use furbake_formats::{PackWriter, sections::fin_atlas::FinAtlas};
//!
//! let fins = FinAtlas { width: 4, height: 2, slices: 20, alpha: vec![0, 255, 0, 9, 1, 2, 3, 4] };
//! let base = packs::PackModel::parse(&PackWriter::new().push_section(&fins).to_bytes()).unwrap();
//! let mutant = packs::mutate_pack(&mut Rng::for_case(1, 0), &[base]);
//! let scene = packs::pack_scene(&mut Rng::new(0), std::path::Path::new("."));
//! let (outcome, _world) = packs::run_pack(&mutant, scene, 2); // an outcome, never a panic
//! println!("{outcome:?}");
//! ```

#![deny(missing_docs)]
pub mod campaign;
pub mod corpus;
pub mod gltf;
pub mod packs;
#[cfg(unix)]
pub mod pipelines;
pub mod rng;
pub mod scenes;

use std::process::Command;

/// Limits the address space of the child `cmd` starts to `mib` MiB (Unix `RLIMIT_AS`), so that
/// an allocation past the limit fails in the child instead of exhausting the machine.
#[cfg(unix)]
pub fn limit_memory(cmd: &mut Command, mib: u64) {
    use std::os::unix::process::CommandExt;
    let bytes = mib.saturating_mul(1 << 20) as libc::rlim_t;
    // SAFETY: the closure runs in the forked child before exec; it allocates nothing and calls
    // only setrlimit, which is async-signal-safe.
    unsafe {
        cmd.pre_exec(move || {
            let limit = libc::rlimit { rlim_cur: bytes, rlim_max: bytes };
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

/// Limits the address space of the child `cmd` starts (no-op where `RLIMIT_AS` does not exist).
#[cfg(not(unix))]
pub fn limit_memory(_cmd: &mut Command, _mib: u64) {}
