//! Container-level tests: round trips of every section kind this crate defines, and the
//! never-panic guarantees — every truncation and a sweep of single-byte corruptions of a real
//! pack are rejected with an error, and lying headers cause no huge allocation.

use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::fin_edges::{FinEdgeKind, FinEdges};
use furbake_formats::sections::manifest::BakeManifest;
use furbake_formats::sections::shell_atlas::{HairCoat, ShellAtlas, VolumeParams};
use furbake_formats::sections::skin_mesh::{SkinMesh, SkinMeshStats};
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use furbake_formats::{FormatError, HEADER_SIZE, Pack, PackWriter, Section, SectionKind};

fn coat() -> HairCoat {
    HairCoat {
        density: 0.1,
        length_min: 0.5,
        length_max: 1.0,
        max_deviation_texels: 3.0,
        curvature_exponent: 2.0,
        radius_texels: 0.8,
        taper: 0.5,
    }
}

fn sample_shells() -> ShellAtlas {
    let params = VolumeParams {
        layers: 3,
        resolution: 4,
        coat: coat(),
        undercoat: Some(coat()),
        shadow_min: 0.4,
        shadow_exponent: 1.0,
        fin_slices: 20,
        fin_height: 8,
    };
    ShellAtlas {
        params,
        seed: 7,
        fur_length_m: 0.02,
        alpha: (0..48).map(|i| (i * 5) as u8).collect(),
        shadow: vec![0.4, 0.7, 1.0],
        coverage: vec![0.9, 0.5, 0.1],
    }
}

fn sample_mesh() -> SkinMesh {
    SkinMesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.5]],
        normals: vec![[0.0, 0.0, 1.0]; 4],
        colors: vec![[1.0, 0.5, 0.25, 1.0]; 4],
        triangles: vec![[0, 1, 2], [1, 3, 2]],
        fur_mask: vec![1, 0],
        corner_texcoords: vec![[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]; 2],
        stats: SkinMeshStats {
            primitives: 1,
            input_vertices: 6,
            degenerate_triangles_skipped: 1,
            ..Default::default()
        },
    }
}

fn sample_pack() -> Vec<u8> {
    let mut w = PackWriter::new();
    w.push_section(&BakeManifest {
        tool: "furbake".into(),
        tool_version: "0.1.0".into(),
        input_name: "quad.glb".into(),
        input_bytes: 123,
        input_sha256: "00".repeat(32),
        preset: "fur".into(),
        seed: 1,
        settings_json: r#"{"a":1}"#.into(),
        inputs: vec![furbake_formats::sections::manifest::ManifestInput {
            name: "quad.glb".into(),
            bytes: 123,
            sha256: "00".repeat(32),
        }],
    });
    w.push_section(&sample_mesh());
    w.push_section(&sample_shells());
    w.push_section(&FinAtlas { width: 4, height: 8, slices: 20, alpha: (0..32).collect() });
    w.push_section(&TriangleUvMap { repeat_m: 0.1, seed: 3, corners: vec![[[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]]; 2] });
    w.push_section(&FinEdges {
        vertices: vec![[0, 1], [2, 0]],
        triangles: vec![0, 0],
        kinds: vec![FinEdgeKind::Border, FinEdgeKind::FurBoundary],
    });
    w.to_bytes()
}

fn round_trip<S: Section + PartialEq + std::fmt::Debug>(value: &S) {
    let mut w = PackWriter::new();
    w.push_section(value);
    let pack = Pack::from_bytes(&w.to_bytes()).expect("a freshly written pack validates");
    assert_eq!(pack.sections().len(), 1);
    let back: S = pack.decode_first().expect("decodes");
    assert_eq!(&back, value);
}

#[test]
fn every_section_kind_round_trips() {
    round_trip(&sample_mesh());
    round_trip(&sample_shells());
    round_trip(&FinAtlas { width: 2, height: 2, slices: 1, alpha: vec![1, 2, 3, 4] });
    round_trip(&TriangleUvMap { repeat_m: 0.5, seed: 9, corners: vec![[[0.0, 0.0], [1.0, 0.0], [0.5, 0.8]]] });
    round_trip(&FinEdges { vertices: vec![[3, 4]], triangles: vec![1], kinds: vec![FinEdgeKind::Border] });
    let pack = Pack::from_bytes(&sample_pack()).unwrap();
    let kinds: Vec<SectionKind> = pack.sections().iter().map(|e| e.kind).collect();
    assert_eq!(kinds.len(), 6);
    let m: BakeManifest = pack.decode_first().unwrap();
    assert_eq!(m.input_name, "quad.glb");
}

#[test]
fn sections_are_aligned_and_encoding_is_deterministic() {
    let a = sample_pack();
    assert_eq!(a, sample_pack(), "same sections must give the same bytes");
    let pack = Pack::from_bytes(&a).unwrap();
    for e in pack.sections() {
        assert_eq!(e.offset % 16, 0);
    }
    assert_eq!(pack.payload(1).unwrap().as_ptr() as usize % 16, 0, "payloads are 16-byte aligned in memory");
}

