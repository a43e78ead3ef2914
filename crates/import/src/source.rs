//! Reading the asset: splitting a GLB container (validated with checked arithmetic, never
//! trusting its header), parsing and validating the JSON with the `gltf` crate, refusing
//! unsupported required extensions *before* the `gltf` crate sees them, and loading every buffer
//! (GLB binary chunk, base64 `data:` URI or external file, the last only from inside the asset
//! roots: see `external`) with the input hash computed over the main file's bytes then each
//! external buffer file's bytes read (its first `byteLength`), in buffer order.

use std::io::Read;
use std::path::Path;

use gltf::json;
use sha2::{Digest, Sha256};

use crate::ImportError;
use crate::external::{ExternalFiles, ExternalRef, Need};
use crate::limits::MAX_FILE_BYTES;

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Required extensions that change nothing this importer reads (geometry, node transforms,
/// `COLOR_0`, `TEXCOORD_0`, base colour factor, material names), so a file that requires them
/// still imports correctly.
const HARMLESS_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_clearcoat",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_iridescence",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_unlit",
    "KHR_materials_variants",
    "KHR_materials_volume",
    "KHR_materials_anisotropy",
    "KHR_materials_dispersion",
    "KHR_texture_basisu",
    "KHR_texture_transform",
    "EXT_texture_webp",
    "EXT_texture_avif",
];

/// A parsed, validated asset with its buffers loaded.
pub(crate) struct Asset {
    /// The glTF JSON, validated by the `gltf` crate (indices in range, enums known); the
    /// importer still reads it with `get()` so a validation gap cannot become a panic.
    pub root: json::Root,
    /// Buffer contents, each exactly its declared `byteLength` long.
    pub buffers: Vec<Vec<u8>>,
    /// Bytes hashed: the main file plus every external buffer file.
    pub input_bytes: u64,
    /// SHA-256 state over the main file then each external buffer file, in buffer order; the
    /// importer appends the external images it samples, then finalises it.
    pub input_hasher: Sha256,
    /// Non-fatal findings (ignored extensions and the like).
    pub warnings: Vec<String>,
    /// The external buffer files read, in buffer order (name relative to the glTF's directory,
    /// bytes read, their SHA-256).
    pub files: Vec<crate::InputFile>,
}

#[derive(Debug)]
struct Glb<'a> {
    json: &'a [u8],
    bin: Option<&'a [u8]>,
}

fn read_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Splits a GLB container into its JSON and BIN chunks, checking every length against the data.
fn split_glb(bytes: &[u8]) -> Result<Glb<'_>, String> {
    let version = read_u32(bytes, 4).ok_or("GLB header truncated (fewer than 12 bytes)")?;
    if version != 2 {
        return Err(format!("GLB container version {version} (only version 2 is glTF 2.0)"));
    }
    let declared = read_u32(bytes, 8).ok_or("GLB header truncated (fewer than 12 bytes)")? as usize;
    if declared > bytes.len() {
        return Err(format!("GLB header declares {declared} bytes but the file has only {}", bytes.len()));
    }
    let bytes = &bytes[..declared];
    let mut offset = 12usize;
    let mut json = None;
    let mut bin = None;
    let mut index = 0;
    while offset < bytes.len() {
        let (len, kind) = match (read_u32(bytes, offset), read_u32(bytes, offset + 4)) {
            (Some(l), Some(k)) => (l as usize, k),
            _ => return Err(format!("GLB chunk {index} header truncated at byte {offset}")),
        };
        let start = offset + 8;
        let end = start
            .checked_add(len)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| format!("GLB chunk {index} ({len} bytes at byte {start}) runs past the end of the file"))?;
        match (index, kind) {
            (0, CHUNK_JSON) => json = Some(&bytes[start..end]),
            (0, _) => return Err(format!("the first GLB chunk has type {kind:#010x}, not JSON")),
            (1, CHUNK_BIN) => bin = Some(&bytes[start..end]),
            _ => {} // Unknown chunks are skipped, as the GLB spec requires.
        }
        offset = end;
        index += 1;
    }
    let json = json.ok_or("the GLB container has no JSON chunk")?;
    Ok(Glb { json, bin })
}

