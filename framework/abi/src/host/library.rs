//! Opening a plugin library, checking its declaration in a fixed order, and keeping it for the process.
//!
//! The order matters: the ABI version (offset 0) is read first and alone, then the layout fingerprint
//! and the framework version; only a declaration that passed all three is read as a [`LibraryDecl`],
//! and then each of its plugins: name, texts, default config, and a function table of the declared slot
//! with every entry non-null.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use parking_lot::{ReentrantMutex, ReentrantMutexGuard};

use skid_core::{Params, Slot};

use super::{AbiError, logging};
use crate::ffi::{
    AbiStr, AddEdgeFn, AddKeyframeFn, AddPriorFn, AlignFn, BackendListsFn, BackendOdometryFn, BackendPoseFn,
    BackendVTable, Checked, CoarseVTable, CreateFn, DescribeFn, DescriptorLenFn, DescriptorVTable, DestroyFn,
    DestroyPreparedFn, FineVTable, IndexInsertFn, IndexLenFn, IndexQueryFn, LibraryDecl, NewIndexFn,
    NextScanFn, OdometryVTable, OptimizeFn, PluginDecl, PrepareFn, PreparedPointsFn, RefineFn, RegisterFn,
    RejectedLoopsFn, RemoveLoopFn, SlotKind, SourceInfoFn, SourceVTable, Status, SubmitFn, Threading,
    VerifierVTable,
};
use crate::{ABI_VERSION, ENTRY_SYMBOL, FRAMEWORK_VERSION};

/// The entry symbol's type as the host calls it: foreign code, hence `unsafe`.
type RawEntryFn = unsafe extern "C" fn() -> *const LibraryDecl;

/// The most plugins one library may declare; a larger count is taken for a corrupt declaration.
const MAX_PLUGINS_PER_LIBRARY: usize = 1024;

/// A loaded, checked plugin library. Never dropped: it is leaked when loaded.
pub(crate) struct Library {
    pub(crate) path: PathBuf,
    /// The library's own name (its crate or project).
    pub(crate) name: String,
    pub(crate) framework_version: String,
    pub(crate) plugins: Vec<PluginSpec>,
    /// Keeps the code mapped; the last field, and never dropped anyway.
    _library: libloading::Library,
}

impl std::fmt::Debug for Library {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Library")
            .field("path", &self.path)
            .field("name", &self.name)
            .field("plugins", &self.plugins.len())
            .finish_non_exhaustive()
    }
}

/// One checked plugin of a library.
#[derive(Debug)]
pub(crate) struct PluginSpec {
    pub(crate) name: String,
    pub(crate) summary: String,
    pub(crate) defaults: Params,
    /// The library file, for errors and `skid plugins`.
    pub(crate) path: PathBuf,
    pub(crate) table: SlotTable,
    /// Held across every call into a plugin declared [`Threading::SERIAL`]; `None` for the others.
    /// Re-entrant, because a call's clean-up (freeing what a failed call lent) may call the plugin
    /// again on the same thread.
    serial: Option<ReentrantMutex<()>>,
}

impl PluginSpec {
    /// Waits until no other thread is inside this plugin, for a plugin declared serial; a no-op for
    /// the others. Hold the guard for the whole call.
    pub(crate) fn serialise(&self) -> Option<ReentrantMutexGuard<'_, ()>> {
        self.serial.as_ref().map(ReentrantMutex::lock)
    }

    /// Whether every call to this plugin's instances is serialised.
    pub(crate) fn is_serial(&self) -> bool {
        self.serial.is_some()
    }

    /// The slot the plugin fills.
    pub(crate) fn slot(&self) -> Slot {
        match self.table {
            SlotTable::Source(_) => Slot::Source,
            SlotTable::Backend(_) => Slot::Backend,
            SlotTable::Verifier(_) => Slot::Verifier,
            SlotTable::Odometry(_) => Slot::Odometry,
            SlotTable::Descriptor(_) => Slot::Descriptor,
            SlotTable::Coarse(_) => Slot::Coarse,
            SlotTable::Fine(_) => Slot::Fine,
        }
    }
}

/// A plugin's function table, every pointer checked non-null.
#[derive(Clone, Copy, Debug)]
pub(crate) enum SlotTable {
    Source(SourceFns),
    Backend(BackendFns),
    Verifier(VerifierFns),
    Odometry(OdometryFns),
    Descriptor(DescriptorFns),
    Coarse(CoarseFns),
    Fine(FineFns),
}

