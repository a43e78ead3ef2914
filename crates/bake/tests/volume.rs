//! Tests of the hair volume stage (fur thesis §3.1, eq. 3.1–3.2, fig. 3.5–3.8; §3.2 shadow table):
//! parameter validation, determinism, thread-count independence, tileability, the hair curve,
//! coverage and undercoat behaviour, the shadow table, and the fin atlas.

use furbake_bake::volume::{
    CoatKind, CurveShape, GrowthDirection, HairSet, MAX_VOXELS, VolumeError, bake_volume, compose_fin_atlas,
    fin_row_height, fur_preset, grass_preset, grow_hairs, hair_centre, layer_height, shadow_table, slice_shell_atlas,
    validate_volume_params,
};
use furbake_formats::Section;
use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::shell_atlas::{ShellAtlas, VolumeParams};
use glam::Vec2;

const SEED: u64 = 0x5EED_F00D;

/// A hair set holding exactly one hair, for geometric tests.
fn one_hair(
    res: u32,
    root: Vec2,
    length: f32,
    bend: f32,
    dir: GrowthDirection,
    radius: f32,
    shape: CurveShape,
) -> HairSet {
    HairSet {
        resolution: res,
        shapes: [shape, shape],
        root_x: vec![root.x],
        root_y: vec![root.y],
        length: vec![length],
        bend: vec![bend],
        direction: vec![dir],
        radius_texels: vec![radius],
        coat: vec![CoatKind::Coat],
    }
}

const STRAIGHT: CurveShape = CurveShape { max_deviation_texels: 0.0, curvature_exponent: 2.0, taper: 0.0 };

fn small_params(res: u32, layers: u32) -> VolumeParams {
    VolumeParams { resolution: res, layers, ..fur_preset() }
}

fn alpha_at(atlas: &ShellAtlas, layer: usize, x: usize, y: usize) -> u8 {
    atlas.layer(layer)[y * atlas.params.resolution as usize + x]
}

// ------------------------------------------------------------------------------------------
// Validation
// ------------------------------------------------------------------------------------------

#[test]
fn presets_are_valid() {
    for p in [fur_preset(), grass_preset()] {
        validate_volume_params(&p).unwrap();
    }
    let fur = fur_preset();
    assert_eq!((fur.layers, fur.resolution, fur.fin_slices), (16, 128, 20));
    let under = fur.undercoat.as_ref().expect("fur preset has an undercoat");
    assert!(under.density > fur.coat.density && under.length_max < fur.coat.length_max, "undercoat: denser, shorter");
    let grass = grass_preset();
    assert_eq!((grass.layers, grass.resolution, grass.fin_slices), (64, 64, 20));
    assert!(grass.undercoat.is_none());
    assert!(grass.coat.max_deviation_texels > fur.coat.max_deviation_texels);
}

