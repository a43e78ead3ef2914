//! The hair volume stage: grows a tileable volume of hairs and slices it into the shell atlas and
//! the fin atlas (fur thesis §3.1, eq. 3.1–3.2, fig. 3.2–3.8), with the per-layer self-shadow table
//! of §3.2 ("darkened the closer they are to the skin", after Banks \[5\]).
//!
//! The stage reads as four verbs, which [`bake_volume`] runs in order:
//! 1. [`validate_volume_params`]: every bound checked once; later steps trust the parameters.
//! 2. [`grow_hairs`]: distributes hair roots over the `res × res` base of the volume (coat, then the
//!    optional undercoat of fig. 3.8) and draws each hair's random shape: bend weight `w1`, one of
//!    four growth directions, length `l ∈ [lmin, lmax]`.
//! 3. [`slice_shell_atlas`]: one anti-aliased alpha slice per shell layer, plus the shadow table and
//!    the per-layer coverage.
//! 4. [`compose_fin_atlas`]: K vertical slices composited "over" onto one fin texture (fig. 3.7).
//!
//! The volume is never stored as voxels: hairs are curves (eq. 3.2) evaluated analytically at the
//! height each output row needs, so the fin texture can be taller than the layer count.
//!
//! Coordinates: texel `(x, y)` covers `[x, x+1) × [y, y+1)`, its centre is `(x + 0.5, y + 0.5)`;
//! heights `h` are fractions of the volume height (0 = skin, 1 = outermost shell). All distances
//! wrap around the texture border (a torus), so the textures tile without a seam.
//!
//! Determinism: randomness comes from [`crate::rng`] streams keyed by (seed, coat, texel), so the
//! hairs do not depend on iteration order; slicing is parallel over layers / fin rows, each written
//! by exactly one task with a fixed operation order, so the bytes are identical for any thread count.

use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::shell_atlas::{HairCoat, MAX_LAYERS, MAX_RESOLUTION, ShellAtlas, VolumeParams};
use glam::Vec2;
use rayon::prelude::*;

use crate::rng::{SplitMix64, derive_seed};

/// Smallest shell resolution accepted (texels per side).
pub const MIN_RESOLUTION: u32 = 4;
/// Largest volume accepted, in voxels (`layers × resolution²`): 2^28, i.e. 256 MiB of alpha.
pub const MAX_VOXELS: u64 = 1 << 28;
/// Most vertical slices composed onto a fin texture (the thesis uses 20).
pub const MAX_FIN_SLICES: u32 = 1024;

/// Errors of the volume stage, split by blame: a bad parameter (the caller's) or a size limit.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VolumeError {
    /// A parameter is out of its allowed range or not finite.
    #[error("volume parameter `{field}` = {value} is out of range (allowed: {allowed})")]
    Parameter {
        /// Dotted field path, e.g. `undercoat.length_min`.
        field: String,
        /// The offending value as given.
        value: String,
        /// The allowed range, e.g. `(0, 1]`.
        allowed: String,
    },
    /// The volume would be larger than [`MAX_VOXELS`].
    #[error("volume of {layers} layers × {resolution}² texels = {voxels} voxels exceeds the limit of {limit}")]
    TooManyVoxels {
        /// Requested layers.
        layers: u32,
        /// Requested resolution.
        resolution: u32,
        /// `layers × resolution²`.
        voxels: u64,
        /// [`MAX_VOXELS`].
        limit: u64,
    },
}

// ---------------------------------------------------------------------------------------------
// Presets
// ---------------------------------------------------------------------------------------------

/// Animal fur (fur thesis fig. 3.8, 3.12): 16 layers of 128² texels, a sparse coat of long,
/// slightly bent, tapering hairs over a dense undercoat of short ones; fins 20 slices × 64 rows.
pub fn fur_preset() -> VolumeParams {
    VolumeParams {
        layers: 16,
        resolution: 128,
        coat: HairCoat {
            density: 0.05,
            length_min: 0.55,
            length_max: 1.0,
            max_deviation_texels: 6.0,
            curvature_exponent: 2.0,
            radius_texels: 1.1,
            taper: 0.7,
        },
        undercoat: Some(HairCoat {
            density: 0.35,
            length_min: 0.15,
            length_max: 0.45,
            max_deviation_texels: 3.0,
            curvature_exponent: 2.0,
            radius_texels: 0.6,
            taper: 0.5,
        }),
        shadow_min: 0.35,
        shadow_exponent: 1.0,
        fin_slices: 20,
        fin_height: 64,
    }
}

