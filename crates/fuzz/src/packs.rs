//! The pack target: structure-aware mutations of real packs, and what is run on each mutant.
//!
//! A base pack is taken apart into sections ([`PackModel`]) and each record payload into its
//! metadata and typed arrays ([`RecordModel`], docs/format.md "Section payloads"). A case applies
//! one to four mutations at one of three levels — the record (a metadata field set to an
//! interesting value, an array element, an array resized with the declared counts in the
//! metadata following along, arrays dropped, swapped or retyped), the section list (sections
//! dropped, duplicated, swapped, spliced in from another base pack, their kind or version
//! changed) or the raw container bytes (header and table fields, bytes flipped, the file
//! truncated) — and then, in most cases, recomputes every section CRC, the table CRC, the file
//! size and the header CRC (docs/format.md "Header", "Section table"), so that the mutant reaches
//! the semantic checks instead of failing at a checksum.
//!
//! [`run_pack`] is what a game and `furbake verify` do with a pack: [`Pack::from_bytes`], every
//! known section decoded, [`check_consistency`], and a [`World`] over a scene with gravity, wind
//! and (sometimes) parting, delayed wind sources and object motion, stepped a few times, and
//! `furbake export` of the same bytes (which must refuse a bad pack, never panic).

use std::path::Path;
use std::sync::Arc;

use furbake_formats::sections::animation_clips::AnimationClips;
use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::fin_edges::FinEdges;
use furbake_formats::sections::keyframe_table::KeyframeTable;
use furbake_formats::sections::manifest::BakeManifest;
use furbake_formats::sections::morph_targets::MorphTargets;
use furbake_formats::sections::shell_atlas::ShellAtlas;
use furbake_formats::sections::skeleton::Skeleton;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::SkinWeights;
use furbake_formats::sections::spring_topology::SpringTopology;
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use furbake_formats::{HEADER_SIZE, Pack, PackSections, SectionKind, TABLE_ENTRY_SIZE, check_consistency};
use furbake_runtime::{Scene, World, WorldOptions};

use crate::rng::Rng;

/// One section of a pack, as the table describes it plus its payload.
#[derive(Clone, Debug)]
pub struct SectionModel {
    /// Kind code.
    pub kind: u32,
    /// Layout version.
    pub version: u16,
    /// Flags (0 when written by furbake).
    pub flags: u16,
    /// Payload bytes.
    pub payload: Vec<u8>,
}

/// A pack taken apart into its sections.
#[derive(Clone, Debug, Default)]
pub struct PackModel {
    /// Sections in table order.
    pub sections: Vec<SectionModel>,
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}
fn u64_at(b: &[u8], at: usize) -> u64 {
    let mut x = [0u8; 8];
    x.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(x)
}

impl PackModel {
    /// Takes apart a *valid* container (a base pack); `None` when it is not one.
    pub fn parse(bytes: &[u8]) -> Option<PackModel> {
        Pack::from_bytes(bytes).ok()?;
        let count = u32_at(bytes, 16) as usize;
        let table = u64_at(bytes, 24) as usize;
        let sections = (0..count)
            .map(|i| {
                let e = table + i * TABLE_ENTRY_SIZE;
                let (off, len) = (u64_at(bytes, e + 8) as usize, u64_at(bytes, e + 16) as usize);
                SectionModel {
                    kind: u32_at(bytes, e),
                    version: u16_at(bytes, e + 4),
                    flags: u16_at(bytes, e + 6),
                    payload: bytes[off..off + len].to_vec(),
                }
            })
            .collect();
        Some(PackModel { sections })
    }

