//! The glTF target: mutations of glTF JSON (the generated test meshes, and the JSON chunk of `.glb`
//! files, re-packed into a well-formed GLB) and of raw `.glb` bytes, and what is run on each
//! mutant: the importer in-process, then — for a mesh it accepts — a small bake whose pack must
//! verify (an accepted bake always writes a pack that verifies); and for a sample, the
//! `furbake bake` binary as a child process under a memory limit ([`run_cli_bake`]).
//!
//! JSON mutations know glTF's structure: numbers become non-finite-looking, huge, negative or
//! zero; arrays are shortened or emptied; indices (accessors, buffer views, nodes, meshes,
//! materials, scenes) point one past the end or far away; accessor counts, offsets, component
//! types and types change; node trees grow cycles and deep DAGs (2^k paths from k nodes); buffer
//! URIs name files outside the directory, devices, schemes and broken `data:` URIs; and the
//! embedded buffer's bytes get NaN, huge and out-of-range values.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_formats::Pack;
use furbake_import::{ImportSettings, import_gltf_slice};
use serde_json::{Value, json};

use crate::rng::Rng;

const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 with padding.
pub fn base64_encode(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(B64[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Standard base64 (padding optional); `None` on any other character.
pub fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in text.bytes().filter(|&c| c != b'=') {
        let v = B64.iter().position(|&x| x == c)? as u32;
        acc = acc << 6 | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Some(out)
}

const DATA_PREFIX: &str = "data:application/octet-stream;base64,";

/// A GLB taken apart: its JSON and its binary chunk.
#[derive(Clone, Debug)]
pub struct Glb {
    /// The JSON chunk, parsed.
    pub json: Value,
    /// The BIN chunk, if any.
    pub bin: Option<Vec<u8>>,
}

impl Glb {
    /// Parses a well-formed GLB; `None` otherwise.
    pub fn parse(bytes: &[u8]) -> Option<Glb> {
        if bytes.get(0..4)? != b"glTF" {
            return None;
        }
        let json_len = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
        let json = serde_json::from_slice(bytes.get(20..20 + json_len)?).ok()?;
        let at = 20 + json_len;
        let bin = match bytes.get(at..at + 8) {
            Some(h) => {
                let n = u32::from_le_bytes(h[0..4].try_into().ok()?) as usize;
                Some(bytes.get(at + 8..at + 8 + n)?.to_vec())
            }
            None => None,
        };
        Some(Glb { json, bin })
    }

    /// The GLB bytes (chunks padded to 4 bytes, lengths right).
    pub fn emit(&self) -> Vec<u8> {
        let mut json = serde_json::to_vec(&self.json).unwrap_or_default();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut out = b"glTF".to_vec();
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        if let Some(bin) = &self.bin {
            let mut bin = bin.clone();
            while !bin.len().is_multiple_of(4) {
                bin.push(0);
            }
            out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
            out.extend_from_slice(b"BIN\0");
            out.extend_from_slice(&bin);
        }
        let total = out.len() as u32;
        out[8..12].copy_from_slice(&total.to_le_bytes());
        out
    }
}

fn len_of(json: &Value, key: &str) -> usize {
    json.get(key).and_then(Value::as_array).map_or(0, Vec::len)
}

/// An index into an array of `n`: usually in range, often one past it, sometimes absurd.
fn index(rng: &mut Rng, n: usize) -> Value {
    match rng.below(6) {
        0 => json!(n),
        1 => json!(*rng.pick(&[-1i64, 4_294_967_295, 4_294_967_296, 9_007_199_254_740_991])),
        2 => json!(n + 1 + rng.below(100)),
        _ => json!(rng.below(n.max(1))),
    }
}

/// A replacement for a JSON number.
fn number(rng: &mut Rng, near: f64) -> Value {
    match rng.below(8) {
        0 => json!(*rng.pick(&[1e308, -1e308, 1e39, 3.5e38, -3.5e38, 1e-320, 5e-324])),
        1 => json!(*rng.pick(&[0i64, -1, 1, 2, 3, 4, 255, 65_535, 4_294_967_295, 9_007_199_254_740_993])),
        2 => json!(-near),
        3 => json!(near * 1e9),
        4 => json!(near + 1.0),
        5 => json!((near as i64).saturating_mul(1000)),
        6 => Value::Null,
        _ => json!(near * 0.5),
    }
}

/// Every path (object keys and array indices) to a value inside `v`.
fn paths(v: &Value, prefix: &mut Vec<Value>, out: &mut Vec<Vec<Value>>) {
    out.push(prefix.clone());
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                prefix.push(json!(k));
                paths(x, prefix, out);
                prefix.pop();
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                prefix.push(json!(i));
                paths(x, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn at_path<'a>(v: &'a mut Value, path: &[Value]) -> Option<&'a mut Value> {
    let mut cur = v;
    for p in path {
        cur = match p {
            Value::String(k) => cur.get_mut(k.as_str())?,
            Value::Number(i) => cur.get_mut(i.as_u64()? as usize)?,
            _ => return None,
        };
    }
    Some(cur)
}

const INDEX_KEYS: [(&str, &str); 9] = [
    ("bufferView", "bufferViews"),
    ("buffer", "buffers"),
    ("indices", "accessors"),
    ("POSITION", "accessors"),
    ("NORMAL", "accessors"),
    ("mesh", "meshes"),
    ("material", "materials"),
    ("scene", "scenes"),
    ("source", "images"),
];

/// One generic mutation anywhere in the document.
fn mutate_anywhere(rng: &mut Rng, doc: &mut Value) {
    let mut all = Vec::new();
    paths(doc, &mut Vec::new(), &mut all);
    let path = rng.pick(&all).clone();
    let key = path.last().and_then(Value::as_str).unwrap_or("").to_owned();
    let index_target = INDEX_KEYS.iter().find(|(k, _)| *k == key).map(|(_, t)| *t);
    let n_target = index_target.map_or(0, |t| len_of(doc, t));
    let Some(v) = at_path(doc, &path) else { return };
    match v {
        Value::Number(x) if index_target.is_some() && rng.chance(2, 3) => *v = index(rng, n_target),
        Value::Number(x) => {
            let near = x.as_f64().unwrap_or(1.0);
            *v = number(rng, near);
        }
        Value::Array(a) => match rng.below(4) {
            0 => a.clear(),
            1 => {
                let n = rng.below(a.len() + 1);
                a.truncate(n);
            }
            2 if !a.is_empty() => {
                let x = a[rng.below(a.len())].clone();
                a.push(x);
            }
            _ => a.reverse(),
        },
        Value::Object(m) if !m.is_empty() => {
            let keys: Vec<String> = m.keys().cloned().collect();
            m.remove(rng.pick(&keys));
        }
        Value::String(s) => {
            *s = rng.pick(&["", "VEC2", "MAT4", "SCALAR", "x", "\u{0}", "é", "BLEND", "MASK"]).to_string()
        }
        Value::Bool(b) => *b = !*b,
        _ => *v = json!(rng.below(3)),
    }
}

/// The node graph made hostile: a cycle, a deep DAG, a huge or degenerate transform.
fn mutate_nodes(rng: &mut Rng, doc: &mut Value) {
    let Some(nodes) = doc.get_mut("nodes").and_then(Value::as_array_mut) else { return };
    let n = nodes.len();
    if n == 0 {
        return;
    }
    match rng.below(5) {
        0 => {
            // A cycle (a node its own descendant).
            let k = rng.below(n);
            nodes[k]["children"] = json!([rng.below(n)]);
        }
        1 => {
            // A DAG of `depth` levels, each node pointing twice at the next: 2^depth paths.
            let depth = 8 + rng.below(40);
            let mesh = nodes.iter().find_map(|x| x.get("mesh").cloned()).unwrap_or(json!(0));
            let first = n;
            for d in 0..depth {
                let next = first + d + 1;
                let mut node = json!({ "children": [next, next] });
                if d + 1 == depth {
                    node = json!({ "mesh": mesh });
                }
                nodes.push(node);
            }
            if let Some(scene) = doc.get_mut("scenes").and_then(|s| s.get_mut(0)) {
                scene["nodes"] = json!([first]);
            }
        }
        2 => {
            let k = rng.below(n);
            let s = *rng.pick(&[0.0, -1.0, 1e-30, 1e30, 3e38]);
            nodes[k]["scale"] = json!([s, s, s]);
        }
        3 => {
            let k = rng.below(n);
            nodes[k]["matrix"] = json!([0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
            if rng.chance(1, 2) {
                nodes[k]["matrix"][15] = json!(1);
                nodes[k]["matrix"][0] = json!(-1e38);
            }
        }
        _ => {
            let k = rng.below(n);
            nodes[k]["rotation"] = json!([0, 0, 0, 0]);
        }
    }
}

/// Accessor fields: count, offset, component type, type, sparse.
fn mutate_accessor(rng: &mut Rng, doc: &mut Value) {
    let n_views = len_of(doc, "bufferViews");
    let Some(accs) = doc.get_mut("accessors").and_then(Value::as_array_mut) else { return };
    if accs.is_empty() {
        return;
    }
    let k = rng.below(accs.len());
    let a = &mut accs[k];
    let count = a.get("count").and_then(Value::as_u64).unwrap_or(1);
    match rng.below(7) {
        0 => a["count"] = json!(*rng.pick(&[0, 1, count + 1, count * 2, count * 1000, 1 << 31, u32::MAX as u64])),
        1 => a["byteOffset"] = json!(*rng.pick(&[1, 2, 3, 4, 1 << 20, u32::MAX as u64])),
        2 => a["componentType"] = json!(*rng.pick(&[5120, 5121, 5122, 5123, 5125, 5126, 0, 5124])),
        3 => a["type"] = json!(*rng.pick(&["SCALAR", "VEC2", "VEC3", "VEC4", "MAT4", "MAT2"])),
        4 => a["bufferView"] = index(rng, n_views),
        5 => {
            a["sparse"] = json!({
                "count": rng.below(8) + 1,
                "indices": { "bufferView": 0, "componentType": 5125 },
                "values": { "bufferView": 0 }
            })
        }
        _ => a["normalized"] = json!(true),
    }
}

/// Buffer views and buffers: lengths, offsets, strides, URIs.
fn mutate_buffers(rng: &mut Rng, doc: &mut Value) {
    if rng.chance(1, 2) {
        let Some(views) = doc.get_mut("bufferViews").and_then(Value::as_array_mut) else { return };
        if views.is_empty() {
            return;
        }
        let k = rng.below(views.len());
        let v = &mut views[k];
        let len = v.get("byteLength").and_then(Value::as_u64).unwrap_or(4);
        match rng.below(3) {
            0 => v["byteLength"] = json!(*rng.pick(&[0, 1, len - len.min(1), len + 1, len * 4, u32::MAX as u64])),
            1 => v["byteOffset"] = json!(*rng.pick(&[1, 3, len, u32::MAX as u64])),
            _ => v["byteStride"] = json!(*rng.pick(&[0, 1, 3, 4, 252, 256, 1 << 20])),
        }
    } else {
        let Some(bufs) = doc.get_mut("buffers").and_then(Value::as_array_mut) else { return };
        if bufs.is_empty() {
            return;
        }
        let b = &mut bufs[0];
        match rng.below(3) {
            0 => {
                b["uri"] = json!(*rng.pick(&[
                    "../../../../etc/passwd",
                    "/etc/passwd",
                    "%2Fetc%2Fpasswd",
                    "..%2F..%2Fetc%2Fpasswd",
                    "%2e%2e/%2e%2e/etc/passwd",
                    "/dev/zero",
                    "file:///etc/passwd",
                    "http://example.invalid/x.bin",
                    "missing.bin",
                    "sub\\..\\..\\x.bin",
                    "data:application/octet-stream;base64,!!!!",
                    "data:application/octet-stream;base64,AAA",
                    "data:text/plain,hello",
                    "",
                    ".",
                ]))
            }
            1 => {
                let len = b.get("byteLength").and_then(Value::as_u64).unwrap_or(4);
                b["byteLength"] = json!(*rng.pick(&[0, 1, len + 1, len * 2, u32::MAX as u64, 1u64 << 40]));
            }
            _ => {
                b.as_object_mut().map(|m| m.remove("uri"));
            }
        }
    }
}

/// Bytes of an embedded buffer: floats made NaN, infinite or huge, indices out of range.
fn mutate_buffer_bytes(rng: &mut Rng, bytes: &mut [u8]) {
    for _ in 0..1 + rng.below(8) {
        if bytes.len() < 4 {
            return;
        }
        let at = rng.below(bytes.len() / 4) * 4;
        let v: u32 = match rng.below(4) {
            0 => rng.interesting_f32(1.0).to_bits(),
            1 => rng.interesting_u32(1000),
            2 => {
                (rng.interesting_u32(100) & 0xFFFF)
                    | (u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap_or([0; 4])) & 0xFFFF_0000)
            }
            _ => rng.next_u64() as u32,
        };
        bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
    }
}

/// One structure-aware mutation of a glTF document (`bin`: a GLB's binary chunk, else the
/// first buffer's `data:` URI is decoded, mutated and re-encoded).
pub fn mutate_json(rng: &mut Rng, doc: &mut Value, bin: Option<&mut Vec<u8>>) {
    match rng.below(10) {
        0..=2 => mutate_anywhere(rng, doc),
        3 => mutate_nodes(rng, doc),
        4 | 5 => mutate_accessor(rng, doc),
        6 => mutate_buffers(rng, doc),
        7 => {
            // A mesh primitive's mode or attributes.
            if let Some(p) = doc.pointer_mut("/meshes/0/primitives/0") {
                match rng.below(3) {
                    0 => p["mode"] = json!(*rng.pick(&[0, 1, 2, 3, 4, 5, 6, 7, 100])),
                    1 => {
                        p.get_mut("attributes").and_then(Value::as_object_mut).map(|m| m.remove("POSITION"));
                    }
                    _ => p["targets"] = json!([{ "POSITION": 0 }]),
                }
            }
        }
        _ => match bin {
            Some(bin) => mutate_buffer_bytes(rng, bin),
            None => {
                let uri = doc.pointer("/buffers/0/uri").and_then(Value::as_str).unwrap_or("");
                if let Some(mut bytes) = uri.strip_prefix(DATA_PREFIX).and_then(base64_decode) {
                    mutate_buffer_bytes(rng, &mut bytes);
                    doc["buffers"][0]["uri"] = json!(format!("{DATA_PREFIX}{}", base64_encode(&bytes)));
                }
            }
        },
    }
}

/// Byte-level mutation of any file: bytes flipped, 32-bit words set to interesting values
/// (GLB chunk lengths among them), the file truncated or extended.
pub fn mutate_bytes(rng: &mut Rng, bytes: &mut Vec<u8>) {
    match rng.below(4) {
        0 => {
            for _ in 0..1 + rng.below(16) {
                let at = rng.below(bytes.len());
                if let Some(b) = bytes.get_mut(at) {
                    *b ^= 1 << rng.below(8);
                }
            }
        }
        1 => {
            let words = [8usize, 12, 16];
            let at = if rng.chance(1, 2) { *rng.pick(&words) } else { rng.below(bytes.len() / 4) * 4 };
            if at + 4 <= bytes.len() {
                let near = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap_or([0; 4]));
                bytes[at..at + 4].copy_from_slice(&rng.interesting_u32(near).to_le_bytes());
            }
        }
        2 => bytes.truncate(rng.below(bytes.len() + 1)),
        _ => {
            let at = rng.below(bytes.len() + 1);
            let n = 1 + rng.below(64);
            let fill = rng.next_u64() as u8;
            bytes.splice(at..at, std::iter::repeat_n(fill, n));
        }
    }
}

/// A mutant of `seed` (a `.gltf` JSON or a `.glb`): structure-aware most of the time, raw
/// bytes otherwise.
pub fn mutate_gltf(rng: &mut Rng, seed: &[u8]) -> Vec<u8> {
    let rounds = *rng.pick(&[1, 1, 2, 3]);
    let structured = rng.chance(4, 5);
    let mut out = if let (true, Some(mut glb)) = (structured, Glb::parse(seed)) {
        for _ in 0..rounds {
            mutate_json(rng, &mut glb.json, glb.bin.as_mut());
        }
        glb.emit()
    } else if let (true, Ok(mut doc)) = (structured, serde_json::from_slice::<Value>(seed)) {
        for _ in 0..rounds {
            mutate_json(rng, &mut doc, None);
        }
        serde_json::to_vec(&doc).unwrap_or_default()
    } else {
        let mut bytes = seed.to_vec();
        for _ in 0..rounds {
            mutate_bytes(rng, &mut bytes);
        }
        bytes
    };
    if structured && rng.chance(1, 20) {
        mutate_bytes(rng, &mut out);
    }
    out
}

/// What happened to one glTF mutant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum GltfOutcome {
    /// The importer refused it.
    ImportRejected,
    /// Imported; the bake refused it (settings against the mesh, no furry triangle, ...).
    BakeRejected,
    /// Imported and baked; the pack verifies.
    BakedAndVerified,
    /// Imported; too large to bake in a fuzz case (skipped).
    Imported,
}

/// The tiny bake every imported mutant gets (16² × 2 layers, prisms).
pub fn fuzz_bake_settings() -> BakeSettings {
    let mut s = BakeSettings::preset("fur").expect("the fur preset exists");
    s.volume.resolution = 16;
    s.volume.layers = 2;
    s.topologies = vec!["prisms".into()];
    s
}

/// Imports `bytes`; bakes what imports (meshes up to 50,000 triangles) and verifies the pack.
/// `Err` is a property violation: a bake that succeeded but wrote a pack `verify` refuses.
pub fn run_gltf(bytes: &[u8], name: &str) -> Result<GltfOutcome, String> {
    let Ok(mesh) = import_gltf_slice(bytes, name, None, &ImportSettings::default()) else {
        return Ok(GltfOutcome::ImportRejected);
    };
    if mesh.mesh.triangles.len() > 50_000 {
        return Ok(GltfOutcome::Imported);
    }
    let Ok(baked) =
        bake(&mesh, name, &fuzz_bake_settings().plan().expect("the harness's settings are valid"), &mut NoProgress)
    else {
        return Ok(GltfOutcome::BakeRejected);
    };
    let pack = Pack::from_bytes(&baked.to_writer().to_bytes()).map_err(|e| format!("baked pack: {e}"))?;
    crate::packs::verify(&pack)
        .map_err(|(o, e)| format!("the bake succeeded but its pack fails verify: {o:?}: {e}"))?;
    Ok(GltfOutcome::BakedAndVerified)
}

/// The `furbake bake` binary's verdict on one mutant.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CliOutcome {
    /// Exit code (0, 1 or 2 when all is well).
    pub code: i32,
}

/// Runs `furbake bake` on `bytes` (written as `input` in a fresh directory) as a child process
/// with an address-space limit of `max_memory_mib` and a wall-time limit; `Err` says what went
/// wrong: a signal (an abort, a crash, the memory limit), the time limit, an exit code other than
/// 0/1/2, a panic message, an output file after a failure, a leftover temporary file, or an
/// output that `furbake verify` refuses.
pub fn run_cli_bake(
    furbake: &Path,
    bytes: &[u8],
    input: &str,
    max_memory_mib: u64,
    limit: Duration,
) -> Result<CliOutcome, String> {
    let dir = tempfile::tempdir().map_err(|e| format!("tempdir: {e}"))?;
    std::fs::write(dir.path().join(input), bytes).map_err(|e| format!("write input: {e}"))?;
    let out = dir.path().join("out.fbk");
    let args = [
        "bake",
        input,
        "-o",
        "out.fbk",
        "--resolution",
        "16",
        "--layers",
        "2",
        "--topology",
        "prisms",
        "-q",
        "--threads",
        "1",
    ];
    let (code, stderr) = run_limited(furbake, &args, dir.path(), max_memory_mib, limit)?;
    if stderr.contains("panicked") {
        return Err(format!("exit {code} with a panic: {stderr}"));
    }
    if !matches!(code, 0..=2) {
        return Err(format!("exit code {code}: {stderr}"));
    }
    let mut left: Vec<String> = std::fs::read_dir(dir.path())
        .map_err(|e| format!("list: {e}"))?
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n != input && !(code == 0 && n == "out.fbk"))
        .collect();
    left.sort();
    if !left.is_empty() {
        return Err(format!("exit {code} left {left:?} behind: {stderr}"));
    }
    if code == 0 {
        let (v, verr) = run_limited(furbake, &["verify", "out.fbk"], dir.path(), max_memory_mib, limit)?;
        if v != 0 {
            return Err(format!("bake exited 0 but verify exits {v}: {verr}"));
        }
    } else if out.exists() {
        return Err(format!("exit {code} but out.fbk exists"));
    }
    Ok(CliOutcome { code })
}

