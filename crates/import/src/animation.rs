//! Skins, morph targets and animation clips (glTF 2.0 specification, "Skins", "Morph Targets",
//! "Animations"). The scene walk asks this module, per primitive, for each raw vertex's influences
//! (`JOINTS_0/1`, `WEIGHTS_0/1`: up to eight, normalised) and morph deltas; after welding it
//! builds the sections:
//!
//! - the *binds* (skinning palette): every joint of every skin a skinned mesh uses, with its
//!   inverse bind matrix; and, in a file with skins or animations, one rigid bind per node of an
//!   unskinned mesh (inverse of the node's rest world matrix), so rigid parts follow their node;
//! - the skeleton: the binds' nodes and all their ancestors in topological order, rest local TRS;
//! - the morph targets: one group per mesh instance with targets, deltas per welded vertex;
//! - the clips: every animation's channels that drive a skeleton joint or a morph group.
//!
//! Skinned meshes obey the specification's rule: the skinned mesh node's own transform is
//! ignored (the walker passes the identity), the joints carry it. Bad data is an
//! [`ImportError::Animation`] naming the skin, sampler, channel or primitive and the index; weights
//! that do not sum to 1 are renormalised and counted.

use std::collections::HashMap;
use std::path::Path;

use furbake_formats::sections::animation_clips::{
    AnimationClip, AnimationClips, ChannelTarget, ClipChannel, Interpolation,
};
use furbake_formats::sections::morph_targets::{MorphGroup, MorphTargets};
use furbake_formats::sections::skeleton::{AFFINE_TOLERANCE, MAX_NAME_BYTES, MIN_INVERSE_BIND_DETERMINANT, Skeleton};
use furbake_formats::sections::skin_weights::{SkinWeightStats, SkinWeights};
use glam::{DMat3, DMat4, DQuat, DVec3};
use gltf::json;
use gltf::json::accessor::Type;
use gltf::json::animation::{Interpolation as GltfInterpolation, Property};
use gltf::json::validation::Checked;

use crate::accessor::{AccessorReader, semantic_name};
use crate::error::AnimationRef;
use crate::limits::{MAX_CHANNELS, MAX_CLIPS, MAX_JOINTS, MAX_KEYS, MAX_MORPH_DELTAS, MAX_MORPH_TARGETS};
use crate::source::Asset;
use crate::{ImportError, PrimitiveRef};

/// Influence slots kept per vertex (`JOINTS_0` + `JOINTS_1`).
pub(crate) const MAX_INFLUENCES: usize = 8;
/// Up to eight `(bind, weight)` pairs, largest weight first, unused slots `(0, 0.0)`.
pub(crate) type Influences = [(u32, f32); MAX_INFLUENCES];
/// Morph group of a raw vertex without morph targets.
pub(crate) const NO_GROUP: u32 = u32::MAX;
/// A vertex's weights are renormalised *and counted* when their sum is off by more than this.
const SUM_REPORT_TOLERANCE: f64 = 1e-3;

/// A palette entry before the skeleton exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum BindKey {
    Skin { skin: usize, slot: usize },
    Rigid { node: usize },
}

/// A mesh instance with morph targets.
struct Group {
    name: String,
    target_names: Vec<String>,
    defaults: Vec<f32>,
}

/// What the walk collects for the animation sections.
pub(crate) struct Rig {
    /// Whether vertices get influences (the file has skins or animations).
    pub binding: bool,
    binds: Vec<BindKey>,
    bind_index: HashMap<BindKey, u32>,
    inverse_binds: Vec<DMat4>,
    /// Per skin: bind index of each joint slot.
    skin_binds: HashMap<usize, Vec<u32>>,
    groups: Vec<Group>,
    group_of_node: HashMap<usize, u32>,
    pub stats: SkinWeightStats,
    pub warnings: Vec<String>,
}

fn cut_name(name: &str) -> String {
    let mut end = name.len().min(MAX_NAME_BYTES);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    name[..end].to_string()
}

/// `m` with its bottom row exactly `0, 0, 0, 1` when it is that within the stored form's
/// tolerance (`skeleton::AFFINE_TOLERANCE`: an inverse bind is affine, and readers refuse any other
/// bottom row), else `None`.
fn affine(m: DMat4) -> Option<DMat4> {
    let row = m.row(3);
    let tolerance = f64::from(AFFINE_TOLERANCE);
    let near = [row.x, row.y, row.z, row.w - 1.0].iter().all(|x| x.abs() <= tolerance);
    near.then(|| {
        let mut m = m;
        (m.x_axis.w, m.y_axis.w, m.z_axis.w, m.w_axis.w) = (0.0, 0.0, 0.0, 1.0);
        m
    })
}

