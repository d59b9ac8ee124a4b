//! Events a core adds to the network's stream: [`NetEvent::Ext`](super::NetEvent::Ext).
//!
//! **Why.** The door's events are the ones every core shares (boot-ups, states, EMCY, PDOs,
//! ports). A core that knows more (a redundant master: its pairs, its role, A/B discrepancies)
//! reports it through the same stream, typed, without the door naming its types: the event is
//! an [`Extension`] behind an [`ExtEvent`], which answers the common questions (when, which
//! node, a failover?) and prints one line, and the reader who knows the type gets it back with
//! [`ExtEvent::downcast_ref`] or [`NetEvent::ext`](super::NetEvent::ext).

use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use core::any::Any;
use core::fmt;
use std::sync::Arc;

/// An event of a core's own, carried by [`NetEvent::Ext`](super::NetEvent::Ext). `Display`
/// prints it as one line, as every event of the stream.
///
/// `eq_dyn` compares it with another extension event (false for one of another type):
///
/// ```
/// # use duocan::net::Extension;
/// # use duocan::{Instant, NodeId};
/// #[derive(Debug, PartialEq)]
/// struct Tick(Instant);
/// # impl std::fmt::Display for Tick {
/// #     fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result { f.write_str("tick") }
/// # }
/// impl Extension for Tick {
///     fn at(&self) -> Instant { self.0 }
///     fn node(&self) -> Option<NodeId> { None }
///     fn eq_dyn(&self, other: &dyn Extension) -> bool {
///         (other as &dyn std::any::Any).downcast_ref::<Tick>() == Some(self)
///     }
/// }
/// ```
pub trait Extension: Any + fmt::Debug + fmt::Display + Send + Sync {
    /// When it happened (the network's clock).
    fn at(&self) -> Instant;
    /// The node it is about, if one.
    fn node(&self) -> Option<NodeId>;
    /// True if it is a failover (something in use failed and another part took over).
    fn is_failover(&self) -> bool {
        false
    }
    /// True if `other` is the same event (of the same type).
    fn eq_dyn(&self, other: &dyn Extension) -> bool;
}

/// An [`Extension`] event, shared (cloning it is cheap: every reader of the stream gets the
/// same one).
#[derive(Clone)]
pub struct ExtEvent(Arc<dyn Extension>);

impl ExtEvent {
    /// `e` as an event of the stream.
    pub fn new(e: impl Extension) -> Self {
        ExtEvent(Arc::new(e))
    }
    /// The event as its own type `T`, if it is one.
    #[must_use]
    pub fn downcast_ref<T: Extension>(&self) -> Option<&T> {
        let any: &dyn Any = &*self.0;
        any.downcast_ref()
    }
    /// The event itself.
    #[must_use]
    pub fn get(&self) -> &dyn Extension {
        &*self.0
    }
}

impl fmt::Debug for ExtEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&*self.0, f)
    }
}

impl fmt::Display for ExtEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&*self.0, f)
    }
}

impl PartialEq for ExtEvent {
    fn eq(&self, other: &Self) -> bool {
        self.0.eq_dyn(&*other.0)
    }
}