/// Runs the `gltf` crate's validation (indices in range, enums known, sizes sane), minus the
/// findings this importer handles itself with better errors: a missing `POSITION` (reported per
/// primitive as [`ImportError::MissingPosition`]), missing accessor `min`/`max` (not needed: bounds
/// are computed, so malformed ones are ignored too), and required extensions (already checked against [`HARMLESS_EXTENSIONS`]).
fn validate(root: &json::Root) -> Result<(), String> {
    use json::validation::{Error, Validate};
    // gltf-json 1.4.1 indexes `accessors[POSITION]` unchecked in its primitive hook
    // (mesh.rs:151) and panics on an out-of-range index; check that index first.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = primitive.attributes.get(&json::validation::Checked::Valid(json::mesh::Semantic::Positions));
            if let Some(index) = position.filter(|i| i.value() >= root.accessors.len()) {
                return Err(format!(
                    "meshes[{m}].primitives[{p}].attributes[\"POSITION\"]: accessor {} does not exist ({} accessors)",
                    index.value(),
                    root.accessors.len()
                ));
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(root, json::Path::new, &mut |path, error| {
        let path = path().to_string();
        let ours = match error {
            Error::Missing => path.ends_with("[\"POSITION\"]") || path.ends_with(".min") || path.ends_with(".max"),
            Error::Invalid => path.ends_with(".min") || path.ends_with(".max"),
            Error::Unsupported => path.starts_with("extensionsRequired"),
            _ => false,
        };
        if !ours {
            errors.push(format!("{path}: {error}"));
        }
    });
    if errors.is_empty() {
        return Ok(());
    }
    let more = if errors.len() > 5 { format!(" (and {} more)", errors.len() - 5) } else { String::new() };
    errors.truncate(5);
    Err(format!("validation failed: {}{more}", errors.join("; ")))
}

fn extension_hint(extension: &str) -> &'static str {
    match extension {
        "KHR_draco_mesh_compression" | "EXT_meshopt_compression" | "KHR_mesh_quantization" => {
            " (re-export without mesh compression/quantization, e.g. `gltf-transform copy` or \
             `gltfpack -noq`, or from your DCC tool with compression off)"
        }
        _ => "",
    }
}

/// The glTF JSON as `json::Root`, or the problem and where it was found: the JSON path of the
/// value that does not fit the schema (`cameras[0]` for a camera without its required `type`),
/// then serde's line and column, so a file with one bad object among thousands names it.
fn parse_root(json_bytes: &[u8]) -> Result<json::Root, String> {
    let mut de = serde_json::Deserializer::from_slice(json_bytes);
    let root: json::Root = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = e.path().to_string();
        if path == "." { format!("JSON: {}", e.inner()) } else { format!("JSON at {path}: {}", e.inner()) }
    })?;
    de.end().map_err(|e| format!("JSON: {e}"))?;
    Ok(root)
}

