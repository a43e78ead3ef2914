//! `furbake shaders --target spirv|glsl|hlsl|msl -o DIR`: the renderer's shaders for an engine's
//! own graphics API (`furbake_render::export_shaders`) and their `manifest.json`, written into a
//! directory.

use anyhow::Context;

use crate::args::ShadersArgs;
use crate::failure::{Classify, Failure};

/// Runs `furbake shaders`.
pub fn run(args: ShadersArgs, quiet: bool) -> Result<(), Failure> {
    let target = furbake_render::ShaderTarget::from_name(&args.target).expect("clap accepts only the listed targets");
    let export = furbake_render::export_shaders(target).context("shader export").input()?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create directory", args.output.display()))
        .input()?;
    for file in &export.files {
        furbake_formats::write_file_atomic(&args.output.join(&file.file), &file.bytes).input()?;
    }
    let manifest = serde_json::to_string_pretty(&export.manifest).expect("JSON values always serialise");
    furbake_formats::write_file_atomic(&args.output.join("manifest.json"), format!("{manifest}\n").as_bytes())
        .input()?;
    if !quiet {
        crate::stdout::line(format_args!(
            "wrote {} {} shaders and manifest.json into {}",
            export.files.len(),
            target.name(),
            args.output.display()
        ))?;
    }
    Ok(())
}
