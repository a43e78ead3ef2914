//! The world `furbake view` shows and what the viewer's keys do to it: play and pause, step
//! forward, step back (by re-simulating from time 0: physics does not run backwards), reset,
//! cycle animation clips, and switch declared effects off and on by zeroing and restoring their
//! strength through `World::update_effects` (the stage plan stays as the scene declared it).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::anyhow;
use furbake_formats::SectionKind;
use furbake_render::FurAsset;
use furbake_runtime::scene::PackAnimation;
use furbake_runtime::{Effect, Effects, Pack, Scene, ScenePack, StageStats, World, WorldOptions, WorldPlan};

use crate::failure::{self, Failure};
use crate::preview_cmd;

/// Cross-fade when the viewer switches clips, seconds of scene time.
pub const CLIP_FADE_S: f32 = 0.25;

/// A running world and what rebuilding it takes.
pub struct Session {
    /// The input file, for messages.
    pub path: PathBuf,
    /// The scene as loaded: effects at their declared strengths, clips as declared.
    scene: Scene,
    /// The opened packs, one per scene entry, shared by every rebuilt world (nothing is read or
    /// decoded twice).
    packs: Vec<Arc<Pack>>,
    /// The world on screen.
    pub world: World,
    /// The declared effects in order (keys 1–9), each with whether the viewer switched it off.
    pub effects: Vec<(Effect, bool)>,
    /// Whether scene time runs.
    pub playing: bool,
}

impl Session {
    /// The session of a world as loaded (effects on, playing).
    pub fn new(path: &Path, world: World) -> Session {
        let scene = world.scene().clone();
        let packs = (0..world.pack_count()).map(|i| Arc::clone(world.pack(i))).collect();
        let effects = scene.effects().enabled().into_iter().map(|e| (e, false)).collect();
        Session { path: path.to_path_buf(), scene, packs, world, effects, playing: true }
    }

    /// The scene's time step, seconds.
    pub fn time_step_s(&self) -> f64 {
        self.scene.time_step_s() as f64
    }

    /// Advances the world one time step.
    pub fn step(&mut self) -> Result<(), Failure> {
        self.world.step().map_err(|e| failure::runtime(e, &self.path))
    }

    /// Back to time 0 as loaded: a new world over the same packs, every effect on, the scene's
    /// clips, playing.
    pub fn reset(&mut self) -> Result<(), Failure> {
        self.world = self.rebuild()?;
        self.effects.iter_mut().for_each(|(_, off)| *off = false);
        self.playing = true;
        Ok(())
    }

    /// Pauses and goes back `steps` time steps. A mass–spring world cannot be stepped backwards,
    /// so this re-simulates: a new world from time 0 over the same packs, the effects switched off
    /// now switched off from the start and each animated pack playing the clip it plays now,
    /// stepped forward to the earlier time (its cost grows with the scene time reached). The
    /// world is deterministic, so without switches or clip changes this is the state the world
    /// had then.
    pub fn step_back(&mut self, steps: u64) -> Result<(), Failure> {
        self.playing = false;
        let target = self.world.steps().saturating_sub(steps);
        let clips: Vec<Option<String>> = (0..self.world.pack_count())
            .map(|i| self.world.animation(i).map(|a| a.clip_name(a.playback().clip).to_string()))
            .collect();
        let mut world = self.rebuild()?;
        let (declared, off) = (&self.scene.effects(), &self.effects);
        world
            .update_effects(|e| {
                for &(effect, switched_off) in off {
                    set_strength(e, declared, effect, !switched_off);
                }
            })
            .map_err(|e| failure::runtime(e, &self.path))?;
        for (i, clip) in clips.iter().enumerate() {
            if let (Some(clip), Some(animator)) = (clip, world.animation_mut(i)) {
                animator.play(clip, 0.0).map_err(|e| Failure::Input(anyhow!("{}: {e}", self.path.display())))?;
            }
        }
        self.world = world;
        for _ in 0..target {
            self.step()?;
        }
        Ok(())
    }

    /// Switches the `index`-th declared effect (0-based) off or back on. Returns what happened,
    /// for the user: the effect's new state, or why it cannot be switched.
    pub fn toggle_effect(&mut self, index: usize) -> Result<String, Failure> {
        let Some(&(effect, off)) = self.effects.get(index) else {
            return Ok(format!("key {}: the scene declares {} effects", index + 1, self.effects.len()));
        };
        if !is_switchable(effect) {
            return Ok(format!(
                "{}: cannot be switched from the viewer (it has no strength to set to zero)",
                effect_name(effect)
            ));
        }
        let declared = &self.scene.effects();
        self.world
            .update_effects(|e| {
                set_strength(e, declared, effect, off);
            })
            .map_err(|e| failure::runtime(e, &self.path))?;
        self.effects[index].1 = !off;
        Ok(format!("{}: {}", effect_name(effect), if off { "on" } else { "off" }))
    }