fn mat4_array(m: DMat4) -> [f32; 16] {
    m.to_cols_array().map(|x| x as f32)
}

/// An accessor error about a skin or sampler, renamed from the dummy primitive the reader needs.
fn rename(e: ImportError, dummy: &PrimitiveRef, at: &AnimationRef) -> ImportError {
    match e {
        ImportError::Accessor { file, attribute, accessor, message, .. } => ImportError::Animation {
            file,
            at: Box::new(at.clone()),
            message: format!("{attribute} (accessor {accessor}): {message}"),
        },
        ImportError::TooLarge { file, what, count, limit } => {
            ImportError::TooLarge { file, what: what.replacen(&dummy.to_string(), &at.to_string(), 1), count, limit }
        }
        other => other,
    }
}

impl Rig {
    pub fn new(root: &json::Root) -> Self {
        Rig {
            binding: !root.skins.is_empty() || !root.animations.is_empty(),
            binds: Vec::new(),
            bind_index: HashMap::new(),
            inverse_binds: Vec::new(),
            skin_binds: HashMap::new(),
            groups: Vec::new(),
            group_of_node: HashMap::new(),
            stats: SkinWeightStats::default(),
            warnings: Vec::new(),
        }
    }

    fn error(file: &Path, at: AnimationRef, message: String) -> ImportError {
        ImportError::Animation { file: file.to_path_buf(), at: Box::new(at), message }
    }

    fn add_bind(&mut self, key: BindKey, inverse_bind: DMat4, file: &Path) -> Result<u32, ImportError> {
        if let Some(&b) = self.bind_index.get(&key) {
            return Ok(b);
        }
        if self.binds.len() >= MAX_JOINTS {
            return Err(ImportError::TooLarge {
                file: file.to_path_buf(),
                what: "the number of skin binds (joints of the skins used plus rigidly bound meshes)".into(),
                count: self.binds.len() as u64 + 1,
                limit: MAX_JOINTS as u64,
            });
        }
        let b = self.binds.len() as u32;
        self.binds.push(key);
        self.bind_index.insert(key, b);
        self.inverse_binds.push(inverse_bind);
        Ok(b)
    }

    /// The bind of each joint slot of skin `skin`, reading and checking its inverse bind
    /// matrices the first time.
    pub fn skin_binds(&mut self, asset: &Asset, file: &Path, skin: usize) -> Result<Vec<u32>, ImportError> {
        if let Some(b) = self.skin_binds.get(&skin) {
            return Ok(b.clone());
        }
        let s = asset.root.skins.get(skin).ok_or_else(|| ImportError::InvalidGltf {
            file: file.to_path_buf(),
            message: format!("skin {skin} does not exist"),
        })?;
        let at = AnimationRef::Skin { skin, name: s.name.as_deref().map(Box::from) };
        if s.joints.is_empty() {
            return Err(Rig::error(file, at, "the skin has no joints".into()));
        }
        if s.joints.len() > MAX_JOINTS {
            return Err(ImportError::TooLarge {
                file: file.to_path_buf(),
                what: format!("{at}: the number of joints"),
                count: s.joints.len() as u64,
                limit: MAX_JOINTS as u64,
            });
        }
        if let Some(j) = s.joints.iter().position(|j| j.value() >= asset.root.nodes.len()) {
            return Err(Rig::error(
                file,
                at,
                format!("joint {j} names node {}, which does not exist", s.joints[j].value()),
            ));
        }
        let ibms: Vec<DMat4> = match s.inverse_bind_matrices {
            None => vec![DMat4::IDENTITY; s.joints.len()],
            Some(acc) => {
                let dummy = PrimitiveRef { mesh: 0, mesh_name: None, primitive: 0 };
                let reader = AccessorReader { root: &asset.root, buffers: &asset.buffers, file, at: &dummy };
                let e = reader
                    .read("inverseBindMatrices", acc.value(), &[Type::Mat4])
                    .map_err(|e| rename(e, &dummy, &at))?;
                if e.count() != s.joints.len() {
                    return Err(Rig::error(
                        file,
                        at,
                        format!("{} inverse bind matrices for {} joints", e.count(), s.joints.len()),
                    ));
                }
                (0..e.count()).map(|j| DMat4::from_cols_slice(e.get(j))).collect()
            }
        };
        let mut binds = Vec::with_capacity(ibms.len());
        for (slot, m) in ibms.into_iter().enumerate() {
            let det = DMat3::from_mat4(m).determinant();
            if !m.is_finite()
                || m.abs().to_cols_array().iter().any(|x| *x > 1e7)
                || det.abs() < MIN_INVERSE_BIND_DETERMINANT
            {
                return Err(Rig::error(
                    file,
                    at,
                    format!(
                        "the inverse bind matrix of joint {slot} is not invertible, not finite or beyond 1e7 (det {det:e})"
                    ),
                ));
            }
            let Some(m) = affine(m) else {
                return Err(Rig::error(
                    file,
                    at,
                    format!("the inverse bind matrix of joint {slot} is not affine (bottom row {:?})", m.row(3)),
                ));
            };
            binds.push(self.add_bind(BindKey::Skin { skin, slot }, m, file)?);
        }
        self.skin_binds.insert(skin, binds.clone());
        Ok(binds)
    }

