//! [`Pack`]: a baked pack opened for use at runtime (SPEC "Runtime": load only the sections a
//! scene needs). Opening validates the container header and section table only; each section is
//! read from disk, checksummed and decoded the first time it is asked for, then kept. A per-section
//! read counter records what was actually touched, so tests can prove that a scene which does not
//! declare an effect never reads the sections only that effect needs.
//!
//! Spring topologies (fur thesis §3.4.1) are the one kind a pack holds several of; the runtime
//! needs exactly one. [`Pack::topology_kinds`] learns each one's [`TopologyKind`] from the first
//! bytes of its metadata (a few hundred bytes, not counted as a section read), so
//! [`Pack::spring_topology`] reads and decodes only the section it picks.

use std::any::Any;
use std::collections::HashMap;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::fin_edges::FinEdges;
use furbake_formats::sections::manifest::BakeManifest;
use furbake_formats::sections::shell_atlas::ShellAtlas;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::{SpringTopology, TopologyKind};
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use furbake_formats::{FormatError, PackFile, Section, SectionEntry, SectionKind};

use crate::RuntimeError;

type Cached = Arc<dyn Any + Send + Sync>;

/// A pack file opened lazily. Cheap to open; every typed accessor reads its section at most once.
///
/// The accessors return `Arc`s so that decoded sections can be shared with renderers and solvers
/// without copying. `Pack` is `Send + Sync`; concurrent first reads of the same section are
/// serialised (the file handle sits behind a mutex).
pub struct Pack {
    path: PathBuf,
    entries: Vec<SectionEntry>,
    inner: Mutex<Inner>,
}

struct Inner {
    file: PackFile,
    /// Decoded sections by table index.
    decoded: HashMap<usize, Cached>,
    /// How many times each table entry was read from disk (0 or 1 unless decoding failed).
    reads: Vec<u32>,
    /// The topology kind of every spring-topology entry, once peeked.
    topology_kinds: Option<Vec<(usize, TopologyKind)>>,
    /// Bytes read by metadata peeks (not section reads).
    peeked_bytes: u64,
}

/// Size of one array-table entry of a record payload (formats `record.rs`: type, pad, offset,
/// count — 4 + 4 + 8 + 8 bytes).
const RECORD_ARRAY_ENTRY: u64 = 24;

impl std::fmt::Debug for Pack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pack").field("path", &self.path).field("sections", &self.entries.len()).finish()
    }
}

impl Pack {
    /// Opens the pack at `path`, validating only its header and section table (no section is read).
    pub fn open(path: impl AsRef<Path>) -> Result<Pack, RuntimeError> {
        let path = path.as_ref();
        let file = PackFile::open(path)?;
        let entries = file.sections().to_vec();
        let reads = vec![0; entries.len()];
        Ok(Pack {
            path: path.to_path_buf(),
            entries,
            inner: Mutex::new(Inner { file, decoded: HashMap::new(), reads, topology_kinds: None, peeked_bytes: 0 }),
        })
    }

    /// The path the pack was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The section table (read at open; no payload is touched).
    pub fn sections(&self) -> &[SectionEntry] {
        &self.entries
    }

    /// True when the pack holds at least one section of `kind`.
    pub fn has(&self, kind: SectionKind) -> bool {
        self.entries.iter().any(|e| e.kind == kind)
    }