/// Grass (fur thesis fig. 3.2–3.4, 3.13): 64 layers of 64² texels, long blades of widely varying
/// length that bend far (quadratically) and taper almost to a point; no undercoat; fins 20 × 128.
pub fn grass_preset() -> VolumeParams {
    VolumeParams {
        layers: 64,
        resolution: 64,
        coat: HairCoat {
            density: 0.06,
            length_min: 0.35,
            length_max: 1.0,
            max_deviation_texels: 12.0,
            curvature_exponent: 2.0,
            radius_texels: 1.3,
            taper: 0.85,
        },
        undercoat: None,
        shadow_min: 0.25,
        shadow_exponent: 1.5,
        fin_slices: 20,
        fin_height: 128,
    }
}

// ---------------------------------------------------------------------------------------------
// Validation
// ---------------------------------------------------------------------------------------------

fn param_error(field: &str, value: impl std::fmt::Display, allowed: impl Into<String>) -> VolumeError {
    VolumeError::Parameter { field: field.to_owned(), value: value.to_string(), allowed: allowed.into() }
}

fn check(ok: bool, field: &str, value: impl std::fmt::Display, allowed: impl Into<String>) -> Result<(), VolumeError> {
    if ok { Ok(()) } else { Err(param_error(field, value, allowed)) }
}

fn validate_coat(prefix: &str, c: &HairCoat, resolution: u32) -> Result<(), VolumeError> {
    let f = |name: &str| format!("{prefix}.{name}");
    let d = c.density;
    check(d.is_finite() && d > 0.0 && d <= 1.0, &f("density"), d, "(0, 1]")?;
    let (lo, hi) = (c.length_min, c.length_max);
    check(hi.is_finite() && hi > 0.0 && hi <= 1.0, &f("length_max"), hi, "(0, 1]")?;
    check(lo.is_finite() && lo > 0.0 && lo <= hi, &f("length_min"), lo, format!("(0, length_max = {hi}]"))?;
    let dev = c.max_deviation_texels;
    check(dev.is_finite() && dev >= 0.0, &f("max_deviation_texels"), dev, "[0, ∞), finite")?;
    let n = c.curvature_exponent;
    check(n.is_finite() && n > 0.0, &f("curvature_exponent"), n, "(0, ∞), finite")?;
    let r = c.radius_texels;
    let r_max = resolution as f32 / 2.0;
    check(r.is_finite() && r > 0.0 && r <= r_max, &f("radius_texels"), r, format!("(0, resolution / 2 = {r_max}]"))?;
    let t = c.taper;
    check(t.is_finite() && (0.0..=1.0).contains(&t), &f("taper"), t, "[0, 1]")
}

