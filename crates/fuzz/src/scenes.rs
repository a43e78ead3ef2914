//! The scene target: mutations of the fixture scenes (`fixtures/scenes/*.toml`) whose packs are
//! pointed at base packs written beside them, and what is run on each mutant:
//! [`Scene::from_toml_str`], then a [`World`] over it stepped a few times.
//!
//! TOML mutations know the scene's shape: numbers become NaN, infinite, huge, negative or zero;
//! strings become other effect, solver and event names; keys are removed; arrays shortened or
//! lengthened; `[[packs]]` entries multiplied (up to 64 entries of the same file); events moved
//! to absurd times; and now and then the text itself is mangled.

use std::path::Path;

use furbake_runtime::{Scene, World};
use toml::Value;

use crate::rng::Rng;

/// The names the base packs are written under in the scene directory.
pub const PACK_FILES: [&str; 4] = ["sphere.fbk", "grass_patch.fbk", "plane.fbk", "Fox.fbk"];

/// `text` with every `[[packs]]` path pointing at one of [`PACK_FILES`] (by entry order).
pub fn point_at_base_packs(text: &str) -> Option<String> {
    let mut doc: toml::Table = toml::from_str(text).ok()?;
    if let Some(Value::Array(packs)) = doc.get_mut("packs") {
        for (i, p) in packs.iter_mut().enumerate() {
            if let Some(t) = p.as_table_mut() {
                t.insert("path".into(), Value::String(PACK_FILES[(i + 3) % PACK_FILES.len()].into()));
            }
        }
    }
    toml::to_string(&doc).ok()
}

fn walk(v: &Value, prefix: &mut Vec<PathStep>, out: &mut Vec<Vec<PathStep>>) {
    out.push(prefix.clone());
    match v {
        Value::Table(t) => {
            for (k, x) in t {
                prefix.push(PathStep::Key(k.clone()));
                walk(x, prefix, out);
                prefix.pop();
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                prefix.push(PathStep::Index(i));
                walk(x, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

#[derive(Clone, Debug)]
enum PathStep {
    Key(String),
    Index(usize),
}

fn at<'a>(v: &'a mut Value, path: &[PathStep]) -> Option<&'a mut Value> {
    let mut cur = v;
    for p in path {
        cur = match p {
            PathStep::Key(k) => cur.as_table_mut()?.get_mut(k)?,
            PathStep::Index(i) => cur.as_array_mut()?.get_mut(*i)?,
        };
    }
    Some(cur)
}

fn float(rng: &mut Rng, near: f64) -> Value {
    Value::Float(match rng.below(6) {
        0 => *rng.pick(&[f64::NAN, f64::INFINITY, f64::NEG_INFINITY]),
        1 => *rng.pick(&[1e300, -1e300, 3.5e38, 1e9, 1e-9, 1e-45, 0.0, -0.0]),
        2 => -near,
        3 => near * 1e6,
        4 => near * 1e-6,
        _ => near + 1.0,
    })
}

/// One mutation of a parsed scene.
fn mutate_value(rng: &mut Rng, doc: &mut Value) {
    let mut all = Vec::new();
    walk(doc, &mut Vec::new(), &mut all);
    let path = rng.pick(&all).clone();
    let Some(v) = at(doc, &path) else { return };
    match v {
        Value::Float(x) => *v = float(rng, *x),
        Value::Integer(x) => {
            *v = if rng.chance(1, 2) {
                Value::Integer(*rng.pick(&[0, -1, 1, 1000, 100_000_000, i64::MAX, i64::MIN, u32::MAX as i64 + 1]))
            } else {
                float(rng, *x as f64)
            }
        }
        Value::String(s) => {
            *s = rng
                .pick(&[
                    "",
                    "gravity",
                    "wind",
                    "wind_sources",
                    "parting",
                    "teleport",
                    "forces_off",
                    "forces_on",
                    "play_clip",
                    "Walk",
                    "Run",
                    "Survey",
                    "implicit",
                    "explicit",
                    "stick",
                    "reference",
                    "auto",
                    "sphere",
                    "ellipsoid",
                    "fox",
                    "grass",
                    "../../etc/passwd",
                    "/dev/zero",
                    "Fox.fbk",
                    "sphere.fbk",
                ])
                .to_string()
        }
        Value::Boolean(b) => *b = !*b,
        Value::Array(a) => match rng.below(4) {
            0 => a.clear(),
            1 => {
                let n = rng.below(a.len() + 1);
                a.truncate(n);
            }
            _ if !a.is_empty() => {
                let x = a[rng.below(a.len())].clone();
                let copies = if matches!(x, Value::Table(_)) { 1 + rng.below(63) } else { 1 };
                for k in 0..copies {
                    let mut y = x.clone();
                    // Copies of a [[packs]] entry need names of their own to be a valid scene.
                    if let Some(Value::String(name)) = y.as_table_mut().and_then(|t| t.get_mut("name")) {
                        name.push_str(&format!("_{k}"));
                    }
                    a.push(y);
                }
            }
            _ => a.push(Value::Float(1.0)),
        },
        Value::Table(t) => {
            if !t.is_empty() && rng.chance(2, 3) {
                let keys: Vec<String> = t.keys().cloned().collect();
                t.remove(rng.pick(&keys));
            } else {
                let key = rng.pick(&[
                    "time_step_s",
                    "duration_s",
                    "at_s",
                    "velocity_m_per_s",
                    "falloff_exponent",
                    "gust_frequency_hz",
                    "implicit_iterations",
                    "scale",
                    "radius_m",
                    "delayed_attenuation",
                    "speed",
                    "start_s",
                    "cut_speed_m_per_s",
                    "fade_s",
                    "dt_s",
                    "velocity_m_s",
                ]);
                t.insert(key.to_string(), float(rng, 1.0));
            }
        }
        Value::Datetime(_) => *v = Value::Integer(0),
    }
}

/// A mutant of the scene text `seed` (already pointing at the base packs).
pub fn mutate_scene(rng: &mut Rng, seed: &str) -> String {
    let rounds = *rng.pick(&[1, 1, 2, 3, 4]);
    let mut text = match (rng.chance(9, 10), toml::from_str::<toml::Table>(seed)) {
        (true, Ok(table)) => {
            let mut doc = Value::Table(table);
            for _ in 0..rounds {
                mutate_value(rng, &mut doc);
            }
            toml::to_string(&doc).unwrap_or_default()
        }
        _ => seed.to_owned(),
    };
    if rng.chance(1, 10) {
        let mut bytes = text.into_bytes();
        crate::gltf::mutate_bytes(rng, &mut bytes);
        text = String::from_utf8_lossy(&bytes).into_owned();
    }
    text
}

/// What happened to one scene mutant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SceneOutcome {
    /// The scene parser refused it.
    SceneRejected,
    /// The world refused it (a pack missing, the wrong topology, ...).
    WorldRejected,
    /// A step failed with an error.
    StepFailed,
    /// Every step ran.
    Stepped,
}

/// Parses `text` (packs resolved in `dir`), builds a world and steps it `steps` times.
pub fn run_scene(text: &str, dir: &Path, steps: u32) -> SceneOutcome {
    let Ok(scene) = Scene::from_toml_str(text, Path::new("fuzz.toml"), dir) else {
        return SceneOutcome::SceneRejected;
    };
    let Ok(mut world) = World::new(scene) else { return SceneOutcome::WorldRejected };
    for _ in 0..steps {
        if world.step().is_err() {
            return SceneOutcome::StepFailed;
        }
    }
    for i in 0..world.pack_count() {
        let _ = world.pack_state(i);
    }
    SceneOutcome::Stepped
}
