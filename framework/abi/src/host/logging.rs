//! The host's logging callbacks: plugin events re-emitted as host `tracing` events.
//!
//! Every event arrives under the target `skid::plugin` with the plugin library's name in the `library`
//! field and the plugin-side target (the module that logged) in `plugin_target`, so one filter directive (`skid::plugin=debug`) controls all
//! plugins. Neither callback may unwind into the plugin, so both run under `catch_unwind`.

use std::panic::{AssertUnwindSafe, catch_unwind};

use tracing::Level;

use crate::ffi::{AbiStr, level};

/// The target under which plugin events are re-emitted.
pub const PLUGIN_TARGET: &str = "skid::plugin";

/// Receives one formatted event from a plugin.
///
/// # Safety
///
/// The strings must be valid for the duration of the call (the plugin guarantees it).
pub(crate) unsafe extern "C" fn host_log(level: u32, library: AbiStr, target: AbiStr, message: AbiStr) {
    let _ = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: the plugin passes strings valid for this call; invalid UTF-8 is reported, not read.
        let (library, target, message) = unsafe { (library.to_str(), target.to_str(), message.to_str()) };
        let library = library.unwrap_or("<non-UTF-8 library name>");
        let target = target.unwrap_or("<non-UTF-8 target>");
        let message = message.unwrap_or("<non-UTF-8 message>");
        macro_rules! emit {
            ($level:expr) => {
                tracing::event!(target: "skid::plugin", $level, library, plugin_target = target, "{message}")
            };
        }
        match level {
            level::ERROR => emit!(Level::ERROR),
            level::WARN => emit!(Level::WARN),
            level::INFO => emit!(Level::INFO),
            level::DEBUG => emit!(Level::DEBUG),
            _ => emit!(Level::TRACE),
        }
    }));
}

/// Tells a plugin whether the host would record an event of this level.
///
/// # Safety
///
/// Always safe to call; `unsafe` only because it is an ABI callback.
pub(crate) unsafe extern "C" fn host_enabled(level: u32, _target: AbiStr) -> bool {
    catch_unwind(|| match level {
        level::ERROR => tracing::enabled!(target: "skid::plugin", Level::ERROR),
        level::WARN => tracing::enabled!(target: "skid::plugin", Level::WARN),
        level::INFO => tracing::enabled!(target: "skid::plugin", Level::INFO),
        level::DEBUG => tracing::enabled!(target: "skid::plugin", Level::DEBUG),
        _ => tracing::enabled!(target: "skid::plugin", Level::TRACE),
    })
    .unwrap_or(false)
}