/// Parses `bytes` (a `.glb` or `.gltf`) and loads its buffers. `file` names the input in errors;
/// `external` resolves relative buffer URIs and confines them to the asset roots.
pub(crate) fn load_asset(bytes: &[u8], file: &Path, external: ExternalFiles<'_>) -> Result<Asset, ImportError> {
    let invalid = |message: String| ImportError::InvalidGltf { file: file.to_path_buf(), message };
    let (json_bytes, bin) = if bytes.starts_with(GLB_MAGIC) {
        let glb = split_glb(bytes).map_err(invalid)?;
        (glb.json, glb.bin)
    } else {
        (bytes, None)
    };
    let root = parse_root(json_bytes).map_err(invalid)?;

    // Refuse unsupported required extensions before validation, which would report them
    // obscurely (or, for compressed meshes, as missing accessors).
    for extension in &root.extensions_required {
        if !HARMLESS_EXTENSIONS.contains(&extension.as_str()) {
            return Err(ImportError::UnsupportedExtension {
                file: file.to_path_buf(),
                extension: extension.clone(),
                hint: extension_hint(extension).to_string(),
            });
        }
    }
    let mut warnings = Vec::new();
    for extension in &root.extensions_used {
        if extension == "EXT_mesh_gpu_instancing" {
            warnings.push(format!(
                "{}: EXT_mesh_gpu_instancing is used but ignored: only each node's own mesh is imported",
                file.display()
            ));
        }
    }

    validate(&root).map_err(invalid)?;

    let mut hasher = Sha256::new();
    hasher.update(bytes);
    let mut input_bytes = bytes.len() as u64;
    let mut buffers = Vec::with_capacity(root.buffers.len());
    let mut files = Vec::new();
    for (index, buffer) in root.buffers.iter().enumerate() {
        let buffer_error = |message: String| ImportError::Buffer { file: file.to_path_buf(), buffer: index, message };
        let declared = buffer.byte_length.0;
        if declared > MAX_FILE_BYTES {
            return Err(ImportError::TooLarge {
                file: file.to_path_buf(),
                what: format!("buffer {index}'s byteLength"),
                count: declared,
                limit: MAX_FILE_BYTES,
            });
        }
        let mut data: Vec<u8> = match &buffer.uri {
            None => match (index, bin) {
                (0, Some(bin)) => bin.to_vec(),
                _ => return Err(buffer_error("has no uri and there is no GLB binary chunk for it".to_string())),
            },
            Some(uri) if uri.starts_with("data:") => {
                let comma = uri.find(',').ok_or_else(|| buffer_error("data: URI without a ','".to_string()))?;
                if !uri[..comma].ends_with(";base64") {
                    return Err(buffer_error("only base64 data: URIs are supported".to_string()));
                }
                crate::base64::decode(&uri[comma + 1..]).map_err(|e| buffer_error(format!("data: URI: {e}")))?
            }
            Some(uri) => {
                // Exactly `declared` bytes (checked against the limit above), or a refusal.
                let (data, name) =
                    external.read(uri, Need::Prefix(declared)).map_err(|problem| ImportError::ExternalFile {
                        file: file.to_path_buf(),
                        referrer: ExternalRef::Buffer(index),
                        uri: uri.as_str().into(),
                        problem: Box::new(problem),
                    })?;
                hasher.update(&data);
                input_bytes += data.len() as u64;
                files.push(crate::InputFile::external(external.base_dir, name, &data));
                data
            }
        };
        if (data.len() as u64) < declared {
            return Err(buffer_error(format!("holds {} bytes but declares byteLength {declared}", data.len())));
        }
        data.truncate(declared as usize);
        buffers.push(data);
    }
    Ok(Asset { root, buffers, input_bytes, input_hasher: hasher, warnings, files })
}

/// The external files the glTF at `path` names (buffer and image URIs that are not `data:`),
/// percent-decoded and joined to its directory, without reading them or validating anything
/// else: what a caller planning outputs must not write over before the import runs. A URI the
/// import would refuse (a scheme, an absolute path, a bad escape) is left out — the import
/// refuses it — and so is everything of a file that cannot be read or parsed.
pub(crate) fn referenced_files(path: &Path) -> Vec<std::path::PathBuf> {
    let Some(json) = json_chunk(path) else { return Vec::new() };
    let Ok(doc) = serde_json::from_slice::<serde_json::Value>(&json) else { return Vec::new() };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let uris = ["buffers", "images"]
        .into_iter()
        .filter_map(|key| doc.get(key).and_then(|v| v.as_array()))
        .flatten()
        .filter_map(|item| item.get("uri").and_then(|u| u.as_str()));
    uris.filter(|uri| !uri.starts_with("data:"))
        .filter_map(|uri| crate::external::relative_uri_path(uri).map(|p| dir.join(p)))
        .collect()
}

/// The JSON of the glTF at `path` and nothing more: a `.glb`'s 12-byte header and first chunk
/// (its binary chunk, which may be most of the file, is not read), or a `.gltf` whole, within
/// [`MAX_FILE_BYTES`]; `None` when it cannot be read.
fn json_chunk(path: &Path) -> Option<Vec<u8>> {
    let (mut file, len) = furbake_formats::input::open_regular(path).ok()?;
    if len > MAX_FILE_BYTES {
        return None;
    }
    let mut head = [0u8; 20];
    let got = (&mut file).take(20).read(&mut head).ok()?;
    if got == 20 && head.starts_with(GLB_MAGIC) && read_u32(&head, 16) == Some(CHUNK_JSON) {
        let chunk = u64::from(read_u32(&head, 12)?);
        if 20 + chunk > len {
            return None;
        }
        let mut json = vec![0u8; chunk as usize];
        file.read_exact(&mut json).ok()?;
        return Some(json);
    }
    let mut bytes = head[..got].to_vec();
    file.take(MAX_FILE_BYTES).read_to_end(&mut bytes).ok()?;
    (!bytes.starts_with(GLB_MAGIC)).then_some(bytes)
}