    /// The container bytes, laid out as `PackWriter` does, with every checksum right.
    pub fn assemble(&self) -> Vec<u8> {
        let count = self.sections.len();
        let table_end = HEADER_SIZE + count * TABLE_ENTRY_SIZE;
        let mut cursor = table_end.div_ceil(16) * 16;
        let mut out = vec![0u8; cursor];
        for (i, s) in self.sections.iter().enumerate() {
            out.resize(cursor, 0);
            out.extend_from_slice(&s.payload);
            let e = HEADER_SIZE + i * TABLE_ENTRY_SIZE;
            out[e..e + 4].copy_from_slice(&s.kind.to_le_bytes());
            out[e + 4..e + 6].copy_from_slice(&s.version.to_le_bytes());
            out[e + 6..e + 8].copy_from_slice(&s.flags.to_le_bytes());
            out[e + 8..e + 16].copy_from_slice(&(cursor as u64).to_le_bytes());
            out[e + 16..e + 24].copy_from_slice(&(s.payload.len() as u64).to_le_bytes());
            cursor = (cursor + s.payload.len()).div_ceil(16) * 16;
        }
        out.resize(cursor, 0);
        out[0..8].copy_from_slice(&furbake_formats::MAGIC);
        out[8..10].copy_from_slice(&furbake_formats::VERSION_MAJOR.to_le_bytes());
        out[10..12].copy_from_slice(&furbake_formats::VERSION_MINOR.to_le_bytes());
        out[12..16].copy_from_slice(&(HEADER_SIZE as u32).to_le_bytes());
        out[16..20].copy_from_slice(&(count as u32).to_le_bytes());
        out[24..32].copy_from_slice(&(HEADER_SIZE as u64).to_le_bytes());
        fix_checksums(&mut out, true);
        out
    }
}

/// Recomputes what a mutation broke: each section CRC whose span lies inside the file, the table
/// CRC, the header's file size (when `fix_size`) and the header CRC. Leaves alone what cannot be
/// fixed (a table outside the file), so the container checks still see it.
pub fn fix_checksums(bytes: &mut [u8], fix_size: bool) {
    if bytes.len() < HEADER_SIZE {
        return;
    }
    let len = bytes.len() as u64;
    if fix_size {
        bytes[32..40].copy_from_slice(&len.to_le_bytes());
    }
    let count = u32_at(bytes, 16) as u64;
    let table = u64_at(bytes, 24);
    let table_end = count.checked_mul(TABLE_ENTRY_SIZE as u64).and_then(|n| n.checked_add(table));
    if let Some(table_end) = table_end.filter(|&end| end <= len && table >= HEADER_SIZE as u64) {
        for i in 0..count as usize {
            let e = table as usize + i * TABLE_ENTRY_SIZE;
            let (off, n) = (u64_at(bytes, e + 8), u64_at(bytes, e + 16));
            if let Some(end) = off.checked_add(n).filter(|&end| end <= len) {
                let crc = crc32fast::hash(&bytes[off as usize..end as usize]);
                bytes[e + 24..e + 28].copy_from_slice(&crc.to_le_bytes());
            }
        }
        let crc = crc32fast::hash(&bytes[table as usize..table_end as usize]);
        bytes[40..44].copy_from_slice(&crc.to_le_bytes());
    }
    let crc = crc32fast::hash(&bytes[..44]);
    bytes[44..48].copy_from_slice(&crc.to_le_bytes());
}

/// A record payload taken apart (docs/format.md "the record layout").
#[derive(Clone, Debug, Default)]
pub struct RecordModel {
    /// The bincode metadata bytes.
    pub meta: Vec<u8>,
    /// `(element type code, element size, element bytes)` per array.
    pub arrays: Vec<(u32, usize, Vec<u8>)>,
}

fn elem_size(code: u32) -> usize {
    match code {
        1 | 2 => 1,
        3 | 4 | 8 => 2,
        9 => 8,
        _ => 4,
    }
}

impl RecordModel {
    /// Takes apart a well-formed record; `None` otherwise.
    pub fn parse(p: &[u8]) -> Option<RecordModel> {
        if p.len() < 8 {
            return None;
        }
        let meta_len = u32_at(p, 0) as usize;
        let count = u32_at(p, 4) as usize;
        let head = count.checked_mul(24)?.checked_add(8)?;
        let meta = p.get(head..head.checked_add(meta_len)?)?.to_vec();
        let mut arrays = Vec::with_capacity(count);
        for i in 0..count {
            let e = 8 + i * 24;
            let code = u32_at(p, e);
            let (off, n) = (u64_at(p, e + 8) as usize, u64_at(p, e + 16) as usize);
            let size = elem_size(code);
            let bytes = p.get(off..off.checked_add(n.checked_mul(size)?)?)?.to_vec();
            arrays.push((code, size, bytes));
        }
        Some(RecordModel { meta, arrays })
    }

