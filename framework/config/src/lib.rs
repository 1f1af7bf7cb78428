//! SKiD configuration, layered with figment and validated by each plugin's own parameter type.
//!
//! Layers, later ones winning: `configs/default.toml` (or the copy embedded in the binary), a profile
//! overlay `configs/profiles/<name>.toml`, extra overlay files, `SKID_<SECTION>__<KEY>` environment
//! variables (only names containing `__`, so `SKID_DATA_DIR` and friends are left alone), and
//! `--set section.key=value` pairs from the command line.
//!
//! Each slot is a table `[slot]` with `plugin = "name"`; the plugin's parameters live in `[slot.name]`.
//! Switching plugins in an overlay therefore never inherits the previous plugin's keys, and every
//! sub-table is parsed by the plugin's own `deny_unknown_fields` type. Every error names where the bad
//! value came from (file, environment variable or `--set`), the full key path and what was expected.

mod error;
mod layers;
mod resolve;
mod schema;

pub use error::ConfigError;
pub use layers::{ConfigSources, DEFAULT_CONFIG_TOML, EMBEDDED_PROFILES, profile_names_in};
pub use resolve::{ResolvedConfig, ResolvedSlot};
pub use schema::{
    DeployMode, DeploySection, LoopsSection, NONE_PLUGIN, OutputSection, PriorMode, PriorSection, RunSection,
};
