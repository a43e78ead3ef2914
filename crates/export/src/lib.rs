//! furbake-export: turns a decoded furbake pack into a self-contained binary glTF 2.0 (`.glb`)
//! byte vector — nothing else (no file I/O, no command line: `furbake export` writes the bytes).
//!
//! What the file holds, in node (and, where a viewer honours it, draw) order:
//! 1. `skin` — the pack's skin mesh, opaque: positions, normals, the vertex colours as `COLOR_0`
//!    (the pack's colours already include the input's base colour factor and texture) and the
//!    input's per-corner `TEXCOORD_0` when the pack kept them; vertices are unwelded per corner
//!    only where those UVs differ;
//! 2. `shell NN` — one mesh (one primitive) per drawn shell layer, innermost first, over the
//!    furry triangles: the skin's vertices moved along their rest normal by
//!    `t·fur_length`, `t = (layer + 1)/layers` — eq. 3.36 at rest (`s = n`, no shear), exactly
//!    the renderer's `shell_vertex` (crates/render/shaders/shell.wgsl) — with the per-triangle UV map
//!    (`triangle_uv_map`, texture repeats) as `TEXCOORD_0`, the layer's shell-atlas slice as a PNG
//!    whose alpha is the slice (`ShellAtlas::slice_for`, as the renderer picks it), and the
//!    layer's self-shadow factor as the material's base colour factor. The layers share every
//!    accessor but `POSITION`;
//! 3. `fins` — one quad per fin edge standing on the edge, its top edge moved along the rest
//!    normals by the fur length (crates/render/shaders/fin.wgsl at rest), `u` = metres along the edge / the UV
//!    map's repeat, `v` = 0 at the tip and 1 at the root, textured with the fin atlas (the
//!    self-shadow ramp baked into its colour, the atlas in its alpha);
//! 4. when the pack has a skeleton and skin weights: the joints as nodes (rest TRS), one glTF
//!    skin (one joint per bind, exactly affine inverse bind matrices), `JOINTS_n`/`WEIGHTS_n` on
//!    the skin (a bind repeated within a vertex merged into one influence), every
//!    shell layer and the fins (a fin corner takes its edge vertex's influences), and every clip
//!    as an animation with its samplers' interpolation as stored, so the shells and fins follow
//!    the character in any viewer.
//!
//! Shells and fins are `BLEND` (or `MASK`, [`ShellAlpha::Mask`], for viewers that sort
//! transparent meshes badly) and double-sided (the renderer culls neither); every material is
//! dielectric and fully rough (metallic 0, roughness 1), the nearest PBR material to the
//! renderer's Lambert shading. glTF has no draw-order guarantee: the shells are emitted inner to
//! outer (node, mesh and material order, and `extras.layer` on each node and material), which
//! viewers that draw transparent meshes of equal depth in file order (three.js, Babylon.js) honour;
//! others may sort them differently. Shell and fin nodes carry `extras.furbake` (`"shell"`,
//! `"fins"`): furbake's importer skips them, so baking an exported file again grows fur on its
//! skin only.
//!
//! Not exported: the view-dependent fin fade (fins fade as the surface faces the viewer; glTF
//! materials cannot), morph targets (the pack merges every mesh's targets into one skin; see
//! [`Export::notes`]), spring topologies, grass blades and keyframes (physics data, no glTF
//! meaning), and the manifest (summarised in `asset.extras.furbake`).
//!
//! Everything is deterministic: the same pack and options give the same bytes.
//!
//! ```
//! use furbake_bake::{BakeSettings, NoProgress, bake};
//! use furbake_export::{ExportOptions, export_glb};
//! use furbake_formats::Pack;
//! use furbake_import::{import_gltf_slice, testmesh};
//!
//! // A small furry sphere, baked into a pack in memory.
//! let mesh = import_gltf_slice(&testmesh::uv_sphere(6, 8, 0.5).gltf, "ball.gltf", None, &Default::default())?;
//! let mut settings = BakeSettings::preset("fur")?;
//! (settings.volume.resolution, settings.volume.layers) = (16, 4);
//! let pack = Pack::from_bytes(&bake(&mesh, "ball.gltf", &settings.plan()?, &mut NoProgress)?.to_writer().to_bytes())?;
//!
//! let glb = export_glb(&pack, &ExportOptions::default())?;
//! assert_eq!(&glb[..4], b"glTF"); // a binary glTF 2.0 container
//! assert_eq!(u32::from_le_bytes(glb[4..8].try_into()?), 2);
//! assert_eq!(glb, export_glb(&pack, &ExportOptions::default())?, "deterministic");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![deny(missing_docs)]
mod glb;

use std::collections::HashMap;

use furbake_formats::sections::animation_clips::{AnimationClips, ChannelTarget, Interpolation};
use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::fin_edges::FinEdges;
use furbake_formats::sections::shell_atlas::ShellAtlas;
use furbake_formats::sections::skeleton::Skeleton;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::SkinWeights;
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use furbake_formats::{FormatError, Pack, PackSections, SectionKind};
use serde_json::{Value, json};

