//! The per-frame cluster force field (grass thesis §3.2.2, §4.5, ch. 5): forces are computed only
//! at the cluster grid's corners — global wind, point wind sources `normalize(WP)·ω/|WP|^σ`
//! (eq. 4.1), collisions as local sources (a sphere or an ellipsoid pushing outwards, §5.2),
//! windless areas whose blockers zero the wind at the corners inside them (§5.1) — so the CPU cost
//! per frame grows with corners × sources, never with blades. Each blade's force is the bilinear
//! blend of its cluster's four corners (eq. 3.6–3.8). A wind source may use *delayed attenuation*
//! (§4.5, fig. 4.8): the corners carry only its direction, and each blade scales the interpolated
//! direction by the source's attenuation at the blade itself.
//!
//! Forces are horizontal (§3.2.3) and returned as `Vec2(x, z)`.

use furbake_formats::sections::blade_field::ClusterGrid;
use glam::{Vec2, Vec3, Vec3Swizzles};
use rayon::prelude::*;

/// A point wind source (eq. 4.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BladeWindSource {
    /// Position `W`, metres.
    pub position_m: Vec3,
    /// Emissive power `ω` (force × metres^σ).
    pub power: f32,
    /// Concentration `σ` (≥ 0): higher values keep the wind more local.
    pub falloff_exponent: f32,
    /// Delay the attenuation to the blades (fig. 4.8) instead of applying it at the corners.
    pub delayed: bool,
}

impl BladeWindSource {
    /// The exact (horizontal) wind of this source at `p`; distances are clamped below by
    /// `min_distance_m` so a blade on the source does not receive an infinite force.
    pub fn force_at(&self, p: Vec3, min_distance_m: f32) -> Vec2 {
        let wp = p - self.position_m;
        let d = wp.length();
        if d == 0.0 {
            return Vec2::ZERO;
        }
        (wp / d).xz() * (self.power / d.max(min_distance_m).powf(self.falloff_exponent))
    }
}

/// A colliding object, treated as a local force source pushing blades away from it (§5.2). The
/// push has full `strength` inside the object and fades smoothly to zero `falloff_m` beyond it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BladeCollider {
    /// A sphere.
    Sphere {
        /// Centre, metres.
        center_m: Vec3,
        /// Radius, metres.
        radius_m: f32,
        /// Force at and inside the surface.
        strength: f32,
        /// Distance beyond the surface over which the push fades out, metres.
        falloff_m: f32,
    },
    /// An axis-aligned ellipsoid (e.g. a shoe).
    Ellipsoid {
        /// Centre, metres.
        center_m: Vec3,
        /// Semi-axes, metres.
        radii_m: Vec3,
        /// Force at and inside the surface.
        strength: f32,
        /// Distance beyond the surface (measured along the smallest semi-axis) over which the push
        /// fades out, metres.
        falloff_m: f32,
    },
}

fn fade(outside_m: f32, falloff_m: f32) -> f32 {
    if outside_m <= 0.0 {
        return 1.0;
    }
    if falloff_m <= 0.0 || outside_m >= falloff_m {
        return 0.0;
    }
    let t = 1.0 - outside_m / falloff_m;
    t * t * (3.0 - 2.0 * t)
}

impl BladeCollider {
    /// The exact (horizontal) push at `p`.
    pub fn force_at(&self, p: Vec3) -> Vec2 {
        match *self {
            BladeCollider::Sphere { center_m, radius_m, strength, falloff_m } => {
                let d = p - center_m;
                let dir = d.xz().normalize_or_zero();
                dir * (strength * fade(d.length() - radius_m, falloff_m))
            }
            BladeCollider::Ellipsoid { center_m, radii_m, strength, falloff_m } => {
                let r = radii_m.max(Vec3::splat(1e-6));
                let q = (p - center_m) / r;
                let grad = (q / r).xz().normalize_or_zero();
                let outside = (q.length() - 1.0) * r.min_element();
                grad * (strength * fade(outside, falloff_m))
            }
        }
    }
}

/// A windless area (§5.1): an `xz` rectangle; the wind (global and sources, not collisions) is zero
/// at every cluster corner inside it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindBlocker {
    /// Smallest `(x, z)`, metres.
    pub min_m: Vec2,
    /// Largest `(x, z)`, metres.
    pub max_m: Vec2,
}

