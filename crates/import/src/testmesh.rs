//! Generated test meshes as minimal `.gltf` JSON with one embedded base64 `data:` buffer, for
//! tests in this and other furbake crates (import them with
//! [`import_gltf_slice`](crate::import_gltf_slice), no files needed). Each generator returns the
//! bytes together with the counts the import must produce, so tests can assert against them:
//! the fur thesis's grass patch (13 V / 16 F, §3.4.1's example), a UV sphere, a unit cube with
//! split faces, and a plane grid with a bare region marked by material.

use std::f32::consts::PI;

use serde_json::{Value, json};

/// A generated glTF and what importing it with default settings yields.
#[derive(Clone, Debug)]
pub struct TestMesh {
    /// The `.gltf` JSON bytes (buffer embedded as a base64 `data:` URI).
    pub gltf: Vec<u8>,
    /// Welded vertices.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Triangles that carry fur under `FurMaskSource::Materials { names: ["fur"] }` (all of
    /// them for meshes without a bare region).
    pub furry_triangles: usize,
    /// Unique undirected edges.
    pub edges: usize,
}

/// One primitive for [`gltf_json`]. Attributes left `None` are not written.
#[derive(Clone, Debug, Default)]
pub struct TestPrimitive {
    /// `POSITION`.
    pub positions: Vec<[f32; 3]>,
    /// Index list (`None`: unindexed).
    pub indices: Option<Vec<u32>>,
    /// `NORMAL`.
    pub normals: Option<Vec<[f32; 3]>>,
    /// `COLOR_0` as float `VEC4`.
    pub colors: Option<Vec<[f32; 4]>>,
    /// `TEXCOORD_0`.
    pub texcoords: Option<Vec<[f32; 2]>>,
    /// Extra float `SCALAR` attributes, e.g. `("_FUR", values)`.
    pub scalars: Vec<(String, Vec<f32>)>,
    /// Material name (materials are created once per distinct name, base colour white).
    pub material: Option<String>,
    /// Primitive mode (4 = TRIANGLES, 5 = TRIANGLE_STRIP, 6 = TRIANGLE_FAN, 0 = POINTS).
    pub mode: u32,
}

impl TestPrimitive {
    /// An indexed TRIANGLES primitive with positions only.
    pub fn triangles(positions: Vec<[f32; 3]>, indices: Vec<u32>) -> Self {
        TestPrimitive { positions, indices: Some(indices), mode: 4, ..TestPrimitive::default() }
    }
}

/// `data:application/octet-stream;base64,…` for `bytes`.
pub fn data_uri(bytes: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", crate::base64::encode(bytes))
}