/// Checks every parameter of the volume stage; the first violation is returned, naming the field
/// and its allowed range. After this succeeds the other functions of this module trust `p`.
///
/// Ranges: `layers` 1..=1024, `resolution` 4..=8192, `layers × resolution²` ≤ [`MAX_VOXELS`];
/// per coat `density` (0, 1], `0 < length_min ≤ length_max ≤ 1`, `max_deviation_texels` ≥ 0,
/// `curvature_exponent` > 0, `radius_texels` in (0, resolution/2], `taper` [0, 1];
/// `shadow_min` (0, 1], `shadow_exponent` > 0, `fin_slices` 1..=[`MAX_FIN_SLICES`],
/// `fin_height` 1..=8192. Floats must be finite.
pub fn validate_volume_params(p: &VolumeParams) -> Result<(), VolumeError> {
    check((1..=MAX_LAYERS).contains(&p.layers), "layers", p.layers, format!("1..={MAX_LAYERS}"))?;
    check(
        (MIN_RESOLUTION..=MAX_RESOLUTION).contains(&p.resolution),
        "resolution",
        p.resolution,
        format!("{MIN_RESOLUTION}..={MAX_RESOLUTION}"),
    )?;
    let voxels = p.layers as u64 * (p.resolution as u64).pow(2);
    if voxels > MAX_VOXELS {
        return Err(VolumeError::TooManyVoxels {
            layers: p.layers,
            resolution: p.resolution,
            voxels,
            limit: MAX_VOXELS,
        });
    }
    validate_coat("coat", &p.coat, p.resolution)?;
    if let Some(u) = &p.undercoat {
        validate_coat("undercoat", u, p.resolution)?;
    }
    let s = p.shadow_min;
    check(s.is_finite() && s > 0.0 && s <= 1.0, "shadow_min", s, "(0, 1]")?;
    let e = p.shadow_exponent;
    check(e.is_finite() && e > 0.0, "shadow_exponent", e, "(0, ∞), finite")?;
    check((1..=MAX_FIN_SLICES).contains(&p.fin_slices), "fin_slices", p.fin_slices, format!("1..={MAX_FIN_SLICES}"))?;
    check((1..=MAX_RESOLUTION).contains(&p.fin_height), "fin_height", p.fin_height, format!("1..={MAX_RESOLUTION}"))
}

/// Stream tags for [`derive_seed`]: the two coats draw from independent streams of one seed.
const STREAM_COAT: u64 = 0x636F_6174; // "coat"
const STREAM_UNDERCOAT: u64 = 0x756E_6465_7263_6F61; // "undercoa"

// ---------------------------------------------------------------------------------------------
// Hairs
// ---------------------------------------------------------------------------------------------

/// One of the four growth directions of eq. 3.2 ("a stochastic function of four values").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum GrowthDirection {
    /// Bends towards +x.
    PosX = 0,
    /// Bends towards +y.
    PosY = 1,
    /// Bends towards −x.
    NegX = 2,
    /// Bends towards −y.
    NegY = 3,
}

impl GrowthDirection {
    /// All four, in code order.
    pub const ALL: [GrowthDirection; 4] = [Self::PosX, Self::PosY, Self::NegX, Self::NegY];

    /// The direction for a code in 0..4 (only the low two bits are used).
    pub fn from_code(code: u64) -> Self {
        Self::ALL[(code & 3) as usize]
    }

    /// Unit vector in texel space.
    pub fn unit(self) -> Vec2 {
        match self {
            Self::PosX => Vec2::X,
            Self::PosY => Vec2::Y,
            Self::NegX => Vec2::NEG_X,
            Self::NegY => Vec2::NEG_Y,
        }
    }
}

/// Which population a hair belongs to (fur thesis fig. 3.8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum CoatKind {
    /// The outer hairs ([`VolumeParams::coat`]).
    Coat = 0,
    /// The short, dense second pass ([`VolumeParams::undercoat`]).
    Undercoat = 1,
}

/// The shape parameters shared by all hairs of one coat.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveShape {
    /// `dmax` of eq. 3.2: lateral deviation at the top of the volume (h = 1) for `w1 = 1`, texels.
    pub max_deviation_texels: f32,
    /// `n` of eq. 3.2 (2 = quadratic).
    pub curvature_exponent: f32,
    /// Fraction by which the radius shrinks from root to tip, [0, 1].
    pub taper: f32,
}

impl CurveShape {
    fn of(c: &HairCoat) -> Self {
        Self { max_deviation_texels: c.max_deviation_texels, curvature_exponent: c.curvature_exponent, taper: c.taper }
    }
}

/// The hairs of a volume, struct-of-arrays: hair `i` is described by index `i` of every `Vec`.
#[derive(Clone, Debug, PartialEq)]
pub struct HairSet {
    /// Texture resolution the roots were drawn for (texels per side; positions wrap modulo it).
    pub resolution: u32,
    /// Curve shape per coat, indexed by `CoatKind as usize` (the undercoat entry repeats the
    /// coat's when there is no undercoat).
    pub shapes: [CurveShape; 2],
    /// Root x, texels in [0, resolution).
    pub root_x: Vec<f32>,
    /// Root y, texels in [0, resolution).
    pub root_y: Vec<f32>,
    /// Length `l` as a fraction of the volume height, in [length_min, length_max] of its coat.
    pub length: Vec<f32>,
    /// Bend weight `w1 ∈ [0, 1)` of eq. 3.2.
    pub bend: Vec<f32>,
    /// Growth direction (eq. 3.2's four values).
    pub direction: Vec<GrowthDirection>,
    /// Radius at the root, texels (its coat's `radius_texels`).
    pub radius_texels: Vec<f32>,
    /// Population of each hair.
    pub coat: Vec<CoatKind>,
}

