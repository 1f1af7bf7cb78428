//! What each plugin parameter means, for `skid plugins`: read from the JSON Schema that `schemars`
//! derives from the config type, whose descriptions are the fields' doc comments. Nested tables give
//! dotted keys (`keyframe.distance_m`); enumerations add their accepted values.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde_json::{Map, Value};

/// Dotted parameter key → its doc comment (and, for enumerations, the accepted values).
pub type ParamDocs = BTreeMap<String, String>;

/// The documentation of every parameter of `C`.
pub fn param_docs<C: JsonSchema>() -> ParamDocs {
    let schema = schemars::schema_for!(C);
    let root = schema.as_value();
    let mut docs = ParamDocs::new();
    if let Some(object) = root.as_object() {
        collect(root, object, "", &mut docs, 0);
    }
    docs
}

/// The schema a `$ref` (possibly inside `allOf`/`anyOf`, as for `Option`s) points at in `$defs`.
fn resolve<'a>(root: &'a Value, schema: &'a Map<String, Value>) -> &'a Map<String, Value> {
    let reference = schema.get("$ref").and_then(Value::as_str).or_else(|| {
        ["allOf", "anyOf", "oneOf"].iter().find_map(|key| {
            schema
                .get(*key)?
                .as_array()?
                .iter()
                .find_map(|item| item.get("$ref")?.as_str())
        })
    });
    reference
        .and_then(|r| r.strip_prefix("#/$defs/"))
        .and_then(|name| root.get("$defs")?.get(name)?.as_object())
        .unwrap_or(schema)
}

/// The accepted values of an enumeration schema, if it is one.
fn accepted_values(schema: &Map<String, Value>) -> Vec<String> {
    let mut values = Vec::new();
    if let Some(list) = schema.get("enum").and_then(Value::as_array) {
        values.extend(list.iter().filter_map(Value::as_str).map(str::to_owned));
    }
    for key in ["oneOf", "anyOf"] {
        for item in schema.get(key).and_then(Value::as_array).into_iter().flatten() {
            if let Some(value) = item.get("const").and_then(Value::as_str) {
                values.push(value.to_owned());
            }
            if let Some(list) = item.get("enum").and_then(Value::as_array) {
                values.extend(list.iter().filter_map(Value::as_str).map(str::to_owned));
            }
        }
    }
    values
}

fn collect(root: &Value, object: &Map<String, Value>, prefix: &str, docs: &mut ParamDocs, depth: usize) {
    // Config types nest a few levels at most; the bound keeps a self-referencing schema finite.
    if depth > 8 {
        return;
    }
    let Some(properties) = object.get("properties").and_then(Value::as_object) else {
        return;
    };
    for (name, property) in properties {
        let Some(property) = property.as_object() else {
            continue;
        };
        let key = if prefix.is_empty() {
            name.clone()
        } else {
            format!("{prefix}.{name}")
        };
        let target = resolve(root, property);
        let description = property
            .get("description")
            .or_else(|| target.get("description"))
            .and_then(Value::as_str)
            .map(|text| text.split_whitespace().collect::<Vec<_>>().join(" "));
        let values = accepted_values(target);
        let text = match (description, values.is_empty()) {
            (Some(text), true) => text,
            (Some(text), false) => format!("{text} (one of: {})", values.join(", ")),
            (None, false) => format!("one of: {}", values.join(", ")),
            (None, true) => String::new(),
        };
        if !text.is_empty() {
            docs.insert(key.clone(), text);
        }
        if target.contains_key("properties") {
            collect(root, target, &key, docs, depth + 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// How a point is chosen.
    #[derive(schemars::JsonSchema, serde::Serialize, serde::Deserialize)]
    #[serde(rename_all = "snake_case")]
    #[allow(dead_code)]
    enum Mode {
        First,
        Last,
    }

    #[derive(schemars::JsonSchema, serde::Serialize, serde::Deserialize)]
    #[allow(dead_code)]
    struct Inner {
        /// Distance travelled, in metres.
        distance_m: f64,
    }

    #[derive(schemars::JsonSchema, serde::Serialize, serde::Deserialize)]
    #[allow(dead_code)]
    struct Example {
        /// Voxel size, in metres.
        voxel_size_m: f64,
        mode: Mode,
        inner: Inner,
        maybe: Option<u32>,
    }

    #[test]
    fn doc_comments_become_dotted_key_docs_with_enum_values() {
        let docs = param_docs::<Example>();
        assert_eq!(docs["voxel_size_m"], "Voxel size, in metres.");
        assert_eq!(docs["inner.distance_m"], "Distance travelled, in metres.");
        assert!(docs["mode"].contains("first, last"), "{docs:?}");
        assert!(!docs.contains_key("maybe"));
    }
}
