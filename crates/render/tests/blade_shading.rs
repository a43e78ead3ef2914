//! Grass blade shading (docs/design.md "Grass blade shading"; grass thesis §4.1, fig. 4.1) on a
//! patch seen from eye height, against the flat colour × two-sided Lambert it replaces
//! ([`BladeShading::FLAT`], which the same renderer still draws): blade colours vary between
//! blades and clumps, blades darken towards the root, a blade lit from behind looks different
//! from one lit from the front (translucency; two-sided Lambert cannot tell them apart), and an
//! out-of-range setting is refused by name. Images go to the temp folder for looking at.

use crate::common;

use crate::common::gpu;
use furbake_grass::{ForceField, ForceScene};
use furbake_render::headless::{RenderTarget, read_back};
use furbake_render::{BladeRenderSettings, BladeRenderer, BladeShading, View};
use furbake_runtime::{Camera, Light};
use image::RgbaImage;

const SIZE: u32 = 256;

/// Eye height on +z looking at the patch; the light travels along `light` (from the light).
fn view(light: [f32; 3]) -> View {
    View {
        camera: Camera { eye: [0.0, 0.35, 1.6], target: [0.0, 0.12, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 30.0 },
        lighting: Light { direction: light, ..Light::default() }.into(),
        bounds_center: [0.0, 0.12, 0.0],
        bounds_radius: 1.2,
    }
}

/// Light from behind the camera, a little from above (front-lit blades).
const FRONT: [f32; 3] = [0.2, -0.5, -1.0];
/// [`FRONT`] turned half a turn about the vertical: from behind the patch towards the camera
/// (back-lit blades). An upright blade's normal is horizontal, so `n·l` only changes sign.
const BACK: [f32; 3] = [-0.2, -0.5, 1.0];

fn render(shading: BladeShading, light: [f32; 3], name: &str) -> RgbaImage {
    let (device, queue) = (&gpu().device, &gpu().queue);
    let settings = BladeRenderSettings { shading, ..BladeRenderSettings::default() };
    let blades = BladeRenderer::new(
        gpu().pipelines(),
        queue,
        common::default_blade_patch(),
        common::default_blade_table(),
        &settings,
        &RenderTarget::desc(),
    )
    .expect("the blade renderer takes the settings");
    let mut forces = ForceField::new(common::default_blade_patch().grid);
    forces.update(&ForceScene::default());
    blades.set_force_field(queue, &forces).unwrap();
    let target = RenderTarget::new(device, SIZE, SIZE).unwrap();
    blades.render_to(device, queue, &target, &view(light), Some([0.0, 0.0, 0.0, 0.0])).unwrap();
    let image = read_back(device, queue, &target).unwrap();
    let dir = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&dir).unwrap();
    image.save(dir.join(format!("blade_shading_{name}.png"))).unwrap();
    image
}

/// Blade pixels (alpha > 0) as (row, linear-ish luminance, hue in [0, 1)).
fn blade_pixels(image: &RgbaImage) -> Vec<(u32, f64, f64)> {
    image
        .enumerate_pixels()
        .filter(|(_, _, p)| p[3] > 0)
        .map(|(_, y, p)| {
            let [r, g, b] = [p[0], p[1], p[2]].map(|c| c as f64 / 255.0);
            (y, 0.2126 * r + 0.7152 * g + 0.0722 * b, hue(r, g, b))
        })
        .collect()
}

fn hue(r: f64, g: f64, b: f64) -> f64 {
    let (max, min) = (r.max(g).max(b), r.min(g).min(b));
    if max - min < 1e-9 {
        return 0.0;
    }
    let h = if max == r {
        ((g - b) / (max - min)).rem_euclid(6.0)
    } else if max == g {
        (b - r) / (max - min) + 2.0
    } else {
        (r - g) / (max - min) + 4.0
    };
    h / 6.0
}

