//! The host side (feature `host`): opens plugin libraries, checks them, and wraps their plugins' C
//! tables back into skid-core's slot traits so they register into a [`Registry`] like built-ins.
//!
//! Libraries are never unloaded: each one is leaked into a process-wide list the first time it loads,
//! and loading the same file again returns the same plugin. Instances are destroyed by their wrappers'
//! `Drop`, always before the process ends and always while their library is still mapped.

mod backend;
mod call;
mod code_address;
mod descriptor;
mod index;
mod instance;
mod library;
mod logging;
mod odometry;
mod plugin_index;
mod registration;
mod source;
mod verifier;

use std::path::{Path, PathBuf};

use skid_core::{ParamError, Params, PluginError, Registry, Slot};

pub use backend::DynBackend;
pub use descriptor::DynDescriptor;
pub use index::ExactL2Index;
pub use logging::PLUGIN_TARGET;
pub use odometry::DynOdometry;
pub use plugin_index::PluginIndex;
pub use registration::{DynCoarse, DynFine};
pub use source::DynSource;
pub use verifier::DynVerifier;

use library::{Library, PluginSpec, SlotTable};

/// Why a plugin library could not be loaded or registered.
#[derive(Debug, thiserror::Error)]
pub enum AbiError {
    /// The file does not exist.
    #[error("plugin library {} not found", path.display())]
    NotFound { path: PathBuf },

    /// The file exists but the dynamic loader refused it.
    #[error("{} is not a loadable plugin library: {source}", path.display())]
    NotALibrary {
        path: PathBuf,
        source: libloading::Error,
    },

    /// The library does not export the entry symbol.
    #[error("{} exports no `{symbol}` symbol; is it a SKiD plugin built with skid-abi's export macro? ({source})", path.display())]
    MissingSymbol {
        path: PathBuf,
        symbol: &'static str,
        source: libloading::Error,
    },

    /// The plugin speaks another version of the C ABI.
    #[error("{}: plugin built for ABI v{plugin}, host speaks v{host}; rebuild the plugin against this skid-abi", path.display())]
    AbiVersion { path: PathBuf, plugin: u32, host: u32 },

    /// The plugin's wire types have another layout.
    #[error(
        "{}: wire type layout mismatch (plugin fingerprint {plugin:#018x}, host {host:#018x}); rebuild the plugin against this skid-msgs",
        path.display()
    )]
    Layout { path: PathBuf, plugin: u64, host: u64 },

    /// The plugin was built against an incompatible framework version.
    #[error("{}: plugin built for SKiD {plugin}, host is SKiD {host}", path.display())]
    FrameworkVersion {
        path: PathBuf,
        plugin: String,
        host: String,
    },

    /// The plugin fills a slot this host cannot load dynamically yet.
    #[error("{}: plugin `{name}` has slot kind {kind}, which this host cannot load (supported: source, odometry, descriptor, coarse, fine, verifier, back-end)", path.display())]
    UnsupportedSlot { path: PathBuf, name: String, kind: u32 },

    /// The plugin declares a threading model this host cannot honour.
    #[error("{}: plugin `{name}` {reason}", path.display())]
    Threading {
        path: PathBuf,
        name: String,
        reason: String,
    },

    /// The declaration is broken: a null pointer, a non-UTF-8 string, an unparsable default config.
    #[error("{}: malformed plugin declaration: {reason}", path.display())]
    Malformed { path: PathBuf, reason: String },

    /// The plugin could not be registered (a plugin of the same name is already there).
    #[error("registering plugin from {}: {source}", path.display())]
    Register { path: PathBuf, source: PluginError },
}

/// A plugin library that passed every check; cheap to copy, valid for the rest of the process.
#[derive(Clone, Copy, Debug)]
pub struct LoadedLibrary {
    library: &'static Library,
}

/// One plugin of a loaded library.
#[derive(Clone, Copy, Debug)]
pub struct LoadedPlugin {
    plugin: &'static PluginSpec,
}

/// Opens the plugin library at `path`, checks its ABI version, layout fingerprint, framework version and
/// every plugin's declaration, and installs the host's logger in it. Loading the same file again returns
/// the same library.
pub fn load_library(path: impl AsRef<Path>) -> Result<LoadedLibrary, AbiError> {
    library::load(path.as_ref()).map(|library| LoadedLibrary { library })
}

/// Loads the plugin library at `path` and registers all its plugins into `registry`.
pub fn load_into(registry: &mut Registry, path: impl AsRef<Path>) -> Result<LoadedLibrary, AbiError> {
    let library = load_library(path)?;
    library.register(registry)?;
    Ok(library)
}

impl LoadedLibrary {
    /// The library's own name (its crate or project).
    pub fn name(&self) -> &'static str {
        &self.library.name
    }

    /// The file the library was loaded from (canonical).
    pub fn path(&self) -> &'static Path {
        &self.library.path
    }

    /// The framework version the library was built against.
    pub fn framework_version(&self) -> &'static str {
        &self.library.framework_version
    }

    /// The plugins the library provides, in declaration order.
    pub fn plugins(&self) -> Vec<LoadedPlugin> {
        self.library
            .plugins
            .iter()
            .map(|plugin| LoadedPlugin { plugin })
            .collect()
    }

    /// The plugin called `name`, if the library has one.
    pub fn plugin(&self, name: &str) -> Option<LoadedPlugin> {
        self.library
            .plugins
            .iter()
            .find(|plugin| plugin.name == name)
            .map(|plugin| LoadedPlugin { plugin })
    }

    /// Registers every plugin of the library into its slot's table of `registry`.
    pub fn register(&self, registry: &mut Registry) -> Result<(), AbiError> {
        self.plugins()
            .iter()
            .try_for_each(|plugin| plugin.register(registry))
    }
}

