//! Typed import errors. Every variant names the input file; errors about mesh data also name the
//! mesh (index and name) and the primitive, so a user can find the bad data in a DCC tool.
//! Split by blame (docs/design.md "Determinism and errors"): I/O, not-glTF, unsupported glTF, bad mesh data, limits and
//! caller mistakes (settings).

use std::fmt;
use std::path::PathBuf;

use crate::external::{ExternalRef, UriProblem};

/// Where in the file a primitive lives: mesh index, mesh name (if any) and primitive index.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PrimitiveRef {
    /// Index of the mesh in the file's `meshes` array.
    pub mesh: usize,
    /// The mesh's `name`, when it has one (boxed to keep [`ImportError`] small).
    pub mesh_name: Option<Box<str>>,
    /// Index of the primitive inside the mesh.
    pub primitive: usize,
}

impl fmt::Display for PrimitiveRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.mesh_name {
            Some(name) => write!(f, "mesh {} \"{}\", primitive {}", self.mesh, name, self.primitive),
            None => write!(f, "mesh {}, primitive {}", self.mesh, self.primitive),
        }
    }
}

/// Where in the file skinning or animation data lives (glTF 2.0 specification, "Skins",
/// "Animations", "Morph Targets").
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AnimationRef {
    /// A skin: index and name.
    Skin {
        /// Index in the file's `skins` array.
        skin: usize,
        /// Its `name`, when it has one.
        name: Option<Box<str>>,
    },
    /// A sampler of an animation.
    Sampler {
        /// Index in the file's `animations` array.
        animation: usize,
        /// The animation's `name`, when it has one.
        name: Option<Box<str>>,
        /// Index of the sampler inside the animation.
        sampler: usize,
    },
    /// A channel of an animation.
    Channel {
        /// Index in the file's `animations` array.
        animation: usize,
        /// The animation's `name`, when it has one.
        name: Option<Box<str>>,
        /// Index of the channel inside the animation.
        channel: usize,
    },
    /// The skin attributes or morph targets of a primitive.
    Primitive(PrimitiveRef),
}

impl fmt::Display for AnimationRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let named = |f: &mut fmt::Formatter<'_>, what: &str, i: usize, name: &Option<Box<str>>| match name {
            Some(n) => write!(f, "{what} {i} \"{n}\""),
            None => write!(f, "{what} {i}"),
        };
        match self {
            AnimationRef::Skin { skin, name } => named(f, "skin", *skin, name),
            AnimationRef::Sampler { animation, name, sampler } => {
                named(f, "animation", *animation, name)?;
                write!(f, ", sampler {sampler}")
            }
            AnimationRef::Channel { animation, name, channel } => {
                named(f, "animation", *animation, name)?;
                write!(f, ", channel {channel}")
            }
            AnimationRef::Primitive(p) => p.fmt(f),
        }
    }
}

