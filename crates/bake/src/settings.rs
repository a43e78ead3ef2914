//! The bake plan: one settings struct per stage, presets (`fur`, `grass`), and deep-merged
//! overrides from a config file or `--set key=value` flags. Parse, then plan: [`BakeSettings`] is
//! validated as a whole before any stage runs ([`BakeSettings::plan`] makes a
//! [`crate::validate::BakePlan`]; the ranges are in [`crate::validate`]), and it is what the
//! manifest records.

use furbake_formats::sections::shell_atlas::VolumeParams;
use furbake_formats::sections::spring_topology::{TopologyKind, TopologyParams};
use furbake_grass::{BladeFieldSettings, KeyframeSettings};
use furbake_import::ImportSettings;
use serde::{Deserialize, Serialize};

use furbake_formats::OutOfRange;

use crate::uv_map::UvSettings;
use crate::volume;

/// A bake setting that cannot be used. Blame: the caller (the CLI exits 2). Every message starts
/// with the setting's key.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// A value outside its allowed range (or not finite).
    #[error("{key} = {value} is out of range (allowed: {allowed})")]
    OutOfRange {
        /// Dotted path of the setting, as under the manifest's `settings`.
        key: String,
        /// The value given, as text.
        value: String,
        /// The allowed range or values.
        allowed: String,
    },
    /// A key, name or value that is not understood (unknown key, unknown topology, wrong type,
    /// settings that contradict each other).
    #[error("{key}: {what}")]
    Invalid {
        /// Dotted path of the setting (or `settings` when no single key is to blame).
        key: String,
        /// What is wrong.
        what: String,
    },
    /// A value that is in range alone but asks for more than the bake accepts (memory, counts).
    #[error("{key} = {value} asks for {amount} {what}, above the limit of {limit}")]
    TooLarge {
        /// Dotted path of the setting to lower.
        key: String,
        /// The value given, as text (with the other settings it combines with).
        value: String,
        /// What would be counted.
        what: String,
        /// How many.
        amount: u64,
        /// The largest count accepted.
        limit: u64,
    },
}

impl SettingsError {
    /// The dotted key of the offending setting.
    pub fn key(&self) -> &str {
        match self {
            SettingsError::OutOfRange { key, .. }
            | SettingsError::Invalid { key, .. }
            | SettingsError::TooLarge { key, .. } => key,
        }
    }

    pub(crate) fn range(key: impl Into<String>, value: impl std::fmt::Display, allowed: impl Into<String>) -> Self {
        SettingsError::OutOfRange { key: key.into(), value: value.to_string(), allowed: allowed.into() }
    }

    pub(crate) fn prefixed(prefix: &str, e: OutOfRange) -> Self {
        SettingsError::OutOfRange { key: format!("{prefix}.{}", e.field), value: e.value, allowed: e.allowed }
    }
}

/// Settings of the shell geometry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ShellSettings {
    /// Distance from the skin to the outermost shell, in metres (scene units). `None` = a
    /// fraction of the mesh's bounding-box diagonal given by `auto_fur_length_fraction`.
    pub fur_length_m: Option<f32>,
    /// Fur length as a fraction of the bounding-box diagonal when `fur_length_m` is unset.
    /// `fur` preset 0.015, `grass` 0.04.
    pub auto_fur_length_fraction: f32,
}

/// Every parameter of one bake.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct BakeSettings {
    /// Preset the settings started from (recorded in the manifest).
    pub preset: String,
    /// Master seed; every stochastic stage derives its own stream from it. Default 1.
    pub seed: u64,
    /// How the glTF is read (fur mask, welding).
    pub import: ImportSettings,
    /// The hair volume and the atlases sliced from it.
    pub volume: VolumeParams,
    /// Shell geometry.
    pub shells: ShellSettings,
    /// Per-triangle UV map.
    pub uv: UvSettings,
    /// Grass blades (grass thesis): a blade field scattered over the furry triangles and the
    /// keyframe table that animates it. `None` (the default of both presets) bakes no blades;
    /// `--blades DENSITY` turns it on.
    pub blades: Option<BladeSettings>,
    /// Mass–spring topologies to bake (fur thesis §3.4.1), by name: `chain`, `reduced-chain`,
    /// `sticks`, `spring-sticks`, `prisms`, `separable-sticks`, `separable-spring-sticks`,
    /// `separable-prisms`. Default none.
    pub topologies: Vec<String>,
    /// Masses, stiffness and damping of the topologies. Their `fur_length_m` and `chain_layers`
    /// are taken from the shells (fur length, layer count) so the physics matches the render.
    pub topology: TopologyParams,
}

/// Settings of the grass-blade stages.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct BladeSettings {
    /// Where blades grow and how they are clustered.
    pub field: BladeFieldSettings,
    /// The keyframe table (blade shape, simulated poses, compression).
    pub keyframes: KeyframeSettings,
}

/// Names of the built-in presets.
pub const PRESETS: [&str; 2] = ["fur", "grass"];

