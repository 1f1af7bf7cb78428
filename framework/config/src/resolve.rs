//! From the merged layers to a validated configuration: plugin names checked against the registry,
//! every plugin table parsed by its plugin, and errors traced back to the layer that caused them.

use std::collections::BTreeMap;

use figment::error::Kind;
use figment::{Figment, Source};
use skid_core::{Params, ParsedParams, Registry, Slot};

use crate::schema::{AUTO_PLUGIN, MAX_ROBOTS, NONE_PLUGIN, RawConfig, RawSlot};
use crate::{ConfigError, DeploySection, LoopsSection, OutputSection, PriorSection, RunSection};

/// One slot after validation: the selected plugin, its complete parameters (defaults filled in) and,
/// unless the slot is empty, those parameters parsed and checked, from which every robot's instance is
/// built.
#[derive(Clone, Debug, PartialEq)]
pub struct ResolvedSlot {
    pub plugin: String,
    pub params: Params,
    pub parsed: Option<ParsedParams>,
}

impl ResolvedSlot {
    /// True when the slot is left empty (`plugin = "none"`).
    pub fn is_none(&self) -> bool {
        self.plugin == NONE_PLUGIN
    }

    /// Builds an instance of the selected plugin from the parameters parsed at load time (a slot put
    /// together by hand, without them, is parsed here).
    pub fn build<T: ?Sized + 'static>(
        &self,
        table: &skid_core::SlotTable<T>,
        context: &skid_core::PluginContext,
    ) -> Result<Box<T>, skid_core::PluginError> {
        match &self.parsed {
            Some(parsed) => table.build(parsed, context),
            None => table.create(&self.plugin, &self.params, context),
        }
    }

    /// An empty slot.
    pub fn none() -> Self {
        Self {
            plugin: NONE_PLUGIN.to_owned(),
            params: Params::default(),
            parsed: None,
        }
    }
}

/// A validated configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct ResolvedConfig {
    pub run: RunSection,
    pub deploy: DeploySection,
    pub loops: LoopsSection,
    pub output: OutputSection,
    pub prior: PriorSection,
    pub slots: BTreeMap<Slot, ResolvedSlot>,
}

impl ResolvedConfig {
    /// The resolved table of a slot (every slot is present after resolution).
    pub fn slot(&self, slot: Slot) -> &ResolvedSlot {
        static NONE: std::sync::OnceLock<ResolvedSlot> = std::sync::OnceLock::new();
        self.slots
            .get(&slot)
            .unwrap_or_else(|| NONE.get_or_init(ResolvedSlot::none))
    }

    /// The effective configuration as TOML: run, deploy, and each slot with only its selected plugin's
    /// complete parameters.
    pub fn to_toml_string(&self) -> String {
        let mut root = toml::Table::new();
        if let Ok(toml::Value::Table(run)) = toml::Value::try_from(&self.run) {
            root.insert("run".to_owned(), toml::Value::Table(run));
        }
        if let Ok(toml::Value::Table(deploy)) = toml::Value::try_from(&self.deploy) {
            root.insert("deploy".to_owned(), toml::Value::Table(deploy));
        }
        if let Ok(toml::Value::Table(loops)) = toml::Value::try_from(&self.loops) {
            root.insert("loops".to_owned(), toml::Value::Table(loops));
        }
        if let Ok(toml::Value::Table(output)) = toml::Value::try_from(&self.output) {
            root.insert("output".to_owned(), toml::Value::Table(output));
        }
        if let Ok(toml::Value::Table(prior)) = toml::Value::try_from(&self.prior) {
            root.insert("prior".to_owned(), toml::Value::Table(prior));
        }
        for (slot, resolved) in &self.slots {
            let mut table = toml::Table::new();
            table.insert("plugin".to_owned(), toml::Value::String(resolved.plugin.clone()));
            if resolved.plugin == AUTO_PLUGIN {
                // The candidates' tables, where a configuration file sets them.
                table.extend(resolved.params.table().clone());
            } else if !resolved.is_none() {
                table.insert(
                    resolved.plugin.clone(),
                    toml::Value::Table(resolved.params.table().clone()),
                );
            }
            root.insert(slot.key().to_owned(), toml::Value::Table(table));
        }
        toml::to_string_pretty(&root).unwrap_or_default()
    }
}