    /// The payload, laid out as `RecordWriter` does.
    pub fn emit(&self) -> Vec<u8> {
        let head = 8 + 24 * self.arrays.len();
        let mut cursor = head + self.meta.len();
        let mut out = vec![0u8; cursor];
        out[0..4].copy_from_slice(&(self.meta.len() as u32).to_le_bytes());
        out[4..8].copy_from_slice(&(self.arrays.len() as u32).to_le_bytes());
        out[head..cursor].copy_from_slice(&self.meta);
        for (i, (code, size, bytes)) in self.arrays.iter().enumerate() {
            cursor = cursor.div_ceil(16) * 16;
            out.resize(cursor, 0);
            let e = 8 + i * 24;
            out[e..e + 4].copy_from_slice(&code.to_le_bytes());
            out[e + 8..e + 16].copy_from_slice(&(cursor as u64).to_le_bytes());
            out[e + 16..e + 24].copy_from_slice(&((bytes.len() / size) as u64).to_le_bytes());
            out.extend_from_slice(bytes);
            cursor = out.len();
        }
        out
    }
}

/// Reads up to 8 little-endian bytes at `at` (missing bytes are zero).
fn read_le(bytes: &[u8], at: usize, width: usize) -> u64 {
    let mut x = [0u8; 8];
    for (d, s) in x.iter_mut().zip(bytes.iter().skip(at).take(width)) {
        *d = *s;
    }
    u64::from_le_bytes(x)
}

/// Writes an interesting value of a random width (1, 2, 4 or 8 bytes; integer or `f32`) at a
/// random position of `bytes`.
pub fn poke_value(rng: &mut Rng, bytes: &mut [u8]) {
    if bytes.is_empty() {
        return;
    }
    let width = *rng.pick(&[1usize, 4, 4, 4, 8, 2]);
    let at = rng.below(bytes.len());
    let near = read_le(bytes, at, width);
    let value: Vec<u8> = match width {
        1 => {
            let flipped = (near as u8) ^ (1 << rng.below(8));
            vec![*rng.pick(&[0u8, 1, 2, 0x7F, 0x80, 0xFF, flipped])]
        }
        2 => (rng.interesting_u32(near as u32) as u16).to_le_bytes().to_vec(),
        4 if rng.chance(1, 2) => {
            let f = f32::from_bits(near as u32);
            rng.interesting_f32(if f.is_finite() { f } else { 1.0 }).to_le_bytes().to_vec()
        }
        4 => rng.interesting_u32(near as u32).to_le_bytes().to_vec(),
        _ => rng.interesting_u64(near).to_le_bytes().to_vec(),
    };
    for (d, s) in bytes[at..].iter_mut().zip(&value) {
        *d = *s;
    }
}

/// Replaces the first little-endian occurrence of `old` (as `u32`, or as a `u64` length prefix)
/// in `meta` by `new`: when an array is resized, the count the metadata declares follows it, so
/// the mutant is consistent at the record level and only the semantic checks can refuse it.
fn follow_count(meta: &mut [u8], old: u64, new: u64) {
    for width in [8usize, 4] {
        if width == 4 && (old > u32::MAX as u64 || new > u32::MAX as u64) {
            continue;
        }
        let needle = &old.to_le_bytes()[..width];
        if let Some(at) = meta.windows(width).position(|w| w == needle) {
            meta[at..at + width].copy_from_slice(&new.to_le_bytes()[..width]);
            return;
        }
    }
}

