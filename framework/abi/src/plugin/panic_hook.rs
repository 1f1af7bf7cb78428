//! The plugin's panic hook, installed with the logger.
//!
//! A cdylib has its own copy of std and so its own panic hook, which by default prints to stderr. Once
//! the host's logger is installed the plugin replaces it: a panic inside an exported call (which the
//! call's guard turns into an error for the host) only records where it happened, so the host's error
//! names the location; a panic anywhere else (a thread the plugin spawned) is logged as an error.

use std::cell::{Cell, RefCell};
use std::panic::PanicHookInfo;

thread_local! {
    /// True while this thread runs inside an exported call's guard.
    static IN_CALL: Cell<bool> = const { Cell::new(false) };
    /// Where the last panic on this thread happened, taken by the guard.
    static LOCATION: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Replaces the default panic hook; called once, when the logger is installed.
pub(super) fn install() {
    std::panic::set_hook(Box::new(hook));
}

fn hook(info: &PanicHookInfo<'_>) {
    let location = info
        .location()
        .map(|l| format!("{}:{}:{}", l.file(), l.line(), l.column()));
    if IN_CALL.with(Cell::get) {
        LOCATION.with(|slot| *slot.borrow_mut() = location);
    } else {
        let message = info
            .payload_as_str()
            .unwrap_or("a panic with a non-string payload");
        let location = location.as_deref().unwrap_or("an unknown location");
        tracing::error!(target: "skid_abi::panic", "panicked outside a plugin call at {location}: {message}");
    }
}

/// Marks the current thread as inside an exported call until the returned guard drops.
pub(super) fn enter_call() -> CallScope {
    let outer = IN_CALL.with(|flag| flag.replace(true));
    LOCATION.with(|slot| slot.borrow_mut().take());
    CallScope { outer }
}

/// Restores the thread's previous "inside a call" state when dropped.
pub(super) struct CallScope {
    outer: bool,
}

impl CallScope {
    /// The location of a panic caught in this call, if the hook recorded one.
    pub(super) fn take_location(&self) -> Option<String> {
        LOCATION.with(|slot| slot.borrow_mut().take())
    }
}

impl Drop for CallScope {
    fn drop(&mut self) {
        IN_CALL.with(|flag| flag.set(self.outer));
    }
}
