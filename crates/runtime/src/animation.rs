//! The CPU reference of character animation (glTF 2.0 specification, "Animations" →
//! "Interpolation", "Skins" → "Joint hierarchy" and "Skinned mesh", "Morph Targets"), the
//! groundwork for the fur thesis's future work (§3.4.1): the furry object's own motion drives the
//! mass points on its surface.
//!
//! Stages, each a function over caller-owned buffers so a frame allocates nothing:
//! 1. [`sample_clip`] — a clip's channels at a time into a [`Pose`] (local TRS per joint, morph
//!    weights): `STEP`, `LINEAR` (rotations by spherical linear interpolation, shortest arc) and
//!    `CUBICSPLINE` (Hermite, tangents scaled by the key interval `t_{k+1} − t_k`); before the first
//!    key the first value holds, after the last the last;
//! 2. [`AnimationPlayer`] — a clip by name, time, speed, looping, and a cross-fade from the
//!    previous clip ([`blend_poses`]: translations, scales and weights linearly, rotations by slerp);
//! 3. [`joint_world_matrices`] and [`skinning_matrices`] — `world(j) = world(parent) × T × R × S`,
//!    then per bind `world(joint) × inverseBind`;
//! 4. [`morph_and_skin`] — morph (`p + Σ wₜ·Δpₜ`, normals likewise), then linear blend skinning
//!    `p' = (Σ wᵢ·Mᵢ)·p`; normals by the inverse transpose of the blended matrix (its cofactor
//!    matrix times the sign of its determinant, defined even when it is singular), renormalised.

use std::sync::Arc;

use furbake_formats::sections::animation_clips::{
    AnimationClip, AnimationClips, ChannelTarget, ClipChannel, Interpolation,
};
use furbake_formats::sections::morph_targets::{MorphGroup, MorphTargets};
use furbake_formats::sections::skeleton::Skeleton;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::SkinWeights;
use furbake_sim::SkinTransform;
use glam::{Mat4, Quat, Vec3};

/// Why an animation call cannot proceed. Blame: the caller (a clip name the pack lacks, buffers
/// sized for another pack); the sections themselves were validated when decoded.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum AnimationError {
    /// No clip of that name.
    #[error("no animation clip named {name:?} (the pack has: {known})")]
    UnknownClip {
        /// The name asked for.
        name: String,
        /// The clips the pack has, comma-separated.
        known: String,
    },
    /// A value out of range (not finite, or beyond its documented bound).
    #[error("{what} = {value} is out of range")]
    Value {
        /// Which value.
        what: &'static str,
        /// The value given.
        value: f32,
    },
    /// A buffer or section does not have the size the others imply.
    #[error("{what}: {got} elements, expected {expected}")]
    SizeMismatch {
        /// Which buffer or section.
        what: &'static str,
        /// Elements expected.
        expected: usize,
        /// Elements given.
        got: usize,
    },
}

fn finite(what: &'static str, value: f32) -> Result<(), AnimationError> {
    if value.is_finite() { Ok(()) } else { Err(AnimationError::Value { what, value }) }
}

fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), AnimationError> {
    if expected == got { Ok(()) } else { Err(AnimationError::SizeMismatch { what, expected, got }) }
}

/// The animated state of a skeleton: local TRS per joint and morph weights per target.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Pose {
    /// Local translation per joint.
    pub translations: Vec<Vec3>,
    /// Local rotation per joint (unit).
    pub rotations: Vec<Quat>,
    /// Local scale per joint.
    pub scales: Vec<Vec3>,
    /// Weight per morph target.
    pub morph_weights: Vec<f32>,
}

impl Pose {
    /// The rest pose: the skeleton's rest TRS and the default morph weights.
    pub fn rest(skeleton: Option<&Skeleton>, morphs: Option<&MorphTargets>) -> Pose {
        let mut pose = Pose::default();
        pose.set_rest(skeleton, morphs);
        pose
    }

    /// Resets every joint and weight to rest (reusing the buffers once they have their size).
    pub fn set_rest(&mut self, skeleton: Option<&Skeleton>, morphs: Option<&MorphTargets>) {
        self.translations.clear();
        self.rotations.clear();
        self.scales.clear();
        self.morph_weights.clear();
        if let Some(s) = skeleton {
            self.translations.extend(s.translations.iter().map(|&t| Vec3::from(t)));
            self.rotations.extend(s.rotations.iter().map(|&q| Quat::from_array(q)));
            self.scales.extend(s.scales.iter().map(|&v| Vec3::from(v)));
        }
        if let Some(m) = morphs {
            self.morph_weights.extend_from_slice(&m.default_weights);
        }
    }
}