use crate::glb::Builder;

/// How shells and fins are blended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShellAlpha {
    /// `alphaMode: BLEND` — what the renderer does by default; needs the viewer to draw the
    /// layers inner to outer.
    Blend,
    /// `alphaMode: MASK` with this `alphaCutoff` in `[0, 1]` — the renderer's alpha-tested mode:
    /// order-independent, harder edges.
    Mask {
        /// Fragments with alpha below this are discarded.
        cutoff: f32,
    },
}

/// What to export.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// Shell layers to emit, `0..=atlas layers`; `None` = one per atlas slice. Fewer layers
    /// sample the atlas as the renderer does with fewer drawn layers; `Some(0)` exports the
    /// skin (and fins, when asked) alone.
    pub layers: Option<u32>,
    /// Emit the fins (when the pack has a fin atlas and fin edges). Default true.
    pub fins: bool,
    /// Emit the skeleton, skin and clips when the pack has them. Default true; false exports the
    /// rest pose as static meshes.
    pub animation: bool,
    /// Blend mode of shells and fins. Default [`ShellAlpha::Blend`].
    pub alpha: ShellAlpha,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions { layers: None, fins: true, animation: true, alpha: ShellAlpha::Blend }
    }
}

/// Why a pack cannot be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A section the export needs is missing or unreadable. Blame: the pack.
    #[error("cannot read the pack's {kind} section: {source}")]
    Section {
        /// The section kind.
        kind: SectionKind,
        /// What the reader said.
        #[source]
        source: FormatError,
    },
    /// The sections do not belong together. Blame: the pack.
    #[error("the pack's sections disagree: {0}")]
    Inconsistent(#[source] FormatError),
    /// An option is out of range. Blame: the caller.
    #[error("export option {option}: {what}")]
    Option {
        /// The option's name.
        option: &'static str,
        /// What is wrong.
        what: String,
    },
    /// The result would exceed a glTF/GLB limit (4 GiB binary chunk, 32-bit counts). Blame: the
    /// pack's size.
    #[error("the export is too large for a GLB: {0}")]
    TooLarge(String),
    /// A texture could not be encoded as PNG. Blame: the export (should not happen).
    #[error("cannot encode {what} as PNG: {source}")]
    Png {
        /// Which texture.
        what: String,
        /// The encoder's error.
        #[source]
        source: image::ImageError,
    },
}

/// The exported file and what was left out.
#[derive(Clone, Debug, PartialEq)]
pub struct Export {
    /// The `.glb` bytes.
    pub glb: Vec<u8>,
    /// What the pack has that the file does not carry (one sentence each), for the caller to
    /// print as warnings.
    pub notes: Vec<String>,
}

/// Exports `pack` as a binary glTF 2.0 file (see the crate doc for its contents).
pub fn export_glb(pack: &Pack, options: &ExportOptions) -> Result<Vec<u8>, ExportError> {
    export(pack, options).map(|e| e.glb)
}

/// [`export_glb`] with the notes on what was left out.
pub fn export(pack: &Pack, options: &ExportOptions) -> Result<Export, ExportError> {
    fn need<T>(kind: SectionKind, r: furbake_formats::Result<T>) -> Result<T, ExportError> {
        r.map_err(|source| ExportError::Section { kind, source })
    }
    let mesh = need(SectionKind::SKIN_MESH, pack.skin_mesh())?;
    let shells = need(SectionKind::SHELL_ATLAS, pack.shell_atlas())?;
    let uv_map = need(SectionKind::TRIANGLE_UV_MAP, pack.triangle_uv_map())?;
    let fins = if options.fins && pack.has(SectionKind::FIN_ATLAS) && pack.has(SectionKind::FIN_EDGES) {
        Some((need(SectionKind::FIN_ATLAS, pack.fin_atlas())?, need(SectionKind::FIN_EDGES, pack.fin_edges())?))
    } else {
        None
    };
    let skeleton = need(SectionKind::SKELETON, pack.skeleton())?;
    let weights = need(SectionKind::SKIN_WEIGHTS, pack.skin_weights())?;
    let clips = need(SectionKind::ANIMATION_CLIPS, pack.animation_clips())?;
    let morphs = need(SectionKind::MORPH_TARGETS, pack.morph_targets())?;
    let sections = PackSections {
        mesh: Some(&mesh),
        shells: Some(&shells),
        uv_map: Some(&uv_map),
        fins: fins.as_ref().map(|(a, _)| &**a),
        fin_edges: fins.as_ref().map(|(_, e)| &**e),
        skeleton: skeleton.as_deref(),
        skin_weights: weights.as_deref(),
        morph_targets: morphs.as_deref(),
        clips: clips.as_deref(),
        ..Default::default()
    };
    furbake_formats::check_consistency(pack.sections(), &sections).map_err(ExportError::Inconsistent)?;
    let mut notes = Vec::new();
    let rig = match (options.animation, skeleton.as_deref(), weights.as_deref()) {
        (true, Some(sk), Some(w)) => Some((sk, w)),
        _ => None,
    };
    if morphs.is_some() {
        notes.push("the pack's morph targets are not exported (the shells and fins would need every target moved per layer); the export shows the unmorphed rest shape".into());
    }
    if !options.animation && skeleton.is_some() {
        notes.push("animation not exported (option): the skeleton and clips are left out".into());
    }
    let input = Input {
        mesh: &mesh,
        shells: &shells,
        uv_map: &uv_map,
        fins: fins.as_ref().map(|(a, e)| (&**a, &**e)),
        rig,
        clips: if rig.is_some() { clips.as_deref() } else { None },
        manifest: pack.manifest().ok().map(|m| (m.input_name.clone(), m.preset.clone(), m.seed)),
    };
    let glb = build(&input, options, &mut notes)?;
    Ok(Export { glb, notes })
}

