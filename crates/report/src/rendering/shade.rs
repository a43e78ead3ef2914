//! The CPU twin of furbake's fur shading, so that the reference ([`super::reference`]) lights its
//! hairs with exactly the function the shells, fins and skin use: `lambert`, `cell_noise`,
//! `strand_lobe`, `strand_shade` and `strand_mask` of `crates/render/shaders/fur_common.wgsl` (docs/design.md
//! "Fur shading"; fur thesis §3.2 for Lambert and the self-shadow table, §3.3 for Kajiya–Kay),
//! in the shaders' order of operations, f32. The parameters are the renderer's
//! ([`furbake_runtime::scene::FurShading`]) and the frame's lights and hemisphere ambient, read
//! from the very `FrameUniforms` the renderer uploads (`light_at`, `ambient_at` of
//! `crates/render/shaders/lighting.wgsl`).

use furbake_render::FrameUniforms;
use furbake_runtime::scene::FurShading;
use glam::{Vec3, Vec4};

/// One light as `light_at` sees it (`Light` of `crates/render/shaders/lighting.wgsl`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct LightUniform {
    /// Directional: unit vector towards the light, w = 0; point: position, w = 1.
    vector: Vec4,
    /// rgb: radiance; a: a point light's range (0: unbounded).
    radiance: Vec4,
}

/// What the shading reads from the `Frame` and `Fur` uniforms: the frame's lights and hemisphere
/// ambient (`FrameUniforms`, as the renderer packs them from a `View`), the strand parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadeSettings {
    lights: Vec<LightUniform>,
    ambient_sky: Vec3,
    ambient_ground: Vec3,
    /// The strand shading's parameters; with `enabled` off the Lambert × self-shadow path.
    pub shading: FurShading,
    /// The `LAMBERT` switch (off: unlit colour). The report keeps it on.
    pub lambert: bool,
}

impl ShadeSettings {
    /// The parameters of a frame whose uniforms are `frame` (`View::uniforms`) with `shading`.
    pub fn new(frame: &FrameUniforms, shading: FurShading) -> ShadeSettings {
        let (sky, ground) = frame.ambient();
        ShadeSettings {
            lights: frame
                .lights()
                .map(|(vector, radiance)| LightUniform { vector: Vec4::from(vector), radiance: Vec4::from(radiance) })
                .collect(),
            ambient_sky: Vec3::from(sky),
            ambient_ground: Vec3::from(ground),
            shading,
            lambert: true,
        }
    }

    /// Whether the strand path runs (`STRAND && LAMBERT` in the shaders).
    pub fn strand(&self) -> bool {
        self.shading.enabled && self.lambert
    }

    /// `light_at(i, world)`: the unit vector towards light `i` and its radiance at `world`.
    fn light_at(&self, i: usize, world: Vec3) -> (Vec3, Vec3) {
        let light = &self.lights[i];
        if light.vector.w == 0.0 {
            return (light.vector.truncate(), light.radiance.truncate());
        }
        let d = light.vector.truncate() - world;
        let dist2 = d.dot(d).max(1e-8);
        let mut falloff = 1.0 / dist2;
        if light.radiance.w > 0.0 {
            let r = dist2 / (light.radiance.w * light.radiance.w);
            let window = (1.0 - r * r).clamp(0.0, 1.0);
            falloff *= window * window;
        }
        (d / dist2.sqrt(), light.radiance.truncate() * falloff)
    }

    /// `ambient_at(n)`: the hemisphere ambient on unit normal `n`.
    fn ambient_at(&self, n: Vec3) -> Vec3 {
        self.ambient_ground.lerp(self.ambient_sky, 0.5 + 0.5 * n.y)
    }

    /// `lambert(n, world)`: Lambert diffuse of every light plus the ambient (fur thesis §3.2).
    pub fn lambert(&self, n_in: Vec3, world: Vec3) -> Vec3 {
        if !self.lambert {
            return Vec3::ONE;
        }
        let n = n_in.normalize();
        let mut rgb = self.ambient_at(n);
        for i in 0..self.lights.len() {
            let (l, radiance) = self.light_at(i, world);
            rgb += radiance * n.dot(l).max(0.0);
        }
        rgb
    }

    /// `strand_mask(x, y)`: the secondary highlight's per-hair mask of texel (x, y).
    pub fn strand_mask(&self, x: i32, y: i32) -> f32 {
        1.0 - self.shading.secondary_noise * cell_noise(x, y)
    }

    /// `strand_shade(albedo, n, tangent, world, to_eye, h, direct, mask)` of `fur_common.wgsl`.
    #[allow(clippy::too_many_arguments)]
    pub fn strand_shade(
        &self,
        albedo: Vec3,
        n_in: Vec3,
        tangent: Vec3,
        world: Vec3,
        to_eye: Vec3,
        h: f32,
        direct: f32,
        mask: f32,
    ) -> Vec3 {
        let s = &self.shading;
        let n = n_in.normalize();
        let t = if tangent.dot(tangent) > 1e-12 { tangent.normalize() } else { n };
        let v = to_eye;
        let colour = albedo * Vec3::ONE.lerp(Vec3::from(s.tip_color), h);
        let occlusion = 1.0 - s.root_occlusion * (1.0 - h);
        let mut rgb = colour * self.ambient_at(n) * occlusion;
        let tv = t.dot(v);
        let sin2_tv = (1.0 - tv * tv).max(0.0);
        for i in 0..self.lights.len() {
            let (l, radiance) = self.light_at(i, world);
            let nl = n.dot(l);
            let body = ((nl + 0.15) / 1.15).clamp(0.0, 1.0);
            let wrap = 0.5 + 0.5 * nl;
            let tl = t.dot(l);
            let kajiya_kay = (1.0 - tl * tl).max(0.0).sqrt();
            let diffuse = mix(nl.max(0.0), kajiya_kay * body, s.kajiya_kay_diffuse);
            let lv = l + v;
            let half_vector = if lv.dot(lv) > 1e-8 { lv.normalize() } else { n };
            let th = t.dot(half_vector);
            let sin_th = (1.0 - th * th).max(0.0).sqrt();
            let primary = s.primary_strength * strand_lobe(th, sin_th, s.primary_shift, s.primary_exponent);
            let secondary =
                s.secondary_strength * strand_lobe(th, sin_th, s.secondary_shift, s.secondary_exponent) * mask;
            let specular = body * (Vec3::splat(primary) + secondary * Vec3::from(s.secondary_tint) * colour);
            let behind = 0.5 - 0.5 * v.dot(l);
            let behind2 = behind * behind;
            let back = s.back_light * colour * (behind2 * behind2) * sin2_tv * wrap;
            rgb += radiance * direct * (colour * diffuse + specular + back);
        }
        rgb
    }

