//! `furbake export`: a pack, validated as `verify` does, as a self-contained binary glTF
//! (`furbake_export`), written atomically; what the file cannot carry is printed as warnings.

use anyhow::anyhow;
use furbake_export::{ExportError, ExportOptions, ShellAlpha, export};

use crate::args::ExportArgs;
use crate::failure::Failure;

/// Runs `furbake export`.
pub fn run(args: ExportArgs, quiet: bool) -> Result<(), Failure> {
    let options = ExportOptions {
        layers: args.layers,
        fins: !args.no_fins,
        animation: !args.no_animation,
        alpha: match args.alpha_mask {
            Some(cutoff) => ShellAlpha::Mask { cutoff },
            None => ShellAlpha::Blend,
        },
    };
    // The glb (`-o -`: stdout) may not replace the pack or anything but a regular file
    // (docs/design.md "Safe outputs").
    crate::files::Files::with_inputs([args.file.as_path()]).stream_output("--output", &args.output)?;
    // Validated as `verify` does before anything is exported (docs/design.md "Runtime: packs").
    let pack = crate::describe::open_verified(&args.file)?;
    let file = args.file.display();
    let done = export(&pack, &options).map_err(|e| match e {
        // A flag that does not fit this pack (more layers than its atlas, a cutoff outside
        // [0, 1]) is the caller's; everything else is the pack's.
        e @ ExportError::Option { .. } => Failure::Usage(anyhow!("{file}: {e}")),
        e => Failure::Input(anyhow!("{file}: {e}")),
    })?;
    crate::files::write_output(&args.output, &done.glb, "the glTF")?;
    if !quiet {
        for note in &done.notes {
            eprintln!("furbake: warning: {file}: {note}");
        }
        // With `-o -` stdout is the file: the summary goes to stderr.
        let summary = format!("exported {file} → {} ({} bytes)", args.output.display(), done.glb.len());
        if crate::files::is_stdout(&args.output) {
            eprintln!("{summary}");
        } else {
            crate::stdout::line(summary)?;
        }
    }
    Ok(())
}
