//! furbake-sim: fur physics — and only that. It builds the mass–spring topologies of the fur
//! thesis (§3.4.1: chain, reduced chain, sticks, spring–sticks, prisms and their separable forms)
//! from a welded skin mesh, and simulates them under gravity, wind, object motion, local
//! interaction and the restoring force of eq. 3.37, with the explicit (eq. 3.20–3.25), implicit
//! (eq. 3.26–3.34) and stick solvers (§3.3.2) plus a reference: backward Euler with the exact
//! Jacobian, solved by BiCGSTAB in f64 (Baraff & Witkin 1998); the wrong-side-scale guard of §3.4.3 and the shell shearing of
//! eq. 3.35–3.36 run on the CPU as the reference for the shaders. Shared by the baker (topology
//! building) and the runtime (simulation).
//!
//! ```
//! use furbake_formats::sections::spring_topology::{TopologyKind, TopologyParams};
//! use furbake_sim::{ForceSet, SolverKind, SolverSettings, Simulator, build_topology, meshes};
//!
//! let mesh = meshes::grass_patch(0.1);
//! let topo = build_topology(&mesh, TopologyKind::PRISMS, &TopologyParams::default())?;
//! assert_eq!((topo.mass_kg.len(), topo.spring_ends.len()), (26, 13 + 28));
//!
//! let mut sim = Simulator::new(&topo, SolverSettings::of(SolverKind::Implicit))?;
//! sim.set_forces(ForceSet::default())?; // gravity + restoring force
//! for _ in 0..60 {
//!     sim.step(1.0 / 60.0)?;
//! }
//! assert!(sim.positions().iter().flatten().all(|c| c.is_finite()));
//! # Ok::<(), furbake_sim::SimError>(())
//! ```
//!
//! Determinism: every kernel gathers each mass's forces over its own links in a fixed order and
//! every sum uses fixed-size chunks, so results are bit-identical for any rayon thread count.

#![deny(missing_docs)]
mod clusters;
mod compute;
mod error;
pub mod forces;
mod groups;
mod link_graph;
pub mod meshes;
mod model;
mod sentinel;
pub mod shell;
mod simulator;
pub mod skin;
mod solvers;
pub mod synth;
pub mod topology;

pub use compute::{
    ComputeBetween, ComputeModel, ComputePose, ComputeTip, ComputeUpdate, ComputeXpbd, ComputeXpbdLink, NO_LINK,
};
pub use error::SimError;
pub use forces::{ForceSet, FrameMotion, LocalForce, WindForce, restoring_force};
pub use furbake_formats::sections::spring_topology::{SpringTopology, TopologyKind, TopologyParams};
pub use shell::{GuardSettings, scale_vector, shell_offset, shell_vertex_position};
pub use simulator::{Energy, Simulator, SolverKind, SolverSettings, StepStats};
pub use skin::{SkinMove, SkinTransform};
pub use topology::{build_topology, mesh_edges, validate_mesh};
