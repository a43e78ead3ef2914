//! Topology counts against docs/design.md (fur thesis §3.4.1): spring–sticks 2V/V, prisms 2V/V+E,
//! separable spring–sticks 6F/3F, separable prisms 6F/6F, on the thesis's grass patch (V=13,
//! E=28, F=16), grids, icospheres and a synthetic stand-in with the thesis dog's counts.

use furbake_formats::Section;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::{NO_MASS, SpringTopology, TopologyKind, TopologyParams};
use furbake_sim::{build_topology, mesh_edges, meshes};

fn counts(t: &SpringTopology) -> (usize, usize, usize) {
    (t.mass_kg.len(), t.spring_ends.len(), t.stick_ends.len())
}

/// Expected (masses, springs, sticks) for each kind on a fully furry mesh.
fn expected(kind: TopologyKind, v: usize, e: usize, f: usize, p: &TopologyParams) -> (usize, usize, usize) {
    let (l, k) = (p.chain_layers as usize, p.reduced_chain_masses as usize);
    match kind {
        TopologyKind::CHAIN => (l * v, (l - 1) * v, 0),
        TopologyKind::REDUCED_CHAIN => (k * v, (k - 1) * v, 0),
        TopologyKind::STICKS => (2 * v, 0, v),
        TopologyKind::SPRING_STICKS => (2 * v, v, 0),
        TopologyKind::PRISMS => (2 * v, v + e, 0),
        TopologyKind::SEPARABLE_STICKS => (6 * f, 0, 3 * f),
        TopologyKind::SEPARABLE_SPRING_STICKS => (6 * f, 3 * f, 0),
        TopologyKind::SEPARABLE_PRISMS => (6 * f, 6 * f, 0),
        other => panic!("no expectation for {other}"),
    }
}

fn check_mesh(mesh: &SkinMesh, v: usize, e: usize, f: usize) -> usize {
    assert_eq!(mesh.positions.len(), v);
    assert_eq!(mesh.triangles.len(), f);
    assert_eq!(mesh_edges(&mesh.triangles, |_| true).len(), e);
    let p = TopologyParams::default();
    let mut checked = 0;
    for kind in TopologyKind::KNOWN {
        let t = build_topology(mesh, kind, &p).expect("valid meshes build");
        assert_eq!(counts(&t), expected(kind, v, e, f, &p), "{kind} on V={v} E={e} F={f}");
        // Round trip through the section codec and check the summary's counts.
        let back = SpringTopology::decode(&t.encode()).expect("built topologies decode");
        assert_eq!(back, t);
        let s = t.summary();
        assert_eq!(s["kind"], kind.name().expect("known"));
        assert_eq!(s["masses"], t.mass_kg.len());
        assert_eq!(s["springs"], t.spring_ends.len());
        assert_eq!(s["sticks"], t.stick_ends.len());
        // Shell map: one entry per vertex (per corner when separable), all furry here.
        let shell = if kind.is_separable() { 3 * f } else { v };
        assert_eq!(t.shell_vertex_masses.len(), shell);
        assert!(t.shell_vertex_masses.iter().all(|m| m[0] != NO_MASS));
        // Roots anchored on the skin, tips free at root + normal · fur length.
        for &[r, tip] in &t.shell_vertex_masses {
            assert_eq!(t.mass_anchored[r as usize], 1);
            assert_eq!(t.mass_anchored[tip as usize], 0);
            let (pr, pt) = (t.mass_rest_positions[r as usize], t.mass_rest_positions[tip as usize]);
            let d = ((pt[0] - pr[0]).powi(2) + (pt[1] - pr[1]).powi(2) + (pt[2] - pr[2]).powi(2)).sqrt();
            assert!((d - p.fur_length_m).abs() < 1e-5, "{kind}: tip {d} m from its root");
        }
        checked += 1;
    }
    checked
}

#[test]
fn grass_patch_counts_match_the_thesis() {
    let mesh = meshes::grass_patch(0.1);
    assert_eq!(check_mesh(&mesh, 13, 28, 16), 8);
    let p = TopologyParams::default();
    let ss = build_topology(&mesh, TopologyKind::SPRING_STICKS, &p).expect("builds");
    assert_eq!(counts(&ss), (26, 13, 0));
    let sp = build_topology(&mesh, TopologyKind::SEPARABLE_PRISMS, &p).expect("builds");
    assert_eq!(counts(&sp), (96, 96, 0));
}

#[test]
fn grids_and_spheres() {
    let mut checked = 0;
    checked += check_mesh(&meshes::grid(4, 3, 0.05), 12, 9 + 8 + 6, 12);
    checked += check_mesh(&meshes::icosphere(0, 1.0), 12, 30, 20);
    checked += check_mesh(&meshes::icosphere(1, 1.0), 42, 120, 80);
    assert_eq!(checked, 24);
}

