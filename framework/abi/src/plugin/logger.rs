//! Forwards the plugin's `tracing` events to the host.
//!
//! A cdylib has its own copy of `tracing` with its own global dispatcher, so without this its events go
//! nowhere. [`install`] sets, once per library, a small subscriber in the plugin's copy that asks the
//! host's filter callback whether an event is wanted and passes the level, target and formatted message
//! (the `message` field first, then `name=value` pairs) to the host's log callback. Spans are not
//! forwarded: the subscriber reports them as disabled, so span fields do not appear in messages.

use std::fmt::{self, Write as _};
use std::sync::OnceLock;

use tracing::field::{Field, Visit};
use tracing::span::{Attributes, Id, Record};
use tracing::subscriber::Interest;
use tracing::{Event, Level, Metadata, Subscriber};

use crate::ffi::{AbiStr, Checked, EnabledFn, LogFn, level};

/// Set once the subscriber is installed; later calls (a second host load of the same library) are no-ops.
static INSTALLED: OnceLock<()> = OnceLock::new();

/// Installs the forwarding subscriber as this library's global `tracing` dispatcher, and the panic
/// hook that reports through it, once.
pub(super) fn install(library: &'static str, log: Checked<LogFn>, enabled: Checked<EnabledFn>) {
    INSTALLED.get_or_init(|| {
        // If the plugin already installed a subscriber of its own, keep it: it was a deliberate choice.
        let _ = tracing::subscriber::set_global_default(Forwarder {
            library,
            log,
            enabled,
        });
        super::panic_hook::install();
    });
}

/// The wire code of a `tracing` level.
fn level_code(level: &Level) -> u32 {
    match *level {
        Level::ERROR => level::ERROR,
        Level::WARN => level::WARN,
        Level::INFO => level::INFO,
        Level::DEBUG => level::DEBUG,
        Level::TRACE => level::TRACE,
    }
}

/// The subscriber that hands every enabled event to the host.
struct Forwarder {
    library: &'static str,
    log: Checked<LogFn>,
    enabled: Checked<EnabledFn>,
}

impl Subscriber for Forwarder {
    fn register_callsite(&self, metadata: &'static Metadata<'static>) -> Interest {
        // The host's filter can change at any time, so ask it on every event; spans are never wanted.
        if metadata.is_span() {
            Interest::never()
        } else {
            Interest::sometimes()
        }
    }

    fn enabled(&self, metadata: &Metadata<'_>) -> bool {
        if metadata.is_span() {
            return false;
        }
        // SAFETY: the host's callback reads the target only during the call and never unwinds.
        unsafe { (self.enabled)(level_code(metadata.level()), AbiStr::borrowed(metadata.target())) }
    }

    fn new_span(&self, _span: &Attributes<'_>) -> Id {
        // Spans are disabled in `enabled`, so this is not reached; any non-zero id is valid.
        Id::from_u64(1)
    }

    fn record(&self, _span: &Id, _values: &Record<'_>) {}

    fn record_follows_from(&self, _span: &Id, _follows: &Id) {}

    fn event(&self, event: &Event<'_>) {
        let mut fields = FieldFormatter::default();
        event.record(&mut fields);
        let message = match (fields.message.is_empty(), fields.rest.is_empty()) {
            (_, true) => fields.message,
            (true, false) => fields.rest,
            (false, false) => format!("{} {}", fields.message, fields.rest),
        };
        let metadata = event.metadata();
        // SAFETY: the host's callback reads the strings only during the call and never unwinds.
        unsafe {
            (self.log)(
                level_code(metadata.level()),
                AbiStr::from_static(self.library),
                AbiStr::borrowed(metadata.target()),
                AbiStr::borrowed(&message),
            );
        }
    }

    fn enter(&self, _span: &Id) {}

    fn exit(&self, _span: &Id) {}
}

/// Formats an event's fields: the `message` field as is, the others as `name=value`.
#[derive(Default)]
struct FieldFormatter {
    message: String,
    rest: String,
}

impl Visit for FieldFormatter {
    fn record_debug(&mut self, field: &Field, value: &dyn fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.message, "{value:?}");
        } else {
            if !self.rest.is_empty() {
                self.rest.push(' ');
            }
            let _ = write!(self.rest, "{}={value:?}", field.name());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_format_message_first() {
        struct Probe;
        impl Subscriber for Probe {
            fn enabled(&self, _: &Metadata<'_>) -> bool {
                true
            }
            fn new_span(&self, _: &Attributes<'_>) -> Id {
                Id::from_u64(1)
            }
            fn record(&self, _: &Id, _: &Record<'_>) {}
            fn record_follows_from(&self, _: &Id, _: &Id) {}
            fn event(&self, event: &Event<'_>) {
                let mut fields = FieldFormatter::default();
                event.record(&mut fields);
                assert_eq!(fields.message, "described 3 points");
                assert_eq!(fields.rest, "rings=20 name=\"x\"");
            }
            fn enter(&self, _: &Id) {}
            fn exit(&self, _: &Id) {}
        }
        tracing::subscriber::with_default(Probe, || {
            tracing::info!(rings = 20, name = "x", "described {} points", 3);
        });
    }
}
