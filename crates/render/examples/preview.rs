//! Renders a baked pack to a PNG — what `furbake preview` does:
//! `cargo run -p furbake-render --example preview -- PACK.fbk OUT.png [WIDTH HEIGHT [ZOOM [THRESHOLD]]]`.
//! ZOOM > 1 moves the automatic camera closer (2 = half the distance); THRESHOLD is the shell
//! alpha threshold (default: [`RenderSettings::default`]).

use furbake_render::headless::render_pack;
use furbake_render::{FurAsset, RenderSettings};
use furbake_runtime::Pack;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(pack), Some(out)) = (args.first(), args.get(1)) else {
        return Err("usage: preview PACK.fbk OUT.png [WIDTH HEIGHT [ZOOM [THRESHOLD]]]".into());
    };
    let width = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(512);
    let height = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(width);
    let zoom: f32 = args.get(4).map(|s| s.parse()).transpose()?.unwrap_or(1.0);
    let mut settings = RenderSettings::default();
    if let Some(t) = args.get(5) {
        settings.alpha_threshold = t.parse()?;
    }
    let pack = Pack::open(pack)?;
    let asset = FurAsset::from_pack(&pack, true)?;
    let (center, _) = asset.bounding_sphere();
    let mut view = asset.auto_view(width as f32 / height as f32);
    let (center, eye) = (glam::Vec3::from(center), glam::Vec3::from(view.camera.eye));
    view.camera.eye = (center + (eye - center) / zoom).to_array();
    let start = std::time::Instant::now();
    let image = render_pack(&pack, width, height, Some(view), &settings)?;
    image.save(out)?;
    println!("{out}: {width}×{height} in {:.2} s", start.elapsed().as_secs_f64());
    Ok(())
}
