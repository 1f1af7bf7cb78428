//! A plugin's parameters read once: the table as given (defaults filled in) and the typed, range-checked
//! value the plugin's constructor takes. A configuration is parsed and checked when it is loaded; every
//! instance (one per robot) is then built from the same value, without parsing or checking again.

use std::any::Any;
use std::fmt;
use std::sync::Arc;

use super::{ParamError, Params};

/// Checks that the files a plugin's parameters name exist (see `PluginParams::check_files`).
pub(crate) type FilesCheck = Arc<dyn Fn() -> Result<(), ParamError> + Send + Sync>;

/// Parameters parsed and checked for one plugin, ready to build any number of instances.
#[derive(Clone)]
pub struct ParsedParams {
    plugin: String,
    params: Params,
    value: Arc<dyn Any + Send + Sync>,
    files: Option<FilesCheck>,
}

impl ParsedParams {
    pub(crate) fn new(
        plugin: &str,
        params: Params,
        value: Arc<dyn Any + Send + Sync>,
        files: Option<FilesCheck>,
    ) -> Self {
        Self {
            plugin: plugin.to_owned(),
            params,
            value,
            files,
        }
    }

    /// Checks that the files and folders the parameters name exist on this machine; the error's `path`
    /// is the key. Plugins that name no file (and dynamic plugins, which check in `create`) pass.
    pub fn check_files(&self) -> Result<(), ParamError> {
        self.files.as_ref().map_or(Ok(()), |check| check())
    }

    /// The plugin these parameters were parsed for.
    pub fn plugin(&self) -> &str {
        &self.plugin
    }

    /// The parameter table they were parsed from.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The typed value, when it is of type `C`.
    pub(crate) fn value<C: 'static>(&self) -> Option<&C> {
        self.value.downcast_ref::<C>()
    }
}

impl PartialEq for ParsedParams {
    fn eq(&self, other: &Self) -> bool {
        self.plugin == other.plugin && self.params == other.params
    }
}

impl fmt::Debug for ParsedParams {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ParsedParams")
            .field("plugin", &self.plugin)
            .field("params", &self.params)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use std::cell::Cell;

    use serde::{Deserialize, Serialize};

    use crate::registry::{PluginContext, PluginEntry, PluginParams, SlotTable};
    use crate::{ParamError, Params, PluginError, Slot};

    thread_local! {
        /// The checks run on this test's thread (the tests run in parallel).
        static CHECKS: Cell<usize> = const { Cell::new(0) };
    }

    #[derive(Clone, Debug, Default, Deserialize, Serialize, schemars::JsonSchema)]
    #[serde(default, deny_unknown_fields)]
    struct Counted {
        size_m: f64,
    }

    impl PluginParams for Counted {
        fn check(&self) -> Result<(), ParamError> {
            CHECKS.set(CHECKS.get() + 1);
            crate::registry::check::non_negative("size_m", self.size_m)
        }
    }

    /// A stand-in plugin object: the size it was built with.
    type Built = f64;

    fn table() -> SlotTable<Built> {
        let mut table = SlotTable::new(Slot::Fine);
        let entry = |name: &str| {
            PluginEntry::new(name, "test", |config: Counted, _: &PluginContext| {
                Ok(Box::new(config.size_m))
            })
            .unwrap()
        };
        table.register(entry("counted")).unwrap();
        table.register(entry("other")).unwrap();
        table
    }

    #[test]
    fn parameters_are_parsed_and_checked_once_for_any_number_of_instances() {
        let table = table();
        let params = Params::from_toml_str("size_m = 0.5").unwrap();
        let before = CHECKS.get();
        let parsed = table.parse("counted", &params).unwrap();
        let built: Vec<f64> = (0..4)
            .map(|_| *table.build(&parsed, &PluginContext::default()).unwrap())
            .collect();
        assert_eq!(built, vec![0.5; 4]);
        assert_eq!(CHECKS.get() - before, 1, "checked more than once");
        assert_eq!(parsed.plugin(), "counted");
        assert_eq!(parsed.params(), &params);
    }

    #[test]
    fn out_of_range_values_are_refused_at_parse_with_their_key() {
        let table = table();
        let params = Params::from_toml_str("size_m = -1.0").unwrap();
        let Err(PluginError::Params(error)) = table.parse("counted", &params) else {
            panic!("a negative size was accepted");
        };
        assert_eq!(error.path, "size_m");
    }

    #[test]
    fn parameters_parsed_for_one_plugin_do_not_build_another() {
        let table = table();
        let parsed = table.parse("counted", &Params::default()).unwrap();
        let entry = table.get("other").unwrap();
        let Err(error) = entry.build(&parsed, &PluginContext::default()) else {
            panic!("built `other` from parameters parsed for `counted`");
        };
        assert!(error.to_string().contains("counted"), "{error}");
    }
}