struct BufferBuilder {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl BufferBuilder {
    /// Appends little-endian 4-byte values and returns the new accessor's index.
    fn push(&mut self, words: &[[u8; 4]], count: usize, ty: &str, component_type: u32, extra: Value) -> usize {
        let offset = self.data.len();
        for w in words {
            self.data.extend_from_slice(w);
        }
        self.views.push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": words.len() * 4 }));
        let mut acc = json!({
            "bufferView": self.views.len() - 1,
            "componentType": component_type,
            "count": count,
            "type": ty,
        });
        if let (Value::Object(a), Value::Object(e)) = (&mut acc, extra) {
            a.extend(e);
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }

    fn floats<const N: usize>(&mut self, values: &[[f32; N]], ty: &str, min_max: bool) -> usize {
        let words: Vec<[u8; 4]> = values.iter().flatten().map(|v| v.to_le_bytes()).collect();
        let mut extra = json!({});
        if min_max && values.iter().flatten().all(|v| v.is_finite()) && !values.is_empty() {
            let min: Vec<f32> = (0..N).map(|k| values.iter().map(|v| v[k]).fold(f32::INFINITY, f32::min)).collect();
            let max: Vec<f32> = (0..N).map(|k| values.iter().map(|v| v[k]).fold(f32::NEG_INFINITY, f32::max)).collect();
            extra = json!({ "min": min, "max": max });
        }
        self.push(&words, values.len(), ty, 5126, extra)
    }
}

/// Writes `primitives` as one mesh on one node (with `node_matrix`, column-major, if given) in
/// the default scene, as `.gltf` JSON bytes with an embedded buffer.
pub fn gltf_json(primitives: &[TestPrimitive], node_matrix: Option<[f32; 16]>) -> Vec<u8> {
    let mut b = BufferBuilder { data: Vec::new(), views: Vec::new(), accessors: Vec::new() };
    let mut materials: Vec<String> = Vec::new();
    let mut prims = Vec::new();
    for p in primitives {
        let mut attributes = serde_json::Map::new();
        attributes.insert("POSITION".into(), json!(b.floats(&p.positions, "VEC3", true)));
        if let Some(n) = &p.normals {
            attributes.insert("NORMAL".into(), json!(b.floats(n, "VEC3", false)));
        }
        if let Some(c) = &p.colors {
            attributes.insert("COLOR_0".into(), json!(b.floats(c, "VEC4", false)));
        }
        if let Some(t) = &p.texcoords {
            attributes.insert("TEXCOORD_0".into(), json!(b.floats(t, "VEC2", false)));
        }
        for (name, values) in &p.scalars {
            let wrapped: Vec<[f32; 1]> = values.iter().map(|&v| [v]).collect();
            attributes.insert(name.clone(), json!(b.floats(&wrapped, "SCALAR", false)));
        }
        let mut prim = json!({ "attributes": attributes, "mode": p.mode });
        if let Some(idx) = &p.indices {
            let words: Vec<[u8; 4]> = idx.iter().map(|i| i.to_le_bytes()).collect();
            prim["indices"] = json!(b.push(&words, idx.len(), "SCALAR", 5125, json!({})));
        }
        if let Some(m) = &p.material {
            let index = materials.iter().position(|x| x == m).unwrap_or_else(|| {
                materials.push(m.clone());
                materials.len() - 1
            });
            prim["material"] = json!(index);
        }
        prims.push(prim);
    }
    let mut node = json!({ "mesh": 0 });
    if let Some(m) = node_matrix {
        node["matrix"] = json!(m);
    }
    let root = json!({
        "asset": { "version": "2.0", "generator": "furbake-import testmesh" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [node],
        "meshes": [{ "name": "testmesh", "primitives": prims }],
        "materials": materials.iter().map(|m| json!({
            "name": m,
            "pbrMetallicRoughness": { "baseColorFactor": [1.0, 1.0, 1.0, 1.0] },
        })).collect::<Vec<_>>(),
        "buffers": [{ "byteLength": b.data.len(), "uri": data_uri(&b.data) }],
        "bufferViews": b.views,
        "accessors": b.accessors,
    });
    // Serialising a `Value` built from finite numbers and strings cannot fail.
    serde_json::to_vec_pretty(&root).expect("a serde_json::Value always serialises")
}

/// The fur thesis's grass patch: a 3×3 vertex grid (2×2 cells, `size_m` wide, in the XZ plane,
/// Y up) plus one vertex at each cell centre, each cell split into 4 triangles around its
/// centre: V = 13, F = 16, E = 28. No normals (they are generated, all +Y); TEXCOORD_0 = xz.
pub fn grass_patch(size_m: f32) -> TestMesh {
    let h = size_m / 2.0;
    let mut positions = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            positions.push([-h + j as f32 * h, 0.0, -h + i as f32 * h]);
        }
    }
    for i in 0..2 {
        for j in 0..2 {
            positions.push([-h / 2.0 + j as f32 * h, 0.0, -h / 2.0 + i as f32 * h]);
        }
    }
    let g = |i: u32, j: u32| i * 3 + j;
    let mut indices = Vec::new();
    for i in 0..2 {
        for j in 0..2 {
            let m = 9 + i * 2 + j;
            // Corners counter-clockwise seen from +Y (+z then +x): normals point up.
            let ring = [g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)];
            for k in 0..4 {
                indices.extend_from_slice(&[ring[k], ring[(k + 1) % 4], m]);
            }
        }
    }
    let texcoords = positions.iter().map(|p| [p[0] / size_m + 0.5, p[2] / size_m + 0.5]).collect();
    let prim = TestPrimitive { texcoords: Some(texcoords), ..TestPrimitive::triangles(positions, indices) };
    TestMesh { gltf: gltf_json(&[prim], None), vertices: 13, triangles: 16, furry_triangles: 16, edges: 28 }
}

