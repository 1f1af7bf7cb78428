//! Opening a plugin library, checking its declaration in a fixed order, and keeping it for the process.
//!
//! The order matters: the ABI version (offset 0) is read first and alone, then the layout fingerprint
//! and the framework version; only a declaration that passed all three is read as a [`PluginDecl`].

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use skid_core::{Params, Slot};

use super::{AbiError, logging};
use crate::ffi::{
    CreateFn, DescribeFn, DescriptorLenFn, DescriptorVTable, DestroyFn, PluginDecl, SlotKind, Status,
};
use crate::{ABI_VERSION, ENTRY_SYMBOL, FRAMEWORK_VERSION};

/// The entry symbol's type as the host calls it: foreign code, hence `unsafe`.
type RawEntryFn = unsafe extern "C" fn() -> *const PluginDecl;

/// A loaded, checked plugin library. Never dropped: it is leaked when loaded.
pub(crate) struct Library {
    pub(crate) path: PathBuf,
    pub(crate) name: String,
    pub(crate) summary: String,
    pub(crate) framework_version: String,
    pub(crate) slot: Slot,
    pub(crate) defaults: Params,
    pub(crate) descriptor: DescriptorFns,
    /// Keeps the code mapped; the last field, and never dropped anyway.
    _library: libloading::Library,
}

impl std::fmt::Debug for Library {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Library")
            .field("path", &self.path)
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

/// The descriptor function table, every pointer checked non-null.
#[derive(Clone, Copy)]
pub(crate) struct DescriptorFns {
    pub(crate) create: CreateFn,
    pub(crate) descriptor_len: DescriptorLenFn,
    pub(crate) describe: DescribeFn,
    pub(crate) destroy: DestroyFn,
}

/// Every library loaded so far, by canonical path.
static LOADED: Mutex<Vec<&'static Library>> = Mutex::new(Vec::new());

/// Loads and checks the library at `path`, or returns the one already loaded from that file.
pub(super) fn load(path: &Path) -> Result<&'static Library, AbiError> {
    let path = path.canonicalize().map_err(|_| AbiError::NotFound {
        path: path.to_owned(),
    })?;
    let mut loaded = LOADED.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some(library) = loaded.iter().find(|library| library.path == path) {
        return Ok(library);
    }
    // SAFETY: opening a library runs its initialisers. That is the trust a host places in the plugins it
    // is configured to load; SKiD plugins built with skid-abi have no initialisers of their own.
    let library = unsafe { libloading::Library::new(&path) }.map_err(|source| AbiError::NotALibrary {
        path: path.clone(),
        source,
    })?;
    match check(&path, &library) {
        Ok(checked) => {
            let Checked {
                name,
                summary,
                framework_version,
                slot,
                defaults,
                descriptor,
            } = checked;
            let library = Library {
                path,
                name,
                summary,
                framework_version,
                slot,
                defaults,
                descriptor,
                _library: library,
            };
            let library: &'static Library = Box::leak(Box::new(library));
            loaded.push(library);
            Ok(library)
        }
        Err(error) => {
            // Libraries are never unloaded, not even rejected ones: their initialisers have run.
            std::mem::forget(library);
            Err(error)
        }
    }
}

/// The fields of a [`Library`] other than the handle itself, read from a checked declaration.
struct Checked {
    name: String,
    summary: String,
    framework_version: String,
    slot: Slot,
    defaults: Params,
    descriptor: DescriptorFns,
}

