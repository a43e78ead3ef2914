//! furbake-render's integration tests, one binary (one link of wgpu, one shared lavapipe
//! device: `common::gpu`). Each module is one subject; run one with
//! `cargo test -p furbake-render --test render <module>::`.

mod alpha_coverage;
mod asset;
mod blade_shading;
mod blades;
mod common;
mod depth_pyramid;
mod frame_cost;
mod fur_shading;
mod golden_images;
mod gpu_physics;
mod grass_culling;
mod host;
mod lights;
mod lod;
mod parting;
mod physics;
mod render;
mod render_options;
mod rest_pose;
mod scene;
mod silhouette;
mod skinning;
mod views;
