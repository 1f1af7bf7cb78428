//! Where configuration comes from: files, the embedded default, the environment and `--set`.

use std::path::{Path, PathBuf};

use figment::providers::{Env, Format, Toml};
use figment::value::{Dict, Map, Value};
use figment::{Figment, Metadata, Profile, Provider};
use skid_core::Registry;

use crate::resolve::{ResolvedConfig, resolve};
use crate::{ConfigError, schema::RawConfig};

/// The default profile, compiled into every binary so `skid` runs without a checkout.
pub const DEFAULT_CONFIG_TOML: &str = include_str!("../../../configs/default.toml");

/// The profiles, compiled in like the default so `skid run kitti` works outside a checkout. A test checks
/// that this list and `configs/profiles/` agree.
pub const EMBEDDED_PROFILES: &[(&str, &str)] = &[
    (
        "dcl_like",
        include_str!("../../../configs/profiles/dcl_like.toml"),
    ),
    (
        "disco_like",
        include_str!("../../../configs/profiles/disco_like.toml"),
    ),
    ("iris", include_str!("../../../configs/profiles/iris.toml")),
    ("kitti", include_str!("../../../configs/profiles/kitti.toml")),
    ("ransac", include_str!("../../../configs/profiles/ransac.toml")),
    (
        "scan_context",
        include_str!("../../../configs/profiles/scan_context.toml"),
    ),
];

/// Environment variable naming the configuration folder (the one holding `default.toml`).
pub const CONFIG_DIR_VAR: &str = "SKID_CONFIG_DIR";

/// The layers to merge, lowest priority first.
#[derive(Clone, Debug, Default)]
pub struct ConfigSources {
    /// Folder with `default.toml` and `profiles/`; `None` uses the embedded default and no profiles.
    pub config_dir: Option<PathBuf>,
    /// Profile overlay name: merges `<config_dir>/profiles/<name>.toml`.
    pub profile: Option<String>,
    /// Further overlay files, merged in order after the profile.
    pub overlays: Vec<PathBuf>,
    /// `section.key=value` overrides, merged last.
    pub sets: Vec<String>,
    /// Read `SKID_<SECTION>__<KEY>` variables.
    pub use_env: bool,
}

impl ConfigSources {
    /// Sources rooted at the discovered configuration folder, with the environment enabled.
    pub fn discover() -> Self {
        Self {
            config_dir: discover_config_dir(),
            use_env: true,
            ..Self::default()
        }
    }

    /// Merges every layer into a figment, checking that explicitly named files exist and parse.
    pub fn figment(&self) -> Result<Figment, ConfigError> {
        let mut figment = match &self.config_dir {
            Some(dir) => Figment::new().merge(checked_toml(&dir.join("default.toml"))?),
            None => Figment::new().merge(Named {
                inner: Toml::string(DEFAULT_CONFIG_TOML),
                name: "embedded configs/default.toml".to_owned(),
            }),
        };
        if let Some(profile) = &self.profile {
            figment = match self.profile_path(profile)? {
                Some(path) => figment.merge(checked_toml(&path)?),
                None => figment.merge(embedded_profile(profile)?),
            };
        }
        for overlay in &self.overlays {
            figment = figment.merge(checked_toml(overlay)?);
        }
        if self.use_env {
            figment = figment.merge(
                Env::prefixed("SKID_")
                    .filter(|key| key.as_str().contains("__"))
                    .split("__"),
            );
        }
        for argument in &self.sets {
            figment = figment.merge(SetOverride::parse(argument)?);
        }
        Ok(figment)
    }

    /// Loads, merges and validates against the plugins in `registry`.
    pub fn load(&self, registry: &Registry) -> Result<ResolvedConfig, ConfigError> {
        let figment = self.figment()?;
        let raw: RawConfig = figment
            .extract()
            .map_err(|error| crate::resolve::from_figment(&figment, error))?;
        resolve(&figment, raw, registry)
    }

    /// [`Self::load`], then checks that the files and folders every selected plugin names exist on this
    /// machine (`skid config check`); the error names the layer that set the key, and the key.
    pub fn load_and_check_files(&self, registry: &Registry) -> Result<ResolvedConfig, ConfigError> {
        let config = self.load(registry)?;
        let figment = self.figment()?;
        crate::resolve::check_files(&figment, &config)?;
        Ok(config)
    }

    /// Names of the profiles available: the configuration folder's and the embedded ones, sorted.
    pub fn available_profiles(&self) -> Vec<String> {
        let mut names: Vec<String> = EMBEDDED_PROFILES
            .iter()
            .map(|(name, _)| (*name).to_owned())
            .collect();
        if let Some(dir) = &self.config_dir {
            names.extend(profile_names_in(&dir.join("profiles")));
        }
        names.sort();
        names.dedup();
        names
    }