/// Hermite basis of glTF's cubic spline at `s ∈ [0, 1]` over an interval of `td` seconds:
/// `(value k, out-tangent k, value k+1, in-tangent k+1)` coefficients.
fn hermite(s: f32, td: f32) -> [f32; 4] {
    let (s2, s3) = (s * s, s * s * s);
    [2.0 * s3 - 3.0 * s2 + 1.0, td * (s3 - 2.0 * s2 + s), -2.0 * s3 + 3.0 * s2, td * (s3 - s2)]
}

/// Samples one channel at `time_s` into `out` (`components` values; a rotation is normalised).
pub fn sample_channel(channel: &ClipChannel, time_s: f32, out: &mut [f32]) {
    let n = channel.components as usize;
    let times = &channel.times_s;
    let e = channel.interpolation.elements_per_key();
    // Element `which` (0 in-tangent, 1 value, 2 out-tangent for splines) of key `k`.
    let element = |k: usize, which: usize| {
        let at = (k * e + if e == 3 { which } else { 0 }) * n;
        &channel.values[at..at + n]
    };
    let last = times.len() - 1;
    // Decoded channels have at least one key and strictly increasing times.
    let next = times.partition_point(|&t| t <= time_s);
    if next == 0 || next > last || channel.interpolation == Interpolation::Step {
        let k = next.saturating_sub(1).min(last);
        out[..n].copy_from_slice(element(k, 1));
    } else {
        let k = next - 1;
        let td = times[k + 1] - times[k];
        let s = ((time_s - times[k]) / td).clamp(0.0, 1.0);
        match channel.interpolation {
            Interpolation::Linear if matches!(channel.target, ChannelTarget::Rotation(_)) => {
                let a = Quat::from_slice(element(k, 1));
                let b = Quat::from_slice(element(k + 1, 1));
                out[..4].copy_from_slice(&a.slerp(b, s).to_array());
            }
            Interpolation::Linear => {
                let (a, b) = (element(k, 1), element(k + 1, 1));
                for c in 0..n {
                    out[c] = a[c] + (b[c] - a[c]) * s;
                }
            }
            Interpolation::CubicSpline => {
                let h = hermite(s, td);
                let (vk, bk, vk1, ak1) = (element(k, 1), element(k, 2), element(k + 1, 1), element(k + 1, 0));
                for c in 0..n {
                    out[c] = h[0] * vk[c] + h[1] * bk[c] + h[2] * vk1[c] + h[3] * ak1[c];
                }
            }
            Interpolation::Step => unreachable!("handled above"),
        }
    }
    if matches!(channel.target, ChannelTarget::Rotation(_)) {
        let q = Quat::from_slice(&out[..4]);
        let q = if q.length_squared() > 0.0 { q.normalize() } else { Quat::IDENTITY };
        out[..4].copy_from_slice(&q.to_array());
    }
}

/// Samples every channel of `clip` at `time_s` into `pose`; joints and weights the clip does not
/// drive keep their values. `groups` are the morph targets' groups (empty without morph targets).
/// Channels naming joints or groups outside `pose` are skipped (`check_consistency` rules them
/// out for a verified pack).
pub fn sample_clip(clip: &AnimationClip, time_s: f32, groups: &[MorphGroup], pose: &mut Pose) {
    let mut buf = [0.0f32; 4];
    for ch in &clip.channels {
        let i = ch.target.index() as usize;
        match ch.target {
            ChannelTarget::Translation(_) if i < pose.translations.len() => {
                sample_channel(ch, time_s, &mut buf);
                pose.translations[i] = Vec3::from_slice(&buf);
            }
            ChannelTarget::Scale(_) if i < pose.scales.len() => {
                sample_channel(ch, time_s, &mut buf);
                pose.scales[i] = Vec3::from_slice(&buf);
            }
            ChannelTarget::Rotation(_) if i < pose.rotations.len() => {
                sample_channel(ch, time_s, &mut buf);
                pose.rotations[i] = Quat::from_slice(&buf);
            }
            ChannelTarget::MorphWeights(_) => {
                let Some(g) = groups.get(i) else { continue };
                let range = g.first_target as usize..(g.first_target + g.target_count) as usize;
                if g.target_count == ch.components && range.end <= pose.morph_weights.len() {
                    sample_channel(ch, time_s, &mut pose.morph_weights[range]);
                }
            }
            _ => {}
        }
    }
}

