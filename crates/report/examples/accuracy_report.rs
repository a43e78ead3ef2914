//! Writes the whole accuracy-vs-time document (`accuracy.md` and its SVG plots) into the
//! directory given as the first argument (default: the current directory), as `furbake report
//! accuracy` does: `cargo run --release -p furbake-report --example accuracy_report -- docs`.

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    let doc = furbake_report::accuracy_document(&furbake_report::AccuracyOptions::default(), |part| {
        eprintln!("measuring {part:?}…");
    })?;
    let path = doc.write_into(&dir)?;
    println!("{}", doc.markdown);
    eprintln!("wrote {} and {} plots", path.display(), doc.plots.len());
    Ok(())
}
