//! A minimal `tracing` subscriber that records every event's target, level and fields.
//!
//! It is installed once as the test process's global default, before any plugin is loaded, the way a
//! real host installs its subscriber at start-up. (A scoped `with_default` subscriber would race with
//! other test threads registering the same callsites, a known limitation of `tracing`'s interest cache.)

use std::fmt::{self, Write as _};
use std::sync::{Arc, Mutex, OnceLock};

use tracing::field::{Field, Visit};
use tracing::span::{Attributes, Id, Record};
use tracing::{Event, Level, Metadata, Subscriber};

/// One recorded event.
#[derive(Clone, Debug)]
pub struct Captured {
    pub target: String,
    pub level: Level,
    /// Every field as `name=value` (strings unquoted), space-separated, the message as `message=…`.
    pub fields: String,
}

/// Records events into a shared list.
#[derive(Clone, Default)]
pub struct Capture {
    pub events: Arc<Mutex<Vec<Captured>>>,
}

/// The process-wide capture, installed as the global default on first use.
pub fn global() -> &'static Capture {
    static GLOBAL: OnceLock<Capture> = OnceLock::new();
    GLOBAL.get_or_init(|| {
        let capture = Capture::default();
        tracing::subscriber::set_global_default(capture.clone()).expect("no other global subscriber");
        capture
    })
}

impl Capture {
    /// The events recorded so far.
    pub fn events(&self) -> Vec<Captured> {
        self.events.lock().unwrap().clone()
    }
}

struct Fields(String);

impl Visit for Fields {
    fn record_str(&mut self, field: &Field, value: &str) {
        let _ = write!(self.0, "{}={value} ", field.name());
    }

    fn record_debug(&mut self, field: &Field, value: &dyn fmt::Debug) {
        let _ = write!(self.0, "{}={value:?} ", field.name());
    }
}

impl Subscriber for Capture {
    fn enabled(&self, _metadata: &Metadata<'_>) -> bool {
        true
    }

    fn new_span(&self, _span: &Attributes<'_>) -> Id {
        Id::from_u64(1)
    }

    fn record(&self, _span: &Id, _values: &Record<'_>) {}

    fn record_follows_from(&self, _span: &Id, _follows: &Id) {}

    fn event(&self, event: &Event<'_>) {
        let mut fields = Fields(String::new());
        event.record(&mut fields);
        let metadata = event.metadata();
        self.events.lock().unwrap().push(Captured {
            target: metadata.target().to_owned(),
            level: *metadata.level(),
            fields: fields.0,
        });
    }

    fn enter(&self, _span: &Id) {}

    fn exit(&self, _span: &Id) {}
}
