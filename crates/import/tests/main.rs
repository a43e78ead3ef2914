//! furbake-import's integration tests, one binary; run one subject with
//! `cargo test -p furbake-import --test import <module>::`.

mod animation;
mod common;
mod confinement;
mod errors;
mod generated;
mod generated_files;
mod never_panic;
mod real_models;