impl HairSet {
    /// Number of hairs.
    pub fn len(&self) -> usize {
        self.root_x.len()
    }

    /// True when there are no hairs.
    pub fn is_empty(&self) -> bool {
        self.root_x.is_empty()
    }

    /// Number of hairs of one coat.
    pub fn count(&self, coat: CoatKind) -> usize {
        self.coat.iter().filter(|&&c| c == coat).count()
    }

    /// Centre of hair `i` at height `h` (eq. 3.2, see [`hair_centre`]), not wrapped.
    pub fn centre(&self, i: usize, h: f32) -> Vec2 {
        let s = &self.shapes[self.coat[i] as usize];
        hair_centre(
            Vec2::new(self.root_x[i], self.root_y[i]),
            self.direction[i],
            s.max_deviation_texels,
            s.curvature_exponent,
            self.bend[i],
            h,
        )
    }

    /// Radius of hair `i` at height `h`, texels: `r0·(1 − taper·h/l)`, shrinking linearly from
    /// the root to `r0·(1 − taper)` at its tip `h = l`.
    pub fn radius_at(&self, i: usize, h: f32) -> f32 {
        let taper = self.shapes[self.coat[i] as usize].taper;
        self.radius_texels[i] * (1.0 - taper * (h / self.length[i]).min(1.0))
    }

    /// Whether hair `i` reaches height `h` (it is cut at its length, fur thesis §3.1).
    pub fn reaches(&self, i: usize, h: f32) -> bool {
        h <= self.length[i]
    }
}

/// Centre of a hair at height `h` (fraction of the volume height), eq. 3.1–3.2:
/// `root + direction · dmax · (h / hmax)^n · w1`.
///
/// Interpretation: `hmax` is the top of the volume (`hmax = 1`), the same for every hair, so
/// `dmax` is the deviation a fully bent hair (`w1 = 1`) would reach at the outermost shell, and a
/// hair of length `l < 1` is the same curve cut at `h = l` ("filling the volume buffer with the
/// actual blade is stopped when its respective length is reached"). Short hairs (the undercoat)
/// therefore bend less than long ones of the same `dmax`, as on a real blade.
pub fn hair_centre(
    root: Vec2,
    direction: GrowthDirection,
    max_deviation_texels: f32,
    curvature_exponent: f32,
    bend: f32,
    h: f32,
) -> Vec2 {
    root + direction.unit() * (max_deviation_texels * h.powf(curvature_exponent) * bend)
}

/// Appends one coat's hairs: each base texel holds a root with probability `density` (so
/// `density` is the expected roots per texel, a stratified distribution: no clumps, no gaps wider
/// than a texel of empty luck), jittered uniformly inside the texel. Every texel draws from its
/// own SplitMix64 stream, keyed by (seed, coat stream, texel index).
fn grow_coat(set: &mut HairSet, coat: &HairCoat, kind: CoatKind, seed: u64, stream: u64, res: u32) {
    for ty in 0..res {
        for tx in 0..res {
            let texel = ty as u64 * res as u64 + tx as u64;
            let mut rng = SplitMix64::new(derive_seed(seed, stream, texel));
            if rng.next_f32() >= coat.density {
                continue;
            }
            set.root_x.push(tx as f32 + rng.next_f32());
            set.root_y.push(ty as f32 + rng.next_f32());
            set.length.push(coat.length_min + (coat.length_max - coat.length_min) * rng.next_f32());
            set.bend.push(rng.next_f32());
            set.direction.push(GrowthDirection::from_code(rng.next_u64() >> 62));
            set.radius_texels.push(coat.radius_texels);
            set.coat.push(kind);
        }
    }
}

