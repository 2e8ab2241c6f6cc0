//! A global allocator that counts allocations, for the no-allocation tests. Each such test file
//! installs it with `#[global_allocator]`. Only threads that called [`watch_this_thread`] are
//! counted: the test harness's own threads may allocate at any moment (CI saw it do so), and
//! what is under test is the evaluating thread.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

pub struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    // A const-initialised Cell has no destructor, so reading it never allocates.
    static WATCHED: Cell<bool> = const { Cell::new(false) };
}

/// Count this thread's allocations from now on.
pub fn watch_this_thread() {
    WATCHED.with(|w| w.set(true));
}

fn count() {
    if WATCHED.try_with(Cell::get).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
    }
}

/// Allocations (including reallocations) by watched threads so far.
pub fn allocations() -> usize {
    ALLOCATIONS.load(Ordering::SeqCst)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
