//! Each lenient warning is a `tracing` event at the warn level, target `duocan::eds`, whose
//! message is the warning: file, line, section, key, what was wrong and the value taken.

use crate::path;
use duocan::eds::Description;
use std::fmt::Debug;
use std::sync::{Arc, Mutex};
use tracing::field::{Field, Visit};
use tracing::span::{Attributes, Id, Record};
use tracing::{Event, Level, Metadata};

type Seen = Arc<Mutex<Vec<(Level, String, String)>>>;

/// Keeps every event's level, target and message.
struct Capture(Seen);

struct Message(String);

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}");
        }
    }
}

impl tracing::Subscriber for Capture {
    fn enabled(&self, _: &Metadata<'_>) -> bool {
        true
    }
    fn new_span(&self, _: &Attributes<'_>) -> Id {
        Id::from_u64(1)
    }
    fn record(&self, _: &Id, _: &Record<'_>) {}
    fn record_follows_from(&self, _: &Id, _: &Id) {}
    fn event(&self, e: &Event<'_>) {
        let mut m = Message(String::new());
        e.record(&mut m);
        let meta = e.metadata();
        self.0
            .lock()
            .unwrap()
            .push((*meta.level(), meta.target().into(), m.0));
    }
    fn enter(&self, _: &Id) {}
    fn exit(&self, _: &Id) {}
}

/// What `f` returns, and the events it traced (level, target, message).
pub fn traced<T>(f: impl FnOnce() -> T) -> (T, Vec<(Level, String, String)>) {
    let seen: Seen = Arc::default();
    let r = tracing::subscriber::with_default(Capture(seen.clone()), f);
    let seen = seen.lock().unwrap().clone();
    (r, seen)
}

#[test]
fn every_warning_is_a_tracing_event() {
    let seen: Seen = Arc::default();
    let d = tracing::subscriber::with_default(Capture(seen.clone()), || {
        Description::read(path("strict/duplicate_key.eds")).unwrap()
    });
    let seen = seen.lock().unwrap();
    assert_eq!(d.warnings.len(), 1);
    assert_eq!(seen.len(), 1, "{seen:?}");
    let (level, target, message) = &seen[0];
    assert_eq!((*level, target.as_str()), (Level::WARN, "duocan::eds"));
    assert_eq!(*message, d.warnings[0].to_string());
    assert!(
        message.ends_with("duplicate_key.eds:117: [2000] DefaultValue: the key appears twice; taken: \"2\", the last one (the first is on line 115)"),
        "{message}"
    );
}

#[test]
fn a_clean_file_says_nothing() {
    let seen: Seen = Arc::default();
    tracing::subscriber::with_default(Capture(seen.clone()), || {
        Description::read(path("data_types.eds")).unwrap()
    });
    assert!(seen.lock().unwrap().is_empty());
}