    /// The rigid bind of an unskinned mesh on `node` whose rest world matrix is `world`.
    pub fn rigid_bind(&mut self, file: &Path, node: usize, world: DMat4) -> Result<u32, ImportError> {
        let det = DMat3::from_mat4(world).determinant();
        let inverse = world.inverse();
        let usable = det.abs() >= MIN_INVERSE_BIND_DETERMINANT
            && DMat3::from_mat4(inverse).determinant().abs() >= MIN_INVERSE_BIND_DETERMINANT
            && inverse.abs().to_cols_array().iter().all(|x| *x <= 1e7);
        let inverse = match affine(inverse).filter(|_| usable) {
            Some(inverse) => inverse,
            None => {
                // Every triangle of such a node is (nearly) degenerate; the bind only has to be valid.
                self.warnings.push(format!(
                    "node {node}: a (nearly) singular or non-affine rest transform; its rigid bind uses the identity"
                ));
                DMat4::IDENTITY
            }
        };
        self.add_bind(BindKey::Rigid { node }, inverse, file)
    }

    /// Reads `JOINTS_0/1` and `WEIGHTS_0/1` of a skinned primitive with `n` vertices: per vertex
    /// the influences as binds of `binds` (the skin's slots), normalised. Only `referenced`
    /// vertices (used by a triangle) must carry a usable set.
    #[allow(clippy::too_many_arguments)]
    pub fn read_influences(
        &mut self,
        reader: &AccessorReader<'_>,
        primitive: &json::mesh::Primitive,
        n: usize,
        binds: &[u32],
        referenced: &[bool],
        skin: usize,
    ) -> Result<Vec<Influences>, ImportError> {
        let file = reader.file;
        let at = || AnimationRef::Primitive(reader.at.clone());
        let find = |name: &str| {
            primitive.attributes.iter().find_map(|(s, a)| match s {
                Checked::Valid(s) if semantic_name(s) == name => Some(a.value()),
                _ => None,
            })
        };
        let mut sets = Vec::new();
        for set in 0..2 {
            match (find(&format!("JOINTS_{set}")), find(&format!("WEIGHTS_{set}"))) {
                (Some(j), Some(w)) => {
                    let joints = reader.read(&format!("JOINTS_{set}"), j, &[Type::Vec4])?;
                    let weights = reader.read(&format!("WEIGHTS_{set}"), w, &[Type::Vec4])?;
                    for (name, e) in [("JOINTS", &joints), ("WEIGHTS", &weights)] {
                        if e.count() != n {
                            return Err(Rig::error(
                                file,
                                at(),
                                format!("{name}_{set} has {} elements, POSITION has {n}", e.count()),
                            ));
                        }
                    }
                    sets.push((joints, weights));
                }
                (None, None) if set > 0 => {}
                _ => {
                    return Err(Rig::error(
                        file,
                        at(),
                        format!("the node has skin {skin} but the primitive lacks JOINTS_{set} or WEIGHTS_{set}"),
                    ));
                }
            }
        }
        if find("JOINTS_2").is_some() || find("WEIGHTS_2").is_some() {
            self.warnings.push(format!("{}: JOINTS_2/WEIGHTS_2 and beyond ignored (at most 8 influences)", reader.at));
        }
        let mut out = Vec::with_capacity(n);
        let mut zero_weight = 0u32;
        for (v, &used) in referenced.iter().enumerate().take(n) {
            let mut list: Vec<(u32, f64)> = Vec::with_capacity(MAX_INFLUENCES);
            for (joints, weights) in &sets {
                for k in 0..4 {
                    let (j, w) = (joints.get(v)[k], weights.get(v)[k]);
                    if !w.is_finite() {
                        if used {
                            return Err(Rig::error(file, at(), format!("vertex {v}: weight {k} is not finite ({w})")));
                        }
                        continue;
                    }
                    if w < 0.0 {
                        self.stats.dropped_influences += 1;
                        continue;
                    }
                    if w == 0.0 {
                        continue;
                    }
                    let Some(&bind) = binds.get(j as usize) else {
                        if used {
                            return Err(Rig::error(
                                file,
                                at(),
                                format!(
                                    "vertex {v}: joint index {j} is out of range (skin {skin} has {} joints)",
                                    binds.len()
                                ),
                            ));
                        }
                        continue;
                    };
                    match list.iter_mut().find(|(b, _)| *b == bind) {
                        Some(entry) => entry.1 += w,
                        None => list.push((bind, w)),
                    }
                }
            }
            let sum: f64 = list.iter().map(|(_, w)| w).sum();
            if sum <= 0.0 || !sum.is_finite() {
                // No joint moves it (weights all zero): a reported repair, not a refusal — the
                // vertex is bound wholly to the skin's first joint, as if renormalised onto it,
                // so it follows the skeleton instead of collapsing to the origin.
                if used {
                    self.stats.renormalised_vertices += 1;
                    zero_weight += 1;
                }
                out.push([(binds[0], 1.0), (0, 0.0), (0, 0.0), (0, 0.0), (0, 0.0), (0, 0.0), (0, 0.0), (0, 0.0)]);
                continue;
            }
            if (sum - 1.0).abs() > SUM_REPORT_TOLERANCE && used {
                self.stats.renormalised_vertices += 1;
            }
            list.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            let mut inf: Influences = [(0, 0.0); MAX_INFLUENCES];
            for (slot, (b, w)) in inf.iter_mut().zip(&list) {
                *slot = (*b, (w / sum) as f32);
            }
            out.push(inf);
        }
        self.stats.skinned_vertices += n as u32;
        if zero_weight > 0 {
            self.warnings.push(format!(
                "{}: {zero_weight} vertices have weights that sum to 0; bound to the skin's first joint \
                 (counted in renormalised_vertices)",
                reader.at
            ));
        }
        Ok(out)
    }

