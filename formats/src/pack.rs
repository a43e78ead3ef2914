//! [`Pack`]: the one reader of a furbake container, for every user — `verify` and `inspect`,
//! the runtime (docs/design.md "Runtime: packs": load only the sections a scene needs), renderers and tests.
//!
//! A pack comes from one of two sources:
//! - [`Pack::open`] validates a file's header and section table only; each section is read from
//!   disk and checksummed the first time it is asked for (positioned reads: no shared cursor, so
//!   concurrent first reads of different sections do not serialise on a seek);
//! - [`Pack::from_bytes`] / [`Pack::read`] hold the whole container in memory and validate every
//!   checksum up front (what `verify` wants, and what a fuzzer feeds).
//!
//! Typed access has two forms: [`Pack::decode`] decodes a section into a fresh value (nothing
//! kept), and [`Pack::section`] (with the named shortcuts [`Pack::skin_mesh`], …) decodes it once
//! and shares it as an `Arc`, so a world and a renderer holding the same `Pack` decode each
//! section once. A per-section read counter ([`Pack::read_counts`]) records what was touched, so
//! tests can prove that a scene which does not declare an effect never reads the sections only
//! that effect needs.
//!
//! Spring topologies (fur thesis §3.4.1) are the one kind a pack holds several of; the runtime
//! needs exactly one. [`Pack::topology_kinds`] learns each one's [`TopologyKind`] from the first
//! bytes of its record metadata ([`crate::record::meta_span`],
//! [`SpringTopology::kind_from_meta_prefix`]) without reading the section, so
//! [`Pack::spring_topology`] reads and decodes only the section it picks.

use std::any::Any;
use std::collections::HashMap;
use std::fs::File;
use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use crate::container::{
    AlignedBytes, HEADER_SIZE, SectionEntry, TABLE_ENTRY_SIZE, check_section_crc, parse_header, parse_table,
};
use crate::error::{FormatError, Result};
use crate::sections::animation_clips::AnimationClips;
use crate::sections::blade_field::BladeField;
use crate::sections::fin_atlas::FinAtlas;
use crate::sections::fin_edges::FinEdges;
use crate::sections::keyframe_table::KeyframeTable;
use crate::sections::manifest::BakeManifest;
use crate::sections::morph_targets::MorphTargets;
use crate::sections::shell_atlas::ShellAtlas;
use crate::sections::skeleton::Skeleton;
use crate::sections::skin_mesh::SkinMesh;
use crate::sections::skin_weights::SkinWeights;
use crate::sections::spring_topology::{SpringTopology, TopologyKind};
use crate::sections::triangle_uv_map::TriangleUvMap;
use crate::{Section, SectionKind, decode_section};

type Cached = Arc<dyn Any + Send + Sync>;

/// Where the container's bytes live.
enum Source {
    /// The whole container, every checksum verified.
    Memory(AlignedBytes),
    /// A file whose header and table were validated; sections are read on demand.
    File(File),
}

/// A furbake container opened for reading (see the module doc). `Send + Sync`.
pub struct Pack {
    path: Option<PathBuf>,
    minor: u16,
    file_size: u64,
    entries: Vec<SectionEntry>,
    source: Source,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    /// Shared decoded sections by table index.
    decoded: HashMap<usize, Cached>,
    /// How many times each table entry's payload was read (or, in memory, handed out).
    reads: Vec<u32>,
    /// The topology kind of every spring-topology entry, once peeked.
    topology_kinds: Option<Vec<(usize, TopologyKind)>>,
    /// Bytes read by metadata peeks (not section reads).
    peeked_bytes: u64,
}

/// A section's payload: borrowed from a pack held in memory, or read from disk.
pub enum Payload<'a> {
    /// Part of the in-memory container.
    Borrowed(&'a [u8]),
    /// Read from the file (16-byte aligned).
    Owned(AlignedBytes),
}

impl Deref for Payload<'_> {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            Payload::Borrowed(b) => b,
            Payload::Owned(b) => b,
        }
    }
}

impl std::fmt::Debug for Pack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pack")
            .field("path", &self.path)
            .field("sections", &self.entries.len())
            .field("in_memory", &matches!(self.source, Source::Memory(_)))
            .finish()
    }
}

