//! Walking the scene: every mesh primitive reachable from the default scene (or scene 0, or every
//! root node when the file has no scene), with node transforms (matrix or TRS) composed
//! recursively, normals transformed by the inverse transpose and winding flipped under a
//! mirroring transform. Triangle strips and fans are triangulated; points and lines are skipped
//! with a warning. Skins, joints and morph targets are ignored: a skinned mesh is imported in its
//! bind pose, i.e. its own POSITIONs under its node's world transform. The output is an unwelded
//! triangle soup with the per-triangle fur mask already decided (docs/design.md "Import").

use std::collections::BTreeSet;
use std::path::Path;

use furbake_formats::sections::MAX_COORDINATE_M;
use glam::{DMat3, DMat4, DQuat, DVec3};
use gltf::json;
use gltf::json::accessor::Type;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use crate::accessor::{AccessorReader, Elements, semantic_name};
use crate::animation::{Influences, MAX_INFLUENCES, NO_GROUP, Rig};
use crate::external::ExternalFiles;

use crate::limits::{MAX_INSTANCED_VERTICES, MAX_NODE_DEPTH, MAX_NODE_VISITS, MAX_RAW_TRIANGLES, MAX_RAW_VERTICES};
use crate::source::Asset;
use crate::texture::TextureCache;
use crate::{FurMaskSource, ImportError, ImportSettings, PrimitiveRef};

/// The unwelded triangles of the whole scene, in world space, struct of arrays per raw vertex.
#[derive(Default)]
pub(crate) struct Soup {
    pub positions: Vec<DVec3>,
    /// The file's normal in world space (unit length), `None` where absent or unusable.
    pub normals: Vec<Option<DVec3>>,
    /// `COLOR_0 × baseColorFactor` (white × factor when absent).
    pub colors: Vec<[f32; 4]>,
    /// `TEXCOORD_0` (zeros where absent).
    pub texcoords: Vec<[f32; 2]>,
    /// Raw vertex indices, winding already corrected for mirroring transforms.
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle: 1 furry, 0 bare.
    pub fur: Vec<u8>,
    /// Triangle primitives imported (node instances counted separately).
    pub primitives: u32,
    /// Whether every imported primitive had `TEXCOORD_0`.
    pub all_have_texcoords: bool,
    /// Whether some primitive had no `NORMAL` or some normal was unusable.
    pub missing_normals: bool,
    /// Whether some primitive had `COLOR_0`.
    pub had_vertex_colors: bool,
    /// Primitives skipped because they are points or lines.
    pub skipped_primitives: u32,
    /// Per raw vertex: its influences (empty unless the file has skins or animations).
    pub influences: Vec<Influences>,
    /// Per raw vertex: its morph group ([`NO_GROUP`] for none).
    pub morph_group: Vec<u32>,
    /// Per raw vertex: where its `2t` morph deltas start in `morph_deltas`.
    pub morph_at: Vec<u32>,
    /// Morph deltas: per raw vertex with a group, `t` position then `t` normal deltas.
    pub morph_deltas: Vec<[f32; 3]>,
    /// Per morph group: `2t`, the deltas stored per raw vertex.
    pub morph_group_len: Vec<usize>,
}

/// How a primitive's vertices are bound to the skeleton.
enum Binding {
    /// The file has no skins and no animations.
    None,
    /// A skinned mesh: the bind of each joint slot of its skin.
    Skin { skin: usize, binds: Vec<u32> },
    /// An unskinned mesh in a rigged file: one bind on its node.
    Rigid(u32),
}

/// Splits an index list into triangles for `mode` (glTF 2.0 §3.7.2.1 topology types).
fn triangulate(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::Triangles => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
            .map(|i| if i % 2 == 0 { [idx[i], idx[i + 1], idx[i + 2]] } else { [idx[i + 1], idx[i], idx[i + 2]] })
            .collect(),
        Mode::TriangleFan => (1..idx.len().saturating_sub(1)).map(|i| [idx[i], idx[i + 1], idx[0]]).collect(),
        _ => Vec::new(),
    }
}

fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "POINTS",
        Mode::Lines => "LINES",
        Mode::LineLoop => "LINE_LOOP",
        Mode::LineStrip => "LINE_STRIP",
        Mode::Triangles => "TRIANGLES",
        Mode::TriangleStrip => "TRIANGLE_STRIP",
        Mode::TriangleFan => "TRIANGLE_FAN",
    }
}

