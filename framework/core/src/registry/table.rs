//! One slot's table of plugins: name, summary, default parameters, and the two steps that make an
//! instance: parsing and checking the parameters (once per configuration) and building from the parsed
//! value (once per robot).

use std::collections::BTreeMap;
use std::sync::Arc;

use super::parsed::FilesCheck;
use super::{ParamDocs, ParamError, Params, ParsedParams, PluginContext, PluginParams, Slot, param_docs};
use crate::PluginError;

type Builder<T> = Arc<dyn Fn(&ParsedParams, &PluginContext) -> Result<Box<T>, PluginError> + Send + Sync>;
type Parser = Arc<dyn Fn(&Params) -> Result<ParsedParams, ParamError> + Send + Sync>;
type Creator<T> = Arc<dyn Fn(&Params, &PluginContext) -> Result<Box<T>, PluginError> + Send + Sync>;

/// A registered plugin for a slot whose trait object type is `T`.
pub struct PluginEntry<T: ?Sized> {
    name: String,
    summary: String,
    origin: String,
    defaults: Params,
    docs: ParamDocs,
    parse: Parser,
    build: Builder<T>,
    /// Parse and build in one step, for tools that build one instance.
    create: Creator<T>,
}

impl<T: ?Sized> Clone for PluginEntry<T> {
    fn clone(&self) -> Self {
        Self {
            name: self.name.clone(),
            summary: self.summary.clone(),
            origin: self.origin.clone(),
            defaults: self.defaults.clone(),
            docs: self.docs.clone(),
            parse: Arc::clone(&self.parse),
            build: Arc::clone(&self.build),
            create: Arc::clone(&self.create),
        }
    }
}

impl<T: ?Sized + 'static> PluginEntry<T> {
    /// A built-in plugin whose parameters are the serde type `C` (`deny_unknown_fields`, `Default` = the
    /// reference values, `check` = the valid ranges). The parameters are parsed and checked once, by
    /// [`PluginEntry::parse`]; `construct` receives a copy of that checked value for each instance.
    pub fn new<C, F>(name: &str, summary: &str, construct: F) -> Result<Self, ParamError>
    where
        C: PluginParams + Clone + Send + Sync,
        F: Fn(C, &PluginContext) -> Result<Box<T>, PluginError> + Send + Sync + 'static,
    {
        let defaults = Params::from_config(&C::default())?;
        let keys = defaults.table().clone();
        let plugin = name.to_owned();
        let parse = move |params: &Params| -> Result<ParsedParams, ParamError> {
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
            let config = Arc::new(config);
            let files: FilesCheck = {
                let config = Arc::clone(&config);
                Arc::new(move || config.check_files())
            };
            Ok(ParsedParams::new(&plugin, params.clone(), config, Some(files)))
        };
        let parse = Arc::new(parse);
        let build = {
            let plugin = name.to_owned();
            Arc::new(move |parsed: &ParsedParams, context: &PluginContext| {
                let config = parsed
                    .value::<C>()
                    .filter(|_| parsed.plugin() == plugin)
                    .cloned()
                    .ok_or_else(|| {
                        PluginError::failed(
                            &plugin,
                            format!("parameters parsed for `{}`, not for this plugin", parsed.plugin()),
                        )
                    })?;
                construct(config, context)
            })
        };
        let create = {
            let (parse, build) = (Arc::clone(&parse), Arc::clone(&build));
            Arc::new(move |params: &Params, context: &PluginContext| build(&parse(params)?, context))
        };
        Ok(Self {
            name: name.to_owned(),
            summary: summary.to_owned(),
            origin: "built-in".to_owned(),
            defaults,
            docs: param_docs::<C>(),
            parse,
            build,
            create,
        })
    }

    /// A plugin whose parameters are checked by `validate` and read by `construct` from the table
    /// itself (dynamic plugins, which parse their own config string, so `construct` checks them too and
    /// building one instance directly skips `validate`).
    pub fn from_parts(
        name: &str,
        summary: &str,
        origin: &str,
        defaults: Params,
        validate: impl Fn(&Params) -> Result<(), ParamError> + Send + Sync + 'static,
        construct: impl Fn(&Params, &PluginContext) -> Result<Box<T>, PluginError> + Send + Sync + 'static,
    ) -> Self {
        let plugin = name.to_owned();
        let parse = move |params: &Params| {
            validate(params)?;
            Ok(ParsedParams::new(&plugin, params.clone(), Arc::new(()), None))
        };
        let construct = Arc::new(construct);
        let build = {
            let construct = Arc::clone(&construct);
            move |parsed: &ParsedParams, context: &PluginContext| construct(parsed.params(), context)
        };
        Self {
            name: name.to_owned(),
            summary: summary.to_owned(),
            origin: origin.to_owned(),
            defaults,
            docs: ParamDocs::new(),
            parse: Arc::new(parse),
            build: Arc::new(build),
            create: Arc::new(move |params: &Params, context: &PluginContext| construct(params, context)),
        }
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Parses and checks parameters (missing keys take their defaults).
    pub fn parse(&self, params: &Params) -> Result<ParsedParams, ParamError> {
        (self.parse)(params)
    }

    /// Builds an instance from parameters parsed by [`PluginEntry::parse`].
    pub fn build(&self, parsed: &ParsedParams, context: &PluginContext) -> Result<Box<T>, PluginError> {
        (self.build)(parsed, context)
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

    /// Parses, checks and builds the plugin called `name` (tools that build one instance; a run parses
    /// once with [`SlotTable::parse`] and builds each robot's with [`SlotTable::build`]).
    pub fn create(
        &self,
        name: &str,
        params: &Params,
        context: &PluginContext,
    ) -> Result<Box<T>, PluginError> {
        (self.get(name)?.create)(params, context)
    }

    /// Parses and checks parameters for the plugin called `name`.
    pub fn parse(&self, name: &str, params: &Params) -> Result<ParsedParams, PluginError> {
        Ok(self.get(name)?.parse(params)?)
    }

    /// Builds the plugin the parsed parameters are for.
    pub fn build(&self, parsed: &ParsedParams, context: &PluginContext) -> Result<Box<T>, PluginError> {
        self.get(parsed.plugin())?.build(parsed, context)
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
