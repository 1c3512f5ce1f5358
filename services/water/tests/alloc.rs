//! Frames of a fixed size allocate nothing once the detector is warmed up.

mod common;

use common::{frame, scene};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts heap allocations so the steady-state test can assert there are none.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;
use water::{WaterConfig, WaterDetector};

#[test]
fn steady_state_frames_do_not_allocate() {
    let s = scene();
    let mut det = WaterDetector::new(WaterConfig::default());
    // Warm-up sizes every buffer (twice: the first frame also starts rayon's pool).
    for _ in 0..2 {
        det.process(&frame(&s)).unwrap();
    }
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    for _ in 0..3 {
        let d = det.process(&frame(&s)).unwrap();
        assert_eq!(d.regions.len(), 1);
    }
    // The only test in this binary, so nothing else allocates meanwhile.
    assert_eq!(ALLOCATIONS.load(Ordering::SeqCst) - before, 0);
}