/// The node's local transform: its matrix, or translation × rotation × scale.
fn local_transform(node: &json::scene::Node) -> DMat4 {
    if let Some(m) = node.matrix {
        return DMat4::from_cols_array(&m.map(f64::from));
    }
    let t = node.translation.unwrap_or([0.0; 3]).map(f64::from);
    let r = node.rotation.as_ref().map_or([0.0, 0.0, 0.0, 1.0], |q| q.0).map(f64::from);
    let s = node.scale.unwrap_or([1.0; 3]).map(f64::from);
    let q = DQuat::from_xyzw(r[0], r[1], r[2], r[3]);
    // A non-unit quaternion is normalised; a zero one becomes NaN and is reported by the caller.
    let q = q.normalize();
    DMat4::from_scale_rotation_translation(DVec3::from(s), q, DVec3::from(t))
}

/// A primitive's vertex attributes, read and checked: every count is `POSITION`'s, every value
/// finite (normals may be unusable: they are regenerated).
struct PrimitiveAttributes {
    /// The vertex count.
    n: usize,
    positions: Elements,
    normals: Option<Elements>,
    colors: Option<Elements>,
    uvs: Option<Elements>,
    /// The fur-mask attribute, when the mask source is one and the primitive has it.
    mask: Option<Elements>,
}

/// A primitive's material as its vertices use it.
struct PrimitiveMaterial {
    /// The base colour factor (white without a material).
    factor: [f32; 4],
    name: Option<String>,
    /// The `TEXCOORD` set the base colour texture is sampled at, when it is sampled.
    texture_uvs: Option<Elements>,
    /// The base colour texture (glTF texture index) when its image decoded.
    texture: Option<usize>,
}

/// A node's world transform as a primitive's vertices take it: positions by `world`, morph
/// position deltas by its 3×3 part `linear`, normals by the inverse transpose of that, computed
/// as the cofactor matrix (columns c1×c2, c2×c0, c0×c1) times sign(det), which stays defined for
/// singular matrices. A negative determinant mirrors: the winding flips.
struct NodeTransform {
    world: DMat4,
    linear: DMat3,
    normal_matrix: DMat3,
    mirrors: bool,
}

impl NodeTransform {
    /// The transform of a primitive under `world`.
    fn of(world: DMat4) -> NodeTransform {
        let m3 = DMat3::from_mat4(world);
        let det = m3.determinant();
        let (c0, c1, c2) = (m3.x_axis, m3.y_axis, m3.z_axis);
        let normal_matrix = DMat3::from_cols(c1.cross(c2), c2.cross(c0), c0.cross(c1)) * det.signum();
        NodeTransform { world, linear: m3, normal_matrix, mirrors: det < 0.0 }
    }
}

/// Walks the scene graph and gathers every triangle primitive into a [`Soup`].
pub(crate) struct SceneWalker<'a> {
    pub asset: &'a Asset,
    pub file: &'a Path,
    pub mask: &'a FurMaskSource,
    external: ExternalFiles<'a>,
    sample_textures: bool,
    pub textures: TextureCache,
    pub soup: Soup,
    pub warnings: Vec<String>,
    on_path: Vec<bool>,
    visits: u64,
    /// Mesh nodes skipped because `furbake export` wrote them (shell layers, fins).
    exported_fur_nodes: usize,
    /// Per mesh: imported at least once (a later node naming it is an instance).
    mesh_seen: Vec<bool>,
    /// Vertices added by second and later instances of a mesh.
    instanced_vertices: u64,
    /// Whether some primitive had the fur-mask attribute / colour.
    mask_source_found: bool,
    /// Material names used by imported primitives.
    used_materials: BTreeSet<String>,
    mask_warnings: u32,
    /// Skins, morph targets and animation binds collected on the way.
    pub rig: Rig,
}

impl<'a> SceneWalker<'a> {
    pub fn new(asset: &'a Asset, file: &'a Path, external: ExternalFiles<'a>, settings: &'a ImportSettings) -> Self {
        SceneWalker {
            asset,
            file,
            mask: &settings.fur_mask,
            external,
            sample_textures: settings.base_color_texture,
            textures: TextureCache::default(),
            soup: Soup { all_have_texcoords: true, ..Soup::default() },
            warnings: Vec::new(),
            on_path: vec![false; asset.root.nodes.len()],
            visits: 0,
            exported_fur_nodes: 0,
            mesh_seen: vec![false; asset.root.meshes.len()],
            instanced_vertices: 0,
            mask_source_found: false,
            used_materials: BTreeSet::new(),
            mask_warnings: 0,
            rig: Rig::new(&asset.root),
        }
    }