    /// Every animated pack cross-fades to its next clip (after the last, the first). Returns the
    /// clips now playing, `pack: clip`, or `None` when no pack is animated.
    pub fn next_clip(&mut self) -> Result<Option<String>, Failure> {
        let mut playing = Vec::new();
        for i in 0..self.world.pack_count() {
            let Some(animator) = self.world.animation_mut(i) else { continue };
            let next = animator.playback().clip + 1;
            // `clip_name` is empty past the last clip.
            let name = match animator.clip_name(next) {
                "" => animator.clip_name(0),
                name => name,
            }
            .to_string();
            animator.play(&name, CLIP_FADE_S).map_err(|e| Failure::Input(anyhow!("{}: {e}", self.path.display())))?;
            playing.push(format!("{}: {name}", self.scene.packs()[i].name));
        }
        Ok((!playing.is_empty()).then(|| playing.join(", ")))
    }

    /// The clip of the first animated pack, if any.
    pub fn clip(&self) -> Option<&str> {
        (0..self.world.pack_count()).find_map(|i| self.world.animation(i).map(|a| a.clip_name(a.playback().clip)))
    }

    /// The names of the effects switched off, in declared order.
    pub fn switched_off(&self) -> Vec<&'static str> {
        self.effects.iter().filter(|(_, off)| *off).map(|&(e, _)| effect_name(e)).collect()
    }

    /// The planned stage with the largest mean wall time per step (`None` before the first step
    /// or without stages).
    pub fn slowest_stage(&self) -> Option<StageStats> {
        self.world.stage_stats().into_iter().filter(|s| s.runs > 0).max_by_key(StageStats::mean)
    }

    fn rebuild(&self) -> Result<World, Failure> {
        World::with_packs(self.scene.clone(), self.packs.clone(), WorldOptions::default())
            .map_err(|e| failure::runtime(e, &self.path))
    }
}

/// A pack alone in a default scene, as `furbake preview PACK` shows it: at the origin, no
/// effects, the default light and time step, framed tightly from the three-quarter view for a
/// target of `aspect` (width / height) when it has fur (else framed from its bounds), playing its
/// first clip in a loop when it is animated. The renderers' GPU memory plus `target_bytes` is
/// checked against `max_memory` as for a scene.
pub fn pack_world(path: &Path, aspect: f32, target_bytes: u64, max_memory: u64) -> Result<World, Failure> {
    let input = |e: anyhow::Error| Failure::Input(e.context(format!("{}: cannot view", path.display())));
    // Validated as `verify` does before anything reads it (docs/design.md "Runtime: packs").
    let pack = crate::describe::open_verified(path)?;
    let first_clip = pack
        .animation_clips()
        .map_err(|e| input(e.into()))?
        .and_then(|clips| clips.clips.first().map(|c| c.name.clone()));
    let mut entry = ScenePack::new("pack", path);
    entry.animation = first_clip.map(PackAnimation::new);
    // A pack alone says nothing of its units (the Fox glTF is in centimetres): distances in
    // metres would cull its grass, so only the frustum culls (G switches that off too).
    let mut scene = Scene::builder(vec![entry]).grass_culling(furbake_runtime::GrassCulling::frustum_only());
    if pack.has(SectionKind::SKIN_MESH) && pack.has(SectionKind::SHELL_ATLAS) {
        let asset = FurAsset::from_pack(&pack, false).map_err(|e| preview_cmd::render_failure(e, path))?;
        scene = scene.camera(Some(asset.auto_view(aspect).camera));
    }
    let scene = scene.build().map_err(failure::scene)?;
    let world = WorldPlan::with_packs(scene, vec![Arc::new(pack)], WorldOptions::default())
        .and_then(WorldPlan::build)
        .map_err(|e| failure::runtime(e, path))?;
    preview_cmd::check_gpu_memory(&world, path, target_bytes, max_memory)?;
    Ok(world)
}

/// True for the effects the viewer can switch off: those with a strength (gravity's
/// acceleration, the wind's velocity, the wind sources' power, object motion's inertia scale,
/// the interaction brush's force).
pub fn is_switchable(effect: Effect) -> bool {
    matches!(effect, Effect::Gravity | Effect::Wind | Effect::WindSources | Effect::ObjectMotion | Effect::Interaction)
}