#[test]
fn every_truncation_is_rejected() {
    let bytes = sample_pack();
    let mut checked = 0;
    for len in 0..bytes.len() {
        let r = std::panic::catch_unwind(|| Pack::from_bytes(&bytes[..len]));
        let r = r.unwrap_or_else(|_| panic!("panic on truncation to {len} bytes"));
        assert!(r.is_err(), "truncation to {len} bytes was accepted");
        checked += 1;
    }
    assert_eq!(checked, bytes.len());
}

/// Decodes every section with its typed decoder; used to prove corruptions are caught either by
/// the container checksums or by the typed validation.
fn decode_everything(bytes: &[u8]) -> Result<(), FormatError> {
    let pack = Pack::from_bytes(bytes)?;
    pack.decode_first::<BakeManifest>()?;
    pack.decode_first::<SkinMesh>()?;
    pack.decode_first::<ShellAtlas>()?;
    pack.decode_first::<FinAtlas>()?;
    pack.decode_first::<TriangleUvMap>()?;
    pack.decode_first::<FinEdges>()?;
    Ok(())
}

#[test]
fn single_byte_corruptions_are_rejected() {
    let bytes = sample_pack();
    decode_everything(&bytes).expect("the clean pack decodes");
    let mut rejected = 0;
    for at in 0..bytes.len() {
        for flip in [0x01u8, 0x80, 0xff] {
            let mut b = bytes.clone();
            b[at] ^= flip;
            let r = std::panic::catch_unwind(|| decode_everything(&b))
                .unwrap_or_else(|_| panic!("panic with byte {at} ^ {flip:#x}"));
            // Padding bytes between sections are not covered by any checksum; everything else is.
            if r.is_err() {
                rejected += 1;
            }
        }
    }
    let pack = Pack::from_bytes(&bytes).unwrap();
    let covered: usize =
        HEADER_SIZE + pack.sections().len() * 32 + pack.sections().iter().map(|e| e.length as usize).sum::<usize>();
    assert!(rejected >= covered * 3 - 48 * 3, "only {rejected} of {} corruptions rejected", covered * 3);
}

#[test]
fn lying_headers_give_errors_without_huge_allocations() {
    let bytes = sample_pack();
    // Section count of 4 billion: rejected by the limit before any table allocation.
    let mut b = bytes.clone();
    b[16..20].copy_from_slice(&u32::MAX.to_le_bytes());
    fix_header_crc(&mut b);
    assert!(matches!(Pack::from_bytes(&b), Err(FormatError::Limit { .. })));
    // A section claiming 2^62 bytes.
    let mut b = bytes.clone();
    let row = HEADER_SIZE + 16;
    b[row..row + 8].copy_from_slice(&(1u64 << 62).to_le_bytes());
    fix_table_crc(&mut b);
    let err = Pack::from_bytes(&b).unwrap_err();
    assert!(err.to_string().contains("outside the file"), "{err}");
    // A future major version.
    let mut b = bytes.clone();
    b[8..10].copy_from_slice(&2u16.to_le_bytes());
    fix_header_crc(&mut b);
    assert!(matches!(Pack::from_bytes(&b), Err(FormatError::UnsupportedVersion { major: 2, .. })));
    // Wrong magic.
    let mut b = bytes;
    b[0] = b'X';
    assert!(Pack::from_bytes(&b).unwrap_err().to_string().contains("magic"));
}

#[test]
fn lying_record_counts_are_rejected() {
    // A shell atlas whose meta claims 1024 layers of 8192² texels: the array length check
    // rejects it without allocating 64 GiB.
    let mut shells = sample_shells();
    shells.params.layers = 1024;
    shells.params.resolution = 8192;
    let payload = shells.encode();
    let err = ShellAtlas::decode(&payload).unwrap_err();
    assert!(err.to_string().contains("shell alpha"), "{err}");
    // An index out of range in the skin mesh.
    let mut mesh = sample_mesh();
    mesh.triangles[1][2] = 99;
    let err = SkinMesh::decode(&mesh.encode()).unwrap_err();
    assert!(err.to_string().contains("out of range"), "{err}");
    // A NaN position.
    let mut mesh = sample_mesh();
    mesh.positions[2][1] = f32::NAN;
    assert!(SkinMesh::decode(&mesh.encode()).unwrap_err().to_string().contains("not finite"));
}