    fn warn(&mut self, message: String) {
        self.warnings.push(format!("{}: {message}", self.file.display()));
    }

    /// The root nodes to import: the default scene, else scene 0, else every node that is no
    /// other node's child.
    fn root_nodes(&mut self) -> Vec<usize> {
        let root = &self.asset.root;
        let scene = match root.scene {
            Some(s) => root.scenes.get(s.value()),
            None => root.scenes.first(),
        };
        if let Some(scene) = scene {
            if root.scene.is_none() && root.scenes.len() > 1 {
                self.warn("no default scene; importing scene 0".to_string());
            }
            return scene.nodes.iter().map(|n| n.value()).collect();
        }
        let mut is_child = vec![false; root.nodes.len()];
        for node in &root.nodes {
            for c in node.children.iter().flatten() {
                if let Some(flag) = is_child.get_mut(c.value()) {
                    *flag = true;
                }
            }
        }
        (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
    }

    /// Imports everything reachable from the scene, then checks the fur-mask source was usable.
    pub fn walk(&mut self) -> Result<(), ImportError> {
        for node in self.root_nodes() {
            self.visit(node, DMat4::IDENTITY, 0)?;
        }
        if self.exported_fur_nodes > 0 {
            self.warn(format!(
                "skipped {} mesh nodes that furbake export wrote (shell layers and fins): only the skin grows fur",
                self.exported_fur_nodes
            ));
        }
        match self.mask {
            FurMaskSource::VertexColor { .. } if !self.mask_source_found && self.soup.primitives > 0 => {
                return Err(ImportError::FurMask {
                    file: self.file.to_path_buf(),
                    message: "fur mask source is vertex_color, but no imported primitive has COLOR_0".to_string(),
                });
            }
            FurMaskSource::Attribute { name, .. } if !self.mask_source_found && self.soup.primitives > 0 => {
                return Err(ImportError::FurMask {
                    file: self.file.to_path_buf(),
                    message: format!("no imported primitive has the vertex attribute {name}"),
                });
            }
            FurMaskSource::Materials { names } => {
                let missing: Vec<&String> = names.iter().filter(|n| !self.used_materials.contains(*n)).collect();
                if !missing.is_empty() {
                    let used: Vec<&String> = self.used_materials.iter().collect();
                    self.warn(format!(
                        "fur mask names material(s) {missing:?} that no imported primitive uses (used: {used:?})"
                    ));
                }
            }
            _ => {}
        }
        Ok(())
    }

    fn scene_error(&self, node: usize, message: String) -> ImportError {
        ImportError::Scene { file: self.file.to_path_buf(), node, message }
    }

    fn visit(&mut self, index: usize, parent: DMat4, depth: usize) -> Result<(), ImportError> {
        let asset = self.asset;
        let node = asset
            .root
            .nodes
            .get(index)
            .ok_or_else(|| self.scene_error(index, "the node does not exist".to_string()))?;
        if self.on_path[index] {
            return Err(self.scene_error(index, "the node hierarchy has a cycle through this node".to_string()));
        }
        if depth >= MAX_NODE_DEPTH {
            return Err(self.scene_error(index, format!("the node hierarchy is deeper than {MAX_NODE_DEPTH}")));
        }
        self.visits += 1;
        if self.visits > MAX_NODE_VISITS {
            return Err(ImportError::TooLarge {
                file: self.file.to_path_buf(),
                what: "the number of node instances in the scene".to_string(),
                count: self.visits,
                limit: MAX_NODE_VISITS,
            });
        }
        let world = parent * local_transform(node);
        if !world.is_finite() {
            return Err(self.scene_error(index, "the node's world transform is not finite".to_string()));
        }
        let mesh = node.mesh.filter(|_| {
            let exported = is_exported_fur(node);
            self.exported_fur_nodes += usize::from(exported);
            !exported
        });
        if let Some(mesh) = mesh {
            // glTF 2.0 "Skins": a skinned mesh ignores its node's transform; the joints carry it.
            let (binding, mesh_world) = match node.skin {
                Some(skin) => {
                    let binds = self.rig.skin_binds(asset, self.file, skin.value())?;
                    (Binding::Skin { skin: skin.value(), binds }, DMat4::IDENTITY)
                }
                None if self.rig.binding => (Binding::Rigid(self.rig.rigid_bind(self.file, index, world)?), world),
                None => (Binding::None, world),
            };
            let morph = self.rig.morph_group(asset, self.file, index, mesh.value())?;
            self.import_mesh(mesh.value(), mesh_world, &binding, morph)?;
        }
        self.on_path[index] = true;
        for child in node.children.iter().flatten() {
            self.visit(child.value(), world, depth + 1)?;
        }
        self.on_path[index] = false;
        Ok(())
    }

    fn import_mesh(
        &mut self,
        mesh_index: usize,
        world: DMat4,
        binding: &Binding,
        morph: Option<(u32, usize)>,
    ) -> Result<(), ImportError> {
        let asset = self.asset;
        let mesh = asset.root.meshes.get(mesh_index).ok_or_else(|| ImportError::InvalidGltf {
            file: self.file.to_path_buf(),
            message: format!("mesh {mesh_index} does not exist"),
        })?;
        // Instancing multiplies vertices without bytes to back them: a 2 KB file whose nodes
        // branch into 2^19 paths to one mesh made millions of vertices (8 s, 1.2 GB). Repeated
        // instances may add at most MAX_INSTANCED_VERTICES (declared POSITION counts).
        if self.mesh_seen[mesh_index] {
            let declared: u64 = mesh
                .primitives
                .iter()
                .filter_map(|p| p.attributes.iter().find(|(s, _)| matches!(s, Checked::Valid(Semantic::Positions))))
                .filter_map(|(_, acc)| asset.root.accessors.get(acc.value()).map(|a| a.count.0))
                .sum();
            self.instanced_vertices = self.instanced_vertices.saturating_add(declared);
            if self.instanced_vertices > MAX_INSTANCED_VERTICES {
                return Err(ImportError::TooLarge {
                    file: self.file.to_path_buf(),
                    what: "the number of vertices added by repeated mesh instances".to_string(),
                    count: self.instanced_vertices,
                    limit: MAX_INSTANCED_VERTICES,
                });
            }
        }
        self.mesh_seen[mesh_index] = true;
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let at = PrimitiveRef { mesh: mesh_index, mesh_name: mesh.name.as_deref().map(Box::from), primitive: p };
            self.import_primitive(primitive, &at, world, binding, morph)?;
        }
        Ok(())
    }