/// `out = a` blended towards `b` by `weight` (0 → `a`, 1 → `b`): translations, scales and morph
/// weights linearly, rotations by slerp. All four poses must have the same sizes.
pub fn blend_poses(a: &Pose, b: &Pose, weight: f32, out: &mut Pose) -> Result<(), AnimationError> {
    let w = weight.clamp(0.0, 1.0);
    check_len("pose b joints", a.translations.len(), b.translations.len())?;
    check_len("pose b weights", a.morph_weights.len(), b.morph_weights.len())?;
    check_len("output pose joints", a.translations.len(), out.translations.len())?;
    check_len("output pose weights", a.morph_weights.len(), out.morph_weights.len())?;
    for j in 0..a.translations.len() {
        out.translations[j] = a.translations[j].lerp(b.translations[j], w);
        out.scales[j] = a.scales[j].lerp(b.scales[j], w);
        out.rotations[j] = a.rotations[j].slerp(b.rotations[j], w).normalize();
    }
    for (k, o) in out.morph_weights.iter_mut().enumerate() {
        *o = a.morph_weights[k] + (b.morph_weights[k] - a.morph_weights[k]) * w;
    }
    Ok(())
}

/// One clip being played: which, where, how fast, looping or clamped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipPlayback {
    /// Index of the clip in the pack's [`AnimationClips`].
    pub clip: usize,
    /// Clip time, seconds (already wrapped or clamped to the clip).
    pub time_s: f32,
    /// Playback speed (1 = real time; negative plays backwards).
    pub speed: f32,
    /// Whether the clip wraps around at its end (else it holds its last pose).
    pub looping: bool,
}

impl ClipPlayback {
    fn advance(&mut self, dt_s: f32, duration_s: f32) {
        let t = self.time_s + dt_s * self.speed;
        self.time_s = if duration_s <= 0.0 {
            0.0
        } else if self.looping {
            t.rem_euclid(duration_s)
        } else {
            t.clamp(0.0, duration_s)
        };
    }
}

/// Plays clips on one pack's skeleton and morph targets: the current clip, and while a cross-fade
/// runs the previous one, blended by the elapsed fraction of the fade. Owns its scratch poses, so
/// [`AnimationPlayer::pose`] allocates nothing.
#[derive(Clone, Debug)]
pub struct AnimationPlayer {
    current: ClipPlayback,
    /// The clip faded out: its playback, the fade's length and time elapsed, seconds.
    fading: Option<(ClipPlayback, f32, f32)>,
    rest: Pose,
    scratch_a: Pose,
    scratch_b: Pose,
}

fn clip_index(clips: &AnimationClips, name: &str) -> Result<usize, AnimationError> {
    clips.clips.iter().position(|c| c.name == name).ok_or_else(|| AnimationError::UnknownClip {
        name: name.to_string(),
        known: if clips.clips.is_empty() {
            "no clips".into()
        } else {
            clips.clips.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", ")
        },
    })
}

impl AnimationPlayer {
    /// Starts clip `name` at time 0 with `speed` and `looping`, on the rest pose of `skeleton` and
    /// `morphs` (joints and weights the clip does not drive stay at rest).
    pub fn new(
        clips: &AnimationClips,
        name: &str,
        speed: f32,
        looping: bool,
        skeleton: Option<&Skeleton>,
        morphs: Option<&MorphTargets>,
    ) -> Result<Self, AnimationError> {
        let clip = clip_index(clips, name)?;
        let rest = Pose::rest(skeleton, morphs);
        Ok(AnimationPlayer {
            current: ClipPlayback { clip, time_s: 0.0, speed, looping },
            fading: None,
            scratch_a: rest.clone(),
            scratch_b: rest.clone(),
            rest,
        })
    }

    /// A player of no clip: it poses the rest pose of `skeleton` and `morphs` until
    /// [`AnimationPlayer::play`] starts one (its [`ClipPlayback::clip`] names none).
    pub fn at_rest(skeleton: Option<&Skeleton>, morphs: Option<&MorphTargets>) -> Self {
        let rest = Pose::rest(skeleton, morphs);
        AnimationPlayer {
            current: ClipPlayback { clip: usize::MAX, time_s: 0.0, speed: 1.0, looping: true },
            fading: None,
            scratch_a: rest.clone(),
            scratch_b: rest.clone(),
            rest,
        }
    }

    /// The clip playing now.
    pub fn current(&self) -> ClipPlayback {
        self.current
    }

    /// Switches to clip `name` from time 0, cross-fading from the current clip over `fade_s`
    /// seconds (0: switch at once). Speed and looping are kept.
    pub fn play(&mut self, clips: &AnimationClips, name: &str, fade_s: f32) -> Result<(), AnimationError> {
        let clip = clip_index(clips, name)?;
        let previous = self.current;
        self.current = ClipPlayback { clip, time_s: 0.0, ..previous };
        self.fading = (fade_s > 0.0).then_some((previous, fade_s, 0.0));
        Ok(())
    }