/// One mutation of one record payload.
fn mutate_record(rng: &mut Rng, rec: &mut RecordModel) {
    let n_arrays = rec.arrays.len();
    match rng.below(if n_arrays == 0 { 2 } else { 12 }) {
        0 => poke_value(rng, &mut rec.meta),
        1 => {
            // Metadata grows or shrinks by a few bytes (bincode must notice).
            if rng.chance(1, 2) && !rec.meta.is_empty() {
                let n = rec.meta.len() - rng.below(4).min(rec.meta.len());
                rec.meta.truncate(n);
            } else {
                let at = rng.below(rec.meta.len() + 1);
                rec.meta.insert(at, rng.next_u64() as u8);
            }
        }
        2..=4 => {
            // One element of one array set to an interesting value of its type.
            let (code, size, bytes) = &mut rec.arrays[rng.below(n_arrays)];
            let count = bytes.len() / *size;
            if count == 0 {
                return;
            }
            let at = rng.below(count) * *size;
            let near = read_le(bytes, at, *size);
            let v: u64 = match *code {
                7 => rng.interesting_f32(f32::from_bits(near as u32)).to_bits() as u64,
                5 | 6 => {
                    let base = if rng.chance(1, 2) { count as u32 } else { near as u32 };
                    rng.interesting_u32(base) as u64
                }
                9 => rng.interesting_u64(near),
                _ => rng.next_u64(),
            };
            bytes[at..at + *size].copy_from_slice(&v.to_le_bytes()[..*size]);
        }
        5 => {
            // A whole array filled with one value (every index out of range, every float NaN, ...).
            let (code, size, bytes) = &mut rec.arrays[rng.below(n_arrays)];
            let v: u64 = match *code {
                7 => rng.interesting_f32(1.0).to_bits() as u64,
                _ => rng.interesting_u64(bytes.len() as u64 / *size as u64),
            };
            for chunk in bytes.chunks_exact_mut(*size) {
                chunk.copy_from_slice(&v.to_le_bytes()[..*size]);
            }
        }
        6..=8 => {
            // An array resized (copies of its own elements, or zeros), its declared count in the
            // metadata following along most of the time.
            let k = rng.below(n_arrays);
            let (_, size, bytes) = &mut rec.arrays[k];
            let size = *size;
            let old = (bytes.len() / size) as u64;
            let new = match rng.below(6) {
                0 => 0,
                1 => old.saturating_sub(1 + rng.below(3) as u64),
                2 => old + 1 + rng.below(3) as u64,
                3 => old * 2,
                4 => old / 2,
                _ => (old * (2 + rng.below(15) as u64)).min(1 << 20),
            };
            let zeros = rng.chance(1, 3);
            let mut grown = Vec::with_capacity(new as usize * size);
            for i in 0..new as usize {
                if zeros || old == 0 {
                    grown.extend(std::iter::repeat_n(0u8, size));
                } else {
                    let j = i % old as usize;
                    grown.extend_from_slice(&bytes[j * size..(j + 1) * size]);
                }
            }
            *bytes = grown;
            if rng.chance(3, 4) {
                for d in [1u64, 2, 3, 4, 6] {
                    if old.is_multiple_of(d) && new.is_multiple_of(d) && old / d > 0 {
                        follow_count(&mut rec.meta, old / d, new / d);
                    }
                }
            }
        }
        9 => {
            let k = rng.below(n_arrays);
            match rng.below(3) {
                0 => {
                    rec.arrays.remove(k);
                }
                1 => {
                    let a = rec.arrays[k].clone();
                    rec.arrays.push(a);
                }
                _ => {
                    let j = rng.below(n_arrays);
                    rec.arrays.swap(k, j);
                }
            }
        }
        10 => {
            // An element type changed (the bytes stay; the count follows the new size).
            let (code, size, bytes) = &mut rec.arrays[rng.below(n_arrays)];
            *code = *rng.pick(&[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, u32::MAX]);
            *size = elem_size(*code);
            let keep = bytes.len() / *size * *size;
            bytes.truncate(keep);
        }
        _ => {
            // Two mutations of the metadata at once (e.g. a grid's two dimensions).
            poke_value(rng, &mut rec.meta);
            poke_value(rng, &mut rec.meta);
        }
    }
}

