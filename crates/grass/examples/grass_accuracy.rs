//! Prints the grass section of `docs/accuracy.md` (the report command's grass part) with the
//! default options: `cargo run --release -p furbake-grass --example grass_accuracy`.

fn main() -> Result<(), furbake_grass::GrassError> {
    let start = std::time::Instant::now();
    let md = furbake_grass::grass_accuracy_markdown(&furbake_grass::GrassAccuracyOptions::default())?;
    print!("{md}");
    eprintln!("generated in {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}
