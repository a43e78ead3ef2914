//! furbake-import: turns a glTF 2.0 file (`.glb`, or `.gltf` with embedded or external buffers)
//! into the [`SkinMesh`] furbake grows fur from — nothing else (docs/design.md "Import").
//!
//! The pipeline, one verb per stage:
//! 1. `source` — read the bytes, split the GLB container, refuse unsupported
//!    required extensions, validate with the `gltf` crate, load and hash the buffers (external
//!    files only from inside the asset roots, through `external`);
//! 2. `scene` — walk the default scene (else scene 0, else every root node), apply node
//!    transforms (matrix or TRS, normals by the inverse transpose, winding flipped under
//!    mirroring), triangulate lists/strips/fans, decide the per-triangle fur mask;
//! 3. `weld` — weld positions within the tolerance, skip degenerate triangles (counted),
//!    average normals and colours per welded vertex, generate area-weighted normals where the
//!    file had none.
//!
//! 4. `animation` — skins (joint hierarchy, inverse binds, up to eight normalised influences per
//!    vertex), morph targets and every animation clip (glTF 2.0 "Skins", "Morph Targets",
//!    "Animations"), carried through the weld to the welded vertices.
//!
//! A skinned mesh is imported in its bind space (its node's transform ignored, as glTF says);
//! its rest shape is what the skeleton's binds reproduce at the bind pose. Every
//! failure is an [`ImportError`] naming the file (and mesh/primitive); no input makes it panic.
//!
//! ```
//! use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
//!
//! let patch = testmesh::grass_patch(1.0);
//! let imported = import_gltf_slice(&patch.gltf, "grass_patch.gltf", None, &ImportSettings::default())?;
//! assert_eq!(imported.mesh.positions.len(), 13);
//! assert_eq!(imported.mesh.triangles.len(), 16);
//! assert_eq!(imported.mesh.furry_triangles(), 16);
//! assert_eq!(imported.input_sha256.len(), 64);
//! # Ok::<(), furbake_import::ImportError>(())
//! ```

#![deny(missing_docs)]
mod accessor;
mod animation;
mod base64;
mod error;
mod external;
pub mod limits;
mod scene;
mod settings;
mod source;
#[doc(hidden)]
pub mod testmesh;
mod texture;
mod weld;

use std::path::{Path, PathBuf};

pub use animation::ImportedAnimation;
pub use error::{AnimationRef, ImportError, PrimitiveRef};
pub use external::{ExternalRef, UriProblem};
pub use furbake_formats::sections::skin_mesh::{SkinMesh, SkinMeshStats};
pub use settings::{ColorChannel, FurMaskSource, ImportSettings, InvalidImportSetting, WeldTolerance};

/// The result of an import: the skin and what the bake manifest records about its input.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportedMesh {
    /// The welded, triangulated skin.
    pub mesh: SkinMesh,
    /// Bytes read: the main file, every external buffer file (its first `byteLength` bytes, all
    /// that is read of it) and every external image file sampled for colour (embedded `data:`
    /// buffers and GLB images are part of the main file).
    pub input_bytes: u64,
    /// Lowercase hex SHA-256 over the main file's bytes, then each external buffer file's first
    /// `byteLength` bytes in buffer order, then each external base-colour image file sampled, in
    /// first-use order.
    pub input_sha256: String,
    /// Non-fatal findings, each prefixed with the file name: skipped point/line primitives,
    /// ignored influences or animation channels, fur-mask fallbacks, dropped vertices.
    pub warnings: Vec<String>,
    /// The skeleton, skin weights, morph targets and clips (all `None` for a static file).
    pub animation: ImportedAnimation,
    /// Every file the import read, in the order [`ImportedMesh::input_sha256`] hashes them: the
    /// glTF itself, its external buffers, the external images it sampled. What a depfile lists
    /// and what the bake manifest records (by name relative to the glTF, never an absolute path).
    pub inputs: Vec<InputFile>,
}

