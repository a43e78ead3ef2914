//! Scene descriptions (docs/design.md "Runtime: scenes and stages"): which packs to load and where, the camera, the
//! light, the time step, and the list of effects the scene wants. Parsed from TOML, then
//! validated once into a [`Scene`] whose values can be trusted (finite, in range, unique names);
//! the runtime builds only the stages the declared effects need (see [`Scene::effects`]).
//!
//! Effects and the thesis parts they stand for: gravity and global wind (fur thesis §3.3 external
//! forces), wind sources `w = normalize(WP)·ω/|WP|^σ` (grass thesis eq. 4.1), object motion
//! (inertial forces, fur thesis §3.4), local interaction, collisions as local sources (grass
//! thesis §5), windless areas (grass thesis §5.1), parting (separable topologies, fur thesis
//! §3.4.1) and the wrong-side guard (fur thesis §3.4.3, eq. 3.37).
//!
//! ```toml
//! time_step_s = 0.0166
//! [camera]
//! eye = [0.0, 1.0, 3.0]
//! target = [0.0, 0.5, 0.0]
//! [[lights]]
//! type = "directional"
//! direction = [-0.3, -1.0, -0.4]
//! [[lights]]
//! type = "point"
//! position = [1.0, 1.5, 1.0]
//! color = [1.0, 0.8, 0.6]
//! intensity = 2.0
//! [ambient]
//! sky = [0.3, 0.32, 0.35]
//! ground = [0.15, 0.14, 0.12]
//! [[packs]]
//! name = "fox"
//! path = "fox.fbk"
//! [effects.gravity]
//! [effects.wind]
//! velocity_m_per_s = [2.0, 0.0, 0.0]
//! ```

use std::path::{Path, PathBuf};

use glam::{EulerRot, Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};

/// Why a scene file was rejected.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: {source}", path = path.display())]
    Io {
        /// The scene file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML or does not have the scene's shape (unknown key, wrong type).
    #[error("{path}: {message}", path = path.display())]
    Parse {
        /// The scene file (or `<memory>`).
        path: PathBuf,
        /// The TOML parser's message, with line and column.
        message: String,
    },
    /// The scene is written in a form furbake no longer reads (a retired key, or a whole
    /// furbake-sim scene); `what` says how to write it now. Blame: the caller's usage.
    #[error("{path}: {field}: {what}", path = path.display())]
    Outdated {
        /// The scene file (or `<memory>`).
        path: PathBuf,
        /// Dotted path of the retired key.
        field: String,
        /// What to write instead.
        what: String,
    },
    /// A value is out of range. Blame: the scene's author.
    #[error("{path}: {field}: {what}", path = path.display())]
    Invalid {
        /// The scene file (or `<memory>`).
        path: PathBuf,
        /// Dotted path of the offending key (`effects.wind_sources[1].falloff_exponent`).
        field: String,
        /// What is wrong with it.
        what: String,
    },
}

/// A validated scene: made only by [`Scene::load`], [`Scene::from_toml_str`] or
/// [`SceneBuilder::build`], each of which checks every value, so a `Scene` is valid by
/// construction and the stages below trust it (docs/design.md "Scenes"). Its fields are read
/// through accessors; [`Scene::into_builder`] changes one and validates again.
///
/// ```
/// use furbake_runtime::{Scene, ScenePack, scene::{Effects, Gravity}};
/// let scene = Scene::builder(vec![ScenePack::new("fox", "fox.fbk")])
///     .time_step_s(0.01)
///     .effects(Effects { gravity: Some(Gravity::default()), ..Effects::default() })
///     .build()?;
/// assert_eq!(scene.packs()[0].name, "fox");
/// // A value out of range is refused with the key that holds it.
/// let err = scene.into_builder().time_step_s(-1.0).build().unwrap_err();
/// assert!(err.to_string().contains("time_step_s"), "{err}");
/// # Ok::<(), furbake_runtime::SceneError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Simulation time step in seconds. Default 1/60.
    #[serde(default = "default_time_step")]
    pub(crate) time_step_s: f32,
    /// The fur solver: `[solver] kind = "auto" | "explicit" | "implicit" | "stick" | "reference"
    /// | "xpbd" | "local_global"` and `implicit_iterations`, `xpbd_iterations`,
    /// `local_global_iterations`, or the shorthand `solver = "implicit"`. Default `auto` (picked
    /// from the topology, see [`SolverChoice::Auto`]) with one implicit iteration.
    #[serde(default)]
    pub(crate) solver: Solver,
    /// How long `furbake simulate` runs the scene when no `--frames` is given, seconds, in
    /// (0, 86400]. Default `None` (2 s).
    #[serde(default)]
    pub(crate) duration_s: Option<f64>,
    /// The viewpoint. Default: framed automatically from the packs' bounds (`None`).
    #[serde(default)]
    pub(crate) camera: Option<Camera>,
    /// The single directional light with its ambient share (`[light]`), the shorthand of
    /// `lights` + `ambient`. `None` with no `lights`: [`Light::default`]. A scene gives either
    /// `[light]` or `[[lights]]`/`[ambient]`, not both; [`Scene::lighting`] is what is drawn.
    #[serde(default)]
    pub(crate) light: Option<Light>,
    /// Up to [`MAX_LIGHTS`] light sources (`[[lights]]`, `type = "directional"` or `"point"`).
    #[serde(default)]
    pub(crate) lights: Vec<LightSource>,
    /// The hemisphere ambient light (`[ambient]`) that goes with `lights`. Default
    /// [`Ambient::default`].
    #[serde(default)]
    pub(crate) ambient: Option<Ambient>,
    /// The packs to load, at least one.
    pub(crate) packs: Vec<ScenePack>,
    /// The effects the scene asks for; anything absent is not built.
    #[serde(default)]
    pub(crate) effects: Effects,
    /// Timed events (`[[events]]`): teleports and effects switched off or on, applied before the
    /// first step that starts at or after their time, in file order among equal times.
    #[serde(default)]
    pub(crate) events: Vec<Event>,
    /// How every pack is drawn (`[render]`: shell count, fins, blending, shading switches),
    /// unless a pack's `[packs.render]` says otherwise. Default: the renderer's defaults.
    #[serde(default)]
    pub(crate) render: RenderOptions,
    /// How grass blades are culled and simplified with distance (`[grass_culling]`). Default:
    /// [`GrassCulling::default`].
    #[serde(default)]
    pub(crate) grass_culling: GrassCulling,
}

/// How many blades the renderer draws, and at what detail (grass thesis §5.3 and ch. 7; Jahrmann
/// & Wimmer 2017): the blade field's clusters are culled against the view frustum and
/// `max_distance_m`, then each blade by orientation, by the frustum (padded for any pose) and by
/// distance thinning, and the survivors are drawn at one of three levels of detail (every
/// segment, every second node, every fourth node). Distances are world metres from the eye to the
/// blade root.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct GrassCulling {
    /// Cull and simplify at all. Off: every blade at full detail, one instanced draw. Default on.
    pub enabled: bool,
    /// Blades farther than this are not drawn, metres, in (0, 1e6]. Default 150.
    pub max_distance_m: f32,
    /// Where the half-segment and quarter-segment levels of detail start, metres, increasing,
    /// each in (0, 1e6]. Default `[10, 30]`.
    pub lod_distances_m: [f32; 2],
    /// Width of the band around each LOD distance over which blades switch level one by one (a
    /// fixed random threshold per blade), as a fraction of that distance, in [0, 1]. Default 0.2.
    pub lod_transition: f32,
    /// Beyond this distance a blade is kept with probability `(thinning_start_m / d)²` (at least
    /// `min_density`) and drawn wider by the inverse, so the field's coverage stays the same
    /// while the number of blades per pixel stays constant; metres, in (0, 1e6]. Default 20.
    pub thinning_start_m: f32,
    /// Smallest fraction of blades thinning keeps, in (0, 1]. Default 0.25.
    pub min_density: f32,
    /// Blades seen so nearly edge-on that their projected width is below this fraction of their
    /// width are culled, in [0, 1). Default 0.1.
    pub min_visible_width: f32,
}

impl Default for GrassCulling {
    fn default() -> Self {
        GrassCulling {
            enabled: true,
            max_distance_m: 150.0,
            lod_distances_m: [10.0, 30.0],
            lod_transition: 0.2,
            thinning_start_m: 20.0,
            min_density: 0.25,
            min_visible_width: 0.1,
        }
    }
}

impl GrassCulling {
    /// No culling and no simplification: every blade at full detail.
    pub fn off() -> Self {
        GrassCulling { enabled: false, ..GrassCulling::default() }
    }

    /// Only what cannot change the image: clusters and blades outside the frustum or beyond
    /// `max_distance_m` (default 1e6 m here) are culled; no orientation culling, no thinning, every
    /// blade at full detail.
    pub fn frustum_only() -> Self {
        GrassCulling {
            enabled: true,
            max_distance_m: 1e6,
            lod_distances_m: [1e6, 1e6],
            lod_transition: 0.0,
            thinning_start_m: 1e6,
            min_density: 1.0,
            min_visible_width: 0.0,
        }
    }