/// The decoded, cross-checked sections the export reads.
struct Input<'a> {
    mesh: &'a SkinMesh,
    shells: &'a ShellAtlas,
    uv_map: &'a TriangleUvMap,
    fins: Option<(&'a FinAtlas, &'a FinEdges)>,
    rig: Option<(&'a Skeleton, &'a SkinWeights)>,
    clips: Option<&'a AnimationClips>,
    manifest: Option<(String, String, u64)>,
}

/// Indices of the glTF objects every mesh primitive refers to.
struct Shared {
    /// `(JOINTS_n, WEIGHTS_n)` source per welded vertex: bind indices and weights.
    influences: Option<(usize, Vec<u16>, Vec<f32>)>,
    /// Skin index when skinned.
    skin: Option<usize>,
    /// The skeleton's bind count (0 without a rig): the bound on the `JOINTS_n` values.
    bind_count: usize,
}

fn f(x: f32) -> Value {
    json!(x)
}

fn material(name: &str, factor: [f32; 4], texture: Option<usize>, alpha: Option<ShellAlpha>, double: bool) -> Value {
    let mut pbr = json!({
        "baseColorFactor": factor.map(f),
        "metallicFactor": 0.0,
        "roughnessFactor": 1.0,
    });
    if let Some(t) = texture {
        pbr["baseColorTexture"] = json!({ "index": t });
    }
    let mut m = json!({ "name": name, "pbrMetallicRoughness": pbr });
    match alpha {
        None => {}
        Some(ShellAlpha::Blend) => m["alphaMode"] = json!("BLEND"),
        Some(ShellAlpha::Mask { cutoff }) => {
            m["alphaMode"] = json!("MASK");
            m["alphaCutoff"] = f(cutoff);
        }
    }
    if double {
        m["doubleSided"] = json!(true);
    }
    m
}

/// sRGB transfer of a linear value in `[0, 1]`, as an 8-bit code (PNG colour is sRGB in glTF).
fn srgb8(linear: f32) -> u8 {
    let x = linear.clamp(0.0, 1.0);
    let s = if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// PNG of a `width × height` luminance + alpha image.
fn png_la(what: String, width: u32, height: u32, la: Vec<u8>) -> Result<Vec<u8>, ExportError> {
    let img = image::GrayAlphaImage::from_raw(width, height, la)
        .ok_or_else(|| ExportError::TooLarge(format!("{what}: {width}×{height} texels do not match its data")))?;
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).map_err(|source| ExportError::Png { what, source })?;
    Ok(out.into_inner())
}

/// Builds the file from the checked sections: one stage per part of the glTF document, in the
/// order their data is written into the binary chunk (buffer views and accessors are numbered in
/// that order, so the order is part of the file's bytes).
fn build(input: &Input<'_>, options: &ExportOptions, notes: &mut Vec<String>) -> Result<Vec<u8>, ExportError> {
    let layers = check_options(input, options)?;
    let shared = skinning_palette(input.rig);
    let mut doc = Document::default();
    add_skin(&mut doc, input.mesh, &shared);
    add_shells(&mut doc, input, &shared, layers, options.alpha, notes)?;
    let fins_exported = add_fins(&mut doc, input, &shared, options.alpha, notes)?;
    if let Some((skeleton, _)) = input.rig {
        let joint_base = add_skeleton(&mut doc, skeleton);
        add_clips(&mut doc, input.clips, joint_base, skeleton.joint_count(), notes);
    }
    finish_document(doc, input, layers, fins_exported)
}

/// The glTF document as the stages of [`build`] fill it: the binary chunk with its buffer views
/// and accessors, and the top-level arrays whose indices the stages refer to.
#[derive(Default)]
struct Document {
    b: Builder,
    nodes: Vec<Value>,
    meshes: Vec<Value>,
    materials: Vec<Value>,
    textures: Vec<Value>,
    images: Vec<Value>,
    /// The scene's root nodes.
    scene_nodes: Vec<usize>,
    skins: Vec<Value>,
    animations: Vec<Value>,
}