impl BakeSettings {
    /// The settings of a named preset (`fur`: 16 layers of 128², undercoat; `grass`: 64 layers of
    /// 64², longer blades, no undercoat).
    pub fn preset(name: &str) -> Result<BakeSettings, SettingsError> {
        let (volume, fraction) = match name {
            "fur" => (volume::fur_preset(), 0.015),
            "grass" => (volume::grass_preset(), 0.04),
            _ => {
                return Err(SettingsError::Invalid {
                    key: "preset".into(),
                    what: format!("unknown preset {name:?} (known: {})", PRESETS.join(", ")),
                });
            }
        };
        Ok(BakeSettings {
            preset: name.to_owned(),
            seed: 1,
            import: ImportSettings::default(),
            volume,
            shells: ShellSettings { fur_length_m: None, auto_fur_length_fraction: fraction },
            uv: UvSettings::default(),
            blades: None,
            topologies: Vec::new(),
            topology: TopologyParams::default(),
        })
    }

    /// Applies `overrides` (a JSON object, e.g. parsed from TOML) on top of these settings: objects
    /// merge key by key, anything else replaces. Unknown keys and values of the wrong type are
    /// errors that name the key. Ranges are not checked here: see [`Self::plan`].
    pub fn with_overrides(&self, overrides: &serde_json::Value) -> Result<BakeSettings, SettingsError> {
        let mut start = self.clone();
        // A patch that configures blades on settings without them starts from the blade defaults,
        // so `--set blades.field.density_per_m2=100` alone turns blades on.
        if start.blades.is_none() && overrides.get("blades").is_some_and(|b| b.is_object()) {
            start.blades = Some(BladeSettings::default());
        }
        let mut base = serde_json::to_value(&start).expect("settings are plain serde structs");
        merge(&mut base, overrides);
        let leaves = leaf_keys(overrides);
        // One key patched (`--set`): blame it; several (a config file): serde's message names the
        // field, the caller names the file.
        let blamed = || if leaves.len() == 1 { leaves[0].clone() } else { "settings".to_owned() };
        // The failing key's dotted path (`volume.resolution`) from the deserializer itself.
        let merged: BakeSettings = serde_path_to_error::deserialize(base).map_err(|e| {
            let path = e.path().to_string();
            let key = match path.trim_start_matches('.') {
                "" | "?" => blamed(),
                path => path.to_owned(),
            };
            SettingsError::Invalid {
                key,
                what: furbake_formats::input::settings_message_in_words(&e.into_inner().to_string()),
            }
        })?;
        // Structs that tolerate unknown fields when read from a pack (`topology`, whose metadata
        // must stay readable when fields are added) would drop a misspelt key silently: every
        // patched key must survive the round trip.
        let back = serde_json::to_value(&merged).expect("settings are plain serde structs");
        if let Some(key) = leaves.iter().find(|k| !has_key(&back, k)) {
            return Err(SettingsError::Invalid { key: key.clone(), what: "unknown key".into() });
        }
        Ok(merged)
    }

    /// The JSON Schema (draft 2020-12) of bake config files (`--config`, a batch's `config`):
    /// every key of these settings, documented, none required — a config patches a preset
    /// (`furbake schema config` prints it). Feature `schema`.
    #[cfg(feature = "schema")]
    pub fn config_schema() -> schemars::Schema {
        furbake_formats::schema::toml_file_schema::<BakeSettings>(
            "furbake bake config",
            "A furbake bake config (TOML, `furbake bake --config FILE`): keys of the bake settings that replace \
             the preset's, table by table (README \"Bake settings\"; `furbake schema config` prints this schema).",
            true,
        )
    }
}

