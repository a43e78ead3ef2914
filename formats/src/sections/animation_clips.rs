//! Animation clips (glTF 2.0 specification, "Animations"): every clip of the file, each a name,
//! a duration and channels; a channel drives one joint's translation, rotation or scale, or one
//! morph group's weights, with its sampler's interpolation (`LINEAR`, `STEP`, `CUBICSPLINE`), key
//! times and values stored as plain `f32` (no quantisation, so no stored error to report).
//! `CUBICSPLINE` keys hold three elements each — in-tangent, value, out-tangent — as in glTF.
//!
//! Layout (record, see `docs/format.md` "13 `animation_clips`"): metadata `clips: Vec<ClipMeta>`
//! with `ClipMeta = { name: String, duration_s: f32, channel_count: u32 }` (channels stored clip
//! after clip); arrays 0 channel target `u32 × C`, 1 path `u8 × C` (0 translation, 1 rotation,
//! 2 scale, 3 weights), 2 interpolation `u8 × C` (0 linear, 1 step, 2 cubic spline), 3 key count
//! `u32 × C`, 4 components per element `u32 × C` (3, 4, 3, or the group's target count),
//! 5 key times `f32 × Σ keys` (seconds), 6 values `f32 × Σ keys·components·(3 if cubic else 1)`.

use serde::{Deserialize, Serialize};

use super::skeleton::check_unit_quaternions;
use super::{Section, check_coordinates, check_range};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// Longest clip a reader accepts, seconds (a bit over eleven days).
pub const MAX_CLIP_DURATION_S: f32 = 1e6;
/// Most morph weights one weights channel may carry per key.
pub const MAX_WEIGHTS_PER_KEY: u32 = 4096;

/// What a channel animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ChannelTarget {
    /// The local translation of a skeleton joint.
    Translation(u32),
    /// The local rotation (unit quaternion `xyzw`) of a skeleton joint.
    Rotation(u32),
    /// The local scale of a skeleton joint.
    Scale(u32),
    /// The weights of a morph group.
    MorphWeights(u32),
}

impl ChannelTarget {
    fn path_code(self) -> u8 {
        match self {
            ChannelTarget::Translation(_) => 0,
            ChannelTarget::Rotation(_) => 1,
            ChannelTarget::Scale(_) => 2,
            ChannelTarget::MorphWeights(_) => 3,
        }
    }

    /// The joint or morph group index.
    pub fn index(self) -> u32 {
        match self {
            ChannelTarget::Translation(i)
            | ChannelTarget::Rotation(i)
            | ChannelTarget::Scale(i)
            | ChannelTarget::MorphWeights(i) => i,
        }
    }

    /// The glTF path name (`translation`, `rotation`, `scale`, `weights`).
    pub fn path_name(self) -> &'static str {
        match self {
            ChannelTarget::Translation(_) => "translation",
            ChannelTarget::Rotation(_) => "rotation",
            ChannelTarget::Scale(_) => "scale",
            ChannelTarget::MorphWeights(_) => "weights",
        }
    }
}

/// A sampler's interpolation (glTF 2.0 specification, "Animations" → "Interpolation").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// Linear between keys; rotations by spherical linear interpolation.
    Linear,
    /// The value of the last key at or before the time.
    Step,
    /// Cubic Hermite spline with per-key in- and out-tangents (scaled by the key interval).
    CubicSpline,
}

impl Interpolation {
    /// Elements stored per key: 3 for cubic splines (in-tangent, value, out-tangent), else 1.
    pub fn elements_per_key(self) -> usize {
        if self == Interpolation::CubicSpline { 3 } else { 1 }
    }

    /// The glTF name.
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Linear => "LINEAR",
            Interpolation::Step => "STEP",
            Interpolation::CubicSpline => "CUBICSPLINE",
        }
    }
}

