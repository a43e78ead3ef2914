//! How opaque a stack of shell layers should be (docs/design.md "Shell opacity"): for each view
//! angle, drawn layer count and mip level, the exponent e with which each layer blends
//! 1 − (1 − α)^e so that the stack lets through, on average over the surface, as much light as
//! the hair volume the atlas slices. Computed once per asset from the atlas alone, on the CPU.
//!
//! The volume is the atlas's slices extruded through their slabs (slice s fills heights
//! [s, s + 1)·L/A, texel by texel), crossed by a straight ray: the ray is stopped by what it meets,
//! and the cells it meets in one texel column in a row are one hair (their alphas combine by max,
//! not as independent layers). The stack is what the shell shader draws: N layers at heights
//! (i + 1)/N, each sampling its slice (`ShellAtlas::slice_for`) bilinearly at one mip level where
//! the ray crosses it, composited over each other. Along the hairs the stack counts one hair once
//! per layer and is too opaque (e < 1); seen across them, with layers far apart, it misses the hair
//! between the layers and is too clear (e > 1).

use furbake_formats::sections::shell_atlas::ShellAtlas;

/// View angles of the table: 0°, 10°, …, 80° between the ray and the hair direction.
pub const ANGLE_BINS: usize = 9;
/// Degrees between two angle bins.
pub const ANGLE_STEP_DEG: f32 = 10.0;
/// Drawn layer counts of the table: 1, 2, 4, …, 64.
pub const COUNT_BINS: usize = 7;
/// Mip levels of the table: 0 (the atlas) to 5 (1/32 of its resolution).
pub const MIP_BINS: usize = 6;
/// Entries of the table, `[(angle · MIP_BINS + mip) · COUNT_BINS + count]`.
pub const TABLE_LEN: usize = ANGLE_BINS * MIP_BINS * COUNT_BINS;

/// Rays per table entry: a grid of entry points (`RAY_GRID`²).
const RAY_GRID: usize = 24;
/// The exponent's range.
const E_MIN: f32 = 1.0 / 64.0;
const E_MAX: f32 = 64.0;

/// The stacking exponents of `atlas` for fur `length_texels` atlas texels long (fur length ×
/// resolution / metres per atlas repeat), `[(angle · MIP_BINS + mip) · COUNT_BINS + count]`.
/// Deterministic.
pub fn stacking_table(atlas: &ShellAtlas, length_texels: f32) -> Vec<f32> {
    let res = atlas.params.resolution.max(1) as usize;
    let layers = atlas.layers().max(1);
    // Mips per slice, as the GPU's (crate::mips::mip_chain), up to MIP_BINS levels.
    let mips: Vec<Vec<(usize, Vec<u8>)>> = (0..layers)
        .map(|s| {
            crate::mips::mip_chain(res as u32, res as u32, atlas.layer(s))
                .into_iter()
                .take(MIP_BINS)
                .map(|(w, _, t)| (w as usize, t))
                .collect()
        })
        .collect();
    let length = length_texels.max(1e-3);
    // One angle's rows (every mip level and count); the angles split over two threads.
    let rows = |angle: usize| -> Vec<f32> {
        let theta = (angle as f32 * ANGLE_STEP_DEG).to_radians();
        let rays = rays(res, theta);
        let volume: f64 = rays.iter().map(|r| volume_transmittance(atlas, res, length, r)).sum::<f64>();
        let target = volume / rays.len() as f64;
        let mut out = Vec::with_capacity(MIP_BINS * COUNT_BINS);
        let most = 1u32 << (COUNT_BINS - 1);
        let mut logs = vec![vec![0.0f64; rays.len()]; COUNT_BINS];
        for mip in 0..MIP_BINS {
            // Layer j of the most layers sits where layer (j + 1)·n/most − 1 of n does, with the
            // same slice: each count's stack is every (most/n)-th of those layers.
            for (k, r) in rays.iter().enumerate() {
                let per_layer = layer_logs(atlas, &mips, mip, res, length, most, r);
                for (count, l) in logs.iter_mut().enumerate() {
                    let stride = (most >> count) as usize;
                    l[k] = per_layer.iter().skip(stride - 1).step_by(stride).sum();
                }
            }
            out.extend(logs.iter().map(|l| solve_exponent(l, target)));
        }
        out
    };
    let mut table = Vec::with_capacity(TABLE_LEN);
    std::thread::scope(|s| {
        let odd = s.spawn(|| (1..ANGLE_BINS).step_by(2).map(|a| (a, rows(a))).collect::<Vec<_>>());
        let mut all: Vec<(usize, Vec<f32>)> = (0..ANGLE_BINS).step_by(2).map(|a| (a, rows(a))).collect();
        all.extend(odd.join().unwrap_or_default());
        all.sort_by_key(|(a, _)| *a);
        for (_, row) in all {
            table.extend(row);
        }
    });
    if table.len() != TABLE_LEN {
        // A panicking worker (never expected): blend as the layers are.
        return vec![1.0; TABLE_LEN];
    }
    table
}

