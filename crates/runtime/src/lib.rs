//! furbake-runtime: what a game or tool links to use baked furbake packs — open a pack lazily
//! ([`Pack`]) and describe a scene ([`Scene`]: packs, camera, light, time step and the effects
//! it wants). No CLI, no GPU code (rendering is `furbake-render`), no baking.
//!
//! A pack is opened by validating its header and section table only; each section is read,
//! checksummed and decoded the first time an accessor asks for it ([`Pack::read_counts`] shows
//! which ones were touched). A scene is parsed from TOML and validated once; its
//! [`Effects`] list is what later stages are planned from: an effect the scene does not declare
//! gets no stage (SPEC "Runtime: Scenes").
//!
//! ```
//! use furbake_formats::{PackWriter, SectionKind, sections::fin_atlas::FinAtlas};
//! use furbake_runtime::{Effect, Pack, Scene};
//!
//! // A one-section pack on disk.
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("fins.fbk");
//! let fins = FinAtlas { width: 2, height: 2, slices: 20, alpha: vec![0, 255, 128, 9] };
//! PackWriter::new().push_section(&fins).write_atomic(&path)?;
//!
//! let pack = Pack::open(&path)?;
//! assert!(pack.kinds_read().is_empty()); // opening reads no section
//! assert_eq!(pack.fin_atlas()?.alpha, fins.alpha);
//! assert_eq!(pack.kinds_read(), vec![SectionKind::FIN_ATLAS]);
//!
//! let scene = Scene::from_toml_str(
//!     r#"
//!     [[packs]]
//!     name = "fins"
//!     path = "fins.fbk"
//!     [effects.gravity]
//!     [effects.wind]
//!     velocity_m_s = [2.0, 0.0, 0.0]
//!     "#,
//!     "scene.toml".as_ref(),
//!     dir.path(),
//! )?;
//! assert_eq!(scene.effects(), vec![Effect::Gravity, Effect::Wind]);
//! assert_eq!(scene.packs[0].path, path);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod pack;
pub mod scene;

use std::path::PathBuf;

use furbake_formats::{FormatError, SectionKind};

pub use pack::Pack;
pub use scene::{Camera, Effect, Effects, Light, Scene, SceneError, ScenePack};

/// Why a runtime operation failed.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    /// The pack file is unreadable or invalid (blame: the file or the OS; see [`FormatError`]).
    #[error(transparent)]
    Format(#[from] FormatError),
    /// The pack lacks a section the caller needs (e.g. rendering a pack baked without shells).
    #[error("{path}: the pack has no {kind} section", path = path.display())]
    MissingSection {
        /// The pack file.
        path: PathBuf,
        /// The kind asked for.
        kind: SectionKind,
    },
    /// The scene file is unreadable or invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
}