impl LoadedPlugin {
    /// The registry name.
    pub fn name(&self) -> &'static str {
        &self.plugin.name
    }

    /// The one-line summary.
    pub fn summary(&self) -> &'static str {
        &self.plugin.summary
    }

    /// The slot the plugin fills.
    pub fn slot(&self) -> Slot {
        self.plugin.slot()
    }

    /// The file the plugin was loaded from (canonical).
    pub fn path(&self) -> &'static Path {
        &self.plugin.path
    }

    /// Whether the plugin declared itself serial, so that the host runs one call into any of its
    /// instances at a time.
    pub fn is_serial(&self) -> bool {
        self.plugin.is_serial()
    }

    /// The default parameters, as the plugin declares them.
    pub fn default_params(&self) -> &'static Params {
        &self.plugin.defaults
    }

    /// Registers the plugin into its slot's table of `registry`.
    pub fn register(&self, registry: &mut Registry) -> Result<(), AbiError> {
        let plugin = self.plugin;
        let result = match plugin.table {
            SlotTable::Backend(fns) => registry.backend.register(backend::entry(plugin, fns)),
            SlotTable::Verifier(fns) => registry.verifier.register(verifier::entry(plugin, fns)),
            SlotTable::Source(fns) => registry.source.register(source::entry(plugin, fns)),
            SlotTable::Odometry(fns) => registry.odometry.register(odometry::entry(plugin, fns)),
            SlotTable::Descriptor(fns) => registry.descriptor.register(descriptor::entry(plugin, fns)),
            SlotTable::Coarse(fns) => registry.coarse.register(registration::coarse_entry(plugin, fns)),
            SlotTable::Fine(fns) => registry.fine.register(registration::fine_entry(plugin, fns)),
        };
        result.map_err(|source| AbiError::Register {
            path: plugin.path.clone(),
            source,
        })
    }

    /// Checks parameters by building an instance and destroying it again.
    pub fn validate(&self, params: &Params) -> Result<(), ParamError> {
        let (create, destroy) = match self.plugin.table {
            SlotTable::Backend(fns) => (fns.create, fns.destroy),
            SlotTable::Verifier(fns) => (fns.create, fns.destroy),
            SlotTable::Source(fns) => (fns.create, fns.destroy),
            SlotTable::Odometry(fns) => (fns.create, fns.destroy),
            SlotTable::Descriptor(fns) => (fns.create, fns.destroy),
            SlotTable::Coarse(fns) => (fns.create, fns.destroy),
            SlotTable::Fine(fns) => (fns.create, fns.destroy),
        };
        call::validate_params(self.plugin, create, destroy, params)
    }

    /// A descriptor instance built from `params`, for callers that do not go through a [`Registry`];
    /// `None` when the plugin is not a descriptor.
    pub fn create_descriptor(
        &self,
        params: &Params,
        context: &skid_core::PluginContext,
    ) -> Option<Result<DynDescriptor, PluginError>> {
        match self.plugin.table {
            SlotTable::Descriptor(fns) => Some(DynDescriptor::create(self.plugin, fns, params, context)),
            _ => None,
        }
    }

    /// A back-end instance built from `params`; `None` when the plugin is not one.
    pub fn create_backend(
        &self,
        params: &Params,
        context: &skid_core::PluginContext,
    ) -> Option<Result<DynBackend, PluginError>> {
        match self.plugin.table {
            SlotTable::Backend(fns) => Some(DynBackend::create(self.plugin, fns, params, context)),
            _ => None,
        }
    }

    /// A verifier instance built from `params`; `None` when the plugin is not one.
    pub fn create_verifier(
        &self,
        params: &Params,
        context: &skid_core::PluginContext,
    ) -> Option<Result<DynVerifier, PluginError>> {
        match self.plugin.table {
            SlotTable::Verifier(fns) => Some(DynVerifier::create(self.plugin, fns, params, context)),
            _ => None,
        }
    }

    /// A source instance built from `params`; `None` when the plugin is not one.
    pub fn create_source(
        &self,
        params: &Params,
        context: &skid_core::PluginContext,
    ) -> Option<Result<DynSource, PluginError>> {
        match self.plugin.table {
            SlotTable::Source(fns) => Some(DynSource::create(self.plugin, fns, params, context)),
            _ => None,
        }
    }

    /// An odometry instance built from `params`; `None` when the plugin is not one.
    pub fn create_odometry(
        &self,
        params: &Params,
        context: &skid_core::PluginContext,
    ) -> Option<Result<DynOdometry, PluginError>> {
        match self.plugin.table {
            SlotTable::Odometry(fns) => Some(DynOdometry::create(self.plugin, fns, params, context)),
            _ => None,
        }
    }

    /// A fine registration instance built from `params`; `None` when the plugin is not one.
    pub fn create_fine(
        &self,
        params: &Params,
        context: &skid_core::PluginContext,
    ) -> Option<Result<DynFine, PluginError>> {
        match self.plugin.table {
            SlotTable::Fine(fns) => Some(DynFine::create(self.plugin, fns, params, context)),
            _ => None,
        }
    }

    /// A coarse registration instance built from `params`; `None` when the plugin is not one.
    pub fn create_coarse(
        &self,
        params: &Params,
        context: &skid_core::PluginContext,
    ) -> Option<Result<DynCoarse, PluginError>> {
        match self.plugin.table {
            SlotTable::Coarse(fns) => Some(DynCoarse::create(self.plugin, fns, params, context)),
            _ => None,
        }
    }
}