    /// A shell fragment (`fs_shell`) of hair colour `albedo` (vertex colour × tint) at `world`,
    /// relative height `h`, surface normal `n`, hair direction `tangent`, self-shadow factor
    /// `direct` (1 without `SHADOW`) on atlas texel `cell`: the strand or the Lambert path.
    #[allow(clippy::too_many_arguments)]
    pub fn hair(
        &self,
        albedo: Vec3,
        n: Vec3,
        tangent: Vec3,
        world: Vec3,
        to_eye: Vec3,
        h: f32,
        direct: f32,
        cell: [i32; 2],
    ) -> Vec3 {
        if self.strand() {
            self.strand_shade(albedo, n, tangent, world, to_eye, h, direct, self.strand_mask(cell[0], cell[1]))
        } else {
            albedo * self.lambert(n, world) * direct
        }
    }

    /// `fs_skin`: furry skin as the root of the innermost shell (height 0, hair along `n`, the
    /// mean noise mask, the innermost self-shadow factor `direct`), bare skin Lambert only.
    pub fn skin(&self, albedo: Vec3, n: Vec3, world: Vec3, to_eye: Vec3, furry: bool, direct: f32) -> Vec3 {
        if self.strand() && furry {
            let mask = 1.0 - 0.5 * self.shading.secondary_noise;
            return self.strand_shade(albedo, n, n, world, to_eye, 0.0, direct, mask);
        }
        albedo * self.lambert(n, world) * if furry { direct } else { 1.0 }
    }
}

fn mix(a: f32, b: f32, t: f32) -> f32 {
    a * (1.0 - t) + b * t
}

/// `cell_noise(x, y)`: the PCG hash (Jarzynski & Olano 2020) of an integer cell, in [0, 1).
pub fn cell_noise(x: i32, y: i32) -> f32 {
    let mut h = (x as u32).wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    h ^= (y as u32).wrapping_mul(277_803_737);
    h = ((h >> ((h >> 28) + 4)) ^ h).wrapping_mul(277_803_737);
    h ^= h >> 22;
    (h >> 8) as f32 / 16_777_216.0
}

/// `strand_lobe(th, sin_th, shift, exponent)`: one shifted Kajiya–Kay highlight lobe, normalised
/// by (p + 2)/2π.
pub fn strand_lobe(th: f32, sin_th: f32, shift: f32, exponent: f32) -> f32 {
    let shifted = (th + shift * sin_th) / (1.0 + shift * shift).sqrt();
    let sin2 = (1.0 - shifted * shifted).max(0.0);
    (exponent + 2.0) * 0.159_154_94 * sin2.powf(0.5 * exponent)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_is_in_the_unit_interval_and_varies() {
        let values: Vec<f32> = (0..64).map(|i| cell_noise(i % 8, i / 8)).collect();
        assert!(values.iter().all(|v| (0.0..1.0).contains(v)));
        let mean = values.iter().sum::<f32>() / values.len() as f32;
        assert!((0.3..0.7).contains(&mean), "mean {mean}");
        assert_ne!(cell_noise(0, 0), cell_noise(1, 0));
    }

    #[test]
    fn the_lobe_peaks_where_the_shifted_tangent_is_perpendicular_to_h() {
        // Unshifted: sin(T, H)^p is 1 at T ⊥ H, so the lobe is (p + 2)/2π there.
        let p = 80.0;
        assert!((strand_lobe(0.0, 1.0, 0.0, p) - (p + 2.0) / std::f32::consts::TAU).abs() < 1e-4);
        assert!(strand_lobe(0.5, 0.75f32.sqrt(), 0.0, p) < 1e-3);
    }

    #[test]
    fn ambient_only_light_leaves_the_occluded_colour() {
        // No light source, ambient 1 everywhere: rgb = colour · occlusion at the root.
        let ambient = furbake_runtime::Ambient { sky: [1.0; 3], ground: [1.0; 3] };
        let lighting = furbake_runtime::Lighting::new(&[], ambient).expect("no sources");
        let frame = FrameUniforms::new(glam::Mat4::IDENTITY, Vec3::ZERO, lighting, glam::Mat4::IDENTITY);
        let p = ShadeSettings::new(&frame, FurShading::default());
        let rgb = p.strand_shade(Vec3::splat(0.5), Vec3::Y, Vec3::Y, Vec3::ZERO, Vec3::Y, 0.0, 1.0, 1.0);
        let expected = 0.5 * (1.0 - FurShading::default().root_occlusion);
        assert!((rgb - Vec3::splat(expected)).abs().max_element() < 1e-6, "{rgb}");
    }
}