    /// Sets the current clip's time (wrapped or clamped to it).
    pub fn seek(&mut self, clips: &AnimationClips, time_s: f32) {
        self.current.time_s = 0.0;
        let d = clips.clips.get(self.current.clip).map_or(0.0, |c| c.duration_s);
        let speed = self.current.speed;
        self.current.speed = 1.0;
        self.current.advance(time_s, d);
        self.current.speed = speed;
    }

    /// Sets the playback speed of the current clip (1 = real time; negative plays backwards).
    pub fn set_speed(&mut self, speed: f32) {
        self.current.speed = speed;
    }

    /// Sets whether the current clip wraps around at its end.
    pub fn set_looping(&mut self, looping: bool) {
        self.current.looping = looping;
    }

    /// Advances by `dt_s` seconds of scene time.
    pub fn advance(&mut self, clips: &AnimationClips, dt_s: f32) {
        let duration = |i: usize| clips.clips.get(i).map_or(0.0, |c| c.duration_s);
        self.current.advance(dt_s, duration(self.current.clip));
        if let Some((prev, fade, elapsed)) = &mut self.fading {
            prev.advance(dt_s, duration(prev.clip));
            *elapsed += dt_s.abs();
            if *elapsed >= *fade {
                self.fading = None;
            }
        }
    }

    /// The weight of the current clip (1 when no fade runs).
    pub fn fade_weight(&self) -> f32 {
        self.fading.map_or(1.0, |(_, fade, elapsed)| (elapsed / fade).clamp(0.0, 1.0))
    }

    /// Writes the pose of now into `out` (which must have the rest pose's sizes).
    pub fn pose(
        &mut self,
        clips: &AnimationClips,
        groups: &[MorphGroup],
        out: &mut Pose,
    ) -> Result<(), AnimationError> {
        check_len("output pose joints", self.rest.translations.len(), out.translations.len())?;
        check_len("output pose weights", self.rest.morph_weights.len(), out.morph_weights.len())?;
        let sample = |p: ClipPlayback, into: &mut Pose, rest: &Pose| {
            copy_pose(rest, into);
            if let Some(c) = clips.clips.get(p.clip) {
                sample_clip(c, p.time_s, groups, into);
            }
        };
        match self.fading {
            None => sample(self.current, out, &self.rest),
            Some((prev, _, _)) => {
                sample(prev, &mut self.scratch_a, &self.rest);
                sample(self.current, &mut self.scratch_b, &self.rest);
                blend_poses(&self.scratch_a, &self.scratch_b, self.fade_weight(), out)?;
            }
        }
        Ok(())
    }
}

/// Copies `from` into `to` without allocating (same sizes).
fn copy_pose(from: &Pose, to: &mut Pose) {
    to.translations.copy_from_slice(&from.translations);
    to.rotations.copy_from_slice(&from.rotations);
    to.scales.copy_from_slice(&from.scales);
    to.morph_weights.copy_from_slice(&from.morph_weights);
}

/// World matrix of every joint: `world(j) = world(parent(j)) × T × R × S` (the identity above a
/// root). The skeleton is in topological order, so one pass suffices.
pub fn joint_world_matrices(skeleton: &Skeleton, pose: &Pose, out: &mut [Mat4]) -> Result<(), AnimationError> {
    let j = skeleton.joint_count();
    check_len("pose joints", j, pose.translations.len())?;
    check_len("world matrices", j, out.len())?;
    for i in 0..j {
        let local = Mat4::from_scale_rotation_translation(pose.scales[i], pose.rotations[i], pose.translations[i]);
        let parent = skeleton.parents[i];
        // Decoded skeletons have parents before children (`Skeleton::decode` checks it).
        out[i] = if parent == Skeleton::NO_PARENT { local } else { out[parent as usize] * local };
    }
    Ok(())
}

/// The skinning matrix of every bind: `world(joint) × inverseBind`.
pub fn skinning_matrices(skeleton: &Skeleton, world: &[Mat4], out: &mut [Mat4]) -> Result<(), AnimationError> {
    check_len("world matrices", skeleton.joint_count(), world.len())?;
    check_len("skinning matrices", skeleton.bind_count(), out.len())?;
    for (b, o) in out.iter_mut().enumerate() {
        *o = world[skeleton.bind_joints[b] as usize] * Mat4::from_cols_array(&skeleton.inverse_binds[b]);
    }
    Ok(())
}

