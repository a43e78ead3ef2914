//! furbake-sim's integration tests, one binary; run one subject with
//! `cargo test -p furbake-sim --test sim <module>::`.

mod common;
mod convergence;
mod hard_cases;
mod peers;
mod randomised;
mod reference_check;
mod skinned;
mod solvers;
mod topology_counts;