/// One mutation of the section list.
fn mutate_sections(rng: &mut Rng, pack: &mut PackModel, bases: &[PackModel]) {
    let n = pack.sections.len();
    if n == 0 {
        return;
    }
    let k = rng.below(n);
    match rng.below(9) {
        0 => {
            pack.sections.remove(k);
        }
        1 => {
            let s = pack.sections[k].clone();
            pack.sections.insert(rng.below(n + 1), s);
        }
        2 => pack.sections.swap(k, rng.below(n)),
        3 | 4 => {
            // A section of the same kind from another base pack (a mesh that the others were not
            // baked from), or any section of another pack added.
            let other = rng.pick(bases);
            let kind = pack.sections[k].kind;
            let same: Vec<&SectionModel> = other.sections.iter().filter(|s| s.kind == kind).collect();
            if !same.is_empty() && rng.chance(3, 4) {
                pack.sections[k] = (*rng.pick(&same)).clone();
            } else if !other.sections.is_empty() {
                pack.sections.push(rng.pick(&other.sections).clone());
            }
        }
        5 => pack.sections[k].kind = *rng.pick(&[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 0xFFFF_FFFF]),
        6 => pack.sections[k].version = *rng.pick(&[0, 1, 2, 0xFFFF]),
        7 => pack.sections[k].flags = rng.next_u64() as u16,
        _ => {
            let p = &mut pack.sections[k].payload;
            if rng.chance(1, 2) {
                p.truncate(rng.below(p.len() + 1));
            } else {
                p.extend(std::iter::repeat_n(0u8, 1 + rng.below(64)));
            }
        }
    }
}

/// One mutation of the raw container bytes (header, table, anything).
fn mutate_raw(rng: &mut Rng, bytes: &mut Vec<u8>) {
    match rng.below(5) {
        0 => {
            let end = HEADER_SIZE.min(bytes.len());
            poke_value(rng, &mut bytes[..end]);
        }
        1 | 2 => {
            let count = if bytes.len() >= 20 { u32_at(bytes, 16) as usize } else { 0 };
            let end = (HEADER_SIZE + count * TABLE_ENTRY_SIZE).min(bytes.len());
            if end > HEADER_SIZE {
                poke_value(rng, &mut bytes[HEADER_SIZE..end]);
            }
        }
        3 => {
            for _ in 0..1 + rng.below(8) {
                let at = rng.below(bytes.len());
                if let Some(b) = bytes.get_mut(at) {
                    *b ^= 1 << rng.below(8);
                }
            }
        }
        _ => {
            if rng.chance(1, 2) {
                bytes.truncate(rng.below(bytes.len() + 1));
            } else {
                bytes.extend(std::iter::repeat_n(0u8, 16 * (1 + rng.below(4))));
            }
        }
    }
}

/// Mutant `rng` makes from one of `bases` (see the module doc).
pub fn mutate_pack(rng: &mut Rng, bases: &[PackModel]) -> Vec<u8> {
    let mut pack = rng.pick(bases).clone();
    let mut raw = Vec::new();
    let rounds = *rng.pick(&[1, 1, 1, 2, 2, 3, 4]);
    for _ in 0..rounds {
        match rng.below(10) {
            0..=6 => {
                if pack.sections.is_empty() {
                    continue;
                }
                let k = rng.below(pack.sections.len());
                if let Some(mut rec) = RecordModel::parse(&pack.sections[k].payload) {
                    mutate_record(rng, &mut rec);
                    pack.sections[k].payload = rec.emit();
                } else {
                    poke_value(rng, &mut pack.sections[k].payload);
                }
            }
            7 | 8 => mutate_sections(rng, &mut pack, bases),
            _ => raw.push(rng.next_u64()),
        }
    }
    let mut bytes = pack.assemble();
    for seed in raw {
        mutate_raw(&mut Rng::new(seed), &mut bytes);
    }
    // Most mutants get their checksums recomputed, so the semantic checks are reached.
    if rng.chance(9, 10) {
        fix_checksums(&mut bytes, rng.chance(19, 20));
    }
    bytes
}