/// The [`SkinTransform`] of skin vertex `i`: the blended skinning matrix `Σ wᵢ·Mᵢ` (identity
/// without `weights`) and the morph offset `Σ wₜ·Δpₜ` (zero without `morphs`). Sizes must have
/// been checked by the caller ([`morph_and_skin`], [`Animator`]).
fn vertex_transform(
    i: usize,
    weights: Option<&SkinWeights>,
    morphs: Option<(&MorphTargets, &[f32])>,
    skinning: &[Mat4],
) -> SkinTransform {
    let mut offset = Vec3::ZERO;
    if let Some((m, mw)) = morphs {
        let v = m.vertex_count as usize;
        for (t, &wt) in mw.iter().enumerate() {
            if wt != 0.0 {
                offset += wt * Vec3::from(m.position_deltas[t * v + i]);
            }
        }
    }
    let matrix = match weights {
        Some(w) => {
            let mut blended = Mat4::ZERO;
            for (b, wi) in w.influences(i) {
                if wi != 0.0 {
                    blended += skinning[b as usize] * wi;
                }
            }
            blended
        }
        None => Mat4::IDENTITY,
    };
    SkinTransform::new(matrix, offset)
}

/// Applies `t` (vertex `i`'s transform) to its bind position and normal: `p' = M(p + Δp)`,
/// `n' = normalize(N(n + Σ wₜ·Δnₜ))`; a collapsed normal (a joint scaled to zero) keeps the
/// bind normal rather than NaN.
fn pose_vertex(
    mesh: &SkinMesh,
    i: usize,
    t: &SkinTransform,
    morphs: Option<(&MorphTargets, &[f32])>,
) -> ([f32; 3], [f32; 3]) {
    let p = t.matrix.transform_point3(Vec3::from(mesh.positions[i]) + t.morph_offset_m);
    let mut n = Vec3::from(mesh.normals[i]);
    if let Some((m, mw)) = morphs.filter(|(m, _)| !m.normal_deltas.is_empty()) {
        let v = m.vertex_count as usize;
        for (k, &wt) in mw.iter().enumerate() {
            if wt != 0.0 {
                n += wt * Vec3::from(m.normal_deltas[k * v + i]);
            }
        }
    }
    let n = (t.normal_matrix * n).try_normalize().unwrap_or(Vec3::from(mesh.normals[i]));
    (p.to_array(), n.to_array())
}

fn check_skin_inputs(
    mesh: &SkinMesh,
    weights: Option<&SkinWeights>,
    morphs: Option<(&MorphTargets, &[f32])>,
    skinning: &[Mat4],
) -> Result<(), AnimationError> {
    let v = mesh.positions.len();
    if let Some(w) = weights {
        check_len("skin weights vertices", v, w.vertex_count())?;
        check_len("skinning matrices", w.bind_count as usize, skinning.len())?;
    }
    if let Some((m, mw)) = morphs {
        check_len("morph target vertices", v, m.vertex_count as usize)?;
        check_len("morph weights", m.target_count(), mw.len())?;
    }
    Ok(())
}

/// Morphs then skins every skin vertex into `positions` and `normals` (one per skin vertex):
/// `p' = (Σ wᵢ·Mᵢ)(p + Σ wₜ·Δpₜ)`, `n' = normalize(cof(Σ wᵢ·Mᵢ)·(n + Σ wₜ·Δnₜ))`. Without
/// `weights` only the morph is applied; without `morphs` only the skinning.
pub fn morph_and_skin(
    mesh: &SkinMesh,
    weights: Option<&SkinWeights>,
    morphs: Option<(&MorphTargets, &[f32])>,
    skinning: &[Mat4],
    positions: &mut [[f32; 3]],
    normals: &mut [[f32; 3]],
) -> Result<(), AnimationError> {
    let v = mesh.positions.len();
    check_len("output positions", v, positions.len())?;
    check_len("output normals", v, normals.len())?;
    check_skin_inputs(mesh, weights, morphs, skinning)?;
    for i in 0..v {
        let t = vertex_transform(i, weights, morphs, skinning);
        (positions[i], normals[i]) = pose_vertex(mesh, i, &t, morphs);
    }
    Ok(())
}

/// The sections an [`Animator`] plays: a skin mesh and what animates it.
#[derive(Clone, Debug)]
pub struct AnimatedSkin {
    /// The welded skin.
    pub mesh: Arc<SkinMesh>,
    /// Its clips (none: an empty set).
    pub clips: Arc<AnimationClips>,
    /// The joint hierarchy and bind palette, when the skin has skin weights.
    pub skeleton: Option<Arc<Skeleton>>,
    /// Influences per skin vertex.
    pub weights: Option<Arc<SkinWeights>>,
    /// Morph targets per skin vertex.
    pub morphs: Option<Arc<MorphTargets>>,
}