/// The most worker threads a run may ask for (far above any core count it can use).
const MAX_THREADS: usize = 256;

/// A run's name becomes a folder under `run.output_dir`: one plain path component, so a run can never
/// write outside that folder.
fn check_run_name(name: &str) -> Result<(), String> {
    if name.trim().is_empty() {
        return Err("the run name is empty; it names the folder under run.output_dir".into());
    }
    if name == "." || name == ".." || name.contains(['/', '\\', '\0']) {
        return Err(format!(
            "{name:?} is not a plain folder name (no `/`, `\\`, `.` or `..`): the run must stay inside run.output_dir"
        ));
    }
    if name.len() > 128 {
        return Err(format!("{} characters; at most 128", name.len()));
    }
    Ok(())
}

/// Validates the merged configuration against the registry.
pub(crate) fn resolve(
    figment: &Figment,
    raw: RawConfig,
    registry: &Registry,
) -> Result<ResolvedConfig, ConfigError> {
    if !(1..=MAX_ROBOTS).contains(&raw.run.robots) {
        return Err(invalid(
            figment,
            "run.robots",
            format!("{} robots; expected 1 to {MAX_ROBOTS}", raw.run.robots),
        ));
    }
    if let Err(reason) = check_run_name(&raw.run.name) {
        return Err(invalid(figment, "run.name", reason));
    }
    if raw.run.threads > MAX_THREADS {
        return Err(invalid(
            figment,
            "run.threads",
            format!(
                "{} threads; expected 0 (one per core) to {MAX_THREADS}",
                raw.run.threads
            ),
        ));
    }
    raw.deploy
        .validate(raw.run.robots)
        .and_then(|()| raw.output.validate())
        .and_then(|()| raw.loops.validate())
        .and_then(|()| raw.prior.validate())
        .map_err(|error| invalid(figment, error.key, error.message))?;
    let mut slots = BTreeMap::new();
    for slot in Slot::ALL {
        let resolved = match raw.slot(slot) {
            Some(table) => resolve_slot(figment, slot, table, registry)?,
            None if slot == Slot::Source => {
                return Err(invalid(
                    figment,
                    "source",
                    "missing: every configuration needs a [source] table".into(),
                ));
            }
            None => ResolvedSlot::none(),
        };
        slots.insert(slot, resolved);
    }
    Ok(ResolvedConfig {
        run: raw.run,
        deploy: raw.deploy,
        loops: raw.loops,
        output: raw.output,
        prior: raw.prior,
        slots,
    })
}