/// What happened to one mutant pack.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PackOutcome {
    /// The header, table or a checksum was refused.
    ContainerRejected,
    /// A section did not decode (layout, value ranges).
    SectionRejected,
    /// The sections decode but disagree with one another.
    Inconsistent,
    /// The pack verifies (what `furbake verify` accepts).
    Verified,
}

/// What the runtime made of a mutant that passed the container checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum WorldOutcome {
    /// `World::with_packs` refused the pack.
    Refused,
    /// A step failed with an error.
    StepFailed,
    /// Every step ran.
    Stepped,
}

/// Every known section of `pack`, decoded, then checked for consistency (`furbake verify`).
pub fn verify(pack: &Pack) -> Result<usize, (PackOutcome, String)> {
    let mut mesh: Option<SkinMesh> = None;
    let mut shells: Option<ShellAtlas> = None;
    let mut fins: Option<FinAtlas> = None;
    let mut uv_map: Option<TriangleUvMap> = None;
    let mut fin_edges: Option<FinEdges> = None;
    let mut skeleton: Option<Skeleton> = None;
    let mut skin_weights: Option<SkinWeights> = None;
    let mut morph_targets: Option<MorphTargets> = None;
    let mut clips: Option<AnimationClips> = None;
    let (mut topologies, mut fields, mut tables) = (Vec::new(), Vec::new(), Vec::new());
    let rejected = |e: furbake_formats::FormatError| (PackOutcome::SectionRejected, e.to_string());
    for (i, e) in pack.sections().iter().enumerate() {
        match e.kind {
            SectionKind::BAKE_MANIFEST => drop(pack.decode::<BakeManifest>(i).map_err(rejected)?),
            SectionKind::SKIN_MESH => mesh = mesh.or(Some(pack.decode(i).map_err(rejected)?)),
            SectionKind::SHELL_ATLAS => shells = shells.or(Some(pack.decode(i).map_err(rejected)?)),
            SectionKind::FIN_ATLAS => fins = fins.or(Some(pack.decode(i).map_err(rejected)?)),
            SectionKind::TRIANGLE_UV_MAP => uv_map = uv_map.or(Some(pack.decode(i).map_err(rejected)?)),
            SectionKind::FIN_EDGES => fin_edges = fin_edges.or(Some(pack.decode(i).map_err(rejected)?)),
            SectionKind::SPRING_TOPOLOGY => topologies.push(pack.decode::<SpringTopology>(i).map_err(rejected)?),
            SectionKind::BLADE_FIELD => fields.push(pack.decode::<BladeField>(i).map_err(rejected)?),
            SectionKind::KEYFRAME_TABLE => tables.push(pack.decode::<KeyframeTable>(i).map_err(rejected)?),
            SectionKind::SKELETON => skeleton = skeleton.or(Some(pack.decode(i).map_err(rejected)?)),
            SectionKind::SKIN_WEIGHTS => skin_weights = skin_weights.or(Some(pack.decode(i).map_err(rejected)?)),
            SectionKind::MORPH_TARGETS => morph_targets = morph_targets.or(Some(pack.decode(i).map_err(rejected)?)),
            SectionKind::ANIMATION_CLIPS => clips = clips.or(Some(pack.decode(i).map_err(rejected)?)),
            _ => {}
        }
    }
    let topologies: Vec<&SpringTopology> = topologies.iter().collect();
    let blade_fields: Vec<&BladeField> = fields.iter().collect();
    let keyframe_tables: Vec<&KeyframeTable> = tables.iter().collect();
    let sections = PackSections {
        mesh: mesh.as_ref(),
        shells: shells.as_ref(),
        fins: fins.as_ref(),
        uv_map: uv_map.as_ref(),
        fin_edges: fin_edges.as_ref(),
        topologies: &topologies,
        blade_fields: &blade_fields,
        keyframe_tables: &keyframe_tables,
        skeleton: skeleton.as_ref(),
        skin_weights: skin_weights.as_ref(),
        morph_targets: morph_targets.as_ref(),
        clips: clips.as_ref(),
    };
    check_consistency(pack.sections(), &sections).map_err(|e| (PackOutcome::Inconsistent, e.to_string()))
}

