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
}

impl Section for BakeManifest {
    const KIND: SectionKind = SectionKind::BAKE_MANIFEST;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        RecordWriter::new(self).finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let m: BakeManifest = Record::parse(payload)?.meta()?;
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
        })
    }
}