impl WindBlocker {
    /// Whether `(x, z)` lies inside (borders included).
    pub fn contains(&self, xz: Vec2) -> bool {
        xz.cmpge(self.min_m).all() && xz.cmple(self.max_m).all()
    }
}

/// Everything that pushes grass in one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ForceScene {
    /// Global wind `(x, z)`, force units.
    pub global_wind: Vec2,
    /// Point wind sources.
    pub sources: Vec<BladeWindSource>,
    /// Colliding objects.
    pub colliders: Vec<BladeCollider>,
    /// Windless areas.
    pub blockers: Vec<WindBlocker>,
    /// Height at which the corners sample the field, metres. Default 0.
    pub sample_height_m: f32,
    /// Lower clamp of source distances, metres. Default 0.05.
    pub min_distance_m: f32,
}

impl Default for ForceScene {
    fn default() -> Self {
        ForceScene {
            global_wind: Vec2::ZERO,
            sources: Vec::new(),
            colliders: Vec::new(),
            blockers: Vec::new(),
            sample_height_m: 0.0,
            min_distance_m: 0.05,
        }
    }
}

impl ForceScene {
    fn blocked(&self, xz: Vec2) -> bool {
        self.blockers.iter().any(|b| b.contains(xz))
    }

    /// The exact field at `p` (the "true solution" of fig. 4.7 (d)).
    pub fn force_at(&self, p: Vec3) -> Vec2 {
        let mut f = Vec2::ZERO;
        if !self.blocked(p.xz()) {
            f += self.global_wind;
            for s in &self.sources {
                f += s.force_at(p, self.min_distance_m);
            }
        }
        for c in &self.colliders {
            f += c.force_at(p);
        }
        f
    }
}

/// Grids with fewer corners are updated on the calling thread (thread wake-up costs more).
const PARALLEL_CORNERS: usize = 16_384;

/// Runs `f(row index, row)` over `data` cut into rows of `row` corners, in parallel for big grids.
fn for_rows(data: &mut [Vec2], row: usize, f: impl Fn(usize, &mut [Vec2]) + Sync) {
    if data.len() < PARALLEL_CORNERS {
        data.chunks_mut(row).enumerate().for_each(|(r, c)| f(r, c));
    } else {
        data.par_chunks_mut(row).enumerate().for_each(|(r, c)| f(r, c));
    }
}

#[derive(Clone, Debug, PartialEq)]
struct DelayedSource {
    source: BladeWindSource,
    /// Unit horizontal direction per corner (zero where blocked).
    directions: Vec<Vec2>,
}

/// The corner forces of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ForceField {
    grid: ClusterGrid,
    /// Force at every corner (everything but delayed sources), `(x, z)`.
    pub corner_forces: Vec<Vec2>,
    delayed: Vec<DelayedSource>,
    min_distance_m: f32,
}

impl ForceField {
    /// An all-zero field over `grid`.
    pub fn new(grid: ClusterGrid) -> Self {
        ForceField { grid, corner_forces: vec![Vec2::ZERO; grid.corners()], delayed: Vec::new(), min_distance_m: 0.05 }
    }

    /// The grid.
    pub fn grid(&self) -> &ClusterGrid {
        &self.grid
    }

    /// Recomputes every corner for `scene`: `O(corners × (sources + colliders + blockers))`.
    pub fn update(&mut self, scene: &ForceScene) {
        let grid = self.grid;
        let y = scene.sample_height_m;
        let row = grid.cells_x as usize + 1;
        let corner = |i: usize| {
            let [x, z] = grid.corner_position(i as u32);
            Vec3::new(x, y, z)
        };
        self.min_distance_m = scene.min_distance_m;
        for_rows(&mut self.corner_forces, row, |r, out| {
            for (i, f) in out.iter_mut().enumerate() {
                let p = corner(r * row + i);
                let mut acc = Vec2::ZERO;
                if !scene.blocked(p.xz()) {
                    acc += scene.global_wind;
                    for s in scene.sources.iter().filter(|s| !s.delayed) {
                        acc += s.force_at(p, scene.min_distance_m);
                    }
                }
                for c in &scene.colliders {
                    acc += c.force_at(p);
                }
                *f = acc;
            }
        });
        self.delayed.clear();
        for s in scene.sources.iter().filter(|s| s.delayed) {
            let mut directions = vec![Vec2::ZERO; grid.corners()];
            for_rows(&mut directions, row, |r, out| {
                for (i, d) in out.iter_mut().enumerate() {
                    let p = corner(r * row + i);
                    *d = if scene.blocked(p.xz()) { Vec2::ZERO } else { (p - s.position_m).xz().normalize_or_zero() };
                }
            });
            self.delayed.push(DelayedSource { source: *s, directions });
        }
    }

