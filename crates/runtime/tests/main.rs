//! furbake-runtime's integration tests, one binary; run one subject with
//! `cargo test -p furbake-runtime --test runtime <module>::`. `animation_alloc` installs this
//! binary's counting global allocator; it counts per thread, so tests running beside it do not count.

mod animated;
mod animation;
mod animation_alloc;
mod events;
mod host;
mod pack;
mod scene;
mod world;