    /// Checks every value's range; the error names the key (`grass_culling.min_density`) and
    /// what is wrong.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let f = |k: &str| format!("grass_culling.{k}");
        range(self.max_distance_m, 1e-6, 1e6, &f("max_distance_m"))?;
        for d in self.lod_distances_m {
            range(d, 1e-6, 1e6, &f("lod_distances_m"))?;
        }
        if self.lod_distances_m[1] < self.lod_distances_m[0] {
            return Err((f("lod_distances_m"), "must not decrease".into()));
        }
        range(self.lod_transition, 0.0, 1.0, &f("lod_transition"))?;
        range(self.thinning_start_m, 1e-6, 1e6, &f("thinning_start_m"))?;
        if !(self.min_density.is_finite() && self.min_density > 0.0 && self.min_density <= 1.0) {
            return Err((f("min_density"), format!("{} is not in (0, 1]", self.min_density)));
        }
        if !(self.min_visible_width.is_finite() && (0.0..1.0).contains(&self.min_visible_width)) {
            return Err((f("min_visible_width"), format!("{} is not in [0, 1)", self.min_visible_width)));
        }
        Ok(())
    }
}

fn default_time_step() -> f32 {
    1.0 / 60.0
}

/// Which mass–spring solver the scene runs (fur thesis §3.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum SolverChoice {
    /// Chosen from the topology and the pack: the stick solver for sticks and separable sticks
    /// (rigid links); for a spring topology on a pack that plays an animation, XPBD with one
    /// iteration per step (`xpbd_iterations` applies only to `kind = "xpbd"`); for every other
    /// spring topology implicit Euler, or XPBD with `xpbd_iterations` where the pack's physics
    /// runs on the GPU (`crate::stages::choose_solver`).
    #[default]
    Auto,
    /// Explicit Euler (eq. 3.20–3.25).
    Explicit,
    /// Implicit Euler (eq. 3.26–3.34).
    Implicit,
    /// Stick solver (orientation only).
    Stick,
    /// Linearised backward Euler converged by conjugate gradient: the accuracy reference, slow.
    Reference,
    /// Extended position-based dynamics (Macklin, Müller & Chentanez 2016), as NVIDIA Warp and
    /// Newton ship it.
    Xpbd,
    /// The fast mass–spring method of Liu, Bargteil, O'Brien & Kavan 2013 (local/global steps,
    /// prefactored matrix).
    LocalGlobal,
}

/// Where a scene's fur physics runs (`[solver] device`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum PhysicsDevice {
    /// furbake-sim on the CPU, the scale vectors uploaded every frame.
    #[default]
    Cpu,
    /// Compute passes the renderer records into the host's frame (furbake-render's
    /// `GpuFurPhysics`): the explicit, stick and XPBD solvers on static and animated skins; the
    /// World keeps each step's forces and skin pose for the renderer and leaves its own
    /// simulators at rest
    /// (docs/design.md "Fur physics on the GPU").
    Gpu,
}

/// The scene's `[solver]` table.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Solver {
    /// Which solver. Default `auto`.
    pub kind: SolverChoice,
    /// Where it runs. Default `cpu`.
    pub device: PhysicsDevice,
    /// Jacobi sweeps per implicit step, in [1, 1000]; 1 is the fur thesis's method. Default 1.
    pub implicit_iterations: u32,
    /// Gauss–Seidel iterations per XPBD step, in [1, 1000]. Default 8.
    pub xpbd_iterations: u32,
    /// Local/global iterations per step of the Liu et al. 2013 solver, in [1, 1000]. Default 10.
    pub local_global_iterations: u32,
}

impl Default for Solver {
    fn default() -> Self {
        let sim = furbake_sim::SolverSettings::default();
        Solver {
            kind: SolverChoice::Auto,
            device: PhysicsDevice::Cpu,
            implicit_iterations: 1,
            xpbd_iterations: sim.xpbd_iterations,
            local_global_iterations: sim.local_global_iterations,
        }
    }
}

/// The `[solver]` table as written (what [`Solver`] reads besides the `solver = "kind"`
/// shorthand).
#[derive(Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "schema", schemars(title = "SolverTable"))]
#[serde(deny_unknown_fields)]
struct SolverTable {
    /// Which solver. Default `auto`.
    #[serde(default)]
    kind: SolverChoice,
    /// Where it runs: `cpu` or `gpu` (the explicit, stick and XPBD solvers).
    /// Default `cpu`.
    #[serde(default)]
    device: PhysicsDevice,
    /// Jacobi sweeps per implicit step, in [1, 1000]; 1 is the fur thesis's method. Default 1.
    #[serde(default = "one_u32")]
    implicit_iterations: u32,
    /// Gauss–Seidel iterations per XPBD step, in [1, 1000]. Default 8.
    xpbd_iterations: Option<u32>,
    /// Local/global iterations per step of the Liu et al. 2013 solver, in [1, 1000]. Default 10.
    local_global_iterations: Option<u32>,
}

/// `solver = "implicit"` (the kind alone) or a `[solver]` table.
#[cfg(feature = "schema")]
impl schemars::JsonSchema for Solver {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Solver".into()
    }

    fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "description": "The fur solver: the kind alone (`solver = \"implicit\"`) or a `[solver]` table with the kind and its iteration counts.",
            "anyOf": [generator.subschema_for::<SolverChoice>(), generator.subschema_for::<SolverTable>()]
        })
    }
}

fn one_u32() -> u32 {
    1
}

impl<'de> Deserialize<'de> for Solver {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        // A string is the kind alone; anything else must be the table.
        let value = toml::Value::deserialize(d)?;
        if let toml::Value::String(_) = value {
            let kind = SolverChoice::deserialize(value).map_err(serde::de::Error::custom)?;
            return Ok(Solver { kind, ..Solver::default() });
        }
        let t = SolverTable::deserialize(value).map_err(serde::de::Error::custom)?;
        let d = Solver::default();
        Ok(Solver {
            kind: t.kind,
            device: t.device,
            implicit_iterations: t.implicit_iterations,
            xpbd_iterations: t.xpbd_iterations.unwrap_or(d.xpbd_iterations),
            local_global_iterations: t.local_global_iterations.unwrap_or(d.local_global_iterations),
        })
    }
}

/// A timed event of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Event {
    /// The pack jumps by `offset_m` (world metres) and stays there; its free fur masses keep their
    /// world positions and are pulled back by their springs — abrupt motion with no inertial
    /// force (the sim's teleport). Object motion ignores the jump.
    Teleport {
        /// Scene time, seconds, ≥ 0.
        at_s: f64,
        /// The pack's scene name.
        pack: String,
        /// The jump, world metres.
        offset_m: [f32; 3],
    },
    /// Switches force effects off from `at_s` on: `effects` lists them by name (`gravity`, `wind`,
    /// `wind_sources`, `object_motion`, `interaction`, `collisions`); empty or absent = every
    /// force. The restoring force of eq. 3.37 is part of the fur model and stays.
    ForcesOff {
        /// Scene time, seconds, ≥ 0.
        at_s: f64,
        /// The force effects switched off; empty = all.
        #[serde(default)]
        effects: Vec<Effect>,
    },
    /// Switches force effects back on (the inverse of `forces_off`).
    ForcesOn {
        /// Scene time, seconds, ≥ 0.
        at_s: f64,
        /// The force effects switched on; empty = all.
        #[serde(default)]
        effects: Vec<Effect>,
    },
    /// The pack switches to clip `clip` from its start, cross-fading from the clip playing over
    /// `fade_s` seconds (0: at once). Speed and looping stay as the pack's `animation` says
    /// (speed 1, looping, when the pack has none).
    PlayClip {
        /// Scene time, seconds, ≥ 0.
        at_s: f64,
        /// The pack's scene name.
        pack: String,
        /// Name of a clip in the pack.
        clip: String,
        /// Cross-fade length, seconds, in [0, 60]. Default 0.
        #[serde(default)]
        fade_s: f32,
    },
}

impl Event {
    /// The event's scene time, seconds.
    pub fn at_s(&self) -> f64 {
        match self {
            Event::Teleport { at_s, .. }
            | Event::ForcesOff { at_s, .. }
            | Event::ForcesOn { at_s, .. }
            | Event::PlayClip { at_s, .. } => *at_s,
        }
    }
}

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Eye position in metres (world space).
    pub eye: [f32; 3],
    /// Point looked at, in metres.
    pub target: [f32; 3],
    /// Up direction. Default `[0, 1, 0]` (glTF is Y-up).
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees, in (0, 180). Default 40.
    #[serde(default = "default_fov")]
    pub fov_y_deg: f32,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn default_fov() -> f32 {
    40.0
}

/// A directional light with an ambient term.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Light {
    /// Direction the light travels (from the light towards the scene); need not be unit length.
    /// Default `[-0.4, -1.0, -0.6]`.
    #[serde(default = "default_light_dir")]
    pub direction: [f32; 3],
    /// Linear RGB colour × intensity. Default white `[1, 1, 1]`.
    #[serde(default = "default_light_color")]
    pub color: [f32; 3],
    /// Ambient term added to Lambert's, in [0, 1]. Default 0.25 (the thesis uses none; a small
    /// ambient keeps the unlit side readable in previews).
    #[serde(default = "default_ambient")]
    pub ambient: f32,
}

fn default_light_dir() -> [f32; 3] {
    [-0.4, -1.0, -0.6]
}
fn default_light_color() -> [f32; 3] {
    [1.0, 1.0, 1.0]
}
fn default_ambient() -> f32 {
    0.25
}

impl Default for Light {
    fn default() -> Self {
        Light { direction: default_light_dir(), color: default_light_color(), ambient: default_ambient() }
    }
}

/// The most light sources one frame is lit by (the frame uniforms hold this many).
pub const MAX_LIGHTS: usize = 4;