/// The back-end function table.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BackendFns {
    pub(crate) create: Checked<CreateFn>,
    pub(crate) add_keyframe: Checked<AddKeyframeFn>,
    pub(crate) add_edge: Checked<AddEdgeFn>,
    pub(crate) add_prior: Checked<AddPriorFn>,
    pub(crate) remove_loop: Checked<RemoveLoopFn>,
    pub(crate) optimize: Checked<OptimizeFn>,
    pub(crate) pose: Checked<BackendPoseFn>,
    pub(crate) odometry_between: Checked<BackendOdometryFn>,
    pub(crate) lists: Checked<BackendListsFn>,
    pub(crate) rejected_loops: Checked<RejectedLoopsFn>,
    pub(crate) destroy: Checked<DestroyFn>,
}

/// The verifier function table.
#[derive(Clone, Copy, Debug)]
pub(crate) struct VerifierFns {
    pub(crate) create: Checked<CreateFn>,
    pub(crate) submit: Checked<SubmitFn>,
    pub(crate) destroy: Checked<DestroyFn>,
}

/// The source function table.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SourceFns {
    pub(crate) create: Checked<CreateFn>,
    pub(crate) info: Checked<SourceInfoFn>,
    pub(crate) next_scan: Checked<NextScanFn>,
    pub(crate) destroy: Checked<DestroyFn>,
}

/// The odometry function table.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OdometryFns {
    pub(crate) create: Checked<CreateFn>,
    pub(crate) register: Checked<RegisterFn>,
    pub(crate) destroy: Checked<DestroyFn>,
}

/// The descriptor function table.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DescriptorFns {
    pub(crate) create: Checked<CreateFn>,
    pub(crate) descriptor_len: Checked<DescriptorLenFn>,
    pub(crate) describe: Checked<DescribeFn>,
    pub(crate) new_index: Checked<NewIndexFn>,
    pub(crate) index_insert: Checked<IndexInsertFn>,
    pub(crate) index_query: Checked<IndexQueryFn>,
    pub(crate) index_len: Checked<IndexLenFn>,
    pub(crate) destroy_index: Checked<DestroyFn>,
    pub(crate) destroy: Checked<DestroyFn>,
}

/// The coarse registration function table.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CoarseFns {
    pub(crate) create: Checked<CreateFn>,
    pub(crate) align: Checked<AlignFn>,
    pub(crate) destroy: Checked<DestroyFn>,
}