/// One pack's animation as a [`crate::World`] runs it: the pack's animation sections, a clip
/// player, and every buffer of a frame — pose, joint and skinning matrices, a [`SkinTransform`]
/// per skin vertex (what the fur simulation poses its masses with) and the skinned positions and
/// normals. Built once; [`Animator::update`] allocates nothing.
#[derive(Clone, Debug)]
pub struct Animator {
    clips: Arc<AnimationClips>,
    skeleton: Option<Arc<Skeleton>>,
    weights: Option<Arc<SkinWeights>>,
    morphs: Option<Arc<MorphTargets>>,
    mesh: Arc<SkinMesh>,
    player: AnimationPlayer,
    pose: Pose,
    /// Whether the pose comes from the host ([`Animator::set_joint_matrices`]) instead of the
    /// clip player.
    host_pose: bool,
    /// Whether [`Animator::update`] poses every skin vertex on the CPU
    /// ([`Animator::set_vertex_posing`]).
    vertex_posing: bool,
    world: Vec<Mat4>,
    skinning: Vec<Mat4>,
    transforms: Vec<SkinTransform>,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
}

impl Animator {
    /// Reads `pack`'s skin mesh and animation sections and starts clip `clip` at `start_s` with
    /// `speed` and `looping`, posed at once; with no `clip`, the skin stands in its rest pose
    /// until the host poses it ([`Animator::set_joint_matrices`]) or a clip is played. Fails when
    /// the pack has no clip named `clip` (the caller's error, [`AnimationError::UnknownClip`]),
    /// or on a bad section.
    pub fn new(
        pack: &crate::Pack,
        clip: Option<&str>,
        speed: f32,
        looping: bool,
        start_s: f32,
    ) -> Result<Animator, crate::RuntimeError> {
        let sections = AnimatedSkin {
            mesh: pack.skin_mesh()?,
            clips: pack.animation_clips()?.unwrap_or_default(),
            skeleton: pack.skeleton()?,
            weights: pack.skin_weights()?,
            morphs: pack.morph_targets()?,
        };
        // The sections were checked against each other when decoded (`check_consistency`); a
        // mismatch here is reported, not assumed away.
        Animator::from_sections(sections, clip, speed, looping, start_s)
            .map_err(|source| crate::RuntimeError::Animation { path: pack.display_path(), source })
    }

    /// [`Animator::new`] from sections already in memory (an imported glTF's, say), checked
    /// against each other here: the skin weights and morph targets must have one entry per
    /// skin vertex and the skeleton one bind per skinning matrix.
    pub fn from_sections(
        sections: AnimatedSkin,
        clip: Option<&str>,
        speed: f32,
        looping: bool,
        start_s: f32,
    ) -> Result<Animator, AnimationError> {
        let AnimatedSkin { mesh, clips, skeleton, weights, morphs } = sections;
        let player = match clip {
            Some(clip) => AnimationPlayer::new(&clips, clip, speed, looping, skeleton.as_deref(), morphs.as_deref())?,
            None => AnimationPlayer::at_rest(skeleton.as_deref(), morphs.as_deref()),
        };
        let pose = Pose::rest(skeleton.as_deref(), morphs.as_deref());
        let joints = skeleton.as_ref().map_or(0, |s| s.joint_count());
        let binds = skeleton.as_ref().map_or(0, |s| s.bind_count());
        let v = mesh.positions.len();
        let mut a = Animator {
            world: vec![Mat4::IDENTITY; joints],
            skinning: vec![Mat4::IDENTITY; binds],
            transforms: vec![SkinTransform::IDENTITY; v],
            positions: mesh.positions.clone(),
            normals: mesh.normals.clone(),
            clips,
            skeleton,
            weights,
            morphs,
            mesh,
            player,
            pose,
            host_pose: false,
            vertex_posing: true,
        };
        check_skin_inputs(
            &a.mesh,
            a.weights.as_deref(),
            a.morphs.as_deref().map(|m| (m, a.pose.morph_weights.as_slice())),
            &a.skinning,
        )?;
        a.player.seek(&a.clips, start_s);
        a.update()?;
        Ok(a)
    }

    /// Fails unless the pack has a clip named `name`.
    pub fn check_clip(&self, name: &str) -> Result<(), AnimationError> {
        clip_index(&self.clips, name).map(|_| ())
    }