    /// The first section of `S`'s kind, read and decoded on first use, or a
    /// [`RuntimeError::MissingSection`] when the pack has none.
    pub fn section<S: Section + Send + Sync + 'static>(&self) -> Result<Arc<S>, RuntimeError> {
        self.optional_section::<S>()?
            .ok_or_else(|| RuntimeError::MissingSection { path: self.path.clone(), kind: S::KIND })
    }

    /// The first section of `S`'s kind, or `None` when the pack has none.
    pub fn optional_section<S: Section + Send + Sync + 'static>(&self) -> Result<Option<Arc<S>>, RuntimeError> {
        match self.entries.iter().position(|e| e.kind == S::KIND) {
            Some(i) => self.decoded::<S>(i).map(Some),
            None => Ok(None),
        }
    }

    /// Every section of `S`'s kind, in table order (e.g. several spring topologies).
    pub fn sections_of<S: Section + Send + Sync + 'static>(&self) -> Result<Vec<Arc<S>>, RuntimeError> {
        let indices: Vec<usize> =
            self.entries.iter().enumerate().filter(|(_, e)| e.kind == S::KIND).map(|(i, _)| i).collect();
        indices.into_iter().map(|i| self.decoded::<S>(i)).collect()
    }

    /// The topology kind of every spring-topology section, as `(table index, kind)` in table
    /// order. Learnt from the first field of each section's metadata — its record head and the
    /// kind's four bytes, read without the rest of the section and without a checksum (so this is
    /// not a section read and [`Pack::read_counts`] does not change); the kind is confirmed when
    /// [`Pack::spring_topology`] decodes the section. A section of a layout version this peek
    /// does not know is decoded instead (and then counts as read).
    pub fn topology_kinds(&self) -> Result<Vec<(usize, TopologyKind)>, RuntimeError> {
        if let Some(k) = &self.lock().topology_kinds {
            return Ok(k.clone());
        }
        let mut kinds = Vec::new();
        let mut file: Option<File> = None;
        for (i, e) in self.entries.iter().enumerate().filter(|(_, e)| e.kind == SectionKind::SPRING_TOPOLOGY) {
            let kind = if e.version == 1 {
                let f = match &mut file {
                    Some(f) => f,
                    None => file.insert(File::open(&self.path).map_err(|source| self.io(source))?),
                };
                self.peek_topology_kind(f, i, e)?
            } else {
                self.decoded::<SpringTopology>(i)?.kind
            };
            kinds.push((i, kind));
        }
        self.lock().topology_kinds = Some(kinds.clone());
        Ok(kinds)
    }

    /// The spring topology of `kind`: only that section is read and decoded.
    pub fn spring_topology(&self, kind: TopologyKind) -> Result<Arc<SpringTopology>, RuntimeError> {
        let Some(&(index, _)) = self.topology_kinds()?.iter().find(|(_, k)| *k == kind) else {
            return Err(RuntimeError::MissingSection { path: self.path.clone(), kind: SectionKind::SPRING_TOPOLOGY });
        };
        let t = self.decoded::<SpringTopology>(index)?;
        if t.kind != kind {
            return Err(RuntimeError::Format(FormatError::Parameter {
                path: Some(self.path.clone()),
                what: format!("section {index}: its metadata head says {kind}, the decoded topology is {}", t.kind),
            }));
        }
        Ok(t)
    }

    /// Bytes read so far by metadata peeks ([`Pack::topology_kinds`]), outside any section read.
    pub fn peeked_bytes(&self) -> u64 {
        self.lock().peeked_bytes
    }

    /// The skin mesh.
    pub fn skin_mesh(&self) -> Result<Arc<SkinMesh>, RuntimeError> {
        self.section()
    }

    /// The shell atlas (alpha slices and per-layer shadow table).
    pub fn shell_atlas(&self) -> Result<Arc<ShellAtlas>, RuntimeError> {
        self.section()
    }

    /// The fin atlas.
    pub fn fin_atlas(&self) -> Result<Arc<FinAtlas>, RuntimeError> {
        self.section()
    }

    /// The per-triangle UV map.
    pub fn triangle_uv_map(&self) -> Result<Arc<TriangleUvMap>, RuntimeError> {
        self.section()
    }

    /// The fin-carrying edges.
    pub fn fin_edges(&self) -> Result<Arc<FinEdges>, RuntimeError> {
        self.section()
    }

    /// The grass blade field (blades, clusters and their grid).
    pub fn blade_field(&self) -> Result<Arc<BladeField>, RuntimeError> {
        self.section()
    }

    /// The bake manifest.
    pub fn manifest(&self) -> Result<Arc<BakeManifest>, RuntimeError> {
        self.section()
    }

    /// How many times each section-table entry has been read from disk, in table order. An entry
    /// that no accessor asked for stays at 0.
    pub fn read_counts(&self) -> Vec<(SectionKind, u32)> {
        let inner = self.lock();
        self.entries.iter().zip(&inner.reads).map(|(e, &n)| (e.kind, n)).collect()
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

    fn io(&self, source: std::io::Error) -> RuntimeError {
        RuntimeError::Format(FormatError::Io { path: self.path.clone(), source })
    }

    /// Reads the topology kind of spring-topology entry `index` (layout version 1): a record
    /// payload starts with `meta_len: u32, array_count: u32`, then `array_count` 24-byte array
    /// entries, then the bincode metadata (fixed-width little-endian integers) whose first field
    /// is the kind's `u32` code. Every offset is checked against the entry's length, which the
    /// container validated against the file at open.
    fn peek_topology_kind(
        &self,
        file: &mut File,
        index: usize,
        e: &SectionEntry,
    ) -> Result<TopologyKind, RuntimeError> {
        let bad = |what: String| {
            RuntimeError::Format(FormatError::Parameter {
                path: Some(self.path.clone()),
                what: format!("spring topology section {index}: {what}"),
            })
        };
        let mut head = [0u8; 8];
        if e.length < 8 {
            return Err(bad(format!("{} bytes is shorter than a record head", e.length)));
        }
        file.seek(SeekFrom::Start(e.offset)).map_err(|s| self.io(s))?;
        file.read_exact(&mut head).map_err(|s| self.io(s))?;
        let meta_len = u32::from_le_bytes([head[0], head[1], head[2], head[3]]) as u64;
        let arrays = u32::from_le_bytes([head[4], head[5], head[6], head[7]]) as u64;
        let meta_at = 8 + arrays * RECORD_ARRAY_ENTRY;
        if meta_len < 4 || meta_at + 4 > e.length {
            return Err(bad(format!("metadata of {meta_len} bytes after {arrays} arrays does not fit")));
        }
        let mut code = [0u8; 4];
        file.seek(SeekFrom::Start(e.offset + meta_at)).map_err(|s| self.io(s))?;
        file.read_exact(&mut code).map_err(|s| self.io(s))?;
        self.lock().peeked_bytes += 12;
        Ok(TopologyKind(u32::from_le_bytes(code)))
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        // A panic while holding the lock cannot leave `Inner` half-updated: entries are inserted
        // only after a successful decode, so a poisoned lock is safe to reuse.
        self.inner.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn decoded<S: Section + Send + Sync + 'static>(&self, index: usize) -> Result<Arc<S>, RuntimeError> {
        let mut inner = self.lock();
        if let Some(any) = inner.decoded.get(&index) {
            let cloned: Cached = Arc::clone(any);
            return Ok(cloned.downcast::<S>().expect("a table index always caches the type of its kind"));
        }
        inner.reads[index] += 1;
        let section: S = inner.file.decode(index)?;
        let section = Arc::new(section);
        inner.decoded.insert(index, section.clone() as Cached);
        Ok(section)
    }
}