    /// The profile's file in the configuration folder; `None` when only the embedded copy has it.
    fn profile_path(&self, profile: &str) -> Result<Option<PathBuf>, ConfigError> {
        let dir = self
            .config_dir
            .clone()
            .unwrap_or_else(|| PathBuf::from("configs"));
        let path = dir.join("profiles").join(format!("{profile}.toml"));
        if self.config_dir.is_some() && path.is_file() {
            return Ok(Some(path));
        }
        if EMBEDDED_PROFILES.iter().any(|(name, _)| *name == profile) {
            return Ok(None);
        }
        Err(ConfigError::UnknownProfile {
            name: profile.to_owned(),
            path,
            available: self.available_profiles(),
        })
    }
}

/// The `.toml` file stems of a folder.
pub fn profile_names_in(folder: &Path) -> Vec<String> {
    std::fs::read_dir(folder)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| {
            let path = entry.path();
            let is_toml = path.extension().is_some_and(|ext| ext == "toml");
            is_toml
                .then(|| path.file_stem().map(|stem| stem.to_string_lossy().into_owned()))
                .flatten()
        })
        .collect()
}

/// The compiled-in copy of a profile.
fn embedded_profile(profile: &str) -> Result<Named<figment::providers::Data<Toml>>, ConfigError> {
    let (_, text) = EMBEDDED_PROFILES
        .iter()
        .find(|(name, _)| *name == profile)
        .ok_or_else(|| ConfigError::UnknownProfile {
            name: profile.to_owned(),
            path: PathBuf::from(format!("configs/profiles/{profile}.toml")),
            available: EMBEDDED_PROFILES
                .iter()
                .map(|(name, _)| (*name).to_owned())
                .collect(),
        })?;
    Ok(Named {
        inner: Toml::string(text),
        name: format!("embedded configs/profiles/{profile}.toml"),
    })
}

/// The configuration folder: `$SKID_CONFIG_DIR`, else the nearest `configs/` holding `default.toml` in the
/// current folder or one of its parents; `None` when there is none (the embedded default is used).
pub fn discover_config_dir() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os(CONFIG_DIR_VAR) {
        return Some(PathBuf::from(dir));
    }
    let cwd = std::env::current_dir().ok()?;
    cwd.ancestors()
        .map(|dir| dir.join("configs"))
        .find(|dir| dir.join("default.toml").is_file())
}

/// A TOML file provider, after checking that the file exists and is valid TOML (figment would
/// silently skip a missing file and report syntax errors without the file name).
fn checked_toml(path: &Path) -> Result<figment::providers::Data<Toml>, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|error| ConfigError::MissingFile {
        path: path.to_owned(),
        reason: error.to_string(),
    })?;
    text.parse::<toml::Table>().map_err(|error| ConfigError::Syntax {
        path: path.to_owned(),
        message: error.to_string(),
    })?;
    Ok(Toml::file_exact(path))
}

/// A provider under another name, for the embedded default.
struct Named<P> {
    inner: P,
    name: String,
}

impl<P: Provider> Provider for Named<P> {
    fn metadata(&self) -> Metadata {
        Metadata::named(self.name.clone())
    }

    fn data(&self) -> Result<Map<Profile, Dict>, figment::Error> {
        self.inner.data()
    }
}

/// One `--set section.key=value` override. The value is read as TOML (`3`, `true`, `"x"`, `[1, 2]`) and
/// falls back to a plain string, so `--set descriptor.plugin=scan_context` needs no quotes.
struct SetOverride {
    argument: String,
    key: String,
    value: Value,
}

impl SetOverride {
    fn parse(argument: &str) -> Result<Self, ConfigError> {
        let bad = || ConfigError::BadSetArgument {
            argument: argument.to_owned(),
        };
        let (key, raw) = argument.split_once('=').ok_or_else(bad)?;
        let key = key.trim();
        let valid_key = !key.is_empty() && key.split('.').all(|part| !part.is_empty());
        if !valid_key {
            return Err(bad());
        }
        let parsed = format!("value = {raw}")
            .parse::<toml::Table>()
            .ok()
            .and_then(|mut table| table.remove("value"))
            .unwrap_or_else(|| toml::Value::String(raw.to_owned()));
        let value = Value::serialize(parsed).map_err(|_| bad())?;
        Ok(Self {
            argument: argument.to_owned(),
            key: key.to_owned(),
            value,
        })
    }
}

impl Provider for SetOverride {
    fn metadata(&self) -> Metadata {
        Metadata::named(format!("--set {}", self.argument))
    }

    fn data(&self) -> Result<Map<Profile, Dict>, figment::Error> {
        let nested = figment::util::nest(&self.key, self.value.clone());
        let dict = nested.into_dict().unwrap_or_default();
        Ok(Map::from([(Profile::Default, dict)]))
    }
}