    fn non_finite(&self, at: &PrimitiveRef, attribute: &str, vertex: usize, value: &[f64]) -> ImportError {
        ImportError::NonFinite {
            file: self.file.to_path_buf(),
            at: at.clone(),
            attribute: attribute.to_string(),
            vertex,
            value: value.iter().map(|&v| v as f32).collect(),
        }
    }

    fn out_of_range(&self, at: &PrimitiveRef, attribute: &str, vertex: usize, value: &[f64]) -> ImportError {
        ImportError::OutOfRange {
            file: self.file.to_path_buf(),
            at: at.clone(),
            attribute: attribute.to_string(),
            vertex,
            value: value.iter().map(|&v| v as f32).collect(),
            limit: MAX_COORDINATE_M,
        }
    }

    /// Reads an optional attribute, checking its count and that every value is finite.
    fn read_optional(
        &self,
        reader: &AccessorReader<'_>,
        primitive: &json::mesh::Primitive,
        name: &str,
        types: &[Type],
        vertex_count: usize,
    ) -> Result<Option<Elements>, ImportError> {
        let Some((_, &acc)) = primitive.attributes.iter().find(|(s, _)| match s {
            Checked::Valid(s) => semantic_name(s) == name,
            Checked::Invalid => false,
        }) else {
            return Ok(None);
        };
        let e = reader.read(name, acc.value(), types)?;
        if e.count() != vertex_count {
            return Err(ImportError::Accessor {
                file: self.file.to_path_buf(),
                at: reader.at.clone(),
                attribute: name.to_string(),
                accessor: acc.value(),
                message: format!("{} elements, but POSITION has {vertex_count}", e.count()),
            });
        }
        if name != "NORMAL" {
            // Normals are allowed to be unusable (they are regenerated); other attributes are not.
            if let Some(v) = (0..vertex_count).find(|&v| e.get(v).iter().any(|x| !x.is_finite())) {
                return Err(self.non_finite(reader.at, name, v, e.get(v)));
            }
        }
        Ok(Some(e))
    }

