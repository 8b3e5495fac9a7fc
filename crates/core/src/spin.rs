//! A two-thread [`Join`] for work split into halves of tens of
//! microseconds: one helper thread that spins between jobs, so a half
//! handed to it starts within a fraction of a microsecond, and parks after
//! a quiet spell (no CPU burnt between the frames of a slow camera).
//!
//! A pool whose workers sleep (rayon's) wakes a worker in tens of
//! microseconds, about as long as the half it is given: the magnifier's
//! passes over a 256x256 level ran 1.05x faster on two threads than on
//! one through rayon, 1.57x through a spinning helper
//! (`cargo bench --bench roofline`).
//!
//! The caller runs the first half itself. If the helper has not taken the
//! second half by the time the first is done (it was parked, or the OS ran
//! something else on its core), the caller takes it back and runs it too,
//! so a late helper never makes a join slower than running both halves in
//! turn. A join called while one is under way (from inside a half) runs
//! its halves in turn. A panic in either half reaches the caller after
//! both halves have stopped.

use std::any::Any;
use std::cell::UnsafeCell;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering::*};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use vibroscope_math::join::Join;

/// No job; a caller may claim the slot.
const IDLE: u8 = 0;
/// A caller is writing the job into the slot.
const WRITING: u8 = 1;
/// The slot holds a job nobody has taken.
const JOB: u8 = 2;
/// The helper is running the job.
const RUNNING: u8 = 3;
/// The helper has finished the job; the caller has not yet seen it.
const DONE: u8 = 4;
/// The helper is to stop.
const EXIT: u8 = 5;