/// One light source of a scene or a host's frame (`[[lights]]`; docs/design.md "Lights").
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum LightSource {
    /// Light from infinitely far away, travelling along `direction`.
    Directional {
        /// Direction the light travels (from the light towards the scene); need not be unit
        /// length.
        direction: [f32; 3],
        /// Linear RGB colour. Default white.
        #[serde(default = "default_light_color")]
        color: [f32; 3],
        /// Multiplier of `color`, ≥ 0. Default 1.
        #[serde(default = "default_intensity")]
        intensity: f32,
    },
    /// Light from a point, falling off with the inverse square of the distance: at 1 m it lights
    /// as a directional light of the same colour and intensity does.
    Point {
        /// Where the light is, world metres.
        position: [f32; 3],
        /// Linear RGB colour. Default white.
        #[serde(default = "default_light_color")]
        color: [f32; 3],
        /// Multiplier of `color` (the radiance at 1 m), ≥ 0. Default 1.
        #[serde(default = "default_intensity")]
        intensity: f32,
        /// Distance beyond which the light reaches nothing, metres, ≥ 0; the inverse square is
        /// windowed smoothly to zero there, `(1 − (d/range)⁴)²` (Karis 2013, as in Unreal and
        /// Filament). 0: unbounded. Default 0.
        #[serde(default)]
        range_m: f32,
    },
}

fn default_intensity() -> f32 {
    1.0
}

impl LightSource {
    /// Linear RGB colour × intensity.
    pub fn radiance(&self) -> [f32; 3] {
        let (LightSource::Directional { color, intensity, .. } | LightSource::Point { color, intensity, .. }) = *self;
        (Vec3::from(color) * intensity).to_array()
    }

    fn validate(&self, field: &str) -> Result<(), (String, String)> {
        let (LightSource::Directional { color, intensity, .. } | LightSource::Point { color, intensity, .. }) = *self;
        finite3(&color, &format!("{field}.color"))?;
        if color.iter().any(|&c| c < 0.0) {
            return Err((format!("{field}.color"), "must not be negative".into()));
        }
        range(intensity, 0.0, 1e9, &format!("{field}.intensity"))?;
        match self {
            LightSource::Directional { direction, .. } => nonzero3(direction, &format!("{field}.direction")),
            LightSource::Point { position, range_m, .. } => {
                finite3(position, &format!("{field}.position"))?;
                range(*range_m, 0.0, 1e9, &format!("{field}.range_m"))
            }
        }
    }
}

/// Hemisphere ambient light (`[ambient]`): `sky` on surfaces facing up (+Y), `ground` on those
/// facing down, blended by the normal's height, `mix(ground, sky, (1 + n.y)/2)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Ambient {
    /// Linear RGB from above. Default `[0.25, 0.25, 0.25]` (the `[light]` default's ambient).
    #[serde(default = "default_ambient_rgb")]
    pub sky: [f32; 3],
    /// Linear RGB from below. Default `[0.25, 0.25, 0.25]`.
    #[serde(default = "default_ambient_rgb")]
    pub ground: [f32; 3],
}

fn default_ambient_rgb() -> [f32; 3] {
    [default_ambient(); 3]
}

impl Default for Ambient {
    fn default() -> Self {
        Ambient { sky: default_ambient_rgb(), ground: default_ambient_rgb() }
    }
}

/// What a frame is lit by: up to [`MAX_LIGHTS`] sources and a hemisphere ambient term
/// (docs/design.md "Lights"). Fixed-size, `Copy`: a host builds one per frame without
/// allocating.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    sources: [LightSource; MAX_LIGHTS],
    count: usize,
    /// The ambient term.
    pub ambient: Ambient,
}

impl Lighting {
    /// The lighting of `sources` (at most [`MAX_LIGHTS`]: more are an error naming the count)
    /// and `ambient`.
    pub fn new(sources: &[LightSource], ambient: Ambient) -> Result<Lighting, String> {
        if sources.len() > MAX_LIGHTS {
            return Err(format!("{} light sources; at most {MAX_LIGHTS} light one frame", sources.len()));
        }
        let none = LightSource::Directional { direction: [0.0, -1.0, 0.0], color: [0.0; 3], intensity: 0.0 };
        let mut all = [none; MAX_LIGHTS];
        all[..sources.len()].copy_from_slice(sources);
        Ok(Lighting { sources: all, count: sources.len(), ambient })
    }

    /// The light sources.
    pub fn sources(&self) -> &[LightSource] {
        &self.sources[..self.count]
    }
}

impl Default for Lighting {
    /// What a scene without light keys and a pack previewed alone are lit by: a studio's key and
    /// rim light and a dim hemisphere ambient (docs/design.md "Lights"). The key comes from the
    /// upper left in front of `furbake_render::View::framing`'s three-quarter camera, about 70°
    /// from the view (so the terminator and the body's shape are in the picture; a light beside
    /// the eye draws a flat disc), the rim from behind on the right (the back-lit fur edge), and
    /// the ambient is dim in linear terms (0.25, the `[light]` default, reads as half brightness
    /// once encoded as sRGB and flattens the shading).
    fn default() -> Self {
        let key = LightSource::Directional { direction: [0.45, -0.75, -0.48], color: [1.0, 0.96, 0.9], intensity: 1.1 };
        let rim = LightSource::Directional { direction: [-0.6, -0.3, 0.75], color: [0.75, 0.85, 1.0], intensity: 0.45 };
        let ambient = Ambient { sky: [0.08, 0.09, 0.11], ground: [0.05, 0.045, 0.04] };
        Lighting::new(&[key, rim], ambient).expect("two lights")
    }
}

impl From<Light> for Lighting {
    /// The `[light]` shorthand: one directional light of colour `(1 − ambient) · color` and a
    /// uniform ambient of `ambient · color`, so `lambert = color · (ambient + (1 − ambient) ·
    /// N·L)` as before there were several lights.
    fn from(light: Light) -> Lighting {
        let color = Vec3::from(light.color);
        let direct = LightSource::Directional {
            direction: light.direction,
            color: (color * (1.0 - light.ambient)).to_array(),
            intensity: 1.0,
        };
        let ambient = (color * light.ambient).to_array();
        Lighting::new(&[direct], Ambient { sky: ambient, ground: ambient }).expect("one light")
    }
}

/// One pack placed in the scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ScenePack {
    /// Unique name within the scene.
    pub name: String,
    /// Path of the pack; relative paths are resolved against the scene file's directory.
    pub path: PathBuf,
    /// Translation at time 0, in metres. Default zero.
    #[serde(default)]
    pub translation: [f32; 3],
    /// Rotation at time 0 about X, then Y, then Z, in degrees. Default zero.
    #[serde(default)]
    pub rotation_deg: [f32; 3],
    /// Uniform scale, > 0. Default 1.
    #[serde(default = "one")]
    pub scale: f32,
    /// Keyframes of a motion path (times strictly increasing), applied on top of the placement
    /// above (world = motion(t) · placement); empty = static. Before the first key the pack sits
    /// at the first key, after the last at the last.
    #[serde(default)]
    pub motion: Vec<MotionKey>,
    /// The clip the pack's skeleton and morph targets play
    /// (`animation = { clip = "Walk", speed = 1.0, loop = true }`); absent = the bind pose.
    /// `play_clip` events switch clips later.
    #[serde(default)]
    pub animation: Option<PackAnimation>,
    /// How the pack's fur is shaded (`[packs.shading]`: the strand model's parameters, each
    /// optional). Default: [`FurShading::default`].
    #[serde(default)]
    pub shading: FurShading,
    /// How this pack is drawn (`[packs.render]`): each key given here overrides the scene's
    /// `[render]`. Default: nothing overridden.
    #[serde(default)]
    pub render: RenderOptions,
    /// Where this pack's fur physics runs (`physics_device = "cpu" | "gpu"`), overriding the
    /// scene's `[solver] device` for it. Default: the scene's.
    #[serde(default)]
    pub physics_device: Option<PhysicsDevice>,
}

/// How shells and fins are blended into what is behind them (`blend` of [`RenderOptions`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum ShellBlendMode {
    /// Alpha blending, no depth writes (soft; the renderer's default).
    AlphaBlend,
    /// Alpha test: fragments above the threshold are opaque and write depth (hard, order-free).
    AlphaTest,
}

/// The anisotropic filtering ratios the renderer accepts (`anisotropy` of [`RenderOptions`]).
pub const ANISOTROPY_RATIOS: [u16; 5] = [1, 2, 4, 8, 16];

/// Render settings a scene (`[render]`), a scene pack (`[packs.render]`) or a command's flags
/// (`furbake preview`, `furbake view`) choose; every key is optional and a key left out keeps
/// what the level below says (flags over the pack's keys, over the scene's, over the
/// renderer's defaults: `furbake_render::RenderSettings`, `BladeRenderSettings`, which document
/// each). Validated with the scene, naming the key.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct RenderOptions {
    /// Shell layers drawn, at most the atlas limit (1024); 0 draws the bare skin. Default: one per
    /// atlas slice.
    pub shell_layers: Option<u32>,
    /// Fins on the pack's fin edges (and, with `silhouette_fins`, on the silhouette).
    pub fins: Option<bool>,
    /// Fins on the interior edges on or near each frame's silhouette.
    pub silhouette_fins: Option<bool>,
    /// Half-width of the silhouette band in units of n·v, in [0, 1].
    pub silhouette_band: Option<f32>,
    /// `"alpha_blend"` or `"alpha_test"`.
    pub blend: Option<ShellBlendMode>,
    /// Shell and fin fragments with alpha at or below this are discarded, in [0, 1).
    pub alpha_threshold: Option<f32>,
    /// The fur's strand shading (off: Lambert × self-shadow); overrides `[packs.shading]
    /// enabled`.
    pub strand_shading: Option<bool>,
    /// The grass blades' shading (off: a flat colour with two-sided Lambert).
    pub blade_shading: Option<bool>,
    /// The shells' level of detail (fewer layers where the fur projects short; off: every view
    /// draws `shell_layers`).
    pub lod: Option<bool>,
    /// Anisotropic filtering of the blended shell and fin atlases, the most texels averaged
    /// along the pixel footprint's long axis: 1 (off), 2, 4, 8 or 16 (the default).
    pub anisotropy: Option<u16>,
}