#[test]
fn every_out_of_range_parameter_is_named() {
    type Mutation = (&'static str, fn(&mut VolumeParams));
    let cases: &[Mutation] = &[
        ("layers", |p| p.layers = 0),
        ("layers", |p| p.layers = 1025),
        ("resolution", |p| p.resolution = 3),
        ("resolution", |p| p.resolution = 8193),
        ("coat.density", |p| p.coat.density = 0.0),
        ("coat.density", |p| p.coat.density = 1.5),
        ("coat.density", |p| p.coat.density = f32::NAN),
        ("coat.length_max", |p| p.coat.length_max = 1.01),
        ("coat.length_max", |p| p.coat.length_max = f32::INFINITY),
        ("coat.length_min", |p| p.coat.length_min = 0.0),
        ("coat.length_min", |p| p.coat.length_min = p.coat.length_max + 0.01),
        ("coat.max_deviation_texels", |p| p.coat.max_deviation_texels = -1.0),
        ("coat.max_deviation_texels", |p| p.coat.max_deviation_texels = f32::INFINITY),
        ("coat.curvature_exponent", |p| p.coat.curvature_exponent = 0.0),
        ("coat.curvature_exponent", |p| p.coat.curvature_exponent = f32::NAN),
        ("coat.radius_texels", |p| p.coat.radius_texels = 0.0),
        ("coat.radius_texels", |p| p.coat.radius_texels = 65.0),
        ("coat.taper", |p| p.coat.taper = -0.1),
        ("coat.taper", |p| p.coat.taper = 1.1),
        ("undercoat.density", |p| p.undercoat.as_mut().unwrap().density = -0.2),
        ("undercoat.length_min", |p| p.undercoat.as_mut().unwrap().length_min = 0.9),
        ("undercoat.taper", |p| p.undercoat.as_mut().unwrap().taper = f32::NAN),
        ("shadow_min", |p| p.shadow_min = 0.0),
        ("shadow_min", |p| p.shadow_min = 1.2),
        ("shadow_exponent", |p| p.shadow_exponent = 0.0),
        ("shadow_exponent", |p| p.shadow_exponent = f32::NEG_INFINITY),
        ("fin_slices", |p| p.fin_slices = 0),
        ("fin_slices", |p| p.fin_slices = 1025),
        ("fin_height", |p| p.fin_height = 0),
        ("fin_height", |p| p.fin_height = 8193),
    ];
    let mut checked = 0;
    for (field, mutate) in cases {
        let mut p = fur_preset();
        mutate(&mut p);
        match validate_volume_params(&p) {
            Err(VolumeError::Parameter { field: f, allowed, .. }) => {
                assert_eq!(f, *field);
                assert!(!allowed.is_empty());
                checked += 1;
            }
            other => panic!("{field}: expected a parameter error, got {other:?}"),
        }
        // The whole stage refuses the same parameters.
        assert!(bake_volume(&p, SEED, 0.02).is_err(), "{field}");
    }
    assert_eq!(checked, cases.len());
    assert_eq!(checked, 30);
}

#[test]
fn error_messages_state_the_allowed_range() {
    let mut p = fur_preset();
    p.coat.density = 2.0;
    let msg = validate_volume_params(&p).unwrap_err().to_string();
    assert!(msg.contains("coat.density") && msg.contains("(0, 1]") && msg.contains('2'), "{msg}");
}

#[test]
fn oversized_volume_is_a_limit_error() {
    let p = VolumeParams { layers: 1024, resolution: 8192, ..fur_preset() };
    match validate_volume_params(&p) {
        Err(VolumeError::TooManyVoxels { voxels, limit, .. }) => {
            assert_eq!(voxels, 1024 * 8192 * 8192);
            assert_eq!(limit, MAX_VOXELS);
        }
        other => panic!("expected a limit error, got {other:?}"),
    }
    // Exactly at the limit is accepted: 16 × 4096² = 2^28.
    validate_volume_params(&VolumeParams { layers: 16, resolution: 4096, ..fur_preset() }).unwrap();
}

#[test]
fn bad_fur_length_is_refused() {
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        match bake_volume(&small_params(16, 4), SEED, bad) {
            Err(VolumeError::Parameter { field, .. }) => assert_eq!(field, "fur_length_m"),
            other => panic!("fur length {bad}: {other:?}"),
        }
    }
}

// ------------------------------------------------------------------------------------------
// Hairs and eq. 3.2
// ------------------------------------------------------------------------------------------

#[test]
fn hair_centre_follows_eq_3_2() {
    let root = Vec2::new(10.25, 20.5);
    let (dmax, n) = (7.0f32, 2.0f32);
    let mut checked = 0;
    for dir in GrowthDirection::ALL {
        for i in 0..=10 {
            let h = i as f32 / 10.0;
            let full = hair_centre(root, dir, dmax, n, 1.0, h);
            let expected = root + dir.unit() * dmax * h.powf(n);
            assert!((full - expected).length() < 1e-5, "{dir:?} h={h}: {full} vs {expected}");
            // w1 = 0 is a straight stem, w1 = 0.5 half the deviation.
            assert_eq!(hair_centre(root, dir, dmax, n, 0.0, h), root);
            let half = hair_centre(root, dir, dmax, n, 0.5, h);
            assert!(((half - root).length() - 0.5 * dmax * h * h).abs() < 1e-5);
            checked += 1;
        }
    }
    assert_eq!(checked, 44);
    // The top of the volume (h = hmax = 1) deviates by exactly dmax.
    assert_eq!(hair_centre(root, GrowthDirection::PosX, dmax, 3.0, 1.0, 1.0), root + Vec2::new(dmax, 0.0));
    // The four directions are distinct unit vectors.
    let units: Vec<Vec2> = GrowthDirection::ALL.iter().map(|d| d.unit()).collect();
    assert_eq!(units, [Vec2::X, Vec2::Y, Vec2::NEG_X, Vec2::NEG_Y]);
}