/// The second half of a join, its lifetime erased: valid from the moment
/// the state becomes `JOB` until the caller sees `DONE` (or takes the job
/// back), and the caller does not return before then.
type JobPtr = *mut (dyn FnMut() + Send + 'static);

struct Shared {
    state: AtomicU8,
    sleeping: AtomicBool,
    job: UnsafeCell<Option<JobPtr>>,
    panic: Mutex<Option<Box<dyn Any + Send>>>,
    spin: Duration,
}

// SAFETY: `job` is written only by the caller that moved the state from
// `IDLE` to `WRITING`, and read only by the helper after it moved the
// state from `JOB` to `RUNNING`; the atomic state orders the two (Release
// on publishing, Acquire on taking), so they never touch it at once.
unsafe impl Sync for Shared {}
// SAFETY: the pointer in `job` is only dereferenced under the protocol
// above; the closure it points to is `Send`.
unsafe impl Send for Shared {}

/// A [`Join`] over the calling thread and one helper thread that spins
/// between jobs for `spin`, then parks until the next.
pub struct SpinJoin {
    shared: Arc<Shared>,
    helper: Option<JoinHandle<()>>,
}

impl SpinJoin {
    /// Starts the helper thread (named `name`). It spins for `spin` after
    /// each job before it parks: long enough to cover the gaps between the
    /// joins of one frame, short enough not to spin through the wait for
    /// the next frame of a live camera.
    pub fn new(name: &str, spin: Duration) -> std::io::Result<Self> {
        let shared = Arc::new(Shared {
            state: AtomicU8::new(IDLE),
            sleeping: AtomicBool::new(false),
            job: UnsafeCell::new(None),
            panic: Mutex::new(None),
            spin,
        });
        let s = Arc::clone(&shared);
        let helper = thread::Builder::new()
            .name(name.to_string())
            .spawn(move || helper(&s))?;
        Ok(Self {
            shared,
            helper: Some(helper),
        })
    }

    fn wake(&self) {
        if self.shared.sleeping.load(SeqCst) {
            if let Some(h) = &self.helper {
                h.thread().unpark();
            }
        }
    }
}

/// A helper thread's wait between jobs: it spins for `spin` after its
/// last job, so a job that comes soon starts within a fraction of a
/// microsecond, then parks until a publisher that sees `sleeping` unparks
/// it (no CPU burnt between the frames of a slow camera).
pub struct Idle {
    spin: Duration,
    last: Instant,
    spins: u32,
}

impl Idle {
    pub fn new(spin: Duration) -> Self {
        Self {
            spin,
            last: Instant::now(),
            spins: 0,
        }
    }

    /// A job has just ended: the spin starts again.
    pub fn worked(&mut self) {
        self.last = Instant::now();
        self.spins = 0;
    }

    /// One turn of the wait: a spin, or, once `spin` has passed, a park
    /// unless `ready()` (a job or an exit) already holds. A publisher
    /// makes its job visible, then reads `sleeping` (both SeqCst), and
    /// unparks this thread if it is set: one of the two sees the other's
    /// write, so no job is left waiting for a sleeper.
    pub fn wait(&mut self, sleeping: &AtomicBool, ready: impl Fn() -> bool) {
        std::hint::spin_loop();
        self.spins = self.spins.wrapping_add(1);
        if self.spins.is_multiple_of(256) && self.last.elapsed() >= self.spin {
            sleeping.store(true, SeqCst);
            if !ready() {
                thread::park();
            }
            sleeping.store(false, SeqCst);
            self.last = Instant::now();
        }
    }
}

/// Spins until `done()`, yielding the core every 1024 turns (the thread
/// being waited for may have lost its core to something else).
pub fn spin_until(done: impl Fn() -> bool) {
    let mut spins = 0u32;
    while !done() {
        spins = spins.wrapping_add(1);
        if spins.is_multiple_of(1024) {
            thread::yield_now();
        } else {
            std::hint::spin_loop();
        }
    }
}

fn helper(s: &Shared) {
    let mut idle = Idle::new(s.spin);
    loop {
        match s.state.load(Acquire) {
            JOB => {
                if s.state
                    .compare_exchange(JOB, RUNNING, Acquire, Relaxed)
                    .is_err()
                {
                    // The caller took the job back.
                    continue;
                }
                // SAFETY: the state was `JOB`, so the caller wrote the
                // slot and waits for `DONE` before it returns (see
                // `JobPtr`).
                let f = unsafe { (*s.job.get()).take() };
                if let Some(f) = f {
                    // SAFETY: as above; no one else holds the closure.
                    let r = catch_unwind(AssertUnwindSafe(|| unsafe { (*f)() }));
                    if let Err(p) = r {
                        if let Ok(mut slot) = s.panic.lock() {
                            *slot = Some(p);
                        }
                    }
                }
                s.state.store(DONE, Release);
                idle.worked();
            }
            EXIT => return,
            _ => idle.wait(&s.sleeping, || matches!(s.state.load(SeqCst), JOB | EXIT)),
        }
    }
}

impl Join for SpinJoin {
    fn join(&self, a: &mut (dyn FnMut() + Send), b: &mut (dyn FnMut() + Send)) {
        let s = &*self.shared;
        if s.state
            .compare_exchange(IDLE, WRITING, Acquire, Relaxed)
            .is_err()
        {
            // A join is under way (this is a nested one): in turn.
            a();
            b();
            return;
        }
        let ptr: *mut (dyn FnMut() + Send + '_) = b;
        // SAFETY: only the lifetime is changed; the helper runs the
        // closure only before this function returns (it waits below for
        // `DONE` or takes the job back).
        let ptr: JobPtr = unsafe { std::mem::transmute(ptr) };
        // SAFETY: this caller moved the state to `WRITING`; nobody else
        // reads or writes the slot until it publishes `JOB`.
        unsafe { *s.job.get() = Some(ptr) };
        s.state.store(JOB, SeqCst);
        self.wake();
        let first = catch_unwind(AssertUnwindSafe(&mut *a));
        // Take the second half back if the helper has not started it.
        let mut second = Ok(());
        if s.state
            .compare_exchange(JOB, WRITING, Acquire, Acquire)
            .is_ok()
        {
            // SAFETY: the state is ours again (`WRITING`).
            unsafe { *s.job.get() = None };
            if first.is_ok() {
                second = catch_unwind(AssertUnwindSafe(&mut *b));
            }
        } else {
            spin_until(|| s.state.load(Acquire) == DONE);
            if let Some(p) = s.panic.lock().ok().and_then(|mut p| p.take()) {
                second = Err(p);
            }
        }
        s.state.store(IDLE, Release);
        if let Err(p) = first.and(second) {
            resume_unwind(p);
        }
    }
}

impl Drop for SpinJoin {
    fn drop(&mut self) {
        // Wait out a job under way (only a join in progress on another
        // thread could hold one; `Drop` takes `&mut self`, so none is).
        self.shared.state.store(EXIT, SeqCst);
        if let Some(h) = self.helper.take() {
            h.thread().unpark();
            let _ = h.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    #[test]
    fn both_halves_run_once_each_every_time() {
        let j = SpinJoin::new("test-spin", Duration::from_micros(50)).unwrap();
        let (ca, cb) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let mut out = vec![0u64; 1000];
        for round in 0..2000u64 {
            let (lo, hi) = out.split_at_mut(500);
            j.join(
                &mut || {
                    ca.fetch_add(1, Relaxed);
                    lo.iter_mut().for_each(|v| *v += round);
                },
                &mut || {
                    cb.fetch_add(1, Relaxed);
                    hi.iter_mut().for_each(|v| *v += round);
                },
            );
            if round % 500 == 0 {
                // Let the helper park, so a join also meets a sleeper.
                thread::sleep(Duration::from_millis(1));
            }
        }
        assert_eq!(ca.load(Relaxed), 2000);
        assert_eq!(cb.load(Relaxed), 2000);
        let sum: u64 = (0..2000).sum();
        assert!(out.iter().all(|&v| v == sum));
    }

    #[test]
    fn a_nested_join_runs_in_turn() {
        let j = SpinJoin::new("test-spin", Duration::from_micros(50)).unwrap();
        let n = AtomicUsize::new(0);
        j.join(
            &mut || {
                j.join(&mut || _ = n.fetch_add(1, Relaxed), &mut || {
                    _ = n.fetch_add(1, Relaxed)
                })
            },
            &mut || _ = n.fetch_add(1, Relaxed),
        );
        assert_eq!(n.load(Relaxed), 3);
    }

    #[test]
    fn a_panic_in_either_half_reaches_the_caller_and_the_join_still_works() {
        let j = SpinJoin::new("test-spin", Duration::from_micros(50)).unwrap();
        for which in 0..2 {
            let r = catch_unwind(AssertUnwindSafe(|| {
                j.join(
                    &mut || {
                        if which == 0 {
                            panic!("first half")
                        }
                    },
                    &mut || {
                        if which == 1 {
                            panic!("second half")
                        }
                    },
                )
            }));
            assert!(r.is_err(), "half {which}'s panic was lost");
        }
        let n = AtomicUsize::new(0);
        j.join(&mut || _ = n.fetch_add(1, Relaxed), &mut || {
            _ = n.fetch_add(1, Relaxed)
        });
        assert_eq!(n.load(Relaxed), 2);
    }
}
