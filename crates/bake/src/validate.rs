//! Validation of a whole [`BakeSettings`] plan, stage by stage, before any work starts (STYLE:
//! "parse, then plan"; "validate at the boundary, then trust the data").
//!
//! Every error is a [`SettingsError`] whose message starts with the setting's key exactly as
//! `inspect` shows it under the manifest's `settings` (`topology.stiffness_n_per_m`), then the
//! value given and the allowed range. Two checks, in this order:
//!
//! 1. [`BakeSettings::plan`] needs nothing but the settings, so a caller runs it before it reads
//!    the input: import (fur mask, welding), volume, shells, UV, blades (field and keyframes),
//!    topologies and their parameters, and the sizes they imply alone (hairs of the volume).
//! 2. [`check_against_mesh`] adds the limits that depend on the imported mesh (blade count,
//!    cluster grid, topology masses, the automatic fur length); [`crate::bake`] runs it before the
//!    first stage.
//!
//! The ranges refuse what would give an unusable pack: non-finite values, zero or negative where
//! a positive value is needed, absurd sizes (a fur length of 3e38 or 1e-45 metres) and counts that
//! would need gigabytes. After both checks the stages trust their settings.

use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::{CHAIN_MASSES_RANGE, FUR_LENGTH_RANGE_M, TopologyKind};
use furbake_grass::{BladeFieldSettings, KeyframeSettings};

use crate::settings::{BakeSettings, BladeSettings, SettingsError, topology_names};
use crate::volume::{self, VolumeError};

/// Shortest and longest length in metres (scene units) of every length setting: fur length, UV
/// repeat, blade heights, cluster size. Outside, the pack is unusable (denormal or overflowing
/// offsets, texel densities and UVs).
pub const LENGTH_RANGE_M: (f32, f32) = FUR_LENGTH_RANGE_M;
/// Most hairs a volume may grow (`resolution² × (coat.density + undercoat.density)`): 2^24,
/// about 400 MiB of hair curves.
pub const MAX_HAIRS: u64 = 1 << 24;
/// Most blades per square metre.
pub const MAX_BLADE_DENSITY_PER_M2: f32 = 1e6;
/// Most blades one bake scatters (furry area × density): 2^24, about 700 MiB of blade field.
pub const MAX_BLADES: u64 = 1 << 24;
/// Most masses of one topology (welded vertices × masses per hair): 2^24.
pub const MAX_TOPOLOGY_MASSES: u64 = 1 << 24;
/// Largest keyframe force magnitude (force units of the blade material; default 4).
pub const MAX_KEYFRAME_FORCE: f32 = 1e3;
/// Range of the blade material's stiffnesses and weight (force units; defaults 1, 20, 0.05).
pub const BLADE_MATERIAL_MAX: f64 = 1e6;

fn real(key: &str, v: f32, lo: f32, hi: f32) -> Result<(), SettingsError> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(SettingsError::range(key, bound(v), interval(lo, hi)))
    }
}

fn real64(key: &str, v: f64, lo: f64, hi: f64, allowed: &str) -> Result<(), SettingsError> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(SettingsError::range(key, bound(v as f32), allowed))
    }
}

/// A number as people write it: `0`, `0.5`, `1000`, `1e-6`, `3e38` (also used for values given).
fn bound(x: f32) -> String {
    if x == 0.0 || (1e-3..1e4).contains(&x.abs()) { x.to_string() } else { format!("{x:e}") }
}

fn interval(lo: f32, hi: f32) -> String {
    format!("[{}, {}]", bound(lo), bound(hi))
}

/// Bake settings that passed every check that needs no mesh ([`BakeSettings::plan`]): the only
/// settings [`crate::bake`] takes, so they are checked once, where they are read (a config file,
/// `--set` flags, a batch entry), and the stages trust them. Made only by [`BakeSettings::plan`];
/// read through `Deref` or [`BakePlan::settings`].
#[derive(Clone, Debug, PartialEq)]
pub struct BakePlan {
    settings: BakeSettings,
}

impl BakePlan {
    /// The validated settings.
    pub fn settings(&self) -> &BakeSettings {
        &self.settings
    }

    /// The settings, to change and plan again.
    pub fn into_settings(self) -> BakeSettings {
        self.settings
    }
}

impl std::ops::Deref for BakePlan {
    type Target = BakeSettings;
    fn deref(&self) -> &BakeSettings {
        &self.settings
    }
}