/// The dotted paths of the leaves of a JSON object (`{"a":{"b":1}}` → `a.b`); arrays and scalars
/// are leaves.
fn leaf_keys(v: &serde_json::Value) -> Vec<String> {
    fn walk(v: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
        match v {
            serde_json::Value::Object(m) if !m.is_empty() => {
                for (k, child) in m {
                    let path = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                    walk(child, &path, out);
                }
            }
            _ if !prefix.is_empty() => out.push(prefix.to_owned()),
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(v, "", &mut out);
    out
}

/// True when the dotted `path` names a key of `v`.
fn has_key(v: &serde_json::Value, path: &str) -> bool {
    let mut at = v;
    for k in path.split('.') {
        match at.get(k) {
            Some(next) => at = next,
            None => return false,
        }
    }
    true
}

/// The eight topology kind names, in code order.
pub fn topology_names() -> Vec<&'static str> {
    TopologyKind::KNOWN.iter().filter_map(|k| k.name()).collect()
}

/// Deep-merges `patch` into `base`. A patch object that picks another variant of an enum replaces
/// the base instead of merging into it (the old variant's fields would be unknown to the new one):
/// internally tagged (`import.fur_mask`: a different `source`) or externally tagged
/// (`import.weld_tolerance`: one key each, different).
fn merge(base: &mut serde_json::Value, patch: &serde_json::Value) {
    match (base, patch) {
        (serde_json::Value::Object(b), serde_json::Value::Object(p)) if is_other_variant(b, p) => {
            *b = p.clone();
        }
        (serde_json::Value::Object(b), serde_json::Value::Object(p)) => {
            for (k, v) in p {
                match b.get_mut(k) {
                    Some(slot) if slot.is_object() && v.is_object() => merge(slot, v),
                    _ => {
                        b.insert(k.clone(), v.clone());
                    }
                }
            }
        }
        (b, p) => *b = p.clone(),
    }
}

fn is_other_variant(
    base: &serde_json::Map<String, serde_json::Value>,
    patch: &serde_json::Map<String, serde_json::Value>,
) -> bool {
    let retagged = matches!((base.get("source"), patch.get("source")), (Some(a), Some(b)) if a != b);
    let single = !base.contains_key("source")
        && base.len() == 1
        && patch.len() == 1
        && base.keys().next() != patch.keys().next();
    retagged || single
}

/// Turns `a.b.c=value` into `{"a":{"b":{"c":value}}}`; the value is parsed as JSON when it can
/// be (numbers, booleans, null, arrays), else taken as a string.
pub fn dotted_override(assignment: &str) -> Result<serde_json::Value, SettingsError> {
    let (path, raw) = assignment.split_once('=').ok_or_else(|| SettingsError::Invalid {
        key: assignment.into(),
        what: "expected KEY=VALUE, e.g. volume.layers=32".into(),
    })?;
    let value = serde_json::from_str(raw.trim()).unwrap_or_else(|_| serde_json::Value::String(raw.trim().to_owned()));
    let mut out = value;
    for key in path.trim().split('.').rev() {
        if key.is_empty() {
            return Err(SettingsError::Invalid { key: path.into(), what: "empty key segment".into() });
        }
        out = serde_json::json!({ key: out });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_merge_deeply_and_reject_unknown_keys() {
        let base = BakeSettings::preset("fur").unwrap();
        let s = base.with_overrides(&dotted_override("volume.layers=32").unwrap()).unwrap();
        assert_eq!(s.volume.layers, 32);
        assert_eq!(s.volume.resolution, base.volume.resolution, "untouched fields keep the preset");
        let err = base.with_overrides(&dotted_override("volume.layerz=3").unwrap()).unwrap_err();
        assert!(err.to_string().contains("layerz"), "{err}");
        let s = base.with_overrides(&dotted_override("volume.undercoat=null").unwrap()).unwrap();
        assert!(s.volume.undercoat.is_none());
        assert!(BakeSettings::preset("fluff").is_err());
        assert!(dotted_override("nokey").is_err());
        let s = base.with_overrides(&dotted_override("blades.field.density_per_m2=50").unwrap()).unwrap();
        let blades = s.blades.expect("a blade override turns blades on");
        assert_eq!(blades.field.density_per_m2, 50.0);
        assert_eq!(blades.keyframes, BladeSettings::default().keyframes);
    }

    #[test]
    fn a_misspelt_key_of_a_tolerant_struct_is_refused_by_name() {
        // Cause: `TopologyParams` accepts unknown fields (pack metadata stays readable as fields
        // are added), so `--set topology.stifness_n_per_m=5` used to be dropped silently.
        let base = BakeSettings::preset("fur").unwrap();
        let err = base.with_overrides(&dotted_override("topology.stifness_n_per_m=5").unwrap()).unwrap_err();
        assert_eq!(err.key(), "topology.stifness_n_per_m");
        assert!(err.to_string().starts_with("topology.stifness_n_per_m: unknown key"), "{err}");
        let err = base.with_overrides(&dotted_override("volume.layers=\"many\"").unwrap()).unwrap_err();
        assert!(err.to_string().starts_with("volume.layers: "), "{err}");
    }

    #[test]
    fn an_override_can_switch_an_enum_variant() {
        // Cause: the deep merge kept the old variant's key beside the new one
        // (`{"relative":1e-6,"absolute_m":0.01}`), which no variant accepts.
        let base = BakeSettings::preset("fur").unwrap();
        let s = base.with_overrides(&dotted_override(r#"import.weld_tolerance={"absolute_m":0.01}"#).unwrap()).unwrap();
        assert_eq!(s.import.weld_tolerance, furbake_import::WeldTolerance::AbsoluteM(0.01));
        let materials = r#"import.fur_mask={"source":"materials","names":["Fur"]}"#;
        let s = base.with_overrides(&dotted_override(materials).unwrap()).unwrap();
        let colour = r#"import.fur_mask={"source":"vertex_color","channel":"r","threshold":0.5}"#;
        let s = s.with_overrides(&dotted_override(colour).unwrap()).unwrap();
        assert!(matches!(s.import.fur_mask, furbake_import::FurMaskSource::VertexColor { .. }));
    }
}