impl Pack {
    /// Opens the container at `path`, validating only its header and section table (no section
    /// is read). Errors carry the path.
    pub fn open(path: impl AsRef<Path>) -> Result<Pack> {
        let path = path.as_ref();
        let io = |source| FormatError::Io { path: path.to_path_buf(), source };
        // Never blocks (a FIFO is refused at once), and only a regular file's length is real.
        let (file, len) = crate::input::open_regular(path).map_err(io)?;
        let mut head = [0u8; HEADER_SIZE];
        let got = read_up_to_at(&file, 0, &mut head).map_err(io)?;
        let header = parse_header(&head[..got], len).map_err(|e| e.with_path(path))?;
        // Bounded by the real file length (checked in parse_header), so no lying-header allocation.
        let mut table = vec![0u8; header.section_count as usize * TABLE_ENTRY_SIZE];
        read_exact_at(&file, header.table_offset, &mut table).map_err(io)?;
        let entries = parse_table(&table, &header).map_err(|e| e.with_path(path))?;
        Ok(Pack::assemble(Some(path.to_path_buf()), header.minor, len, entries, Source::File(file)))
    }

    /// Validates `bytes` as a container — header, table, bounds and every checksum — copying them
    /// once into an aligned buffer.
    pub fn from_bytes(bytes: &[u8]) -> Result<Pack> {
        let header = parse_header(bytes, bytes.len() as u64)?;
        let t0 = header.table_offset as usize;
        let t1 = t0 + header.section_count as usize * TABLE_ENTRY_SIZE;
        let entries = parse_table(&bytes[t0..t1], &header)?;
        for (i, e) in entries.iter().enumerate() {
            check_section_crc(i, e, &bytes[e.offset as usize..(e.offset + e.length) as usize])?;
        }
        let len = bytes.len() as u64;
        Ok(Pack::assemble(None, header.minor, len, entries, Source::Memory(AlignedBytes::copy_from(bytes))))
    }

    /// [`Pack::from_bytes`] for bytes that came from somewhere with a name (an archive entry, an
    /// engine's asset id): errors and [`Pack::display_path`] carry `name`, and [`Pack::path`]
    /// returns it.
    pub fn from_bytes_named(bytes: &[u8], name: impl Into<PathBuf>) -> Result<Pack> {
        let name = name.into();
        let mut pack = Pack::from_bytes(bytes).map_err(|e| e.with_path(&name))?;
        pack.path = Some(name);
        Ok(pack)
    }

    /// Reads the whole container at `path` into memory and validates it as
    /// [`Pack::from_bytes`] does; errors carry the path. Only a regular file is read, never
    /// blocking; its header (the size it declares) is checked against the file's length before
    /// the body is read, and a container above [`crate::input::MAX_PACK_BYTES`] is refused.
    pub fn read(path: impl AsRef<Path>) -> Result<Pack> {
        let path = path.as_ref();
        let io = |source| FormatError::Io { path: path.to_path_buf(), source };
        let (file, len) = crate::input::open_regular(path).map_err(io)?;
        let mut head = [0u8; HEADER_SIZE];
        let got = read_up_to_at(&file, 0, &mut head).map_err(io)?;
        parse_header(&head[..got], len).map_err(|e| e.with_path(path))?;
        let limit = crate::input::MAX_PACK_BYTES;
        let bytes = crate::input::read_open_bounded(file, len, limit, "a pack read whole").map_err(io)?;
        let mut pack = Pack::from_bytes(&bytes).map_err(|e| e.with_path(path))?;
        pack.path = Some(path.to_path_buf());
        Ok(pack)
    }

    fn assemble(path: Option<PathBuf>, minor: u16, file_size: u64, entries: Vec<SectionEntry>, source: Source) -> Pack {
        let state = State { reads: vec![0; entries.len()], ..State::default() };
        Pack { path, minor, file_size, entries, source, state: Mutex::new(state) }
    }

    /// The path the pack was opened or read from, or the name given to
    /// [`Pack::from_bytes_named`] (`None` for [`Pack::from_bytes`]).
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The path for messages (`<memory>` without one).
    pub fn display_path(&self) -> PathBuf {
        self.path.clone().unwrap_or_else(|| PathBuf::from("<memory>"))
    }