    /// Moves the current clip to `time_s` (wrapped or clamped to it; posed at the next step).
    pub fn seek(&mut self, time_s: f32) -> Result<(), AnimationError> {
        finite("clip time", time_s)?;
        self.player.seek(&self.clips, time_s);
        Ok(())
    }

    /// Sets the playback speed (1 = real time, negative plays backwards; finite, |speed| ≤ 100 as
    /// a scene's `animation.speed`).
    pub fn set_speed(&mut self, speed: f32) -> Result<(), AnimationError> {
        finite("speed", speed)?;
        if speed.abs() > 100.0 {
            return Err(AnimationError::Value { what: "speed", value: speed });
        }
        self.player.set_speed(speed);
        Ok(())
    }

    /// Sets whether the current clip loops.
    pub fn set_looping(&mut self, looping: bool) {
        self.player.set_looping(looping);
    }

    /// Advances the player by `dt_s` seconds of scene time (not yet posed: see [`Animator::update`]).
    pub fn advance(&mut self, dt_s: f32) {
        self.player.advance(&self.clips, dt_s);
    }

    /// Switches to clip `name`, cross-fading over `fade_s` seconds (0: at once).
    pub fn play(&mut self, name: &str, fade_s: f32) -> Result<(), AnimationError> {
        self.player.play(&self.clips, name, fade_s)
    }

    /// Poses the skin from the host's animation system instead of the clip player, from the next
    /// [`Animator::update`] on (a `World` step's `animation` stage), until
    /// [`Animator::resume_clips`]: `joint_matrices` has one matrix per skeleton joint, in the
    /// skeleton's joint order ([`Animator::joint_nodes`] gives each joint's glTF node,
    /// [`Animator::joint_names`] its name), each the joint's transform in the skinned mesh's
    /// frame (glTF: the joint node's global transform with the mesh node's taken out, before the
    /// inverse bind — what [`Animator::joint_matrices`] gives for the clips' poses), and
    /// `morph_weights` one weight per morph target. The skin, the fur's anchors and the skinning
    /// matrices a renderer reads follow exactly as they follow the clips: the same matrices give
    /// the same state. Fails, changing nothing, on a wrong count or a non-finite value. Allocates
    /// nothing.
    pub fn set_joint_matrices(&mut self, joint_matrices: &[Mat4], morph_weights: &[f32]) -> Result<(), AnimationError> {
        check_len("joint matrices", self.world.len(), joint_matrices.len())?;
        check_len("morph weights", self.pose.morph_weights.len(), morph_weights.len())?;
        if let Some(v) = joint_matrices.iter().flat_map(|m| m.to_cols_array()).find(|v| !v.is_finite()) {
            return Err(AnimationError::Value { what: "joint matrix element", value: v });
        }
        if let Some(&w) = morph_weights.iter().find(|w| !w.is_finite()) {
            return Err(AnimationError::Value { what: "morph weight", value: w });
        }
        self.world.copy_from_slice(joint_matrices);
        self.pose.morph_weights.copy_from_slice(morph_weights);
        self.host_pose = true;
        Ok(())
    }

    /// Poses the skin from the clip player again after [`Animator::set_joint_matrices`] (the
    /// clip's time has gone on meanwhile).
    pub fn resume_clips(&mut self) {
        self.host_pose = false;
    }

    /// Whether the host poses the skin ([`Animator::set_joint_matrices`]).
    pub fn is_host_posed(&self) -> bool {
        self.host_pose
    }

    /// Whether [`Animator::update`] poses each skin vertex on the CPU (its transform, position
    /// and normal; on by default). A host whose GPU skins the mesh and blends the fur's anchors
    /// from [`Animator::skinning_matrices`] and [`Animator::morph_weights`] (GPU fur physics,
    /// docs/design.md "Fur physics on the GPU") turns it off and saves the per-vertex blend,
    /// which grows with every character of a crowd; [`Animator::transforms`],
    /// [`Animator::positions`] and [`Animator::normals`] then keep the last pose that had it on.
    pub fn set_vertex_posing(&mut self, on: bool) {
        self.vertex_posing = on;
    }

    /// Whether [`Animator::update`] poses each skin vertex ([`Animator::set_vertex_posing`]).
    pub fn is_vertex_posing(&self) -> bool {
        self.vertex_posing
    }