#[test]
fn an_opened_pack_reads_sections_lazily_and_writes_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sample.fbk");
    let mut w = PackWriter::new();
    w.push_section(&sample_mesh());
    w.push_section(&FinAtlas { width: 2, height: 1, slices: 1, alpha: vec![5, 6] });
    w.write_atomic(&path).unwrap();
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(leftovers.len(), 1, "no temporary file left: {leftovers:?}");
    let f = Pack::open(&path).unwrap();
    assert_eq!(f.sections().len(), 2);
    assert_eq!(
        f.read_counts(),
        vec![(SectionKind::SKIN_MESH, 0), (SectionKind::FIN_ATLAS, 0)],
        "open reads no section"
    );
    let fins: FinAtlas = f.decode(1).unwrap();
    assert_eq!(fins.alpha, vec![5, 6]);
    // Corrupt the mesh payload on disk: opening still works (lazy), reading that section fails
    // with the path in the message, the other section still reads.
    let mut bytes = std::fs::read(&path).unwrap();
    let off = f.sections()[0].offset as usize + 20;
    bytes[off] ^= 0x55;
    std::fs::write(&path, &bytes).unwrap();
    let f = Pack::open(&path).unwrap();
    let err = f.decode::<SkinMesh>(0).unwrap_err();
    assert!(err.to_string().contains("sample.fbk") && err.to_string().contains("checksum"), "{err}");
    assert!(f.decode::<FinAtlas>(1).is_ok());
}

#[test]
fn unknown_kinds_print_and_are_skipped() {
    let mut w = PackWriter::new();
    w.push(SectionKind(4242), 1, vec![1, 2, 3]);
    w.push_section(&FinAtlas { width: 1, height: 1, slices: 1, alpha: vec![9] });
    let pack = Pack::from_bytes(&w.to_bytes()).unwrap();
    assert_eq!(pack.sections()[0].kind.to_string(), "unknown(4242)");
    assert_eq!(pack.decode_first::<FinAtlas>().unwrap().alpha, vec![9]);
}

fn fix_header_crc(b: &mut [u8]) {
    let c = crc32fast_hash(&b[..44]);
    b[44..48].copy_from_slice(&c.to_le_bytes());
}

fn fix_table_crc(b: &mut [u8]) {
    let n = u32::from_le_bytes(b[16..20].try_into().unwrap()) as usize;
    let c = crc32fast_hash(&b[HEADER_SIZE..HEADER_SIZE + n * 32]);
    b[40..44].copy_from_slice(&c.to_le_bytes());
    fix_header_crc(b);
}

fn crc32fast_hash(b: &[u8]) -> u32 {
    // Bitwise CRC-32 (IEEE), independent of the crate under test.
    let mut crc = !0u32;
    for &byte in b {
        crc ^= byte as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

#[test]
fn values_outside_their_documented_ranges_are_rejected() {
    // Cause: decoders checked finiteness only, so a pack whose parameters were NaN passed `verify`
    // (`inspect --json` printed null) and one with 3e38 coordinates or a 1e12 N/m spring
    // verified but could not be simulated or drawn.
    let mut cases: Vec<(&str, Vec<u8>)> = Vec::new();
    let mut shells = sample_shells();
    shells.params.coat.density = f32::NAN;
    cases.push(("coat.density", shells.encode()));
    let mut shells = sample_shells();
    shells.fur_length_m = 3e38;
    cases.push(("fur_length_m", shells.encode()));
    let mut shells = sample_shells();
    shells.coverage[1] = 1.5;
    cases.push(("coverage", shells.encode()));
    let mut mesh = sample_mesh();
    mesh.positions[0][0] = 3e38;
    cases.push(("positions", mesh.encode()));
    let mut mesh = sample_mesh();
    mesh.normals[3] = [0.0, 0.0, 0.5];
    cases.push(("normals", mesh.encode()));
    let mut mesh = sample_mesh();
    mesh.colors[2][1] = -0.5;
    cases.push(("colors", mesh.encode()));
    let uv = TriangleUvMap { repeat_m: 1e-45, seed: 9, corners: vec![[[0.0, 0.0], [1.0, 0.0], [0.5, 0.8]]] };
    cases.push(("repeat_m", uv.encode()));
    let mut rejected = 0;
    for (what, payload) in &cases {
        let err = match *what {
            "coat.density" | "fur_length_m" | "coverage" => ShellAtlas::decode(payload).map(|_| ()),
            "repeat_m" => TriangleUvMap::decode(payload).map(|_| ()),
            _ => SkinMesh::decode(payload).map(|_| ()),
        }
        .unwrap_err();
        assert!(err.is_bad_file() && err.to_string().contains(what), "{what}: {err}");
        rejected += 1;
    }
    assert_eq!(rejected, 7);
    // The samples themselves are in range.
    assert!(ShellAtlas::decode(&sample_shells().encode()).is_ok() && SkinMesh::decode(&sample_mesh().encode()).is_ok());
}

#[test]
fn a_skin_mesh_whose_weld_tolerance_is_not_a_distance_is_rejected() {
    for bad in [f32::NAN, f32::INFINITY, -1.0] {
        let mut mesh = sample_mesh();
        mesh.stats.weld_tolerance_m = bad;
        let err = SkinMesh::decode(&mesh.encode()).unwrap_err();
        assert!(err.to_string().contains("weld_tolerance_m"), "{bad}: {err}");
    }
    let mut mesh = sample_mesh();
    mesh.stats.weld_tolerance_m = 1e-6;
    assert_eq!(SkinMesh::decode(&mesh.encode()).unwrap(), mesh);
}
