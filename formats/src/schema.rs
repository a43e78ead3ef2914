//! JSON Schemas (draft 2020-12) of the TOML files people write by hand — scenes, bake configs —
//! derived from the types that read them (schemars; feature `schema`), so that what an editor
//! validates against is what furbake accepts. One generator for every such file: TOML has no
//! null, so an optional key is its type alone (absent means the default) and null defaults are
//! left out; a file of overrides (a bake config patches a preset) has no required key.

use serde_json::Value;

/// The schema of the TOML file read as `T`: `title` and `description` at its root, every key
/// documented from `T`'s documentation; with `partial`, no key is required at any depth.
pub fn toml_file_schema<T: schemars::JsonSchema>(title: &str, description: &str, partial: bool) -> schemars::Schema {
    let toml = schemars::transform::RecursiveTransform(move |s: &mut schemars::Schema| {
        if s.get("default").is_some_and(Value::is_null) {
            s.remove("default");
        }
        if let Some(fields) = s.get_mut("default").and_then(Value::as_object_mut) {
            fields.retain(|_, v| !v.is_null());
        }
        // `Option<T>`: T alone.
        if let Some(Value::Array(types)) = s.get_mut("type") {
            types.retain(|t| t != "null");
            if types.len() == 1 {
                let only = types.remove(0);
                s.insert("type".into(), only);
            }
        }
        let null = serde_json::json!({ "type": "null" });
        if let Some(Value::Array(alternatives)) = s.get_mut("anyOf") {
            alternatives.retain(|a| *a != null);
            if alternatives.len() == 1 {
                if let Some(Value::Object(only)) = alternatives.pop() {
                    s.remove("anyOf");
                    for (k, v) in only {
                        s.insert(k, v);
                    }
                }
            }
        }
        if partial {
            s.remove("required");
        }
    });
    let mut schema = schemars::generate::SchemaSettings::draft2020_12()
        .with_transform(toml)
        .into_generator()
        .into_root_schema_for::<T>();
    schema.insert("title".into(), title.into());
    schema.insert("description".into(), description.into());
    schema
}