    /// Minor format version stored in the file.
    pub fn minor_version(&self) -> u16 {
        self.minor
    }

    /// Total size of the file in bytes.
    pub fn file_size(&self) -> u64 {
        self.file_size
    }

    /// The section table (validated at open; no payload is touched).
    pub fn sections(&self) -> &[SectionEntry] {
        &self.entries
    }

    /// Indices of the sections of `kind`, in table order.
    pub fn find(&self, kind: SectionKind) -> impl Iterator<Item = usize> + '_ {
        self.entries.iter().enumerate().filter(move |(_, e)| e.kind == kind).map(|(i, _)| i)
    }

    /// True when the pack holds at least one section of `kind`.
    pub fn has(&self, kind: SectionKind) -> bool {
        self.entries.iter().any(|e| e.kind == kind)
    }

    /// The payload of section `index`, checksummed (counts as a read).
    pub fn payload(&self, index: usize) -> Result<Payload<'_>> {
        let e = *self.entry(index)?;
        self.lock().reads[index] += 1;
        match &self.source {
            Source::Memory(bytes) => Ok(Payload::Borrowed(&bytes[e.offset as usize..(e.offset + e.length) as usize])),
            Source::File(file) => {
                let mut buf = AlignedBytes::zeroed(e.length as usize);
                read_exact_at(file, e.offset, buf.as_mut_slice()).map_err(|source| self.io(source))?;
                check_section_crc(index, &e, &buf).map_err(|err| self.with_path(err))?;
                Ok(Payload::Owned(buf))
            }
        }
    }

    /// Decodes section `index` as `S` into a fresh value (nothing is kept; see
    /// [`Pack::section`] for the shared form).
    pub fn decode<S: Section>(&self, index: usize) -> Result<S> {
        let entry = *self.entry(index)?;
        let payload = self.payload(index)?;
        decode_section(index, &entry, &payload).map_err(|e| self.with_path(e))
    }

    /// Decodes the first section of `S`'s kind, or fails with [`FormatError::MissingSection`].
    pub fn decode_first<S: Section>(&self) -> Result<S> {
        match self.find(S::KIND).next() {
            Some(i) => self.decode(i),
            None => Err(self.missing(S::KIND)),
        }
    }

    /// Decodes every section of `S`'s kind, in table order.
    pub fn decode_all<S: Section>(&self) -> Result<Vec<S>> {
        self.find(S::KIND).collect::<Vec<_>>().into_iter().map(|i| self.decode(i)).collect()
    }

    /// The first section of `S`'s kind, decoded on first use and shared afterwards, or
    /// [`FormatError::MissingSection`] when the pack has none.
    pub fn section<S: Section + Send + Sync + 'static>(&self) -> Result<Arc<S>> {
        self.optional_section::<S>()?.ok_or_else(|| self.missing(S::KIND))
    }

    /// The first section of `S`'s kind (shared), or `None` when the pack has none.
    pub fn optional_section<S: Section + Send + Sync + 'static>(&self) -> Result<Option<Arc<S>>> {
        match self.find(S::KIND).next() {
            Some(i) => self.shared::<S>(i).map(Some),
            None => Ok(None),
        }
    }

    /// Every section of `S`'s kind (shared), in table order.
    pub fn sections_of<S: Section + Send + Sync + 'static>(&self) -> Result<Vec<Arc<S>>> {
        self.find(S::KIND).collect::<Vec<_>>().into_iter().map(|i| self.shared::<S>(i)).collect()
    }

    /// The topology kind of every spring-topology section, as `(table index, kind)` in table
    /// order. Learnt from the first field of each section's record metadata — the record head and
    /// the kind's four bytes (12 bytes per section), read without the rest of the section and
    /// without a checksum, so this is not a section read and [`Pack::read_counts`] does not
    /// change; the kind is confirmed when [`Pack::spring_topology`] decodes the section. A
    /// section of a layout version the peek does not know is decoded instead (and counts as
    /// read).
    pub fn topology_kinds(&self) -> Result<Vec<(usize, TopologyKind)>> {
        if let Some(k) = &self.lock().topology_kinds {
            return Ok(k.clone());
        }
        let mut kinds = Vec::new();
        for i in self.find(SectionKind::SPRING_TOPOLOGY).collect::<Vec<_>>() {
            let e = self.entries[i];
            let kind = if e.version == SpringTopology::PEEKABLE_VERSION {
                self.peek_topology_kind(i, &e)?
            } else {
                self.shared::<SpringTopology>(i)?.kind
            };
            kinds.push((i, kind));
        }
        self.lock().topology_kinds = Some(kinds.clone());
        Ok(kinds)
    }

    /// The spring topology of `kind` (shared): only that section is read and decoded.
    pub fn spring_topology(&self, kind: TopologyKind) -> Result<Arc<SpringTopology>> {
        let Some(&(index, _)) = self.topology_kinds()?.iter().find(|(_, k)| *k == kind) else {
            return Err(self.missing(SectionKind::SPRING_TOPOLOGY));
        };
        let t = self.shared::<SpringTopology>(index)?;
        if t.kind != kind {
            return Err(FormatError::Invalid {
                path: self.path.clone(),
                section: Some(index),
                offset: None,
                what: format!("its metadata head says {kind}, the decoded topology is {}", t.kind),
            });
        }
        Ok(t)
    }

    /// Bytes read so far by metadata peeks ([`Pack::topology_kinds`]), outside any section read.
    pub fn peeked_bytes(&self) -> u64 {
        self.lock().peeked_bytes
    }

    /// The skin mesh (shared).
    pub fn skin_mesh(&self) -> Result<Arc<SkinMesh>> {
        self.section()
    }

    /// The shell atlas (alpha slices and per-layer shadow table; shared).
    pub fn shell_atlas(&self) -> Result<Arc<ShellAtlas>> {
        self.section()
    }

    /// The fin atlas (shared).
    pub fn fin_atlas(&self) -> Result<Arc<FinAtlas>> {
        self.section()
    }

    /// The per-triangle UV map (shared).
    pub fn triangle_uv_map(&self) -> Result<Arc<TriangleUvMap>> {
        self.section()
    }

    /// The fin-carrying edges (shared).
    pub fn fin_edges(&self) -> Result<Arc<FinEdges>> {
        self.section()
    }

    /// The grass blade field (blades, clusters and their grid; shared).
    pub fn blade_field(&self) -> Result<Arc<BladeField>> {
        self.section()
    }

    /// The grass keyframe table (shared).
    pub fn keyframe_table(&self) -> Result<Arc<KeyframeTable>> {
        self.section()
    }

    /// The skeleton (joint hierarchy and skinning palette; shared), `None` for an unskinned pack.
    pub fn skeleton(&self) -> Result<Option<Arc<Skeleton>>> {
        self.optional_section()
    }

    /// The per-vertex skin weights (shared), `None` for an unskinned pack.
    pub fn skin_weights(&self) -> Result<Option<Arc<SkinWeights>>> {
        self.optional_section()
    }

    /// The morph targets (shared), `None` when the pack has none.
    pub fn morph_targets(&self) -> Result<Option<Arc<MorphTargets>>> {
        self.optional_section()
    }

    /// The animation clips (shared), `None` when the pack has none.
    pub fn animation_clips(&self) -> Result<Option<Arc<AnimationClips>>> {
        self.optional_section()
    }

    /// The bake manifest (shared).
    pub fn manifest(&self) -> Result<Arc<BakeManifest>> {
        self.section()
    }

    /// How many times each section-table entry's payload was read, in table order. An entry
    /// nothing asked for stays at 0.
    pub fn read_counts(&self) -> Vec<(SectionKind, u32)> {
        let state = self.lock();
        self.entries.iter().zip(&state.reads).map(|(e, &n)| (e.kind, n)).collect()
    }

    /// The kinds of the sections read so far (each once, in table order).
    pub fn kinds_read(&self) -> Vec<SectionKind> {
        let mut kinds = Vec::new();
        for (kind, n) in self.read_counts() {
            if n > 0 && !kinds.contains(&kind) {
                kinds.push(kind);
            }
        }
        kinds
    }

    fn entry(&self, index: usize) -> Result<&SectionEntry> {
        self.entries.get(index).ok_or_else(|| FormatError::Parameter {
            path: self.path.clone(),
            what: format!("no section {index} (the pack has {})", self.entries.len()),
        })
    }

    fn missing(&self, kind: SectionKind) -> FormatError {
        FormatError::MissingSection { path: self.path.clone(), kind }
    }

    fn with_path(&self, e: FormatError) -> FormatError {
        match &self.path {
            Some(p) => e.with_path(p),
            None => e,
        }
    }

    fn io(&self, source: std::io::Error) -> FormatError {
        FormatError::Io { path: self.display_path(), source }
    }

    /// Reads the topology kind of spring-topology entry `index` from its record head and the
    /// first four bytes of its metadata. Every offset is checked against the entry's length,
    /// which the table validation checked against the file.
    fn peek_topology_kind(&self, index: usize, e: &SectionEntry) -> Result<TopologyKind> {
        let at = |offset: u64, buf: &mut [u8]| -> Result<()> {
            match &self.source {
                Source::Memory(bytes) => {
                    let start = (e.offset + offset) as usize;
                    buf.copy_from_slice(&bytes[start..start + buf.len()]);
                    Ok(())
                }
                Source::File(file) => read_exact_at(file, e.offset + offset, buf).map_err(|s| self.io(s)),
            }
        };
        let mut head = [0u8; 8];
        if e.length < 8 {
            return Err(self.with_path(FormatError::Invalid {
                path: None,
                section: Some(index),
                offset: Some(e.offset),
                what: format!("{} bytes is shorter than a record head", e.length),
            }));
        }
        at(0, &mut head)?;
        let (meta_at, meta_len) =
            crate::record::meta_span(head, e.length).map_err(|err| self.with_path(err.in_section(index, e.offset)))?;
        let mut prefix = [0u8; 4];
        if meta_len < prefix.len() as u64 {
            return Err(self.with_path(FormatError::Invalid {
                path: None,
                section: Some(index),
                offset: Some(e.offset + meta_at),
                what: format!("topology metadata of {meta_len} bytes has no kind"),
            }));
        }
        at(meta_at, &mut prefix)?;
        self.lock().peeked_bytes += (head.len() + prefix.len()) as u64;
        Ok(SpringTopology::kind_from_meta_prefix(prefix))
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while holding the lock cannot leave `State` half-updated: entries are inserted
        // only after a successful decode, so a poisoned lock is safe to reuse.
        self.state.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn shared<S: Section + Send + Sync + 'static>(&self, index: usize) -> Result<Arc<S>> {
        if let Some(any) = self.lock().decoded.get(&index) {
            let cached: Cached = Arc::clone(any);
            return cached.downcast::<S>().map_err(|_| FormatError::Parameter {
                path: self.path.clone(),
                what: format!("section {index} is {}, not {}", self.entries[index].kind, S::KIND),
            });
        }
        // Decoded outside the lock, so first reads of different sections run concurrently; two
        // threads racing for the same section both decode it and the first insert wins.
        let section = Arc::new(self.decode::<S>(index)?);
        let mut state = self.lock();
        let kept = state.decoded.entry(index).or_insert_with(|| section.clone() as Cached).clone();
        Ok(kept.downcast::<S>().unwrap_or(section))
    }
}

/// Reads exactly `buf.len()` bytes at `offset` without moving a shared cursor.
fn read_exact_at(file: &File, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
    let got = read_up_to_at(file, offset, buf)?;
    if got < buf.len() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::UnexpectedEof,
            format!("the file ends {} bytes into a {}-byte read at byte {offset}", got, buf.len()),
        ));
    }
    Ok(())
}

/// Reads up to `buf.len()` bytes at `offset` (fewer only at the end of the file).
fn read_up_to_at(file: &File, offset: u64, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        #[cfg(unix)]
        let k = std::os::unix::fs::FileExt::read_at(file, &mut buf[n..], offset + n as u64);
        #[cfg(windows)]
        let k = std::os::windows::fs::FileExt::seek_read(file, &mut buf[n..], offset + n as u64);
        match k {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}
