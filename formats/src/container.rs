//! The container: a 64-byte header, a section table, and 16-byte-aligned sections, all
//! little-endian (layout in `docs/format.md`). [`PackWriter`] assembles one and writes it
//! atomically (`atomic.rs`); the header and table parsers here are the only code that
//! reads the container's layout, and [`crate::Pack`] (the one reader) builds on them.
//!
//! Validation happens here, once, with checked arithmetic: after the table parses, every section
//! offset and length is inside the file; the reader checks a section's CRC-32 before handing its
//! bytes to a decoder, so section decoders can trust the bounds of the bytes they are handed.

use std::path::Path;

use crate::SectionKind;
use crate::error::{FormatError, Result};

/// The eight magic bytes every container starts with.
pub const MAGIC: [u8; 8] = *b"FURBAKE\x1a";
/// Major format version written by this crate; readers reject other majors.
pub const VERSION_MAJOR: u16 = 1;
/// Minor format version written by this crate; readers accept any minor of their major.
pub const VERSION_MINOR: u16 = 0;
/// Size of the fixed header in bytes.
pub const HEADER_SIZE: usize = 64;
/// Size of one section-table entry in bytes.
pub const TABLE_ENTRY_SIZE: usize = 32;
/// Alignment of every section (and of every array inside a record section), in bytes.
pub const ALIGN: usize = 16;
/// Largest number of sections a reader accepts.
pub const MAX_SECTIONS: u32 = 65_536;

/// One row of the section table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SectionEntry {
    /// What the section holds.
    pub kind: SectionKind,
    /// Layout version of the payload for its kind.
    pub version: u16,
    /// Reserved flags (written as 0).
    pub flags: u16,
    /// Byte offset of the payload from the start of the file (a multiple of [`ALIGN`]).
    pub offset: u64,
    /// Payload length in bytes.
    pub length: u64,
    /// CRC-32 (IEEE 802.3, as zlib) of the payload bytes.
    pub crc32: u32,
}

/// A byte buffer whose start is 16-byte aligned, so that arrays inside it can be viewed as
/// `&[f32]`, `&[u32]`, ... without copying.
#[derive(Clone, Default)]
pub struct AlignedBytes {
    blocks: Vec<Block>,
    len: usize,
}

#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(16))]
struct Block([u8; 16]);

impl AlignedBytes {
    /// A zeroed buffer of `len` bytes.
    pub fn zeroed(len: usize) -> Self {
        AlignedBytes { blocks: vec![Block::default(); len.div_ceil(16)], len }
    }

    /// Copies `bytes` into a fresh aligned buffer.
    pub fn copy_from(bytes: &[u8]) -> Self {
        let mut b = Self::zeroed(bytes.len());
        b.as_mut_slice().copy_from_slice(bytes);
        b
    }

    /// The bytes.
    pub fn as_slice(&self) -> &[u8] {
        &bytemuck::cast_slice::<Block, u8>(&self.blocks)[..self.len]
    }

    /// The bytes, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [u8] {
        let len = self.len;
        &mut bytemuck::cast_slice_mut::<Block, u8>(&mut self.blocks)[..len]
    }
}

impl std::ops::Deref for AlignedBytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        self.as_slice()
    }
}

impl std::fmt::Debug for AlignedBytes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "AlignedBytes({} bytes)", self.len)
    }
}

/// Assembles a container section by section, then writes it atomically.
#[derive(Default)]
pub struct PackWriter {
    sections: Vec<(SectionKind, u16, Vec<u8>)>,
}

impl PackWriter {
    /// An empty container.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a section with payload layout `version`.
    pub fn push(&mut self, kind: SectionKind, version: u16, payload: Vec<u8>) -> &mut Self {
        self.sections.push((kind, version, payload));
        self
    }

    /// Number of sections added so far.
    pub fn len(&self) -> usize {
        self.sections.len()
    }