/// The stacking exponents of a pack's shells: [`stacking_table`] for its `atlas`, whose fur
/// length the atlas records, laid over the surface at `repeat_m` metres per atlas repeat (the
/// triangle UV map's). About 0.15 s for the `fur` preset's 16 × 128² atlas in the dev profile.
pub fn shell_stacking_table(atlas: &ShellAtlas, repeat_m: f32) -> Vec<f32> {
    let res = atlas.params.resolution as f32;
    stacking_table(atlas, atlas.fur_length_m * res / repeat_m.max(1e-9))
}

/// One ray: where it enters the top of the coat (atlas texels) and its lateral travel per texel
/// of descent.
struct Ray {
    x: f32,
    y: f32,
    dx: f32,
    dy: f32,
}

/// A grid of entry points over the tile, each with its own azimuth (golden-angle sequence).
fn rays(res: usize, theta: f32) -> Vec<Ray> {
    let t = theta.tan();
    let cell = res as f32 / RAY_GRID as f32;
    (0..RAY_GRID * RAY_GRID)
        .map(|i| {
            let (gx, gy) = ((i % RAY_GRID) as f32, (i / RAY_GRID) as f32);
            let phi = i as f32 * 2.399_963;
            Ray { x: (gx + 0.5) * cell, y: (gy + 0.37) * cell, dx: t * phi.cos(), dy: t * phi.sin() }
        })
        .collect()
}

fn wrap(v: f32, res: usize) -> usize {
    (v.floor() as i64).rem_euclid(res as i64) as usize
}

/// The fraction of the ray's light that reaches the skin through the extruded slices.
fn volume_transmittance(atlas: &ShellAtlas, res: usize, length: f32, r: &Ray) -> f64 {
    let layers = atlas.layers();
    let slab = length / layers as f32;
    let lateral = (r.dx * r.dx + r.dy * r.dy).sqrt();
    // Steps of at most a quarter slab and half a texel sideways.
    let step = (slab * 0.25).min(if lateral > 1e-6 { 0.5 / lateral } else { f32::INFINITY });
    let steps = (length / step).ceil() as usize;
    let mut transmittance = 1.0f64;
    let (mut column, mut run_max) = (usize::MAX, 0u8);
    let mut last_cell = usize::MAX;
    for k in 0..steps {
        let depth = (k as f32 + 0.5) * length / steps as f32; // below the top
        let height = length - depth;
        let slice = ((height / slab) as usize).min(layers - 1);
        let (x, y) = (wrap(r.x + r.dx * depth, res), wrap(r.y + r.dy * depth, res));
        let texel = y * res + x;
        let cell = slice * res * res + texel;
        if cell == last_cell {
            continue;
        }
        last_cell = cell;
        let alpha = atlas.layer(slice)[texel];
        if texel != column {
            transmittance *= 1.0 - run_max as f64 / 255.0;
            (column, run_max) = (texel, 0);
        }
        run_max = run_max.max(alpha);
    }
    transmittance * (1.0 - run_max as f64 / 255.0)
}

/// ln(1 − α) of each of `n` layers at heights (i + 1)/n along the ray (−∞ where a layer is
/// opaque), each sampling its slice at mip `mip` bilinearly (repeat addressing, as the shader's
/// sampler).
fn layer_logs(
    atlas: &ShellAtlas,
    mips: &[Vec<(usize, Vec<u8>)>],
    mip: usize,
    res: usize,
    length: f32,
    n: u32,
    r: &Ray,
) -> Vec<f64> {
    let mut logs = Vec::with_capacity(n as usize);
    for i in 0..n {
        let height = (i + 1) as f32 / n as f32 * length;
        let depth = length - height;
        let slice = atlas.slice_for(i, n);
        let levels = &mips[slice];
        let (w, texels) = &levels[mip.min(levels.len() - 1)];
        let scale = *w as f32 / res as f32;
        let alpha = bilinear(texels, *w, (r.x + r.dx * depth) * scale, (r.y + r.dy * depth) * scale);
        logs.push(if alpha >= 1.0 { f64::NEG_INFINITY } else { (1.0 - alpha as f64).ln() });
    }
    logs
}

fn bilinear(texels: &[u8], w: usize, x: f32, y: f32) -> f32 {
    let (fx, fy) = (x - 0.5, y - 0.5);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let at = |dx: f32, dy: f32| texels[wrap(y0 + dy, w) * w + wrap(x0 + dx, w)] as f32 / 255.0;
    let top = at(0.0, 0.0) * (1.0 - tx) + at(1.0, 0.0) * tx;
    let bottom = at(0.0, 1.0) * (1.0 - tx) + at(1.0, 1.0) * tx;
    top * (1.0 - ty) + bottom * ty
}

