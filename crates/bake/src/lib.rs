//! furbake-bake: (being written)
pub mod volume;