impl RenderOptions {
    /// These options with every key they leave out taken from `below`.
    pub fn over(&self, below: &RenderOptions) -> RenderOptions {
        RenderOptions {
            shell_layers: self.shell_layers.or(below.shell_layers),
            fins: self.fins.or(below.fins),
            silhouette_fins: self.silhouette_fins.or(below.silhouette_fins),
            silhouette_band: self.silhouette_band.or(below.silhouette_band),
            blend: self.blend.or(below.blend),
            alpha_threshold: self.alpha_threshold.or(below.alpha_threshold),
            strand_shading: self.strand_shading.or(below.strand_shading),
            blade_shading: self.blade_shading.or(below.blade_shading),
            lod: self.lod.or(below.lod),
            anisotropy: self.anisotropy.or(below.anisotropy),
        }
    }

    /// Checks the ranges; the error names the key (`shell_layers`) and what is wrong.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let max = furbake_formats::sections::shell_atlas::MAX_LAYERS;
        if let Some(n) = self.shell_layers
            && n > max
        {
            return Err(("shell_layers".into(), format!("{n} is above the atlas layer limit of {max}")));
        }
        if let Some(b) = self.silhouette_band {
            range(b, 0.0, 1.0, "silhouette_band")?;
        }
        if let Some(t) = self.alpha_threshold
            && !(t.is_finite() && (0.0..1.0).contains(&t))
        {
            return Err(("alpha_threshold".into(), format!("{t} is not in [0, 1)")));
        }
        if let Some(a) = self.anisotropy
            && !ANISOTROPY_RATIOS.contains(&a)
        {
            return Err(("anisotropy".into(), format!("{a} is not one of 1, 2, 4, 8 or 16")));
        }
        Ok(())
    }
}

/// The fur's strand shading (docs/design.md "Fur shading"): each hair lit as a thin cylinder along
/// its sheared direction (Kajiya & Kay 1989; the fur thesis §2 names their model as the one shells
/// adapt, and §3.2 leaves the specular term out only for its cost), with two shifted highlights
/// (Scheuermann 2004: a light-coloured primary and a fur-coloured, noise-masked secondary, each
/// lobe energy-normalised as Unity HDRP's hair does), light transmitted through the hair tips when
/// it comes from behind, ambient occlusion by shell height and a root-to-tip colour gradient.
/// Used by `furbake-render` (`furbake_render::FurShading`, `RenderSettings::shading`), in a scene
/// per pack as `[packs.shading]`. The defaults are tuned on the bundled Fox and the generated
/// furry sphere. Colours are linear RGB multipliers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct FurShading {
    /// The strand model at all. Off: the fur is shaded as before it existed (vertex colour ×
    /// tint × Lambert × the bake's per-layer self-shadow, fur thesis §3.2), the parameters below
    /// unused. A pipeline switch, not a uniform. Default on.
    pub enabled: bool,
    /// How much of the diffuse term is Kajiya–Kay's `sin(T, L)` (gated by the body's own shadow,
    /// a slightly wrapped Lambert) rather than Lambert's `max(N·L, 0)`, in [0, 1]. Default 0.15.
    pub kajiya_kay_diffuse: f32,
    /// Strength of the primary (light-coloured) highlight, in [0, 16]. Default 0.03.
    pub primary_strength: f32,
    /// Its exponent (the narrower, the higher), in [1, 1024]. Default 80.
    pub primary_exponent: f32,
    /// Its shift along the strand's normal (Scheuermann's tangent shift, `tan` of the angle the
    /// highlight moves towards the root), in [-1, 1]. Default 0.1.
    pub primary_shift: f32,
    /// Strength of the secondary highlight (tinted by the fur colour and masked by noise), in
    /// [0, 16]. Default 0.25.
    pub secondary_strength: f32,
    /// Its exponent, in [1, 1024]. Default 10.
    pub secondary_exponent: f32,
    /// Its shift, in [-1, 1]; negative moves it towards the tips. Default -0.25.
    pub secondary_shift: f32,
    /// Colour multiplier of the secondary highlight on top of the fur colour, each channel in
    /// [0, 16]. Default `[1, 1, 1]`.
    pub secondary_tint: [f32; 3],
    /// How deeply the per-hair noise masks the secondary highlight, in [0, 1] (0: unmasked).
    /// Default 0.8.
    pub secondary_noise: f32,
    /// Strength of the light transmitted through the hairs when the light is behind the fur
    /// relative to the viewer, in [0, 16]. Default 2.
    pub back_light: f32,
    /// Ambient occlusion at the roots, fading linearly to none at the tips, in [0, 1] (applied
    /// to the ambient term only; the direct light has the bake's self-shadow table). Default
    /// 0.65: the roots keep 0.35 of the ambient light, the `fur` preset's `shadow_min`, so both
    /// lights darken alike towards the skin.
    pub root_occlusion: f32,
    /// Colour multiplier at the hair tips, blended linearly from none at the roots, each channel
    /// in [0, 4]. Default `[1.15, 1.08, 1.0]` (lighter, warmer tips).
    pub tip_color: [f32; 3],
}

impl Default for FurShading {
    fn default() -> Self {
        FurShading {
            enabled: true,
            kajiya_kay_diffuse: 0.15,
            primary_strength: 0.03,
            primary_exponent: 80.0,
            primary_shift: 0.1,
            secondary_strength: 0.25,
            secondary_exponent: 10.0,
            secondary_shift: -0.25,
            secondary_tint: [1.0, 1.0, 1.0],
            secondary_noise: 0.8,
            back_light: 2.0,
            root_occlusion: 0.65,
            tip_color: [1.15, 1.08, 1.0],
        }
    }
}

impl FurShading {
    /// The shading of fur before the strand model: Lambert and the self-shadow table only.
    pub fn off() -> Self {
        FurShading { enabled: false, ..FurShading::default() }
    }

    /// Checks every value's range; the error names the field (`primary_exponent`) and what is
    /// wrong with it.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let scalars = [
            ("kajiya_kay_diffuse", self.kajiya_kay_diffuse, 0.0, 1.0),
            ("primary_strength", self.primary_strength, 0.0, 16.0),
            ("primary_exponent", self.primary_exponent, 1.0, 1024.0),
            ("primary_shift", self.primary_shift, -1.0, 1.0),
            ("secondary_strength", self.secondary_strength, 0.0, 16.0),
            ("secondary_exponent", self.secondary_exponent, 1.0, 1024.0),
            ("secondary_shift", self.secondary_shift, -1.0, 1.0),
            ("secondary_noise", self.secondary_noise, 0.0, 1.0),
            ("back_light", self.back_light, 0.0, 16.0),
            ("root_occlusion", self.root_occlusion, 0.0, 1.0),
        ];
        for (field, x, lo, hi) in scalars {
            range(x, lo, hi, field)?;
        }
        for (field, color, hi) in [("secondary_tint", self.secondary_tint, 16.0), ("tip_color", self.tip_color, 4.0)] {
            for c in color {
                range(c, 0.0, hi, field)?;
            }
        }
        Ok(())
    }
}

/// What a pack's animation plays from time 0 (the fur thesis's future work, §3.4.1: the skin's
/// own motion drives the fur's anchored masses).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct PackAnimation {
    /// Name of a clip in the pack (`furbake inspect` lists them). Without one
    /// (`animation = {}`), the pack's skin stands in its rest pose until the host poses it with
    /// its own joint matrices (`Animator::set_joint_matrices`, through `World::animation_mut`):
    /// a character animated by the host's animation system, whose pack may have no clips at all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clip: Option<String>,
    /// Playback speed, in [-100, 100] (1 = real time; negative plays backwards). Default 1.
    #[serde(default = "one")]
    pub speed: f32,
    /// Whether the clip wraps around at its end (else it holds its last pose). Default true.
    #[serde(default = "yes", rename = "loop")]
    pub looping: bool,
    /// Clip time at scene time 0, seconds, ≥ 0. Default 0.
    #[serde(default)]
    pub start_s: f32,
    /// A skin point moving faster than this between two steps is a cut (a jump in the
    /// animation): the fur is carried along with the skin instead of being dragged, m/s, > 0.
    /// Default 50.
    #[serde(default = "default_cut_speed")]
    pub cut_speed_m_per_s: f32,
}

fn yes() -> bool {
    true
}

impl PackAnimation {
    /// `clip` played from its start at normal speed, looping (what `animation = { clip = "…" }`
    /// reads as).
    pub fn new(clip: impl Into<String>) -> PackAnimation {
        PackAnimation { clip: Some(clip.into()), ..PackAnimation::posed_by_host() }
    }

    /// No clip: the skin stands in its rest pose until the host poses it (what `animation = {}`
    /// reads as).
    pub fn posed_by_host() -> PackAnimation {
        PackAnimation { clip: None, speed: one(), looping: yes(), start_s: 0.0, cut_speed_m_per_s: default_cut_speed() }
    }
}

fn default_cut_speed() -> f32 {
    50.0
}

/// Translation, Euler rotation (XYZ, degrees) and uniform scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Translation in metres.
    pub translation: [f32; 3],
    /// Rotation about X, then Y, then Z, in degrees.
    pub rotation_deg: [f32; 3],
    /// Uniform scale, > 0.
    pub scale: f32,
}

