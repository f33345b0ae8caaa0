//! A global allocator that counts the allocations the calling thread makes while it counts:
//! a test proves a path allocates nothing (or as much as another) by counting around it. The
//! memory comes from the system allocator; other threads' allocations are never counted.
//!
//! ```ignore
//! #[global_allocator]
//! static ALLOCATOR: platform::alloc::Counting = platform::alloc::Counting;
//! let n = platform::alloc::Counting::count(|| step_the_drive());
//! ```

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// The system allocator, counting each `alloc` and `realloc` of a thread inside
/// [`Counting::count`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
    /// A thread whose allocations count while the window is open.
    static MARKED: Cell<bool> = const { Cell::new(false) };
    /// Inside [`Counting::show_where`]: its own allocations are not shown again.
    static SHOWING: Cell<bool> = const { Cell::new(false) };
}

/// With `COUNTING_BACKTRACE=1` in the environment, each allocation a window counts prints
/// the backtrace of where it was made (to find an allocation a test counts): read at
/// [`Counting::open_window`].
static SHOW: AtomicBool = AtomicBool::new(false);

/// Open between [`Counting::open_window`] and [`Counting::close_window`].
static WINDOW: AtomicBool = AtomicBool::new(false);
static MARKED_COUNT: AtomicU64 = AtomicU64::new(0);

impl Counting {
    /// Runs `f` and returns how many allocations (and reallocations) it made on this thread;
    /// counts only where `Counting` is the global allocator.
    pub fn count(f: impl FnOnce()) -> u64 {
        COUNT.with(|c| c.set(0));
        COUNTING.with(|c| c.set(true));
        f();
        COUNTING.with(|c| c.set(false));
        COUNT.with(Cell::get)
    }

    /// Marks the calling thread, so that a window opened on another thread
    /// ([`Counting::open_window`]) counts its allocations: a thread that runs a loop is
    /// measured from the thread that drives it, which may await between the two calls.
    pub fn mark_this_thread() {
        MARKED.with(|c| c.set(true));
    }

    /// Starts counting the marked threads' allocations from zero.
    pub fn open_window() {
        SHOW.store(
            std::env::var_os("COUNTING_BACKTRACE").is_some_and(|v| v == "1"),
            Ordering::Relaxed,
        );
        MARKED_COUNT.store(0, Ordering::Relaxed);
        WINDOW.store(true, Ordering::Relaxed);
    }

    /// Stops counting; how many allocations the marked threads made since
    /// [`Counting::open_window`].
    pub fn close_window() -> u64 {
        WINDOW.store(false, Ordering::Relaxed);
        MARKED_COUNT.load(Ordering::Relaxed)
    }

    fn note() {
        if COUNTING.with(Cell::get) {
            COUNT.with(|c| c.set(c.get() + 1));
        }
        if WINDOW.load(Ordering::Relaxed) && MARKED.with(Cell::get) {
            MARKED_COUNT.fetch_add(1, Ordering::Relaxed);
            if SHOW.load(Ordering::Relaxed) {
                Self::show_where();
            }
        }
    }

    /// Prints where the counted allocation was made; what printing allocates is neither
    /// counted nor shown.
    fn show_where() {
        if SHOWING.with(|s| s.replace(true)) {
            return;
        }
        let was = WINDOW.swap(false, Ordering::Relaxed);
        eprintln!(
            "counted allocation at:\n{}",
            std::backtrace::Backtrace::force_capture()
        );
        WINDOW.store(was, Ordering::Relaxed);
        SHOWING.with(|s| s.set(false));
    }
}

// SAFETY: every call goes to the system allocator with the caller's arguments; the count is a
// thread-local `Cell` with a `const` initialiser, which never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        Self::note();
        // SAFETY: as the caller's contract.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as the caller's contract.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        Self::note();
        // SAFETY: as the caller's contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