impl BakeSettings {
    /// Checks every setting's range, stage by stage (import, volume, shells, UV, blades, topologies), and returns the
    /// settings as a [`BakePlan`]; the first violation names its key, the value and the allowed
    /// range.
    pub fn plan(self) -> Result<BakePlan, SettingsError> {
        validate_settings(&self)?;
        Ok(BakePlan { settings: self })
    }
}

/// Checks every setting that needs no mesh; the first violation is returned. Stages in pipeline
/// order: preset, import, volume, shells, UV, blades, topologies.
pub(crate) fn validate_settings(s: &BakeSettings) -> Result<(), SettingsError> {
    validate_import(s)?;
    validate_volume(s)?;
    validate_shells(s)?;
    validate_uv(s)?;
    if let Some(b) = &s.blades {
        validate_blades(b)?;
    }
    validate_topologies(s)
}

fn validate_import(s: &BakeSettings) -> Result<(), SettingsError> {
    s.import.validate().map_err(|e| SettingsError::OutOfRange {
        key: format!("import.{}", e.key),
        value: e.value,
        allowed: e.allowed.to_owned(),
    })
}

/// Ranges: those of [`volume::validate_volume_params`] under `volume.`, and at most
/// [`MAX_HAIRS`] hairs.
fn validate_volume(s: &BakeSettings) -> Result<(), SettingsError> {
    let p = &s.volume;
    volume::validate_volume_params(p).map_err(|e| match e {
        VolumeError::Parameter { field, value, allowed } => {
            SettingsError::OutOfRange { key: format!("volume.{field}"), value, allowed }
        }
        VolumeError::TooManyVoxels { layers, resolution, voxels, limit } => SettingsError::TooLarge {
            key: "volume.layers".into(),
            value: format!("{layers} with volume.resolution = {resolution}"),
            what: "voxels (layers × resolution²)".into(),
            amount: voxels,
            limit,
        },
    })?;
    let texels = (p.resolution as f64).powi(2);
    let densities = p.coat.density + p.undercoat.as_ref().map_or(0.0, |u| u.density);
    let hairs = (texels * densities as f64).ceil() as u64;
    if hairs > MAX_HAIRS {
        return Err(SettingsError::TooLarge {
            key: "volume.resolution".into(),
            value: format!("{} with hair densities adding up to {densities}", p.resolution),
            what: "hairs (resolution² × (coat.density + undercoat.density))".into(),
            amount: hairs,
            limit: MAX_HAIRS,
        });
    }
    Ok(())
}

/// Ranges: `shells.fur_length_m` in [`LENGTH_RANGE_M`], `shells.auto_fur_length_fraction` (0, 1].
fn validate_shells(s: &BakeSettings) -> Result<(), SettingsError> {
    let (lo, hi) = LENGTH_RANGE_M;
    if let Some(l) = s.shells.fur_length_m {
        real("shells.fur_length_m", l, lo, hi)?;
    }
    let f = s.shells.auto_fur_length_fraction;
    if !(f.is_finite() && f > 0.0 && f <= 1.0) {
        return Err(SettingsError::range("shells.auto_fur_length_fraction", bound(f), "(0, 1]"));
    }
    Ok(())
}

/// Ranges: `uv.repeat_m` in [`LENGTH_RANGE_M`].
fn validate_uv(s: &BakeSettings) -> Result<(), SettingsError> {
    let (lo, hi) = LENGTH_RANGE_M;
    match s.uv.repeat_m {
        Some(r) => real("uv.repeat_m", r, lo, hi),
        None => Ok(()),
    }
}

/// Ranges under `blades.field`: `density_per_m2` (0, [`MAX_BLADE_DENSITY_PER_M2`]], heights and
/// `cluster_size_m` in [`LENGTH_RANGE_M`] with `height_min_m ≤ height_max_m`. Under
/// `blades.keyframes`: see [`validate_keyframes`].
fn validate_blades(b: &BladeSettings) -> Result<(), SettingsError> {
    validate_blade_field(&b.field)?;
    validate_keyframes(&b.keyframes)
}

fn validate_blade_field(f: &BladeFieldSettings) -> Result<(), SettingsError> {
    let d = f.density_per_m2;
    if !(d.is_finite() && d > 0.0 && d <= MAX_BLADE_DENSITY_PER_M2) {
        return Err(SettingsError::range(
            "blades.field.density_per_m2",
            bound(d),
            format!("(0, {MAX_BLADE_DENSITY_PER_M2:e}]; leave blades unset to bake none"),
        ));
    }
    let (lo, hi) = LENGTH_RANGE_M;
    real("blades.field.height_min_m", f.height_min_m, lo, hi)?;
    let h = f.height_max_m;
    if !(h.is_finite() && h >= f.height_min_m && h <= hi) {
        return Err(SettingsError::range(
            "blades.field.height_max_m",
            bound(h),
            format!("[height_min_m = {}, {}]", f.height_min_m, bound(hi)),
        ));
    }
    real("blades.field.cluster_size_m", f.cluster_size_m, lo, hi)
}