    /// True when no section was added.
    pub fn is_empty(&self) -> bool {
        self.sections.is_empty()
    }

    /// Kind, layout version and payload size in bytes of each section, in file order.
    pub fn sections(&self) -> impl Iterator<Item = (SectionKind, u16, usize)> + '_ {
        self.sections.iter().map(|(kind, version, payload)| (*kind, *version, payload.len()))
    }

    /// The complete file image.
    pub fn to_bytes(&self) -> Vec<u8> {
        let count = self.sections.len();
        let table_end = HEADER_SIZE + count * TABLE_ENTRY_SIZE;
        let mut offsets = Vec::with_capacity(count);
        let mut cursor = align_up(table_end);
        for (_, _, payload) in &self.sections {
            offsets.push(cursor);
            cursor = align_up(cursor + payload.len());
        }
        let file_size = cursor;
        let mut out = vec![0u8; file_size];
        let mut table = Vec::with_capacity(count * TABLE_ENTRY_SIZE);
        for ((kind, version, payload), &off) in self.sections.iter().zip(&offsets) {
            out[off..off + payload.len()].copy_from_slice(payload);
            table.extend_from_slice(&kind.0.to_le_bytes());
            table.extend_from_slice(&version.to_le_bytes());
            table.extend_from_slice(&0u16.to_le_bytes());
            table.extend_from_slice(&(off as u64).to_le_bytes());
            table.extend_from_slice(&(payload.len() as u64).to_le_bytes());
            table.extend_from_slice(&crc32fast::hash(payload).to_le_bytes());
            table.extend_from_slice(&0u32.to_le_bytes());
        }
        out[HEADER_SIZE..table_end].copy_from_slice(&table);
        let h = &mut out[..HEADER_SIZE];
        h[0..8].copy_from_slice(&MAGIC);
        h[8..10].copy_from_slice(&VERSION_MAJOR.to_le_bytes());
        h[10..12].copy_from_slice(&VERSION_MINOR.to_le_bytes());
        h[12..16].copy_from_slice(&(HEADER_SIZE as u32).to_le_bytes());
        h[16..20].copy_from_slice(&(count as u32).to_le_bytes());
        h[24..32].copy_from_slice(&(HEADER_SIZE as u64).to_le_bytes());
        h[32..40].copy_from_slice(&(file_size as u64).to_le_bytes());
        h[40..44].copy_from_slice(&crc32fast::hash(&table).to_le_bytes());
        let header_crc = crc32fast::hash(&h[..44]);
        h[44..48].copy_from_slice(&header_crc.to_le_bytes());
        out
    }

    /// Writes the container to `path` with [`crate::write_file_atomic`]: a crash or error never
    /// leaves a half-written `path`, nor (on Linux) a temporary file.
    pub fn write_atomic(&self, path: &Path) -> Result<()> {
        crate::atomic::write_file_atomic(path, &self.to_bytes())
    }
}

fn align_up(x: usize) -> usize {
    x.div_ceil(ALIGN) * ALIGN
}

fn le_u16(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4-byte slice"))
}
fn le_u64(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8-byte slice"))
}

/// The validated header fields that readers need.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Header {
    pub(crate) minor: u16,
    pub(crate) section_count: u32,
    pub(crate) table_offset: u64,
    file_size: u64,
    table_crc: u32,
}

