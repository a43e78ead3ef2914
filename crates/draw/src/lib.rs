//! furbake-draw: what drawing a baked pack takes, computed on the CPU without a graphics API —
//! the vertex and uniform layouts furbake's shaders read ([`layout`]), the geometry built from a
//! pack's sections ([`geometry`]: per-corner skin vertices, fin quads, silhouette edges), the
//! atlases' mip chains ([`mips`]), the shells' stacking exponents ([`stacking`]), the `Fur`
//! uniform block's parameters ([`FurLook`]) and the shells' level of detail ([`lod`]). Nothing
//! else: `furbake-render` draws with these on wgpu, `furbake-capi` hands them to engines that
//! draw with the shaders `furbake shaders` exports (docs/c-api.md).

pub mod geometry;
pub mod layout;
pub mod lod;
mod look;
pub mod mips;
pub mod stacking;

pub use look::{FurLook, FurShading};
