//! The unit tests' allocator: the system's, counting the heap bytes that the threads of a
//! measurement hold ([`peak_heap_bytes`]), so that a test can bound what a walk holds
//! at its peak. Threads outside a measurement (the other tests') are not counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

thread_local! {
    /// Whether this thread's allocations are counted.
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

/// Bytes the counted threads hold (never below zero: [`shrink`]), and its highest.
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

/// One measurement at a time.
static MEASURING: Mutex<()> = Mutex::new(());

/// The system's allocator, counting the counted threads' bytes.
pub struct CountedHeap;

fn counted() -> bool {
    COUNTED.try_with(Cell::get).unwrap_or(false)
}

fn grow(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(live, Ordering::Relaxed);
}

/// Frees of blocks taken before the measurement (the pool's own, let go as it starts)
/// bring the count no lower than zero, so they cannot hide what the measurement holds.
fn shrink(bytes: usize) {
    let _ = LIVE.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |live| {
        Some(live.saturating_sub(bytes))
    });
}

// SAFETY: every call is the system allocator's with the caller's own arguments; the
// counting beside it allocates nothing (a const thread-local `Cell` and atomics).
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for CountedHeap {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() && counted() {
            grow(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() && counted() {
            grow(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) };
        if counted() {
            shrink(layout.size());
        }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() && counted() {
            if new_size <= layout.size() {
                // Shrunk where it stands (glibc's heap splits the block, a mapping is
                // remapped smaller): never held twice.
                shrink(layout.size() - new_size);
            } else {
                // Grown, perhaps moved: both held for the copy.
                grow(new_size);
                shrink(layout.size());
            }
        }
        p
    }
}

/// `f`'s result, and the most heap its run held at once beyond what was held before it
/// (bytes; what it returns included; blocks taken before it and let go by its threads
/// are counted off, a few KiB of the pool's own): `f` runs on a rayon pool of `threads` threads of its
/// own, counted with the calling thread.
pub fn peak_heap_bytes<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> (R, usize) {
    let _one = MEASURING.lock().unwrap_or_else(|e| e.into_inner());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .start_handler(|_| COUNTED.with(|c| c.set(true)))
        .build()
        .expect("a measurement's thread pool");
    // Every thread started (and counted) before the count starts.
    pool.broadcast(|_| ());
    COUNTED.with(|c| c.set(true));
    LIVE.store(0, Ordering::Relaxed);
    PEAK.store(0, Ordering::Relaxed);
    let r = pool.install(f);
    let peak = PEAK.load(Ordering::Relaxed);
    COUNTED.with(|c| c.set(false));
    (r, peak)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_measurement_counts_what_its_threads_hold_at_once() {
        use rayon::prelude::*;
        // Four buffers of 1 MB held at once on four threads, let go, then one of 2 MB.
        let ((), peak) = peak_heap_bytes(4, || {
            let held: Vec<Vec<u8>> = (0..4)
                .into_par_iter()
                .map(|i| vec![i as u8; 1 << 20])
                .collect();
            assert_eq!(held.len(), 4);
            drop(held);
            let two = vec![1u8; 2 << 20];
            assert_eq!(two.len(), 2 << 20);
        });
        // Within 64 KiB: blocks of rayon's taken before the count and let go during it
        // are counted off it, and the threads' own small ones on it.
        let about = |bytes: usize| bytes - (64 << 10)..bytes + (64 << 10);
        assert!(about(4 << 20).contains(&peak), "{peak}");
        // What is returned is held at the end.
        let (kept, peak) = peak_heap_bytes(2, || vec![0u64; 1 << 17]);
        assert_eq!(kept.len(), 1 << 17);
        assert!(about(1 << 20).contains(&peak), "{peak}");
    }
}
