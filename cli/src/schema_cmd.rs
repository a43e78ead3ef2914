//! `furbake schema scene`: prints the JSON Schema (draft 2020-12) of runtime scene files,
//! derived from the types that read them (`furbake_runtime::Scene::json_schema`), so the schema an
//! editor validates against says what `furbake` accepts. The committed copy is
//! docs/schemas/scene.schema.json (a test holds it equal to this output).

use crate::args::SchemaArgs;
use crate::failure::Failure;

/// Runs `furbake schema`.
pub fn run(args: SchemaArgs) -> Result<(), Failure> {
    let schema = match args.which.as_str() {
        "scene" => furbake_runtime::Scene::json_schema(),
        other => unreachable!("clap accepts only the listed schemas, not {other}"),
    };
    let text = serde_json::to_string_pretty(&schema).expect("a schema is plain JSON");
    crate::stdout::line(text)
}