fn one() -> f32 {
    1.0
}

impl Default for Transform {
    fn default() -> Self {
        Transform { translation: [0.0; 3], rotation_deg: [0.0; 3], scale: 1.0 }
    }
}

impl Transform {
    /// The model matrix (scale, then rotation, then translation).
    pub fn to_mat4(&self) -> Mat4 {
        let [x, y, z] = self.rotation_deg.map(f32::to_radians);
        Mat4::from_scale_rotation_translation(
            Vec3::splat(self.scale),
            Quat::from_euler(EulerRot::XYZ, x, y, z),
            Vec3::from(self.translation),
        )
    }
}

/// One keyframe of a pack's motion path; positions between keys are interpolated linearly.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct MotionKey {
    /// Time of the key in seconds, ≥ 0.
    pub time_s: f32,
    /// Translation at that time, in metres. Default zero.
    #[serde(default)]
    pub translation: [f32; 3],
    /// Rotation at that time (XYZ, degrees). Default zero.
    #[serde(default)]
    pub rotation_deg: [f32; 3],
    /// Uniform scale at that time, > 0. Default 1.
    #[serde(default = "one")]
    pub scale: f32,
}

impl MotionKey {
    /// The placement at this key.
    pub fn transform(&self) -> Transform {
        Transform { translation: self.translation, rotation_deg: self.rotation_deg, scale: self.scale }
    }
}

impl ScenePack {
    /// A pack named `name` read from `path`, placed at the origin, unscaled, unmoving, in its
    /// bind pose, shaded and drawn with the defaults (what a `[[packs]]` entry with only `name`
    /// and `path` reads as).
    pub fn new(name: impl Into<String>, path: impl Into<PathBuf>) -> ScenePack {
        ScenePack {
            name: name.into(),
            path: path.into(),
            translation: [0.0; 3],
            rotation_deg: [0.0; 3],
            scale: 1.0,
            motion: Vec::new(),
            animation: None,
            shading: FurShading::default(),
            render: RenderOptions::default(),
            physics_device: None,
        }
    }

    /// The placement (without the motion path).
    pub fn transform(&self) -> Transform {
        Transform { translation: self.translation, rotation_deg: self.rotation_deg, scale: self.scale }
    }

    /// The motion path at `time_s`: translation, rotation and scale interpolated linearly between
    /// the surrounding keys (Euler angles component-wise), clamped to the first and last key;
    /// the identity when the pack has no motion keys.
    pub fn motion_at(&self, time_s: f64) -> Transform {
        let keys = &self.motion;
        let (Some(first), Some(last)) = (keys.first(), keys.last()) else { return Transform::default() };
        if time_s <= first.time_s as f64 {
            return first.transform();
        }
        if time_s >= last.time_s as f64 {
            return last.transform();
        }
        // Keys are strictly increasing (validated), so exactly one interval holds `time_s`.
        let i = keys.partition_point(|k| (k.time_s as f64) <= time_s);
        let (a, b) = (&keys[i - 1], &keys[i]);
        let u = ((time_s - a.time_s as f64) / (b.time_s as f64 - a.time_s as f64)) as f32;
        let lerp3 = |x: [f32; 3], y: [f32; 3]| [0, 1, 2].map(|k| x[k] + (y[k] - x[k]) * u);
        Transform {
            translation: lerp3(a.translation, b.translation),
            rotation_deg: lerp3(a.rotation_deg, b.rotation_deg),
            scale: a.scale + (b.scale - a.scale) * u,
        }
    }

    /// The model matrix at `time_s`: the motion path applied on top of the placement.
    pub fn model_at(&self, time_s: f64) -> Mat4 {
        self.motion_at(time_s).to_mat4() * self.transform().to_mat4()
    }
}

/// The effects a scene declares. Every field defaults to "absent"; the runtime builds a stage
/// only for what is present.
#[derive(Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Effects {
    /// Constant acceleration on every mass.
    #[serde(default, deserialize_with = "table::optional")]
    pub gravity: Option<Gravity>,
    /// Global wind.
    #[serde(default, deserialize_with = "table::optional")]
    pub wind: Option<Wind>,
    /// Point wind sources (grass thesis eq. 4.1).
    #[serde(default)]
    pub wind_sources: Vec<WindSource>,
    /// Inertial forces from the packs' motion paths.
    #[serde(default, deserialize_with = "table::optional")]
    pub object_motion: Option<ObjectMotion>,
    /// A local force the user applies (e.g. a brush following the cursor).
    #[serde(default, deserialize_with = "table::optional")]
    pub interaction: Option<Interaction>,
    /// Colliders acting as local wind sources (grass thesis §5).
    #[serde(default)]
    pub collisions: Vec<Collider>,
    /// Boxes in which wind does not blow (grass thesis §5.1).
    #[serde(default)]
    pub windless_areas: Vec<WindlessArea>,
    /// Fur that can part: the runtime loads a separable topology.
    #[serde(default, deserialize_with = "table::optional")]
    pub parting: Option<Parting>,
    /// The wrong-side-scale guard (fur thesis §3.4.3).
    #[serde(default, deserialize_with = "table::optional")]
    pub wrong_side_guard: Option<WrongSideGuard>,
}

/// The effects are TOML tables (`[effects.gravity]` or `gravity = { … }`). serde's derived
/// structs also accept a sequence of their fields in order, so `gravity = [0.0, -9.81, 0.0]`
/// used to fail on its first number with "expected an array of length 3" — for an array of
/// length 3. These fields accept only a table, and anything else is answered with the form
/// to write (`tests/scene.rs` checks the messages).
/// A TOML or shape error as a scene's author reads it: the dotted key (`packs[0].scale`; none for
/// a TOML syntax error or an unknown top-level key), serde's message with Rust's type names in
/// words (`expected f32` → `expected a number`), and the line and column.
fn parse_message(text: &str, e: &toml::de::Error, key: &str) -> String {
    furbake_formats::input::located_message(text, key, e.message(), e.span())
}

mod table {
    use std::fmt;
    use std::marker::PhantomData;

    use serde::de::{Deserialize, Deserializer, MapAccess, Visitor, value::MapAccessDeserializer};

    /// An effect's table written inline, quoted in the error for any other value.
    pub(super) trait Example {
        const EXAMPLE: &'static str;
    }

    pub(super) fn optional<'de, D, T>(deserializer: D) -> Result<Option<T>, D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de> + Example,
    {
        struct TableOnly<T>(PhantomData<T>);
        impl<'de, T: Deserialize<'de> + Example> Visitor<'de> for TableOnly<T> {
            type Value = T;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "a table, e.g. `{}`", T::EXAMPLE)
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<T, A::Error> {
                T::deserialize(MapAccessDeserializer::new(map))
            }
        }
        deserializer.deserialize_map(TableOnly(PhantomData)).map(Some)
    }
}

impl table::Example for Gravity {
    const EXAMPLE: &'static str = "gravity = { acceleration_m_per_s2 = [0.0, -9.81, 0.0] }";
}

impl table::Example for Wind {
    const EXAMPLE: &'static str = "wind = { velocity_m_per_s = [2.0, 0.0, 0.0], gust_amplitude = 0.3 }";
}

impl table::Example for ObjectMotion {
    const EXAMPLE: &'static str = "object_motion = { inertia_scale = 1.0 }";
}

impl table::Example for Interaction {
    const EXAMPLE: &'static str = "interaction = { position = [0.0, 0.3, 0.0], radius_m = 0.3, strength_n = 2.0 }";
}

impl table::Example for Parting {
    const EXAMPLE: &'static str = "parting = {}";
}

impl table::Example for WrongSideGuard {
    const EXAMPLE: &'static str = "wrong_side_guard = { max_angle_deg = 75.0 }";
}

impl Clone for Effects {
    fn clone(&self) -> Self {
        let mut out = Effects::default();
        out.clone_from(self);
        out
    }

    /// Field by field, the lists through `Vec::clone_from`, so copying effects into effects of
    /// the same sizes allocates nothing (`World::update_effects` does it every frame).
    fn clone_from(&mut self, source: &Self) {
        let Effects {
            gravity,
            wind,
            wind_sources,
            object_motion,
            interaction,
            collisions,
            windless_areas,
            parting,
            wrong_side_guard,
        } = source;
        self.gravity = *gravity;
        self.wind = *wind;
        self.wind_sources.clone_from(wind_sources);
        self.object_motion = *object_motion;
        self.interaction = *interaction;
        self.collisions.clone_from(collisions);
        self.windless_areas.clone_from(windless_areas);
        self.parting = *parting;
        self.wrong_side_guard = *wrong_side_guard;
    }
}

/// Gravity.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// Acceleration in m/s². Default `[0, -9.81, 0]`.
    #[serde(default = "default_gravity")]
    pub acceleration_m_per_s2: [f32; 3],
}

fn default_gravity() -> [f32; 3] {
    [0.0, -9.81, 0.0]
}

impl Default for Gravity {
    /// Earth's gravity along −Y (what `[effects.gravity]` with no keys reads as).
    fn default() -> Self {
        Gravity { acceleration_m_per_s2: default_gravity() }
    }
}

/// Global wind: a constant velocity plus an optional sinusoidal gust.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Wind {
    /// Wind velocity in m/s.
    pub velocity_m_per_s: [f32; 3],
    /// Relative gust amplitude in [0, 1]. Default 0.
    #[serde(default)]
    pub gust_amplitude: f32,
    /// Gust frequency in Hz, ≥ 0. Default 0.5.
    #[serde(default = "default_gust_hz")]
    pub gust_frequency_hz: f32,
}

