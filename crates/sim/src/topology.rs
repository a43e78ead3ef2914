//! Topology builders (fur thesis §3.4.1, fig. 3.23–3.28): turn a welded skin mesh into one of the
//! eight mass–spring topologies stored as a [`SpringTopology`].
//!
//! Counts on a mesh of V welded vertices, E unique edges and F triangles, all furry (docs/design.md "Topology counts"):
//!
//! | kind | masses | springs | sticks |
//! |---|---|---|---|
//! | `chain` (L layers) | L·V | (L−1)·V | 0 |
//! | `reduced-chain` (k masses) | k·V | (k−1)·V | 0 |
//! | `sticks` | 2V | 0 | V |
//! | `spring-sticks` | 2V | V | 0 |
//! | `prisms` | 2V | V+E | 0 |
//! | `separable-sticks` | 6F | 0 | 3F |
//! | `separable-spring-sticks` | 6F | 3F | 0 |
//! | `separable-prisms` | 6F | 6F | 0 |
//!
//! **Partially furry meshes.** Only furry triangles (`fur_mask = 1`) carry fur. Non-separable
//! kinds give masses to the vertices of furry triangles only, and prisms link the tips along the
//! edges of furry triangles only; separable kinds give masses to the corners of furry triangles
//! only. Shell vertices without fur map to `[NO_MASS, NO_MASS]`, so V, E and F above count the
//! furry part of the mesh.
//!
//! Layout: the masses of one chain (or of one triangle corner) are consecutive, root first; the
//! root is anchored (on the skin) and every other mass of the chain lies on the root's unit normal
//! at heights `fur_length · i / (masses − 1)`. Springs and sticks go from the mass nearer the skin
//! to the one further out. Prism edge springs follow the vertical ones, sorted by vertex pair.

use std::collections::BTreeSet;

use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::{
    NO_MASS, SpringTopology, TopologyKind, TopologyParams, TopologyStats,
};
use glam::Vec3;

use crate::SimError;

/// Checks the mesh's arrays against each other (lengths, index ranges, finite values).
pub fn validate_mesh(mesh: &SkinMesh) -> Result<(), SimError> {
    let v = mesh.positions.len();
    if mesh.normals.len() != v {
        return Err(SimError::InvalidInput(format!("{} normals for {v} vertices", mesh.normals.len())));
    }
    if mesh.fur_mask.len() != mesh.triangles.len() {
        return Err(SimError::InvalidInput(format!(
            "{} fur mask entries for {} triangles",
            mesh.fur_mask.len(),
            mesh.triangles.len()
        )));
    }
    if let Some(i) = mesh.positions.iter().chain(&mesh.normals).position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(SimError::InvalidInput(format!("vertex data entry {i} is not finite")));
    }
    if let Some(t) = mesh.triangles.iter().position(|t| t.iter().any(|&i| i as usize >= v)) {
        return Err(SimError::InvalidInput(format!("triangle {t} has a vertex index ≥ {v}")));
    }
    if v > (u32::MAX / 1024) as usize || mesh.triangles.len() > (u32::MAX / 8) as usize {
        return Err(SimError::InvalidInput("mesh too large for 32-bit mass indices".into()));
    }
    Ok(())
}

/// Unique undirected edges `(a < b)` of the triangles selected by `keep`, sorted.
pub fn mesh_edges(triangles: &[[u32; 3]], keep: impl Fn(usize) -> bool) -> Vec<[u32; 2]> {
    let mut set = BTreeSet::new();
    for (t, tri) in triangles.iter().enumerate() {
        if !keep(t) {
            continue;
        }
        for c in 0..3 {
            let (a, b) = (tri[c], tri[(c + 1) % 3]);
            if a != b {
                set.insert([a.min(b), a.max(b)]);
            }
        }
    }
    set.into_iter().collect()
}

/// Unit vertex normals; zero or near-zero normals are replaced by the area-weighted normal of the
/// adjacent triangles, or +Y when that vanishes too. Returns the normals and the fallback count.
fn unit_normals(mesh: &SkinMesh) -> (Vec<Vec3>, u32) {
    let mut face_sum = vec![Vec3::ZERO; mesh.positions.len()];
    for tri in &mesh.triangles {
        let [a, b, c] = tri.map(|i| Vec3::from(mesh.positions[i as usize]));
        let n = (b - a).cross(c - a);
        for &i in tri {
            face_sum[i as usize] += n;
        }
    }
    let mut fallbacks = 0;
    let normals = mesh
        .normals
        .iter()
        .zip(&face_sum)
        .map(|(n, f)| match Vec3::from(*n).try_normalize() {
            Some(n) if n.length_squared() > 0.5 => n,
            _ => {
                fallbacks += 1;
                f.try_normalize().unwrap_or(Vec3::Y)
            }
        })
        .collect();
    (normals, fallbacks)
}

