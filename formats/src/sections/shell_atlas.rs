//! The shell atlas (fur thesis §3.1–3.2): one alpha slice per shell layer of the hair volume,
//! innermost first, plus the per-layer self-shadow table (after Banks: darker towards the skin)
//! and the hair coverage of each layer. Also defines the volume parameters (eq. 3.1–3.2).

use serde::{Deserialize, Serialize};

use super::{Section, check_finite, check_param, check_range, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// One population of hairs in the volume (the coat, or the undercoat).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct HairCoat {
    /// Hair roots per base texel, in (0, 1]. Coat default 0.05, undercoat 0.35.
    pub density: f32,
    /// Shortest hair `lmin`, as a fraction of the volume height (the length range of §3.1).
    pub length_min: f32,
    /// Longest hair, as a fraction of the volume height (≤ 1). Each hair's length is drawn from
    /// `[length_min, length_max]`; the bending curve of eq. 3.1 is normalised by the volume top
    /// (`hmax` = 1), so a short hair bends less than a long one.
    pub length_max: f32,
    /// Lateral deviation `dmax` of eq. 3.1 at the top of the volume (h = hmax = 1), in texels.
    pub max_deviation_texels: f32,
    /// Exponent `n` of the bending curve (eq. 3.1; 2 = quadratic, the thesis's choice).
    pub curvature_exponent: f32,
    /// Hair radius at the root, in texels.
    pub radius_texels: f32,
    /// Fraction by which the radius shrinks from root to tip, in [0, 1].
    pub taper: f32,
}

/// Parameters of the hair volume and of the atlases sliced from it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct VolumeParams {
    /// Shell layers (volume depth). `fur` preset 16, `grass` 64.
    pub layers: u32,
    /// Shell texture width and height in texels (the volume is `res × res` per layer, tileable).
    pub resolution: u32,
    /// Outer hairs.
    pub coat: HairCoat,
    /// Optional second, shorter and denser pass (fur thesis fig. 3.8).
    pub undercoat: Option<HairCoat>,
    /// Self-shadow factor at the innermost layer (1 = no darkening); the outermost layer is 1.
    pub shadow_min: f32,
    /// Shape of the shadow ramp: factor = min + (1 − min)·(i/(n−1))^exponent.
    pub shadow_exponent: f32,
    /// Vertical slices composed onto the fin texture (fur thesis fig. 3.7; default 20).
    pub fin_slices: u32,
    /// Fin texture height in texels (the width is `resolution`).
    pub fin_height: u32,
}

impl HairCoat {
    fn check_stored(&self, what: &str) -> Result<()> {
        check_param(self.density, 0.0, 1.0, &format!("{what}.density"))?;
        check_param(self.length_min, 0.0, 1.0, &format!("{what}.length_min"))?;
        check_param(self.length_max, self.length_min, 1.0, &format!("{what}.length_max"))?;
        check_param(self.max_deviation_texels, 0.0, 1e6, &format!("{what}.max_deviation_texels"))?;
        check_param(self.curvature_exponent, 0.0, 1e6, &format!("{what}.curvature_exponent"))?;
        check_param(self.radius_texels, 0.0, 1e6, &format!("{what}.radius_texels"))?;
        check_param(self.taper, 0.0, 1.0, &format!("{what}.taper"))
    }
}

impl VolumeParams {
    /// What a reader requires of stored volume parameters: finite and in the ranges a bake can
    /// produce (they are informative — the atlas is baked — but `inspect` prints them, so they
    /// must be numbers).
    fn check_stored(&self) -> Result<()> {
        self.coat.check_stored("coat")?;
        if let Some(u) = &self.undercoat {
            u.check_stored("undercoat")?;
        }
        check_param(self.shadow_min, 0.0, 1.0, "shadow_min")?;
        check_param(self.shadow_exponent, 0.0, 1e6, "shadow_exponent")?;
        if self.fin_slices == 0 || self.fin_slices > 1024 || self.fin_height == 0 || self.fin_height > MAX_RESOLUTION {
            return Err(FormatError::invalid(format!(
                "fin_slices = {} and fin_height = {} must lie in 1..=1024 and 1..={MAX_RESOLUTION}",
                self.fin_slices, self.fin_height
            )));
        }
        Ok(())
    }
}

