//! Wake-ups put off until the state's lock is given back.
//!
//! **Why.** A transfer's outcome reaches the task waiting for it through a channel whose send
//! wakes that task: from a reader thread, a system call that unparks the runtime's worker.
//! Done while the thread still holds the state's lock, the woken task's next call (the next
//! read) finds the lock held and sleeps on it: another pair of system calls and a context
//! switch for every transfer, on a machine whose cores are all busy. So what the device does
//! inside the lock that would wake another thread is handed to [`after_unlock`], and the
//! runtime runs it once the lock is released ([`Unlocked`]). Outside the runtime's lock (a
//! device driven by hand, a test) it runs at once.

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;

/// What [`after_unlock`] was given: each runs once.
type Later = Box<dyn FnOnce() + Send>;

thread_local! {
    /// How many [`Unlocked`] guards this thread holds (nested runtime sections).
    static DEPTH: Cell<u32> = const { Cell::new(0) };
    /// What waits for the outermost guard's drop, oldest first.
    static LATER: RefCell<VecDeque<Later>> = const { RefCell::new(VecDeque::new()) };
}

/// Runs `f` once the runtime has given the state's lock back, if this thread holds it now;
/// at once otherwise.
pub(crate) fn after_unlock(f: impl FnOnce() + Send + 'static) {
    if DEPTH.get() == 0 {
        f();
    } else {
        LATER.with_borrow_mut(|l| l.push_back(Box::new(f)));
    }
}

/// Held around every section in which the runtime holds the state's lock, made before the
/// lock is taken so that it is dropped after the lock is: its drop runs what the section put
/// off (also when the section panicked: the waiting tasks then see their channels closed as
/// the device goes, not hang).
pub(crate) struct Unlocked(());

impl Unlocked {
    pub(crate) fn new() -> Self {
        DEPTH.set(DEPTH.get() + 1);
        Unlocked(())
    }
}

impl Drop for Unlocked {
    fn drop(&mut self) {
        let depth = DEPTH.get().saturating_sub(1);
        DEPTH.set(depth);
        if depth == 0 {
            // One at a time, the queue not borrowed while one runs (it may put off more, which
            // then runs at once: depth 0); the queue keeps its room for the next section.
            while let Some(f) = LATER.with_borrow_mut(VecDeque::pop_front) {
                f();
            }
        }
    }
}