fn default_gust_hz() -> f32 {
    0.5
}

/// A point wind source, `w = normalize(WP)·ω/|WP|^σ` (grass thesis eq. 4.1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct WindSource {
    /// Position W in metres.
    pub position: [f32; 3],
    /// Emissive power ω, ≥ 0.
    pub power: f32,
    /// Concentration σ, ≥ 0 (higher spreads the wind more locally). Default 2.
    #[serde(default = "default_sigma")]
    pub falloff_exponent: f32,
    /// Delayed attenuation (grass thesis §4.2, fig. 4.8): the source's wind reaches each blade
    /// with the source's exact per-blade strength and a direction blended from the cluster's
    /// corners, instead of the bilinear blend of the corner forces (which smears a near source
    /// over a whole cluster). Evaluated per blade — on the GPU when rendering. Default false.
    #[serde(default)]
    pub delayed_attenuation: bool,
}

fn default_sigma() -> f32 {
    2.0
}

/// Inertial forces from object motion.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ObjectMotion {
    /// Scale of the inertial force, ≥ 0. Default 1.
    #[serde(default = "one")]
    pub inertia_scale: f32,
}

/// A spherical force brush controlled by the user: it pushes fur masses within `radius_m` of its
/// position away from it with `strength_n · (1 − d/radius)²`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Interaction {
    /// Where the brush starts, world metres; `None` = inactive until the application moves it
    /// (`World::set_interaction_point`). Default `None`.
    #[serde(default)]
    pub position: Option<[f32; 3]>,
    /// Radius of influence in metres, > 0.
    pub radius_m: f32,
    /// Peak force in newtons, ≥ 0.
    pub strength_n: f32,
}

/// A collider acting as a local wind source.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum Collider {
    /// A sphere.
    Sphere {
        /// Centre in metres.
        center: [f32; 3],
        /// Radius in metres, > 0.
        radius_m: f32,
    },
    /// An axis-aligned ellipsoid.
    Ellipsoid {
        /// Centre in metres.
        center: [f32; 3],
        /// Semi-axes in metres, each > 0.
        radii_m: [f32; 3],
    },
}

/// An axis-aligned box in which wind forces are removed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct WindlessArea {
    /// Minimum corner in metres.
    pub min: [f32; 3],
    /// Maximum corner in metres, ≥ `min` on every axis.
    pub max: [f32; 3],
}

/// Fur parting: use a separable topology so triangles can move apart.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Parting {}

/// The wrong-side guard: restoring force `F = (n − s)(1 − n·s)·w` (eq. 3.37) and the threshold
/// test `n·s < cos α` with impulse and frozen scale vector.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct WrongSideGuard {
    /// Weight `w` of the restoring force on each tip mass, in the topology's force units (newtons
    /// when the mesh is in metres), ≥ 0. Default 0.01 (furbake-sim's default). Without the guard
    /// the restoring force keeps that default: it is part of the fur model.
    #[serde(default = "default_restoring_weight")]
    pub restoring_weight_n: f32,
    /// Threshold angle α between normal and scale vector in degrees, in (0, 90). Default 80.
    #[serde(default = "default_alpha")]
    pub max_angle_deg: f32,
    /// Speed added along the normal to a tip when the test fires, in the mesh's units per second,
    /// ≥ 0. Default 0.05.
    #[serde(default = "default_impulse")]
    pub impulse_m_per_s: f32,
}

fn default_restoring_weight() -> f32 {
    0.01
}

fn default_impulse() -> f32 {
    0.05
}

fn default_alpha() -> f32 {
    80.0
}

/// One effect kind, for planning stages and for stage counters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// [`Effects::gravity`].
    Gravity,
    /// [`Effects::wind`].
    Wind,
    /// [`Effects::wind_sources`].
    WindSources,
    /// [`Effects::object_motion`].
    ObjectMotion,
    /// [`Effects::interaction`].
    Interaction,
    /// [`Effects::collisions`].
    Collisions,
    /// [`Effects::windless_areas`].
    WindlessAreas,
    /// [`Effects::parting`].
    Parting,
    /// [`Effects::wrong_side_guard`].
    WrongSideGuard,
}

impl Effects {
    /// Every effect with whether it is declared, in a fixed order (allocates nothing).
    pub fn declared(&self) -> [(bool, Effect); 9] {
        [
            (self.gravity.is_some(), Effect::Gravity),
            (self.wind.is_some(), Effect::Wind),
            (!self.wind_sources.is_empty(), Effect::WindSources),
            (self.object_motion.is_some(), Effect::ObjectMotion),
            (self.interaction.is_some(), Effect::Interaction),
            (!self.collisions.is_empty(), Effect::Collisions),
            (!self.windless_areas.is_empty(), Effect::WindlessAreas),
            (self.parting.is_some(), Effect::Parting),
            (self.wrong_side_guard.is_some(), Effect::WrongSideGuard),
        ]
    }

    /// The declared effects, in a fixed order.
    pub fn enabled(&self) -> Vec<Effect> {
        self.declared().into_iter().filter(|(on, _)| *on).map(|(_, e)| e).collect()
    }

    /// True when `effect` is declared.
    pub fn has(&self, effect: Effect) -> bool {
        self.declared().iter().any(|&(on, e)| on && e == effect)
    }
}

impl Effect {
    /// The effects that are forces (what `forces_off` / `forces_on` events switch).
    pub const FORCES: [Effect; 6] = [
        Effect::Gravity,
        Effect::Wind,
        Effect::WindSources,
        Effect::ObjectMotion,
        Effect::Interaction,
        Effect::Collisions,
    ];

    /// True for the effects in [`Effect::FORCES`].
    pub fn is_force(self) -> bool {
        Effect::FORCES.contains(&self)
    }
}

/// Builds a [`Scene`] in code: every value starts at its default (what a scene file that lists
/// only its packs reads as) and [`SceneBuilder::build`] validates the whole scene as
/// [`Scene::from_toml_str`] does. Pack paths are used as given.
#[derive(Clone, Debug)]
#[must_use = "a builder does nothing until `build` is called"]
pub struct SceneBuilder {
    scene: Scene,
}

/// The name errors of a scene built in code carry in place of a file.
const BUILT_SCENE: &str = "<scene built in code>";

impl SceneBuilder {
    /// Simulation time step in seconds, in (0, 1]. Default 1/60.
    pub fn time_step_s(mut self, seconds: f32) -> Self {
        self.scene.time_step_s = seconds;
        self
    }
    /// The fur solver. Default [`Solver::default`].
    pub fn solver(mut self, solver: Solver) -> Self {
        self.scene.solver = solver;
        self
    }
    /// How long `furbake simulate` runs the scene, seconds, or `None` (2 s).
    pub fn duration_s(mut self, seconds: Option<f64>) -> Self {
        self.scene.duration_s = seconds;
        self
    }
    /// The viewpoint, or `None` to frame the packs automatically.
    pub fn camera(mut self, camera: Option<Camera>) -> Self {
        self.scene.camera = camera;
        self
    }
    /// One directional light with an ambient share (replaces `lights` and `ambient`).
    pub fn light(mut self, light: Light) -> Self {
        self.scene.light = Some(light);
        self.scene.lights.clear();
        self.scene.ambient = None;
        self
    }
    /// Up to [`MAX_LIGHTS`] light sources and the hemisphere ambient (replaces `light`).
    pub fn lights(mut self, sources: Vec<LightSource>, ambient: Ambient) -> Self {
        self.scene.light = None;
        self.scene.lights = sources;
        self.scene.ambient = Some(ambient);
        self
    }
    /// Adds a pack (names must stay unique).
    pub fn pack(mut self, pack: ScenePack) -> Self {
        self.scene.packs.push(pack);
        self
    }
    /// Changes the pack named `name` (nothing when there is none; `build` still validates it).
    pub fn edit_pack(mut self, name: &str, edit: impl FnOnce(&mut ScenePack)) -> Self {
        if let Some(p) = self.scene.packs.iter_mut().find(|p| p.name == name) {
            edit(p);
        }
        self
    }
    /// The effects the scene asks for.
    pub fn effects(mut self, effects: Effects) -> Self {
        self.scene.effects = effects;
        self
    }
    /// Timed events, applied in time order (file order among equal times).
    pub fn events(mut self, events: Vec<Event>) -> Self {
        self.scene.events = events;
        self
    }
    /// How every pack is drawn unless a pack says otherwise.
    pub fn render(mut self, render: RenderOptions) -> Self {
        self.scene.render = render;
        self
    }
    /// How grass blades are culled and simplified with distance.
    pub fn grass_culling(mut self, culling: GrassCulling) -> Self {
        self.scene.grass_culling = culling;
        self
    }
    /// A builder holding the values of scene TOML, which may leave `[[packs]]` out for the host
    /// to add ([`SceneBuilder::pack`]); `name` labels errors. The text's keys are read (parse
    /// errors name the key, as [`Scene::from_toml_str`]'s do); [`SceneBuilder::build`] validates
    /// the values. Pack paths stay as written.
    pub fn from_toml_str(text: &str, name: &Path) -> Result<SceneBuilder, SceneError> {
        let without_packs = toml::from_str::<toml::Table>(text).is_ok_and(|t| !t.contains_key("packs"));
        if !without_packs {
            return Ok(SceneBuilder { scene: Scene::parse(text, name)? });
        }
        // `packs` is a required key of a scene file; a placeholder entry appended after the
        // text (a table header may follow anything) keeps every line and column of the text's
        // own errors where they are, and is dropped again.
        let mut scene = Scene::parse(&format!("{text}\n[[packs]]\nname = \"\"\npath = \"\"\n"), name)?;
        scene.packs.clear();
        Ok(SceneBuilder { scene })
    }