    /// Imports one primitive into the soup: one stage per part, in the order the checks must
    /// run (the first problem found is the error reported).
    fn import_primitive(
        &mut self,
        primitive: &json::mesh::Primitive,
        at: &PrimitiveRef,
        world: DMat4,
        binding: &Binding,
        morph: Option<(u32, usize)>,
    ) -> Result<(), ImportError> {
        let Some(mode) = self.triangle_mode(primitive, at)? else { return Ok(()) };
        let (asset, file) = (self.asset, self.file);
        let reader = AccessorReader { root: &asset.root, buffers: &asset.buffers, file, at };
        let transform = NodeTransform::of(world);
        let attributes = self.read_attributes(&reader, primitive)?;
        let (referenced, triangles) = self.read_triangles(&reader, primitive, mode, attributes.n, &transform)?;
        let material = self.read_material(&reader, primitive, attributes.n)?;
        self.add_rig_data(&reader, primitive, &referenced, binding, morph, &transform)?;
        let base = self.add_vertices(at, &attributes, &material, &transform)?;
        let fur = self.fur_mask(at, &attributes, material.name.as_ref(), &triangles);
        self.add_triangles(base, &triangles, fur);
        Ok(())
    }

    /// The primitive's mode when it has triangles; a point or line primitive is counted, warned
    /// about and skipped (`None`).
    fn triangle_mode(
        &mut self,
        primitive: &json::mesh::Primitive,
        at: &PrimitiveRef,
    ) -> Result<Option<Mode>, ImportError> {
        let mode = match primitive.mode {
            Checked::Valid(m) => m,
            Checked::Invalid => {
                return Err(ImportError::InvalidGltf {
                    file: self.file.to_path_buf(),
                    message: format!("{at}: invalid primitive mode"),
                });
            }
        };
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.soup.skipped_primitives += 1;
            self.warn(format!("{at}: skipped, mode {} has no triangles", mode_name(mode)));
            return Ok(None);
        }
        Ok(Some(mode))
    }

    /// Reads and checks the vertex attributes: `POSITION` (finite, within the scene's vertex
    /// limit), `NORMAL`, `COLOR_0`, `TEXCOORD_0` and the fur-mask attribute when the mask is one.
    fn read_attributes(
        &self,
        reader: &AccessorReader<'_>,
        primitive: &json::mesh::Primitive,
    ) -> Result<PrimitiveAttributes, ImportError> {
        let (file, at) = (self.file, reader.at);
        let Some(pos_acc) = primitive.attributes.get(&Checked::Valid(Semantic::Positions)) else {
            return Err(ImportError::MissingPosition { file: file.to_path_buf(), at: at.clone() });
        };
        let positions = reader.read("POSITION", pos_acc.value(), &[Type::Vec3])?;
        let n = positions.count();
        if let Some(v) = (0..n).find(|&v| positions.get(v).iter().any(|x| !x.is_finite())) {
            return Err(self.non_finite(at, "POSITION", v, positions.get(v)));
        }
        let total = self.soup.positions.len() as u64 + n as u64;
        if total > MAX_RAW_VERTICES {
            return Err(ImportError::TooLarge {
                file: file.to_path_buf(),
                what: "the number of vertices in the scene (before welding)".to_string(),
                count: total,
                limit: MAX_RAW_VERTICES,
            });
        }
        let normals = self.read_optional(reader, primitive, "NORMAL", &[Type::Vec3], n)?;
        let colors = self.read_optional(reader, primitive, "COLOR_0", &[Type::Vec3, Type::Vec4], n)?;
        let uvs = self.read_optional(reader, primitive, "TEXCOORD_0", &[Type::Vec2], n)?;
        let mask = match self.mask {
            FurMaskSource::Attribute { name, .. } => {
                let full = if name.starts_with('_') { name.clone() } else { format!("_{name}") };
                match self.read_optional(reader, primitive, &full, &[Type::Scalar], n)? {
                    Some(e) => Some(e),
                    None => self.read_optional(reader, primitive, name, &[Type::Scalar], n)?,
                }
            }
            _ => None,
        };
        Ok(PrimitiveAttributes { n, positions, normals, colors, uvs, mask })
    }

    /// Reads the indices (checked against the `n` vertices; all vertices in order without an
    /// index accessor) and triangulates them for `mode` within the scene's triangle limit, wound
    /// for `transform`. Returns which vertices the indices reference, and the triangles
    /// (primitive-local vertex indices).
    fn read_triangles(
        &mut self,
        reader: &AccessorReader<'_>,
        primitive: &json::mesh::Primitive,
        mode: Mode,
        n: usize,
        transform: &NodeTransform,
    ) -> Result<(Vec<bool>, Vec<[u32; 3]>), ImportError> {
        let (file, at) = (self.file, reader.at);
        let indices: Vec<u32> = match primitive.indices {
            Some(acc) => {
                let idx = reader.read_indices(acc.value())?;
                if let Some(position) = idx.iter().position(|&i| i as usize >= n) {
                    return Err(ImportError::IndexOutOfRange {
                        file: file.to_path_buf(),
                        at: at.clone(),
                        position,
                        index: idx[position],
                        vertex_count: n,
                    });
                }
                idx
            }
            None => (0..n as u32).collect(),
        };
        if indices.len() < 3 {
            return Err(ImportError::PrimitiveWithoutTriangles {
                file: file.to_path_buf(),
                at: at.clone(),
                elements: indices.len(),
            });
        }
        if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
            self.warn(format!(
                "{at}: {} indices is not a multiple of 3; the last {} ignored",
                indices.len(),
                indices.len() % 3
            ));
        }
        let mut local = triangulate(mode, &indices);
        let total = self.soup.triangles.len() as u64 + local.len() as u64;
        if total > MAX_RAW_TRIANGLES {
            return Err(ImportError::TooLarge {
                file: file.to_path_buf(),
                what: "the number of triangles in the scene".to_string(),
                count: total,
                limit: MAX_RAW_TRIANGLES,
            });
        }
        if transform.mirrors {
            for t in &mut local {
                t.swap(1, 2);
            }
        }
        let mut referenced = vec![false; n];
        for &i in &indices {
            referenced[i as usize] = true;
        }
        Ok((referenced, local))
    }

    /// Reads the material's base colour factor and name, and its base colour texture with the
    /// `TEXCOORD` set it is sampled at (thesis §3.2: the fur takes the skin's colour), decoding
    /// the image on first use; records the material's name as used.
    fn read_material(
        &mut self,
        reader: &AccessorReader<'_>,
        primitive: &json::mesh::Primitive,
        n: usize,
    ) -> Result<PrimitiveMaterial, ImportError> {
        let (asset, file) = (self.asset, self.file);
        let material = primitive.material.and_then(|m| asset.root.materials.get(m.value()));
        let factor = material.map_or([1.0; 4], |m| m.pbr_metallic_roughness.base_color_factor.0);
        let name = material.and_then(|m| m.name.clone());
        let texture_info = material.and_then(|m| m.pbr_metallic_roughness.base_color_texture.as_ref());
        let texture_uvs = match texture_info {
            Some(info) if self.sample_textures => {
                let name = format!("TEXCOORD_{}", info.tex_coord);
                self.read_optional(reader, primitive, &name, &[Type::Vec2], n)?
            }
            _ => None,
        };
        let texture = match (texture_info, &texture_uvs) {
            (Some(info), Some(_)) => {
                let index = info.index.value();
                self.textures.get(asset, file, self.external, index, &mut self.warnings)?.map(|_| index)
            }
            _ => None,
        };
        if let Some(name) = &name {
            self.used_materials.insert(name.clone());
        }
        Ok(PrimitiveMaterial { factor, name, texture_uvs, texture })
    }

    /// Adds the skin influences and morph deltas of the primitive's raw vertices to the soup
    /// (glTF 2.0 "Skins", "Morph Targets"; the skin's weights are checked on the `referenced`
    /// vertices only).
    fn add_rig_data(
        &mut self,
        reader: &AccessorReader<'_>,
        primitive: &json::mesh::Primitive,
        referenced: &[bool],
        binding: &Binding,
        morph: Option<(u32, usize)>,
        transform: &NodeTransform,
    ) -> Result<(), ImportError> {
        let file = self.file;
        let n = referenced.len();
        match binding {
            Binding::None => {}
            Binding::Skin { skin, binds } => {
                let inf = self.rig.read_influences(reader, primitive, n, binds, referenced, *skin)?;
                self.soup.influences.extend(inf);
            }
            Binding::Rigid(b) => {
                let mut one: Influences = [(0, 0.0); MAX_INFLUENCES];
                one[0] = (*b, 1.0);
                self.soup.influences.extend(std::iter::repeat_n(one, n));
                self.rig.stats.rigid_vertices += n as u32;
            }
        }
        match morph {
            Some((group, t)) => {
                let deltas =
                    Rig::read_morph_deltas(reader, primitive, n, t, transform.linear, transform.normal_matrix)?;
                let start = self.soup.morph_deltas.len();
                if start + deltas.len() > u32::MAX as usize {
                    return Err(ImportError::TooLarge {
                        file: file.to_path_buf(),
                        what: "the morph deltas before welding".to_string(),
                        count: (start + deltas.len()) as u64,
                        limit: u64::from(u32::MAX),
                    });
                }
                self.soup.morph_deltas.extend(deltas);
                if self.soup.morph_group_len.len() <= group as usize {
                    self.soup.morph_group_len.resize(group as usize + 1, 0);
                }
                self.soup.morph_group_len[group as usize] = 2 * t;
                for v in 0..n {
                    self.soup.morph_group.push(group);
                    self.soup.morph_at.push((start + v * 2 * t) as u32);
                }
            }
            None => {
                self.soup.morph_group.extend(std::iter::repeat_n(NO_GROUP, n));
                self.soup.morph_at.extend(std::iter::repeat_n(0, n));
            }
        }
        Ok(())
    }

    /// Adds the primitive's vertices to the soup: positions and normals moved by `transform`
    /// (checked finite in f32 and within the coordinate limit), colours `COLOR_0 ×
    /// baseColorFactor × texture` clamped to [0, 1], texture coordinates; warns about replaced
    /// normals and clamped colours. Returns the soup index of the primitive's first vertex.
    fn add_vertices(
        &mut self,
        at: &PrimitiveRef,
        attributes: &PrimitiveAttributes,
        material: &PrimitiveMaterial,
        transform: &NodeTransform,
    ) -> Result<u32, ImportError> {
        let PrimitiveAttributes { n, positions, normals, colors, uvs, .. } = attributes;
        let (n, world, normal_matrix, factor) = (*n, transform.world, transform.normal_matrix, material.factor);
        let texture = material.texture.and_then(|t| self.textures.decoded(self.asset, t));
        let texture_uvs = &material.texture_uvs;
        let base = self.soup.positions.len() as u32;
        let mut bad_normals = 0usize;
        let mut clamped_colors = 0usize;
        for v in 0..n {
            let p = positions.get(v);
            let wp = world.transform_point3(DVec3::new(p[0], p[1], p[2]));
            // Finite in f64 is not enough: the skin stores f32.
            if !wp.as_vec3().is_finite() {
                return Err(self.non_finite(at, "POSITION (after node transform)", v, &wp.to_array()));
            }
            if wp.abs().max_element() > MAX_COORDINATE_M as f64 {
                return Err(self.out_of_range(at, "POSITION (after node transform)", v, &wp.to_array()));
            }
            self.soup.positions.push(wp);
            let normal = normals.as_ref().and_then(|e| {
                let q = e.get(v);
                let wn = (normal_matrix * DVec3::new(q[0], q[1], q[2])).normalize_or_zero();
                if wn == DVec3::ZERO || !wn.is_finite() {
                    bad_normals += 1;
                    None
                } else {
                    Some(wn)
                }
            });
            self.soup.normals.push(normal);
            let rgba = colors.as_ref().map_or([1.0; 4], |e| {
                let c = e.get(v);
                [c[0] as f32, c[1] as f32, c[2] as f32, if c.len() > 3 { c[3] as f32 } else { 1.0 }]
            });
            let texel = match (texture, texture_uvs) {
                (Some(img), Some(uv)) => img.sample([uv.get(v)[0] as f32, uv.get(v)[1] as f32]),
                _ => [1.0; 4],
            };
            let color = [0, 1, 2, 3].map(|k| rgba[k] * factor[k] * texel[k]);
            if !color.iter().all(|c| c.is_finite()) {
                let value = color.map(f64::from);
                return Err(self.non_finite(at, "COLOR_0 × baseColorFactor", v, &value));
            }
            // glTF colours and factors are normalised to [0, 1]; a file outside that range is
            // repaired (clamped) and reported, so the pack holds what the format documents.
            if color.iter().any(|c| !(0.0..=1.0).contains(c)) {
                clamped_colors += 1;
            }
            self.soup.colors.push(color.map(|c| c.clamp(0.0, 1.0)));
            let uv = uvs.as_ref().map_or([0.0; 2], |e| [e.get(v)[0] as f32, e.get(v)[1] as f32]);
            // The pack stores texture coordinates within the coordinate limit too.
            if uv.iter().any(|c| c.abs() > MAX_COORDINATE_M) {
                return Err(self.out_of_range(at, "TEXCOORD_0", v, &uv.map(f64::from)));
            }
            self.soup.texcoords.push(uv);
        }
        if normals.is_none() || bad_normals > 0 {
            self.soup.missing_normals = true;
        }
        if bad_normals > 0 {
            self.warn(format!("{at}: {bad_normals} zero or non-finite normals replaced by generated ones"));
        }
        if clamped_colors > 0 {
            self.warn(format!("{at}: {clamped_colors} vertex colours outside [0, 1] clamped"));
        }
        self.soup.had_vertex_colors |= colors.is_some();
        self.soup.all_have_texcoords &= uvs.is_some();
        Ok(base)
    }

    /// The fur mask of each triangle (1 furry, 0 bare) from the mask source: the mean of its
    /// corners' raw values against the threshold, or its material's name.
    fn fur_mask(
        &mut self,
        at: &PrimitiveRef,
        attributes: &PrimitiveAttributes,
        material_name: Option<&String>,
        local: &[[u32; 3]],
    ) -> Vec<u8> {
        let mean = |t: &[u32; 3], f: &dyn Fn(usize) -> f64| t.iter().map(|&i| f(i as usize)).sum::<f64>() / 3.0;
        match self.mask {
            FurMaskSource::All => vec![1; local.len()],
            FurMaskSource::VertexColor { channel, threshold } => {
                let ch = channel.index();
                match &attributes.colors {
                    Some(e) => {
                        self.mask_source_found = true;
                        let value = |v: usize| e.get(v).get(ch).copied().unwrap_or(1.0);
                        local.iter().map(|t| u8::from(mean(t, &value) >= f64::from(*threshold))).collect()
                    }
                    None => {
                        self.note_mask_fallback(at, "has no COLOR_0; counted as white");
                        vec![u8::from(*threshold <= 1.0); local.len()]
                    }
                }
            }
            FurMaskSource::Attribute { name, threshold } => match &attributes.mask {
                Some(e) => {
                    self.mask_source_found = true;
                    let value = |v: usize| e.get(v)[0];
                    local.iter().map(|t| u8::from(mean(t, &value) >= f64::from(*threshold))).collect()
                }
                None => {
                    self.note_mask_fallback(at, &format!("has no attribute {name}; its triangles are bare"));
                    vec![0; local.len()]
                }
            },
            FurMaskSource::Materials { names } => {
                let furry = material_name.is_some_and(|m| names.contains(m));
                vec![u8::from(furry); local.len()]
            }
        }
    }

    /// Adds the primitive's triangles (local indices offset by `base`) and their fur mask to the
    /// soup, and counts the primitive.
    fn add_triangles(&mut self, base: u32, local: &[[u32; 3]], fur: Vec<u8>) {
        self.soup.triangles.extend(local.iter().map(|t| [t[0] + base, t[1] + base, t[2] + base]));
        self.soup.fur.extend(fur);
        self.soup.primitives += 1;
    }

    fn note_mask_fallback(&mut self, at: &PrimitiveRef, what: &str) {
        self.mask_warnings += 1;
        if self.mask_warnings <= 8 {
            self.warn(format!("{at}: fur mask: the primitive {what}"));
        }
    }
}

