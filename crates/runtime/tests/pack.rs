//! Lazy pack loading: opening reads only the header and table; each accessor reads its one
//! section once; a corrupt section fails only when (and each time) it is asked for, with a typed
//! error; a missing section names its kind.

use std::sync::Arc;

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_formats::FormatError;
use furbake_formats::{PackWriter, SectionKind, sections::fin_atlas::FinAtlas};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_runtime::Pack;

fn baked_sphere_bytes() -> Vec<u8> {
    let gltf = testmesh::uv_sphere(6, 8, 1.0).gltf;
    let imported = import_gltf_slice(&gltf, "sphere.gltf", None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    settings.volume.resolution = 16;
    settings.volume.layers = 4;
    bake(&imported, "sphere.gltf", &settings.plan().unwrap(), &mut NoProgress).unwrap().to_writer().to_bytes()
}

#[test]
fn sections_are_read_only_when_asked_for_and_only_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.fbk");
    std::fs::write(&path, baked_sphere_bytes()).unwrap();

    let pack = Pack::open(&path).unwrap();
    assert_eq!(pack.sections().len(), 6);
    assert!(pack.read_counts().iter().all(|&(_, n)| n == 0), "open reads no section");

    let mesh = pack.skin_mesh().unwrap();
    let again = pack.skin_mesh().unwrap();
    assert!(Arc::ptr_eq(&mesh, &again), "the decoded section is cached");
    assert_eq!(pack.kinds_read(), vec![SectionKind::SKIN_MESH]);

    let shells = pack.shell_atlas().unwrap();
    assert_eq!(shells.layers(), 4);
    let uv = pack.triangle_uv_map().unwrap();
    assert_eq!(uv.corners.len(), mesh.triangles.len());
    let counts = pack.read_counts();
    let read: Vec<_> = counts.iter().filter(|&&(_, n)| n > 0).collect();
    assert_eq!(read.len(), 3);
    assert!(read.iter().all(|&&(_, n)| n == 1), "each section read exactly once: {counts:?}");
    for kind in [SectionKind::BAKE_MANIFEST, SectionKind::FIN_ATLAS, SectionKind::FIN_EDGES] {
        assert!(counts.iter().any(|&(k, n)| k == kind && n == 0), "{kind} must stay unread");
    }
    // A kind the pack does not hold is a typed error naming it, and reads nothing.
    match pack.section::<furbake_formats::sections::blade_field::BladeField>() {
        Err(FormatError::MissingSection { kind, .. }) => assert_eq!(kind, SectionKind::BLADE_FIELD),
        other => panic!("expected MissingSection, got {other:?}"),
    }
    assert_eq!(pack.kinds_read().len(), 3);
}

#[test]
fn a_corrupt_section_fails_only_when_read() {
    let bytes = baked_sphere_bytes();
    let probe = furbake_formats::Pack::from_bytes(&bytes).unwrap();
    let fin_index = probe.find(SectionKind::FIN_ATLAS).next().unwrap();
    let entry = probe.sections()[fin_index];
    let mut corrupt = bytes.clone();
    corrupt[entry.offset as usize + entry.length as usize / 2] ^= 0x5a;

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("corrupt.fbk");
    std::fs::write(&path, &corrupt).unwrap();
    let pack = Pack::open(&path).expect("the table is intact, so open succeeds");
    assert!(pack.skin_mesh().is_ok(), "an intact section still loads");
    for attempt in 0..2 {
        match pack.fin_atlas() {
            Err(e) => {
                assert!(e.is_bad_file(), "{e}");
                assert!(e.to_string().contains("corrupt.fbk"), "the error names the file: {e}");
            }
            other => panic!("attempt {attempt}: expected a checksum error, got {other:?}"),
        }
    }
    let fin_reads = pack.read_counts()[fin_index].1;
    assert_eq!(fin_reads, 2, "a failed read is not cached");
}

#[test]
fn open_rejects_a_non_pack() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("junk.fbk");
    std::fs::write(&path, b"not a furbake container at all, just some bytes of text......").unwrap();
    assert!(Pack::open(&path).is_err_and(|e| e.is_bad_file()));
    assert!(matches!(Pack::open(dir.path().join("absent.fbk")), Err(FormatError::Io { .. })));
}

#[test]
fn sections_of_returns_every_section_of_a_kind_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two.fbk");
    let a = FinAtlas { width: 1, height: 1, slices: 1, alpha: vec![7] };
    let b = FinAtlas { width: 1, height: 1, slices: 2, alpha: vec![9] };
    PackWriter::new().push_section(&a).push_section(&b).write_atomic(&path).unwrap();
    let pack = Pack::open(&path).unwrap();
    let all = pack.sections_of::<FinAtlas>().unwrap();
    assert_eq!(all.iter().map(|f| f.alpha[0]).collect::<Vec<_>>(), vec![7, 9]);
    assert_eq!(pack.fin_atlas().unwrap().alpha, vec![7], "the typed accessor returns the first");
    assert_eq!(pack.read_counts().iter().map(|&(_, n)| n).collect::<Vec<_>>(), vec![1, 1]);
}
