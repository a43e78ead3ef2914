//! Writes the accuracy-vs-time report (`accuracy.md` and its SVG plots) into the directory given
//! as the first argument (default: the current directory). The CLI's `furbake report accuracy`
//! does the same; this example exists so the report can be produced from this crate alone:
//! `cargo run --release -p furbake-sim --example accuracy_report -- docs`.

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    let report = furbake_sim::accuracy::accuracy_report(&furbake_sim::accuracy::AccuracySettings::default())?;
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join("accuracy.md"), &report.markdown)?;
    for (name, svg) in &report.plots {
        std::fs::write(dir.join(name), svg)?;
    }
    println!("{}", report.markdown);
    Ok(())
}