/// Checks the options and the mesh's size against the pack; returns the shell layers to export.
fn check_options(input: &Input<'_>, options: &ExportOptions) -> Result<u32, ExportError> {
    let m = input.mesh;
    let atlas_layers = input.shells.layers() as u32;
    let layers = options.layers.unwrap_or(atlas_layers);
    if layers > atlas_layers {
        return Err(ExportError::Option {
            option: "layers",
            what: format!("{layers} layers asked for; the pack's shell atlas has {atlas_layers}"),
        });
    }
    if let ShellAlpha::Mask { cutoff } = options.alpha
        && !(0.0..=1.0).contains(&cutoff)
    {
        return Err(ExportError::Option { option: "alpha", what: format!("cutoff {cutoff} is outside [0, 1]") });
    }
    if m.positions.len() > u32::MAX as usize / 4 || m.triangles.len() > u32::MAX as usize / 8 {
        return Err(ExportError::TooLarge(format!(
            "{} vertices / {} triangles exceed 32-bit glTF counts",
            m.positions.len(),
            m.triangles.len()
        )));
    }
    Ok(layers)
}

/// The skinning palette every mesh primitive shares, when the pack is rigged.
fn skinning_palette(rig: Option<(&Skeleton, &SkinWeights)>) -> Shared {
    let bind_count = rig.map_or(0, |(sk, _)| sk.bind_count());
    match rig {
        Some((sk, w)) => {
            let k = w.influences_per_vertex as usize;
            let (binds, weights) = gltf_influences(w);
            Shared { influences: Some((k, binds, weights)), skin: Some(0), bind_count }.with_bind_count(sk.bind_count())
        }
        None => Shared { influences: None, skin: None, bind_count },
    }
}

/// Adds the skin: one mesh of the whole surface, unwelded by corner UV, and its scene node.
fn add_skin(doc: &mut Document, m: &SkinMesh, shared: &Shared) {
    if m.triangles.is_empty() {
        return;
    }
    let Document { b, nodes, meshes, materials, scene_nodes, .. } = doc;
    let uvs = (!m.corner_texcoords.is_empty()).then_some(&m.corner_texcoords);
    let (vertex_of, uv, indices) = unweld(&m.triangles, (0..m.triangles.len()).collect(), uvs);
    let mut attributes = serde_json::Map::new();
    let positions: Vec<f32> = vertex_of.iter().flat_map(|&v| m.positions[v as usize]).collect();
    attributes.insert("POSITION".into(), json!(b.floats(&positions, 3, false, true)));
    let normals: Vec<f32> = vertex_of.iter().flat_map(|&v| m.normals[v as usize]).collect();
    attributes.insert("NORMAL".into(), json!(b.floats(&normals, 3, false, false)));
    let colors: Vec<f32> = vertex_of.iter().flat_map(|&v| rgb(m.colors[v as usize])).collect();
    attributes.insert("COLOR_0".into(), json!(b.floats(&colors, 3, false, false)));
    if uvs.is_some() {
        attributes.insert("TEXCOORD_0".into(), json!(b.floats(&uv, 2, false, false)));
    }
    shared.skin_attributes(b, &mut attributes, &vertex_of);
    let ind = b.indices(&indices);
    materials.push(material("skin", [1.0; 4], None, None, false));
    meshes.push(json!({ "name": "skin", "primitives": [{
        "attributes": attributes, "indices": ind, "material": materials.len() - 1, "mode": 4 }] }));
    scene_nodes.push(nodes.len());
    nodes.push(shared.mesh_node("skin", meshes.len() - 1, None));
}