/// Runs `program args` in `dir` under an address-space limit and a wall-time limit; returns the
/// exit code (`Err` for a signal or the time limit) and stderr.
pub fn run_limited(
    program: &Path,
    args: &[&str],
    dir: &Path,
    max_memory_mib: u64,
    limit: Duration,
) -> Result<(i32, String), String> {
    let mut cmd = Command::new(program);
    cmd.args(args).current_dir(dir).stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped());
    crate::limit_memory(&mut cmd, max_memory_mib);
    let mut child = cmd.spawn().map_err(|e| format!("spawn {}: {e}", program.display()))?;
    let mut stderr = child.stderr.take();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        if let Some(e) = stderr.as_mut() {
            let _ = std::io::Read::read_to_string(e, &mut s);
        }
        s
    });
    let started = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if started.elapsed() > limit => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!("still running after {limit:?}"));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(5)),
            Err(e) => return Err(format!("wait: {e}")),
        }
    };
    let stderr = reader.join().unwrap_or_default();
    match status.code() {
        Some(code) => Ok((code, stderr)),
        None => Err(format!("killed by a signal ({status}): {stderr}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_and_glb_round_trip() {
        for n in 0..10 {
            let bytes: Vec<u8> = (0..n as u8).map(|i| i.wrapping_mul(37)).collect();
            assert_eq!(base64_decode(&base64_encode(&bytes)).as_deref(), Some(&bytes[..]));
        }
        let glb = Glb { json: json!({ "asset": { "version": "2.0" } }), bin: Some(vec![1, 2, 3]) };
        let back = Glb::parse(&glb.emit()).expect("a well-formed GLB");
        assert_eq!(back.json, glb.json);
        assert_eq!(back.bin, Some(vec![1, 2, 3, 0]));
    }
}
