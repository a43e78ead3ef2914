//! The rendering accuracy report (`docs/rendering-accuracy.md`): how close furbake's shells and
//! fins (fur thesis §3.2) come to the hair volume they slice (§3.1), and what each shell costs.
//!
//! - [`reference`](mod@reference): the ground truth, a CPU ray-marcher of the bake's hairs on the mesh.
//! - [`shade`]: the CPU twin of the shaders' fur shading, which the reference lights with.
//! - [`gpu`]: the headless host that renders furbake's frame and counts its fragments.
//! - [`scenes`]: the flat patch, the sphere and the Fox, baked with the `fur` preset, and views.
//! - [`score`]: NVIDIA FLIP (mean, 99th percentile) and coverage IoU.
//! - [`report`]: the sweep over scenes, angles, shell counts and fins, the level-of-detail sweep
//!   and its knee table, the chart and the document.

pub mod gpu;
pub mod reference;
pub mod report;
pub mod scenes;
pub mod score;
pub mod shade;

/// Why the rendering report failed, by stage.
#[derive(Debug, thiserror::Error)]
pub enum RenderReportError {
    /// A mesh could not be imported.
    #[error("{0}: {1}")]
    Import(String, String),
    /// A bake failed (or a baked scene lacks what a view needs).
    #[error("bake: {0}")]
    Bake(String),
    /// The GPU side failed.
    #[error(transparent)]
    Render(#[from] furbake_render::RenderError),
    /// The reference refused its input.
    #[error(transparent)]
    Reference(#[from] reference::ReferenceError),
    /// An image could not be encoded.
    #[error("PNG encoding: {0}")]
    Png(String),
    /// The document could not be written.
    #[error("{}: {source}", path.display())]
    Write {
        /// The file or directory.
        path: std::path::PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}