/// Adds the shells: per exported layer one mesh of the furry triangles pushed out along the
/// normals, textured with its atlas slice (one PNG per slice, shared by the layers that use it).
fn add_shells(
    doc: &mut Document,
    input: &Input<'_>,
    shared: &Shared,
    layers: u32,
    alpha: ShellAlpha,
    notes: &mut Vec<String>,
) -> Result<(), ExportError> {
    let m = input.mesh;
    let alpha = Some(alpha);
    let fur_m = input.shells.fur_length_m;
    let Document { b, nodes, meshes, materials, textures, images, scene_nodes, .. } = doc;
    let furry: Vec<usize> = (0..m.triangles.len()).filter(|&t| m.fur_mask[t] != 0).collect();
    if layers > 0 && !furry.is_empty() {
        let (vertex_of, uv, indices) = unweld(&m.triangles, furry, Some(&input.uv_map.corners));
        let normals: Vec<[f32; 3]> = vertex_of.iter().map(|&v| unit(m.normals[v as usize])).collect();
        let mut common = serde_json::Map::new();
        common.insert("NORMAL".into(), json!(b.floats(normals.as_flattened(), 3, false, false)));
        let colors: Vec<f32> = vertex_of.iter().flat_map(|&v| rgb(m.colors[v as usize])).collect();
        common.insert("COLOR_0".into(), json!(b.floats(&colors, 3, false, false)));
        common.insert("TEXCOORD_0".into(), json!(b.floats(&uv, 2, false, false)));
        shared.skin_attributes(b, &mut common, &vertex_of);
        let ind = b.indices(&indices);
        let res = input.shells.params.resolution;
        let mut slice_texture: HashMap<usize, usize> = HashMap::new();
        for layer in 0..layers {
            let t = (layer + 1) as f32 / layers as f32;
            let slice = input.shells.slice_for(layer, layers);
            let texture = match slice_texture.get(&slice) {
                Some(&tex) => tex,
                None => {
                    let la: Vec<u8> = input.shells.layer(slice).iter().flat_map(|&a| [255, a]).collect();
                    let png = png_la(format!("shell slice {slice}"), res, res, la)?;
                    let view = b.view(&png, None);
                    images.push(json!({ "name": format!("shell slice {slice:02}"), "bufferView": view, "mimeType": "image/png" }));
                    textures.push(json!({ "sampler": 0, "source": images.len() - 1 }));
                    slice_texture.insert(slice, textures.len() - 1);
                    textures.len() - 1
                }
            };
            let shade = input.shells.shadow[slice];
            let name = format!("shell {layer:02}");
            let mut mat = material(&name, [shade, shade, shade, 1.0], Some(texture), alpha, true);
            mat["extras"] = json!({ "layer": layer, "atlas_slice": slice });
            materials.push(mat);
            let positions: Vec<f32> = vertex_of
                .iter()
                .zip(&normals)
                .flat_map(|(&v, n)| {
                    let p = m.positions[v as usize];
                    [0, 1, 2].map(|k| p[k] + n[k] * (t * fur_m))
                })
                .collect();
            let mut attributes = common.clone();
            attributes.insert("POSITION".into(), json!(b.floats(&positions, 3, false, true)));
            meshes.push(json!({ "name": name, "primitives": [{
                "attributes": attributes, "indices": ind, "material": materials.len() - 1, "mode": 4 }] }));
            scene_nodes.push(nodes.len());
            let extras = json!({ "furbake": "shell", "layer": layer, "height": t, "offset_m": t * fur_m });
            nodes.push(shared.mesh_node(&name, meshes.len() - 1, Some(extras)));
        }
    } else if layers > 0 {
        notes.push("the pack has no furry triangle: no shell is exported".into());
    }
    Ok(())
}

/// Adds the fins, when the pack has them and the options ask for them: one quad per fin edge
/// from root to fur length, textured with the fin atlas shaded like the shell layers. Returns
/// whether any fin was exported.
fn add_fins(
    doc: &mut Document,
    input: &Input<'_>,
    shared: &Shared,
    alpha: ShellAlpha,
    notes: &mut Vec<String>,
) -> Result<bool, ExportError> {
    let Some((atlas, edges)) = input.fins.filter(|(_, e)| !e.vertices.is_empty()) else {
        return Ok(false);
    };
    let m = input.mesh;
    let alpha = Some(alpha);
    let fur_m = input.shells.fur_length_m;
    let atlas_layers = input.shells.layers() as u32;
    let Document { b, nodes, meshes, materials, textures, images, scene_nodes, .. } = doc;
    let n = edges.vertices.len();
    let mut vertex_of = Vec::with_capacity(4 * n);
    let mut positions = Vec::with_capacity(12 * n);
    let mut normals = Vec::with_capacity(12 * n);
    let mut uv = Vec::with_capacity(8 * n);
    let mut indices = Vec::with_capacity(6 * n);
    let repeat = input.uv_map.repeat_m;
    for &[a, bv] in &edges.vertices {
        let (pa, pb) = (m.positions[a as usize], m.positions[bv as usize]);
        let length = dist(pa, pb);
        let base = vertex_of.len() as u32;
        // a root, b root, a tip, b tip.
        for (v, along, h) in [(a, 0.0, 0.0), (bv, length, 0.0), (a, 0.0, 1.0), (bv, length, 1.0)] {
            let p = m.positions[v as usize];
            let nn = unit(m.normals[v as usize]);
            vertex_of.push(v);
            positions.extend([0, 1, 2].map(|k| p[k] + nn[k] * (h * fur_m)));
            normals.extend(nn);
            uv.extend([along / repeat, 1.0 - h]);
        }
        indices.extend([base, base + 1, base + 3, base, base + 3, base + 2]);
    }
    let mut attributes = serde_json::Map::new();
    attributes.insert("POSITION".into(), json!(b.floats(&positions, 3, false, true)));
    attributes.insert("NORMAL".into(), json!(b.floats(&normals, 3, false, false)));
    let colors: Vec<f32> = vertex_of.iter().flat_map(|&v| rgb(m.colors[v as usize])).collect();
    attributes.insert("COLOR_0".into(), json!(b.floats(&colors, 3, false, false)));
    attributes.insert("TEXCOORD_0".into(), json!(b.floats(&uv, 2, false, false)));
    shared.skin_attributes(b, &mut attributes, &vertex_of);
    let ind = b.indices(&indices);
    // Colour: the self-shadow of the shell layer at each row's height (as fin.wgsl shades
    // it); alpha: the atlas. Rows run tip (top) to root (bottom).
    let (w, h) = (atlas.width as usize, atlas.height as usize);
    let mut la = Vec::with_capacity(2 * w * h);
    for y in 0..h {
        let height = 1.0 - (y as f32 + 0.5) / h as f32;
        let layer = ((height * atlas_layers as f32) as usize).min(atlas_layers as usize - 1);
        let shade = srgb8(input.shells.shadow[layer]);
        la.extend(atlas.alpha[y * w..(y + 1) * w].iter().flat_map(|&a| [shade, a]));
    }
    let png = png_la("the fin atlas".into(), atlas.width, atlas.height, la)?;
    let view = b.view(&png, None);
    images.push(json!({ "name": "fin atlas", "bufferView": view, "mimeType": "image/png" }));
    textures.push(json!({ "sampler": 1, "source": images.len() - 1 }));
    materials.push(material("fins", [1.0; 4], Some(textures.len() - 1), alpha, true));
    meshes.push(json!({ "name": "fins", "primitives": [{
        "attributes": attributes, "indices": ind, "material": materials.len() - 1, "mode": 4 }] }));
    scene_nodes.push(nodes.len());
    nodes.push(shared.mesh_node("fins", meshes.len() - 1, Some(json!({ "furbake": "fins" }))));
    notes.push("fins are exported without the renderer's view-dependent fade (glTF materials cannot express it): they show at full opacity from every side".into());
    Ok(true)
}

