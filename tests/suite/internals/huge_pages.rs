//! Unit tests of `huge_pages` (src/huge_pages.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::huge_pages::HugePages;
use std::alloc::{GlobalAlloc, Layout};

#[cfg(target_os = "linux")]
/// The VmFlags of the mapping holding `address`, from /proc/self/smaps.
fn flags_of(address: usize) -> Option<String> {
    let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
    let mut inside = false;
    for line in smaps.lines() {
        let range = line.split_whitespace().next().unwrap_or("");
        if let Some((lo, hi)) = range.split_once('-')
            && let (Ok(lo), Ok(hi)) = (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
        {
            inside = (lo..hi).contains(&address);
        } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
            return Some(flags.to_string());
        }
    }
    None
}

#[cfg(target_os = "linux")]
#[test]
fn large_blocks_are_advised_for_huge_pages() {
    let thp =
        std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled").unwrap_or_default();
    if !thp.contains("[madvise]") && !thp.contains("[always]") {
        eprintln!("transparent huge pages are off here ({thp:?}): nothing to check");
        return;
    }
    let large = Layout::from_size_align(16 << 20, 4096).unwrap();
    // SAFETY: a non-zero size; the block is freed with its own layout.
    unsafe {
        let block = HugePages.alloc(large);
        assert!(!block.is_null());
        block.write_bytes(7, large.size());
        let flags = flags_of(block as usize + (8 << 20)).expect("the block is mapped");
        assert!(flags.contains(" hg"), "a 16 MiB block not advised: {flags}");
        assert_eq!(*block.add(large.size() - 1), 7);
        HugePages.dealloc(block, large);
    }
}