    /// The morph group of mesh `mesh` instanced on `node`, registered the first time: its target
    /// count (all primitives must agree), names and default weights (the node's, else the
    /// mesh's). `None` when the mesh has no targets.
    pub fn morph_group(
        &mut self,
        asset: &Asset,
        file: &Path,
        node: usize,
        mesh: usize,
    ) -> Result<Option<(u32, usize)>, ImportError> {
        if let Some(&g) = self.group_of_node.get(&node) {
            return Ok(Some((g, self.groups[g as usize].defaults.len())));
        }
        let Some(m) = asset.root.meshes.get(mesh) else { return Ok(None) };
        let counts: Vec<usize> = m.primitives.iter().map(|p| p.targets.as_ref().map_or(0, Vec::len)).collect();
        let t = counts.iter().copied().max().unwrap_or(0);
        if t == 0 {
            return Ok(None);
        }
        if let Some(p) = counts.iter().position(|&c| c != t) {
            let at = AnimationRef::Primitive(PrimitiveRef {
                mesh,
                mesh_name: m.name.as_deref().map(Box::from),
                primitive: p,
            });
            return Err(Rig::error(
                file,
                at,
                format!("{} morph targets, another primitive of the mesh has {t}", counts[p]),
            ));
        }
        let total: usize = self.groups.iter().map(|g| g.defaults.len()).sum::<usize>() + t;
        if total > MAX_MORPH_TARGETS {
            return Err(ImportError::TooLarge {
                file: file.to_path_buf(),
                what: "the number of morph targets over all mesh instances".into(),
                count: total as u64,
                limit: MAX_MORPH_TARGETS as u64,
            });
        }
        let node_ref = &asset.root.nodes[node];
        let mut defaults = node_ref.weights.clone().or_else(|| m.weights.clone()).unwrap_or_default();
        if defaults.len() != t || defaults.iter().any(|w| !w.is_finite() || w.abs() > 1e3) {
            if !defaults.is_empty() {
                self.warnings.push(format!(
                    "node {node}: {} default morph weights for {t} targets (or out of range); zeros used",
                    defaults.len()
                ));
            }
            defaults = vec![0.0; t];
        }
        let target_names = m
            .extras
            .as_ref()
            .and_then(|raw| serde_json::from_str::<serde_json::Value>(raw.get()).ok())
            .and_then(|v| v.get("targetNames").cloned())
            .and_then(|v| serde_json::from_value::<Vec<String>>(v).ok())
            .filter(|names| names.len() == t)
            .map(|names| names.iter().map(|n| cut_name(n)).collect())
            .unwrap_or_else(|| vec![String::new(); t]);
        let name = cut_name(node_ref.name.as_deref().or(m.name.as_deref()).unwrap_or(""));
        let g = self.groups.len() as u32;
        self.groups.push(Group { name, target_names, defaults });
        self.group_of_node.insert(node, g);
        Ok(Some((g, t)))
    }

