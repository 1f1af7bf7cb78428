//! The plugin side: the safe traits a plugin author implements (one per slot the C ABI carries), config
//! parsing helpers, and the [`export_plugins!`](crate::export_plugins) macro that turns implementations
//! into the C ABI.
//!
//! A plugin crate (`crate-type = ["cdylib"]`, depending on `skid-abi` without the `host` feature) writes:
//!
//! ```
//! use serde::Deserialize;
//! use skid_abi::{ConfigError, DescriptorPlugin, InstanceContext, parse_config};
//! use skid_msgs::Point;
//!
//! #[derive(Default, Deserialize)]
//! #[serde(default, deny_unknown_fields)]
//! struct Config {
//!     scale: f32,
//! }
//!
//! /// The mean height of the cloud, times `scale`.
//! struct MeanHeight {
//!     config: Config,
//! }
//!
//! impl DescriptorPlugin for MeanHeight {
//!     const NAME: &'static str = "mean_height";
//!     const SUMMARY: &'static str = "Mean point height";
//!     const DEFAULT_CONFIG: &'static str = "scale = 1.0\n";
//!
//!     fn from_config(config: &str, _context: &InstanceContext) -> Result<Self, ConfigError> {
//!         Ok(Self { config: parse_config(config)? })
//!     }
//!
//!     fn descriptor_len(&self) -> usize {
//!         1
//!     }
//!
//!     fn describe(&mut self, points: &[Point], out: &mut [f32]) -> Result<(), String> {
//!         if points.is_empty() {
//!             return Err("empty cloud".to_owned());
//!         }
//!         out[0] = self.config.scale * points.iter().map(|p| p.z).sum::<f32>() / points.len() as f32;
//!         Ok(())
//!     }
//! }
//!
//! skid_abi::export_descriptor!(MeanHeight);
//! # fn main() {}
//! ```
//!
//! and no `unsafe` code: the macro's generated items carry their own `#[allow(unsafe_code)]`.

mod backend;
mod descriptor;
mod glue;
mod logger;
mod odometry;
mod panic_hook;
mod registration;
mod source;
mod verifier;

use std::fmt;

use serde::de::DeserializeOwned;

pub use backend::{BackendPlugin, backend_vtable};
pub use descriptor::{DescriptorPlugin, IndexCandidate, IndexPlugin, descriptor_vtable};
pub use glue::{LibraryName, library_decl, plugin_decl};
pub use odometry::{OdometryOutcome, OdometryPlugin, ScanView, odometry_vtable};
pub use registration::{CoarseOutcome, CoarsePlugin, FineOutcome, FinePlugin, coarse_vtable, fine_vtable};
pub use source::{OwnedScan, SourcePlugin, source_vtable};
pub use verifier::{GraphAccess, VerdictOutcome, VerifierPlugin, verifier_vtable};

/// What the host tells a new instance about where it runs (skid-core's `PluginContext`, as it crosses).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InstanceContext {
    /// The robot this instance serves.
    pub robot: u32,
    /// Number of robots in the fleet.
    pub fleet_size: u32,
    /// Threads the instance may use (size any rayon pool from it); at least 1.
    pub threads: usize,
    /// Seed for anything random, so runs are reproducible.
    pub seed: u64,
    /// Folder for the run's outputs, when the host has one.
    pub output_dir: Option<String>,
}

impl Default for InstanceContext {
    /// One robot, one thread, seed 0, no output folder: the host's defaults.
    fn default() -> Self {
        Self {
            robot: 0,
            fleet_size: 1,
            threads: 1,
            seed: 0,
            output_dir: None,
        }
    }
}

/// A config string the plugin refuses: the dotted path of the offending key (empty for the whole
/// config) and the reason.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ConfigError {
    pub key: String,
    pub message: String,
}

impl ConfigError {
    /// An error about one key.
    pub fn for_key(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.key.is_empty() {
            f.write_str(&self.message)
        } else {
            write!(f, "key `{}`: {}", self.key, self.message)
        }
    }
}