/// Reads the main glTF file the caller named, at most [`MAX_FILE_BYTES`]: opened without
/// blocking and refused unless the opened handle is a regular file (a FIFO or a device such as
/// `/dev/zero` is named as what it is, `furbake_formats::input`), its size checked before
/// reading, and the read bounded by `take`.
pub(crate) fn read_file_limited(path: &Path, file: &Path) -> Result<Vec<u8>, ImportError> {
    let io = |source| ImportError::Io { file: file.to_path_buf(), what: path.to_path_buf(), source };
    let too_large = |count| ImportError::TooLarge {
        file: file.to_path_buf(),
        what: format!("the size of {}", path.display()),
        count,
        limit: MAX_FILE_BYTES,
    };
    let (handle, len) = furbake_formats::input::open_regular(path).map_err(io)?;
    if len > MAX_FILE_BYTES {
        return Err(too_large(len));
    }
    let mut data = Vec::new();
    handle.take(MAX_FILE_BYTES + 1).read_to_end(&mut data).map_err(io)?;
    if data.len() as u64 > MAX_FILE_BYTES {
        return Err(too_large(data.len() as u64));
    }
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn referenced_files_come_from_the_json_alone_for_glb_and_gltf() {
        let dir = tempfile::tempdir().unwrap();
        let json = br#"{"buffers":[{"uri":"data:,x"},{"uri":"ext%20a.bin"},{"uri":"/etc/passwd"}],"images":[{"uri":"t/b.png"}]}  "#;
        let mut glb = b"glTF".to_vec();
        glb.extend_from_slice(&2u32.to_le_bytes());
        glb.extend_from_slice(&((20 + json.len() + 8 + 4) as u32).to_le_bytes());
        glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
        glb.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        glb.extend_from_slice(json);
        glb.extend_from_slice(&4u32.to_le_bytes());
        glb.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        glb.extend_from_slice(&[0; 4]);
        std::fs::write(dir.path().join("m.glb"), &glb).unwrap();
        std::fs::write(dir.path().join("m.gltf"), json).unwrap();
        let want = vec![dir.path().join("ext a.bin"), dir.path().join("t/b.png")];
        assert_eq!(referenced_files(&dir.path().join("m.glb")), want);
        assert_eq!(referenced_files(&dir.path().join("m.gltf")), want);
        assert!(referenced_files(&dir.path().join("missing.glb")).is_empty());
    }

    #[test]
    fn glb_splitting_rejects_lying_lengths() {
        let mut glb = Vec::new();
        glb.extend_from_slice(b"glTF");
        glb.extend_from_slice(&2u32.to_le_bytes());
        glb.extend_from_slice(&0u32.to_le_bytes()); // patched below
        glb.extend_from_slice(&4u32.to_le_bytes());
        glb.extend_from_slice(&CHUNK_JSON.to_le_bytes());
        glb.extend_from_slice(b"{}  ");
        let total = glb.len() as u32;
        glb[8..12].copy_from_slice(&total.to_le_bytes());
        let ok = split_glb(&glb).unwrap();
        assert_eq!(ok.json, b"{}  ");
        assert!(ok.bin.is_none());

        let mut lying = glb.clone();
        lying[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(split_glb(&lying).unwrap_err().contains("runs past the end"));
        let mut long = glb.clone();
        long[8..12].copy_from_slice(&(total + 1).to_le_bytes());
        assert!(split_glb(&long).unwrap_err().contains("declares"));
        let mut v1 = glb.clone();
        v1[4] = 1;
        assert!(split_glb(&v1).unwrap_err().contains("version 1"));
        assert!(split_glb(&glb[..7]).is_err());
    }
}
