//! The bake manifest: everything needed to reproduce a pack — tool version, the input's name,
//! size and SHA-256, the seed, and every stage parameter as a JSON document.

use serde::{Deserialize, Serialize};

use super::Section;
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// Provenance and parameters of one bake. No timestamps: identical bakes give identical bytes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeManifest {
    /// Name of the tool that wrote the pack (`furbake`).
    pub tool: String,
    /// Version of that tool (`CARGO_PKG_VERSION`).
    pub tool_version: String,
    /// File name of the input mesh (no directories, so moving the input keeps bytes identical).
    pub input_name: String,
    /// Size of the input in bytes (main file plus external buffers).
    pub input_bytes: u64,
    /// Lower-case hex SHA-256 of the input bytes (main file, then external buffers in order).
    pub input_sha256: String,
    /// Name of the preset the settings started from (`fur`, `grass`, ...).
    pub preset: String,
    /// Master seed of every stochastic stage.
    pub seed: u64,
    /// Every stage parameter, as a JSON object (the resolved bake plan).
    pub settings_json: String,
    /// Every file the bake read, in hash order: the glTF, its external buffers, the external
    /// images it sampled — by name relative to the glTF's directory (layout version 2; empty
    /// when read from a version 1 manifest). With `tool_version` and `settings_json` this is the
    /// bake's whole input: a build system can tell from it alone whether a pack is up to date.
    pub inputs: Vec<ManifestInput>,
}

/// One file a bake read, as the manifest records it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ManifestInput {
    /// Name relative to the glTF's directory, `/`-separated (no absolute path, so the pack does
    /// not depend on where the input lies).
    pub name: String,
    /// Bytes read from it.
    pub bytes: u64,
    /// Lower-case hex SHA-256 of those bytes.
    pub sha256: String,
}

/// Layout version 1 of the manifest: version 2 without `inputs`.
#[derive(Deserialize)]
struct ManifestV1 {
    tool: String,
    tool_version: String,
    input_name: String,
    input_bytes: u64,
    input_sha256: String,
    preset: String,
    seed: u64,
    settings_json: String,
}

impl Section for BakeManifest {
    const KIND: SectionKind = SectionKind::BAKE_MANIFEST;
    const VERSION: u16 = 2;

    fn encode(&self) -> Vec<u8> {
        RecordWriter::new(self).finish()
    }

    /// Reads layout 2, or layout 1 (the same fields without `inputs`, which a layout 2 decoder
    /// cannot mistake for layout 2: its input list's length would lie past the end).
    fn decode(payload: &[u8]) -> Result<Self> {
        let record = Record::parse(payload)?;
        let m = match record.meta::<BakeManifest>() {
            Ok(m) => m,
            Err(v2_error) => match record.meta::<ManifestV1>() {
                Ok(v1) => BakeManifest {
                    tool: v1.tool,
                    tool_version: v1.tool_version,
                    input_name: v1.input_name,
                    input_bytes: v1.input_bytes,
                    input_sha256: v1.input_sha256,
                    preset: v1.preset,
                    seed: v1.seed,
                    settings_json: v1.settings_json,
                    inputs: Vec::new(),
                },
                Err(_) => return Err(v2_error),
            },
        };
        serde_json::from_str::<serde_json::Value>(&m.settings_json)
            .map_err(|e| FormatError::invalid(format!("manifest settings are not valid JSON: {e}")))?;
        Ok(m)
    }

    fn summary(&self) -> serde_json::Value {
        let settings =
            serde_json::from_str::<serde_json::Value>(&self.settings_json).unwrap_or(serde_json::Value::Null);
        serde_json::json!({
            "tool": self.tool,
            "tool_version": self.tool_version,
            "input_name": self.input_name,
            "input_bytes": self.input_bytes,
            "input_sha256": self.input_sha256,
            "preset": self.preset,
            "seed": self.seed,
            "settings": settings,
            "inputs": self.inputs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v2() -> BakeManifest {
        BakeManifest {
            tool: "furbake".into(),
            tool_version: "0.1.0".into(),
            input_name: "fox.glb".into(),
            input_bytes: 10,
            input_sha256: "ab".repeat(32),
            preset: "fur".into(),
            seed: 7,
            settings_json: "{}".into(),
            inputs: vec![ManifestInput { name: "fox.glb".into(), bytes: 10, sha256: "ab".repeat(32) }],
        }
    }

    #[test]
    fn layout_two_round_trips_and_layout_one_still_reads() {
        let m = v2();
        assert_eq!(BakeManifest::decode(&m.encode()).expect("v2 decodes"), m);
        // A version 1 payload: the same fields without `inputs`.
        #[derive(Serialize)]
        struct V1<'a>(&'a str, &'a str, &'a str, u64, &'a str, &'a str, u64, &'a str);
        let v1 = RecordWriter::new(&V1("furbake", "0.1.0", "fox.glb", 10, &m.input_sha256, "fur", 7, "{}")).finish();
        let read = BakeManifest::decode(&v1).expect("v1 decodes");
        assert_eq!(read, BakeManifest { inputs: Vec::new(), ..m });
        // Neither layout: the v2 error is reported.
        let broken = RecordWriter::new(&(1u8, 2u8)).finish();
        assert!(BakeManifest::decode(&broken).is_err());
    }
}
