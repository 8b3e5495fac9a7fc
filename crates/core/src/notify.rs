//! A wake-up primitive for threads that wait on a lock-free structure.
//!
//! The ring buffers and the frame pool are lock-free; only a thread that has
//! nothing to do takes this lock, so idle stages sleep instead of spinning.
//! The protocol is the classic store-then-load pair: the waiter registers and
//! re-checks its condition, the notifier changes state and then looks for
//! waiters, with a `SeqCst` fence on both sides, so one of them always sees
//! the other and no wake-up is lost.

use std::sync::atomic::{fence, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

#[derive(Default)]
pub struct Notify {
    waiters: AtomicUsize,
    lock: Mutex<()>,
    cv: Condvar,
}

impl Notify {
    pub fn new() -> Self {
        Self::default()
    }

    /// Waits until `ready()` holds, or `timeout` elapses. Returns `ready()`.
    ///
    /// Spurious returns are allowed; callers loop and re-check their own
    /// stop flags between calls.
    pub fn wait_until(&self, timeout: Duration, mut ready: impl FnMut() -> bool) -> bool {
        if ready() {
            return true;
        }
        let guard = self.lock.lock().unwrap_or_else(|e| e.into_inner());
        self.waiters.fetch_add(1, Ordering::SeqCst);
        fence(Ordering::SeqCst);
        let ok = if ready() {
            true
        } else {
            let (_guard, _) = self
                .cv
                .wait_timeout(guard, timeout)
                .unwrap_or_else(|e| e.into_inner());
            ready()
        };
        self.waiters.fetch_sub(1, Ordering::SeqCst);
        ok
    }

    /// Wakes every waiter. Cheap (one atomic load) when nobody waits.
    pub fn notify(&self) {
        fence(Ordering::SeqCst);
        if self.waiters.load(Ordering::SeqCst) > 0 {
            let _guard = self.lock.lock().unwrap_or_else(|e| e.into_inner());
            self.cv.notify_all();
        }
    }
}