fn resolve_slot(
    figment: &Figment,
    slot: Slot,
    table: &RawSlot,
    registry: &Registry,
) -> Result<ResolvedSlot, ConfigError> {
    let known = registry.infos(slot);
    let known_names = || {
        known
            .iter()
            .map(|info| info.name.clone())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let plugin_key = format!("{slot}.plugin");
    let selected = table.plugin.as_str();
    let none_allowed = slot != Slot::Source;
    if selected == NONE_PLUGIN && !none_allowed {
        return Err(invalid(
            figment,
            &plugin_key,
            format!("the source slot cannot be `none`; known: {}", known_names()),
        ));
    }
    if selected != NONE_PLUGIN && !known.iter().any(|info| info.name == selected) {
        if let Some(how_to_build) = registry.left_out(slot, selected) {
            let message = format!("the {slot} plugin `{selected}` is not in this build: {how_to_build}");
            return Err(invalid(figment, &plugin_key, message));
        }
        let message = format!(
            "unknown {slot} plugin `{selected}`; known {slot} plugins: {}{}",
            known_names(),
            if none_allowed { ", none" } else { "" }
        );
        return Err(invalid(figment, &plugin_key, message));
    }
    // Every parameter table must belong to a plugin of this slot and parse as that plugin's parameters,
    // so a typo in a plugin that is not selected today is still caught. Each table is parsed once: the
    // selected plugin's, with its defaults filled in, is kept to build every robot's instance from.
    let parse = |name: &str, params: &Params, key: &str| {
        registry.parse(slot, name, params).map_err(|error| match error {
            skid_core::PluginError::Params(param) => {
                let full = if param.path.is_empty() {
                    key.to_owned()
                } else {
                    format!("{key}.{}", param.path)
                };
                invalid(figment, &full, param.message)
            }
            other => invalid(figment, key, other.to_string()),
        })
    };
    let mut selected_params = None;
    for (name, value) in &table.tables {
        let key = format!("{slot}.{name}");
        if name == AUTO_PLUGIN {
            let message = format!(
                "`auto` has no parameters of its own: it runs one of the plugins it chooses between with that plugin's table ({})",
                candidate_keys(&known, slot).join(", ")
            );
            return Err(invalid(figment, &key, message));
        }
        let Some(info) = known.iter().find(|info| &info.name == name) else {
            // The parameters of a plugin this build leaves out cannot be checked; unless it is selected
            // (refused above) they are kept for the builds that have it, as a shared robot file may be.
            if registry.left_out(slot, name).is_some() {
                continue;
            }
            let message = format!(
                "`{name}` is not a {slot} plugin; expected `plugin` or a table named after one of: {}",
                known_names()
            );
            return Err(invalid(figment, &key, message));
        };
        let toml::Value::Table(given) = value else {
            return Err(invalid(
                figment,
                &key,
                format!(
                    "expected a table of {name} parameters, found a {}",
                    value.type_str()
                ),
            ));
        };
        if name == selected {
            selected_params = Some(Params::new(merged(info.defaults.table(), given)));
        } else {
            parse(name, &Params::new(given.clone()), &key)?;
        }
    }
    if selected == NONE_PLUGIN {
        return Ok(ResolvedSlot::none());
    }
    let params = if selected == AUTO_PLUGIN {
        auto_params(&known, table)
    } else {
        selected_params.unwrap_or_else(|| {
            known
                .iter()
                .find(|info| info.name == selected)
                .map(|info| info.defaults.clone())
                .unwrap_or_default()
        })
    };
    // The `auto` plugin's parameters are its candidates' tables, `[slot.candidate]`.
    let key = if selected == AUTO_PLUGIN {
        slot.key().to_owned()
    } else if table.tables.contains_key(selected) {
        format!("{slot}.{selected}")
    } else {
        plugin_key
    };
    let parsed = parse(selected, &params, &key)?;
    Ok(ResolvedSlot {
        plugin: selected.to_owned(),
        params,
        parsed: Some(parsed),
    })
}

/// The `auto` plugin's defaults name its candidates, one table each; the keys `[slot.candidate]` set them.
fn candidate_keys(known: &[skid_core::PluginInfo], slot: Slot) -> Vec<String> {
    known
        .iter()
        .find(|info| info.name == AUTO_PLUGIN)
        .map(|info| {
            info.defaults
                .table()
                .keys()
                .map(|name| format!("{slot}.{name}"))
                .collect()
        })
        .unwrap_or_default()
}

/// The `auto` plugin's parameters: each candidate's own table from the file, laid over its defaults.
fn auto_params(known: &[skid_core::PluginInfo], table: &RawSlot) -> Params {
    let Some(auto) = known.iter().find(|info| info.name == AUTO_PLUGIN) else {
        return Params::default();
    };
    let mut params = toml::Table::new();
    for (candidate, defaults) in auto.defaults.table() {
        let defaults = defaults.as_table().cloned().unwrap_or_default();
        let given = table.tables.get(candidate).and_then(toml::Value::as_table);
        let value = given.map_or_else(|| defaults.clone(), |given| merged(&defaults, given));
        params.insert(candidate.clone(), toml::Value::Table(value));
    }
    Params::new(params)
}

/// `given` laid over `defaults`, recursively for nested tables.
fn merged(defaults: &toml::Table, given: &toml::Table) -> toml::Table {
    let mut out = defaults.clone();
    for (key, value) in given {
        let combined = match (out.get(key), value) {
            (Some(toml::Value::Table(base)), toml::Value::Table(over)) => {
                toml::Value::Table(merged(base, over))
            }
            _ => value.clone(),
        };
        out.insert(key.clone(), combined);
    }
    out
}

/// Checks the files every selected plugin's parameters name (see `ParsedParams::check_files`).
pub(crate) fn check_files(figment: &Figment, config: &ResolvedConfig) -> Result<(), ConfigError> {
    for slot in Slot::ALL {
        let resolved = config.slot(slot);
        if let Some(parsed) = &resolved.parsed {
            parsed.check_files().map_err(|error| {
                let key = format!("{}.{}.{}", slot.key(), resolved.plugin, error.path);
                invalid(figment, &key, error.message)
            })?;
        }
    }
    Ok(())
}

/// An invalid-value error for `key`, naming the layer that supplied it.
fn invalid(figment: &Figment, key: &str, message: String) -> ConfigError {
    ConfigError::Invalid {
        origin: origin_of(figment, key),
        key: key.to_owned(),
        message,
    }
}

/// Describes the layer that supplied `key` (or its nearest present parent).
fn origin_of(figment: &Figment, key: &str) -> String {
    let mut probe = key.to_owned();
    loop {
        if let Some(metadata) = figment.find_metadata(&probe) {
            return describe_metadata(metadata, &probe);
        }
        match probe.rfind('.') {
            Some(dot) => probe.truncate(dot),
            None => return "configuration".to_owned(),
        }
    }
}

fn describe_metadata(metadata: &figment::Metadata, key: &str) -> String {
    match &metadata.source {
        Some(Source::File(path)) => {
            let shown = std::env::current_dir()
                .ok()
                .and_then(|cwd| path.strip_prefix(cwd).ok().map(|p| p.to_owned()));
            shown.unwrap_or_else(|| path.clone()).display().to_string()
        }
        // The variable is named back from the key the way `SKID_<SECTION>__<KEY>` was split.
        _ if metadata.name.contains("environment") => {
            format!(
                "environment variable SKID_{}",
                key.to_uppercase().replace('.', "__")
            )
        }
        _ => metadata.name.to_string(),
    }
}

/// Turns figment's error (unknown section, wrong type in `[run]`, …) into one that names the layer.
pub(crate) fn from_figment(figment: &Figment, error: figment::Error) -> ConfigError {
    let mut key = error.path.join(".");
    let message = match &error.kind {
        Kind::UnknownField(field, expected) => {
            if error.path.last() != Some(field) {
                key = if key.is_empty() {
                    field.clone()
                } else {
                    format!("{key}.{field}")
                };
            }
            format!("unknown key `{field}`; expected one of: {}", expected.join(", "))
        }
        Kind::MissingField(field) => {
            if error.path.last().map(String::as_str) != Some(field.as_ref()) {
                key = if key.is_empty() {
                    field.to_string()
                } else {
                    format!("{key}.{field}")
                };
            }
            format!("missing key `{field}`")
        }
        Kind::UnknownVariant(found, expected) => {
            let expected: Vec<String> = expected.iter().map(|name| format!("`{name}`")).collect();
            format!(
                "unknown value `{found}`; expected one of: {}",
                expected.join(", ")
            )
        }
        other => other.to_string(),
    };
    // A value of the wrong type says what serde expected; the fleet size's range is worth saying too.
    let message =
        if key == "run.robots" && matches!(error.kind, Kind::InvalidType(..) | Kind::InvalidValue(..)) {
            format!("{message}: the number of robots, 1 to {MAX_ROBOTS}")
        } else {
            message
        };
    let origin = if key.is_empty() {
        error
            .metadata
            .as_ref()
            .map(|m| m.name.to_string())
            .unwrap_or_else(|| "configuration".to_owned())
    } else {
        origin_of(figment, &key)
    };
    ConfigError::Invalid { origin, key, message }
}

#[cfg(test)]
mod tests {
    use super::check_run_name;

    #[test]
    fn run_names_stay_inside_the_output_folder() {
        assert!(check_run_name("default").is_ok());
        assert!(check_run_name("kitti-00_v2").is_ok());
        for bad in ["", "  ", ".", "..", "../../x", "a/b", "a\\b", "nul\0"] {
            assert!(check_run_name(bad).is_err(), "{bad:?}");
        }
    }
}
