//! Atlases as viewable PNG images: the shell slices as one grid (innermost layer top-left, row by
//! row), each slice alone, and the fin texture. Greyscale: white = hair, black = empty.

use std::path::Path;

use anyhow::Context;
use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::shell_atlas::ShellAtlas;

/// Writes `shells_grid.png`, `shell_layer_NNN.png` and `fins.png` into `dir` (created if needed).
/// Returns the paths written.
pub fn write_atlases(dir: &Path, shells: &ShellAtlas, fins: &FinAtlas) -> anyhow::Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create directory", dir.display()))?;
    let mut written = Vec::new();
    let res = shells.params.resolution;
    let layers = shells.layers();
    let cols = (layers as f64).sqrt().ceil() as u32;
    let rows = (layers as u32).div_ceil(cols);
    let gap = 2u32;
    let (gw, gh) = (cols * (res + gap) - gap, rows * (res + gap) - gap);
    let mut grid = image::GrayImage::from_pixel(gw, gh, image::Luma([48]));
    for i in 0..layers {
        let (cx, cy) = ((i as u32 % cols) * (res + gap), (i as u32 / cols) * (res + gap));
        let layer = shells.layer(i);
        for y in 0..res {
            for x in 0..res {
                grid.put_pixel(cx + x, cy + y, image::Luma([layer[(y * res + x) as usize]]));
            }
        }
        let single = image::GrayImage::from_raw(res, res, layer.to_vec()).expect("layer is res² bytes");
        written.push(save(dir, &format!("shell_layer_{i:03}.png"), single)?);
    }
    written.push(save(dir, "shells_grid.png", grid)?);
    let fin =
        image::GrayImage::from_raw(fins.width, fins.height, fins.alpha.clone()).expect("fin is width×height bytes");
    written.push(save(dir, "fins.png", fin)?);
    Ok(written)
}

fn save(dir: &Path, name: &str, img: image::GrayImage) -> anyhow::Result<std::path::PathBuf> {
    let path = dir.join(name);
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
        .with_context(|| format!("{}: cannot encode PNG", path.display()))?;
    furbake_formats::write_file_atomic(&path, &bytes)?;
    Ok(path)
}