/// Adds the skeleton's joint nodes, the skin over its binds and the skeleton's root as a scene
/// node; returns the index of joint 0's node (joint `j` is node `base + j`).
fn add_skeleton(doc: &mut Document, sk: &Skeleton) -> usize {
    let Document { b, nodes, scene_nodes, skins, .. } = doc;
    let base = nodes.len();
    let joint_count = sk.joint_count();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); joint_count];
    let mut roots = Vec::new();
    for (j, &p) in sk.parents.iter().enumerate() {
        if p == Skeleton::NO_PARENT {
            roots.push(base + j);
        } else {
            children[p as usize].push(base + j);
        }
    }
    for (j, kids) in children.iter().enumerate() {
        let mut n = json!({
            "name": sk.names[j],
            "translation": sk.translations[j].map(f),
            "rotation": unit_quat(sk.rotations[j]).map(f),
            "scale": sk.scales[j].map(f),
        });
        if !kids.is_empty() {
            n["children"] = json!(kids);
        }
        nodes.push(n);
    }
    // One skin joint per bind; a joint bound twice (two source skins, or a rigid bind on a
    // joint) gets an identity child node for its second inverse bind, as glTF joints are unique.
    let mut used = vec![false; joint_count];
    let mut joints = Vec::with_capacity(sk.bind_count());
    for (bi, &j) in sk.bind_joints.iter().enumerate() {
        let j = j as usize;
        if !used[j] {
            used[j] = true;
            joints.push(base + j);
        } else {
            let extra = nodes.len();
            nodes.push(json!({ "name": format!("{} bind {bi}", sk.names[j]) }));
            let kids = nodes[base + j].get("children").cloned().unwrap_or(json!([]));
            let mut kids: Vec<Value> = kids.as_array().cloned().unwrap_or_default();
            kids.push(json!(extra));
            nodes[base + j]["children"] = json!(kids);
            joints.push(extra);
        }
    }
    // A common root for the joints: the skeleton's only root, or a new identity root.
    let root = if roots.len() == 1 {
        roots[0]
    } else {
        let r = nodes.len();
        nodes.push(json!({ "name": "skeleton root", "children": roots }));
        r
    };
    scene_nodes.push(root);
    // Exactly affine (the decoder accepts rounding in the bottom row; glTF does not).
    let ibm: Vec<f32> = (0..sk.bind_count()).flat_map(|b| sk.affine_inverse_bind(b)).collect();
    let mut skin = json!({ "name": "skin", "joints": joints, "skeleton": root });
    if !ibm.is_empty() {
        skin["inverseBindMatrices"] = json!(b.mat4(&ibm));
    }
    skins.push(skin);
    base
}