/// A UV sphere of `radius_m` with `rings` (≥ 2) latitude bands and `segments` (≥ 3) meridians.
/// Written with a duplicated seam and per-segment pole copies (as DCC tools export it, for the
/// UVs), which welding merges: V = 2 + (rings − 1)·segments, F = 2·segments·(rings − 1),
/// E = V + F − 2. No normals; outward winding.
pub fn uv_sphere(rings: u32, segments: u32, radius_m: f32) -> TestMesh {
    let (rings, segments) = (rings.max(2), segments.max(3));
    let row = segments + 1;
    let mut positions = Vec::new();
    let mut texcoords = Vec::new();
    for r in 0..=rings {
        let theta = PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = 2.0 * PI * (s % segments) as f32 / segments as f32;
            let (st, ct) = if r == 0 {
                (0.0, 1.0)
            } else if r == rings {
                (0.0, -1.0)
            } else {
                theta.sin_cos()
            };
            positions.push([radius_m * st * phi.cos(), radius_m * ct, -radius_m * st * phi.sin()]);
            texcoords.push([s as f32 / segments as f32, r as f32 / rings as f32]);
        }
    }
    let mut indices = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = r * row + s;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            if r != 0 {
                indices.extend_from_slice(&[a, d, b]);
            }
            if r != rings - 1 {
                indices.extend_from_slice(&[a, c, d]);
            }
        }
    }
    let v = 2 + (rings as usize - 1) * segments as usize;
    let f = 2 * segments as usize * (rings as usize - 1);
    let prim = TestPrimitive { texcoords: Some(texcoords), ..TestPrimitive::triangles(positions, indices) };
    TestMesh { gltf: gltf_json(&[prim], None), vertices: v, triangles: f, furry_triangles: f, edges: v + f - 2 }
}

/// An axis-aligned cube of edge `size_m` centred at the origin, written as 6 faces with their own
/// 4 vertices each (24) and no normals: welds to V = 8, F = 12, E = 18, winding outward.
pub fn cube(size_m: f32) -> TestMesh {
    let h = size_m / 2.0;
    // (normal, u, v) with u × v = normal, so corners -u-v, +u-v, +u+v, -u+v are CCW from outside.
    let faces: [([f32; 3], [f32; 3], [f32; 3]); 6] = [
        ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]),
        ([-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]),
        ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]),
        ([0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ([0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]),
    ];
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for (n, u, v) in faces {
        let base = positions.len() as u32;
        for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            positions.push([0, 1, 2].map(|k| h * (n[k] + su * u[k] + sv * v[k])));
        }
        indices.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    let prim = TestPrimitive::triangles(positions, indices);
    TestMesh { gltf: gltf_json(&[prim], None), vertices: 8, triangles: 12, furry_triangles: 12, edges: 18 }
}

/// A `cells × cells` grid (`cells` ≥ 4, `size_m` wide, XZ plane, Y up), each cell split into two
/// triangles. The central cells `[cells/4, cells − cells/4)²` use material `"bare"`, all others
/// `"fur"`; the two materials are separate primitives with their own vertex copies (welding
/// joins them). V = (cells+1)², F = 2·cells², E = 3·cells² + 2·cells;
/// `furry_triangles` counts the `"fur"` triangles.
pub fn plane_with_bare_region(cells: u32, size_m: f32) -> TestMesh {
    let n = cells.max(4);
    let (lo, hi) = (n / 4, n - n / 4);
    let step = size_m / n as f32;
    let mut positions = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            positions.push([-size_m / 2.0 + j as f32 * step, 0.0, -size_m / 2.0 + i as f32 * step]);
        }
    }
    let g = |i: u32, j: u32| i * (n + 1) + j;
    let (mut fur, mut bare) = (Vec::new(), Vec::new());
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1));
            let target = if (lo..hi).contains(&i) && (lo..hi).contains(&j) { &mut bare } else { &mut fur };
            target.extend_from_slice(&[a, b, c, a, c, d]);
        }
    }
    let furry = fur.len() / 3;
    let prims = [("fur", fur), ("bare", bare)].map(|(m, idx)| TestPrimitive {
        material: Some(m.to_string()),
        ..TestPrimitive::triangles(positions.clone(), idx)
    });
    let n = n as usize;
    TestMesh {
        gltf: gltf_json(&prims, None),
        vertices: (n + 1) * (n + 1),
        triangles: 2 * n * n,
        furry_triangles: furry,
        edges: 3 * n * n + 2 * n,
    }
}

/// The generated meshes committed under `fixtures/generated/` (file name, mesh): the thesis's
/// grass patch scaled to 4 m, a 1 m sphere of ~1,000 triangles, and a 2 m plane with a bare
/// centre (materials `fur` / `bare`).
pub fn committed_meshes() -> Vec<(&'static str, TestMesh)> {
    vec![
        ("grass_patch.gltf", grass_patch(4.0)),
        ("sphere.gltf", uv_sphere(24, 24, 0.5)),
        ("plane_bare_centre.gltf", plane_with_bare_region(8, 2.0)),
    ]
}

