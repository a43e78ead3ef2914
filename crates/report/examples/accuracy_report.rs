//! Writes the whole accuracy-vs-time document (`accuracy.md` and its SVG plots) into the
//! directory given as the first argument (default: the current directory) — what `make report`
//! runs: `cargo run --release -p furbake-report --example accuracy_report -- docs`.

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let start = std::time::Instant::now();
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    let doc = furbake_report::accuracy_document(&furbake_report::AccuracyOptions::default(), |part| {
        eprintln!("measuring {part:?} ({:.0} s so far)…", start.elapsed().as_secs_f64());
    })?;
    let path = doc.write_into(&dir)?;
    eprintln!("wrote {} and {} plots in {:.0} s", path.display(), doc.plots.len(), start.elapsed().as_secs_f64());
    Ok(())
}