/// Ranges under `blades.keyframes`: `shape.segments` 1..=256, `shape.base_width` and
/// `shape.tip_width` (0, 1], `shape.curl` [−0.5, 0.5] (0 under `xz` symmetry);
/// `material.bending_stiffness` and `material.width_stiffness_ratio` (0, 1e6], `material.weight`
/// [0, 1e6]; `grid.poses` 1..=2^20, `grid.max_force` (0, 1e3], `grid.magnitudes` a divisor of
/// `poses` leaving a whole number of angles per mirrored quadrant.
pub fn validate_keyframes(k: &KeyframeSettings) -> Result<(), SettingsError> {
    let shape = &k.shape;
    let max_segments = furbake_grass::blade::MAX_SEGMENTS;
    if !(1..=max_segments).contains(&shape.segments) {
        return Err(SettingsError::range(
            "blades.keyframes.shape.segments",
            shape.segments,
            format!("1..={max_segments}"),
        ));
    }
    for (key, w) in
        [("blades.keyframes.shape.base_width", shape.base_width), ("blades.keyframes.shape.tip_width", shape.tip_width)]
    {
        if !(w.is_finite() && w > 0.0 && w <= 1.0) {
            return Err(SettingsError::range(key, bound(w), "(0, 1] blade lengths"));
        }
    }
    real("blades.keyframes.shape.curl", shape.curl, -0.5, 0.5)?;
    if k.symmetry.mirrors_z() && shape.curl != 0.0 {
        return Err(SettingsError::Invalid {
            key: "blades.keyframes.shape.curl".into(),
            what: format!(
                "{} bends the blade out of its z = 0 mirror plane, which symmetry {} assumes; use curl 0 or symmetry none or x",
                shape.curl,
                k.symmetry.name()
            ),
        });
    }
    let m = &k.material;
    let positive = format!("(0, {BLADE_MATERIAL_MAX:e}]");
    for (key, v) in [
        ("blades.keyframes.material.bending_stiffness", m.bending_stiffness),
        ("blades.keyframes.material.width_stiffness_ratio", m.width_stiffness_ratio),
    ] {
        real64(key, v, f64::MIN_POSITIVE, BLADE_MATERIAL_MAX, &positive)?;
    }
    real64(
        "blades.keyframes.material.weight",
        m.weight,
        0.0,
        BLADE_MATERIAL_MAX,
        &format!("[0, {BLADE_MATERIAL_MAX:e}]"),
    )?;
    let g = &k.grid;
    let max_poses = furbake_grass::keyframes::MAX_POSES;
    if !(1..=max_poses).contains(&g.poses) {
        return Err(SettingsError::range("blades.keyframes.grid.poses", g.poses, format!("1..={max_poses}")));
    }
    let f = g.max_force;
    if !(f.is_finite() && f > 0.0 && f <= MAX_KEYFRAME_FORCE) {
        return Err(SettingsError::range(
            "blades.keyframes.grid.max_force",
            bound(f),
            format!("(0, {MAX_KEYFRAME_FORCE:e}]"),
        ));
    }
    g.resolve(k.symmetry).map(|_| ()).map_err(|e| SettingsError::Invalid {
        key: if g.magnitudes.is_some() { "blades.keyframes.grid.magnitudes" } else { "blades.keyframes.grid.poses" }
            .into(),
        what: e.to_string(),
    })
}