/// Everything that can go wrong while importing a glTF file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// The file (or one of its external buffers) could not be found or read.
    #[error("{}: cannot read {}: {source}", file.display(), what.display())]
    Io {
        /// The glTF file being imported.
        file: PathBuf,
        /// The file that could not be read (the glTF itself or an external buffer).
        what: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },

    /// The bytes are not a valid glTF 2.0 asset (bad GLB container, bad JSON, or rejected by the
    /// `gltf` crate's validation, whose message is included).
    #[error("{}: not a valid glTF 2.0 file: {message}", file.display())]
    InvalidGltf {
        /// The glTF file being imported.
        file: PathBuf,
        /// What is wrong, including the `gltf` crate's message where it found the problem.
        message: String,
    },

    /// The file lists an extension in `extensionsRequired` that this importer does not implement.
    #[error(
        "{}: the file requires the glTF extension {extension}, which furbake does not support{hint}",
        file.display()
    )]
    UnsupportedExtension {
        /// The glTF file being imported.
        file: PathBuf,
        /// The extension's name, e.g. `KHR_draco_mesh_compression`.
        extension: String,
        /// A hint on how to convert the file, possibly empty.
        hint: String,
    },

    /// A buffer could not be loaded: missing GLB binary chunk, bad `data:` URI, or shorter than
    /// its declared `byteLength`.
    #[error("{}: buffer {buffer}: {message}", file.display())]
    Buffer {
        /// The glTF file being imported.
        file: PathBuf,
        /// Index of the buffer in the file's `buffers` array.
        buffer: usize,
        /// What is wrong.
        message: String,
    },

    /// An accessor is unusable: wrong type for its attribute, reads past its buffer view, or
    /// its element count disagrees with the primitive's vertex count.
    #[error("{}: {at}: {attribute} (accessor {accessor}): {message}", file.display())]
    Accessor {
        /// The glTF file being imported.
        file: PathBuf,
        /// The primitive that uses the accessor.
        at: PrimitiveRef,
        /// The attribute name (`POSITION`, `indices`, …).
        attribute: String,
        /// Index of the accessor in the file's `accessors` array.
        accessor: usize,
        /// What is wrong.
        message: String,
    },

    /// A triangle primitive has no `POSITION` attribute.
    #[error("{}: {at}: the primitive has no POSITION attribute", file.display())]
    MissingPosition {
        /// The glTF file being imported.
        file: PathBuf,
        /// The offending primitive.
        at: PrimitiveRef,
    },

    /// A float attribute holds NaN or infinity (or a node transform made a position infinite).
    #[error("{}: {at}: {attribute} of vertex {vertex} is not finite ({value:?})", file.display())]
    NonFinite {
        /// The glTF file being imported.
        file: PathBuf,
        /// The offending primitive.
        at: PrimitiveRef,
        /// The attribute name (`POSITION`, `COLOR_0`, …; `POSITION (after node transform)`).
        attribute: String,
        /// Vertex index inside the primitive.
        vertex: usize,
        /// The offending value.
        value: Vec<f32>,
    },

    /// A position (after its node transform) or texture coordinate is finite but larger in
    /// magnitude than a pack stores (`furbake_formats::sections::MAX_COORDINATE_M`).
    #[error("{}: {at}: {attribute} of vertex {vertex} is {value:?}, beyond the ±{limit:e} a pack stores", file.display())]
    OutOfRange {
        /// The glTF file being imported.
        file: PathBuf,
        /// The offending primitive.
        at: PrimitiveRef,
        /// The attribute name (`TEXCOORD_0`, `POSITION (after node transform)`).
        attribute: String,
        /// Vertex index inside the primitive.
        vertex: usize,
        /// The offending value.
        value: Vec<f32>,
        /// The largest magnitude accepted.
        limit: f32,
    },

    /// An index points past the end of the primitive's vertices.
    #[error(
        "{}: {at}: index {position} is {index}, but the primitive has only {vertex_count} vertices",
        file.display()
    )]
    IndexOutOfRange {
        /// The glTF file being imported.
        file: PathBuf,
        /// The offending primitive.
        at: PrimitiveRef,
        /// Position of the index in the index list.
        position: usize,
        /// The index value.
        index: u32,
        /// Number of vertices in the primitive.
        vertex_count: usize,
    },

    /// A triangle primitive has fewer than three vertices/indices, so it makes no triangle.
    #[error("{}: {at}: the primitive makes no triangle ({elements} indices/vertices)", file.display())]
    PrimitiveWithoutTriangles {
        /// The glTF file being imported.
        file: PathBuf,
        /// The offending primitive.
        at: PrimitiveRef,
        /// How many indices (or vertices, when unindexed) it has.
        elements: usize,
    },

    /// The scene yields no usable (non-degenerate) triangle at all.
    #[error("{}: the scene has no usable triangles ({details})", file.display())]
    NoTriangles {
        /// The glTF file being imported.
        file: PathBuf,
        /// What was found instead (primitives, skipped primitives, degenerate triangles).
        details: String,
    },

    /// The node hierarchy is broken: a cycle, or a node transform that is not finite.
    #[error("{}: node {node}: {message}", file.display())]
    Scene {
        /// The glTF file being imported.
        file: PathBuf,
        /// Index of the offending node.
        node: usize,
        /// What is wrong.
        message: String,
    },

    /// An external file named by a buffer or image URI was refused (an escape from the asset
    /// roots, an absolute path, a scheme, a bad escape, a FIFO, device or directory, a buffer
    /// file shorter than its `byteLength`, …) or could not be read. Names the URI as written.
    #[error("{}: {referrer} uri {uri:?}: {problem}", file.display())]
    ExternalFile {
        /// The glTF file being imported.
        file: PathBuf,
        /// The buffer or image whose URI it is.
        referrer: ExternalRef,
        /// The URI exactly as the file writes it.
        uri: Box<str>,
        /// What is wrong (boxed to keep [`ImportError`] small).
        problem: Box<UriProblem>,
    },

    /// The asset root the caller named (`--asset-root`) is not an existing directory. Blame:
    /// the caller.
    #[error("{}: asset root {}: {message}", file.display(), root.display())]
    AssetRoot {
        /// The glTF file being imported.
        file: PathBuf,
        /// The asset root as given.
        root: PathBuf,
        /// What is wrong.
        message: String,
    },

    /// A size is beyond what furbake accepts (file bytes, accessor elements, vertices, node
    /// instances); this guards against lying headers and allocation bombs.
    #[error("{}: {what} is {count}, more than the limit of {limit}", file.display())]
    TooLarge {
        /// The glTF file being imported.
        file: PathBuf,
        /// What was counted.
        what: String,
        /// The count found.
        count: u64,
        /// The limit.
        limit: u64,
    },

    /// Skin, morph-target or animation data is unusable: a joint index out of range, weights that
    /// are NaN or sum to 0, a non-invertible inverse bind matrix, a sampler whose input and
    /// output counts disagree or whose key times do not increase, … The message names the index
    /// (joint, vertex, key) concerned.
    #[error("{}: {at}: {message}", file.display())]
    Animation {
        /// The glTF file being imported.
        file: PathBuf,
        /// The skin, sampler, channel or primitive (boxed to keep [`ImportError`] small).
        at: Box<AnimationRef>,
        /// What is wrong, with the offending index.
        message: String,
    },

    /// The fur-mask source cannot be applied to this file (e.g. the named attribute exists in
    /// no primitive).
    #[error("{}: fur mask: {message}", file.display())]
    FurMask {
        /// The glTF file being imported.
        file: PathBuf,
        /// What is wrong.
        message: String,
    },

    /// The caller's [`ImportSettings`](crate::ImportSettings) are invalid (negative or NaN
    /// tolerance, threshold outside `[0, 1]`, …).
    #[error("{}: invalid import settings: {message}", file.display())]
    Settings {
        /// The glTF file being imported.
        file: PathBuf,
        /// What is wrong.
        message: String,
    },
}

