//! `furbake schema scene|config|batch`: prints the JSON Schema (draft 2020-12) of runtime scene
//! files, bake config files or batch files, derived from the types that read them
//! (`furbake_runtime::Scene::json_schema`, `furbake_bake::BakeSettings::config_schema`, the batch
//! file's own types), so the schema an editor validates against says what `furbake` accepts. The
//! committed copies are docs/schemas/{scene,config,batch}.schema.json (a test holds them equal to
//! this output).

use crate::args::SchemaArgs;
use crate::failure::Failure;

/// Runs `furbake schema`.
pub fn run(args: SchemaArgs) -> Result<(), Failure> {
    let schema = match args.which.as_str() {
        "scene" => furbake_runtime::Scene::json_schema(),
        "config" => furbake_bake::BakeSettings::config_schema(),
        "batch" => batch_schema(),
        other => unreachable!("clap accepts only the listed schemas, not {other}"),
    };
    let text = serde_json::to_string_pretty(&schema).expect("a schema is plain JSON");
    crate::stdout::line(text)
}

/// The batch file's schema: its own keys, and in `settings` the keys of a bake config (none
/// required: they patch the preset, as a `--config` file does).
fn batch_schema() -> schemars::Schema {
    let mut schema = furbake_formats::schema::toml_file_schema::<crate::batch_cmd::BatchFile>(
        "furbake batch file",
        "A furbake batch file (TOML, `furbake batch FILE`): `[defaults]` every asset starts from and one \
         `[[asset]]` table per glTF to bake (`furbake batch --help`; `furbake schema batch` prints this schema).",
        false,
    );
    let own = ["Defaults", "AssetEntry", "Common"];
    if let Some(defs) = schema.get_mut("$defs").and_then(serde_json::Value::as_object_mut) {
        for (name, def) in defs.iter_mut() {
            if let (false, Some(def)) = (own.contains(&name.as_str()), def.as_object_mut()) {
                def.remove("required");
            }
        }
    }
    schema
}