    /// Reads the `t` morph targets of a primitive with `n` vertices: per vertex `2t` deltas
    /// (positions, then normals), by `linear` and `normal_matrix` (the identity for skinned
    /// meshes, the node's world transform otherwise).
    pub fn read_morph_deltas(
        reader: &AccessorReader<'_>,
        primitive: &json::mesh::Primitive,
        n: usize,
        t: usize,
        linear: DMat3,
        normal_matrix: DMat3,
    ) -> Result<Vec<[f32; 3]>, ImportError> {
        let mut out = vec![[0.0f32; 3]; n * 2 * t];
        let targets = primitive.targets.as_deref().unwrap_or(&[]);
        for (k, target) in targets.iter().enumerate().take(t) {
            for (which, acc, m) in [(0, target.positions, linear), (1, target.normals, normal_matrix)] {
                let Some(acc) = acc else { continue };
                let name = format!("target {k} {}", if which == 0 { "POSITION" } else { "NORMAL" });
                let e = reader.read(&name, acc.value(), &[Type::Vec3])?;
                if e.count() != n {
                    return Err(Rig::error(
                        reader.file,
                        AnimationRef::Primitive(reader.at.clone()),
                        format!("{name} has {} elements, POSITION has {n}", e.count()),
                    ));
                }
                for v in 0..n {
                    let d = m * DVec3::from_slice(e.get(v));
                    if !d.as_vec3().is_finite() || d.abs().max_element() > 1e7 {
                        return Err(Rig::error(
                            reader.file,
                            AnimationRef::Primitive(reader.at.clone()),
                            format!("{name} of vertex {v} is not finite or beyond 1e7"),
                        ));
                    }
                    out[v * 2 * t + which * t + k] = d.as_vec3().to_array();
                }
            }
        }
        Ok(out)
    }
}

/// The parent of every node (from the `children` lists), checking that no node has two.
fn parents(root: &json::Root, file: &Path) -> Result<Vec<Option<usize>>, ImportError> {
    let mut parent = vec![None; root.nodes.len()];
    for (p, node) in root.nodes.iter().enumerate() {
        for c in node.children.iter().flatten() {
            let c = c.value();
            let Some(slot) = parent.get_mut(c) else { continue };
            if slot.is_some_and(|q| q != p) {
                return Err(ImportError::Scene {
                    file: file.to_path_buf(),
                    node: c,
                    message: "the node has two parents (the node hierarchy must be a forest)".into(),
                });
            }
            *slot = Some(p);
        }
    }
    Ok(parent)
}

/// A node's rest local transform as TRS (a `matrix` is decomposed; a shear cannot be and is
/// reported by the caller).
fn local_trs(node: &json::scene::Node) -> (DVec3, DQuat, DVec3) {
    if let Some(m) = node.matrix {
        let (s, r, t) = DMat4::from_cols_array(&m.map(f64::from)).to_scale_rotation_translation();
        return (t, r.normalize(), s);
    }
    let t = node.translation.unwrap_or([0.0; 3]).map(f64::from);
    let r = node.rotation.as_ref().map_or([0.0, 0.0, 0.0, 1.0], |q| q.0).map(f64::from);
    let s = node.scale.unwrap_or([1.0; 3]).map(f64::from);
    (DVec3::from(t), DQuat::from_xyzw(r[0], r[1], r[2], r[3]).normalize(), DVec3::from(s))
}

/// The animation sections of an import.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImportedAnimation {
    /// The joint hierarchy and palette (with [`ImportedAnimation::skin_weights`]), when the file
    /// has skins or animations.
    pub skeleton: Option<Skeleton>,
    /// Influences per welded vertex.
    pub skin_weights: Option<SkinWeights>,
    /// Morph targets per welded vertex, when some mesh instance has them.
    pub morph_targets: Option<MorphTargets>,
    /// Every clip that drives a joint or morph group.
    pub clips: Option<AnimationClips>,
}

/// Per raw vertex data the weld carries to the welded vertices.
pub(crate) struct RawRig<'a> {
    pub influences: &'a [Influences],
    pub morph_group: &'a [u32],
    pub morph_at: &'a [u32],
    pub morph_deltas: &'a [[f32; 3]],
}