/// Topology names known; parameters in [`TopologyParams::check_ranges`](furbake_formats::sections::spring_topology::TopologyParams::check_ranges)
/// under `topology.`; with any topology, `volume.layers` ≥ 2 (one chain mass per shell layer).
fn validate_topologies(s: &BakeSettings) -> Result<(), SettingsError> {
    for (i, name) in s.topologies.iter().enumerate() {
        if TopologyKind::from_name(name).is_none() {
            return Err(SettingsError::Invalid {
                key: format!("topologies[{i}]"),
                what: format!("unknown topology {name:?} (known: {})", topology_names().join(", ")),
            });
        }
        // A pack holds one topology per kind (`furbake_formats::check_consistency`).
        if s.topologies[..i].contains(name) {
            return Err(SettingsError::Invalid {
                key: format!("topologies[{i}]"),
                what: format!("{name:?} is listed twice; a pack holds one topology of each kind"),
            });
        }
    }
    // The bake takes the fur length and chain length from the shells (see `bake`): a value set
    // for them would be recorded but ignored, so it is refused, naming the setting that decides.
    let defaults = furbake_formats::sections::spring_topology::TopologyParams::default();
    for (key, differs, instead) in [
        (
            "topology.chain_layers",
            s.topology.chain_layers != defaults.chain_layers,
            "volume.layers (one chain mass per shell layer)",
        ),
        ("topology.fur_length_m", s.topology.fur_length_m != defaults.fur_length_m, "shells.fur_length_m"),
    ] {
        if differs {
            return Err(SettingsError::Invalid {
                key: key.to_owned(),
                what: format!("is taken from {instead}; set that instead"),
            });
        }
    }
    // The stored defaults stand in when no topology is baked, so the ranges of the other fields
    // still hold.
    let mut params = s.topology.clone();
    if let Some(l) = s.shells.fur_length_m {
        params.fur_length_m = l;
    }
    if !s.topologies.is_empty() {
        let (lo, hi) = CHAIN_MASSES_RANGE;
        if !(lo..=hi).contains(&s.volume.layers) {
            return Err(SettingsError::range(
                "volume.layers",
                s.volume.layers,
                format!("{lo}..={hi} with a topology (one chain mass per shell layer)"),
            ));
        }
        params.chain_layers = s.volume.layers;
    }
    params.check_ranges().map_err(|e| SettingsError::prefixed("topology", e))
}

/// The limits that depend on the imported mesh, checked before the first stage: the automatic fur
/// length (bounding-box diagonal × `shells.auto_fur_length_fraction`) in [`LENGTH_RANGE_M`], at
/// most [`MAX_BLADES`] blades and `furbake_grass` cluster-grid cells, at most
/// [`MAX_TOPOLOGY_MASSES`] masses per topology.
pub fn check_against_mesh(s: &BakeSettings, mesh: &SkinMesh) -> Result<(), SettingsError> {
    if s.shells.fur_length_m.is_none() {
        let (lo_b, hi_b) = mesh.bounds();
        let diag = glam::Vec3::from(hi_b).distance(glam::Vec3::from(lo_b));
        let l = diag * s.shells.auto_fur_length_fraction;
        let (lo, hi) = LENGTH_RANGE_M;
        // A degenerate mesh (zero diagonal) keeps the fallback of `fur_length`.
        if l > 0.0 && !(l.is_finite() && (lo..=hi).contains(&l)) {
            return Err(SettingsError::Invalid {
                key: "shells.fur_length_m".into(),
                what: format!(
                    "unset, so the fur length is {l} m ({} × the mesh's {diag} m diagonal), outside {}; set it",
                    s.shells.auto_fur_length_fraction,
                    interval(lo, hi)
                ),
            });
        }
    }
    if let Some(b) = &s.blades {
        let (area, lo, hi) = furry_area_and_xz_bounds(mesh);
        let blades = (area * b.field.density_per_m2 as f64).ceil();
        if blades > MAX_BLADES as f64 {
            return Err(SettingsError::TooLarge {
                key: "blades.field.density_per_m2".into(),
                value: format!("{} on {area:.3} m² of furry surface", b.field.density_per_m2),
                what: "blades".into(),
                amount: blades as u64,
                limit: MAX_BLADES,
            });
        }
        let cell = b.field.cluster_size_m as f64;
        let cells = ((hi[0] - lo[0]) / cell).ceil().max(1.0) * ((hi[1] - lo[1]) / cell).ceil().max(1.0);
        let limit = furbake_grass::field::MAX_CLUSTERS;
        if cells > limit as f64 {
            return Err(SettingsError::TooLarge {
                key: "blades.field.cluster_size_m".into(),
                value: b.field.cluster_size_m.to_string(),
                what: "clusters".into(),
                amount: cells.min(u64::MAX as f64) as u64,
                limit,
            });
        }
    }
    let vertices = mesh.positions.len() as u64;
    for name in &s.topologies {
        let (key, per_hair) = match TopologyKind::from_name(name) {
            Some(TopologyKind::CHAIN) => ("volume.layers", s.volume.layers),
            Some(TopologyKind::REDUCED_CHAIN) => ("topology.reduced_chain_masses", s.topology.reduced_chain_masses),
            _ => continue,
        };
        let masses = vertices * per_hair as u64;
        if masses > MAX_TOPOLOGY_MASSES {
            return Err(SettingsError::TooLarge {
                key: key.into(),
                value: format!("{per_hair} with topology {name} on {vertices} vertices"),
                what: "masses".into(),
                amount: masses,
                limit: MAX_TOPOLOGY_MASSES,
            });
        }
    }
    Ok(())
}

