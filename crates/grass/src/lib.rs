//! furbake-grass: individually animated 3D grass blades after the grass thesis (ch. 3–5). Its one
//! job is the grass data and its CPU reference: it bakes keyframe tables (a reference blade from
//! two parallel cubic Béziers, §4.1; poses simulated physically under a grid of horizontal forces,
//! §3.2.3–3.2.4; compressed by dropping static vertices, sharing one vector per rigid segment
//! pair, mirror symmetry and 16-bit quantisation, §3.3), scatters blade fields over meshes with
//! per-blade bilinear cluster weights (eq. 3.6–3.8), computes the per-frame cluster force field
//! (global wind, point wind sources eq. 4.1, collisions as local sources, windless areas, optional
//! delayed attenuation, §4.5, ch. 5) and decodes poses exactly as the vertex shader will
//! (selection from force magnitude and angle to the blade normal, eq. 3.10–3.12; nearest, linear
//! eq. 3.13 and spherical eq. 3.14 in-betweening). No CLI, no GPU.
//!
//! ```
//! use furbake_grass::{KeyframeSettings, bake_keyframe_table, KeyframeDecoder, PoseInterpolation};
//! use furbake_formats::sections::keyframe_table::Symmetry;
//!
//! let mut settings = KeyframeSettings::default(); // 8 segments, 1000 poses, all stages, snorm16
//! settings.grid.poses = 100;
//! settings.symmetry = Symmetry::XZ;
//! let table = bake_keyframe_table(&settings)?;
//! assert_eq!(table.vertex_count(), 32);
//! assert_eq!(table.stored_vectors, 15); // (32 − 2 static) / 2 rigid pairs
//! assert_eq!(table.raw_bits(), 100 * 32 * 3 * 32);
//! assert_eq!(table.payload_bits(), 25 * 15 * 3 * 16);
//!
//! let decoder = KeyframeDecoder::new(&table)?;
//! let mut pose = vec![glam::Vec3::ZERO; 32];
//! // A force of 2 units straight onto the blade's front (angle 0 to its normal).
//! let blend = decoder.select(glam::Vec2::new(0.0, 2.0), PoseInterpolation::Linear);
//! decoder.pose_positions(&blend, PoseInterpolation::Linear, &mut pose);
//! assert!(pose[31].z > 0.05, "the tip bends along the force");
//! # Ok::<(), furbake_grass::GrassError>(())
//! ```

#![deny(missing_docs)]
pub mod blade;
pub mod decode;
pub mod field;
pub mod force;
pub mod keyframes;
pub mod rng;
pub mod simulate;

pub use blade::{BladeShape, ReferenceBlade, build_reference_blade};
pub use decode::{BladeSoa, KeyframeDecoder, PoseBlend, PoseInterpolation, PoseKey};
pub use field::{BladeFieldSettings, ground_grid_mesh, scatter_blades};
pub use force::{BladeCollider, BladeWindSource, ForceField, ForceScene, WindBlocker};
pub use keyframes::{
    KeyframeSettings, PoseGridSettings, SimulatedPoses, bake_keyframe_table, compress_poses, simulate_poses,
};
pub use simulate::{BladeMaterial, BladeSimulator, Equilibrium};

/// Errors of the grass baker, split by blame.
#[derive(Debug, thiserror::Error)]
pub enum GrassError {
    /// A setting is out of range or settings contradict each other. Blame: the caller.
    #[error("invalid grass parameter: {what}")]
    Parameter {
        /// What is wrong.
        what: String,
    },
    /// The input mesh cannot be scattered on. Blame: the input.
    #[error("invalid input mesh: {what}")]
    Mesh {
        /// What is wrong.
        what: String,
    },
    /// A request exceeds a size limit.
    #[error("{what} is {value}, above the limit of {limit}")]
    Limit {
        /// What was counted.
        what: &'static str,
        /// The value asked for.
        value: u64,
        /// The largest value accepted.
        limit: u64,
    },
    /// The blade simulation did not settle (a force far outside the model's range).
    #[error("blade simulation did not converge under force (x {x:.4}, z {z:.4}): gradient {gradient:e}", x = force[0], z = force[1])]
    NotConverged {
        /// The local force `(x, z)`.
        force: [f64; 2],
        /// Largest gradient component left.
        gradient: f64,
    },
    /// A baked section is invalid or inconsistent.
    #[error(transparent)]
    Format(#[from] furbake_formats::FormatError),
}

impl GrassError {
    pub(crate) fn parameter(what: impl Into<String>) -> Self {
        GrassError::Parameter { what: what.into() }
    }
}