impl std::error::Error for ConfigError {}

impl From<String> for ConfigError {
    fn from(message: String) -> Self {
        Self {
            key: String::new(),
            message,
        }
    }
}

impl From<&str> for ConfigError {
    fn from(message: &str) -> Self {
        Self::from(message.to_owned())
    }
}

/// Parses a TOML config string into the plugin's config type, reporting the path of the offending key
/// the same way the host reports built-in plugins' parameters (use `#[serde(default, deny_unknown_fields)]`
/// on the type so missing keys take defaults and unknown keys are refused).
pub fn parse_config<C: DeserializeOwned>(text: &str) -> Result<C, ConfigError> {
    let table = text
        .parse::<toml::Table>()
        .map_err(|error| ConfigError::from(error.to_string()))?;
    serde_path_to_error::deserialize::<_, C>(toml::Value::Table(table)).map_err(|error| {
        let path = error.path().to_string();
        ConfigError {
            key: if path == "." { String::new() } else { path },
            message: error.inner().to_string(),
        }
    })
}

/// Exports this library's plugins: one `slot: Type` pair per plugin, where the slot is `source` (a
/// [`SourcePlugin`]), `odometry` (an [`OdometryPlugin`]), `descriptor` (a [`DescriptorPlugin`]),
/// `coarse` (a [`CoarsePlugin`]), `fine` (a [`FinePlugin`]), `verifier` (a [`VerifierPlugin`]) or
/// `backend` (a [`BackendPlugin`]).
/// Generates the function tables, the static declarations and the `skid_plugin_entry` symbol. Use it
/// once per library:
///
/// ```ignore
/// skid_abi::export_plugins!(descriptor: RingHistogram, fine: PointToPointIcp);
/// ```
#[macro_export]
macro_rules! export_plugins {
    (@one $slot:ident) => {
        1
    };
    (@decl descriptor $plugin:ty) => {{
        static TABLE: $crate::ffi::DescriptorVTable = $crate::plugin::descriptor_vtable::<$plugin>();
        $crate::plugin::plugin_decl(
            $crate::ffi::SlotKind::DESCRIPTOR,
            <$plugin as $crate::DescriptorPlugin>::NAME,
            <$plugin as $crate::DescriptorPlugin>::SUMMARY,
            <$plugin as $crate::DescriptorPlugin>::DEFAULT_CONFIG,
            &TABLE,
        )
    }};
    (@decl backend $plugin:ty) => {{
        static TABLE: $crate::ffi::BackendVTable = $crate::plugin::backend_vtable::<$plugin>();
        $crate::plugin::plugin_decl(
            $crate::ffi::SlotKind::BACKEND,
            <$plugin as $crate::BackendPlugin>::NAME,
            <$plugin as $crate::BackendPlugin>::SUMMARY,
            <$plugin as $crate::BackendPlugin>::DEFAULT_CONFIG,
            &TABLE,
        )
    }};
    (@decl verifier $plugin:ty) => {{
        static TABLE: $crate::ffi::VerifierVTable = $crate::plugin::verifier_vtable::<$plugin>();
        $crate::plugin::plugin_decl(
            $crate::ffi::SlotKind::VERIFIER,
            <$plugin as $crate::VerifierPlugin>::NAME,
            <$plugin as $crate::VerifierPlugin>::SUMMARY,
            <$plugin as $crate::VerifierPlugin>::DEFAULT_CONFIG,
            &TABLE,
        )
    }};
    (@decl source $plugin:ty) => {{
        static TABLE: $crate::ffi::SourceVTable = $crate::plugin::source_vtable::<$plugin>();
        $crate::plugin::plugin_decl(
            $crate::ffi::SlotKind::SOURCE,
            <$plugin as $crate::SourcePlugin>::NAME,
            <$plugin as $crate::SourcePlugin>::SUMMARY,
            <$plugin as $crate::SourcePlugin>::DEFAULT_CONFIG,
            &TABLE,
        )
    }};
    (@decl odometry $plugin:ty) => {{
        static TABLE: $crate::ffi::OdometryVTable = $crate::plugin::odometry_vtable::<$plugin>();
        $crate::plugin::plugin_decl(
            $crate::ffi::SlotKind::ODOMETRY,
            <$plugin as $crate::OdometryPlugin>::NAME,
            <$plugin as $crate::OdometryPlugin>::SUMMARY,
            <$plugin as $crate::OdometryPlugin>::DEFAULT_CONFIG,
            &TABLE,
        )
    }};
    (@decl coarse $plugin:ty) => {{
        static TABLE: $crate::ffi::CoarseVTable = $crate::plugin::coarse_vtable::<$plugin>();
        $crate::plugin::plugin_decl(
            $crate::ffi::SlotKind::COARSE,
            <$plugin as $crate::CoarsePlugin>::NAME,
            <$plugin as $crate::CoarsePlugin>::SUMMARY,
            <$plugin as $crate::CoarsePlugin>::DEFAULT_CONFIG,
            &TABLE,
        )
    }};
    (@decl fine $plugin:ty) => {{
        static TABLE: $crate::ffi::FineVTable = $crate::plugin::fine_vtable::<$plugin>();
        $crate::plugin::plugin_decl(
            $crate::ffi::SlotKind::FINE,
            <$plugin as $crate::FinePlugin>::NAME,
            <$plugin as $crate::FinePlugin>::SUMMARY,
            <$plugin as $crate::FinePlugin>::DEFAULT_CONFIG,
            &TABLE,
        )
    }};
    ($($slot:ident : $plugin:ty),+ $(,)?) => {
        const _: () = {
            /// The library's name for the host's logs: the plugin crate's package name.
            struct SkidLibraryName;

            impl $crate::plugin::LibraryName for SkidLibraryName {
                const NAME: &'static str = env!("CARGO_PKG_NAME");
            }

            static SKID_PLUGINS: [$crate::ffi::PluginDecl; 0 $(+ $crate::export_plugins!(@one $slot))+] =
                [$($crate::export_plugins!(@decl $slot $plugin)),+];

            static SKID_LIBRARY: $crate::ffi::LibraryDecl =
                $crate::plugin::library_decl::<SkidLibraryName>(&SKID_PLUGINS);

            /// The library's entry symbol: the host reads the declaration it points to.
            // `no_mangle` counts as unsafe code; the symbol name is the ABI's and unique per library.
            #[allow(unsafe_code)]
            #[unsafe(no_mangle)]
            pub extern "C" fn skid_plugin_entry() -> *const $crate::ffi::LibraryDecl {
                &SKID_LIBRARY
            }
        };
    };
}

/// Exports a library holding one [`DescriptorPlugin`]: shorthand for
/// [`export_plugins!(descriptor: Type)`](crate::export_plugins).
#[macro_export]
macro_rules! export_descriptor {
    ($plugin:ty) => {
        $crate::export_plugins!(descriptor: $plugin);
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize, PartialEq)]
    #[serde(default, deny_unknown_fields)]
    struct Example {
        num_rings: u32,
        max_range_m: f32,
    }

    #[test]
    fn parse_config_takes_defaults_and_names_unknown_keys() {
        let parsed: Example = parse_config("num_rings = 3").unwrap();
        assert_eq!(
            parsed,
            Example {
                num_rings: 3,
                max_range_m: 0.0
            }
        );
        let error = parse_config::<Example>("num_ringz = 3").unwrap_err();
        assert_eq!(error.key, "num_ringz");
        assert!(error.message.contains("num_rings"), "{error}");
        let error = parse_config::<Example>("num_rings = ").unwrap_err();
        assert!(
            error.key.is_empty() && error.message.contains("line 1"),
            "{error}"
        );
    }
}