/// Area of the furry triangles (m²) and the xz bounds of their vertices.
pub(crate) fn furry_area_and_xz_bounds(mesh: &SkinMesh) -> (f64, [f64; 2], [f64; 2]) {
    let mut area = 0.0;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if mesh.fur_mask.get(t).copied().unwrap_or(0) == 0 {
            continue;
        }
        let Some(p) = tri
            .iter()
            .map(|&i| mesh.positions.get(i as usize).map(|&v| glam::DVec3::from(v.map(f64::from))))
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        area += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        for v in &p {
            lo = [lo[0].min(v.x), lo[1].min(v.z)];
            hi = [hi[0].max(v.x), hi[1].max(v.z)];
        }
    }
    if area == 0.0 || !lo[0].is_finite() {
        return (area, [0.0; 2], [0.0; 2]);
    }
    (area, lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::dotted_override;

    fn with(set: &str) -> BakeSettings {
        let base = BakeSettings::preset("fur").unwrap();
        base.with_overrides(&dotted_override(set).unwrap()).unwrap()
    }

    #[test]
    fn presets_and_the_blade_defaults_are_valid() {
        for name in crate::settings::PRESETS {
            let mut s = BakeSettings::preset(name).unwrap();
            s.blades = Some(BladeSettings::default());
            s.topologies = topology_names().iter().map(|n| n.to_string()).collect();
            assert_eq!(validate_settings(&s), Ok(()), "{name}");
        }
    }

    #[test]
    fn every_stage_names_its_key_first() {
        let cases = [
            ("import.weld_tolerance={\"absolute_m\":-1}", "import.weld_tolerance.absolute_m"),
            ("volume.coat.radius_texels=1e9", "volume.coat.radius_texels"),
            ("volume.undercoat.density=1", "volume.resolution"),
            ("shells.fur_length_m=3e38", "shells.fur_length_m"),
            ("uv.repeat_m=1e-45", "uv.repeat_m"),
            ("blades.field.cluster_size_m=0", "blades.field.cluster_size_m"),
            ("blades.keyframes.material.bending_stiffness=0", "blades.keyframes.material.bending_stiffness"),
            ("topology.edge_stiffness_n_per_m=1e30", "topology.edge_stiffness_n_per_m"),
        ];
        let mut checked = 0;
        for (set, key) in cases {
            let mut s = with(set);
            if key == "volume.resolution" {
                s.volume.resolution = 8192;
                s.volume.layers = 4;
            }
            let err = validate_settings(&s).expect_err(set);
            assert_eq!(err.key(), key, "{set}: {err}");
            assert!(err.to_string().starts_with(key), "{err}");
            checked += 1;
        }
        assert_eq!(checked, cases.len());
    }

    #[test]
    fn limits_that_need_the_mesh_are_checked_against_it() {
        let mesh = furbake_import::import_gltf_slice(
            &furbake_import::testmesh::uv_sphere(8, 12, 1.0).gltf,
            "sphere.gltf",
            None,
            &Default::default(),
        )
        .unwrap()
        .mesh;
        let ok = with("blades.field.density_per_m2=10");
        assert_eq!(check_against_mesh(&ok, &mesh), Ok(()));
        // ~12.6 m² × 1e6 blades/m² = 1.3e7 blades: in range alone, under the limit; 1e7 m² is not.
        let too_many = with("blades.field.density_per_m2=1000000");
        assert_eq!(check_against_mesh(&too_many, &mesh), Ok(()));
        let mut big = mesh.clone();
        for p in &mut big.positions {
            *p = p.map(|c| c * 1000.0);
        }
        let err = check_against_mesh(&too_many, &big).unwrap_err();
        assert_eq!(err.key(), "blades.field.density_per_m2", "{err}");
        let err = check_against_mesh(&with("shells.auto_fur_length_fraction=1"), &{
            let mut huge = mesh.clone();
            huge.positions[0] = [1e30, 0.0, 0.0];
            huge
        })
        .unwrap_err();
        assert_eq!(err.key(), "shells.fur_length_m", "{err}");
    }
}