/// One animated property.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipChannel {
    /// The property animated.
    pub target: ChannelTarget,
    /// How values between keys are found.
    pub interpolation: Interpolation,
    /// Components per element: 3 (translation, scale), 4 (rotation), or the morph group's
    /// target count (weights).
    pub components: u32,
    /// Key times in seconds, strictly increasing, non-negative.
    pub times_s: Vec<f32>,
    /// `times_s.len() × elements_per_key × components` values, key-major.
    pub values: Vec<f32>,
}

/// One named clip.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationClip {
    /// The glTF animation's name (`animation N` when it has none).
    pub name: String,
    /// The last key time of any channel, seconds.
    pub duration_s: f32,
    /// The clip's channels.
    pub channels: Vec<ClipChannel>,
}

/// Every clip of the pack.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AnimationClips {
    /// The clips, in glTF order.
    pub clips: Vec<AnimationClip>,
}

impl AnimationClips {
    /// The clip named `name`.
    pub fn by_name(&self, name: &str) -> Option<&AnimationClip> {
        self.clips.iter().find(|c| c.name == name)
    }
}

#[derive(Serialize, Deserialize)]
struct ClipMeta {
    name: String,
    duration_s: f32,
    channel_count: u32,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    clips: Vec<ClipMeta>,
}

/// Bytes a clip's channels occupy in the arrays (tables, times and values), for `inspect`.
pub fn clip_bytes(clip: &AnimationClip) -> usize {
    clip.channels.iter().map(|c| 14 + 4 * (c.times_s.len() + c.values.len())).sum()
}