/// Adds one animation per clip with a joint channel, targeting the joint nodes from `joint_base`
/// (of `joint_count` joints); notes the channels left out (morph weights, repeated properties).
fn add_clips(
    doc: &mut Document,
    clips: Option<&AnimationClips>,
    joint_base: usize,
    joint_count: usize,
    notes: &mut Vec<String>,
) {
    let Document { b, animations, .. } = doc;
    let base = joint_base;
    for clip in clips.map(|c| c.clips.as_slice()).unwrap_or_default() {
        let mut samplers = Vec::new();
        let mut channels = Vec::new();
        let mut seen = std::collections::HashSet::new();
        let mut skipped = 0usize;
        for ch in &clip.channels {
            let (joint, path) = match ch.target {
                ChannelTarget::Translation(j) | ChannelTarget::Rotation(j) | ChannelTarget::Scale(j) => {
                    (j as usize, ch.target.path_name())
                }
                ChannelTarget::MorphWeights(_) => {
                    skipped += 1;
                    continue;
                }
            };
            if joint >= joint_count || !seen.insert((joint, path)) {
                skipped += 1;
                continue;
            }
            let comps = ch.components as usize;
            let mut interpolation = ch.interpolation;
            let mut values = ch.values.clone();
            // glTF needs two keys for a cubic spline; one key is a constant.
            if interpolation == Interpolation::CubicSpline && ch.times_s.len() < 2 {
                interpolation = Interpolation::Step;
                values = values[comps..2 * comps].to_vec();
            }
            if path == "rotation" && interpolation != Interpolation::CubicSpline {
                for q in values.chunks_exact_mut(4) {
                    q.copy_from_slice(&unit_quat([q[0], q[1], q[2], q[3]]));
                }
            }
            let input_acc = b.floats(&ch.times_s, 1, true, true);
            let output_acc = b.floats(&values, comps, true, false);
            samplers.push(json!({ "input": input_acc, "output": output_acc, "interpolation": interpolation.name() }));
            channels.push(json!({ "sampler": samplers.len() - 1, "target": { "node": base + joint, "path": path } }));
        }
        if skipped > 0 {
            notes.push(format!(
                "clip {:?}: {skipped} channel(s) not exported (morph weights, or a repeated joint property)",
                clip.name
            ));
        }
        if !channels.is_empty() {
            animations.push(json!({ "name": clip.name, "samplers": samplers, "channels": channels }));
        }
    }
}

/// Writes the document's JSON (asset, scene, the non-empty arrays and the samplers the textures
/// use) and packs it with the binary chunk into the GLB container.
fn finish_document(doc: Document, input: &Input<'_>, layers: u32, fins_exported: bool) -> Result<Vec<u8>, ExportError> {
    let Document { b, nodes, meshes, materials, textures, images, scene_nodes, skins, animations } = doc;
    // Samplers: 0 repeats both ways (shells), 1 repeats along the fin and clamps across it.
    let samplers = json!([
        { "magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497 },
        { "magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 33071 },
    ]);
    let mut extras = json!({
        "fur_length_m": input.shells.fur_length_m,
        "atlas_layers": input.shells.layers() as u32,
        "exported_layers": layers,
        "shell_resolution": input.shells.params.resolution,
        "uv_repeat_m": input.uv_map.repeat_m,
    });
    if let Some((name, preset, seed)) = &input.manifest {
        extras["input_name"] = json!(name);
        extras["preset"] = json!(preset);
        extras["seed"] = json!(seed);
    }
    let mut doc = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("furbake-export ", env!("CARGO_PKG_VERSION")),
            "extras": { "furbake": extras },
        },
        "scene": 0,
        "scenes": [ { "name": "furbake pack" } ],
    });
    if !scene_nodes.is_empty() {
        doc["scenes"][0]["nodes"] = json!(scene_nodes);
    }
    for (key, list) in [
        ("nodes", nodes),
        ("meshes", meshes),
        ("materials", materials),
        ("textures", textures),
        ("images", images),
        ("skins", skins),
        ("animations", animations),
    ] {
        if !list.is_empty() {
            doc[key] = Value::Array(list);
        }
    }
    if doc.get("textures").is_some() {
        let used = if fins_exported { 2 } else { 1 };
        doc["samplers"] = Value::Array(samplers.as_array().map(|s| s[..used].to_vec()).unwrap_or_default());
    }
    b.finish(doc)
}

/// Every welded vertex's influences as glTF `JOINTS_n`/`WEIGHTS_n` carry them, in the pack's
/// slot count: a bind that a vertex names twice becomes one slot with the summed weight (glTF
/// requires distinct joints per vertex — the Khronos glTF-Validator's
/// `ACCESSOR_JOINTS_INDEX_DUPLICATE` — and skinning sums weighted matrices, so the pose is the
/// same), largest weight first, unused slots bind 0 with weight 0, and the weights renormalised in
/// `f64` so that their `f32` sum is 1 within the validator's rounding allowance (a pack's sums are
/// within 1e-3 of 1, docs/format.md "Value ranges readers enforce").
fn gltf_influences(w: &SkinWeights) -> (Vec<u16>, Vec<f32>) {
    let k = w.influences_per_vertex as usize;
    let (mut binds, mut weights) = (Vec::with_capacity(w.binds.len()), Vec::with_capacity(w.weights.len()));
    let mut slots: Vec<(u16, f64)> = Vec::with_capacity(k);
    for v in 0..w.vertex_count() {
        slots.clear();
        for (b, x) in w.influences(v).filter(|&(_, x)| x > 0.0) {
            match slots.iter_mut().find(|(c, _)| *c == b) {
                Some(slot) => slot.1 += f64::from(x),
                None => slots.push((b, f64::from(x))),
            }
        }
        // Stable: equal weights keep the pack's order.
        slots.sort_by(|a, b| b.1.total_cmp(&a.1));
        let sum: f64 = slots.iter().map(|&(_, x)| x).sum();
        for j in 0..k {
            match slots.get(j) {
                Some(&(b, x)) if sum > 0.0 => {
                    binds.push(b);
                    weights.push((x / sum) as f32);
                }
                _ => {
                    binds.push(0);
                    weights.push(0.0);
                }
            }
        }
    }
    (binds, weights)
}