/// Distributes the hairs of the volume (fur thesis §3.1): the coat, then, when present, the
/// undercoat as "a second traversal" with its own parameters and an independent random stream
/// (so adding or changing the undercoat never moves a coat hair). Deterministic in `seed`.
///
/// Expects validated parameters ([`validate_volume_params`]); nonsense values give a nonsense
/// (but never panicking) result.
pub fn grow_hairs(p: &VolumeParams, seed: u64) -> HairSet {
    let coat_shape = CurveShape::of(&p.coat);
    let under_shape = p.undercoat.as_ref().map_or(coat_shape, CurveShape::of);
    let mut set = HairSet {
        resolution: p.resolution,
        shapes: [coat_shape, under_shape],
        root_x: Vec::new(),
        root_y: Vec::new(),
        length: Vec::new(),
        bend: Vec::new(),
        direction: Vec::new(),
        radius_texels: Vec::new(),
        coat: Vec::new(),
    };
    grow_coat(&mut set, &p.coat, CoatKind::Coat, seed, STREAM_COAT, p.resolution);
    if let Some(u) = &p.undercoat {
        grow_coat(&mut set, u, CoatKind::Undercoat, seed, STREAM_UNDERCOAT, p.resolution);
    }
    set
}

// ---------------------------------------------------------------------------------------------
// Slicing
// ---------------------------------------------------------------------------------------------

/// A hair's cross-section at one height, centre wrapped into [0, res).
struct Disc {
    centre: Vec2,
    radius: f32,
}

/// Cross-sections (with hair index) of every hair reaching height `h`, in hair order. `h^n` is computed once per
/// coat, not per hair.
fn discs_at(hairs: &HairSet, h: f32, res: f32) -> impl Iterator<Item = (usize, Disc)> + '_ {
    let hn = hairs.shapes.map(|s| s.max_deviation_texels * h.powf(s.curvature_exponent));
    (0..hairs.len()).filter(move |&i| hairs.reaches(i, h)).map(move |i| {
        let d = hn[hairs.coat[i] as usize] * hairs.bend[i];
        let c = Vec2::new(hairs.root_x[i], hairs.root_y[i]) + hairs.direction[i].unit() * d;
        (i, Disc { centre: Vec2::new(c.x.rem_euclid(res), c.y.rem_euclid(res)), radius: hairs.radius_at(i, h) })
    })
}

/// The signed difference `d` reduced to its shortest equivalent on a circle of circumference
/// `res` (minimal image), for `|d| < 1.5·res`.
fn wrap_delta(d: f32, res: f32) -> f32 {
    if d > 0.5 * res {
        d - res
    } else if d < -0.5 * res {
        d + res
    } else {
        d
    }
}

/// Texel indices (unwrapped, at most `res` of them) whose centres `t + 0.5` lie within `reach`
/// of `c`.
fn texel_span(c: f32, reach: f32, res: usize) -> std::ops::Range<i64> {
    let first = (c - reach - 0.5).floor() as i64;
    let last = (c + reach - 0.5).ceil() as i64;
    let count = (last - first + 1).clamp(0, res as i64);
    first..first + count
}

/// Anti-aliased coverage of a disc edge at distance `dist` from the centre: 1 inside
/// `radius − 0.5`, 0 outside `radius + 0.5`, linear across the 1-texel edge.
fn edge_alpha(radius: f32, dist: f32) -> f32 {
    (radius + 0.5 - dist).clamp(0.0, 1.0)
}

fn to_byte(a: f32) -> u8 {
    (a * 255.0 + 0.5) as u8
}

/// Draws a disc into one `res × res` layer with max-blending, wrapping at the border. Only the
/// disc's bounding box of texels is visited.
fn splat_disc(layer: &mut [u8], res: usize, disc: &Disc) {
    let resf = res as f32;
    let reach = disc.radius + 0.5;
    for ty in texel_span(disc.centre.y, reach, res) {
        let dy = wrap_delta(ty as f32 + 0.5 - disc.centre.y, resf);
        let row = ty.rem_euclid(res as i64) as usize * res;
        for tx in texel_span(disc.centre.x, reach, res) {
            let dx = wrap_delta(tx as f32 + 0.5 - disc.centre.x, resf);
            let a = to_byte(edge_alpha(disc.radius, (dx * dx + dy * dy).sqrt()));
            let texel = &mut layer[row + tx.rem_euclid(res as i64) as usize];
            *texel = (*texel).max(a);
        }
    }
}

