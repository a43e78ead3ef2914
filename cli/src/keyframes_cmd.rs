//! `furbake keyframes`: bake one grass-blade keyframe table (grass thesis §3.2–3.3) into a
//! single-section container.

use furbake_formats::PackWriter;
use furbake_formats::sections::keyframe_table::{DisplacementEncoding, Symmetry};
use furbake_grass::{GrassError, KeyframeSettings, bake_keyframe_table};

use crate::args::KeyframesArgs;
use crate::failure::{Classify, Failure};

/// Stage two of argument parsing: flags → validated keyframe settings.
pub fn plan(args: &KeyframesArgs) -> Result<KeyframeSettings, Failure> {
    let mut s = KeyframeSettings::default();
    s.shape.segments = args.segments;
    s.grid.poses = args.poses;
    s.grid.magnitudes = args.magnitudes;
    s.grid.max_force = args.max_force;
    // clap restricts both values to the known names.
    s.symmetry = Symmetry::from_name(&args.symmetry).expect("clap checked the symmetry name");
    s.encoding = DisplacementEncoding::from_name(&args.encoding).expect("clap checked the encoding name");
    s.stages.drop_static_vertices = !args.no_drop_static;
    s.stages.rigid_segment_pairs = !args.no_rigid_pairs;
    Ok(s)
}

/// Runs `furbake keyframes`.
pub fn run(args: KeyframesArgs, quiet: bool) -> Result<(), Failure> {
    let settings = plan(&args)?;
    crate::files::Files::default().output("--output", &args.output)?;
    let table = match bake_keyframe_table(&settings) {
        Ok(t) => t,
        Err(e @ GrassError::Parameter { .. }) | Err(e @ GrassError::Limit { .. }) => {
            return Err(Failure::Usage(e.into()));
        }
        Err(e) => return Err(Failure::Input(e.into())),
    };
    let mut w = PackWriter::new();
    w.push_section(&table);
    w.write_atomic(&args.output).input()?;
    if !quiet {
        eprintln!(
            "baked keyframe table → {}: {} poses × {} vertices, {} raw bits → {} payload bits ({}, symmetry {})",
            args.output.display(),
            settings.grid.poses,
            table.vertex_count(),
            table.raw_bits(),
            table.payload_bits(),
            settings.encoding.name(),
            settings.symmetry.name(),
        );
    }
    Ok(())
}
