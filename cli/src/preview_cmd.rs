//! `furbake preview`: render a pack headless into a PNG (framed automatically, three-quarter view).

use anyhow::Context;
use furbake_render::{RenderError, render_preview};

use crate::args::PreviewArgs;
use crate::failure::{Classify, Failure};

/// Runs `furbake preview`.
pub fn run(args: PreviewArgs, quiet: bool) -> Result<(), Failure> {
    let (w, h) = args.size;
    let image = match render_preview(&args.pack, w, h) {
        Ok(img) => img,
        Err(e @ RenderError::Parameter { .. }) => return Err(Failure::Usage(e.into())),
        Err(e) => {
            return Err(Failure::Input(
                anyhow::Error::new(e).context(format!("{}: cannot render", args.pack.display())),
            ));
        }
    };
    let mut bytes = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
        .with_context(|| format!("{}: cannot encode PNG", args.output.display()))
        .input()?;
    furbake_formats::write_file_atomic(&args.output, &bytes).input()?;
    if !quiet {
        eprintln!("rendered {} → {} ({w}×{h})", args.pack.display(), args.output.display());
    }
    Ok(())
}