/// Sets `effect`'s strength in `effects` to its declared value in `declared` (`on`) or to zero.
/// Returns false, changing nothing, for an effect without a strength ([`is_switchable`]).
pub fn set_strength(effects: &mut Effects, declared: &Effects, effect: Effect, on: bool) -> bool {
    match effect {
        Effect::Gravity => {
            if let (Some(g), Some(d)) = (effects.gravity.as_mut(), declared.gravity) {
                g.acceleration_m_per_s2 = if on { d.acceleration_m_per_s2 } else { [0.0; 3] };
            }
        }
        Effect::Wind => {
            if let (Some(w), Some(d)) = (effects.wind.as_mut(), declared.wind) {
                w.velocity_m_per_s = if on { d.velocity_m_per_s } else { [0.0; 3] };
            }
        }
        Effect::WindSources => {
            for (s, d) in effects.wind_sources.iter_mut().zip(&declared.wind_sources) {
                s.power = if on { d.power } else { 0.0 };
            }
        }
        Effect::ObjectMotion => {
            if let (Some(m), Some(d)) = (effects.object_motion.as_mut(), declared.object_motion) {
                m.inertia_scale = if on { d.inertia_scale } else { 0.0 };
            }
        }
        Effect::Interaction => {
            if let (Some(i), Some(d)) = (effects.interaction.as_mut(), declared.interaction) {
                i.strength_n = if on { d.strength_n } else { 0.0 };
            }
        }
        Effect::Collisions | Effect::WindlessAreas | Effect::Parting | Effect::WrongSideGuard => return false,
    }
    true
}

/// The effect's name as a scene's `[effects]` table spells it.
pub fn effect_name(effect: Effect) -> &'static str {
    match effect {
        Effect::Gravity => "gravity",
        Effect::Wind => "wind",
        Effect::WindSources => "wind_sources",
        Effect::ObjectMotion => "object_motion",
        Effect::Interaction => "interaction",
        Effect::Collisions => "collisions",
        Effect::WindlessAreas => "windless_areas",
        Effect::Parting => "parting",
        Effect::WrongSideGuard => "wrong_side_guard",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn demo_effects() -> Effects {
        let text = r#"
            [[packs]]
            name = "a"
            path = "a.fbk"
            [effects.gravity]
            [effects.wind]
            velocity_m_per_s = [2.0, 0.0, 0.5]
            gust_amplitude = 0.5
            [[effects.wind_sources]]
            position = [-1.0, 0.4, 0.0]
            power = 2.0
            [effects.object_motion]
            inertia_scale = 0.5
            [effects.interaction]
            radius_m = 0.1
            strength_n = 3.0
            [effects.wrong_side_guard]
        "#;
        Scene::from_toml_str(text, "s.toml".as_ref(), Path::new("")).unwrap().effects().clone()
    }

    #[test]
    fn switching_an_effect_off_zeroes_its_strength_and_on_restores_it() {
        let declared = demo_effects();
        let mut effects = declared.clone();
        let switchable: Vec<Effect> = declared.enabled().into_iter().filter(|&e| is_switchable(e)).collect();
        assert_eq!(switchable.len(), 5, "{switchable:?}");
        for &effect in &switchable {
            assert!(set_strength(&mut effects, &declared, effect, false));
        }
        assert_eq!(effects.gravity.unwrap().acceleration_m_per_s2, [0.0; 3]);
        assert_eq!(effects.wind.unwrap().velocity_m_per_s, [0.0; 3]);
        assert_eq!(effects.wind.unwrap().gust_amplitude, 0.5, "the gust is relative: it stays");
        assert_eq!(effects.wind_sources[0].power, 0.0);
        assert_eq!(effects.object_motion.unwrap().inertia_scale, 0.0);
        assert_eq!(effects.interaction.unwrap().strength_n, 0.0);
        assert_eq!(effects.declared(), declared.declared(), "the declared set is unchanged");
        for &effect in &switchable {
            assert!(set_strength(&mut effects, &declared, effect, true));
        }
        assert_eq!(effects, declared);
    }

    #[test]
    fn effects_without_a_strength_are_not_switched() {
        let declared = demo_effects();
        let mut effects = declared.clone();
        let mut refused = 0;
        for effect in [Effect::Collisions, Effect::WindlessAreas, Effect::Parting, Effect::WrongSideGuard] {
            assert!(!is_switchable(effect));
            assert!(!set_strength(&mut effects, &declared, effect, false));
            refused += 1;
        }
        assert_eq!(refused, 4);
        assert_eq!(effects, declared);
    }
}