/// One file an import read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputFile {
    /// Where it was read: the glTF's path as the caller gave it, or the glTF's directory (as
    /// given) joined with [`InputFile::name`] — a path a build system run from the caller's
    /// directory can stat. Empty for in-memory input.
    pub path: PathBuf,
    /// Its name relative to the glTF's directory, `/`-separated (`textures/fur.png`,
    /// `../common/body.bin` under an asset root); the glTF itself by its file name.
    pub name: String,
    /// Bytes read from it (a buffer file: its declared `byteLength`).
    pub bytes: u64,
    /// Lowercase hex SHA-256 of those bytes.
    pub sha256: String,
}

impl InputFile {
    fn new(path: PathBuf, name: String, data: &[u8]) -> InputFile {
        let sha256 = sha2::Digest::finalize(<sha2::Sha256 as sha2::Digest>::new_with_prefix(data));
        InputFile { path, name, bytes: data.len() as u64, sha256: sha256.iter().map(|b| format!("{b:02x}")).collect() }
    }

    /// An external file `name` (relative to `base_dir`, the glTF's directory as given).
    pub(crate) fn external(base_dir: Option<&Path>, name: String, data: &[u8]) -> InputFile {
        let path = base_dir.map(|d| d.join(&name)).unwrap_or_default();
        InputFile::new(path, name, data)
    }
}

/// Imports the glTF file at `path` (`.glb` or `.gltf`). External buffers and images are
/// resolved relative to the file's directory and must lie inside it (symlinks followed); see
/// [`import_gltf_with_asset_root`] to allow a wider directory.
pub fn import_gltf(path: &Path, settings: &ImportSettings) -> Result<ImportedMesh, ImportError> {
    import_file(path, None, settings)
}

/// Imports the glTF file at `path`, reading external buffers and images from inside its own
/// directory *or* inside `asset_root` (for pipelines that keep textures in shared folders, e.g.
/// `../textures/fur.png` with `asset_root` the folder above both). URIs are still resolved relative
/// to the glTF's directory. `asset_root` must be an existing directory
/// ([`ImportError::AssetRoot`] otherwise, checked before the file is read).
pub fn import_gltf_with_asset_root(
    path: &Path,
    asset_root: &Path,
    settings: &ImportSettings,
) -> Result<ImportedMesh, ImportError> {
    let refuse =
        |message: String| ImportError::AssetRoot { file: path.to_path_buf(), root: asset_root.to_path_buf(), message };
    match std::fs::metadata(asset_root) {
        Ok(m) if m.is_dir() => import_file(path, Some(asset_root), settings),
        Ok(_) => Err(refuse("is not a directory".to_owned())),
        Err(e) => Err(refuse(e.to_string())),
    }
}

fn import_file(path: &Path, extra_root: Option<&Path>, settings: &ImportSettings) -> Result<ImportedMesh, ImportError> {
    let bytes = source::read_file_limited(path, path)?;
    let base_dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    let real_dir = std::fs::symlink_metadata(path)
        .is_ok_and(|m| m.file_type().is_symlink())
        .then(|| std::fs::canonicalize(path).ok()?.parent().map(Path::to_path_buf))
        .flatten();
    let files = external::ExternalFiles {
        base_dir: Some(base_dir),
        extra_root,
        real_dir: real_dir.as_deref(),
        strict: settings.strict_inputs,
    };
    import(&bytes, path, true, files, settings)
}

/// The external files (buffers and images) the glTF at `path` names, joined to its directory,
/// read from its JSON alone: nothing they name is opened, nothing else is validated, and a file
/// that cannot be read or parsed names none (its import then says why). `furbake batch` adds
/// them to its plan's inputs, so no asset's output can be another asset's buffer or texture.
pub fn referenced_files(path: &Path) -> Vec<PathBuf> {
    source::referenced_files(path)
}

