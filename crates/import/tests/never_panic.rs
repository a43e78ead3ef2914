//! Never-panic checks (docs/design.md "Determinism and errors": no input makes the importer panic): every truncation of
//! small real files, strided truncations of a large one, single-byte corruptions of the GLB JSON
//! chunk and of the binary chunk. Each import must return `Ok` or `Err`; a panic (in our code or
//! in the `gltf` crate underneath) is caught with `catch_unwind` and fails the test with the
//! input that caused it. The single-byte JSON test found a panic inside gltf-json 1.4.1's
//! validation (an out-of-range POSITION accessor index, mesh.rs:151), which the importer now
//! checks before validating; `errors.rs` pins it.

use std::panic::{AssertUnwindSafe, catch_unwind};

use crate::common::fixture;
use furbake_import::{ImportSettings, import_gltf, import_gltf_slice};

/// Imports `bytes`; returns whether it succeeded, or panics with a description of the input.
fn survives(bytes: &[u8], what: &str) -> bool {
    let settings = ImportSettings::default();
    let result = catch_unwind(AssertUnwindSafe(|| import_gltf_slice(bytes, "fuzz.glb", None, &settings)));
    match result {
        Ok(r) => r.is_ok(),
        Err(panic) => {
            let msg = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            panic!("import panicked on {what}: {msg}");
        }
    }
}

fn json_chunk_range(glb: &[u8]) -> std::ops::Range<usize> {
    let len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    20..20 + len
}

#[test]
fn every_truncation_of_small_glbs_is_an_error_or_a_mesh() {
    let mut tried = 0;
    for name in ["Box.glb", "BoxVertexColors.glb"] {
        let bytes = std::fs::read(fixture(name)).unwrap();
        let mut ok = 0;
        for n in 0..bytes.len() {
            ok += usize::from(survives(&bytes[..n], &format!("{name} truncated to {n} bytes")));
            tried += 1;
        }
        // A truncated GLB always lies about its length, so no prefix may import.
        assert_eq!(ok, 0, "{name}: a truncated file imported");
        assert!(survives(&bytes, name));
    }
    assert_eq!(tried, 1664 + 1924);
}

#[test]
fn strided_truncations_of_fox_and_files_on_disk() {
    let bytes = std::fs::read(fixture("Fox.glb")).unwrap();
    let mut tried = 0;
    for n in (0..bytes.len()).step_by(1009) {
        assert!(!survives(&bytes[..n], &format!("Fox.glb truncated to {n} bytes")));
        tried += 1;
    }
    assert_eq!(tried, bytes.len().div_ceil(1009));
    // The same through the file path, in a temp dir.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.glb");
    for n in [0, 3, 12, 19, 20, 700, bytes.len() - 1] {
        std::fs::write(&path, &bytes[..n]).unwrap();
        let r = catch_unwind(|| import_gltf(&path, &ImportSettings::default()));
        assert!(matches!(r, Ok(Err(_))), "truncated to {n}");
        tried += 1;
    }
    assert!(tried > 160);
}

#[test]
fn single_byte_corruptions_of_the_json_chunk() {
    let mut tried = 0;
    let mut imported = 0;
    for name in ["Box.glb", "BoxVertexColors.glb"] {
        let bytes = std::fs::read(fixture(name)).unwrap();
        let range = json_chunk_range(&bytes);
        let mut copy = bytes.clone();
        for at in range {
            let original = bytes[at];
            for replacement in [b'0', b'9', b'-', b'"', b'}', b'[', b'e', 0xFF, original ^ 0x01] {
                if replacement == original {
                    continue;
                }
                copy[at] = replacement;
                imported += usize::from(survives(&copy, &format!("{name} with byte {at} = {replacement:#04x}")));
                tried += 1;
            }
            copy[at] = original;
        }
    }
    assert!(tried > 10_000, "{tried}");
    // Some corruptions are harmless (a digit in a float), most are errors.
    assert!(imported > 0 && imported < tried, "{imported} of {tried}");
}