fn std_dev(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = values.clone().count().max(1) as f64;
    let mean = values.clone().sum::<f64>() / n;
    (values.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt()
}

/// Mean luminance of the blade pixels in the bottom and the top quarter of the rows blades cover.
fn bottom_and_top_quarters(pixels: &[(u32, f64, f64)]) -> (f64, f64) {
    let top = pixels.iter().map(|p| p.0).min().unwrap() as f64;
    let bottom = pixels.iter().map(|p| p.0).max().unwrap() as f64;
    let quarter = (bottom - top) / 4.0;
    let mean = |keep: &dyn Fn(f64) -> bool| {
        let l: Vec<f64> = pixels.iter().filter(|p| keep(p.0 as f64)).map(|p| p.1).collect();
        l.iter().sum::<f64>() / l.len().max(1) as f64
    };
    (mean(&|y| y >= bottom - quarter), mean(&|y| y <= top + quarter))
}

#[test]
fn blade_colours_vary_between_blades_and_clumps() {
    let flat = blade_pixels(&render(BladeShading::FLAT, FRONT, "flat_front"));
    let shaded = blade_pixels(&render(BladeShading::default(), FRONT, "front"));
    assert!(flat.len() > 3000 && shaded.len() > 3000, "{} flat and {} shaded blade pixels", flat.len(), shaded.len());
    let spread = |p: &[(u32, f64, f64)]| std_dev(p.iter().map(|q| q.2));
    let (before, after) = (spread(&flat), spread(&shaded));
    println!("hue spread of blade pixels: flat {before:.5}, shaded {after:.5}");
    assert!(after >= 0.007 && after >= 10.0 * before, "hue spread: flat {before:.5}, shaded {after:.5}");
    // Still grass: every shaded blade pixel is green-dominant.
    let not_green = shaded.iter().filter(|p| !(0.12..0.40).contains(&p.2)).count();
    assert!(not_green * 100 <= shaded.len(), "{not_green} of {} blade pixels are not green", shaded.len());
}

#[test]
fn blades_darken_towards_the_root() {
    let flat = blade_pixels(&render(BladeShading::FLAT, FRONT, "flat_front_rows"));
    let shaded = blade_pixels(&render(BladeShading::default(), FRONT, "front_rows"));
    let (fb, ft) = bottom_and_top_quarters(&flat);
    let (sb, st) = bottom_and_top_quarters(&shaded);
    println!("bottom/top quarter luminance: flat {fb:.3}/{ft:.3}, shaded {sb:.3}/{st:.3}");
    assert!(sb <= 0.8 * st, "shaded: bottom quarter {sb:.3} against top quarter {st:.3}");
}

#[test]
fn back_lit_blades_differ_from_front_lit_ones() {
    let mean_abs_diff = |a: &RgbaImage, b: &RgbaImage| {
        let sum: u64 =
            a.pixels().zip(b.pixels()).map(|(p, q)| (0..3).map(|c| p[c].abs_diff(q[c]) as u64).sum::<u64>()).sum();
        sum as f64 / (3 * SIZE * SIZE) as f64
    };
    // Two-sided Lambert takes |n·l|, which the half turn leaves as it is: the same picture.
    let flat = mean_abs_diff(&render(BladeShading::FLAT, FRONT, "flat_f"), &render(BladeShading::FLAT, BACK, "flat_b"));
    let front = render(BladeShading::default(), FRONT, "front_lit");
    let back = render(BladeShading::default(), BACK, "back_lit");
    let shaded = mean_abs_diff(&front, &back);
    println!("mean |front − back| per channel: flat {flat:.3}, shaded {shaded:.3} (of 255)");
    assert!(shaded > 2.0 && shaded > 4.0 * flat, "front- and back-lit: flat {flat:.3}, shaded {shaded:.3}");
    // Lit from behind, the light comes through the blades: their tips glow, so the back-lit
    // picture's top quarter is not the dark unlit side of a front-lit blade.
    let (_, back_top) = bottom_and_top_quarters(&blade_pixels(&back));
    let unlit = BladeShading { translucency: 0.0, ..BladeShading::default() };
    let (_, opaque_top) = bottom_and_top_quarters(&blade_pixels(&render(unlit, BACK, "back_lit_opaque")));
    assert!(back_top > 1.2 * opaque_top, "back-lit tips: translucent {back_top:.3}, opaque {opaque_top:.3}");
}

#[test]
fn out_of_range_shading_is_refused_by_name() {
    let queue = &gpu().queue;
    let mut checked = 0;
    for (bad, name) in [
        (BladeShading { root_occlusion: 1.5, ..BladeShading::default() }, "root_occlusion"),
        (BladeShading { gloss_exponent: 0.0, ..BladeShading::default() }, "gloss_exponent"),
        (BladeShading { tip_color: [f32::NAN, 0.0, 0.0], ..BladeShading::default() }, "tip_color"),
        (BladeShading { translucency: -0.1, ..BladeShading::default() }, "translucency"),
    ] {
        let settings = BladeRenderSettings { shading: bad, ..BladeRenderSettings::default() };
        let err = BladeRenderer::new(
            gpu().pipelines(),
            queue,
            common::default_blade_patch(),
            common::default_blade_table(),
            &settings,
            &RenderTarget::desc(),
        )
        .err()
        .expect("refused");
        assert!(err.to_string().contains(name), "{name}: {err}");
        checked += 1;
    }
    assert_eq!(checked, 4);
}

#[test]
fn the_ground_under_the_blades_takes_the_grass_colour() {
    use furbake_bake::{BakeSettings, NoProgress, bake};
    use furbake_import::{ImportSettings, import_gltf_slice};
    // The thesis's grass patch (white vertex colours) baked with shells and blades, previewed
    // alone: the gaps between blades show the ground, which is drawn in the blades' colour.
    let mesh = furbake_import::testmesh::grass_patch(2.0);
    let imported = import_gltf_slice(&mesh.gltf, "patch.gltf", None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("grass").unwrap();
    settings.volume.resolution = 16;
    settings = settings.with_overrides(&serde_json::json!({"blades": {"field": {"density_per_m2": 100.0}}})).unwrap();
    let baked = bake(&imported, "patch.gltf", &settings.plan().unwrap(), &mut NoProgress).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("patch.fbk");
    baked.to_writer().write_atomic(&path).unwrap();
    let pack = furbake_runtime::Pack::open(&path).unwrap();
    let image =
        furbake_render::headless::render_pack(&pack, 160, 120, None, &furbake_render::RenderSettings::default())
            .unwrap();
    image.save(std::env::temp_dir().join("furbake-render-tests").join("blade_shading_ground.png")).unwrap();
    let bg = *image.get_pixel(0, 0);
    let drawn: Vec<_> = image.pixels().filter(|p| p.0.iter().zip(bg.0).any(|(a, b)| a.abs_diff(b) > 12)).collect();
    let green = drawn.iter().filter(|p| p[1] > p[0] && p[1] > p[2]).count();
    println!("{green} of {} drawn pixels green", drawn.len());
    assert!(drawn.len() > 2000, "the patch is drawn: {} pixels", drawn.len());
    assert!(green * 100 >= drawn.len() * 98, "grey ground shows: {green} of {} drawn pixels green", drawn.len());
}

/// The drawn outline is the blade's: a row of upright blades at rest, seen face-on from far away
/// (so no blade is thickened edge-on and none overlaps another), covers as many pixels as the
/// exact projected area of their posed quad strips (read back from the same pose pass, each
/// quad's projection measured with the shoelace formula) within 2 %.
#[test]
fn blade_coverage_is_the_outline_area() {
    let (device, queue) = (&gpu().device, &gpu().queue);
    let mut field = common::default_blade_patch().clone();
    let n = 6;
    field.positions.truncate(n);
    field.yaw_rad.truncate(n);
    field.height_scale.truncate(n);
    field.cluster.truncate(n);
    field.weights.truncate(n);
    for i in 0..n {
        field.positions[i] = [-0.5 + 0.2 * i as f32, 0.0, 0.0];
        field.yaw_rad[i] = 0.0;
        field.height_scale[i] = 1.0;
    }
    let size = 256u32;
    let settings =
        BladeRenderSettings { culling: furbake_render::GrassCulling::frustum_only(), ..BladeRenderSettings::default() };
    let blades = BladeRenderer::new(
        gpu().pipelines(),
        queue,
        &field,
        common::default_blade_table(),
        &settings,
        &RenderTarget::desc(),
    )
    .unwrap();
    let mut forces = ForceField::new(field.grid);
    forces.update(&ForceScene::default());
    blades.set_force_field(queue, &forces).unwrap();
    blades.compute(device, queue).unwrap();
    let positions = blades.read_positions(device, queue).unwrap();
    let vertices = positions.len() / n;
    // Face-on: the blade normal of yaw 0, from 12 m with a narrow field of view.
    let top = positions.iter().map(|p| p[1]).fold(0.0f32, f32::max);
    let normal = glam::Vec3::from(blade_normal_at_yaw_zero(&positions[..vertices]));
    let centre = glam::Vec3::new(0.0, 0.5 * top, 0.0);
    let view = View {
        camera: Camera {
            eye: (centre + normal * 12.0).to_array(),
            target: centre.to_array(),
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 6.0,
        },
        lighting: Light::default().into(),
        bounds_center: centre.to_array(),
        bounds_radius: 1.0,
    };
    let target = RenderTarget::new(device, size, size).unwrap();
    blades.render_to(device, queue, &target, &view, Some([0.0, 0.0, 0.0, 0.0])).unwrap();
    let image = read_back(device, queue, &target).unwrap();
    let drawn = image.pixels().filter(|p| p[3] > 0).count() as f64;
    // The projected area of every quad (left-bottom, right-bottom, left-top, right-top), pixels.
    let view_proj = view.view_proj(1.0);
    let pixel = |p: [f32; 3]| {
        let c = view_proj * glam::Vec3::from(p).extend(1.0);
        let ndc = c.truncate() / c.w;
        glam::DVec2::new((ndc.x as f64 + 1.0) * 0.5 * size as f64, (1.0 - ndc.y as f64) * 0.5 * size as f64)
    };
    let mut area = 0.0;
    for blade in positions.chunks_exact(vertices) {
        for quad in blade.chunks_exact(4) {
            let [a, b, c, d] = [quad[0], quad[1], quad[3], quad[2]].map(pixel);
            let ring = [a, b, c, d];
            let twice: f64 = (0..4).map(|k| ring[k].perp_dot(ring[(k + 1) % 4])).sum();
            area += twice.abs() * 0.5;
        }
    }
    let error = (drawn - area).abs() / area;
    println!("{drawn} pixels drawn, outline area {area:.1} pixels: {:.2} %", error * 100.0);
    assert!(area > 2000.0, "the blades are big enough to measure: {area:.0} pixels");
    assert!(error < 0.02, "coverage {drawn} pixels against the outline's {area:.1} ({:.2} %)", error * 100.0);
}

/// The unit normal of a blade's first quad (its face), turned towards +z.
fn blade_normal_at_yaw_zero(vertices: &[[f32; 3]]) -> [f32; 3] {
    let [a, b, c] = [vertices[0], vertices[1], vertices[2]].map(glam::Vec3::from);
    let n = (b - a).cross(c - a).normalize();
    (if n.z < 0.0 { -n } else { n }).to_array()
}
