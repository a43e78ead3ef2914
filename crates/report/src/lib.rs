//! furbake-report: the measured accuracy-vs-time report, `docs/accuracy.md` and its SVG plots —
//! the user's ask "show what accuracy costs in time". Its one job is measurement and reporting:
//! it runs the physics of two crates — the fur solvers of `furbake-sim` (fur thesis eq. 3.20–3.34,
//! §3.4.1) against a converged conjugate-gradient reference, and the keyframe decode and cluster
//! force field of `furbake-grass` (grass thesis ch. 3–4) against exact values — times them, and
//! renders tables, markdown and hand-written SVG plots.
//!
//! It is a crate of its own because it depends on both physics crates and belongs in neither:
//! `furbake-sim` and `furbake-grass` stay physics only (no report orchestration, no markdown),
//! and the CLI (`furbake report accuracy`, `make report`) stays thin glue that calls
//! [`accuracy_document`] and [`AccuracyDocument::write_into`].
//!
//! - [`fur`]: per scene (grass patch, stiff net, Fox; prisms and sticks), solver × iterations ×
//!   step size × raw/default settings: max and RMS error against wall time per simulated second,
//!   one chart per scene with its Pareto front; and time per step against size.
//! - [`grass`]: pose error by keyframe count × selection × encoding against decode time (with its
//!   chart), quantisation, force error by cluster size, with decode and update times.
//! - `rendering` (the `render` feature, on by default): `docs/rendering-accuracy.md`, furbake's
//!   shells and fins (fur thesis §3.2) against a CPU ray-marcher of the baked hair volume (§3.1):
//!   FLIP and coverage IoU per scene × view angle × shell count × fins, fragment counts and frame
//!   times, the error-against-cost chart and the level-of-detail knee table.
//! - [`svg`]: the small plotting module the charts share (legend outside the plots, log axes
//!   marked, label collision avoidance).
//!
//! ```
//! use furbake_report::fur::{AccuracySettings, SceneId, accuracy_report, configurations};
//!
//! // A tiny fur report: one scene, one step size, one iteration count, one small timing size.
//! let settings = AccuracySettings {
//!     scenes: vec![SceneId::GrassPatchPrisms],
//!     step_sizes_s: vec![1.0 / 30.0],
//!     iterations: vec![1],
//!     reference_dt_s: 1.0 / 300.0,
//!     duration_s: 0.05,
//!     repeats: 1,
//!     timing_sizes: vec![(200, 300)],
//!     timing_budget_s: 0.0,
//!     ..AccuracySettings::default()
//! };
//! let report = accuracy_report(&settings, |_| {})?;
//! // Every configuration of `SolverKind::ALL`, raw and with default settings, at the one step.
//! assert_eq!(report.scenes[0].rows.len(), configurations(&[1]).len() * 2);
//! assert!(report.markdown.starts_with("# Accuracy vs time of the fur solvers"));
//! # Ok::<(), furbake_report::ReportError>(())
//! ```
//!
//! Every number comes from running the physics in this process: errors are deterministic, times
//! depend on the machine and its load (the document says how many threads it had).

#![deny(missing_docs)]
use std::path::{Path, PathBuf};

pub mod fur;
pub mod grass;
#[cfg(feature = "render")]
pub mod rendering;
pub mod svg;

/// Errors of the report, split by blame: the physics refused a measurement's settings (the
/// caller's, or a bug), or the document could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The fur measurements failed.
    #[error("fur accuracy report: {0}")]
    Fur(#[from] furbake_sim::SimError),
    /// The Fox scene's glTF could not be imported.
    #[error("{}: {source}", path.display())]
    Import {
        /// The glTF.
        path: PathBuf,
        /// The cause (boxed: the import error is large).
        source: Box<furbake_import::ImportError>,
    },
    /// The walking Fox's clip could not be played.
    #[error("fur accuracy report, the walking Fox: {0}")]
    Animation(furbake_runtime::AnimationError),
    /// The grass measurements failed.
    #[error("grass accuracy report: {0}")]
    Grass(#[from] furbake_grass::GrassError),
    /// The output directory could not be created.
    #[error("{}: cannot create directory: {source}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file could not be written.
    #[error(transparent)]
    Write(#[from] furbake_formats::FormatError),
}

/// What the whole document measures.
#[derive(Clone, Debug, Default)]
pub struct AccuracyOptions {
    /// The fur part.
    pub fur: fur::AccuracySettings,
    /// The grass part.
    pub grass: grass::GrassAccuracyOptions,
}

/// Which part of the document is being measured (for progress messages).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReportPart {
    /// The fur solvers (a few minutes in release with the default options).
    Fur,
    /// The grass keyframes and force field.
    Grass,
}

/// The generated `docs/accuracy.md` and the plots it links to.
#[derive(Clone, Debug)]
pub struct AccuracyDocument {
    /// The markdown: a generated-file header, the fur part, then the grass part.
    pub markdown: String,
    /// (file name, SVG text) of the plots the markdown links to.
    pub plots: Vec<(String, String)>,
    /// The fur part's raw measurements.
    pub fur: fur::AccuracyReport,
}

/// The file name of the document inside the output directory.
pub const DOCUMENT_NAME: &str = "accuracy.md";

/// Runs every measurement and renders `docs/accuracy.md`: the fur part, then the grass part.
/// `progress` is told when each part starts.
pub fn accuracy_document(
    options: &AccuracyOptions,
    mut progress: impl FnMut(ReportPart),
) -> Result<AccuracyDocument, ReportError> {
    progress(ReportPart::Fur);
    let fur = fur::accuracy_report(&options.fur, |_| {})?;
    progress(ReportPart::Grass);
    let grass = grass::grass_accuracy(&options.grass)?;
    let header = format!(
        "<!-- Generated by `make report` (furbake_report::accuracy_document; {}). Do not edit by hand. -->\n\n",
        fur::machine()
    );
    let markdown = format!("{header}{}\n\n{}\n", fur.markdown.trim_end(), grass.markdown.trim_end());
    let mut plots = fur.plots.clone();
    plots.extend(grass.plots);
    Ok(AccuracyDocument { markdown, plots, fur })
}

impl AccuracyDocument {
    /// Writes the plots and then [`DOCUMENT_NAME`] into `dir` (created if missing), each file
    /// atomically; returns the document's path.
    pub fn write_into(&self, dir: &Path) -> Result<PathBuf, ReportError> {
        std::fs::create_dir_all(dir).map_err(|source| ReportError::CreateDir { path: dir.to_path_buf(), source })?;
        for (name, svg) in &self.plots {
            furbake_formats::write_file_atomic(&dir.join(name), svg.as_bytes())?;
        }
        let path = dir.join(DOCUMENT_NAME);
        furbake_formats::write_file_atomic(&path, self.markdown.as_bytes())?;
        Ok(path)
    }
}
