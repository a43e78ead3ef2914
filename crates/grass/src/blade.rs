//! The reference blade (grass thesis §4.1, fig. 4.1–4.2): two parallel cubic Bézier curves (the
//! blade's left and right edges) cut into `S` quads at equal arc length of the centre curve; `S`
//! is the level-of-detail parameter. Each segment is one quad with its own four vertices (left and
//! right at its bottom and top), which is how the thesis counts vertices in §3.3 (8 segments ⇒ 32
//! vertices) and in table 6.2 (`4S − 2` displaced vertices per blade). Front faces are two
//! triangles per quad; back faces reuse the same vertices with the winding reversed.
//!
//! Frame: unit = one blade length (arc length of the centre curve), `+y` along the blade, `+x`
//! across it, `+z` the blade normal; the root centre is the origin.

use glam::DVec3;

use crate::GrassError;

/// Shape of the reference blade. All lengths in blade lengths.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct BladeShape {
    /// Quads along the blade (level of detail), 1..=256. Default 8.
    pub segments: u32,
    /// Width at the root. Default 0.06.
    pub base_width: f32,
    /// Width at the tip (> 0 keeps the last quad non-degenerate). Default 0.01.
    pub tip_width: f32,
    /// Neutral lean of the tip towards `+z` (the blade normal). Default 0 (a straight blade); a
    /// non-zero curl breaks the z mirror symmetry, so `Symmetry::XZ` refuses it.
    pub curl: f32,
}

impl Default for BladeShape {
    fn default() -> Self {
        BladeShape { segments: 8, base_width: 0.06, tip_width: 0.01, curl: 0.0 }
    }
}

/// Largest segment count accepted.
pub const MAX_SEGMENTS: u32 = 256;

/// The reference blade: centre-line nodes (one per level) and the quad vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceBlade {
    /// Number of segments `S`.
    pub segments: u32,
    /// Centre-line node per level (`S + 1`, root first), in blade lengths.
    pub nodes: Vec<DVec3>,
    /// Blade width per level (`S + 1`).
    pub widths: Vec<f64>,
    /// Quad vertices, `4S`: segment `k` owns `4k..4k+4` = left-bottom, right-bottom, left-top, right-top.
    pub positions: Vec<[f32; 3]>,
    /// Texture coordinates (`u` 0 left … 1 right, `v` 0 root … 1 tip).
    pub uvs: Vec<[f32; 2]>,
    /// Front-face triangles (counter-clockwise seen from `+z`).
    pub triangles: Vec<[u32; 3]>,
}

impl ReferenceBlade {
    /// The level (centre-line node) vertex `v` sits on.
    pub fn level_of_vertex(v: usize) -> usize {
        v / 4 + (v % 4) / 2
    }

    /// Number of vertices (`4S`).
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }
}

fn bezier(p: [DVec3; 4], t: f64) -> DVec3 {
    let s = 1.0 - t;
    p[0] * (s * s * s) + p[1] * (3.0 * s * s * t) + p[2] * (3.0 * s * t * t) + p[3] * (t * t * t)
}

