//! `Pack::verify`, the one full validation every command runs on a pack before using it
//! (docs/design.md "Runtime: packs"): on a lazily opened file it decodes every known section
//! through the pack's cache (so nothing is decoded again afterwards) and checksums the unknown
//! ones; it rejects a corrupt section nothing else would read and a pack that fails only a
//! cross-section check, naming the file; and the skeleton decoder refuses inverse binds that are
//! not affine.

use std::path::Path;

use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::skeleton::{AFFINE_TOLERANCE, Skeleton};
use furbake_formats::sections::skin_weights::{SkinWeightStats, SkinWeights};
use furbake_formats::{Pack, PackWriter, Section, SectionKind, VerifySummary};

use crate::rig::{mesh, skeleton};

fn weights(vertices: usize) -> SkinWeights {
    let mut w = SkinWeights {
        influences_per_vertex: 4,
        bind_count: 2,
        binds: vec![0; 4 * vertices],
        weights: vec![0.0; 4 * vertices],
        stats: SkinWeightStats::default(),
    };
    for v in 0..vertices {
        w.binds[4 * v] = (v % 2) as u16;
        w.weights[4 * v] = 1.0;
    }
    w
}

fn fins() -> FinAtlas {
    FinAtlas { width: 4, height: 2, slices: 20, alpha: vec![0, 255, 0, 9, 1, 2, 3, 4] }
}

/// Mesh, fin atlas, skeleton, skin weights for `vertices` vertices and a section of a kind this
/// reader does not know, written to `path`.
fn write_pack(path: &Path, vertices: usize) {
    let mut w = PackWriter::new();
    w.push_section(&mesh()).push_section(&fins()).push_section(&skeleton()).push_section(&weights(vertices));
    w.push(SectionKind(0x7000), 1, vec![7; 32]);
    w.write_atomic(path).unwrap();
}

#[test]
fn verify_decodes_every_section_once_and_shares_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ok.fbk");
    write_pack(&path, 3);
    let pack = Pack::open(&path).unwrap();
    let summary = pack.verify().unwrap();
    assert_eq!(summary.sections, 5);
    assert_eq!(summary.decoded, 4, "the unknown kind is checksummed, not decoded");
    assert!(summary.checks >= 15, "{summary:?}");
    let reads = |p: &Pack| p.read_counts().into_iter().map(|(_, n)| n).collect::<Vec<_>>();
    assert_eq!(reads(&pack), [1, 1, 1, 1, 1], "every section read once");
    // What verification decoded is shared: asking for it again reads nothing.
    assert_eq!(*pack.skin_mesh().unwrap(), mesh());
    assert_eq!(*pack.fin_atlas().unwrap(), fins());
    assert_eq!(*pack.skeleton().unwrap().unwrap(), skeleton());
    let d = pack.decoded_sections().unwrap();
    assert_eq!(d.skin_weights.as_deref(), Some(&weights(3)));
    assert!(d.shells.is_none() && d.topologies.is_empty());
    assert_eq!(reads(&pack), [1, 1, 1, 1, 1]);
    // The same pack in memory verifies the same.
    let in_memory = Pack::read(&path).unwrap().verify().unwrap();
    assert_eq!(in_memory, VerifySummary { sections: 5, decoded: 4, checks: summary.checks });
}

#[test]
fn verify_rejects_a_corrupt_section_nothing_else_reads() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("corrupt.fbk");
    write_pack(&path, 3);
    let entry = Pack::open(&path).unwrap().sections()[1];
    assert_eq!(entry.kind, SectionKind::FIN_ATLAS);
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[(entry.offset + entry.length - 1) as usize] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    // Opening validates the header and table only; the skin reads fine.
    let pack = Pack::open(&path).unwrap();
    assert!(pack.skin_mesh().is_ok());
    let err = pack.verify().unwrap_err();
    let text = err.to_string();
    assert!(err.is_bad_file(), "{text}");
    assert!(text.contains("corrupt.fbk") && text.contains("section 1"), "{text}");
    // Unknown kinds are checksummed too.
    write_pack(&path, 3);
    let last = *Pack::open(&path).unwrap().sections().last().unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[last.offset as usize] ^= 1;
    std::fs::write(&path, &bytes).unwrap();
    let text = Pack::open(&path).unwrap().verify().unwrap_err().to_string();
    assert!(text.contains("corrupt.fbk") && text.contains("section 4"), "{text}");
}

#[test]
fn verify_rejects_a_pack_that_fails_only_a_cross_section_check() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("inconsistent.fbk");
    // Every section decodes alone; the weights are written for 4 vertices, the skin has 3.
    write_pack(&path, 4);
    let pack = Pack::open(&path).unwrap();
    assert!(pack.skin_weights().unwrap().is_some());
    let text = pack.verify().unwrap_err().to_string();
    assert!(text.contains("inconsistent.fbk") && text.contains("skin_weights: 4 vertices"), "{text}");
}

#[test]
fn inverse_binds_must_be_affine() {
    for (at, value) in [(3, 1.0), (7, -0.5), (11, 1e-3), (15, 2.0), (15, 0.0)] {
        let mut s = skeleton();
        s.inverse_binds[1][at] = value;
        let err = Skeleton::decode(&s.encode()).expect_err("not affine");
        assert!(err.is_bad_file() && err.to_string().contains("inverse binds[1] is not affine"), "{err}");
    }
    let mut s = skeleton();
    s.inverse_binds[1][3] = f32::NAN;
    assert!(Skeleton::decode(&s.encode()).is_err());
    // Rounding is accepted, and the exact row is given back (what glTF needs).
    let mut s = skeleton();
    s.inverse_binds[1][7] = AFFINE_TOLERANCE / 2.0;
    s.inverse_binds[1][15] = 1.0 - AFFINE_TOLERANCE / 2.0;
    let back = Skeleton::decode(&s.encode()).unwrap();
    let exact = back.affine_inverse_bind(1);
    assert_eq!([exact[3], exact[7], exact[11], exact[15]], [0.0, 0.0, 0.0, 1.0]);
    assert_eq!(exact[13], -1.0);
}
