//! Plugin parameters: the TOML sub-table `[slot.plugin_name]`, parsed by the plugin's own config type.

use std::fmt;

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::error::ParamError;

/// A plugin's parameter table, as it came out of the merged configuration.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Params {
    table: toml::Table,
}

impl Params {
    /// Parameters from a TOML table.
    pub fn new(table: toml::Table) -> Self {
        Self { table }
    }

    /// Parameters from TOML text (used by tests and by dynamic plugins).
    pub fn from_toml_str(text: &str) -> Result<Self, ParamError> {
        let table = text.parse::<toml::Table>().map_err(|e| ParamError {
            path: String::new(),
            message: e.to_string(),
        })?;
        Ok(Self::new(table))
    }

    /// The serialised parameters of a config value (its defaults, typically).
    pub fn from_config<C: Serialize>(config: &C) -> Result<Self, ParamError> {
        match toml::Value::try_from(config) {
            Ok(toml::Value::Table(table)) => Ok(Self::new(table)),
            Ok(other) => Err(ParamError {
                path: String::new(),
                message: format!("parameters must serialise to a table, not a {}", other.type_str()),
            }),
            Err(e) => Err(ParamError {
                path: String::new(),
                message: e.to_string(),
            }),
        }
    }

    /// The raw table.
    pub fn table(&self) -> &toml::Table {
        &self.table
    }

    /// Parses into the plugin's config type; missing keys take the type's `#[serde(default)]` values.
    pub fn parse<C: DeserializeOwned>(&self) -> Result<C, ParamError> {
        let value = toml::Value::Table(self.table.clone());
        serde_path_to_error::deserialize::<_, C>(value).map_err(|error| {
            let path = error.path().to_string();
            let message = error.inner().to_string();
            ParamError {
                path: if path == "." { String::new() } else { path },
                message,
            }
        })
    }

    /// The parameters as TOML text.
    pub fn to_toml_string(&self) -> String {
        toml::to_string(&self.table).unwrap_or_default()
    }
}

impl fmt::Display for Params {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_toml_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize, Serialize, PartialEq)]
    #[serde(default, deny_unknown_fields)]
    struct Example {
        num_sectors: u32,
        max_range_m: f64,
        inner: Inner,
    }

    #[derive(Debug, Default, Deserialize, Serialize, PartialEq)]
    #[serde(default, deny_unknown_fields)]
    struct Inner {
        enabled: bool,
    }

    #[test]
    fn missing_keys_take_defaults() {
        let params = Params::from_toml_str("num_sectors = 60").unwrap();
        let parsed: Example = params.parse().unwrap();
        assert_eq!(
            parsed,
            Example {
                num_sectors: 60,
                ..Example::default()
            }
        );
    }

    #[test]
    fn unknown_key_names_path_and_expected_keys() {
        let params = Params::from_toml_str("num_sectorz = 60").unwrap();
        let error = params.parse::<Example>().unwrap_err();
        assert_eq!(error.path, "num_sectorz");
        assert!(error.message.contains("expected one of"), "{error}");
        assert!(error.message.contains("num_sectors"), "{error}");
    }

    #[test]
    fn nested_wrong_type_names_full_path() {
        let params = Params::from_toml_str("[inner]\nenabled = 3").unwrap();
        let error = params.parse::<Example>().unwrap_err();
        assert_eq!(error.path, "inner.enabled");
        assert!(error.message.contains("bool"), "{error}");
    }

    #[test]
    fn defaults_serialise_to_a_table() {
        let params = Params::from_config(&Example::default()).unwrap();
        assert!(params.table().contains_key("max_range_m"));
        assert_eq!(params.parse::<Example>().unwrap(), Example::default());
    }
}
