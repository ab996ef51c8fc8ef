//! How the binary and the Python module set up mimalloc, their global allocator (the library
//! itself allocates through whatever allocator its user chose).

use libmimalloc_sys::mi_option_t;
use std::ffi::c_long;

/// mimalloc's purging, set for frame-sized buffers: every frame frees and allocates the same
/// 0.5-3 MB again. With its defaults (freed memory decommitted after 10 ms) the kernel faulted in
/// and cleared fresh pages, often 2 MB huge ones, frame after frame: 37,000 page faults for 300
/// Pandar40P frames on one thread, page clearing 8-15% of the profile on two. Kept a second, and
/// then reset (the kernel may take the pages when it needs them; untaken, they are reused as
/// they are) instead of decommitted: 230 faults (docs/performance.md).
const OPTIONS: [(mi_option_t, c_long); 2] = [
    // `mi_option_purge_delay` (15 in mimalloc's v2 and v3 headers; the bindings do not name it).
    (15, 1000),
    // `mi_option_purge_decommits` (5): 0 = purge by resetting.
    (5, 0),
];

/// Sets mimalloc's options for converting frames ([`OPTIONS`]). For a process whose global
/// allocator is mimalloc; harmless otherwise (mimalloc then serves nothing).
pub fn tune_mimalloc() {
    for (option, value) in OPTIONS {
        // SAFETY: sets a plain integer option; mimalloc reads its options lazily, at any time,
        // from any thread.
        unsafe { libmimalloc_sys::mi_option_set(option, value) };
    }
}
