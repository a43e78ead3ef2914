//! furbake-formats: the one container format every furbake artifact is stored in, and the typed
//! sections inside it. Nothing else: no baking, no rendering, no CLI.
//!
//! A container is a 64-byte header, a section table (kind, layout version, offset, length,
//! CRC-32 per section) and 16-byte-aligned, little-endian sections; `docs/format.md` specifies
//! every byte. A *pack* holds all artifacts of one asset; a single-artifact file is the same
//! container with one section. Readers validate magic, version, bounds, checksums and counts
//! before they allocate or trust anything, and return [`FormatError`]s; writers go through an
//! unnamed (Linux `O_TMPFILE`) or temporary file and a rename (`atomic.rs`).
//!
//! ```
//! use furbake_formats::{Pack, PackWriter, Section, sections::fin_atlas::FinAtlas};
//!
//! let fins = FinAtlas { width: 4, height: 2, slices: 20, alpha: vec![0, 255, 0, 9, 1, 2, 3, 4] };
//! let mut writer = PackWriter::new();
//! writer.push(FinAtlas::KIND, FinAtlas::VERSION, fins.encode());
//! let bytes = writer.to_bytes();
//!
//! let pack = Pack::from_bytes(&bytes)?;
//! let back: FinAtlas = pack.decode_first()?;
//! assert_eq!(back, fins);
//! # Ok::<(), furbake_formats::FormatError>(())
//! ```

#![deny(missing_docs)]
mod atomic;
mod consistency;
mod container;
mod error;
pub mod input;
mod kind;
mod pack;
pub mod record;
#[cfg(feature = "schema")]
pub mod schema;
pub mod sections;
mod verify;

pub use atomic::{write_file_atomic, write_file_atomic_from};
pub use consistency::{PackSections, check_consistency};
pub use container::{
    ALIGN, AlignedBytes, HEADER_SIZE, MAGIC, MAX_SECTIONS, PackWriter, SectionEntry, TABLE_ENTRY_SIZE, VERSION_MAJOR,
    VERSION_MINOR,
};
pub use error::{FormatError, OutOfRange, Result};
pub use kind::SectionKind;
pub use pack::{Pack, Payload};
pub use sections::Section;
pub use verify::{DecodedSections, VerifySummary};

/// Decodes a payload as section type `S` after checking the entry's kind and layout version.
pub fn decode_section<S: Section>(index: usize, entry: &SectionEntry, payload: &[u8]) -> Result<S> {
    if entry.kind != S::KIND {
        return Err(FormatError::Parameter {
            path: None,
            what: format!("section {index} is {}, not {}", entry.kind, S::KIND),
        });
    }
    if entry.version == 0 || entry.version > S::VERSION {
        return Err(FormatError::UnsupportedSectionVersion {
            path: None,
            index,
            kind: entry.kind,
            version: entry.version,
            supported: S::VERSION,
        });
    }
    S::decode(payload).map_err(|e| e.in_section(index, entry.offset))
}

impl PackWriter {
    /// Appends a typed section.
    pub fn push_section<S: Section>(&mut self, section: &S) -> &mut Self {
        self.push(S::KIND, S::VERSION, section.encode())
    }
}
