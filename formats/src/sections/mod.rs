//! Typed sections: one module per artifact kind, each a struct-of-arrays with `encode`/`decode`
//! over the record layout of [`crate::record`] and a JSON `summary` for `furbake inspect`.

use crate::SectionKind;
use crate::error::Result;

pub mod animation_clips;
pub mod blade_field;
pub mod fin_atlas;
pub mod fin_edges;
pub mod keyframe_table;

pub mod manifest;
pub mod morph_targets;
pub mod shell_atlas;
pub mod skeleton;
pub mod skin_mesh;
pub mod skin_weights;
pub mod spring_topology;
pub mod triangle_uv_map;

/// A typed artifact stored as one container section.
pub trait Section: Sized {
    /// The section kind code.
    const KIND: SectionKind;
    /// The payload layout version this crate writes (and the newest it reads).
    const VERSION: u16;
    /// Serialises into a record payload.
    fn encode(&self) -> Vec<u8>;
    /// Parses and validates a record payload (counts, index ranges, finite values).
    fn decode(payload: &[u8]) -> Result<Self>;
    /// Parameters and statistics as named JSON fields (stable: scripts parse them).
    fn summary(&self) -> serde_json::Value;
}

/// Fails with an `Invalid` error unless every value is finite.
pub(crate) fn check_finite(values: &[f32], what: &str) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(crate::FormatError::invalid(format!("{what}[{i}] is not finite ({})", values[i]))),
    }
}

/// Largest magnitude of a stored coordinate or length, metres: ten thousand kilometres. Larger
/// values are no asset (and squaring them overflows `f32`), so readers refuse them.
pub const MAX_COORDINATE_M: f32 = 1e7;

/// Fails unless every value is finite and within `[lo, hi]`.
pub(crate) fn check_range(values: &[f32], lo: f32, hi: f32, what: &str) -> Result<()> {
    match values.iter().position(|v| !(v.is_finite() && (lo..=hi).contains(v))) {
        None => Ok(()),
        Some(i) if !values[i].is_finite() => {
            Err(crate::FormatError::invalid(format!("{what}[{i}] is not finite ({})", values[i])))
        }
        Some(i) => Err(crate::FormatError::invalid(format!("{what}[{i}] = {} is outside [{lo:e}, {hi:e}]", values[i]))),
    }
}

/// Fails unless every value is finite with a magnitude of at most [`MAX_COORDINATE_M`].
pub(crate) fn check_coordinates(values: &[f32], what: &str) -> Result<()> {
    check_range(values, -MAX_COORDINATE_M, MAX_COORDINATE_M, what)
}

/// Fails unless `value` is finite and within `[lo, hi]` (a scalar parameter).
pub(crate) fn check_param(value: f32, lo: f32, hi: f32, what: &str) -> Result<()> {
    check_range(&[value], lo, hi, what)
        .map_err(|_| crate::FormatError::invalid(format!("{what} = {value} is outside [{lo:e}, {hi:e}]")))
}

/// Fails unless every index is below `bound`.
pub(crate) fn check_indices(indices: &[u32], bound: usize, what: &str) -> Result<()> {
    match indices.iter().position(|&i| i as usize >= bound) {
        None => Ok(()),
        Some(i) => Err(crate::FormatError::invalid(format!(
            "{what}[{i}] = {} is out of range (must be below {bound})",
            indices[i]
        ))),
    }
}

/// `a * b`, or an `Invalid` error when the product overflows (a lying count).
pub(crate) fn checked_count(a: usize, b: usize, what: &str) -> Result<usize> {
    a.checked_mul(b).ok_or_else(|| crate::FormatError::invalid(format!("{what}: count {a} × {b} overflows")))
}