/// The self-shadow table of §3.2 (after Banks \[5\]): layer `i` of `n` is darkened by
/// `shadow_min + (1 − shadow_min)·(i/(n−1))^shadow_exponent`, innermost darkest, outermost 1.
/// A single layer is the outermost one (1).
pub fn shadow_table(layers: u32, shadow_min: f32, shadow_exponent: f32) -> Vec<f32> {
    (0..layers)
        .map(|i| {
            if layers <= 1 {
                return 1.0;
            }
            let t = i as f32 / (layers - 1) as f32;
            shadow_min + (1.0 - shadow_min) * t.powf(shadow_exponent)
        })
        .collect()
}

/// Height sampled by shell layer `i` of `layers`: the middle of its slab, `(i + 0.5) / layers`.
pub fn layer_height(i: u32, layers: u32) -> f32 {
    (i as f32 + 0.5) / layers as f32
}

/// Slices the volume into one alpha texture per shell layer (fur thesis §3.1: "each horizontal
/// plane matches a shell texture"). Layer `i` samples height [`layer_height`]; each texel's
/// alpha is the anti-aliased coverage of the hair discs there (max over overlapping hairs),
/// wrapping at the border. Also fills the shadow table and each layer's coverage (fraction of
/// non-zero texels). `seed` and `fur_length_m` are recorded in the atlas, not used. Parallel
/// over layers; identical bytes for any thread count.
///
/// Expects validated parameters and `hairs` grown with the same `p`.
pub fn slice_shell_atlas(p: &VolumeParams, hairs: &HairSet, seed: u64, fur_length_m: f32) -> ShellAtlas {
    let res = p.resolution as usize;
    let texels = res * res;
    let mut alpha = vec![0u8; p.layers as usize * texels];
    if texels > 0 {
        alpha.par_chunks_mut(texels).enumerate().for_each(|(i, layer)| {
            let h = layer_height(i as u32, p.layers);
            for (_, disc) in discs_at(hairs, h, res as f32) {
                splat_disc(layer, res, &disc);
            }
        });
    }
    let coverage = if texels == 0 {
        vec![0.0; p.layers as usize]
    } else {
        alpha.chunks(texels).map(|l| l.iter().filter(|&&a| a > 0).count() as f32 / texels as f32).collect()
    };
    ShellAtlas {
        params: p.clone(),
        seed,
        fur_length_m,
        alpha,
        shadow: shadow_table(p.layers, p.shadow_min, p.shadow_exponent),
        coverage,
    }
}

// ---------------------------------------------------------------------------------------------
// Fins
// ---------------------------------------------------------------------------------------------

/// Height sampled by fin row `row` of `height` rows; row 0 is the top (tip), the last the skin.
pub fn fin_row_height(row: u32, height: u32) -> f32 {
    1.0 - (row as f32 + 0.5) / height as f32
}

/// A hair disc crossing slice plane `slice`, `dy` texels from it.
struct FinHit {
    slice: u32,
    hair: u32,
    centre_x: f32,
    dy: f32,
    radius: f32,
}