#[test]
fn single_byte_corruptions_of_the_binary_chunk() {
    let bytes = std::fs::read(fixture("Box.glb")).unwrap();
    let json = json_chunk_range(&bytes);
    let bin_start = json.end + 8;
    let mut copy = bytes.clone();
    let mut tried = 0;
    let mut failed = 0;
    for at in bin_start..bytes.len() {
        for flip in [0xFFu8, 0x80, 0x7F] {
            copy[at] = bytes[at] ^ flip;
            failed += usize::from(!survives(&copy, &format!("Box.glb with BIN byte {at} ^ {flip:#04x}")));
            tried += 1;
        }
        copy[at] = bytes[at];
    }
    assert_eq!(tried, 3 * (bytes.len() - bin_start));
    // Flipped index bytes go out of range and flipped exponents make NaN/huge positions.
    assert!(failed > 0, "no corruption was detected");
}

/// SplitMix64: a tiny deterministic generator so the splice test is reproducible.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

#[test]
fn json_token_splices_never_panic_and_successes_are_finite() {
    // Splicing JSON tokens (huge counts, out-of-range indices, nulls, f32 overflow) into the
    // JSON reaches the validation and accessor paths that byte flips rarely do.
    let tokens: &[&[u8]] = &[
        b"0",
        b"1",
        b"9",
        b"-1",
        b"1e39",
        b"4294967295",
        b"null",
        b"[]",
        b"{}",
        b"\"\"",
        b"\"POSITION\"",
        b"5",
        b"65535",
        b"1e-45",
        b"18446744073709551615",
    ];
    let mut rng = SplitMix64(0x5EED);
    let (mut ok, mut tried) = (0, 0);
    for name in ["Box.glb", "BoxVertexColors.glb", "TwoSidedPlane/TwoSidedPlane.gltf"] {
        let path = fixture(name);
        let bytes = std::fs::read(&path).unwrap();
        let dir = path.parent().unwrap().to_path_buf();
        let glb = bytes.starts_with(b"glTF");
        let json = if glb { json_chunk_range(&bytes) } else { 0..bytes.len() };
        for _ in 0..3000 {
            let mut j = bytes[json.clone()].to_vec();
            for _ in 0..1 + rng.next() % 3 {
                let at = rng.next() as usize % j.len();
                let end = (at + (rng.next() % 4) as usize).min(j.len());
                j.splice(at..end, tokens[rng.next() as usize % tokens.len()].iter().copied());
            }
            let data = if glb {
                j.resize(j.len().div_ceil(4) * 4, b' ');
                let mut out = bytes[..12].to_vec();
                out.extend_from_slice(&(j.len() as u32).to_le_bytes());
                out.extend_from_slice(&bytes[16..20]);
                out.extend_from_slice(&j);
                out.extend_from_slice(&bytes[json.end..]);
                let total = out.len() as u32;
                out[8..12].copy_from_slice(&total.to_le_bytes());
                out
            } else {
                j
            };
            let settings = ImportSettings::default();
            let r = catch_unwind(AssertUnwindSafe(|| import_gltf_slice(&data, "fuzz", Some(&dir), &settings)));
            match r {
                Ok(Ok(m)) => {
                    let m = m.mesh;
                    let all = m.positions.iter().flatten().chain(m.normals.iter().flatten());
                    assert!(all.chain(m.colors.iter().flatten()).all(|x| x.is_finite()), "{name}: non-finite skin");
                    ok += 1;
                }
                Ok(Err(_)) => {}
                Err(_) => panic!("import panicked on a splice of {name}: {:?}", String::from_utf8_lossy(&data)),
            }
            tried += 1;
        }
    }
    assert_eq!(tried, 9000);
    assert!(ok > 0 && ok < tried, "{ok} of {tried} imported");
}
