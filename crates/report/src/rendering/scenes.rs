//! The scenes of the rendering report — a flat furry patch, the furry sphere
//! (`fixtures/generated/sphere.gltf`) and the Fox (`fixtures/real/Fox.glb`, its bind pose) —
//! baked with the `fur` preset as `make demo` bakes them, and the views of them: the camera
//! aimed at an anchor point on the surface, at an angle from the surface normal there (so the
//! image centre sees the fur at that angle; for the patch the normal is the patch's).

use std::path::Path;
use std::sync::Arc;

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf, import_gltf_slice, testmesh};
use furbake_render::{FurAsset, View};
use furbake_runtime::{Camera, Lighting};
use glam::Vec3;

use super::RenderReportError;
use super::reference::HairVolume;

/// Which mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SceneKind {
    /// `testmesh::grass_patch(1.0)`: a flat 1 m square of 16 triangles, normal +Y.
    Patch,
    /// `fixtures/generated/sphere.gltf`: a 0.5 m UV sphere of 1,104 triangles.
    Sphere,
    /// `fixtures/real/Fox.glb` in its bind pose (the skin weights are not attached).
    Fox,
}

impl SceneKind {
    /// Every scene, in report order.
    pub const ALL: [SceneKind; 3] = [SceneKind::Patch, SceneKind::Sphere, SceneKind::Fox];

    /// Short name (`patch`, `sphere`, `fox`).
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Patch => "patch",
            SceneKind::Sphere => "sphere",
            SceneKind::Fox => "fox",
        }
    }
}

/// One baked scene: the renderer's asset and the reference's volume, built from the same bake.
pub struct FurScene {
    /// Which mesh.
    pub kind: SceneKind,
    /// What furbake draws.
    pub asset: FurAsset,
    /// What the reference traces.
    pub volume: HairVolume,
    /// Skin to outermost shell, metres.
    pub fur_length_m: f32,
    /// The surface point the views aim at, and the normal there.
    pub anchor: (Vec3, Vec3),
}

/// Bakes `kind` (meshes under `fixtures`, the repository's `fixtures/` folder) with `settings`
/// (the `fur` preset for the report; the tests shrink it).
pub fn bake_scene(kind: SceneKind, fixtures: &Path, settings: &BakeSettings) -> Result<FurScene, RenderReportError> {
    let import = ImportSettings::default();
    let (mesh, name) = match kind {
        SceneKind::Patch => {
            (import_gltf_slice(&testmesh::grass_patch(1.0).gltf, "patch.gltf", None, &import), "patch.gltf")
        }
        SceneKind::Sphere => (import_gltf(&fixtures.join("generated/sphere.gltf"), &import), "sphere.gltf"),
        SceneKind::Fox => (import_gltf(&fixtures.join("real/Fox.glb"), &import), "Fox.glb"),
    };
    let mesh = mesh.map_err(|e| RenderReportError::Import(name.into(), e.to_string()))?;
    let plan = settings.clone().plan().map_err(|e| RenderReportError::Bake(e.to_string()))?;
    let baked = bake(&mesh, name, &plan, &mut NoProgress).map_err(|e| RenderReportError::Bake(e.to_string()))?;
    let (m, shells, uv) = (Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map));
    let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
    let asset = FurAsset::new(Arc::clone(&m), Arc::clone(&shells), Arc::clone(&uv), fins)?;
    let volume = HairVolume::new(&m, &shells, &uv)?;
    let fur_length_m = shells.fur_length_m;
    let anchor = match kind {
        SceneKind::Patch => (Vec3::ZERO, Vec3::Y),
        SceneKind::Sphere | SceneKind::Fox => {
            // The point of the skin seen from the front-right and a little above (View::framing's
            // direction; on the Fox its flank and shoulder), with its interpolated normal.
            let (c, r) = asset.bounding_sphere();
            let dir = Vec3::new(0.75, 0.35, 1.0).normalize();
            let origin = Vec3::from(c) + dir * (3.0 * r);
            volume
                .skin_point(origin, -dir)
                .ok_or_else(|| RenderReportError::Bake(format!("{name}: no skin in the anchor direction")))?
        }
    };
    Ok(FurScene { kind, asset, volume, fur_length_m, anchor })
}

impl FurScene {
    /// The view whose centre sees the anchor at `angle_deg` from its normal, from `distance_m`
    /// away, tilted towards +Y (for the patch towards +Z), 35° vertical field of view, the
    /// default lighting (`Lighting::default()`: the studio key and rim lights and a dim hemisphere ambient).
    pub fn view(&self, angle_deg: f32, distance_m: f32) -> View {
        let (p, n) = self.anchor;
        let across = if self.kind == SceneKind::Patch { Vec3::Z } else { Vec3::Y };
        let w = (across - n * across.dot(n)).normalize_or(n.any_orthonormal_vector());
        let (s, c) = angle_deg.to_radians().sin_cos();
        let back = n * c + w * s;
        let up = w * c - n * s;
        let (center, radius) = self.asset.bounding_sphere();
        View {
            camera: Camera {
                eye: (p + back * distance_m).to_array(),
                target: p.to_array(),
                up: up.to_array(),
                fov_y_deg: FOV_Y_DEG,
            },
            lighting: Lighting::default(),
            bounds_center: center,
            bounds_radius: radius,
        }
    }

    /// The distance at which the fur, seen at `angle_deg`, projects to `length_px` pixels at the
    /// anchor in a target `height_px` tall: `L · sin(angle) · f / d` with f the focal length in
    /// pixels.
    pub fn distance_for_projected_length(&self, angle_deg: f32, length_px: f32, height_px: u32) -> f32 {
        let f = 0.5 * height_px as f32 / (0.5 * FOV_Y_DEG.to_radians()).tan();
        self.fur_length_m * angle_deg.to_radians().sin().max(0.05) * f / length_px
    }
}

/// The vertical field of view of every view of the report.
pub const FOV_Y_DEG: f32 = 35.0;