pub(crate) fn parse_header(h: &[u8], actual_len: u64) -> Result<Header> {
    if h.len() < HEADER_SIZE {
        return Err(FormatError::invalid(format!(
            "file is {} bytes, shorter than the {HEADER_SIZE}-byte header",
            h.len()
        )));
    }
    if h[0..8] != MAGIC {
        return Err(FormatError::invalid_at(0, "wrong magic: not a furbake container"));
    }
    let major = le_u16(h, 8);
    let minor = le_u16(h, 10);
    if major != VERSION_MAJOR {
        return Err(FormatError::UnsupportedVersion { path: None, major, minor, supported: VERSION_MAJOR });
    }
    let stored_crc = le_u32(h, 44);
    if crc32fast::hash(&h[..44]) != stored_crc {
        return Err(FormatError::invalid_at(44, "header checksum mismatch"));
    }
    let header_size = le_u32(h, 12);
    if header_size as usize != HEADER_SIZE {
        return Err(FormatError::invalid_at(12, format!("header size {header_size}, expected {HEADER_SIZE}")));
    }
    let section_count = le_u32(h, 16);
    if section_count > MAX_SECTIONS {
        return Err(FormatError::Limit {
            path: None,
            what: "section count",
            value: section_count as u64,
            limit: MAX_SECTIONS as u64,
        });
    }
    let table_offset = le_u64(h, 24);
    let file_size = le_u64(h, 32);
    if file_size != actual_len {
        return Err(FormatError::invalid_at(
            32,
            format!("header says the file is {file_size} bytes but it is {actual_len} (truncated or padded)"),
        ));
    }
    let table_len = section_count as u64 * TABLE_ENTRY_SIZE as u64;
    match table_offset.checked_add(table_len) {
        Some(end) if table_offset >= HEADER_SIZE as u64 && end <= actual_len => {}
        _ => {
            return Err(FormatError::invalid_at(
                24,
                format!("section table ({section_count} entries at byte {table_offset}) lies outside the file"),
            ));
        }
    }
    Ok(Header { minor, section_count, table_offset, file_size, table_crc: le_u32(h, 40) })
}

pub(crate) fn parse_table(table: &[u8], header: &Header) -> Result<Vec<SectionEntry>> {
    if crc32fast::hash(table) != header.table_crc {
        return Err(FormatError::invalid_at(header.table_offset, "section table checksum mismatch"));
    }
    let table_end = header.table_offset + table.len() as u64;
    let mut entries = Vec::with_capacity(header.section_count as usize);
    for (i, row) in table.chunks_exact(TABLE_ENTRY_SIZE).enumerate() {
        let at = header.table_offset + (i * TABLE_ENTRY_SIZE) as u64;
        let e = SectionEntry {
            kind: SectionKind(le_u32(row, 0)),
            version: le_u16(row, 4),
            flags: le_u16(row, 6),
            offset: le_u64(row, 8),
            length: le_u64(row, 16),
            crc32: le_u32(row, 24),
        };
        let bad = |what: String| Err(FormatError::Invalid { path: None, section: Some(i), offset: Some(at), what });
        if !e.offset.is_multiple_of(ALIGN as u64) {
            return bad(format!("section offset {} is not {ALIGN}-byte aligned", e.offset));
        }
        match e.offset.checked_add(e.length) {
            Some(end) if e.offset >= table_end && end <= header.file_size => {}
            _ => return bad(format!("section bytes {}+{} lie outside the file", e.offset, e.length)),
        }
        entries.push(e);
    }
    // Sections must not overlap one another.
    let mut spans: Vec<(u64, u64, usize)> = entries.iter().enumerate().map(|(i, e)| (e.offset, e.length, i)).collect();
    spans.sort_unstable();
    for w in spans.windows(2) {
        let (o0, l0, _) = w[0];
        let (o1, _, i1) = w[1];
        if o0 + l0 > o1 {
            return Err(FormatError::Invalid {
                path: None,
                section: Some(i1),
                offset: Some(header.table_offset + (i1 * TABLE_ENTRY_SIZE) as u64),
                what: "section overlaps the previous one".into(),
            });
        }
    }
    Ok(entries)
}

pub(crate) fn check_section_crc(index: usize, e: &SectionEntry, payload: &[u8]) -> Result<()> {
    if crc32fast::hash(payload) != e.crc32 {
        return Err(FormatError::Invalid {
            path: None,
            section: Some(index),
            offset: Some(e.offset),
            what: format!("section {index} ({}) checksum mismatch", e.kind),
        });
    }
    Ok(())
}