/// The thesis's dog (V=1872, F=3220): 3744/1872 for spring–sticks and 19320/19320 for separable
/// prisms follow from the formulas; a grid with the same V checks the builder at that size.
#[test]
fn thesis_dog_sized_counts() {
    let p = TopologyParams::default();
    assert_eq!(expected(TopologyKind::SPRING_STICKS, 1872, 0, 3220, &p), (3744, 1872, 0));
    assert_eq!(expected(TopologyKind::SEPARABLE_PRISMS, 1872, 0, 3220, &p), (19320, 19320, 0));
    // 48 × 39 = 1872 vertices.
    let mesh = meshes::grid(48, 39, 0.01);
    let f = mesh.triangles.len();
    let t = build_topology(&mesh, TopologyKind::SPRING_STICKS, &p).expect("builds");
    assert_eq!(counts(&t), (3744, 1872, 0));
    let t = build_topology(&mesh, TopologyKind::SEPARABLE_PRISMS, &p).expect("builds");
    assert_eq!(counts(&t), (6 * f, 6 * f, 0));
}

/// Partially furry meshes: bare triangles get no masses; their private vertices map to NO_MASS.
#[test]
fn bare_triangles_carry_no_fur() {
    let mut mesh = meshes::grass_patch(0.1);
    // Make the first cell (triangles 0..4, around centre vertex 9) bare.
    for t in 0..4 {
        mesh.fur_mask[t] = 0;
    }
    let p = TopologyParams::default();
    let ss = build_topology(&mesh, TopologyKind::SPRING_STICKS, &p).expect("builds");
    // Vertex 0 (corner) and 9 (cell centre) only touch bare triangles.
    assert_eq!(ss.shell_vertex_masses[0], [NO_MASS, NO_MASS]);
    assert_eq!(ss.shell_vertex_masses[9], [NO_MASS, NO_MASS]);
    assert_eq!(counts(&ss), (22, 11, 0));
    let pr = build_topology(&mesh, TopologyKind::PRISMS, &p).expect("builds");
    let e_furry = mesh_edges(&mesh.triangles, |t| mesh.fur_mask[t] != 0).len();
    assert_eq!(counts(&pr), (22, 11 + e_furry, 0));
    let sp = build_topology(&mesh, TopologyKind::SEPARABLE_PRISMS, &p).expect("builds");
    assert_eq!(counts(&sp), (72, 72, 0));
    assert_eq!(sp.shell_vertex_masses.iter().filter(|m| m[0] == NO_MASS).count(), 12);
    assert_eq!(sp.stats.bare_triangles, 4);
}

#[test]
fn bad_meshes_are_typed_errors() {
    let p = TopologyParams::default();
    let mut checked = 0;
    let mut m = meshes::grass_patch(0.1);
    m.triangles[3][1] = 99;
    assert!(build_topology(&m, TopologyKind::PRISMS, &p).is_err());
    checked += 1;
    let mut m = meshes::grass_patch(0.1);
    m.normals.pop();
    assert!(build_topology(&m, TopologyKind::PRISMS, &p).is_err());
    checked += 1;
    let mut m = meshes::grass_patch(0.1);
    m.positions[2][0] = f32::NAN;
    assert!(build_topology(&m, TopologyKind::PRISMS, &p).is_err());
    checked += 1;
    let m = meshes::grass_patch(0.1);
    assert!(build_topology(&m, TopologyKind(77), &p).is_err());
    checked += 1;
    let bad = TopologyParams { fur_length_m: f32::NAN, ..p.clone() };
    assert!(build_topology(&m, TopologyKind::PRISMS, &bad).is_err());
    checked += 1;
    // Zero normals fall back to face normals and are counted.
    let mut m = meshes::grass_patch(0.1);
    m.normals[4] = [0.0; 3];
    let t = build_topology(&m, TopologyKind::SPRING_STICKS, &p).expect("zero normals fall back");
    assert_eq!(t.stats.normal_fallbacks, 1);
    let tip = t.mass_rest_positions[t.shell_vertex_masses[4][1] as usize];
    assert!((tip[1].abs() - p.fur_length_m).abs() < 1e-6, "fallback normal is the face normal ±Y: {tip:?}");
    checked += 1;
    assert_eq!(checked, 6);
}

/// The real fixture: Fox.glb welds to V=290, E=864, F=576 (crates/import), all furry by default.
#[test]
fn fox_counts() {
    // Bundled in the repository's fixtures/real/.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let imported = furbake_import::import_gltf(&path, &Default::default()).expect("Fox.glb imports");
    assert_eq!(check_mesh(&imported.mesh, 290, 864, 576), 8);
}
