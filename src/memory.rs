//! The process's allocator: the system's, with large allocations backed by transparent
//! huge pages where the kernel offers them on request (`madvise` mode, the common
//! default).
//!
//! Loading a large scene touches gigabytes of fresh memory (the parsed triangles, the
//! BVH builders' arrays, the records made for the device), and each fresh 4 KiB page
//! costs a fault and a clear. On this project's machine (a virtual machine) first touches
//! ran at 2.5 GB/s in 4 KiB pages and 11 GB/s in 2 MiB pages, and the 20-million-triangle
//! mesh's load spent 17.6 s of its cores' time in the kernel, most of it clearing pages
//! (docs/performance.md, "Twenty-ninth session"). So each allocation of at least
//! [`LARGE`] bytes asks for huge pages over the 2 MiB-aligned part of its range; smaller
//! ones and every free go to the system allocator unchanged.
use std::alloc::{GlobalAlloc, Layout, System};

/// The smallest allocation advised to use huge pages.
pub const LARGE: usize = 8 << 20;

const HUGE_PAGE: usize = 2 << 20;

/// The system allocator, advising huge pages for allocations of [`LARGE`] bytes or more
/// (declared the global allocator by the command line and the Python extension).
pub struct LargePages;

/// Asks the kernel to back the huge-page-aligned part of `[p, p + len)` with huge pages
/// (a hint: where it cannot, the range keeps its small pages).
fn advise(p: *mut u8, len: usize) {
    #[cfg(target_os = "linux")]
    {
        let start = (p as usize).next_multiple_of(HUGE_PAGE);
        let end = (p as usize + len) & !(HUGE_PAGE - 1);
        if end > start {
            // SAFETY: the range lies inside an allocation the caller owns; MADV_HUGEPAGE
            // changes no contents, only how later faults are backed.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (p, len);
}

// SAFETY: every call forwards to `System` with the caller's layout; `advise` only hints.
unsafe impl GlobalAlloc for LargePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if layout.size() >= LARGE && !p.is_null() {
            advise(p, layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc_zeroed(layout);
        if layout.size() >= LARGE && !p.is_null() {
            advise(p, layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        System.dealloc(p, layout)
    }

    unsafe fn realloc(&self, p: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let q = System.realloc(p, layout, new_size);
        if new_size >= LARGE && !q.is_null() {
            advise(q, new_size);
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_allocations_keep_their_contents_through_growth() {
        let a = LargePages;
        unsafe {
            let layout = Layout::from_size_align(LARGE + 12_345, 64).unwrap();
            let p = a.alloc(layout);
            assert!(!p.is_null());
            for i in 0..layout.size() {
                *p.add(i) = (i % 251) as u8;
            }
            let q = a.realloc(p, layout, 3 * LARGE);
            assert!(!q.is_null());
            assert_eq!(q as usize % 64, 0);
            assert!((0..layout.size()).all(|i| *q.add(i) == (i % 251) as u8));
            a.dealloc(q, Layout::from_size_align(3 * LARGE, 64).unwrap());
            let z = a.alloc_zeroed(layout);
            assert!((0..layout.size()).all(|i| *z.add(i) == 0));
            a.dealloc(z, layout);
        }
    }
}
