//! One slot's table of plugins: name, summary, default parameters and constructor.

use std::collections::BTreeMap;
use std::sync::Arc;

use super::{ParamDocs, ParamError, Params, PluginContext, PluginParams, Slot, param_docs};
use crate::PluginError;

type Constructor<T> = Arc<dyn Fn(&Params, &PluginContext) -> Result<Box<T>, PluginError> + Send + Sync>;
type Validator = Arc<dyn Fn(&Params) -> Result<(), ParamError> + Send + Sync>;

/// A registered plugin for a slot whose trait object type is `T`.
pub struct PluginEntry<T: ?Sized> {
    name: String,
    summary: String,
    origin: String,
    defaults: Params,
    docs: ParamDocs,
    validate: Validator,
    construct: Constructor<T>,
}

impl<T: ?Sized> Clone for PluginEntry<T> {
    fn clone(&self) -> Self {
        Self {
            name: self.name.clone(),
            summary: self.summary.clone(),
            origin: self.origin.clone(),
            defaults: self.defaults.clone(),
            docs: self.docs.clone(),
            validate: Arc::clone(&self.validate),
            construct: Arc::clone(&self.construct),
        }
    }
}

impl<T: ?Sized + 'static> PluginEntry<T> {
    /// A built-in plugin whose parameters are the serde type `C` (`deny_unknown_fields`, `Default` = the
    /// reference values, `check` = the valid ranges). `construct` receives the parsed, checked parameters.
    pub fn new<C, F>(name: &str, summary: &str, construct: F) -> Result<Self, ParamError>
    where
        C: PluginParams,
        F: Fn(C, &PluginContext) -> Result<Box<T>, PluginError> + Send + Sync + 'static,
    {
        let defaults = Params::from_config(&C::default())?;
        let keys = defaults.table().clone();
        let parse_checked = move |params: &Params| -> Result<C, ParamError> {
            let config = params.parse::<C>()?;
            config.check().map_err(|error| {
                // The keys an error may name: every default, and keys given that have no default (an
                // optional parameter left unset by default).
                let mut named = keys.clone();
                for (key, value) in params.table() {
                    named.entry(key.clone()).or_insert_with(|| value.clone());
                }
                error.locate_in(&named)
            })?;
            Ok(config)
        };
        let parse_for_construct = parse_checked.clone();
        Ok(Self {
            name: name.to_owned(),
            summary: summary.to_owned(),
            origin: "built-in".to_owned(),
            defaults,
            docs: param_docs::<C>(),
            validate: Arc::new(move |params: &Params| parse_checked(params).map(drop)),
            construct: Arc::new(move |params: &Params, context: &PluginContext| {
                let config = parse_for_construct(params)?;
                construct(config, context)
            }),
        })
    }

    /// A plugin whose parameters are checked and parsed by the given closures (dynamic plugins, which
    /// parse their own config string).
    pub fn from_parts(
        name: &str,
        summary: &str,
        origin: &str,
        defaults: Params,
        validate: impl Fn(&Params) -> Result<(), ParamError> + Send + Sync + 'static,
        construct: impl Fn(&Params, &PluginContext) -> Result<Box<T>, PluginError> + Send + Sync + 'static,
    ) -> Self {
        Self {
            name: name.to_owned(),
            summary: summary.to_owned(),
            origin: origin.to_owned(),
            defaults,
            docs: ParamDocs::new(),
            validate: Arc::new(validate),
            construct: Arc::new(construct),
        }
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Builds an instance from parameters (missing keys take their defaults).
    pub fn construct(&self, params: &Params, context: &PluginContext) -> Result<Box<T>, PluginError> {
        (self.construct)(params, context)
    }
}

/// A plugin's public description, for `skid plugins` and config validation messages.
#[derive(Clone, Debug, PartialEq)]
pub struct PluginInfo {
    pub slot: Slot,
    pub name: String,
    pub summary: String,
    /// `built-in`, or the path of the library a dynamic plugin came from.
    pub origin: String,
    pub defaults: Params,
    /// What each parameter means (dotted keys; empty for plugins that do not describe theirs).
    pub docs: ParamDocs,
}

/// The plugins of one slot, by name.
pub struct SlotTable<T: ?Sized> {
    slot: Slot,
    entries: BTreeMap<String, PluginEntry<T>>,
}

impl<T: ?Sized + 'static> SlotTable<T> {
    /// An empty table for `slot`.
    pub fn new(slot: Slot) -> Self {
        Self {
            slot,
            entries: BTreeMap::new(),
        }
    }

    pub fn slot(&self) -> Slot {
        self.slot
    }

    /// Adds a plugin; a second plugin with the same name is refused.
    pub fn register(&mut self, entry: PluginEntry<T>) -> Result<(), PluginError> {
        if self.entries.contains_key(&entry.name) {
            return Err(PluginError::DuplicatePlugin {
                slot: self.slot,
                name: entry.name,
            });
        }
        self.entries.insert(entry.name.clone(), entry);
        Ok(())
    }

    /// The entry called `name`, or an error listing the known names.
    pub fn get(&self, name: &str) -> Result<&PluginEntry<T>, PluginError> {
        self.entries.get(name).ok_or_else(|| PluginError::UnknownPlugin {
            slot: self.slot,
            name: name.to_owned(),
            known: self.entries.keys().cloned().collect(),
        })
    }

    /// Builds the plugin called `name`.
    pub fn create(
        &self,
        name: &str,
        params: &Params,
        context: &PluginContext,
    ) -> Result<Box<T>, PluginError> {
        self.get(name)?.construct(params, context)
    }

    /// Checks parameters for the plugin called `name`.
    pub fn validate(&self, name: &str, params: &Params) -> Result<(), PluginError> {
        (self.get(name)?.validate)(params).map_err(PluginError::from)
    }

    /// Descriptions of every plugin, sorted by name.
    pub fn infos(&self) -> Vec<PluginInfo> {
        self.entries
            .values()
            .map(|entry| PluginInfo {
                slot: self.slot,
                name: entry.name.clone(),
                summary: entry.summary.clone(),
                origin: entry.origin.clone(),
                defaults: entry.defaults.clone(),
                docs: entry.docs.clone(),
            })
            .collect()
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}