impl Rig {
    /// Builds the sections for the welded vertices, `representatives[v]` being a raw vertex of
    /// welded vertex `v` (all its members agree on influences and morph deltas).
    pub fn finish(
        mut self,
        asset: &Asset,
        file: &Path,
        raw: &RawRig<'_>,
        representatives: &[u32],
    ) -> Result<(ImportedAnimation, Vec<String>), ImportError> {
        let mut out = ImportedAnimation::default();
        let root = &asset.root;
        // Skeleton: the binds' nodes and their ancestors, ordered by depth then node index.
        let mut joint_of_node: HashMap<usize, u32> = HashMap::new();
        if !self.binds.is_empty() {
            let parent = parents(root, file)?;
            let mut needed: Vec<(usize, usize)> = Vec::new(); // (depth, node)
            let mut seen = vec![false; root.nodes.len()];
            let bind_nodes: Vec<usize> = self
                .binds
                .iter()
                .map(|b| match *b {
                    BindKey::Skin { skin, slot } => root.skins[skin].joints[slot].value(),
                    BindKey::Rigid { node } => node,
                })
                .collect();
            for &n in &bind_nodes {
                let mut chain = Vec::new();
                let mut at = Some(n);
                while let Some(x) = at {
                    if seen[x] {
                        break;
                    }
                    if chain.len() > crate::limits::MAX_NODE_DEPTH {
                        return Err(ImportError::Scene {
                            file: file.to_path_buf(),
                            node: n,
                            message: format!(
                                "the joint's ancestry is deeper than {} or cyclic",
                                crate::limits::MAX_NODE_DEPTH
                            ),
                        });
                    }
                    chain.push(x);
                    at = parent[x];
                }
                for &x in &chain {
                    seen[x] = true;
                }
                // Depths: count ancestors (bounded by the check above for new nodes).
                for &x in &chain {
                    let mut d = 0;
                    let mut a = parent[x];
                    while let Some(y) = a {
                        d += 1;
                        a = parent[y];
                        if d > crate::limits::MAX_NODE_DEPTH {
                            break;
                        }
                    }
                    needed.push((d, x));
                }
            }
            if needed.len() > MAX_JOINTS {
                return Err(ImportError::TooLarge {
                    file: file.to_path_buf(),
                    what: "the number of skeleton joints".into(),
                    count: needed.len() as u64,
                    limit: MAX_JOINTS as u64,
                });
            }
            needed.sort_unstable();
            for (j, &(_, n)) in needed.iter().enumerate() {
                joint_of_node.insert(n, j as u32);
            }
            let mut sk = Skeleton::default();
            let mut sheared = 0;
            for &(_, n) in &needed {
                let node = &root.nodes[n];
                sk.names.push(cut_name(node.name.as_deref().unwrap_or("")));
                sk.nodes.push(n as u32);
                sk.parents.push(parent[n].and_then(|p| joint_of_node.get(&p).copied()).unwrap_or(Skeleton::NO_PARENT));
                let (t, r, s) = local_trs(node);
                if let Some(m) = node.matrix {
                    let m = DMat4::from_cols_array(&m.map(f64::from));
                    let back = DMat4::from_scale_rotation_translation(s, r, t);
                    if !back.abs_diff_eq(m, 1e-5 * (1.0 + m.to_cols_array().iter().fold(0.0f64, |a, x| a.max(x.abs()))))
                    {
                        sheared += 1;
                    }
                }
                if !(t.as_vec3().is_finite() && s.as_vec3().is_finite() && r.is_finite())
                    || t.abs().max_element() > 1e7
                    || s.abs().max_element() > 1e7
                {
                    return Err(ImportError::Scene {
                        file: file.to_path_buf(),
                        node: n,
                        message: "the joint's rest transform is not finite or beyond 1e7".into(),
                    });
                }
                sk.translations.push(t.as_vec3().to_array());
                sk.rotations.push(r.as_quat().to_array());
                sk.scales.push(s.as_vec3().to_array());
            }
            if sheared > 0 {
                self.warnings.push(format!("{sheared} joint matrices with shear kept as their nearest TRS"));
            }
            for (b, &node) in bind_nodes.iter().enumerate() {
                sk.bind_joints.push(joint_of_node[&node]);
                sk.inverse_binds.push(mat4_array(self.inverse_binds[b]));
            }
            sk.skin_root =
                root.skins.first().and_then(|s| s.skeleton).and_then(|n| joint_of_node.get(&n.value()).copied());
            // Weights per welded vertex.
            let k = if representatives.iter().any(|&r| raw.influences[r as usize][4].1 > 0.0) { 8 } else { 4 };
            let mut w = SkinWeights {
                influences_per_vertex: k as u32,
                bind_count: sk.bind_count() as u32,
                binds: Vec::with_capacity(k * representatives.len()),
                weights: Vec::with_capacity(k * representatives.len()),
                stats: self.stats.clone(),
            };
            for &r in representatives {
                let inf = &raw.influences[r as usize];
                // Renormalise in f64 after the f32 rounding so the stored sum is 1 within f32.
                let sum: f64 = inf[..k].iter().map(|(_, x)| f64::from(*x)).sum();
                for &(b, x) in &inf[..k] {
                    w.binds.push(b as u16);
                    w.weights.push((f64::from(x) / sum) as f32);
                }
            }
            out.skeleton = Some(sk);
            out.skin_weights = Some(w);
        }
        // Morph targets per welded vertex.
        if !self.groups.is_empty() {
            let t: usize = self.groups.iter().map(|g| g.defaults.len()).sum();
            let v = representatives.len();
            if (t as u64) * (v as u64) > MAX_MORPH_DELTAS {
                return Err(ImportError::TooLarge {
                    file: file.to_path_buf(),
                    what: "the morph deltas (targets × welded vertices)".into(),
                    count: t as u64 * v as u64,
                    limit: MAX_MORPH_DELTAS,
                });
            }
            let mut first = Vec::with_capacity(self.groups.len());
            let mut m = MorphTargets { vertex_count: v as u32, ..MorphTargets::default() };
            for g in &self.groups {
                first.push(m.default_weights.len());
                m.groups.push(MorphGroup {
                    name: g.name.clone(),
                    first_target: m.default_weights.len() as u32,
                    target_count: g.defaults.len() as u32,
                });
                m.names.extend(g.target_names.iter().cloned());
                m.default_weights.extend(&g.defaults);
            }
            m.position_deltas = vec![[0.0; 3]; t * v];
            m.normal_deltas = vec![[0.0; 3]; t * v];
            for (wv, &r) in representatives.iter().enumerate() {
                let g = raw.morph_group[r as usize];
                if g == NO_GROUP {
                    continue;
                }
                let tg = self.groups[g as usize].defaults.len();
                let at = raw.morph_at[r as usize] as usize;
                for k in 0..tg {
                    let target = first[g as usize] + k;
                    m.position_deltas[target * v + wv] = raw.morph_deltas[at + k];
                    m.normal_deltas[target * v + wv] = raw.morph_deltas[at + tg + k];
                }
            }
            if m.normal_deltas.iter().all(|d| *d == [0.0; 3]) {
                m.normal_deltas.clear();
            }
            out.morph_targets = Some(m);
        }
        // Clips.
        if !root.animations.is_empty() {
            out.clips = Some(self.read_clips(asset, file, &joint_of_node)?);
        }
        Ok((out, self.warnings))
    }