    /// Poses the skin at the player's current time, or from the host's joint matrices: pose,
    /// joint and skinning matrices, and (unless [`Animator::set_vertex_posing`] turned it off)
    /// vertex transforms, skinned positions and normals.
    pub fn update(&mut self) -> Result<(), AnimationError> {
        if !self.host_pose {
            let groups = self.morphs.as_ref().map_or(&[][..], |m| m.groups.as_slice());
            self.player.pose(&self.clips, groups, &mut self.pose)?;
        }
        if let Some(s) = &self.skeleton {
            if !self.host_pose {
                joint_world_matrices(s, &self.pose, &mut self.world)?;
            }
            skinning_matrices(s, &self.world, &mut self.skinning)?;
        }
        if !self.vertex_posing {
            return Ok(());
        }
        let weights = self.weights.as_deref();
        let morphs = self.morphs.as_deref().map(|m| (m, self.pose.morph_weights.as_slice()));
        for i in 0..self.transforms.len() {
            let t = vertex_transform(i, weights, morphs, &self.skinning);
            (self.positions[i], self.normals[i]) = pose_vertex(&self.mesh, i, &t, morphs);
            self.transforms[i] = t;
        }
        Ok(())
    }

    /// An axis-aligned box (mesh frame, metres: `(min, max)`) holding the skin in the current
    /// pose and in `samples` poses spread evenly over the whole clip playing now: what a viewer
    /// frames so that a walking character stays in the picture over its clip (docs/design.md
    /// "Rendering"). Poses a copy of this animator; this one is left as it is. Allocates the
    /// copy.
    pub fn clip_bounds(&self, samples: u32) -> Result<([f32; 3], [f32; 3]), AnimationError> {
        let grow = |(lo, hi): (Vec3, Vec3), positions: &[[f32; 3]]| {
            positions.iter().fold((lo, hi), |(lo, hi), &p| (lo.min(Vec3::from(p)), hi.max(Vec3::from(p))))
        };
        let mut bounds = grow((Vec3::INFINITY, Vec3::NEG_INFINITY), &self.positions);
        let mut sweep = self.clone();
        sweep.host_pose = false;
        sweep.vertex_posing = true;
        let duration = self.clips.clips.get(self.player.current().clip).map_or(0.0, |c| c.duration_s);
        for k in 0..samples {
            sweep.player.seek(&sweep.clips, duration * k as f32 / samples as f32);
            sweep.update()?;
            bounds = grow(bounds, &sweep.positions);
        }
        Ok((bounds.0.to_array(), bounds.1.to_array()))
    }

    /// The clip playing now.
    pub fn playback(&self) -> ClipPlayback {
        self.player.current()
    }

    /// The name of clip `index`.
    pub fn clip_name(&self, index: usize) -> &str {
        self.clips.clips.get(index).map_or("", |c| c.name.as_str())
    }

    /// Per skin vertex: bind pose → now.
    pub fn transforms(&self) -> &[SkinTransform] {
        &self.transforms
    }

    /// Skinned positions per skin vertex, mesh frame, metres.
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
    }

    /// Skinned unit normals per skin vertex, mesh frame.
    pub fn normals(&self) -> &[[f32; 3]] {
        &self.normals
    }

    /// The skeleton's joint names (the glTF node names, empty when unnamed), in the order
    /// [`Animator::set_joint_matrices`] takes; empty without a skeleton.
    pub fn joint_names(&self) -> &[String] {
        self.skeleton.as_deref().map_or(&[], |s| s.names.as_slice())
    }

    /// The glTF node index of each joint, in the same order: how an engine that imported the same
    /// glTF maps its skeleton onto this one without relying on names. Empty without a skeleton,
    /// or for a pack baked before joints recorded their nodes (its joints are matched by name).
    pub fn joint_nodes(&self) -> &[u32] {
        self.skeleton.as_deref().map_or(&[], |s| s.nodes.as_slice())
    }

    /// The joint that glTF node `node` is, if any.
    pub fn joint_of_node(&self, node: u32) -> Option<usize> {
        self.joint_nodes().iter().position(|&n| n == node)
    }

    /// Joint matrices of the current pose, one per skeleton joint: each joint's transform in the
    /// skinned mesh's frame (what [`Animator::set_joint_matrices`] takes); empty without a
    /// skeleton.
    pub fn joint_matrices(&self) -> &[Mat4] {
        &self.world
    }

    /// Skinning matrices (`world(joint) × inverseBind`, one per bind) of the current pose; empty
    /// without a skeleton. With [`Animator::morph_weights`] this is what a GPU skinning pass takes.
    pub fn skinning_matrices(&self) -> &[Mat4] {
        &self.skinning
    }

    /// Morph weights of the current pose (one per morph target; empty without morph targets).
    pub fn morph_weights(&self) -> &[f32] {
        &self.pose.morph_weights
    }
}
