//! Prints the grass section of `docs/accuracy.md` (the report's grass part) with the default
//! options: `cargo run --release -p furbake-report --example grass_accuracy`.

use furbake_report::grass::{GrassAccuracyOptions, grass_accuracy_markdown};

fn main() -> Result<(), furbake_grass::GrassError> {
    let start = std::time::Instant::now();
    let md = grass_accuracy_markdown(&GrassAccuracyOptions::default())?;
    print!("{md}");
    eprintln!("generated in {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}
