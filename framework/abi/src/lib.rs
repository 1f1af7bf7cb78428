//! SKiD's versioned C ABI for out-of-tree plugins built as `cdylib`s.
//!
//! Rust trait objects cannot cross a dynamic-library boundary soundly, so a plugin library exports one
//! `extern "C"` symbol, [`ENTRY_SYMBOL`], returning a pointer to a static [`ffi::LibraryDecl`]: ABI
//! version, wire-type layout fingerprint and framework version first, then the library's name, a logger
//! installer and its plugins, each a [`ffi::PluginDecl`] with slot kind, name, summary, default TOML
//! config and the slot's function table. Every plugin slot crosses: source, odometry, descriptor, coarse
//! and fine registration, verifier and back-end (the transport, part of the host, does not); the C
//! header `include/skid_plugin.h` declares the same types for plugins written in C or C++. Only
//! `#[repr(C)]` data and `extern "C"` function pointers cross; every exported function catches panics;
//! config crosses as UTF-8 TOML that the plugin parses itself; clouds cross as borrowed point buffers;
//! results and error messages go into host-allocated structs and buffers, and what a plugin lends back
//! (a prepared cloud, a keyframe, a scan, a verdict, the graph's lists) stays its own until it is freed
//! or the next call.
//!
//! - Plugin side (always compiled, light): implement [`SourcePlugin`], [`OdometryPlugin`],
//!   [`DescriptorPlugin`], [`CoarsePlugin`], [`FinePlugin`], [`VerifierPlugin`] or [`BackendPlugin`] in
//!   safe Rust and call [`export_plugins!`] (or [`export_descriptor!`] for one descriptor). Use
//!   [`parse_config`] for `deny_unknown_fields` configs with key paths.
//! - Host side (feature `host`): [`load_library`] opens and checks a library; each of its
//!   [`LoadedPlugin`]s registers itself into a `skid_core::Registry` like a built-in.

// Unsafe code is the point of this crate: it declares the C ABI, reads raw pointers handed across it,
// and exports `#[no_mangle]` symbols. Every unsafe block carries a `SAFETY:` comment.
#![allow(unsafe_code)]

pub mod ffi;
pub mod plugin;

#[cfg(feature = "core")]
pub mod graph;
#[cfg(feature = "host")]
pub mod host;
#[cfg(feature = "nalgebra")]
pub mod transform;

pub use ffi::AbiTransform;
pub use plugin::{
    BackendPlugin, CoarseOutcome, CoarsePlugin, ConfigError, DescriptorPlugin, FineOutcome, FinePlugin,
    GraphAccess, IndexCandidate, IndexPlugin, InstanceContext, OdometryOutcome, OdometryPlugin, OwnedScan,
    ScanView, SourcePlugin, VerdictOutcome, VerifierPlugin, parse_config,
};

#[cfg(feature = "host")]
pub use host::{AbiError, LoadedLibrary, LoadedPlugin, load_into, load_library};

/// Version of the C ABI. Bump it on any change to the declaration or a function table.
pub const ABI_VERSION: u32 = 4;

/// The version of this crate, which a plugin and the host must agree on (same major, and same minor
/// while the major is 0).
pub const FRAMEWORK_VERSION: &str = env!("CARGO_PKG_VERSION");

/// The name of the entry symbol every plugin library exports.
pub const ENTRY_SYMBOL: &str = "skid_plugin_entry";

/// The signature of the entry symbol.
pub type EntryFn = extern "C" fn() -> *const ffi::LibraryDecl;

/// True when a plugin built against framework version `plugin` can be loaded by a host of version
/// `host`: same major version and, while the major version is 0, the same minor version.
pub fn framework_versions_compatible(plugin: &str, host: &str) -> bool {
    fn major_minor(version: &str) -> Option<(u64, u64)> {
        let mut parts = version.split('.');
        let major = parts.next()?.parse().ok()?;
        let minor = parts.next()?.parse().ok()?;
        Some((major, minor))
    }
    match (major_minor(plugin), major_minor(host)) {
        (Some((0, plugin_minor)), Some((0, host_minor))) => plugin_minor == host_minor,
        (Some((plugin_major, _)), Some((host_major, _))) => plugin_major == host_major,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framework_version_compatibility_follows_semver() {
        assert!(framework_versions_compatible("0.1.0", "0.1.7"));
        assert!(!framework_versions_compatible("0.2.0", "0.1.0"));
        assert!(framework_versions_compatible("1.2.0", "1.5.3"));
        assert!(!framework_versions_compatible("2.0.0", "1.0.0"));
        assert!(!framework_versions_compatible("garbage", "0.1.0"));
    }
}