/// Builds a topology of `kind` on the furry triangles of `mesh` (see the module docs for counts
/// and the treatment of bare triangles).
pub fn build_topology(
    mesh: &SkinMesh,
    kind: TopologyKind,
    params: &TopologyParams,
) -> Result<SpringTopology, SimError> {
    validate_mesh(mesh)?;
    params.validate().map_err(|e| SimError::Parameter { name: "topology params", what: e.to_string() })?;
    if kind.name().is_none() {
        return Err(SimError::Parameter { name: "topology kind", what: format!("{kind} is not a known kind") });
    }
    let (normals, normal_fallbacks) = unit_normals(mesh);
    let furry = |t: usize| mesh.fur_mask[t] != 0;
    let mut b = Builder { topo: empty(kind, params), params };
    b.topo.stats = TopologyStats {
        source_vertices: mesh.positions.len() as u32,
        source_triangles: mesh.triangles.len() as u32,
        bare_triangles: (0..mesh.triangles.len()).filter(|&t| !furry(t)).count() as u32,
        normal_fallbacks,
    };
    let chain_len = match kind {
        TopologyKind::CHAIN => params.chain_layers,
        TopologyKind::REDUCED_CHAIN => params.reduced_chain_masses,
        _ => 2,
    } as usize;
    let link = if kind.uses_sticks() { Link::Stick } else { Link::Spring };

    if kind.is_separable() {
        b.topo.shell_vertex_masses = vec![[NO_MASS; 2]; 3 * mesh.triangles.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if !furry(t) {
                continue;
            }
            let mut tips = [0u32; 3];
            for (c, &v) in tri.iter().enumerate() {
                let (root, tip) = b.chain(mesh.positions[v as usize].into(), normals[v as usize], 2, link);
                b.topo.shell_vertex_masses[3 * t + c] = [root, tip];
                tips[c] = tip;
            }
            if kind == TopologyKind::SEPARABLE_PRISMS {
                for c in 0..3 {
                    b.edge_spring(tips[c], tips[(c + 1) % 3]);
                }
            }
        }
    } else {
        let mut has_fur = vec![false; mesh.positions.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if furry(t) {
                for &v in tri {
                    has_fur[v as usize] = true;
                }
            }
        }
        b.topo.shell_vertex_masses = vec![[NO_MASS; 2]; mesh.positions.len()];
        for v in 0..mesh.positions.len() {
            if has_fur[v] {
                let (root, tip) = b.chain(mesh.positions[v].into(), normals[v], chain_len, link);
                b.topo.shell_vertex_masses[v] = [root, tip];
            }
        }
        if kind == TopologyKind::PRISMS {
            for [a, c] in mesh_edges(&mesh.triangles, furry) {
                let ta = b.topo.shell_vertex_masses[a as usize][1];
                let tc = b.topo.shell_vertex_masses[c as usize][1];
                b.edge_spring(ta, tc);
            }
        }
    }
    Ok(b.topo)
}

/// A topology of `kind` with no masses, springs or sticks yet (filled by the builders and by
/// `synth`).
pub(crate) fn empty(kind: TopologyKind, params: &TopologyParams) -> SpringTopology {
    SpringTopology {
        kind,
        params: params.clone(),
        stats: TopologyStats::default(),
        mass_rest_positions: Vec::new(),
        mass_kg: Vec::new(),
        mass_anchored: Vec::new(),
        spring_ends: Vec::new(),
        spring_rest_lengths_m: Vec::new(),
        spring_stiffness_n_per_m: Vec::new(),
        spring_damping_n_s_per_m: Vec::new(),
        stick_ends: Vec::new(),
        stick_lengths_m: Vec::new(),
        shell_vertex_masses: Vec::new(),
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Link {
    Spring,
    Stick,
}

struct Builder<'a> {
    topo: SpringTopology,
    params: &'a TopologyParams,
}

impl Builder<'_> {
    fn mass(&mut self, p: Vec3, kg: f32, anchored: bool) -> u32 {
        let i = self.topo.mass_kg.len() as u32;
        self.topo.mass_rest_positions.push(p.to_array());
        self.topo.mass_kg.push(kg);
        self.topo.mass_anchored.push(anchored as u8);
        i
    }

    fn spring(&mut self, a: u32, b: u32, rest: f32, k: f32, c: f32) {
        self.topo.spring_ends.push([a, b]);
        self.topo.spring_rest_lengths_m.push(rest);
        self.topo.spring_stiffness_n_per_m.push(k);
        self.topo.spring_damping_n_s_per_m.push(c);
    }

    /// One hair: `count` masses from `root` along `normal`, linked by springs or sticks.
    /// Returns (root, tip).
    fn chain(&mut self, root: Vec3, normal: Vec3, count: usize, link: Link) -> (u32, u32) {
        let p = self.params;
        let segments = (count - 1) as f32;
        let seg_len = p.fur_length_m / segments;
        let first = self.mass(root, p.root_mass_kg, true);
        let mut prev = first;
        for i in 1..count {
            let m = self.mass(root + normal * (p.fur_length_m * i as f32 / segments), p.hair_mass_kg / segments, false);
            match link {
                // Springs in series: each segment is `segments` times stiffer (and more viscous),
                // so the whole hair keeps the stiffness and damping of the parameters.
                Link::Spring => {
                    self.spring(prev, m, seg_len, p.stiffness_n_per_m * segments, p.damping_n_s_per_m * segments)
                }
                Link::Stick => {
                    self.topo.stick_ends.push([prev, m]);
                    self.topo.stick_lengths_m.push(seg_len);
                }
            }
            prev = m;
        }
        (first, prev)
    }

    fn edge_spring(&mut self, a: u32, b: u32) {
        let pa = Vec3::from(self.topo.mass_rest_positions[a as usize]);
        let pb = Vec3::from(self.topo.mass_rest_positions[b as usize]);
        let (k, c) = (self.params.edge_stiffness_n_per_m, self.params.edge_damping_n_s_per_m);
        self.spring(a, b, pa.distance(pb), k, c);
    }
}
