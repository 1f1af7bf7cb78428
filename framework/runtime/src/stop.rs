//! A process-wide request to stop a run early. The binary turns SIGINT/SIGTERM into
//! [`request_stop`]; the executors check [`stop_requested`] between scans (and the process feeds while
//! they wait for a front-end), return [`crate::error::RuntimeError::Interrupted`], and their drops stop the
//! front-end processes. The runtime itself installs no signal handler.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal number that asked to stop, 0 while none did.
static STOP_SIGNAL: AtomicI32 = AtomicI32::new(0);

/// Asks every running executor in this process to stop; `signal` is the number reported back (the
/// first request wins).
pub fn request_stop(signal: i32) {
    let _ = STOP_SIGNAL.compare_exchange(0, signal.max(1), Ordering::SeqCst, Ordering::SeqCst);
}

/// The signal that asked to stop, if any.
pub fn stop_requested() -> Option<i32> {
    match STOP_SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        signal => Some(signal),
    }
}

/// `Err(Interrupted)` once a stop was requested.
pub(crate) fn check() -> Result<(), crate::error::RuntimeError> {
    match stop_requested() {
        Some(signal) => Err(crate::error::RuntimeError::Interrupted { signal }),
        None => Ok(()),
    }
}

/// `error`, or `Interrupted` when a stop was requested (a stop makes waiting stages fail; the stop is
/// the reason to report).
pub(crate) fn or_interrupted(error: crate::error::RuntimeError) -> crate::error::RuntimeError {
    match stop_requested() {
        Some(signal) => crate::error::RuntimeError::Interrupted { signal },
        None => error,
    }
}
