//! Typed errors of the container crate, split by who is to blame: the file (format), the caller
//! (parameter), a limit, or the operating system (I/O). Every variant names the file where one is
//! known, and the section and byte offset where the problem sits.

use std::path::PathBuf;

use crate::SectionKind;

/// What went wrong while reading or writing a furbake container.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// The bytes do not form a valid container or section (wrong magic, bad checksum, bounds
    /// outside the file, a count that does not match the payload, ...). Blame: the file.
    #[error("{path}: invalid container: {what}{at}", path = display_path(path), at = display_at(*section, *offset))]
    Invalid {
        /// File the bytes came from, when known.
        path: Option<PathBuf>,
        /// Index of the section in the section table, when the problem is inside one.
        section: Option<usize>,
        /// Byte offset (from the start of the file) of the offending field, when known.
        offset: Option<u64>,
        /// Human description of the problem.
        what: String,
    },
    /// The file was written by a newer, incompatible major version of the format.
    #[error("{path}: unsupported format version {major}.{minor} (this reader understands {supported}.x)", path = display_path(path))]
    UnsupportedVersion {
        /// File the bytes came from, when known.
        path: Option<PathBuf>,
        /// Major version stored in the file.
        major: u16,
        /// Minor version stored in the file.
        minor: u16,
        /// Major version this reader understands.
        supported: u16,
    },
    /// A section of a known kind uses a payload layout version this reader does not know.
    #[error("{path}: section {index} ({kind}) has layout version {version}, this reader understands up to {supported}", path = display_path(path))]
    UnsupportedSectionVersion {
        /// File the bytes came from, when known.
        path: Option<PathBuf>,
        /// Index of the section in the section table.
        index: usize,
        /// Kind of the section.
        kind: SectionKind,
        /// Layout version stored in the file.
        version: u16,
        /// Newest layout version this reader understands.
        supported: u16,
    },
    /// The caller asked for something the container cannot hold or does not have (e.g. a section
    /// kind that is not in the pack). Blame: the caller.
    #[error("{path}: {what}", path = display_path(path))]
    Parameter {
        /// File concerned, when known.
        path: Option<PathBuf>,
        /// Human description of the problem.
        what: String,
    },
    /// The pack has no section of a kind the caller needs (e.g. rendering a pack baked without
    /// shells). Blame: the file, for the use it is put to.
    #[error("{path}: the pack has no {kind} section", path = display_path(path))]
    MissingSection {
        /// File concerned, when known.
        path: Option<PathBuf>,
        /// The kind asked for.
        kind: SectionKind,
    },
    /// A count or size in the file exceeds the limits this reader accepts.
    #[error("{path}: {what} is {value}, above the limit of {limit}", path = display_path(path))]
    Limit {
        /// File the bytes came from, when known.
        path: Option<PathBuf>,
        /// What was counted.
        what: &'static str,
        /// The value found.
        value: u64,
        /// The largest value accepted.
        limit: u64,
    },
    /// The operating system refused a read, write or rename.
    #[error("{path}: {source}", path = path.display())]
    Io {
        /// File concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// A parameter the caller chose for a new artifact is outside the range this crate accepts
/// (e.g. [`TopologyParams::check_ranges`](crate::sections::spring_topology::TopologyParams::check_ranges)).
/// Blame: the caller. `field` is the parameter's name inside its struct; callers that know where
/// the struct sits in a larger plan prefix it (`topology.stiffness_n_per_m`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{field} = {value} is out of range (allowed: {allowed})")]
pub struct OutOfRange {
    /// Name of the parameter.
    pub field: &'static str,
    /// The value given, as text.
    pub value: String,
    /// The allowed range, e.g. `[0, 1e9]`.
    pub allowed: String,
}

fn display_path(path: &Option<PathBuf>) -> String {
    match path {
        Some(p) => p.display().to_string(),
        None => "<memory>".to_owned(),
    }
}

fn display_at(section: Option<usize>, offset: Option<u64>) -> String {
    match (section, offset) {
        (Some(s), Some(o)) => format!(" (section {s}, byte {o})"),
        (Some(s), None) => format!(" (section {s})"),
        (None, Some(o)) => format!(" (byte {o})"),
        (None, None) => String::new(),
    }
}

impl FormatError {
    /// Shorthand for [`FormatError::Invalid`] without a path (added later with [`Self::with_path`]).
    pub fn invalid(what: impl Into<String>) -> Self {
        FormatError::Invalid { path: None, section: None, offset: None, what: what.into() }
    }

    /// Shorthand for [`FormatError::Invalid`] at a byte offset.
    pub fn invalid_at(offset: u64, what: impl Into<String>) -> Self {
        FormatError::Invalid { path: None, section: None, offset: Some(offset), what: what.into() }
    }

    /// Attaches the file path to an error that does not carry one yet.
    pub fn with_path(mut self, p: &std::path::Path) -> Self {
        match &mut self {
            FormatError::Invalid { path, .. }
            | FormatError::UnsupportedVersion { path, .. }
            | FormatError::UnsupportedSectionVersion { path, .. }
            | FormatError::Parameter { path, .. }
            | FormatError::MissingSection { path, .. }
            | FormatError::Limit { path, .. } => {
                if path.is_none() {
                    *path = Some(p.to_path_buf());
                }
            }
            FormatError::Io { .. } => {}
        }
        self
    }

    /// Attaches the section index (and shifts a section-relative offset to a file offset).
    pub fn in_section(mut self, index: usize, section_offset: u64) -> Self {
        if let FormatError::Invalid { section, offset, .. } = &mut self {
            if section.is_none() {
                *section = Some(index);
                *offset = offset.map(|o| o + section_offset);
            }
        }
        self
    }

    /// True when the file itself is to blame (invalid, unsupported version).
    pub fn is_bad_file(&self) -> bool {
        matches!(
            self,
            FormatError::Invalid { .. }
                | FormatError::UnsupportedVersion { .. }
                | FormatError::UnsupportedSectionVersion { .. }
                | FormatError::Limit { .. }
        )
    }
}

/// Result alias of this crate.
pub type Result<T, E = FormatError> = std::result::Result<T, E>;