/// The fine registration function table.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FineFns {
    pub(crate) create: Checked<CreateFn>,
    pub(crate) prepare: Checked<PrepareFn>,
    pub(crate) prepared_points: Checked<PreparedPointsFn>,
    pub(crate) refine: Checked<RefineFn>,
    pub(crate) destroy_prepared: Checked<DestroyPreparedFn>,
    pub(crate) destroy: Checked<DestroyFn>,
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
        Ok((name, framework_version, plugins)) => {
            let library = Library {
                path,
                name,
                framework_version,
                plugins,
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

/// Finds the entry symbol and checks the declaration; installs the logger once it is accepted.
fn check(path: &Path, library: &libloading::Library) -> Result<(String, String, Vec<PluginSpec>), AbiError> {
    let malformed = |reason: String| AbiError::Malformed {
        path: path.to_owned(),
        reason,
    };
    // SAFETY: the symbol's type is the ABI's entry signature; a library that exports the name with
    // another type is not a SKiD plugin, and the version check below is the best defence against it.
    let entry: RawEntryFn =
        *unsafe { library.get::<RawEntryFn>(ENTRY_SYMBOL) }.map_err(|source| AbiError::MissingSymbol {
            path: path.to_owned(),
            symbol: ENTRY_SYMBOL,
            source,
        })?;
    // Calling a data object as a function crashes the host; the header asks for a function, and a
    // library that exports the name as data is refused here, while its bytes are still only read.
    if crate::host::code_address::is_executable(entry as usize) == Some(false) {
        return Err(malformed(format!(
            "the entry symbol `{ENTRY_SYMBOL}` is data, not a function: define it as \
             `SKID_EXPORT const SkidLibraryDecl *{ENTRY_SYMBOL}(void) {{ … }}`"
        )));
    }
    // SAFETY: the entry function takes no arguments and returns a pointer to static data.
    let decl = unsafe { entry() };
    if decl.is_null() {
        return Err(malformed(
            "the entry symbol returned a null declaration".to_owned(),
        ));
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
    let framework_version =
        text(decl.framework_version).ok_or_else(|| malformed(bad_text("framework version")))?;
    if !crate::framework_versions_compatible(&framework_version, FRAMEWORK_VERSION) {
        return Err(AbiError::FrameworkVersion {
            path: path.to_owned(),
            plugin: framework_version,
            host: FRAMEWORK_VERSION.to_owned(),
        });
    }
    let library_name = text(decl.name).ok_or_else(|| malformed(bad_text("library name")))?;
    if decl.plugin_count == 0 || decl.plugin_count > MAX_PLUGINS_PER_LIBRARY || decl.plugins.is_null() {
        return Err(malformed(format!(
            "the library declares {} plugins at {:p} (expected 1 to {MAX_PLUGINS_PER_LIBRARY} at a non-null address)",
            decl.plugin_count, decl.plugins
        )));
    }
    // SAFETY: a non-null array of `plugin_count` declarations in the library's static data.
    let decls = unsafe { std::slice::from_raw_parts(decl.plugins, decl.plugin_count) };
    let mut plugins: Vec<PluginSpec> = Vec::with_capacity(decls.len());
    for (index, plugin) in decls.iter().enumerate() {
        let spec = check_plugin(path, plugin).map_err(|refusal| match refusal {
            Refusal::Malformed(reason) => malformed(format!("plugin {index}: {reason}")),
            Refusal::UnsupportedSlot { name, kind } => AbiError::UnsupportedSlot {
                path: path.to_owned(),
                name,
                kind,
            },
            Refusal::Threading { name, reason } => AbiError::Threading {
                path: path.to_owned(),
                name,
                reason,
            },
        })?;
        if plugins.iter().any(|other| other.name == spec.name) {
            return Err(malformed(format!("two plugins are named `{}`", spec.name)));
        }
        plugins.push(spec);
    }
    match decl.set_logger {
        Some(set_logger) => {
            // SAFETY: both callbacks are host functions valid for the whole process, and never unwind.
            let status = unsafe { set_logger(Some(logging::host_log), Some(logging::host_enabled)) };
            if status != Status::OK {
                tracing::warn!(target: "skid::plugin", library = %library_name, "set_logger returned status {}; its logs are lost", status.0);
            }
        }
        None => {
            tracing::debug!(target: "skid::plugin", library = %library_name, "the library installs no logger")
        }
    }
    tracing::debug!(target: "skid::plugin", library = %library_name, path = %path.display(), plugins = plugins.len(), "loaded plugin library");
    Ok((library_name, framework_version, plugins))
}

/// A declaration string as owned text; `None` when null or not UTF-8.
fn text(value: AbiStr) -> Option<String> {
    // SAFETY: declaration strings point into the library's static data, mapped for the process.
    unsafe { value.to_str() }.map(str::to_owned)
}

fn bad_text(field: &str) -> String {
    format!("the {field} is null or not UTF-8")
}

/// Why one plugin declaration was refused.
enum Refusal {
    Malformed(String),
    UnsupportedSlot { name: String, kind: u32 },
    Threading { name: String, reason: String },
}

impl From<String> for Refusal {
    fn from(reason: String) -> Self {
        Refusal::Malformed(reason)
    }
}

/// Checks one plugin declaration.
fn check_plugin(path: &Path, decl: &PluginDecl) -> Result<PluginSpec, Refusal> {
    let name = text(decl.name).ok_or_else(|| bad_text("name"))?;
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(format!("the name `{name}` is not a non-empty [A-Za-z0-9_-]+ identifier").into());
    }
    let summary = text(decl.summary).ok_or_else(|| bad_text("summary"))?;
    let default_config = text(decl.default_config).ok_or_else(|| bad_text("default config"))?;
    let defaults = Params::from_toml_str(&default_config)
        .map_err(|error| format!("`{name}`: the default config is not TOML: {error}"))?;
    let serial = match decl.threading {
        Threading::INDEPENDENT_INSTANCES => None,
        Threading::SERIAL => Some(ReentrantMutex::new(())),
        Threading::PINNED_TO_CREATING_THREAD => {
            return Err(Refusal::Threading {
                name,
                reason: "declares that an instance must stay on the thread that created it, but SKiD \
                         moves instances between worker threads; declare SERIAL if the plugin only \
                         needs one call at a time, or keep its thread-bound state out of the instance"
                    .to_owned(),
            });
        }
        Threading(other) => {
            return Err(Refusal::Threading {
                name,
                reason: format!(
                    "declares threading model {other}, which this host does not know (0 = independent \
                     instances, 1 = serial, 2 = pinned to the creating thread)"
                ),
            });
        }
    };
    let null_entry = |slot: &str| format!("`{name}`: the {slot} function table has a null entry");
    let table = match decl.slot_kind {
        SlotKind::BACKEND => {
            // SAFETY: for this kind the table is a static `BackendVTable` (null is checked).
            let table = unsafe { decl.slot_table.cast::<BackendVTable>().as_ref() }
                .ok_or_else(|| format!("`{name}`: the back-end function table is null"))?;
            let (
                Some(create),
                Some(add_keyframe),
                Some(add_edge),
                Some(add_prior),
                Some(remove_loop),
                Some(optimize),
                Some(pose),
                Some(odometry_between),
                Some(lists),
                Some(rejected_loops),
                Some(destroy),
            ) = (
                table.create,
                table.add_keyframe,
                table.add_edge,
                table.add_prior,
                table.remove_loop,
                table.optimize,
                table.pose,
                table.odometry_between,
                table.lists,
                table.rejected_loops,
                table.destroy,
            )
            else {
                return Err(null_entry("back-end").into());
            };
            SlotTable::Backend(BackendFns {
                create,
                add_keyframe,
                add_edge,
                add_prior,
                remove_loop,
                optimize,
                pose,
                odometry_between,
                lists,
                rejected_loops,
                destroy,
            })
        }
        SlotKind::VERIFIER => {
            // SAFETY: for this kind the table is a static `VerifierVTable` (null is checked).
            let table = unsafe { decl.slot_table.cast::<VerifierVTable>().as_ref() }
                .ok_or_else(|| format!("`{name}`: the verifier function table is null"))?;
            let (Some(create), Some(submit), Some(destroy)) = (table.create, table.submit, table.destroy)
            else {
                return Err(null_entry("verifier").into());
            };
            SlotTable::Verifier(VerifierFns {
                create,
                submit,
                destroy,
            })
        }
        SlotKind::SOURCE => {
            // SAFETY: for this kind the table is a static `SourceVTable` (null is checked).
            let table = unsafe { decl.slot_table.cast::<SourceVTable>().as_ref() }
                .ok_or_else(|| format!("`{name}`: the source function table is null"))?;
            let (Some(create), Some(info), Some(next_scan), Some(destroy)) =
                (table.create, table.info, table.next_scan, table.destroy)
            else {
                return Err(null_entry("source").into());
            };
            SlotTable::Source(SourceFns {
                create,
                info,
                next_scan,
                destroy,
            })
        }
        SlotKind::ODOMETRY => {
            // SAFETY: for this kind the table is a static `OdometryVTable` (null is checked).
            let table = unsafe { decl.slot_table.cast::<OdometryVTable>().as_ref() }
                .ok_or_else(|| format!("`{name}`: the odometry function table is null"))?;
            let (Some(create), Some(register), Some(destroy)) = (table.create, table.register, table.destroy)
            else {
                return Err(null_entry("odometry").into());
            };
            SlotTable::Odometry(OdometryFns {
                create,
                register,
                destroy,
            })
        }
        SlotKind::DESCRIPTOR => {
            // SAFETY: for this kind the table is a static `DescriptorVTable` (null is checked).
            let table = unsafe { decl.slot_table.cast::<DescriptorVTable>().as_ref() }
                .ok_or_else(|| format!("`{name}`: the descriptor function table is null"))?;
            let (
                Some(create),
                Some(descriptor_len),
                Some(describe),
                Some(new_index),
                Some(index_insert),
                Some(index_query),
                Some(index_len),
                Some(destroy_index),
                Some(destroy),
            ) = (
                table.create,
                table.descriptor_len,
                table.describe,
                table.new_index,
                table.index_insert,
                table.index_query,
                table.index_len,
                table.destroy_index,
                table.destroy,
            )
            else {
                return Err(null_entry("descriptor").into());
            };
            SlotTable::Descriptor(DescriptorFns {
                create,
                descriptor_len,
                describe,
                new_index,
                index_insert,
                index_query,
                index_len,
                destroy_index,
                destroy,
            })
        }
        SlotKind::COARSE => {
            // SAFETY: for this kind the table is a static `CoarseVTable` (null is checked).
            let table = unsafe { decl.slot_table.cast::<CoarseVTable>().as_ref() }
                .ok_or_else(|| format!("`{name}`: the coarse function table is null"))?;
            let (Some(create), Some(align), Some(destroy)) = (table.create, table.align, table.destroy)
            else {
                return Err(null_entry("coarse").into());
            };
            SlotTable::Coarse(CoarseFns {
                create,
                align,
                destroy,
            })
        }
        SlotKind::FINE => {
            // SAFETY: for this kind the table is a static `FineVTable` (null is checked).
            let table = unsafe { decl.slot_table.cast::<FineVTable>().as_ref() }
                .ok_or_else(|| format!("`{name}`: the fine function table is null"))?;
            let (
                Some(create),
                Some(prepare),
                Some(prepared_points),
                Some(refine),
                Some(destroy_prepared),
                Some(destroy),
            ) = (
                table.create,
                table.prepare,
                table.prepared_points,
                table.refine,
                table.destroy_prepared,
                table.destroy,
            )
            else {
                return Err(null_entry("fine").into());
            };
            SlotTable::Fine(FineFns {
                create,
                prepare,
                prepared_points,
                refine,
                destroy_prepared,
                destroy,
            })
        }
        SlotKind(kind) => return Err(Refusal::UnsupportedSlot { name, kind }),
    };
    Ok(PluginSpec {
        name,
        summary,
        defaults,
        path: path.to_owned(),
        table,
        serial,
    })
}