#[test]
fn shell_slices_place_the_hair_where_eq_3_2_says() {
    // One fully bent hair (w1 = 1) bending +x by dmax = 24 texels; in every layer the brightest
    // texel must hold the analytic centre.
    let res = 64u32;
    let p = small_params(res, 8);
    let shape = CurveShape { max_deviation_texels: 24.0, curvature_exponent: 2.0, taper: 0.0 };
    let hairs = one_hair(res, Vec2::new(20.5, 30.5), 1.0, 1.0, GrowthDirection::PosX, 1.0, shape);
    let atlas = slice_shell_atlas(&p, &hairs, SEED, 0.02);
    for i in 0..8 {
        let h = layer_height(i, 8);
        let c = hairs.centre(0, h);
        assert!((c.x - (20.5 + 24.0 * h * h)).abs() < 1e-4);
        let layer = atlas.layer(i as usize);
        let (best, _) = layer.iter().enumerate().max_by_key(|&(j, &a)| (a, usize::MAX - j)).unwrap();
        let (bx, by) = (best % res as usize, best / res as usize);
        assert_eq!((bx, by), (c.x.floor() as usize, c.y.floor() as usize), "layer {i}, centre {c}");
        assert!(layer[best] >= 200, "the centre texel is (nearly) fully covered");
    }
}

#[test]
fn hair_stops_at_its_length() {
    let res = 32u32;
    let p = small_params(res, 16);
    let hairs = one_hair(res, Vec2::new(8.5, 8.5), 0.5, 0.0, GrowthDirection::PosY, 1.0, STRAIGHT);
    let atlas = slice_shell_atlas(&p, &hairs, SEED, 0.02);
    for i in 0..16 {
        let present = alpha_at(&atlas, i, 8, 8) > 0;
        assert_eq!(present, layer_height(i as u32, 16) <= 0.5, "layer {i}");
    }
    assert_eq!(atlas.coverage.iter().filter(|&&c| c > 0.0).count(), 8);
}

#[test]
fn taper_shrinks_the_hair_towards_its_tip() {
    let shape = CurveShape { taper: 0.75, ..STRAIGHT };
    let hairs = one_hair(32, Vec2::splat(16.0), 0.8, 0.0, GrowthDirection::PosX, 2.0, shape);
    assert_eq!(hairs.radius_at(0, 0.0), 2.0);
    assert!((hairs.radius_at(0, 0.4) - 2.0 * (1.0 - 0.75 * 0.5)).abs() < 1e-6);
    assert!((hairs.radius_at(0, 0.8) - 0.5).abs() < 1e-6);
    let atlas = slice_shell_atlas(&small_params(32, 8), &hairs, SEED, 0.02);
    let texels: Vec<usize> = (0..8).map(|i| atlas.layer(i).iter().filter(|&&a| a > 0).count()).collect();
    assert!(texels[0] > texels[5] && texels[5] > 0, "{texels:?}");
    assert!(texels.windows(2).all(|w| w[0] >= w[1]), "{texels:?}");
}

#[test]
fn grown_hairs_follow_their_coat() {
    let p = fur_preset();
    let hairs = grow_hairs(&p, SEED);
    let res = p.resolution as f32;
    let texels = (p.resolution as f64).powi(2);
    let mut checked = 0;
    for (kind, coat) in [(CoatKind::Coat, &p.coat), (CoatKind::Undercoat, p.undercoat.as_ref().unwrap())] {
        // Bernoulli(density) per texel: the count is within 5 standard deviations of the mean.
        let (mean, sd) = (texels * coat.density as f64, (texels * (coat.density * (1.0 - coat.density)) as f64).sqrt());
        let n = hairs.count(kind) as f64;
        assert!((n - mean).abs() < 5.0 * sd, "{kind:?}: {n} roots, expected {mean} ± {sd}");
        let mut dirs = [0usize; 4];
        for i in (0..hairs.len()).filter(|&i| hairs.coat[i] == kind) {
            assert!((0.0..res).contains(&hairs.root_x[i]) && (0.0..res).contains(&hairs.root_y[i]));
            assert!((coat.length_min..=coat.length_max).contains(&hairs.length[i]));
            assert!((0.0..1.0).contains(&hairs.bend[i]));
            assert_eq!(hairs.radius_texels[i], coat.radius_texels);
            dirs[hairs.direction[i] as usize] += 1;
            checked += 1;
        }
        // Each of the four directions is drawn about a quarter of the time.
        for d in dirs {
            assert!((d as f64 - n / 4.0).abs() < 5.0 * (n * 0.1875).sqrt(), "{kind:?} directions {dirs:?}");
        }
    }
    assert_eq!(checked, hairs.len());
    assert!(checked > 5000);
}

