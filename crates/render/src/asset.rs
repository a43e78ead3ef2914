//! [`FurAsset`]: the sections of one pack the renderer draws, checked against one another once
//! (UV map and fin edges match the skin), and the CPU-side geometry built from them: triangle
//! corners de-indexed (the shell UV map is per triangle corner, fur thesis §3.2, fig. 3.18–3.19),
//! fin quads on the fin edges (§3.2, fig. 3.16), the shell vertices in either scale-vector
//! layout (per welded vertex, or per triangle corner for parted fur, §3.4.1), and the
//! box-filtered mip chain of the shell and fin atlases. An animated pack also brings its skin
//! weights and morph targets (glTF 2.0 "Skins", "Morph Targets"), which the renderer's skinning
//! pass ([`crate::skinning::SkinningPass`]) uploads.

use std::sync::Arc;

use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::fin_edges::FinEdges;
use furbake_formats::sections::morph_targets::MorphTargets;
use furbake_formats::sections::shell_atlas::ShellAtlas;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::SkinWeights;
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use furbake_runtime::Pack;
#[cfg(feature = "testing")]
use furbake_runtime::ShellVertexLayout;

use crate::RenderError;
use crate::shaders::{FinVertex, SurfaceVertex};

/// The sections the fur renderer needs, validated against each other.
#[derive(Clone, Debug)]
pub struct FurAsset {
    mesh: Arc<SkinMesh>,
    shells: Arc<ShellAtlas>,
    uv_map: Arc<TriangleUvMap>,
    fins: Option<(Arc<FinAtlas>, Arc<FinEdges>)>,
    skin_weights: Option<Arc<SkinWeights>>,
    morph_targets: Option<Arc<MorphTargets>>,
    /// The shells' stacking exponents (`furbake_draw::stacking`), computed on first use and shared by
    /// every clone and every renderer of this asset.
    stacking: Arc<std::sync::OnceLock<Vec<f32>>>,
}

impl FurAsset {
    /// Reads exactly the skin mesh, shell atlas, triangle UV map, — when `with_fins` and the
    /// pack has both — the fin atlas and fin edges, and the skin weights and morph targets when
    /// the pack has them (an animated pack; the renderer skins it on the GPU). No other section
    /// of the pack is touched: the skeleton and clips belong to whoever poses it.
    pub fn from_pack(pack: &Pack, with_fins: bool) -> Result<FurAsset, RenderError> {
        use furbake_formats::SectionKind;
        let fins = if with_fins && pack.has(SectionKind::FIN_ATLAS) && pack.has(SectionKind::FIN_EDGES) {
            Some((pack.fin_atlas()?, pack.fin_edges()?))
        } else {
            None
        };
        FurAsset::new(pack.skin_mesh()?, pack.shell_atlas()?, pack.triangle_uv_map()?, fins)?
            .with_animation(pack.skin_weights()?, pack.morph_targets()?)
    }

    /// This asset with skin weights and morph targets (either may be `None`): checked against the
    /// skin (one influence set and one morph delta per welded vertex) by the formats' consistency
    /// check. With either present, [`crate::FurRenderer`] skins the asset on the GPU and takes a
    /// pose each frame ([`crate::FurRenderer::set_pose`]).
    pub fn with_animation(
        self,
        skin_weights: Option<Arc<SkinWeights>>,
        morph_targets: Option<Arc<MorphTargets>>,
    ) -> Result<FurAsset, RenderError> {
        let sections = furbake_formats::PackSections {
            mesh: Some(&self.mesh),
            skin_weights: skin_weights.as_deref(),
            morph_targets: morph_targets.as_deref(),
            ..Default::default()
        };
        if let Err(e) = furbake_formats::check_consistency(&[], &sections) {
            return Err(RenderError::InvalidAsset {
                what: match e {
                    furbake_formats::FormatError::Invalid { what, .. } => what,
                    e => e.to_string(),
                },
            });
        }
        Ok(FurAsset { skin_weights, morph_targets, ..self })
    }

