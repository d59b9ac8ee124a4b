//! The port's writer lock: the reader thread and the port's task both write on the port, and
//! each holds this lock while it takes frames from the queue and writes them, so that frames go
//! out in the order they were queued. Lock-free on the thread's side (it takes it for every
//! frame it reads), a wait on a [`Notify`] on the task's (which takes it seldom).

use std::sync::atomic::{AtomicBool, Ordering};
use tokio::sync::Notify;

/// The port's writer lock, between its reader thread (which takes it for every frame it reads:
/// one atomic swap each way, no wait machinery) and its task (which takes it seldom: for what
/// the device sends on timers and commands).
#[derive(Default)]
pub(super) struct WriterLock {
    busy: AtomicBool,
    /// The task waits for the lock.
    waiting: AtomicBool,
    freed: Notify,
}

/// Holds the writer lock; gives it back when dropped.
pub(super) struct Turn<'a>(&'a WriterLock);

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        // Sequentially consistent with `take`'s store and swap: either the task's last try
        // sees the lock free, or this sees the task waiting.
        self.0.busy.store(false, Ordering::SeqCst);
        if self.0.waiting.swap(false, Ordering::SeqCst) {
            self.0.freed.notify_one();
        }
    }
}

impl WriterLock {
    fn try_take(&self) -> Option<Turn<'_>> {
        // `then`, not `then_some`: a `Turn` made eagerly for a failed try would be dropped at
        // once, and its drop gives the lock back, freeing it under its holder.
        self.busy
            .compare_exchange(false, true, Ordering::SeqCst, Ordering::Relaxed)
            .is_ok()
            .then(|| Turn(self))
    }

    /// For the task.
    pub(super) async fn take(&self) -> Turn<'_> {
        loop {
            if let Some(t) = self.try_take() {
                return t;
            }
            let freed = self.freed.notified();
            tokio::pin!(freed);
            freed.as_mut().enable();
            self.waiting.store(true, Ordering::SeqCst);
            if let Some(t) = self.try_take() {
                self.waiting.store(false, Ordering::SeqCst);
                return t;
            }
            freed.await;
        }
    }

    /// For the reader thread: the task holds the lock only while it writes a few frames.
    pub(super) fn take_blocking(&self) -> Turn<'_> {
        let mut tries = 0u32;
        loop {
            if let Some(t) = self.try_take() {
                return t;
            }
            tries += 1;
            if tries < 64 {
                std::thread::yield_now();
            } else {
                std::thread::sleep(std::time::Duration::from_micros(100));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::WriterLock;

    /// A try that fails must leave the lock with its holder (a guard made for the failed try
    /// and dropped would give it back: two writers at once, frames out of order).
    #[test]
    fn a_failed_try_leaves_the_lock_with_its_holder() {
        let lock = WriterLock::default();
        let held = lock.try_take().expect("a free lock is taken");
        assert!(lock.try_take().is_none());
        assert!(lock.try_take().is_none(), "still held after a failed try");
        drop(held);
        assert!(lock.try_take().is_some());
    }
}