    /// The packs added so far.
    pub fn packs(&self) -> &[ScenePack] {
        &self.scene.packs
    }

    /// Validates the scene: the first value out of range is a [`SceneError::Invalid`] naming its
    /// dotted key.
    pub fn build(self) -> Result<Scene, SceneError> {
        self.scene.validate().map_err(|(field, what)| SceneError::Invalid { path: BUILT_SCENE.into(), field, what })?;
        Ok(self.scene)
    }
}

impl Scene {
    /// A builder for a scene of `packs` with every other value at its default.
    pub fn builder(packs: Vec<ScenePack>) -> SceneBuilder {
        SceneBuilder {
            scene: Scene {
                time_step_s: default_time_step(),
                solver: Solver::default(),
                duration_s: None,
                camera: None,
                light: None,
                lights: Vec::new(),
                ambient: None,
                packs,
                effects: Effects::default(),
                events: Vec::new(),
                render: RenderOptions::default(),
                grass_culling: GrassCulling::default(),
            },
        }
    }

    /// A builder holding this scene's values, to change some and validate again.
    pub fn into_builder(self) -> SceneBuilder {
        SceneBuilder { scene: self }
    }

    /// Simulation time step, seconds.
    pub fn time_step_s(&self) -> f32 {
        self.time_step_s
    }
    /// The fur solver.
    pub fn solver(&self) -> Solver {
        self.solver
    }
    /// How long `furbake simulate` runs the scene when no `--frames` is given (`None`: 2 s).
    pub fn duration_s(&self) -> Option<f64> {
        self.duration_s
    }
    /// The viewpoint (`None`: framed from the packs' bounds).
    pub fn camera(&self) -> Option<Camera> {
        self.camera
    }
    /// The packs, in file order.
    pub fn packs(&self) -> &[ScenePack] {
        &self.packs
    }
    /// The effects the scene asks for ([`Effects::enabled`] lists them).
    pub fn effects(&self) -> &Effects {
        &self.effects
    }
    /// The timed events, in file order.
    pub fn events(&self) -> &[Event] {
        &self.events
    }
    /// How every pack is drawn unless its own `render` says otherwise.
    pub fn render(&self) -> &RenderOptions {
        &self.render
    }
    /// How grass blades are culled and simplified with distance.
    pub fn grass_culling(&self) -> GrassCulling {
        self.grass_culling
    }
}

impl Scene {
    /// The JSON Schema (draft 2020-12) of scene files: every key, its type, range notes and
    /// default from these types' documentation, for editors that validate and complete TOML
    /// (taplo, Even Better TOML) and for `furbake schema scene`. Feature `schema`.
    #[cfg(feature = "schema")]
    pub fn json_schema() -> schemars::Schema {
        furbake_formats::schema::toml_file_schema::<Scene>(
            "furbake scene",
            "A furbake runtime scene (TOML): the packs to place, the camera and lights, the solver, the effects \
             the scene calls for and timed events (README \"Scenes\"; `furbake schema scene` prints this schema).",
            false,
        )
    }

    /// Reads, parses and validates the scene file at `path`; relative pack paths are resolved
    /// against its directory. Only a regular file of at most
    /// [`furbake_formats::input::MAX_TEXT_BYTES`] is read, never blocking on a FIFO.
    pub fn load(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
        let path = path.as_ref();
        let text = furbake_formats::input::read_text(path, "a scene")
            .map_err(|source| SceneError::Io { path: path.into(), source })?;
        let base = path.parent().unwrap_or(Path::new(""));
        Scene::from_toml_str(&text, path, base)
    }

    /// Parses and validates scene TOML. `name` labels errors; `base_dir` resolves relative pack
    /// paths.
    pub fn from_toml_str(text: &str, name: &Path, base_dir: &Path) -> Result<Scene, SceneError> {
        let mut scene = Scene::parse(text, name)?;
        scene.validate().map_err(|(field, what)| SceneError::Invalid { path: name.into(), field, what })?;
        for p in &mut scene.packs {
            if p.path.is_relative() {
                p.path = base_dir.join(&p.path);
            }
        }
        Ok(scene)
    }

