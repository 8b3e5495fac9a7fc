//! Gray frames from a fixed pool.
//!
//! A source allocates its pool once, sized for the graph (every edge full
//! plus what stages hold). A [`FrameMut`] is the unique, writable handle a
//! source fills; [`FrameMut::freeze`] turns it into a [`Frame`], a shared,
//! read-only handle that edges carry. Cloning a `Frame` bumps a counter (no
//! allocation, no copy); when the last handle drops, the buffer goes back to
//! the pool's lock-free free list.

use super::notify::Notify;
use crossbeam_queue::ArrayQueue;
use std::cell::UnsafeCell;
use std::sync::atomic::{fence, AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

pub use vibroscope_io::Depth;

/// Row timing of a rolling-shutter camera: row `y` is captured at
/// `t + y * line_delay_ns` and exposed for `exposure_ns`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowTiming {
    pub line_delay_ns: f64,
    pub exposure_ns: f64,
}

/// What every frame of one stream shares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameFormat {
    pub width: u32,
    pub height: u32,
    pub depth: Depth,
    /// Significant bits (8 for 8-bit, 10/12/16 for deeper cameras).
    pub bits: u8,
    /// Nominal capture rate in Hz (the camera's, not a container's playback rate).
    pub fps: f64,
    pub row_timing: Option<RowTiming>,
}

impl FrameFormat {
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
    pub fn max_value(&self) -> f64 {
        ((1u32 << self.bits.clamp(1, 16)) - 1) as f64
    }
}

/// Per-frame metadata.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameMeta {
    /// Sequence number as the source counted it (gaps mean drops upstream).
    pub seq: u64,
    /// Capture time of the first row, nanoseconds on the source's clock.
    pub t_ns: i64,
}

enum Pixels {
    U8(Box<[u8]>),
    U16(Box<[u16]>),
}

/// Borrowed pixels of a frame, row-major, top row first.
#[derive(Clone, Copy)]
pub enum PixelsRef<'a> {
    U8(&'a [u8]),
    U16(&'a [u16]),
}

/// Mutable pixels of a frame being filled.
pub enum PixelsMut<'a> {
    U8(&'a mut [u8]),
    U16(&'a mut [u16]),
}

struct Slot {
    refs: AtomicUsize,
    data: UnsafeCell<(FrameMeta, Pixels)>,
}

// SAFETY: the cell is written only through a `FrameMut`, which exists only
// while the slot is off the free list with `refs == 1` and is the one handle
// to it; `Frame` handles only read. Handing a slot from one thread to another
// goes through the free list (ArrayQueue, acquire/release) or an edge ring
// (acquire/release), which order the writes before the reads.
unsafe impl Sync for Slot {}

struct PoolShared {
    format: FrameFormat,
    slots: Box<[Slot]>,
    free: ArrayQueue<usize>,
    returned: Notify,
    closed: AtomicBool,
}

/// A fixed pool of frame buffers of one format.
#[derive(Clone)]
pub struct FramePool {
    shared: Arc<PoolShared>,
}

impl FramePool {
    /// Allocates `count` buffers up front (at least one).
    pub fn new(format: FrameFormat, count: usize) -> Self {
        let count = count.max(1);
        let n = format.pixels();
        let slots: Box<[Slot]> = (0..count)
            .map(|_| Slot {
                refs: AtomicUsize::new(0),
                data: UnsafeCell::new((
                    FrameMeta::default(),
                    match format.depth {
                        Depth::U8 => Pixels::U8(vec![0u8; n].into_boxed_slice()),
                        Depth::U16 => Pixels::U16(vec![0u16; n].into_boxed_slice()),
                    },
                )),
            })
            .collect();
        let free = ArrayQueue::new(count);
        for i in 0..count {
            // Cannot fail: the queue has room for exactly `count` indices.
            let _ = free.push(i);
        }
        Self {
            shared: Arc::new(PoolShared {
                format,
                slots,
                free,
                returned: Notify::new(),
                closed: AtomicBool::new(false),
            }),
        }
    }

    pub fn format(&self) -> &FrameFormat {
        &self.shared.format
    }

    pub fn capacity(&self) -> usize {
        self.shared.slots.len()
    }

    /// Buffers currently free.
    pub fn available(&self) -> usize {
        self.shared.free.len()
    }

    /// Takes a free buffer without waiting.
    pub fn try_acquire(&self) -> Option<FrameMut> {
        let idx = self.shared.free.pop()?;
        self.shared.slots[idx].refs.store(1, Ordering::Relaxed);
        Some(FrameMut {
            shared: Arc::clone(&self.shared),
            idx,
        })
    }

    /// Takes a free buffer, sleeping (not spinning) up to `timeout` while
    /// every buffer is in use downstream. `None` on timeout.
    pub fn acquire_timeout(&self, timeout: Duration) -> Option<FrameMut> {
        if let Some(f) = self.try_acquire() {
            return Some(f);
        }
        self.shared
            .returned
            .wait_until(timeout, || !self.shared.free.is_empty());
        self.try_acquire()
    }

    /// Marks the pool closed (informational for sources polling it).
    pub fn close(&self) {
        self.shared.closed.store(true, Ordering::Release);
        self.shared.returned.notify();
    }
}

fn release(shared: &PoolShared, idx: usize) {
    // The last handle returns the slot; the fence orders every read of the
    // slot by other handles before the next writer's writes.
    if shared.slots[idx].refs.fetch_sub(1, Ordering::Release) == 1 {
        fence(Ordering::Acquire);
        // Cannot fail: each index is on the list at most once.
        let _ = shared.free.push(idx);
        shared.returned.notify();
    }
}

/// The unique, writable handle to a pooled frame.
pub struct FrameMut {
    shared: Arc<PoolShared>,
    idx: usize,
}

impl FrameMut {
    pub fn format(&self) -> &FrameFormat {
        &self.shared.format
    }

    fn cell(&mut self) -> &mut (FrameMeta, Pixels) {
        // SAFETY: a FrameMut is the only handle to its slot (refs == 1 and
        // the slot is off the free list), and `&mut self` makes this borrow
        // unique.
        unsafe { &mut *self.shared.slots[self.idx].data.get() }
    }

    /// Index of the pool buffer behind this frame (stable for the pool's life).
    pub fn slot(&self) -> usize {
        self.idx
    }

    pub fn meta_mut(&mut self) -> &mut FrameMeta {
        &mut self.cell().0
    }

    pub fn pixels_mut(&mut self) -> PixelsMut<'_> {
        match &mut self.cell().1 {
            Pixels::U8(p) => PixelsMut::U8(p),
            Pixels::U16(p) => PixelsMut::U16(p),
        }
    }

    /// Ends writing; the frame becomes shareable.
    pub fn freeze(self) -> Frame {
        let me = std::mem::ManuallyDrop::new(self);
        // SAFETY: `me` is never dropped, so the Arc is moved out exactly once.
        let shared = unsafe { std::ptr::read(&me.shared) };
        Frame {
            shared,
            idx: me.idx,
        }
    }
}

impl Drop for FrameMut {
    fn drop(&mut self) {
        release(&self.shared, self.idx);
    }
}

/// A shared, read-only handle to a pooled frame. Cloning is cheap.
pub struct Frame {
    shared: Arc<PoolShared>,
    idx: usize,
}

impl Frame {
    fn cell(&self) -> &(FrameMeta, Pixels) {
        // SAFETY: no FrameMut exists for a slot that has Frame handles, so
        // nobody writes while this shared borrow lives.
        unsafe { &*self.shared.slots[self.idx].data.get() }
    }

    pub fn format(&self) -> &FrameFormat {
        &self.shared.format
    }

    pub fn meta(&self) -> &FrameMeta {
        &self.cell().0
    }

    pub fn width(&self) -> usize {
        self.shared.format.width as usize
    }

    pub fn height(&self) -> usize {
        self.shared.format.height as usize
    }

    pub fn pixels(&self) -> PixelsRef<'_> {
        match &self.cell().1 {
            Pixels::U8(p) => PixelsRef::U8(p),
            Pixels::U16(p) => PixelsRef::U16(p),
        }
    }

    /// Capture time of row `y` (rolling shutter aware).
    pub fn row_time_ns(&self, y: usize) -> i64 {
        let t0 = self.meta().t_ns;
        match self.shared.format.row_timing {
            Some(rt) => t0 + (y as f64 * rt.line_delay_ns).round() as i64,
            None => t0,
        }
    }
}