/// The scene a mutant is run in: gravity and wind always; parting, delayed wind sources, object
/// motion and the wrong-side guard as `rng` decides.
pub fn pack_scene(rng: &mut Rng, dir: &Path) -> Scene {
    let mut text = String::from(
        "time_step_s = 0.02\n[[packs]]\nname = \"p\"\npath = \"fuzz.fbk\"\n\
         [[packs.motion]]\ntime_s = 0.0\n[[packs.motion]]\ntime_s = 1.0\ntranslation = [0.5, 0.0, 0.0]\n\
         [effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [2.0, 0.0, 0.5]\ngust_amplitude = 0.3\n",
    );
    if rng.chance(1, 3) {
        text += "[effects.parting]\n";
    }
    if rng.chance(1, 2) {
        text += "[[effects.wind_sources]]\nposition = [0.0, 1.0, 0.0]\npower = 2.0\ndelayed_attenuation = true\n";
    }
    if rng.chance(1, 2) {
        text += "[effects.object_motion]\n[effects.wrong_side_guard]\n";
    }
    if rng.chance(1, 4) {
        text += "[[effects.collisions]]\nshape = \"sphere\"\ncenter = [0.0, 0.2, 0.0]\nradius_m = 0.25\n";
    }
    Scene::from_toml_str(&text, Path::new("fuzz.toml"), dir).expect("the harness's own scene text is valid")
}

/// Runs one mutant pack (see the module doc); `steps` world steps when the container is valid.
pub fn run_pack(bytes: &[u8], scene: Scene, steps: u32) -> (PackOutcome, Option<WorldOutcome>) {
    let pack = match Pack::from_bytes(bytes) {
        Ok(p) => Arc::new(p),
        Err(_) => return (PackOutcome::ContainerRejected, None),
    };
    let outcome = match verify(&pack) {
        Ok(_) => PackOutcome::Verified,
        Err((o, _)) => o,
    };
    // The runtime reads only what its stages need, so it also meets packs that `verify` refuses.
    let world = match World::with_packs(
        scene,
        vec![Arc::clone(&pack)],
        WorldOptions { step_statistics: true, ..WorldOptions::default() },
    ) {
        Err(_) => WorldOutcome::Refused,
        Ok(mut world) => {
            let mut out = WorldOutcome::Stepped;
            for _ in 0..steps {
                if world.step().is_err() {
                    out = WorldOutcome::StepFailed;
                    break;
                }
            }
            if out == WorldOutcome::Stepped {
                let _ = world.pack_state(0);
            }
            out
        }
    };
    // The exporter, a library call (`furbake export` verifies the pack first), meets packs that
    // `verify` refuses: it must refuse them, never panic.
    let _ = furbake_export::export(&pack, &furbake_export::ExportOptions::default());
    (outcome, Some(world))
}

#[cfg(test)]
mod tests {
    use super::*;
    use furbake_formats::PackWriter;
    use furbake_formats::sections::fin_atlas::FinAtlas;

    #[test]
    fn models_round_trip_a_valid_pack_byte_for_byte() {
        let fins = FinAtlas { width: 4, height: 2, slices: 20, alpha: vec![0, 255, 0, 9, 1, 2, 3, 4] };
        let bytes = PackWriter::new().push_section(&fins).push_section(&fins).to_bytes();
        let model = PackModel::parse(&bytes).expect("a valid pack");
        assert_eq!(model.sections.len(), 2);
        assert_eq!(model.assemble(), bytes);
        let rec = RecordModel::parse(&model.sections[0].payload).expect("a record");
        assert_eq!(rec.arrays.len(), 1);
        assert_eq!(rec.emit(), model.sections[0].payload);
        // A broken checksum is fixed back.
        let mut broken = bytes.clone();
        broken[40] ^= 1;
        broken[44] ^= 1;
        fix_checksums(&mut broken, true);
        assert_eq!(broken, bytes);
    }
}
