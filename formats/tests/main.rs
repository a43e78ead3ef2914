//! furbake-formats' integration tests, one binary (the umask test is a binary of its own:
//! `tests/permissions.rs`); run one subject with `cargo test -p furbake-formats --test formats <module>::`.

mod animation_sections;
mod container;
mod rig;
mod verify;