impl Clone for Frame {
    fn clone(&self) -> Self {
        self.shared.slots[self.idx]
            .refs
            .fetch_add(1, Ordering::Relaxed);
        Frame {
            shared: Arc::clone(&self.shared),
            idx: self.idx,
        }
    }
}

impl Drop for Frame {
    fn drop(&mut self) {
        release(&self.shared, self.idx);
    }
}

impl std::fmt::Debug for Frame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Frame")
            .field("seq", &self.meta().seq)
            .field("t_ns", &self.meta().t_ns)
            .field("width", &self.width())
            .field("height", &self.height())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fmt() -> FrameFormat {
        FrameFormat {
            width: 4,
            height: 2,
            depth: Depth::U8,
            bits: 8,
            fps: 100.0,
            row_timing: None,
        }
    }

    #[test]
    fn frames_return_to_pool_after_last_handle() {
        let pool = FramePool::new(fmt(), 2);
        let mut a = pool.try_acquire().unwrap();
        if let PixelsMut::U8(p) = a.pixels_mut() {
            p[0] = 7;
        }
        a.meta_mut().seq = 3;
        let a = a.freeze();
        let b = a.clone();
        assert_eq!(pool.available(), 1);
        drop(a);
        assert_eq!(pool.available(), 1);
        assert_eq!(b.meta().seq, 3);
        assert!(matches!(b.pixels(), PixelsRef::U8(p) if p[0] == 7));
        drop(b);
        assert_eq!(pool.available(), 2);
    }

    #[test]
    fn exhausted_pool_times_out_then_recovers() {
        let pool = FramePool::new(fmt(), 1);
        let a = pool.try_acquire().unwrap();
        assert!(pool.acquire_timeout(Duration::from_millis(5)).is_none());
        let p2 = pool.clone();
        let h = std::thread::spawn(move || p2.acquire_timeout(Duration::from_secs(5)).is_some());
        std::thread::sleep(Duration::from_millis(20));
        drop(a);
        assert!(h.join().unwrap());
    }
}