    fn read_clips(
        &mut self,
        asset: &Asset,
        file: &Path,
        joint_of_node: &HashMap<usize, u32>,
    ) -> Result<AnimationClips, ImportError> {
        let root = &asset.root;
        if root.animations.len() > MAX_CLIPS {
            return Err(ImportError::TooLarge {
                file: file.to_path_buf(),
                what: "the number of animations".into(),
                count: root.animations.len() as u64,
                limit: MAX_CLIPS as u64,
            });
        }
        let dummy = PrimitiveRef { mesh: 0, mesh_name: None, primitive: 0 };
        let reader = AccessorReader { root, buffers: &asset.buffers, file, at: &dummy };
        let mut clips = Vec::new();
        let (mut channels_total, mut keys_total) = (0usize, 0u64);
        for (a, anim) in root.animations.iter().enumerate() {
            let name = anim.name.as_deref().map(Box::from);
            let mut channels = Vec::new();
            let mut dropped = 0;
            for (c, ch) in anim.channels.iter().enumerate() {
                let at_channel = AnimationRef::Channel { animation: a, name: name.clone(), channel: c };
                let node = ch.target.node.value();
                let target = match ch.target.path {
                    Checked::Valid(Property::Translation) => {
                        joint_of_node.get(&node).map(|&j| ChannelTarget::Translation(j))
                    }
                    Checked::Valid(Property::Rotation) => joint_of_node.get(&node).map(|&j| ChannelTarget::Rotation(j)),
                    Checked::Valid(Property::Scale) => joint_of_node.get(&node).map(|&j| ChannelTarget::Scale(j)),
                    Checked::Valid(Property::MorphTargetWeights) => {
                        self.group_of_node.get(&node).map(|&g| ChannelTarget::MorphWeights(g))
                    }
                    Checked::Invalid => return Err(Rig::error(file, at_channel, "invalid target path".into())),
                };
                let Some(target) = target else {
                    dropped += 1;
                    continue;
                };
                let s = ch.sampler.value();
                let at = AnimationRef::Sampler { animation: a, name: name.clone(), sampler: s };
                let sampler = anim
                    .samplers
                    .get(s)
                    .ok_or_else(|| Rig::error(file, at_channel.clone(), format!("sampler {s} does not exist")))?;
                let interpolation = match sampler.interpolation {
                    Checked::Valid(GltfInterpolation::Linear) => Interpolation::Linear,
                    Checked::Valid(GltfInterpolation::Step) => Interpolation::Step,
                    Checked::Valid(GltfInterpolation::CubicSpline) => Interpolation::CubicSpline,
                    Checked::Invalid => return Err(Rig::error(file, at, "invalid interpolation".into())),
                };
                let times =
                    reader.read("input", sampler.input.value(), &[Type::Scalar]).map_err(|e| rename(e, &dummy, &at))?;
                let k = times.count();
                if k == 0 {
                    return Err(Rig::error(file, at, "the sampler has no keys".into()));
                }
                keys_total += k as u64;
                if keys_total > MAX_KEYS {
                    return Err(ImportError::TooLarge {
                        file: file.to_path_buf(),
                        what: "the number of animation keys".into(),
                        count: keys_total,
                        limit: MAX_KEYS,
                    });
                }
                let times_s: Vec<f32> = times.values.iter().map(|&t| t as f32).collect();
                for (i, &t) in times_s.iter().enumerate() {
                    if !t.is_finite() || !(0.0..=1e6).contains(&t) {
                        return Err(Rig::error(file, at, format!("key {i}: time {t} is not in [0, 1e6] s")));
                    }
                    if i > 0 && t <= times_s[i - 1] {
                        return Err(Rig::error(
                            file,
                            at,
                            format!("key {i}: time {t} s does not increase (key {} is {} s)", i - 1, times_s[i - 1]),
                        ));
                    }
                }
                let (types, components): (&[Type], usize) = match target {
                    ChannelTarget::Translation(_) | ChannelTarget::Scale(_) => (&[Type::Vec3], 3),
                    ChannelTarget::Rotation(_) => (&[Type::Vec4], 4),
                    ChannelTarget::MorphWeights(g) => (&[Type::Scalar], self.groups[g as usize].defaults.len()),
                };
                let values =
                    reader.read("output", sampler.output.value(), types).map_err(|e| rename(e, &dummy, &at))?;
                let e = interpolation.elements_per_key();
                let want = k * e * components;
                if values.values.len() != want {
                    return Err(Rig::error(
                        file,
                        at,
                        format!(
                            "{} output values for {k} keys ({} interpolation, {components} components per element): expected {want}",
                            values.values.len(),
                            interpolation.name()
                        ),
                    ));
                }
                let mut vals: Vec<f32> = values.values.iter().map(|&x| x as f32).collect();
                if let Some(i) = vals.iter().position(|x| !x.is_finite() || x.abs() > 1e7) {
                    return Err(Rig::error(file, at, format!("output value {i} is not finite or beyond 1e7")));
                }
                if matches!(target, ChannelTarget::MorphWeights(_)) {
                    if let Some(i) = vals.iter().position(|x| x.abs() > 1e3) {
                        return Err(Rig::error(file, at, format!("output weight {i} is beyond ±1000")));
                    }
                }
                if matches!(target, ChannelTarget::Rotation(_)) {
                    // Rotations are unit quaternions (glTF requires it); normalise the stored
                    // values (not the cubic tangents); a zero quaternion is an error.
                    for key in 0..k {
                        let at_v = (key * e + if e == 3 { 1 } else { 0 }) * 4;
                        let q = &mut vals[at_v..at_v + 4];
                        let len = q.iter().map(|x| f64::from(*x).powi(2)).sum::<f64>().sqrt();
                        if len < 1e-6 {
                            return Err(Rig::error(file, at, format!("key {key}: the rotation is a zero quaternion")));
                        }
                        for x in q.iter_mut() {
                            *x = (f64::from(*x) / len) as f32;
                        }
                    }
                }
                channels_total += 1;
                if channels_total > MAX_CHANNELS {
                    return Err(ImportError::TooLarge {
                        file: file.to_path_buf(),
                        what: "the number of animation channels".into(),
                        count: channels_total as u64,
                        limit: MAX_CHANNELS as u64,
                    });
                }
                channels.push(ClipChannel {
                    target,
                    interpolation,
                    components: components as u32,
                    times_s,
                    values: vals,
                });
            }
            let label = AnimationRef::Channel { animation: a, name: name.clone(), channel: 0 };
            if dropped > 0 {
                self.warnings.push(format!("{label}: {dropped} channels drive nodes that move no mesh; ignored"));
            }
            if channels.is_empty() {
                self.warnings.push(format!("{label}: the animation drives no mesh; not stored"));
                continue;
            }
            let duration_s = channels.iter().filter_map(|c| c.times_s.last().copied()).fold(0.0f32, f32::max);
            let clip_name = cut_name(anim.name.as_deref().unwrap_or(&format!("animation {a}")));
            clips.push(AnimationClip { name: clip_name, duration_s, channels });
        }
        Ok(AnimationClips { clips })
    }
}
