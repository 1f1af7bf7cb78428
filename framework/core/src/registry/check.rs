//! Range checks of plugin parameters. Every built-in plugin's config type implements [`PluginParams`],
//! and the registry runs its `check` when a configuration is loaded (`skid config check`, the start of
//! `skid run`), so a negative voxel size or a probability of 2 is refused before anything is built,
//! naming the file and the key, rather than failing minutes later inside the run.

use std::fmt::Display;

use serde::Serialize;
use serde::de::DeserializeOwned;

use super::ParamError;

/// A plugin's parameter type: serde for the file, `Default` for the reference values, `check` for the
/// valid range of every value, and a JSON Schema whose descriptions (the fields' doc comments) `skid
/// plugins` shows.
pub trait PluginParams: DeserializeOwned + Serialize + Default + schemars::JsonSchema + 'static {
    /// Refuses values outside their valid range. The error's `path` is the key relative to the
    /// plugin's table (left empty, it is taken from the first key the message names).
    fn check(&self) -> Result<(), ParamError>;

    /// Checks that the files and folders the parameters name exist, which only the machine that runs
    /// the plugin can judge. `skid config check` calls it; loading a configuration does not, so a
    /// robot's configuration can be shown and checked for values on another machine.
    fn check_files(&self) -> Result<(), ParamError> {
        Ok(())
    }
}

impl ParamError {
    /// An out-of-range value at `path` (relative to the plugin's table).
    pub fn at(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            message: message.into(),
        }
    }

    /// The same error for a key of the nested table `table` (its path gains the table's name).
    pub fn in_table(mut self, table: &str) -> Self {
        self.path = if self.path.is_empty() {
            table.to_owned()
        } else {
            format!("{table}.{}", self.path)
        };
        self
    }

    /// A message that names its key somewhere in its text (the first key it names is the path).
    pub fn named_in(message: impl Into<String>) -> Self {
        Self::at("", message)
    }

    /// A plugin's own validation error as a parameter error: its message without the plugin's name (the
    /// configuration error names the plugin's table already).
    pub fn from_plugin_error(error: crate::PluginError) -> Self {
        match error {
            crate::PluginError::Params(param) => param,
            crate::PluginError::Failed { message, .. } => Self::named_in(message),
            other => Self::named_in(other.to_string()),
        }
    }

    /// Fills an empty `path` with the key of `table` (nested keys dotted) that `message` names first.
    pub(crate) fn locate_in(mut self, table: &toml::Table) -> Self {
        if self.path.is_empty() {
            let mut keys = Vec::new();
            flatten_keys(table, "", &mut keys);
            self.path = keys
                .into_iter()
                .filter_map(|key| first_word_position(&self.message, &key).map(|at| (at, key)))
                .min_by(|(a, key_a), (b, key_b)| a.cmp(b).then(key_b.len().cmp(&key_a.len())))
                .map(|(_, key)| key)
                .unwrap_or_default();
        }
        self
    }
}

fn flatten_keys(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
    for (key, value) in table {
        let full = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        if let toml::Value::Table(inner) = value {
            flatten_keys(inner, &full, out);
        }
        out.push(full);
    }
}

/// Where `word` (or, for a dotted key, its last component) first stands in `text` as a whole word.
fn first_word_position(text: &str, key: &str) -> Option<usize> {
    let word = key.rsplit('.').next().unwrap_or(key);
    let is_word_char = |c: char| c.is_ascii_alphanumeric() || c == '_';
    text.match_indices(word).map(|(at, _)| at).find(|&at| {
        let before = text[..at].chars().next_back().is_none_or(|c| !is_word_char(c));
        let after = text[at + word.len()..]
            .chars()
            .next()
            .is_none_or(|c| !is_word_char(c));
        before && after
    })
}

/// `value` must be finite and above zero.
pub fn positive(key: &str, value: f64) -> Result<(), ParamError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ParamError::at(key, format!("{value} must be a positive number")))
    }
}

/// `value` must be finite and at least zero.
pub fn non_negative(key: &str, value: f64) -> Result<(), ParamError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ParamError::at(
            key,
            format!("{value} must be zero or a positive number"),
        ))
    }
}

/// `value` must be finite and within `[low, high]`.
pub fn within(key: &str, value: f64, low: f64, high: f64) -> Result<(), ParamError> {
    if value.is_finite() && (low..=high).contains(&value) {
        Ok(())
    } else {
        Err(ParamError::at(key, format!("{value} is outside [{low}, {high}]")))
    }
}

/// `config` after its range checks, for a constructor that builds one instance directly (the registry
/// checks a loaded configuration itself, once); a refusal names the plugin and the key.
pub fn checked<C: PluginParams>(plugin: &str, config: C) -> Result<C, crate::PluginError> {
    config
        .check()
        .map_err(|error| crate::PluginError::failed(plugin, error.to_string()))?;
    Ok(config)
}

/// A count or size that must lie within `[low, high]`.
pub fn count_within<T: PartialOrd + Display>(key: &str, value: T, low: T, high: T) -> Result<(), ParamError> {
    if low <= value && value <= high {
        Ok(())
    } else {
        Err(ParamError::at(key, format!("{value} is outside {low} to {high}")))
    }
}

/// `value` must be one of `allowed`.
pub fn one_of(key: &str, value: &str, allowed: &[&str]) -> Result<(), ParamError> {
    if allowed.contains(&value) {
        Ok(())
    } else {
        Err(ParamError::at(
            key,
            format!("{value:?} is not one of: {}", allowed.join(", ")),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> toml::Table {
        text.parse().unwrap()
    }

    #[test]
    fn the_first_key_the_message_names_becomes_the_path() {
        let keys = table("min_range_m = 1\nmax_range_m = 2\nrange = 3\n[link]\nloss = 0.5");
        let located = ParamError::named_in("need 0 <= min_range_m < max_range_m").locate_in(&keys);
        assert_eq!(located.path, "min_range_m");
        // `range` is a word of its own only where it stands alone.
        let located = ParamError::named_in("range must be positive, not max_range_m").locate_in(&keys);
        assert_eq!(located.path, "range");
        let located = ParamError::named_in("loss = 2 must lie in [0, 1]").locate_in(&keys);
        assert_eq!(located.path, "link.loss");
        let kept = ParamError::at("given", "max_range_m").locate_in(&keys);
        assert_eq!(kept.path, "given");
    }

    #[test]
    fn helpers_refuse_out_of_range_values() {
        assert!(positive("a", 1.0).is_ok());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(positive("a", bad).unwrap_err().path, "a");
        }
        assert!(non_negative("a", 0.0).is_ok());
        assert!(non_negative("a", -0.1).is_err());
        assert!(within("p", 1.0, 0.0, 1.0).is_ok());
        assert!(within("p", 2.0, 0.0, 1.0).is_err());
        assert!(within("p", f64::NAN, 0.0, 1.0).is_err());
        assert!(count_within("bins", 0u32, 1, 10).is_err());
        assert!(one_of("world", "mars", &["planetary", "cave"]).is_err());
    }
}
