//! An allocator for the process: the system's, with every large block asked to be
//! backed by transparent huge pages (2 MiB instead of 4 KiB). The `agglo` binary and the
//! event benches use it; a program of your own can too:
//! `#[global_allocator] static A: agglo::huge_pages::HugePages = agglo::huge_pages::HugePages;`
//!
//! An event of a large cloud reads a few bytes from each of many arrays (paths, cells,
//! calendar, the world's columns) at places no cache predicts; with 4 KiB pages most of
//! those reads also miss the TLB. Linux backs memory with huge pages only where asked
//! (`/sys/kernel/mm/transparent_hugepage/enabled` is `madvise` on most distributions), so
//! blocks of at least [`ADVISE_FROM`] bytes are advised with `MADV_HUGEPAGE`. A hint
//! only: where the kernel has none to give, or off Linux, nothing changes, and results
//! never do.

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks from this size on are advised [B] (smaller ones share pages with other data).
const ADVISE_FROM: usize = 4 << 20;

/// The system allocator, advising large blocks (see the module docs).
pub struct HugePages;

// SAFETY: every call is forwarded to `System` unchanged; `advise` only sets a hint on
// whole pages inside the block just returned.
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded with the caller's guarantees.
        let block = unsafe { System.alloc(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded with the caller's guarantees.
        let block = unsafe { System.alloc_zeroed(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn dealloc(&self, block: *mut u8, layout: Layout) {
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.dealloc(block, layout) }
    }

    unsafe fn realloc(&self, block: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: forwarded with the caller's guarantees.
        let moved = unsafe { System.realloc(block, layout, new_size) };
        advise(moved, new_size);
        moved
    }
}

/// Ask for huge pages over the whole pages inside `[block, block + len)`.
fn advise(block: *mut u8, len: usize) {
    if block.is_null() || len < ADVISE_FROM {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        const PAGE: usize = 4096;
        let start = (block as usize).next_multiple_of(PAGE);
        let end = (block as usize + len) & !(PAGE - 1);
        if end > start {
            // SAFETY: the range lies inside a block this process owns; MADV_HUGEPAGE
            // changes no content and its failure (e.g. no THP support) is harmless.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
}