#[test]
fn undercoat_stream_leaves_the_coat_untouched() {
    let with = grow_hairs(&fur_preset(), SEED);
    let without = grow_hairs(&VolumeParams { undercoat: None, ..fur_preset() }, SEED);
    let n = without.len();
    assert_eq!(without.count(CoatKind::Undercoat), 0);
    assert_eq!(with.count(CoatKind::Coat), n);
    assert_eq!(with.root_x[..n], without.root_x[..]);
    assert_eq!(with.length[..n], without.length[..]);
    assert_eq!(with.bend[..n], without.bend[..]);
    assert_eq!(with.direction[..n], without.direction[..]);
}

// ------------------------------------------------------------------------------------------
// Determinism and threads
// ------------------------------------------------------------------------------------------

#[test]
fn same_seed_same_bytes_different_seed_different_bytes() {
    let p = fur_preset();
    let (s1, f1) = bake_volume(&p, SEED, 0.02).unwrap();
    let (s2, f2) = bake_volume(&p, SEED, 0.02).unwrap();
    assert_eq!(s1.encode(), s2.encode());
    assert_eq!(f1.encode(), f2.encode());
    let (s3, f3) = bake_volume(&p, SEED + 1, 0.02).unwrap();
    let differing = s1.alpha.iter().zip(&s3.alpha).filter(|(a, b)| a != b).count();
    assert!(differing > s1.alpha.len() / 10, "only {differing} texels differ");
    assert_ne!(f1.alpha, f3.alpha);
}

#[test]
fn output_is_independent_of_thread_count() {
    let mut checked = 0;
    for p in [fur_preset(), VolumeParams { resolution: 48, layers: 24, ..grass_preset() }] {
        let bake_in = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
            pool.install(|| bake_volume(&p, SEED, 0.02).unwrap())
        };
        let (s1, f1) = bake_in(1);
        let (s4, f4) = bake_in(4);
        assert_eq!(s1.encode(), s4.encode());
        assert_eq!(f1.encode(), f4.encode());
        checked += 1;
    }
    assert_eq!(checked, 2);
}

#[test]
fn atlases_round_trip_through_the_container_sections() {
    let (shells, fins) = bake_volume(&fur_preset(), SEED, 0.02).unwrap();
    assert_eq!(ShellAtlas::decode(&shells.encode()).unwrap(), shells);
    assert_eq!(FinAtlas::decode(&fins.encode()).unwrap(), fins);
    assert_eq!(shells.alpha.len(), 16 * 128 * 128);
    assert_eq!(fins.alpha.len(), 128 * 64);
}

// ------------------------------------------------------------------------------------------
// Tileability
// ------------------------------------------------------------------------------------------

#[test]
fn hair_on_the_border_wraps_to_the_other_side() {
    let res = 32usize;
    let p = small_params(res as u32, 4);
    // Centre on the last texel column and row: x = y = res − 0.5, radius 1.
    let hairs = one_hair(res as u32, Vec2::splat(res as f32 - 0.5), 1.0, 0.0, GrowthDirection::PosX, 1.0, STRAIGHT);
    let atlas = slice_shell_atlas(&p, &hairs, SEED, 0.02);
    let last = res - 1;
    assert_eq!(alpha_at(&atlas, 0, last, last), 255);
    // One texel away in either direction across the border sees the same edge coverage.
    let inside = alpha_at(&atlas, 0, last - 1, last);
    assert!(inside > 0 && inside < 255, "edge texel {inside}");
    assert_eq!(alpha_at(&atlas, 0, 0, last), inside, "x wraps");
    assert_eq!(alpha_at(&atlas, 0, last, 0), inside, "y wraps");
    assert_eq!(alpha_at(&atlas, 0, 0, 0), alpha_at(&atlas, 0, last - 1, last - 1), "corner wraps");
    // Nothing far from the corner.
    assert_eq!(alpha_at(&atlas, 0, res / 2, res / 2), 0);
}