impl Section for AnimationClips {
    const KIND: SectionKind = SectionKind::ANIMATION_CLIPS;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta {
            clips: self
                .clips
                .iter()
                .map(|c| ClipMeta {
                    name: c.name.clone(),
                    duration_s: c.duration_s,
                    channel_count: c.channels.len() as u32,
                })
                .collect(),
        };
        let channels = || self.clips.iter().flat_map(|c| &c.channels);
        let targets: Vec<u32> = channels().map(|c| c.target.index()).collect();
        let paths: Vec<u8> = channels().map(|c| c.target.path_code()).collect();
        let interp: Vec<u8> = channels().map(|c| c.interpolation as u8).collect();
        let keys: Vec<u32> = channels().map(|c| c.times_s.len() as u32).collect();
        let comps: Vec<u32> = channels().map(|c| c.components).collect();
        let times: Vec<f32> = channels().flat_map(|c| c.times_s.iter().copied()).collect();
        let values: Vec<f32> = channels().flat_map(|c| c.values.iter().copied()).collect();
        RecordWriter::new(&meta)
            .array::<u32>(&targets)
            .array::<u8>(&paths)
            .array::<u8>(&interp)
            .array::<u32>(&keys)
            .array::<u32>(&comps)
            .array::<f32>(&times)
            .array::<f32>(&values)
            .finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let total: u64 = m.clips.iter().map(|c| u64::from(c.channel_count)).sum();
        let c = usize::try_from(total).map_err(|_| FormatError::invalid("channel count overflows"))?;
        let targets = r.array_exact::<u32>(0, c, "channel targets")?;
        let paths = r.array_exact::<u8>(1, c, "channel paths")?;
        let interp = r.array_exact::<u8>(2, c, "channel interpolations")?;
        let keys = r.array_exact::<u32>(3, c, "channel key counts")?;
        let comps = r.array_exact::<u32>(4, c, "channel components")?;
        let times = r.array::<f32>(5)?;
        let values = r.array::<f32>(6)?;
        // Σ keys and Σ values must match the arrays exactly; both are bounded by the payload
        // (each array was checked to fit), so the sums below cannot run away.
        let (mut t_at, mut v_at) = (0usize, 0usize);
        let mut clips = Vec::with_capacity(m.clips.len());
        let mut ch = 0usize;
        for (ci, cm) in m.clips.into_iter().enumerate() {
            let what = |w: String| FormatError::invalid(format!("clip {ci} \"{}\": {w}", cm.name));
            check_range(&[cm.duration_s], 0.0, MAX_CLIP_DURATION_S, "duration_s")
                .map_err(|_| what(format!("duration_s = {} is outside [0, {MAX_CLIP_DURATION_S:e}]", cm.duration_s)))?;
            let mut channels = Vec::with_capacity(cm.channel_count as usize);
            for _ in 0..cm.channel_count {
                let (index, k, n) = (targets[ch], keys[ch] as usize, comps[ch]);
                let target = match paths[ch] {
                    0 => ChannelTarget::Translation(index),
                    1 => ChannelTarget::Rotation(index),
                    2 => ChannelTarget::Scale(index),
                    3 => ChannelTarget::MorphWeights(index),
                    p => return Err(what(format!("channel {ch} has path code {p} (0..=3)"))),
                };
                let interpolation = match interp[ch] {
                    0 => Interpolation::Linear,
                    1 => Interpolation::Step,
                    2 => Interpolation::CubicSpline,
                    p => return Err(what(format!("channel {ch} has interpolation code {p} (0..=2)"))),
                };
                let want = match target {
                    ChannelTarget::Translation(_) | ChannelTarget::Scale(_) => n == 3,
                    ChannelTarget::Rotation(_) => n == 4,
                    ChannelTarget::MorphWeights(_) => (1..=MAX_WEIGHTS_PER_KEY).contains(&n),
                };
                if !want || k == 0 {
                    return Err(what(format!("channel {ch} ({}) has {k} keys of {n} components", target.path_name())));
                }
                let nv = k
                    .checked_mul(n as usize)
                    .and_then(|x| x.checked_mul(interpolation.elements_per_key()))
                    .filter(|&nv| t_at + k <= times.len() && v_at.checked_add(nv).is_some_and(|e| e <= values.len()))
                    .ok_or_else(|| what(format!("channel {ch}: its keys or values run past the arrays")))?;
                let ts = &times[t_at..t_at + k];
                let vs = &values[v_at..v_at + nv];
                check_range(ts, 0.0, cm.duration_s, "key times").map_err(|e| what(format!("channel {ch}: {e}")))?;
                if let Some(i) = ts.windows(2).position(|w| w[1] <= w[0]) {
                    return Err(what(format!("channel {ch}: key times are not increasing at key {}", i + 1)));
                }
                match target {
                    ChannelTarget::MorphWeights(_) => check_range(
                        vs,
                        -super::morph_targets::MAX_MORPH_WEIGHT,
                        super::morph_targets::MAX_MORPH_WEIGHT,
                        "weights",
                    ),
                    ChannelTarget::Rotation(_) if interpolation != Interpolation::CubicSpline => {
                        check_unit_quaternions(vs, "rotations")
                    }
                    _ => check_coordinates(vs, "values"),
                }
                .map_err(|e| what(format!("channel {ch}: {e}")))?;
                channels.push(ClipChannel {
                    target,
                    interpolation,
                    components: n,
                    times_s: ts.to_vec(),
                    values: vs.to_vec(),
                });
                t_at += k;
                v_at += nv;
                ch += 1;
            }
            clips.push(AnimationClip { name: cm.name, duration_s: cm.duration_s, channels });
        }
        if t_at != times.len() || v_at != values.len() {
            return Err(FormatError::invalid(format!(
                "the channels use {t_at} key times and {v_at} values; the arrays hold {} and {}",
                times.len(),
                values.len()
            )));
        }
        Ok(AnimationClips { clips })
    }

    fn summary(&self) -> serde_json::Value {
        let clips: Vec<serde_json::Value> = self
            .clips
            .iter()
            .map(|c| {
                serde_json::json!({
                    "name": c.name,
                    "duration_s": c.duration_s,
                    "channels": c.channels.len(),
                    "keys": c.channels.iter().map(|ch| ch.times_s.len()).sum::<usize>(),
                    "bytes": clip_bytes(c),
                })
            })
            .collect();
        serde_json::json!({
            "clip_count": self.clips.len(),
            "channels": self.clips.iter().map(|c| c.channels.len()).sum::<usize>(),
            "clips": clips,
        })
    }
}
