//! What the tests inspect, behind the `testing` feature (off by default; this crate's own tests
//! turn it on): never what a host's frame calls, because these submit and wait, or expose the
//! shaders' data layouts, which change with the shaders.
//!
//! - CPU references the GPU passes are checked against: the grass culling ([`CullReference`],
//!   [`blade_random`], [`thinning_keep`]), the silhouette fin selection ([`interior_edges`],
//!   [`silhouette_edges`], [`edge_facing`], [`silhouette_fade`]), the strand direction
//!   ([`strand_tangent`]) and the shell level of detail ([`ShellLevel`], [`projected_fur_px`],
//!   [`shell_level`]).
//! - Readbacks, each submitting and waiting: the posed skin of an animated renderer
//!   ([`SkinningPass::read_back`] through `FurRenderer::skinning`), the sheared shell vertices and
//!   hair directions (`FurRenderer::shell_positions`, `FurRenderer::shell_tangents`), the
//!   silhouette selection (`FurRenderer::silhouette_selection`), the posed blades and their
//!   culling lists (`BladeRenderer::compute`, `BladeRenderer::read_positions`,
//!   `BladeRenderer::read_culling`). These are methods of the renderers that exist only with the
//!   feature, as do `FurRenderer::gpu_asset`,
//!   `FurRenderer::has_silhouette_fins`, `BladeRenderer::shares_data_with`,
//!   `BladeRenderer::params`, `BladeRenderer::lods` and `FurAsset::shell_vertex_count`.
//! - [`blocking_calls_on_this_thread`]: how many times this crate submitted or waited on the
//!   calling thread (the middleware tests hold `prepare` and `render` to zero).
//! - [`RENDERER_OVERHEAD_BYTES`], the fixed memory per renderer the estimates add.

pub use crate::blades::BladeUniforms;
pub use crate::blocking::blocking_calls_on_this_thread;
pub use crate::culling::{
    BladeLods, CullDecision, CullLists, CullReference, CullUniforms, EDGE_ON_WIDTH, MAX_LODS, blade_random,
    thinning_keep,
};
pub use crate::depth_pyramid::reduce_level;
pub use crate::lod::{ShellLevel, projected_fur_px};
pub use crate::scene::RENDERER_OVERHEAD_BYTES;
pub use crate::shading::strand_tangent;
pub use crate::silhouette::{edge_facing, interior_edges, silhouette_edges, silhouette_fade};
pub use crate::skinning::{PosedVertices, SkinningPass};
pub use furbake_draw::layout::SilhouetteEdge;

/// The shell level `renderer`'s next `prepare` of `frame` chooses (its level of detail, or every
/// layer without one or without a viewport).
pub fn shell_level(renderer: &crate::FurRenderer, frame: &crate::FrameUniforms) -> ShellLevel {
    renderer.shell_level(frame)
}