/// One fin row: every slice plane `y_k = (k + 0.5)·res/K` cuts the hair discs at height `h`;
/// each slice's alpha is the max over its hairs (the same anti-aliased density field as the
/// shells, sampled at `y = y_k`), and the slices are composited `a = 1 − Π(1 − a_k)`.
fn compose_fin_row(out: &mut [u8], hairs: &HairSet, h: f32, res: usize, slices: u32) {
    let resf = res as f32;
    let spacing = resf / slices as f32;
    let mut hits = Vec::new();
    for (hair, disc) in discs_at(hairs, h, resf) {
        let reach = disc.radius + 0.5;
        let cy = disc.centre.y;
        // Candidate planes k with |cy − y_k| < reach, at most every plane once.
        let first = ((cy - reach) / spacing - 0.5).floor() as i64;
        let last = ((cy + reach) / spacing - 0.5).ceil() as i64;
        let count = (last - first + 1).clamp(0, slices as i64);
        for k in first..first + count {
            let slice = k.rem_euclid(slices as i64) as u32;
            let dy = wrap_delta(cy - (slice as f32 + 0.5) * spacing, resf);
            if dy.abs() < reach {
                hits.push(FinHit { slice, hair: hair as u32, centre_x: disc.centre.x, dy, radius: disc.radius });
            }
        }
    }
    // Unique (slice, hair) keys: a fixed compositing order whatever produced the list.
    hits.sort_unstable_by_key(|hit| (hit.slice, hit.hair));

    let mut transmit = vec![1.0f32; res];
    let mut slice_alpha = vec![0.0f32; res];
    for group in hits.chunk_by(|a, b| a.slice == b.slice) {
        for hit in group {
            let half = ((hit.radius + 0.5).powi(2) - hit.dy * hit.dy).max(0.0).sqrt();
            for tx in texel_span(hit.centre_x, half, res) {
                let dx = wrap_delta(tx as f32 + 0.5 - hit.centre_x, resf);
                let a = edge_alpha(hit.radius, (dx * dx + hit.dy * hit.dy).sqrt());
                let t = &mut slice_alpha[tx.rem_euclid(res as i64) as usize];
                *t = t.max(a);
            }
        }
        // Composite the slice and clear only what it touched (spans may overlap: a cleared
        // texel composites as 1 − 0, a no-op).
        for hit in group {
            let half = ((hit.radius + 0.5).powi(2) - hit.dy * hit.dy).max(0.0).sqrt();
            for tx in texel_span(hit.centre_x, half, res) {
                let x = tx.rem_euclid(res as i64) as usize;
                transmit[x] *= 1.0 - slice_alpha[x];
                slice_alpha[x] = 0.0;
            }
        }
    }
    for (o, t) in out.iter_mut().zip(&transmit) {
        *o = to_byte(1.0 - t);
    }
}

/// Composes the fin texture (fur thesis §3.1, fig. 3.5–3.7): `resolution` wide, `fin_height`
/// tall, row 0 at the tip and the last row at the skin ([`fin_row_height`]). K = `fin_slices`
/// vertical planes `y_k = (k + 0.5)·res/K` cut the volume; each sees the hairs whose centre passes
/// within their radius of the plane at that height; the slices are composited with alpha "over".
/// Hair curves are evaluated at each row's own height, so `fin_height` may exceed `layers`.
/// Parallel over rows; identical bytes for any thread count.
///
/// Expects validated parameters and `hairs` grown with the same `p`.
pub fn compose_fin_atlas(p: &VolumeParams, hairs: &HairSet) -> FinAtlas {
    let (res, height) = (p.resolution as usize, p.fin_height);
    let slices = p.fin_slices.max(1);
    let mut alpha = vec![0u8; res * height as usize];
    if res > 0 {
        alpha.par_chunks_mut(res).enumerate().for_each(|(row, out)| {
            compose_fin_row(out, hairs, fin_row_height(row as u32, height), res, slices);
        });
    }
    FinAtlas { width: p.resolution, height, slices, alpha }
}

// ---------------------------------------------------------------------------------------------
// The stage
// ---------------------------------------------------------------------------------------------

/// The whole volume stage: validate, grow the hairs, slice the shells, compose the fins.
/// `fur_length_m` (skin to outermost shell, metres) must be finite and positive.
pub fn bake_volume(p: &VolumeParams, seed: u64, fur_length_m: f32) -> Result<(ShellAtlas, FinAtlas), VolumeError> {
    validate_volume_params(p)?;
    check(fur_length_m.is_finite() && fur_length_m > 0.0, "fur_length_m", fur_length_m, "(0, ∞), finite")?;
    let hairs = grow_hairs(p, seed);
    let shells = slice_shell_atlas(p, &hairs, seed, fur_length_m);
    let fins = compose_fin_atlas(p, &hairs);
    Ok((shells, fins))
}
