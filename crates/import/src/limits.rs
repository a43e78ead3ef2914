//! Size limits that keep a lying or hostile file from exhausting memory (docs/design.md "Import", "Determinism and errors": absurd
//! sizes get a clear error). Far above any fur skin (the thesis's dog has 1872 vertices).

/// Largest main file, buffer (`byteLength`) or external image file accepted, in bytes (2 GiB);
/// checked before reading, and reads are bounded by it.
pub const MAX_FILE_BYTES: u64 = 1 << 31;
/// Most elements one accessor may have (8 Mi); also bounds accessors without a buffer view.
pub const MAX_ACCESSOR_ELEMENTS: u64 = 1 << 23;
/// Most vertices in the whole scene before welding, node instances included (8 Mi).
pub const MAX_RAW_VERTICES: u64 = 1 << 23;
/// Most triangles in the whole scene before welding (16 Mi).
pub const MAX_RAW_TRIANGLES: u64 = 1 << 24;
/// Most vertices that second and later instances of meshes may add (1 Mi; declared `POSITION`
/// counts): instancing multiplies vertices without bytes to back them, so a node DAG of a few
/// kilobytes could otherwise fill [`MAX_RAW_VERTICES`] (seconds and a gigabyte). A rug of a
/// thousand instances of a 100-vertex tile stays far below.
pub const MAX_INSTANCED_VERTICES: u64 = 1 << 20;
/// Deepest node hierarchy accepted.
pub const MAX_NODE_DEPTH: usize = 256;
/// Most node visits (a node reached through several parents counts once per path).
pub const MAX_NODE_VISITS: u64 = 1 << 20;
/// Most skeleton joints (skin joints, rigidly bound mesh nodes and their ancestors). Joint names
/// are kept in the skeleton section's metadata, which readers cap at 1 MiB.
pub const MAX_JOINTS: usize = 4096;
/// Most animation clips.
pub const MAX_CLIPS: usize = 1024;
/// Most channels over all clips.
pub const MAX_CHANNELS: usize = 1 << 16;
/// Most key times over all channels of all clips (16 Mi).
pub const MAX_KEYS: u64 = 1 << 24;
/// Most morph targets over all mesh instances.
pub const MAX_MORPH_TARGETS: usize = 1024;
/// Most stored morph deltas, targets × welded vertices (16 Mi; position and normal each).
pub const MAX_MORPH_DELTAS: u64 = 1 << 24;