/// Builds the reference blade: the left and right edges are the cubic Béziers whose control points
/// are the centre curve's `C_k ∓ w_k/2 · x̂` (width controls `[base, base, mid, tip]`), sampled at
/// `S + 1` levels of equal centre-line arc length, scaled so the centre curve is one blade length.
pub fn build_reference_blade(shape: &BladeShape) -> Result<ReferenceBlade, GrassError> {
    if shape.segments == 0 || shape.segments > MAX_SEGMENTS {
        return Err(GrassError::parameter(format!("segments = {} (must be 1..={MAX_SEGMENTS})", shape.segments)));
    }
    let widths_ok = [shape.base_width, shape.tip_width].iter().all(|w| w.is_finite() && *w > 0.0 && *w <= 1.0);
    if !widths_ok {
        return Err(GrassError::parameter(format!(
            "blade widths {} / {} must be in (0, 1] blade lengths",
            shape.base_width, shape.tip_width
        )));
    }
    if !(shape.curl.is_finite() && shape.curl.abs() <= 0.5) {
        return Err(GrassError::parameter(format!("curl = {} (must be within ±0.5)", shape.curl)));
    }
    let curl = shape.curl as f64;
    let centre = [
        DVec3::ZERO,
        DVec3::new(0.0, 1.0 / 3.0, 0.0),
        DVec3::new(0.0, 2.0 / 3.0, 0.3 * curl),
        DVec3::new(0.0, 1.0, curl),
    ];
    let (b, t) = (shape.base_width as f64, shape.tip_width as f64);
    let width_ctrl = [b, b, b + 0.6 * (t - b), t];
    // Arc-length table of the centre curve.
    const SAMPLES: usize = 4096;
    let mut arc = Vec::with_capacity(SAMPLES + 1);
    arc.push(0.0f64);
    let mut prev = bezier(centre, 0.0);
    for i in 1..=SAMPLES {
        let p = bezier(centre, i as f64 / SAMPLES as f64);
        arc.push(arc[i - 1] + (p - prev).length());
        prev = p;
    }
    let total = arc[SAMPLES];
    let s = shape.segments as usize;
    let mut nodes = Vec::with_capacity(s + 1);
    let mut widths = Vec::with_capacity(s + 1);
    for level in 0..=s {
        let target = total * level as f64 / s as f64;
        let i = arc.partition_point(|&a| a < target).clamp(1, SAMPLES);
        let f = ((target - arc[i - 1]) / (arc[i] - arc[i - 1]).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        let param = (i as f64 - 1.0 + f) / SAMPLES as f64;
        nodes.push(bezier(centre, param) / total);
        let w = bezier(width_ctrl.map(DVec3::splat), param).x;
        widths.push(w);
    }
    let mut positions = Vec::with_capacity(4 * s);
    let mut uvs = Vec::with_capacity(4 * s);
    let mut triangles = Vec::with_capacity(2 * s);
    for k in 0..s {
        for v in 0..4 {
            let level = k + v / 2;
            let side = if v % 2 == 0 { -0.5 } else { 0.5 };
            let p = nodes[level] + DVec3::X * (side * widths[level]);
            positions.push([p.x as f32, p.y as f32, p.z as f32]);
            uvs.push([(side + 0.5) as f32, (level as f64 / s as f64) as f32]);
        }
        let q = 4 * k as u32;
        triangles.push([q, q + 1, q + 3]);
        triangles.push([q, q + 3, q + 2]);
    }
    Ok(ReferenceBlade { segments: shape.segments, nodes, widths, positions, uvs, triangles })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_segments_give_the_thesis_vertex_count_and_unit_length() {
        let b = build_reference_blade(&BladeShape::default()).expect("defaults are valid");
        assert_eq!(b.vertex_count(), 32);
        assert_eq!(b.triangles.len(), 16);
        assert_eq!(b.nodes.len(), 9);
        let len: f64 = b.nodes.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        assert!((len - 1.0).abs() < 1e-9, "length {len}");
        // Equal segments (rigid, §3.3) and a tapering width.
        let mut checked = 0;
        for w in b.nodes.windows(2) {
            assert!(((w[1] - w[0]).length() - 0.125).abs() < 1e-9);
            checked += 1;
        }
        assert_eq!(checked, 8);
        assert!(b.widths.windows(2).all(|w| w[1] <= w[0] + 1e-12));
        // Shared levels coincide: the top of segment k is the bottom of segment k + 1.
        for k in 0..7 {
            assert_eq!(b.positions[4 * k + 2], b.positions[4 * k + 4]);
            assert_eq!(b.positions[4 * k + 3], b.positions[4 * k + 5]);
        }
        // Front faces look towards +z.
        for t in &b.triangles {
            let p = t.map(|i| glam::Vec3::from(b.positions[i as usize]));
            assert!((p[1] - p[0]).cross(p[2] - p[0]).z > 0.0);
        }
    }

    #[test]
    fn curled_blade_keeps_unit_length_and_bad_shapes_are_refused() {
        let b = build_reference_blade(&BladeShape { curl: 0.3, segments: 16, ..BladeShape::default() })
            .expect("a curled blade is valid");
        let len: f64 = b.nodes.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        assert!((len - 1.0).abs() < 1e-3, "chord length {len}");
        assert!(b.nodes[16].z > 0.1);
        let bad = [
            BladeShape { segments: 0, ..BladeShape::default() },
            BladeShape { tip_width: 0.0, ..BladeShape::default() },
            BladeShape { base_width: f32::NAN, ..BladeShape::default() },
            BladeShape { curl: 2.0, ..BladeShape::default() },
        ];
        for s in bad {
            assert!(build_reference_blade(&s).is_err(), "{s:?} accepted");
        }
    }
}