    /// Checks that the sections belong together (one UV triple per triangle, one normal and colour
    /// per vertex, fin edge indices inside the mesh). After this the geometry builders trust them.
    pub fn new(
        mesh: Arc<SkinMesh>,
        shells: Arc<ShellAtlas>,
        uv_map: Arc<TriangleUvMap>,
        fins: Option<(Arc<FinAtlas>, Arc<FinEdges>)>,
    ) -> Result<FurAsset, RenderError> {
        let bad = |what: String| Err(RenderError::InvalidAsset { what });
        let (v, f) = (mesh.positions.len(), mesh.triangles.len());
        if mesh.normals.len() != v || mesh.colors.len() != v || mesh.fur_mask.len() != f {
            return bad(format!(
                "skin mesh arrays disagree: {v} positions, {} normals, {} colours; {f} triangles, {} fur flags",
                mesh.normals.len(),
                mesh.colors.len(),
                mesh.fur_mask.len()
            ));
        }
        if v > u32::MAX as usize / 2 {
            return bad(format!("{v} vertices exceed the renderer's index range"));
        }
        if let Some(t) = mesh.triangles.iter().flatten().find(|&&i| i as usize >= v) {
            return bad(format!("triangle index {t} is out of range ({v} vertices)"));
        }
        if shells.alpha.len() != shells.layers() * shells.layer_texels() || shells.shadow.len() != shells.layers() {
            return bad("the shell atlas arrays do not match its layer count".into());
        }
        if 3 * f > u32::MAX as usize / 2 {
            return bad(format!("{f} triangles exceed the renderer's corner index range"));
        }
        if let Some((atlas, _)) = &fins {
            if atlas.alpha.len() != atlas.width as usize * atlas.height as usize {
                return bad("the fin atlas size does not match its texel count".into());
            }
        }
        // The cross-section checks (formats' one function): UV map and fin edges belong to this
        // skin. After them the geometry builders index the mesh in range.
        let sections = furbake_formats::PackSections {
            mesh: Some(&mesh),
            shells: Some(&shells),
            uv_map: Some(&uv_map),
            fins: fins.as_ref().map(|(atlas, _)| &**atlas),
            fin_edges: fins.as_ref().map(|(_, edges)| &**edges),
            ..Default::default()
        };
        if let Err(e) = furbake_formats::check_consistency(&[], &sections) {
            return bad(match e {
                furbake_formats::FormatError::Invalid { what, .. } => what,
                e => e.to_string(),
            });
        }
        Ok(FurAsset {
            mesh,
            shells,
            uv_map,
            fins,
            skin_weights: None,
            morph_targets: None,
            stacking: Default::default(),
        })
    }

    /// Bytes of GPU memory a [`crate::FurRenderer`] of this asset allocates for its data (skin
    /// corners, scale vectors, the shell atlas with its mip chain, fins when `with_fins`, and for
    /// an animated asset the skinning pass's buffers, `SkinningPass::gpu_bytes`, and the
    /// renderer's own pose and posed vertices), not counting the renderer's fixed cost (1 MiB,
    /// `RENDERER_OVERHEAD_BYTES`). Computed from the sections' sizes alone, before anything is
    /// uploaded.
    pub fn gpu_bytes(&self, with_fins: bool) -> u64 {
        self.shared_gpu_bytes(with_fins).saturating_add(self.instance_gpu_bytes())
    }

    /// The part of [`FurAsset::gpu_bytes`] a [`crate::FurGpuAsset`] holds once for every renderer
    /// of this asset: skin corners, shell atlas with mips, with fins the fin atlas and quads, and
    /// for an animated asset its skinning pass (bind pose, influences, morph deltas), which each
    /// renderer's own pass shares.
    pub fn shared_gpu_bytes(&self, with_fins: bool) -> u64 {
        use crate::shaders::{FinVertex, SurfaceVertex};
        let f = self.mesh.triangles.len() as u64;
        let mips = |texels: u64| texels + texels / 3; // a full mip chain adds a third
        let res = self.shells.params.resolution as u64;
        let mut bytes = 3 * f * std::mem::size_of::<SurfaceVertex>() as u64 // skin corners
            + mips(res * res * self.shells.layers() as u64); // R8 shell atlas
        if let (true, Some((atlas, edges))) = (with_fins, &self.fins) {
            bytes += mips(atlas.width as u64 * atlas.height as u64)
                + 6 * edges.vertices.len() as u64 * std::mem::size_of::<FinVertex>() as u64;
            // Silhouette fins (crate::silhouette): at most 3F/2 interior edges of 32 bytes, a
            // colour and a bind-pose vertex (16 + 32 bytes) per welded vertex. An upper bound.
            bytes += 48 * f + 48 * self.mesh.positions.len() as u64;
        }
        // The asset's own skinning pass, whose static part each renderer's pass shares.
        let (weights, morphs) = (self.skin_weights.as_deref(), self.morph_targets.as_deref());
        bytes.saturating_add(crate::skinning::SkinningPass::gpu_bytes(&self.mesh, weights, morphs))
    }

    /// The part of [`FurAsset::gpu_bytes`] each renderer holds of its own: scale vectors (room
    /// for either layout), the silhouette fin instances (a bound) and, for an animated asset,
    /// its skinning pass's pose and posed vertices.
    pub fn instance_gpu_bytes(&self) -> u64 {
        let (v, f) = (self.mesh.positions.len() as u64, self.mesh.triangles.len() as u64);
        // Scale vectors; the silhouette fin instances (8 bytes per interior edge, at most 3F/2)
        // with their draw arguments and parameters.
        (16 * v.max(3 * f) + 12 * f + 64).saturating_add(crate::skinning::SkinningPass::instance_gpu_bytes(
            &self.mesh,
            self.skin_weights.as_deref(),
            self.morph_targets.as_deref(),
        ))
    }

