//! `furbake report accuracy`: regenerate `docs/accuracy.md` and its SVG plots — the user's ask
//! "show what accuracy costs in time". Thin glue: `furbake-report` measures (fur solvers against a
//! converged reference, grass keyframes and force field against exact values) and renders; this
//! file reports progress and writes the files. `make report` runs the same library call through
//! the report crate's example, which does not build the renderer in release.

use crate::args::ReportArgs;
use crate::failure::{Classify, Failure};

/// Runs `furbake report`.
pub fn run(args: ReportArgs, quiet: bool) -> Result<(), Failure> {
    let progress = |part| {
        if !quiet {
            match part {
                furbake_report::ReportPart::Fur => eprintln!("measuring fur solvers (a few minutes in release)…"),
                furbake_report::ReportPart::Grass => eprintln!("measuring grass keyframes and force field…"),
            }
        }
    };
    let doc = furbake_report::accuracy_document(&furbake_report::AccuracyOptions::default(), progress).input()?;
    let path = doc.write_into(&args.output).input()?;
    if !quiet {
        eprintln!("wrote {} and {} plots", path.display(), doc.plots.len());
    }
    Ok(())
}