/// The e in [E_MIN, E_MAX] whose mean stack transmittance, mean(exp(e · log)), is `target`
/// (bisection in ln e; the mean falls as e grows).
fn solve_exponent(logs: &[f64], target: f64) -> f32 {
    let mean =
        |e: f64| logs.iter().map(|&l| if l.is_finite() { (e * l).exp() } else { 0.0 }).sum::<f64>() / logs.len() as f64;
    let (mut lo, mut hi) = ((E_MIN as f64).ln(), (E_MAX as f64).ln());
    if mean(lo.exp()) <= target {
        return E_MIN;
    }
    if mean(hi.exp()) >= target {
        return E_MAX;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if mean(mid.exp()) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi)).exp() as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use furbake_formats::sections::shell_atlas::VolumeParams;

    /// An atlas of `layers` slices of `res`² texels with vertical opaque hairs of one texel on a
    /// regular grid (every `spacing`-th texel), through every slice.
    fn columns(layers: u32, res: u32, spacing: usize) -> ShellAtlas {
        let mut params: VolumeParams = furbake_bake::volume::fur_preset();
        (params.layers, params.resolution) = (layers, res);
        let texels = (res * res) as usize;
        let mut alpha = vec![0u8; layers as usize * texels];
        for s in 0..layers as usize {
            for t in 0..texels {
                let (x, y) = (t % res as usize, t / res as usize);
                if x % spacing == 0 && y % spacing == 0 {
                    alpha[s * texels + t] = 255;
                }
            }
        }
        ShellAtlas {
            params,
            seed: 1,
            fur_length_m: 0.05,
            alpha,
            shadow: vec![1.0; layers as usize],
            coverage: vec![0.0; layers as usize],
        }
    }

    #[test]
    fn the_exponent_matches_the_mean_transmittance() {
        // Half the rays blocked at e = 1 by a layer of alpha 0.5 each: mean(0.5^e) = target.
        let logs = vec![(0.5f64).ln(); 10];
        let e = solve_exponent(&logs, 0.25);
        assert!((e - 2.0).abs() < 1e-3, "{e}");
        assert_eq!(solve_exponent(&[f64::NEG_INFINITY; 4], 0.5), E_MIN, "opaque stacks cannot reach it");
        assert_eq!(solve_exponent(&[0.0; 4], 0.5), E_MAX, "clear stacks cannot reach it");
    }

    #[test]
    fn opaque_vertical_hairs_need_no_correction_at_full_resolution() {
        // Opaque one-texel columns: along them (0°) every stack and the volume let through the
        // same uncovered share, whatever the count, so nothing solves away from 1 by much; at
        // 60° a single layer sees far less hair than the volume (which the ray crosses many
        // columns of): e > 1.
        let atlas = columns(16, 32, 4);
        let table = stacking_table(&atlas, 16.0);
        let at = |angle: usize, mip: usize, count: usize| table[(angle * MIP_BINS + mip) * COUNT_BINS + count];
        assert!(at(6, 0, 0) > 1.5, "one layer at 60°: {}", at(6, 0, 0));
        // Averaged over mips, stacks of one hair's column are too opaque along the hair: e < 1.
        assert!(at(0, 3, 4) < 0.5, "16 layers at 0°, mip 3: {}", at(0, 3, 4));
        assert!(table.iter().all(|e| e.is_finite() && (E_MIN..=E_MAX).contains(e)));
        assert_eq!(table, stacking_table(&atlas, 16.0), "deterministic");
    }
}

#[cfg(test)]
mod timing {
    // Ignored in `make test` on purpose: it asserts nothing (the table's properties are checked by
    // `tests` above; its cost is a measurement quoted in docs/performance.md "Shell opacity and
    // level of detail", not a timed test). Run with
    // `cargo test -p furbake-draw --lib -- --ignored --nocapture print_fur_preset_table`.
    #[test]
    #[ignore = "prints the table and its cost for the fur preset's atlas"]
    fn print_fur_preset_table() {
        let mut p = furbake_bake::volume::fur_preset();
        p.layers = 16;
        let hairs = furbake_bake::volume::grow_hairs(&p, 1);
        let atlas = furbake_bake::volume::slice_shell_atlas(&p, &hairs, 1, 0.05);
        let t = std::time::Instant::now();
        let table = super::stacking_table(&atlas, 32.0);
        eprintln!("{:?}", t.elapsed());
        for a in 0..super::ANGLE_BINS {
            for m in 0..super::MIP_BINS {
                let row: Vec<String> = (0..super::COUNT_BINS)
                    .map(|c| format!("{:.2}", table[(a * super::MIP_BINS + m) * super::COUNT_BINS + c]))
                    .collect();
                eprintln!("angle {} mip {m}: {}", a * 10, row.join(" "));
            }
        }
    }
}