    /// The force on a blade at `position_m` with cluster corners `corners` and weights `weights`
    /// (eq. 3.6); delayed sources add `normalize(Σ δᵢ dᵢ) · |exact wind of the source at the blade|`.
    #[inline]
    pub fn blade_force(&self, corners: [u32; 4], weights: [f32; 4], position_m: Vec3) -> Vec2 {
        let mut f = Vec2::ZERO;
        for k in 0..4 {
            f += self.corner_forces[corners[k] as usize] * weights[k];
        }
        for d in &self.delayed {
            let mut dir = Vec2::ZERO;
            for k in 0..4 {
                dir += d.directions[corners[k] as usize] * weights[k];
            }
            f += dir.normalize_or_zero() * d.source.force_at(position_m, self.min_distance_m).length();
        }
        f
    }

    /// The force on a blade in cluster `cluster` (convenience over [`ForceField::blade_force`]).
    pub fn blade_force_in_cluster(&self, cluster: u32, weights: [f32; 4], position_m: Vec3) -> Vec2 {
        self.blade_force(self.grid.corner_indices(cluster), weights, position_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::{KeyframeDecoder, PoseInterpolation};
    use crate::field::{BladeFieldSettings, ground_grid_mesh, scatter_blades};
    use crate::keyframes::{KeyframeSettings, PoseGridSettings, bake_keyframe_table};

    fn grid() -> ClusterGrid {
        ClusterGrid { origin_m: [-5.0, -5.0], cell_size_m: [0.5, 0.5], cells_x: 20, cells_z: 20 }
    }

    fn decoder() -> KeyframeDecoder {
        let s = KeyframeSettings {
            grid: PoseGridSettings { poses: 400, ..Default::default() },
            ..KeyframeSettings::thesis()
        };
        KeyframeDecoder::new(&bake_keyframe_table(&s).expect("bakes")).expect("decoder")
    }

    #[test]
    fn a_blade_in_a_windless_area_does_not_move() {
        let blocker = WindBlocker { min_m: Vec2::new(-2.0, -2.0), max_m: Vec2::new(1.0, 1.0) };
        let scene = ForceScene {
            global_wind: Vec2::new(2.0, 1.0),
            sources: vec![
                BladeWindSource {
                    position_m: Vec3::new(0.0, 0.5, 3.0),
                    power: 4.0,
                    falloff_exponent: 1.0,
                    delayed: false,
                },
                BladeWindSource {
                    position_m: Vec3::new(-3.0, 0.5, 0.0),
                    power: 4.0,
                    falloff_exponent: 2.0,
                    delayed: true,
                },
            ],
            blockers: vec![blocker],
            ..ForceScene::default()
        };
        let mut field = ForceField::new(grid());
        field.update(&scene);
        let d = decoder();
        let (mut inside, mut outside) = (0, 0);
        let mut pose = vec![Vec3::ZERO; 32];
        for k in 0..200 {
            let p = Vec3::new(-4.9 + 0.049 * k as f32, 0.0, -4.7 + 0.047 * k as f32);
            let (c, [u, v]) = field.grid().locate(p.x, p.z);
            let f = field.blade_force_in_cluster(c, furbake_formats::sections::blade_field::bilinear_weights(u, v), p);
            // Blades whose whole cluster lies inside the blocker get no force and keep the
            // reference pose; blades outside it are pushed.
            let corners = field.grid().corner_indices(c).map(|i| field.grid().corner_position(i));
            if corners.iter().all(|q| blocker.contains(Vec2::from(*q))) {
                assert_eq!(f, Vec2::ZERO, "blade at {p}");
                d.world_positions(p, 0.7, 0.3, f.extend(0.0).xzy(), PoseInterpolation::Linear, &mut pose);
                let mut rest = vec![Vec3::ZERO; 32];
                d.world_positions(p, 0.7, 0.3, Vec3::ZERO, PoseInterpolation::Linear, &mut rest);
                assert_eq!(pose, rest);
                inside += 1;
            } else if corners.iter().all(|q| !blocker.contains(Vec2::from(*q))) {
                assert!(f.length() > 0.5, "blade at {p} outside the windless area: {f}");
                outside += 1;
            }
        }
        assert!(inside >= 40 && outside >= 40, "{inside} inside, {outside} outside");
    }

    #[test]
    fn a_blade_next_to_a_collision_sphere_bends_away_from_it() {
        let center = Vec3::new(0.3, 0.2, -0.4);
        let scene = ForceScene {
            colliders: vec![BladeCollider::Sphere { center_m: center, radius_m: 0.4, strength: 3.0, falloff_m: 0.6 }],
            ..ForceScene::default()
        };
        let mesh = ground_grid_mesh([4.0, 4.0], [4, 4]);
        let blades = scatter_blades(
            &mesh,
            &BladeFieldSettings { density_per_m2: 40.0, cluster_size_m: 0.25, ..Default::default() },
        )
        .expect("scatters");
        let mut field = ForceField::new(blades.grid);
        field.update(&scene);
        let d = decoder();
        let mut pose = vec![Vec3::ZERO; 32];
        let mut near = 0;
        for b in 0..blades.blade_count() {
            let p = Vec3::from(blades.positions[b]);
            let out = (p - center).xz();
            let f = field.blade_force_in_cluster(blades.cluster[b], blades.weights[b], p);
            if out.length() > 1.6 {
                assert_eq!(f, Vec2::ZERO, "far blades are untouched");
                continue;
            }
            if !(0.3..0.6).contains(&out.length()) {
                continue;
            }
            d.world_positions(
                p,
                blades.yaw_rad[b],
                blades.height_scale[b],
                f.extend(0.0).xzy(),
                PoseInterpolation::Linear,
                &mut pose,
            );
            let tip = (pose[30] + pose[31]) * 0.5 - p;
            assert!(tip.xz().dot(out) > 0.0, "blade at {p} bends away from the sphere: tip {tip}");
            near += 1;
        }
        assert!(near > 10, "{near} blades next to the sphere");
    }

    #[test]
    fn corner_forces_follow_eq_4_1_and_delay_removes_cluster_artefacts() {
        let src =
            BladeWindSource { position_m: Vec3::new(0.1, 0.0, 0.2), power: 2.0, falloff_exponent: 3.0, delayed: false };
        // eq. 4.1 at a point.
        let p = Vec3::new(1.1, 0.0, 0.2);
        assert!((src.force_at(p, 0.05) - Vec2::new(2.0, 0.0)).length() < 1e-6);
        let exact = ForceScene { sources: vec![src], ..ForceScene::default() };
        let delayed = ForceScene { sources: vec![BladeWindSource { delayed: true, ..src }], ..ForceScene::default() };
        let mut f_cluster = ForceField::new(grid());
        f_cluster.update(&exact);
        let mut f_delayed = ForceField::new(grid());
        f_delayed.update(&delayed);
        let (mut e_cluster, mut e_delayed, mut n) = (0.0f32, 0.0f32, 0);
        for k in 0..400 {
            let p = Vec3::new(-4.0 + 0.02 * k as f32, 0.0, 1.3 - 0.011 * k as f32);
            let (c, [u, v]) = f_cluster.grid().locate(p.x, p.z);
            let w = furbake_formats::sections::blade_field::bilinear_weights(u, v);
            let truth = exact.force_at(p);
            e_cluster = e_cluster.max((f_cluster.blade_force_in_cluster(c, w, p) - truth).length());
            e_delayed = e_delayed.max((f_delayed.blade_force_in_cluster(c, w, p) - truth).length());
            n += 1;
        }
        assert_eq!(n, 400);
        assert!(e_delayed < 0.2 * e_cluster, "delayed {e_delayed} vs per-cluster {e_cluster}");
    }
}