/// Whether `furbake export` wrote this node as fur (its `extras.furbake` is `"shell"` or
/// `"fins"`): baking an exported file again grows fur on its skin, not on its old fur.
fn is_exported_fur(node: &gltf::json::Node) -> bool {
    let Some(raw) = &node.extras else { return false };
    match serde_json::from_str::<serde_json::Value>(raw.get()) {
        Ok(v) => matches!(v.get("furbake").and_then(|r| r.as_str()), Some("shell" | "fins")),
        Err(_) => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_keep_a_consistent_winding() {
        let strip = triangulate(Mode::TriangleStrip, &[0, 1, 2, 3, 4]);
        assert_eq!(strip, vec![[0, 1, 2], [2, 1, 3], [2, 3, 4]]);
        let fan = triangulate(Mode::TriangleFan, &[0, 1, 2, 3]);
        assert_eq!(fan, vec![[1, 2, 0], [2, 3, 0]]);
        let tris = triangulate(Mode::Triangles, &[0, 1, 2, 3, 4]);
        assert_eq!(tris, vec![[0, 1, 2]]);
        assert!(triangulate(Mode::Lines, &[0, 1, 2]).is_empty());
    }

    #[test]
    fn cofactor_normal_matrix_matches_inverse_transpose() {
        let m = DMat4::from_scale_rotation_translation(
            DVec3::new(2.0, -0.5, 3.0),
            DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
            DVec3::new(1.0, 2.0, 3.0),
        );
        let m3 = DMat3::from_mat4(m);
        let det = m3.determinant();
        let cof = DMat3::from_cols(m3.y_axis.cross(m3.z_axis), m3.z_axis.cross(m3.x_axis), m3.x_axis.cross(m3.y_axis))
            * det.signum();
        let it = m3.inverse().transpose();
        let mut checked = 0;
        for n in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(1.0, -2.0, 0.5)] {
            let a = (cof * n).normalize();
            let b = (it * n).normalize();
            assert!((a - b).length() < 1e-12, "{a} vs {b}");
            checked += 1;
        }
        assert_eq!(checked, 4);
    }
}