/// A skinned, morphing, animated strip for the animation tests (glTF 2.0 "Skins", "Morph
/// Targets", "Animations"): six vertices at `y = 0, 1, 2` and `x = ±0.5` (four triangles, normals
/// +Z), two joints — `root` at the origin and its child `bend` at `y = 1` — with weights 1/0 at
/// `y = 0`, ½/½ at `y = 1`, 0/1 at `y = 2`; inverse binds identity and translate(0, −1, 0). The
/// mesh node carries a translation of 10 m in x that the specification says to ignore. One morph
/// target lifts the top row by +1 in z (normal delta +0.5 x). Edit the fields, then [`to_gltf`].
///
/// [`to_gltf`]: SkinnedStrip::to_gltf
#[derive(Clone, Debug)]
pub struct SkinnedStrip {
    /// `POSITION`.
    pub positions: Vec<[f32; 3]>,
    /// `JOINTS_0` (as float-convertible unsigned shorts).
    pub joints: Vec<[u16; 4]>,
    /// `WEIGHTS_0`.
    pub weights: Vec<[f32; 4]>,
    /// Optional `JOINTS_1` / `WEIGHTS_1`.
    pub second_set: Option<InfluenceSet>,
    /// Inverse bind matrices (column-major), one per joint.
    pub inverse_binds: Vec<[f32; 16]>,
    /// Morph target 0: position deltas.
    pub morph_positions: Vec<[f32; 3]>,
    /// Morph target 0: normal deltas.
    pub morph_normals: Vec<[f32; 3]>,
    /// Animations: (name, channels as (node, path, interpolation, times, flat values)).
    pub animations: Vec<TestAnimation>,
}

/// A `JOINTS_n` / `WEIGHTS_n` pair.
pub type InfluenceSet = (Vec<[u16; 4]>, Vec<[f32; 4]>);

/// One channel of a [`TestAnimation`]: `(node, path, interpolation, key times, flat values)`.
pub type TestChannel = (usize, &'static str, &'static str, Vec<f32>, Vec<f32>);

/// One animation of a [`SkinnedStrip`]: a name and channels, each `(node, path, interpolation,
/// key times, flat output values)`; node 0 is `root`, 1 is `bend`, 2 is the mesh node.
#[derive(Clone, Debug)]
pub struct TestAnimation {
    /// The animation's name.
    pub name: String,
    /// Its channels.
    pub channels: Vec<TestChannel>,
}

impl Default for SkinnedStrip {
    fn default() -> Self {
        let positions = vec![
            [-0.5, 0.0, 0.0],
            [0.5, 0.0, 0.0],
            [-0.5, 1.0, 0.0],
            [0.5, 1.0, 0.0],
            [-0.5, 2.0, 0.0],
            [0.5, 2.0, 0.0],
        ];
        let w = |a: f32| [a, 1.0 - a, 0.0, 0.0];
        let id = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        let mut down = id;
        down[13] = -1.0;
        let s = std::f32::consts::FRAC_1_SQRT_2;
        SkinnedStrip {
            positions,
            joints: vec![[0, 1, 0, 0]; 6],
            weights: vec![w(1.0), w(1.0), w(0.5), w(0.5), w(0.0), w(0.0)],
            second_set: None,
            inverse_binds: vec![id, down],
            morph_positions: vec![[0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]],
            morph_normals: vec![[0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3], [0.5, 0.0, 0.0], [0.5, 0.0, 0.0]],
            animations: vec![
                TestAnimation {
                    name: "Bend".into(),
                    channels: vec![(1, "rotation", "LINEAR", vec![0.0, 1.0], vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, s, s])],
                },
                TestAnimation {
                    name: "Step".into(),
                    channels: vec![(0, "translation", "STEP", vec![0.0, 1.0], vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0])],
                },
                TestAnimation {
                    name: "Cubic".into(),
                    // Keys at 0 s and 2 s: value 0 → 1 in x, out-tangent of key 0 and in-tangent
                    // of key 1 both (3, 0, 0) per second.
                    channels: vec![(
                        0,
                        "translation",
                        "CUBICSPLINE",
                        vec![0.0, 2.0],
                        vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 3.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                    )],
                },
                TestAnimation {
                    name: "Morph".into(),
                    channels: vec![(2, "weights", "LINEAR", vec![0.0, 1.0], vec![0.0, 1.0])],
                },
            ],
        }
    }
}

