//! SIGINT, SIGTERM and SIGHUP stop a run cleanly: the first asks the runtime to stop
//! ([`skid_runtime::request_stop`]), so the executor returns between scans, its front-end processes are
//! stopped and the run's folder stays marked incomplete; the process then exits with `128 + signal`. A
//! second signal, or a run that has not stopped within [`GRACE`], exits at once (front-end processes
//! still exit, as they watch the pipe to this process).

use std::time::Duration;

/// How long a requested stop may take before the process exits anyway.
const GRACE: Duration = Duration::from_secs(15);

/// The exit status of a process stopped by `signal`, as shells report it.
pub fn exit_status(signal: i32) -> u8 {
    u8::try_from(128 + signal).unwrap_or(1)
}

/// Installs the handlers; failures are logged, not fatal (the run then simply cannot be stopped
/// cleanly).
#[cfg(unix)]
pub fn install() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = match signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) {
        Ok(signals) => signals,
        Err(error) => {
            tracing::warn!(%error, "could not install signal handlers");
            return;
        }
    };
    let spawned = std::thread::Builder::new().name("signals".into()).spawn(move || {
        for signal in signals.forever() {
            if skid_runtime::stop_requested().is_some() {
                eprintln!("second signal {signal}: exiting now");
                std::process::exit(exit_status(signal).into());
            }
            tracing::warn!(signal, "stop requested; finishing the current step");
            skid_runtime::request_stop(signal);
            let _ = std::thread::Builder::new()
                .name("stop-grace".into())
                .spawn(move || {
                    std::thread::sleep(GRACE);
                    eprintln!("the run did not stop within {} s: exiting now", GRACE.as_secs());
                    std::process::exit(exit_status(signal).into());
                });
        }
    });
    if let Err(error) = spawned {
        tracing::warn!(%error, "could not start the signal thread");
    }
}

/// Without POSIX signals the default handling (immediate exit) stays.
#[cfg(not(unix))]
pub fn install() {}