/// Finds the entry symbol and checks the declaration; installs the logger once it is accepted.
fn check(path: &Path, library: &libloading::Library) -> Result<Checked, AbiError> {
    let malformed = |reason: &str| AbiError::Malformed {
        path: path.to_owned(),
        reason: reason.to_owned(),
    };
    // SAFETY: the symbol's type is the ABI's entry signature; a library that exports the name with
    // another type is not a SKiD plugin, and the version check below is the best defence against it.
    let entry: RawEntryFn =
        *unsafe { library.get::<RawEntryFn>(ENTRY_SYMBOL) }.map_err(|source| AbiError::MissingSymbol {
            path: path.to_owned(),
            symbol: ENTRY_SYMBOL,
            source,
        })?;
    // SAFETY: the entry function takes no arguments and returns a pointer to static data.
    let decl = unsafe { entry() };
    if decl.is_null() {
        return Err(malformed("the entry symbol returned a null declaration"));
    }
    // SAFETY: every ABI version starts its declaration with the version as a `u32` at offset 0.
    let abi_version = unsafe { (&raw const (*decl).abi_version).read() };
    if abi_version != ABI_VERSION {
        return Err(AbiError::AbiVersion {
            path: path.to_owned(),
            plugin: abi_version,
            host: ABI_VERSION,
        });
    }
    // SAFETY: same ABI version, so the declaration has this crate's layout.
    let decl = unsafe { &*decl };
    if decl.layout_fingerprint != skid_msgs::LAYOUT_FINGERPRINT {
        return Err(AbiError::Layout {
            path: path.to_owned(),
            plugin: decl.layout_fingerprint,
            host: skid_msgs::LAYOUT_FINGERPRINT,
        });
    }
    // SAFETY: declaration strings point into the library's static data, mapped for the process.
    let text = |field: &str, value: crate::ffi::AbiStr| match unsafe { value.to_str() } {
        Some(text) => Ok(text.to_owned()),
        None => Err(malformed(&format!("the {field} is null or not UTF-8"))),
    };
    let framework_version = text("framework version", decl.framework_version)?;
    if !crate::framework_versions_compatible(&framework_version, FRAMEWORK_VERSION) {
        return Err(AbiError::FrameworkVersion {
            path: path.to_owned(),
            plugin: framework_version,
            host: FRAMEWORK_VERSION.to_owned(),
        });
    }
    let name = text("name", decl.name)?;
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(malformed(&format!(
            "the name `{name}` is not a non-empty [A-Za-z0-9_-]+ identifier"
        )));
    }
    if decl.slot_kind != SlotKind::DESCRIPTOR {
        return Err(AbiError::UnsupportedSlot {
            path: path.to_owned(),
            name,
            kind: decl.slot_kind.0,
        });
    }
    let summary = text("summary", decl.summary)?;
    let default_config = text("default config", decl.default_config)?;
    let defaults = Params::from_toml_str(&default_config)
        .map_err(|error| malformed(&format!("the default config is not TOML: {error}")))?;
    let table = decl.slot_table.cast::<DescriptorVTable>();
    // SAFETY: for the descriptor kind the slot table is a static `DescriptorVTable` (null is checked).
    let Some(table) = (unsafe { table.as_ref() }) else {
        return Err(malformed("the descriptor function table is null"));
    };
    let (Some(create), Some(descriptor_len), Some(describe), Some(destroy)) =
        (table.create, table.descriptor_len, table.describe, table.destroy)
    else {
        return Err(malformed("the descriptor function table has a null entry"));
    };
    let set_logger = decl.set_logger.ok_or_else(|| malformed("set_logger is null"))?;
    // SAFETY: both callbacks are host functions valid for the whole process, and never unwind.
    let status = unsafe { set_logger(Some(logging::host_log), Some(logging::host_enabled)) };
    if status != Status::OK {
        tracing::warn!(target: "skid::plugin", plugin = %name, "set_logger returned status {}; its logs are lost", status.0);
    }
    tracing::debug!(target: "skid::plugin", plugin = %name, path = %path.display(), "loaded plugin library");
    Ok(Checked {
        name,
        summary,
        framework_version,
        slot: Slot::Descriptor,
        defaults,
        descriptor: DescriptorFns {
            create,
            descriptor_len,
            describe,
            destroy,
        },
    })
}
