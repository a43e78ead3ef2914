//! `furbake extract`: every atlas of a file as PNG images plus `metadata.json` (the
//! `inspect --json` document) in a directory.

use anyhow::Context;

use crate::args::ExtractArgs;
use crate::describe::{describe, load};
use crate::failure::{Classify, Failure};

/// Runs `furbake extract`.
pub fn run(args: ExtractArgs, quiet: bool) -> Result<(), Failure> {
    let (pack, decoded) = load(&args.file)?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create directory", args.output.display()))
        .input()?;
    let mut written = Vec::new();
    if let (Some(shells), Some(fins)) = (&decoded.shells, &decoded.fins) {
        written.extend(crate::png::write_atlases(&args.output, shells, fins).input()?);
    }
    let doc = describe(&args.file, &pack, &decoded);
    let meta = args.output.join("metadata.json");
    let text = serde_json::to_string_pretty(&doc).expect("JSON values always serialise");
    furbake_formats::write_file_atomic(&meta, text.as_bytes()).input()?;
    written.push(meta);
    if !quiet {
        crate::stdout::line(format_args!("extracted {} files into {}", written.len(), args.output.display()))?;
    }
    Ok(())
}