/// Opens the input file `name` as a pack's manifest records it (relative to the glTF's
/// directory `gltf_dir`, `/`-separated) under exactly the rules the import reads external files
/// by (see `external.rs`): it must resolve inside `gltf_dir` or `asset_root`, symlinks followed,
/// and be a regular file, opened without blocking. Returns the file and its length; a refusal
/// says why. `furbake batch` re-reads recorded inputs through this to decide whether a pack is up
/// to date, so a planted manifest cannot make it read anything the bake could not.
pub fn open_recorded_input(
    gltf_dir: &Path,
    asset_root: Option<&Path>,
    name: &str,
) -> Result<(std::fs::File, u64), UriProblem> {
    let files =
        external::ExternalFiles { base_dir: Some(gltf_dir), extra_root: asset_root, real_dir: None, strict: true };
    files.open_name(name).map(|(file, len, _)| (file, len))
}

/// Imports glTF bytes held in memory. `name_for_errors` names the input in errors and warnings;
/// `base_dir` resolves external buffer and image URIs, which must lie inside it (`None`: only
/// GLB-embedded or `data:` buffers work).
pub fn import_gltf_slice(
    bytes: &[u8],
    name_for_errors: &str,
    base_dir: Option<&Path>,
    settings: &ImportSettings,
) -> Result<ImportedMesh, ImportError> {
    import(
        bytes,
        Path::new(name_for_errors),
        false,
        external::ExternalFiles { base_dir, extra_root: None, real_dir: None, strict: settings.strict_inputs },
        settings,
    )
}

/// `on_disk`: `file` is the path the bytes were read from (else only a name for messages).
fn import(
    bytes: &[u8],
    file: &Path,
    on_disk: bool,
    external: external::ExternalFiles<'_>,
    settings: &ImportSettings,
) -> Result<ImportedMesh, ImportError> {
    settings.validate().map_err(|e| ImportError::Settings { file: file.to_path_buf(), message: e.to_string() })?;
    let asset = source::load_asset(bytes, file, external)?;
    let mut walker = scene::SceneWalker::new(&asset, file, external, settings);
    walker.walk()?;
    let mut warnings = asset.warnings.clone();
    warnings.append(&mut walker.warnings);
    let welded = weld::weld_soup(&walker.soup, settings.weld_tolerance)
        .map_err(|e| ImportError::NoTriangles { file: file.to_path_buf(), details: e.details })?;
    warnings.extend(welded.warnings.iter().map(|w| format!("{}: {w}", file.display())));
    let soup = &walker.soup;
    let raw = animation::RawRig {
        influences: &soup.influences,
        morph_group: &soup.morph_group,
        morph_at: &soup.morph_at,
        morph_deltas: &soup.morph_deltas,
    };
    let rig = std::mem::replace(&mut walker.rig, animation::Rig::new(&asset.root));
    let (animation, rig_warnings) = rig.finish(&asset, file, &raw, &welded.representatives)?;
    warnings.extend(rig_warnings.into_iter().map(|w| format!("{}: {w}", file.display())));
    if welded.mesh.furry_triangles() == 0 {
        warnings.push(format!("{}: no triangle carries fur under the chosen fur mask", file.display()));
    }
    let mut hasher = asset.input_hasher.clone();
    let mut input_bytes = asset.input_bytes;
    let main_name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let main_path = if on_disk { file.to_path_buf() } else { PathBuf::new() };
    let mut inputs = vec![InputFile::new(main_path, main_name, bytes)];
    inputs.extend(asset.files.iter().cloned());
    for (name, image) in &walker.textures.external {
        sha2::Digest::update(&mut hasher, image);
        input_bytes += image.len() as u64;
        inputs.push(InputFile::external(external.base_dir, name.clone(), image));
    }
    let input_sha256 = sha2::Digest::finalize(hasher).iter().map(|b| format!("{b:02x}")).collect();
    Ok(ImportedMesh { mesh: welded.mesh, input_bytes, input_sha256, warnings, animation, inputs })
}