impl SkinnedStrip {
    /// The `.gltf` JSON document (buffer embedded), for editing before [`SkinnedStrip::to_gltf`].
    pub fn to_json(&self) -> Value {
        let mut b = BufferBuilder { data: Vec::new(), views: Vec::new(), accessors: Vec::new() };
        let pos = b.floats(&self.positions, "VEC3", true);
        let normals = b.floats(&vec![[0.0f32, 0.0, 1.0]; self.positions.len()], "VEC3", false);
        let short4 = |b: &mut BufferBuilder, j: &[[u16; 4]]| {
            let words: Vec<[u8; 4]> = j
                .iter()
                .flat_map(|q| [[q[0].to_le_bytes(), q[1].to_le_bytes()], [q[2].to_le_bytes(), q[3].to_le_bytes()]])
                .map(|[a, c]| [a[0], a[1], c[0], c[1]])
                .collect();
            b.push(&words, j.len(), "VEC4", 5123, json!({}))
        };
        let joints = short4(&mut b, &self.joints);
        let weights = b.floats(&self.weights, "VEC4", false);
        let idx: Vec<[u8; 4]> = [0u32, 1, 3, 0, 3, 2, 2, 3, 5, 2, 5, 4].iter().map(|i| i.to_le_bytes()).collect();
        let indices = b.push(&idx, 12, "SCALAR", 5125, json!({}));
        let mut attributes = json!({ "POSITION": pos, "NORMAL": normals, "JOINTS_0": joints, "WEIGHTS_0": weights });
        if let Some((j, w)) = &self.second_set {
            attributes["JOINTS_1"] = json!(short4(&mut b, j));
            attributes["WEIGHTS_1"] = json!(b.floats(w, "VEC4", false));
        }
        let ibm = b.floats(&self.inverse_binds, "MAT4", false);
        let mp = b.floats(&self.morph_positions, "VEC3", true);
        let mn = b.floats(&self.morph_normals, "VEC3", false);
        let mut animations = Vec::new();
        for a in &self.animations {
            let mut samplers = Vec::new();
            let mut channels = Vec::new();
            for (node, path, interpolation, times, values) in &a.channels {
                let t: Vec<[f32; 1]> = times.iter().map(|&x| [x]).collect();
                let input = b.floats(&t, "SCALAR", true);
                let (ty, n) = match *path {
                    "translation" | "scale" => ("VEC3", 3),
                    "rotation" => ("VEC4", 4),
                    _ => ("SCALAR", 1),
                };
                let words: Vec<[u8; 4]> = values.iter().map(|v| v.to_le_bytes()).collect();
                let output = b.push(&words, values.len() / n, ty, 5126, json!({}));
                samplers.push(json!({ "input": input, "output": output, "interpolation": interpolation }));
                channels.push(json!({ "sampler": samplers.len() - 1, "target": { "node": node, "path": path } }));
            }
            animations.push(json!({ "name": a.name, "samplers": samplers, "channels": channels }));
        }
        json!({
            "asset": { "version": "2.0", "generator": "furbake-import testmesh" },
            "scene": 0,
            "scenes": [{ "nodes": [0, 2] }],
            "nodes": [
                { "name": "root", "children": [1] },
                { "name": "bend", "translation": [0.0, 1.0, 0.0] },
                { "name": "strip", "mesh": 0, "skin": 0, "translation": [10.0, 0.0, 0.0] },
            ],
            "skins": [{ "name": "strip_skin", "joints": [0, 1], "inverseBindMatrices": ibm, "skeleton": 0 }],
            "meshes": [{
                "name": "strip",
                "primitives": [{ "attributes": attributes, "indices": indices, "mode": 4,
                                 "targets": [{ "POSITION": mp, "NORMAL": mn }] }],
                "weights": [0.0],
                "extras": { "targetNames": ["lift"] },
            }],
            "animations": animations,
            "buffers": [{ "byteLength": b.data.len(), "uri": data_uri(&b.data) }],
            "bufferViews": b.views,
            "accessors": b.accessors,
        })
    }

    /// The `.gltf` JSON bytes.
    pub fn to_gltf(&self) -> Vec<u8> {
        serde_json::to_vec_pretty(&self.to_json()).expect("a serde_json::Value always serialises")
    }
}