    /// Reads scene TOML into a scene not yet validated (the key-naming parse errors of
    /// [`Scene::from_toml_str`]; pack paths as written).
    fn parse(text: &str, name: &Path) -> Result<Scene, SceneError> {
        if let Ok(table) = toml::from_str::<toml::Table>(text) {
            check_outdated(&table).map_err(|(field, what)| SceneError::Outdated { path: name.into(), field, what })?;
        }
        let parse = |e: toml::de::Error, key: &str| SceneError::Parse {
            path: name.into(),
            message: parse_message(text, &e, key),
        };
        let de = toml::Deserializer::parse(text).map_err(|e| parse(e, ""))?;
        serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            parse(e.into_inner(), &key)
        })
    }

    /// What the scene is lit by: its `[[lights]]` and `[ambient]`, or its `[light]` shorthand,
    /// or, with neither, [`Lighting::default`] (the studio lights, not [`Light::default`]).
    pub fn lighting(&self) -> Lighting {
        match self.light {
            Some(light) => Lighting::from(light),
            None if self.lights.is_empty() && self.ambient.is_none() => Lighting::default(),
            None => {
                Lighting::new(&self.lights, self.ambient.unwrap_or_default()).expect("validated: at most MAX_LIGHTS")
            }
        }
    }

    /// The checks of the effects' values (part of validating a scene; also what
    /// `World::update_effects` runs on a host's edit).
    pub(crate) fn check_effects(&self) -> Result<(), (String, String)> {
        let e = &self.effects;
        if let Some(g) = &e.gravity {
            finite3(&g.acceleration_m_per_s2, "effects.gravity.acceleration_m_per_s2")?;
        }
        if let Some(w) = &e.wind {
            finite3(&w.velocity_m_per_s, "effects.wind.velocity_m_per_s")?;
            range(w.gust_amplitude, 0.0, 1.0, "effects.wind.gust_amplitude")?;
            range(w.gust_frequency_hz, 0.0, 1000.0, "effects.wind.gust_frequency_hz")?;
        }
        for (i, s) in e.wind_sources.iter().enumerate() {
            let f = |k: &str| format!("effects.wind_sources[{i}].{k}");
            finite3(&s.position, "").map_err(|(_, w)| (f("position"), w))?;
            range(s.power, 0.0, f32::MAX, "").map_err(|(_, w)| (f("power"), w))?;
            range(s.falloff_exponent, 0.0, 16.0, "").map_err(|(_, w)| (f("falloff_exponent"), w))?;
        }
        if let Some(m) = &e.object_motion {
            range(m.inertia_scale, 0.0, f32::MAX, "effects.object_motion.inertia_scale")?;
        }
        if let Some(it) = &e.interaction {
            if let Some(p) = &it.position {
                finite3(p, "effects.interaction.position")?;
            }
            positive(it.radius_m, "effects.interaction.radius_m")?;
            range(it.strength_n, 0.0, f32::MAX, "effects.interaction.strength_n")?;
        }
        for (i, c) in e.collisions.iter().enumerate() {
            let f = |k: &str| format!("effects.collisions[{i}].{k}");
            match c {
                Collider::Sphere { center, radius_m } => {
                    finite3(center, "").map_err(|(_, w)| (f("center"), w))?;
                    positive(*radius_m, "").map_err(|(_, w)| (f("radius_m"), w))?;
                }
                Collider::Ellipsoid { center, radii_m } => {
                    finite3(center, "").map_err(|(_, w)| (f("center"), w))?;
                    for &r in radii_m {
                        positive(r, "").map_err(|(_, w)| (f("radii_m"), w))?;
                    }
                }
            }
        }
        for (i, a) in e.windless_areas.iter().enumerate() {
            let f = |k: &str| format!("effects.windless_areas[{i}].{k}");
            finite3(&a.min, "").map_err(|(_, w)| (f("min"), w))?;
            finite3(&a.max, "").map_err(|(_, w)| (f("max"), w))?;
            if (0..3).any(|k| a.max[k] < a.min[k]) {
                return Err((f("max"), "must be ≥ min on every axis".into()));
            }
        }
        if let Some(g) = &e.wrong_side_guard {
            range(g.restoring_weight_n, 0.0, f32::MAX, "effects.wrong_side_guard.restoring_weight_n")?;
            range(g.max_angle_deg, 1e-3, 89.9, "effects.wrong_side_guard.max_angle_deg")?;
            range(g.impulse_m_per_s, 0.0, f32::MAX, "effects.wrong_side_guard.impulse_m_per_s")?;
        }
        Ok(())
    }

    fn validate(&self) -> Result<(), (String, String)> {
        let bad = |field: &str, what: &str| Err((field.to_owned(), what.to_owned()));
        if !(self.time_step_s.is_finite() && self.time_step_s > 0.0 && self.time_step_s <= 1.0) {
            return bad("time_step_s", "must be in (0, 1] seconds");
        }
        if let Some(c) = &self.camera {
            finite3(&c.eye, "camera.eye")?;
            finite3(&c.target, "camera.target")?;
            nonzero3(&c.up, "camera.up")?;
            if Vec3::from(c.eye).distance(Vec3::from(c.target)) <= 0.0 {
                return bad("camera.target", "must differ from camera.eye");
            }
            if Vec3::from(c.up).cross(Vec3::from(c.target) - Vec3::from(c.eye)).length_squared() <= 0.0 {
                return bad("camera.up", "must not be parallel to the viewing direction");
            }
            range(c.fov_y_deg, 1.0, 179.0, "camera.fov_y_deg")?;
        }
        if let Some(light) = &self.light {
            nonzero3(&light.direction, "light.direction")?;
            finite3(&light.color, "light.color")?;
            if light.color.iter().any(|&c| c < 0.0) {
                return bad("light.color", "must not be negative");
            }
            range(light.ambient, 0.0, 1.0, "light.ambient")?;
            if !self.lights.is_empty() || self.ambient.is_some() {
                return bad(
                    "light",
                    "give either [light] (one light with an ambient share) or [[lights]] and [ambient], not both",
                );
            }
        }
        self.render.validate().map_err(|(k, what)| (format!("render.{k}"), what))?;
        if self.lights.len() > MAX_LIGHTS {
            return Err((
                "lights".into(),
                format!("{} lights; at most {MAX_LIGHTS} light one frame", self.lights.len()),
            ));
        }
        for (i, light) in self.lights.iter().enumerate() {
            light.validate(&format!("lights[{i}]"))?;
        }
        if let Some(ambient) = &self.ambient {
            for (rgb, field) in [(&ambient.sky, "ambient.sky"), (&ambient.ground, "ambient.ground")] {
                finite3(rgb, field)?;
                if rgb.iter().any(|&c| c < 0.0) {
                    return bad(field, "must not be negative");
                }
            }
        }
        range(self.solver.implicit_iterations as f32, 1.0, 1000.0, "solver.implicit_iterations")?;
        range(self.solver.xpbd_iterations as f32, 1.0, 1000.0, "solver.xpbd_iterations")?;
        range(self.solver.local_global_iterations as f32, 1.0, 1000.0, "solver.local_global_iterations")?;
        if let Some(d) = self.duration_s {
            if !(d.is_finite() && d > 0.0 && d <= MAX_DURATION_S) {
                return Err(("duration_s".into(), format!("{d} is not in (0, {MAX_DURATION_S}] seconds")));
            }
        }
        if self.packs.is_empty() {
            return bad("packs", "a scene needs at least one [[packs]] entry");
        }
        for (i, p) in self.packs.iter().enumerate() {
            let f = |k: &str| format!("packs[{i}].{k}");
            if p.name.is_empty() {
                return Err((f("name"), "must not be empty".into()));
            }
            if self.packs[..i].iter().any(|q| q.name == p.name) {
                return Err((f("name"), format!("\"{}\" is used twice", p.name)));
            }
            check_transform(&p.transform(), &f(""))?;
            let mut last = -1.0f32;
            for (k, key) in p.motion.iter().enumerate() {
                let g = format!("packs[{i}].motion[{k}]");
                if !(key.time_s.is_finite() && key.time_s >= 0.0 && key.time_s > last) {
                    return Err((format!("{g}.time_s"), "times must be ≥ 0 and strictly increasing".into()));
                }
                last = key.time_s;
                check_transform(&key.transform(), &format!("{g}."))?;
            }
            if let Some(a) = &p.animation {
                let g = |k: &str| format!("packs[{i}].animation.{k}");
                if a.clip.as_deref().is_some_and(str::is_empty) {
                    return Err((g("clip"), "must name a clip (leave it out for a skin the host poses)".into()));
                }
                range(a.speed, -100.0, 100.0, &g("speed"))?;
                range(a.start_s, 0.0, 1e6, &g("start_s"))?;
                range(a.cut_speed_m_per_s, 1e-3, 1e9, &g("cut_speed_m_per_s"))?;
            }
            p.shading.validate().map_err(|(k, what)| (format!("packs[{i}].shading.{k}"), what))?;
            p.render.validate().map_err(|(k, what)| (format!("packs[{i}].render.{k}"), what))?;
        }
        self.check_effects()?;
        self.grass_culling.validate()?;
        let e = &self.effects;
        for (i, event) in self.events.iter().enumerate() {
            let f = |k: &str| format!("events[{i}].{k}");
            let at = event.at_s();
            if !(at.is_finite() && (0.0..=MAX_DURATION_S).contains(&at)) {
                return Err((f("at_s"), format!("{at} is not in [0, {MAX_DURATION_S}] seconds")));
            }
            match event {
                Event::Teleport { pack, offset_m, .. } => {
                    if !self.packs.iter().any(|p| &p.name == pack) {
                        return Err((f("pack"), format!("no pack is named \"{pack}\"")));
                    }
                    finite3(offset_m, &f("offset_m"))?;
                }
                Event::PlayClip { pack, clip, fade_s, .. } => {
                    if !self.packs.iter().any(|p| &p.name == pack) {
                        return Err((f("pack"), format!("no pack is named \"{pack}\"")));
                    }
                    if clip.is_empty() {
                        return Err((f("clip"), "must name a clip".into()));
                    }
                    if self.packs.iter().any(|p| &p.name == pack && p.animation.is_none()) {
                        return Err((
                            f("pack"),
                            format!("pack \"{pack}\" has no `animation = {{ clip = ... }}` to switch from"),
                        ));
                    }
                    range(*fade_s, 0.0, 60.0, &f("fade_s"))?;
                }
                Event::ForcesOff { effects, .. } | Event::ForcesOn { effects, .. } => {
                    for effect in effects {
                        if !effect.is_force() {
                            return Err((f("effects"), format!("{effect:?} is not a force effect")));
                        }
                        if !e.has(*effect) {
                            return Err((f("effects"), format!("{effect:?} is not declared under [effects]")));
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// Longest scene duration and latest event time, seconds (a day of scene time).
const MAX_DURATION_S: f64 = 86_400.0;

/// Retired keys, by the table they sit in, and what to write instead.
const RETIRED_KEYS: [(&str, &str, &str); 7] = [
    ("", "dt_s", "renamed to `time_step_s`"),
    ("", "forces_stop_s", "write an event: `[[events]] kind = \"forces_off\"` with `at_s`"),
    ("", "teleports", "write events: `[[events]] kind = \"teleport\"` with `at_s`, `pack` and `offset_m`"),
    ("effects.gravity", "acceleration_m_s2", "renamed to `acceleration_m_per_s2`"),
    ("effects.wind", "velocity_m_s", "renamed to `velocity_m_per_s`"),
    ("effects.wind_sources", "propagation_m_s", "delayed attenuation is a switch: write `delayed_attenuation = true`"),
    ("effects.wrong_side_guard", "impulse_m_s", "renamed to `impulse_m_per_s`"),
];

/// Finds a retired key (see [`RETIRED_KEYS`]) or a whole furbake-sim scene (`dt_s`, `[forces]`,
/// no `[[packs]]`) before the scene is deserialised, so the error names what to write instead.
fn check_outdated(table: &toml::Table) -> Result<(), (String, String)> {
    const SIM_KEYS: [&str; 6] = ["dt_s", "forces", "forces_stop_s", "teleports", "motion", "record_every"];
    if !table.contains_key("packs") {
        if let Some(key) = SIM_KEYS.iter().find(|k| table.contains_key(**k)) {
            return Err((
                (*key).to_owned(),
                "this is a furbake-sim scene, which furbake no longer reads; write a runtime scene: \
                 `time_step_s`, `duration_s`, `[[packs]]` (name, path), `[effects.gravity]`, \
                 `[effects.wind] velocity_m_per_s`, `[[events]]` (teleport, forces_off) — see README \"Scenes\""
                    .to_owned(),
            ));
        }
    }
    for (parent, key, what) in RETIRED_KEYS {
        let mut tables: Vec<(String, &toml::Table)> = vec![(String::new(), table)];
        for part in parent.split('.').filter(|p| !p.is_empty()) {
            let mut next = Vec::new();
            for (path, t) in &tables {
                let path = if path.is_empty() { part.to_owned() } else { format!("{path}.{part}") };
                match t.get(part) {
                    Some(toml::Value::Table(inner)) => next.push((path, inner)),
                    Some(toml::Value::Array(items)) => next.extend(
                        items
                            .iter()
                            .enumerate()
                            .filter_map(|(i, v)| v.as_table().map(|inner| (format!("{path}[{i}]"), inner))),
                    ),
                    _ => {}
                }
            }
            tables = next;
        }
        if let Some((path, _)) = tables.iter().find(|(_, t)| t.contains_key(key)) {
            let field = if path.is_empty() { key.to_owned() } else { format!("{path}.{key}") };
            return Err((field, what.to_owned()));
        }
    }
    Ok(())
}

fn finite3(v: &[f32; 3], field: &str) -> Result<(), (String, String)> {
    if v.iter().all(|x| x.is_finite()) { Ok(()) } else { Err((field.into(), "must be finite".into())) }
}

fn nonzero3(v: &[f32; 3], field: &str) -> Result<(), (String, String)> {
    finite3(v, field)?;
    if Vec3::from(*v).length_squared() > 0.0 { Ok(()) } else { Err((field.into(), "must not be zero".into())) }
}

fn range(x: f32, lo: f32, hi: f32, field: &str) -> Result<(), (String, String)> {
    if x.is_finite() && x >= lo && x <= hi {
        Ok(())
    } else {
        Err((field.into(), format!("{x} is not in [{lo}, {hi}]")))
    }
}

fn positive(x: f32, field: &str) -> Result<(), (String, String)> {
    if x.is_finite() && x > 0.0 { Ok(()) } else { Err((field.into(), format!("{x} must be positive"))) }
}

fn check_transform(t: &Transform, prefix: &str) -> Result<(), (String, String)> {
    finite3(&t.translation, &format!("{prefix}translation"))?;
    finite3(&t.rotation_deg, &format!("{prefix}rotation_deg"))?;
    positive(t.scale, &format!("{prefix}scale"))
}