/// The shell slices, the shadow table and per-layer statistics.
#[derive(Clone, Debug, PartialEq)]
pub struct ShellAtlas {
    /// The parameters the volume was generated with.
    pub params: VolumeParams,
    /// Seed of the volume stage.
    pub seed: u64,
    /// Fur length in scene units (metres): the distance from skin to the outermost shell.
    pub fur_length_m: f32,
    /// Alpha, `layers × resolution × resolution` bytes, layer-major, rows top to bottom.
    pub alpha: Vec<u8>,
    /// Self-shadow factor per layer in (0, 1], innermost first.
    pub shadow: Vec<f32>,
    /// Fraction of texels with non-zero alpha, per layer.
    pub coverage: Vec<f32>,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    params: VolumeParams,
    seed: u64,
    fur_length_m: f32,
}

impl ShellAtlas {
    /// Number of layers.
    pub fn layers(&self) -> usize {
        self.params.layers as usize
    }

    /// Texels per layer.
    pub fn layer_texels(&self) -> usize {
        (self.params.resolution as usize).pow(2)
    }

    /// Alpha of layer `i` (`resolution²` bytes).
    pub fn layer(&self, i: usize) -> &[u8] {
        let n = self.layer_texels();
        &self.alpha[i * n..(i + 1) * n]
    }

    /// The slice that shell `layer` of `layers` drawn samples: the slab holding its height
    /// `(layer + 1)/layers`, `⌈(layer + 1)·atlas/layers⌉ − 1`, so that layer `2i + 1` of `2N`
    /// samples what layer `i` of `N` does (the renderer's level of detail halves the count).
    /// `shell.wgsl` `shell_slice` is its GPU twin.
    pub fn slice_for(&self, layer: u32, layers: u32) -> usize {
        let (a, n) = (self.params.layers.max(1), layers.max(1));
        (((layer + 1) * a).div_ceil(n) - 1).min(a - 1) as usize
    }
}

/// Largest shell resolution a reader accepts (texels per side).
pub const MAX_RESOLUTION: u32 = 8192;
/// Largest layer count a reader accepts.
pub const MAX_LAYERS: u32 = 1024;

impl Section for ShellAtlas {
    const KIND: SectionKind = SectionKind::SHELL_ATLAS;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta { params: self.params.clone(), seed: self.seed, fur_length_m: self.fur_length_m };
        RecordWriter::new(&meta)
            .array::<u8>(&self.alpha)
            .array::<f32>(&self.shadow)
            .array::<f32>(&self.coverage)
            .finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let (layers, res) = (m.params.layers, m.params.resolution);
        if layers == 0 || layers > MAX_LAYERS || res == 0 || res > MAX_RESOLUTION {
            return Err(FormatError::invalid(format!(
                "shell atlas of {layers} layers × {res}² texels is out of range"
            )));
        }
        let texels = checked_count(layers as usize, (res as usize).pow(2), "shell alpha")?;
        let alpha = r.array_exact::<u8>(0, texels, "shell alpha")?;
        let shadow = r.array_exact::<f32>(1, layers as usize, "shadow table")?;
        let coverage = r.array_exact::<f32>(2, layers as usize, "coverage")?;
        check_finite(&shadow, "shadow table")?;
        if let Some(i) = shadow.iter().position(|&x| !(x > 0.0 && x <= 1.0)) {
            return Err(FormatError::invalid(format!("shadow table[{i}] = {} is outside (0, 1]", shadow[i])));
        }
        check_range(&coverage, 0.0, 1.0, "coverage")?;
        let (lo, hi) = crate::sections::spring_topology::FUR_LENGTH_RANGE_M;
        check_param(m.fur_length_m, lo, hi, "fur_length_m")?;
        m.params.check_stored()?;
        Ok(ShellAtlas {
            params: m.params,
            seed: m.seed,
            fur_length_m: m.fur_length_m,
            alpha: alpha.into_owned(),
            shadow: shadow.into_owned(),
            coverage: coverage.into_owned(),
        })
    }

    fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "layers": self.params.layers,
            "resolution": self.params.resolution,
            "seed": self.seed,
            "fur_length_m": self.fur_length_m,
            "params": self.params,
            "shadow_per_layer": self.shadow,
            "coverage_per_layer": self.coverage,
        })
    }
}