impl ImportError {
    /// The glTF file the error is about.
    pub fn file(&self) -> &std::path::Path {
        match self {
            ImportError::Io { file, .. }
            | ImportError::InvalidGltf { file, .. }
            | ImportError::UnsupportedExtension { file, .. }
            | ImportError::Buffer { file, .. }
            | ImportError::Accessor { file, .. }
            | ImportError::MissingPosition { file, .. }
            | ImportError::NonFinite { file, .. }
            | ImportError::OutOfRange { file, .. }
            | ImportError::IndexOutOfRange { file, .. }
            | ImportError::PrimitiveWithoutTriangles { file, .. }
            | ImportError::NoTriangles { file, .. }
            | ImportError::Scene { file, .. }
            | ImportError::ExternalFile { file, .. }
            | ImportError::AssetRoot { file, .. }
            | ImportError::TooLarge { file, .. }
            | ImportError::FurMask { file, .. }
            | ImportError::Animation { file, .. }
            | ImportError::Settings { file, .. } => file,
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_error_stays_small_enough_to_return_by_value() {
        // clippy's `result_large_err` fires at 128 bytes, in every caller's crate.
        assert!(std::mem::size_of::<super::ImportError>() < 128, "{}", std::mem::size_of::<super::ImportError>());
    }
}
