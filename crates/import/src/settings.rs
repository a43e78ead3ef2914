//! Import settings: which triangles carry fur (docs/design.md "Import": "which triangles carry fur from a
//! vertex attribute/colour or material name (default: all)") and how close two positions must be
//! to be welded into one skin vertex. Serde-readable (TOML/JSON) with unknown fields rejected, so
//! the CLI can read them from a config file and store them verbatim in the bake manifest.

use serde::{Deserialize, Serialize};

/// All settings of the import stage.
///
/// TOML example (every field optional; shown with the defaults except `fur_mask`):
/// ```toml
/// weld_tolerance = { relative = 1e-6 }   # or { absolute_m = 0.0001 }
/// [fur_mask]
/// source = "materials"                   # "all" | "vertex_color" | "attribute" | "materials"
/// names = ["Fur", "Mane"]
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(default, deny_unknown_fields)]
pub struct ImportSettings {
    /// Which triangles carry fur. Default: [`FurMaskSource::All`].
    pub fur_mask: FurMaskSource,
    /// How close two positions must be to become one welded vertex.
    /// Default: [`WeldTolerance::Relative`]`(1e-6)` of the bounding-box diagonal.
    pub weld_tolerance: WeldTolerance,
    /// Multiply each vertex colour by the material's base colour texture sampled at the vertex
    /// (so a textured model's fur takes the texture's colour). Default true.
    pub base_color_texture: bool,
    /// A missing or unreadable external image is an error ([`crate::ImportError::ExternalFile`])
    /// instead of a warning (the fur then takes the base colour factor). A run option, not a
    /// setting of the pack: it changes no pack that is written, so it is neither serialised nor
    /// recorded (build systems set it, so that an input left out of a sandboxed action fails it).
    #[serde(skip)]
    #[cfg_attr(feature = "schema", schemars(skip))]
    pub strict_inputs: bool,
}

impl Default for ImportSettings {
    fn default() -> Self {
        ImportSettings {
            fur_mask: FurMaskSource::default(),
            weld_tolerance: WeldTolerance::default(),
            base_color_texture: true,
            strict_inputs: false,
        }
    }
}

/// Where the per-triangle fur mask comes from.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(tag = "source", rename_all = "snake_case", deny_unknown_fields)]
pub enum FurMaskSource {
    /// Every triangle carries fur (the default).
    #[default]
    All,
    /// A triangle is furry when the mean of its three corners' `COLOR_0` channel is
    /// `>= threshold`. The file's `COLOR_0` value is used as stored (not multiplied by the
    /// material's base colour factor); a primitive without `COLOR_0` counts as white (1.0,
    /// glTF's implied vertex colour) and produces a warning. It is an error when no imported
    /// primitive has `COLOR_0`.
    VertexColor {
        /// The colour channel read.
        channel: ColorChannel,
        /// Threshold in `[0, 1]`.
        threshold: f32,
    },
    /// A triangle is furry when the mean of its corners' values of the scalar vertex attribute
    /// `name` (e.g. `_FUR`; float, or normalized unsigned byte/short) is `>= threshold`.
    /// A primitive without the attribute counts as 0 (bare) and produces a warning. It is an
    /// error when no imported primitive has the attribute.
    Attribute {
        /// Attribute name exactly as in the file (`_FUR`; the leading underscore may be omitted).
        name: String,
        /// Threshold, in the attribute's units (`[0, 1]` for normalized integers).
        threshold: f32,
    },
    /// Triangles whose material's `name` is in `names` are furry; all others (including
    /// primitives without a material) are bare. A listed name that no imported primitive uses
    /// produces a warning.
    Materials {
        /// Material names, compared exactly (case-sensitive).
        names: Vec<String>,
    },
}

/// One channel of a vertex colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum ColorChannel {
    /// Red.
    R,
    /// Green.
    G,
    /// Blue.
    B,
    /// Alpha (1.0 for `vec3` colours).
    A,
}

impl ColorChannel {
    /// Index of the channel in an RGBA array.
    pub fn index(self) -> usize {
        match self {
            ColorChannel::R => 0,
            ColorChannel::G => 1,
            ColorChannel::B => 2,
            ColorChannel::A => 3,
        }
    }
}

/// The welding distance: positions closer than this become one vertex.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum WeldTolerance {
    /// A fraction of the diagonal of the imported positions' bounding box (after node
    /// transforms). Default `1e-6`.
    Relative(f32),
    /// An absolute distance in metres (scene units). `0` welds only bit-identical positions.
    AbsoluteM(f32),
}

impl Default for WeldTolerance {
    fn default() -> Self {
        WeldTolerance::Relative(1e-6)
    }
}

/// An import setting outside its allowed range. Blame: the caller. `key` is the setting's path
/// inside [`ImportSettings`] (`fur_mask.threshold`); a caller that nests the settings prefixes it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{key} = {value} is out of range (allowed: {allowed})")]
pub struct InvalidImportSetting {
    /// Dotted path of the setting.
    pub key: &'static str,
    /// The value given, as text.
    pub value: String,
    /// What is allowed.
    pub allowed: &'static str,
}

impl ImportSettings {
    /// Checks the settings; returns the first setting out of range, with its key and range.
    /// Ranges: `weld_tolerance.relative` [0, 0.1], `weld_tolerance.absolute_m` ≥ 0 (finite),
    /// `fur_mask.threshold` [0, 1] for `vertex_color` and finite for `attribute`,
    /// `fur_mask.name` non-empty, `fur_mask.names` at least one.
    pub fn validate(&self) -> Result<(), InvalidImportSetting> {
        let bad = |key, value: String, allowed| Err(InvalidImportSetting { key, value, allowed });
        match self.weld_tolerance {
            WeldTolerance::Relative(f) if !(f.is_finite() && (0.0..=0.1).contains(&f)) => {
                return bad("weld_tolerance.relative", f.to_string(), "[0, 0.1]");
            }
            WeldTolerance::AbsoluteM(m) if !(m.is_finite() && m >= 0.0) => {
                return bad("weld_tolerance.absolute_m", m.to_string(), "[0, ∞), finite");
            }
            _ => {}
        }
        match &self.fur_mask {
            FurMaskSource::All => {}
            FurMaskSource::VertexColor { threshold, .. } => {
                if !(threshold.is_finite() && (0.0..=1.0).contains(threshold)) {
                    return bad("fur_mask.threshold", threshold.to_string(), "[0, 1]");
                }
            }
            FurMaskSource::Attribute { name, threshold } => {
                if name.trim_start_matches('_').is_empty() {
                    return bad("fur_mask.name", format!("{name:?}"), "a non-empty attribute name, e.g. \"_FUR\"");
                }
                if !threshold.is_finite() {
                    return bad("fur_mask.threshold", threshold.to_string(), "a finite number");
                }
            }
            FurMaskSource::Materials { names } => {
                if names.is_empty() {
                    return bad(
                        "fur_mask.names",
                        "[]".to_owned(),
                        "at least one material name (else no triangle carries fur)",
                    );
                }
            }
        }
        Ok(())
    }
}