#[test]
fn disc_wider_than_half_the_tile_uses_the_nearest_image() {
    // radius = res/2 (the largest allowed): the disc's bounding box covers the whole tile, so
    // each texel must take its distance to the nearest copy of the centre on the torus.
    let res = 8usize;
    let p = small_params(res as u32, 1);
    let hairs = one_hair(res as u32, Vec2::splat(0.5), 1.0, 0.0, GrowthDirection::PosX, 4.0, STRAIGHT);
    let atlas = slice_shell_atlas(&p, &hairs, SEED, 0.02);
    let expected = |x: usize, y: usize| {
        let d = |t: usize| (t as f32).min((res - t) as f32); // distance from centre 0.5 to t + 0.5
        let dist = (d(x).powi(2) + d(y).powi(2)).sqrt();
        ((4.5 - dist).clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    };
    let mut checked = 0;
    for y in 0..res {
        for x in 0..res {
            assert_eq!(alpha_at(&atlas, 0, x, y), expected(x, y), "({x},{y})");
            checked += 1;
        }
    }
    assert_eq!(checked, 64);
    assert_eq!(alpha_at(&atlas, 0, 4, 0), 128, "exactly between two images");
    assert_eq!(alpha_at(&atlas, 0, 7, 0), 255);
}

#[test]
fn bent_hair_crossing_the_border_continues_on_the_other_side() {
    // Root near the right border, bending +x by 20 texels: the upper layers find it on the left.
    let res = 32u32;
    let p = small_params(res, 8);
    let shape = CurveShape { max_deviation_texels: 20.0, curvature_exponent: 1.0, taper: 0.0 };
    let hairs = one_hair(res, Vec2::new(28.5, 10.5), 1.0, 1.0, GrowthDirection::PosX, 1.0, shape);
    let atlas = slice_shell_atlas(&p, &hairs, SEED, 0.02);
    let top = layer_height(7, 8);
    let x = (28.5 + 20.0 * top).rem_euclid(32.0);
    assert!(x < 16.0, "the test needs the hair to wrap");
    assert!(alpha_at(&atlas, 7, x as usize, 10) >= 200);
    assert_eq!(atlas.layer(7).iter().filter(|&&a| a > 0).count(), atlas.layer(0).iter().filter(|&&a| a > 0).count());
}

#[test]
fn shifting_every_root_rolls_the_texture_without_a_seam() {
    // On a torus, translating all roots by (dx, dy) must translate every layer by the same amount;
    // a seam at the border would break this. ±1 per texel: the shifted centres round differently.
    let p = fur_preset();
    let res = p.resolution as usize;
    let hairs = grow_hairs(&p, SEED);
    let (sx, sy) = (37usize, 90usize);
    let mut shifted = hairs.clone();
    for i in 0..shifted.len() {
        shifted.root_x[i] = (shifted.root_x[i] + sx as f32).rem_euclid(res as f32);
        shifted.root_y[i] = (shifted.root_y[i] + sy as f32).rem_euclid(res as f32);
    }
    let a = slice_shell_atlas(&p, &hairs, SEED, 0.02);
    let b = slice_shell_atlas(&p, &shifted, SEED, 0.02);
    let mut checked = 0;
    for layer in 0..p.layers as usize {
        for y in 0..res {
            for x in 0..res {
                let va = alpha_at(&a, layer, x, y);
                let vb = alpha_at(&b, layer, (x + sx) % res, (y + sy) % res);
                assert!(va.abs_diff(vb) <= 1, "layer {layer} ({x},{y}): {va} vs {vb}");
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 16 * 128 * 128);
}

// ------------------------------------------------------------------------------------------
// Coverage, undercoat, shadow
// ------------------------------------------------------------------------------------------

#[test]
fn fur_coverage_thins_towards_the_top() {
    let (atlas, _) = bake_volume(&fur_preset(), SEED, 0.02).unwrap();
    let c = &atlas.coverage;
    assert_eq!(c.len(), 16);
    // Hairs only end and taper going up; max-blending makes coverage non-increasing except
    // where bending moves overlapping hairs apart, a small effect (allow 1% of the texels).
    for (i, w) in c.windows(2).enumerate() {
        assert!(w[1] <= w[0] + 0.01, "layer {} coverage {} > layer {} coverage {}", i + 1, w[1], i, w[0]);
    }
    assert!(c[0] > 0.5, "dense bottom: {c:?}");
    assert!(c[15] < 0.5 * c[0], "sparse top: {c:?}");
    assert!(c[15] > 0.0, "the longest hairs reach the top layer");
    // Coverage is the recorded fraction of non-zero texels.
    let zero_free = atlas.layer(3).iter().filter(|&&a| a > 0).count() as f32 / (128.0 * 128.0);
    assert_eq!(c[3], zero_free);
}

#[test]
fn undercoat_adds_hair_at_the_bottom_only() {
    let with_p = fur_preset();
    let without_p = VolumeParams { undercoat: None, ..fur_preset() };
    let (with, _) = bake_volume(&with_p, SEED, 0.02).unwrap();
    let (without, _) = bake_volume(&without_p, SEED, 0.02).unwrap();
    assert!(with.coverage[0] > without.coverage[0] + 0.2, "{} vs {}", with.coverage[0], without.coverage[0]);
    // The undercoat only adds hairs: no texel loses alpha (the coat hairs are identical).
    assert!(with.alpha.iter().zip(&without.alpha).all(|(w, o)| w >= o));
    // Above the longest undercoat hair the layers are identical.
    let top_under = with_p.undercoat.as_ref().unwrap().length_max;
    let mut identical = 0;
    for i in 0..16 {
        if layer_height(i, 16) > top_under {
            assert_eq!(with.layer(i as usize), without.layer(i as usize), "layer {i}");
            identical += 1;
        }
    }
    assert_eq!(identical, 9);
}

#[test]
fn shadow_table_darkens_towards_the_skin() {
    let mut checked = 0;
    for (layers, min, exp) in [(16, 0.35, 1.0), (64, 0.25, 1.5), (5, 0.5, 0.5), (2, 0.1, 3.0)] {
        let t = shadow_table(layers, min, exp);
        assert_eq!(t.len(), layers as usize);
        assert_eq!(t[0], min, "innermost is darkest");
        assert_eq!(*t.last().unwrap(), 1.0, "outermost is unshadowed");
        assert!(t.windows(2).all(|w| w[0] < w[1]), "strictly increasing: {t:?}");
        checked += 1;
    }
    assert_eq!(shadow_table(1, 0.3, 1.0), [1.0]);
    let t = shadow_table(3, 0.2, 2.0);
    assert!((t[1] - (0.2 + 0.8 * 0.25)).abs() < 1e-6);
    assert_eq!(checked, 4);
    let (atlas, _) = bake_volume(&fur_preset(), SEED, 0.02).unwrap();
    assert_eq!(atlas.shadow, shadow_table(16, 0.35, 1.0));
}

// ------------------------------------------------------------------------------------------
// Fins
// ------------------------------------------------------------------------------------------

fn row_coverage(fin: &FinAtlas, row: usize) -> f32 {
    let w = fin.width as usize;
    fin.alpha[row * w..(row + 1) * w].iter().filter(|&&a| a > 0).count() as f32 / w as f32
}

#[test]
fn fins_hold_hair_and_more_slices_hold_more() {
    let p = fur_preset();
    let hairs = grow_hairs(&p, SEED);
    let one = compose_fin_atlas(&VolumeParams { fin_slices: 1, ..p.clone() }, &hairs);
    let twenty = compose_fin_atlas(&p, &hairs);
    assert_eq!((twenty.width, twenty.height, twenty.slices), (128, 64, 20));
    assert_eq!(one.slices, 1);
    assert!(one.coverage() > 0.0, "a single slice still cuts some hairs");
    assert!(twenty.coverage() > 2.0 * one.coverage(), "K=20 {} vs K=1 {}", twenty.coverage(), one.coverage());
    assert!(twenty.coverage() > 0.3, "fur fin coverage {}", twenty.coverage());
    // Row 0 is the tip: sparser than the skin row.
    let last = twenty.height as usize - 1;
    assert!(row_coverage(&twenty, last) > row_coverage(&twenty, 0) + 0.2);
    assert!(row_coverage(&twenty, 0) > 0.0, "the longest hairs reach the tip row");
}

#[test]
fn fin_slices_see_hairs_within_their_radius_of_the_plane() {
    // K = 4 planes on a 32-texel tile: y = 4, 12, 20, 28. A straight hair on plane 12 shows up as
    // a vertical strand at its x; one 8 texels from every plane (y = 16) does not.
    let res = 32u32;
    let p = VolumeParams { fin_slices: 4, fin_height: 16, ..small_params(res, 8) };
    let on = one_hair(res, Vec2::new(5.5, 12.0), 1.0, 0.0, GrowthDirection::PosX, 1.0, STRAIGHT);
    let fin = compose_fin_atlas(&p, &on);
    for row in 0..16 {
        assert_eq!(fin.alpha[row * 32 + 5], 255, "row {row}");
        assert_eq!(fin.alpha[row * 32 + 20], 0);
    }
    let off = one_hair(res, Vec2::new(5.5, 16.0), 1.0, 0.0, GrowthDirection::PosX, 1.0, STRAIGHT);
    assert!(compose_fin_atlas(&p, &off).alpha.iter().all(|&a| a == 0));
    // A short hair fills only the bottom rows (row 0 is the tip).
    let short = one_hair(res, Vec2::new(5.5, 12.0), 0.25, 0.0, GrowthDirection::PosX, 1.0, STRAIGHT);
    let fin = compose_fin_atlas(&p, &short);
    for row in 0..16 {
        assert_eq!(fin.alpha[row * 32 + 5] > 0, fin_row_height(row as u32, 16) <= 0.25, "row {row}");
    }
}

#[test]
fn fin_composite_is_alpha_over() {
    // Two half-covering slices stacked: 1 − (1 − a)² where one slice alone gives a.
    let res = 32u32;
    let p = VolumeParams { fin_slices: 2, fin_height: 4, ..small_params(res, 4) };
    // Plane 0 at y = 8, plane 1 at y = 24; a radius-1 hair 1.25 texels off each plane gives
    // a = clamp(1.5 − 1.25) = 0.25 at its centre column.
    let mk = |ys: &[f32]| HairSet {
        resolution: res,
        shapes: [STRAIGHT, STRAIGHT],
        root_x: vec![10.5; ys.len()],
        root_y: ys.to_vec(),
        length: vec![1.0; ys.len()],
        bend: vec![0.0; ys.len()],
        direction: vec![GrowthDirection::PosX; ys.len()],
        radius_texels: vec![1.0; ys.len()],
        coat: vec![CoatKind::Coat; ys.len()],
    };
    let single = compose_fin_atlas(&p, &mk(&[9.25]));
    let double = compose_fin_atlas(&p, &mk(&[9.25, 25.25]));
    let same_slice = compose_fin_atlas(&p, &mk(&[9.25, 6.75]));
    assert_eq!(single.alpha[10], 64, "0.25 × 255");
    assert_eq!(double.alpha[10], 112, "(1 − 0.75²) × 255 = 111.6");
    assert_eq!(same_slice.alpha[10], 64, "within one slice overlapping hairs take the max");
}

#[test]
fn fins_can_be_taller_than_the_volume_has_layers() {
    let p = VolumeParams { fin_height: 256, ..fur_preset() };
    let (shells, fins) = bake_volume(&p, SEED, 0.02).unwrap();
    assert_eq!(shells.layers(), 16);
    assert_eq!(fins.alpha.len(), 256 * 128);
    // Rows are sampled at their own heights: neighbouring rows differ (no 16-step staircase).
    let distinct_rows = (1..256).filter(|&r| fins.alpha[r * 128..(r + 1) * 128] != fins.alpha[(r - 1) * 128..r * 128]);
    assert!(distinct_rows.count() > 128);
}