    /// The skin.
    pub fn mesh(&self) -> &SkinMesh {
        &self.mesh
    }

    /// The shell atlas.
    pub fn shells(&self) -> &ShellAtlas {
        &self.shells
    }

    /// The per-triangle UVs.
    pub fn uv_map(&self) -> &TriangleUvMap {
        &self.uv_map
    }

    /// The shells' stacking exponents (docs/design.md "Shell opacity"), computed from the atlas
    /// on first use — 0.15 s for the `fur` preset's 16 × 128² atlas in the dev profile — and kept.
    pub(crate) fn stacking_table(&self) -> &[f32] {
        self.stacking.get_or_init(|| furbake_draw::stacking::shell_stacking_table(&self.shells, self.uv_map.repeat_m))
    }

    /// The fin atlas and edges, when loaded.
    pub fn fins(&self) -> Option<(&FinAtlas, &FinEdges)> {
        self.fins.as_ref().map(|(a, e)| (&**a, &**e))
    }

    /// The skin weights, when the pack has them (a skinned character).
    pub fn skin_weights(&self) -> Option<&SkinWeights> {
        self.skin_weights.as_deref()
    }

    /// The morph targets, when the pack has them.
    pub fn morph_targets(&self) -> Option<&MorphTargets> {
        self.morph_targets.as_deref()
    }

    /// Whether the asset is animated (skin weights or morph targets): its renderer runs a
    /// skinning pass each frame. A static asset draws its bind pose and pays nothing for it.
    pub fn is_animated(&self) -> bool {
        self.skin_weights.is_some() || self.morph_targets.is_some()
    }

    /// A sphere holding the skin and its fur: centre of the skin's bounding box, radius = the
    /// farthest vertex plus the fur length (metres).
    pub fn bounding_sphere(&self) -> ([f32; 3], f32) {
        furbake_draw::geometry::bounding_sphere(&self.mesh, self.shells.fur_length_m)
    }

    /// The automatic preview camera: a three-quarter view fitted tightly around the furry mesh
    /// for a target of the given aspect ratio (width / height).
    pub fn auto_view(&self, aspect: f32) -> crate::View {
        crate::View::fit_points(&self.mesh.positions, self.shells.fur_length_m, aspect, self.bounding_sphere())
    }

    /// Every triangle corner, furry triangles first, and the furry triangle count
    /// ([`furbake_draw::geometry::surface_vertices`]).
    pub(crate) fn surface_vertices(&self) -> (Vec<SurfaceVertex>, u32) {
        furbake_draw::geometry::surface_vertices(&self.mesh, &self.uv_map)
    }

    /// Six corners per fin edge, none without fins ([`furbake_draw::geometry::fin_vertices`]).
    pub(crate) fn fin_vertices(&self) -> Vec<FinVertex> {
        self.fins().map(|(_, edges)| furbake_draw::geometry::fin_vertices(&self.mesh, edges)).unwrap_or_default()
    }

    /// The initial scale vectors (eq. 3.35 at rest: s = n), one `[x, y, z, 0]` per vertex.
    pub(crate) fn rest_scale_vectors(&self) -> Vec<[f32; 4]> {
        self.mesh.normals.iter().map(|n| [n[0], n[1], n[2], 0.0]).collect()
    }

    #[cfg(feature = "testing")]
    /// Shell vertices, i.e. scale vectors the renderer takes, in `layout`: the welded vertex
    /// count, or 3 × the triangle count for [`ShellVertexLayout::PerCorner`].
    pub fn shell_vertex_count(&self, layout: ShellVertexLayout) -> usize {
        match layout {
            ShellVertexLayout::PerVertex => self.mesh.positions.len(),
            ShellVertexLayout::PerCorner => self.mesh.triangles.len() * 3,
        }
    }

    #[cfg(feature = "testing")]
    /// Root position and normal of every shell vertex in `layout` order: the welded vertices, or
    /// every triangle's three corners (`3 × triangle + corner`).
    pub(crate) fn shell_vertices(&self, layout: ShellVertexLayout) -> Vec<([f32; 3], [f32; 3])> {
        let m = &*self.mesh;
        match layout {
            ShellVertexLayout::PerVertex => m.positions.iter().copied().zip(m.normals.iter().copied()).collect(),
            ShellVertexLayout::PerCorner => {
                m.triangles.iter().flatten().map(|&i| (m.positions[i as usize], m.normals[i as usize])).collect()
            }
        }
    }
}
