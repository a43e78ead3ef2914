//! Regenerates `docs/rendering-accuracy.md`, its chart and images (`make report`): furbake's
//! shells and fins against a ray-marched reference of the baked hair volume
//! (`furbake_report::rendering`). Usage: `rendering_report [OUT_DIR] [--quick]` (default `docs`;
//! `--quick`: 64 px, 9 samples per pixel, two shell counts, for a smoke run; `--atlas-layers=N`:
//! bake the atlases with N layers instead of the preset's 16; `--srgb8-target`: draw into the
//! headless host's 8-bit sRGB target, `--f16-target` into a half-float one, instead of a
//! single-float one).

use std::path::PathBuf;

use furbake_report::rendering::gpu::ReportTarget;
use furbake_report::rendering::report::{RenderingOptions, rendering_report};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let out = args.iter().find(|a| !a.starts_with("--")).map_or_else(|| PathBuf::from("docs"), PathBuf::from);
    let fixtures = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
    let mut options = RenderingOptions::new(&fixtures);
    if args.iter().any(|a| a == "--srgb8-target") {
        options.target = ReportTarget::Srgb8;
    }
    if args.iter().any(|a| a == "--f16-target") {
        options.target = ReportTarget::Float16;
    }
    if let Some(layers) = args.iter().find_map(|a| a.strip_prefix("--atlas-layers=")) {
        options.bake.volume.layers = layers.parse().expect("--atlas-layers=N takes a count");
    }
    if quick {
        (options.size, options.strata, options.shells, options.timed_frames) = (64, 3, vec![4, 16], 1);
        options.lod_lengths_px = vec![2.0, 8.0];
    }
    let report = match rendering_report(&options, |line| eprintln!("{line}")) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("rendering report failed: {e}");
            std::process::exit(1);
        }
    };
    match report.write_into(&out) {
        Ok(path) => println!("wrote {}", path.display()),
        Err(e) => {
            eprintln!("rendering report: {e}");
            std::process::exit(1);
        }
    }
}