impl Shared {
    fn with_bind_count(self, binds: usize) -> Shared {
        if binds == 0 { Shared { influences: None, skin: None, ..self } } else { self }
    }

    /// Adds the skinning attributes of `vertex_of` (welded vertex per exported vertex).
    fn skin_attributes(&self, b: &mut Builder, attributes: &mut serde_json::Map<String, Value>, vertex_of: &[u32]) {
        let Some((k, binds, weights)) = &self.influences else { return };
        let bind_count = self.bind_count;
        for set in 0..k / 4 {
            let mut j = Vec::with_capacity(vertex_of.len() * 4);
            let mut wt = Vec::with_capacity(vertex_of.len() * 4);
            for &v in vertex_of {
                let at = v as usize * k + set * 4;
                j.extend_from_slice(&binds[at..at + 4]);
                wt.extend_from_slice(&weights[at..at + 4]);
            }
            attributes.insert(format!("JOINTS_{set}"), json!(b.joints(&j, bind_count)));
            attributes.insert(format!("WEIGHTS_{set}"), json!(b.floats(&wt, 4, false, false)));
        }
    }

    /// A node drawing mesh `mesh`, skinned when the pack is, with `extras`.
    fn mesh_node(&self, name: &str, mesh: usize, extras: Option<Value>) -> Value {
        let mut n = json!({ "name": name, "mesh": mesh });
        if let Some(s) = self.skin {
            n["skin"] = json!(s);
        }
        if let Some(e) = extras {
            n["extras"] = e;
        }
        n
    }
}

/// Exported vertices of `triangles` (in that order): one per distinct (welded vertex, corner
/// UV), first use first. Returns the welded vertex of each, their UVs (flattened) and the indices.
fn unweld(all: &[[u32; 3]], triangles: Vec<usize>, uvs: Option<&Vec<[[f32; 2]; 3]>>) -> (Vec<u32>, Vec<f32>, Vec<u32>) {
    let mut index: HashMap<(u32, u32, u32), u32> = HashMap::new();
    let (mut vertex_of, mut uv, mut indices) = (Vec::new(), Vec::new(), Vec::with_capacity(3 * triangles.len()));
    for t in triangles {
        for c in 0..3 {
            let v = all[t][c];
            let corner = uvs.map_or([0.0; 2], |u| u[t][c]);
            let key = (v, corner[0].to_bits(), corner[1].to_bits());
            let i = *index.entry(key).or_insert_with(|| {
                vertex_of.push(v);
                uv.extend(corner);
                (vertex_of.len() - 1) as u32
            });
            indices.push(i);
        }
    }
    (vertex_of, uv, indices)
}

fn rgb(c: [f32; 4]) -> [f32; 3] {
    [c[0], c[1], c[2]]
}

fn unit(n: [f32; 3]) -> [f32; 3] {
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if l > 0.0 { n.map(|x| x / l) } else { [0.0, 0.0, 1.0] }
}

fn unit_quat(q: [f32; 4]) -> [f32; 4] {
    let l = q.iter().map(|x| f64::from(*x).powi(2)).sum::<f64>().sqrt();
    if l > 0.0 { q.map(|x| (f64::from(x) / l) as f32) } else { [0.0, 0.0, 0.0, 1.0] }
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use furbake_formats::sections::skin_weights::SkinWeightStats;

    use super::*;

    #[test]
    fn a_repeated_bind_is_merged_and_the_weights_renormalised() {
        let w = SkinWeights {
            influences_per_vertex: 4,
            bind_count: 3,
            // Vertex 0 names bind 1 twice; vertex 1 sums to 0.9995 (a pack allows 1e-3).
            binds: vec![1, 2, 1, 0, 2, 0, 0, 0],
            weights: vec![0.25, 0.3, 0.45, 0.0, 0.9995, 0.0, 0.0, 0.0],
            stats: SkinWeightStats::default(),
        };
        let (binds, weights) = gltf_influences(&w);
        assert_eq!(binds, [1, 2, 0, 0, 2, 0, 0, 0], "bind 1 once, largest weight first, unused slots 0");
        for (got, want) in weights.iter().zip([0.7, 0.3, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]) {
            assert!((got - want).abs() < 1e-6, "{weights:?}");
        }
        assert_eq!(weights[4], 1.0);
    }
}
