//! Large arrays on huge pages.
//!
//! Under a hypervisor a TLB miss walks two page tables, so code that reads or writes tens of
//! megabytes in a scattered order pays for every 4 KiB page it touches: a render reading a
//! 128^3 table's nodes all over a slab of it, a batch trace writing each ray's result where its
//! number says. Linux backs memory with 2 MiB pages where a program asks (`madvise`, when
//! transparent huge pages are set to `madvise`, as on Debian) and always where set to `always`.
//! Asking is only a hint: where the system has no huge pages to give, or refuses, nothing changes.
//!
//! Huge pages are not free where their first touch is slow: on this project's KVM machines a
//! fresh 2 MiB page costs several times what 512 small ones do (most likely because the host
//! takes free guest memory back and must back it again at the first touch). So a bake, which
//! writes its table once in order and never reads it scattered, keeps its table on plain pages
//! ([`Pages::Plain`]; on huge ones it took 0.14-0.17 s more system time at 128^3). A table read
//! from disk to render with, or copied, goes on huge pages.

/// Which pages a large array's new storage is asked for on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Pages {
    /// The system's default (4 KiB pages where transparent huge pages are set to `madvise`).
    Plain,
    /// 2 MiB pages where the system gives them: for arrays read in a scattered order.
    Huge,
}

/// `v.resize(n, value)`, any new storage on `pages` (asked for before it is first written: the
/// kernel picks the page size when a page is first touched).
pub(crate) fn resize_on<T: Clone>(pages: Pages, v: &mut Vec<T>, n: usize, value: T) {
    if pages == Pages::Huge && n > v.capacity() {
        v.reserve_exact(n - v.len());
        advise_huge_pages(v.spare_capacity_mut());
    }
    v.resize(n, value);
}

/// `source.to_vec()`, the copy's storage asked for on huge pages before it is written.
pub(crate) fn to_vec_on_huge_pages<T: Clone>(source: &[T]) -> Vec<T> {
    let mut copy = Vec::with_capacity(source.len());
    advise_huge_pages(copy.spare_capacity_mut());
    copy.extend_from_slice(source);
    copy
}

/// Asks Linux to back `storage` with 2 MiB pages where it covers whole ones.
fn advise_huge_pages<T>(storage: &mut [std::mem::MaybeUninit<T>]) {
    #[cfg(target_os = "linux")]
    {
        const HUGE_PAGE: usize = 2 << 20;
        let start = storage.as_mut_ptr() as usize;
        let end = start + std::mem::size_of_val(storage);
        let first = start.next_multiple_of(HUGE_PAGE);
        let last = end / HUGE_PAGE * HUGE_PAGE;
        if first < last {
            // SAFETY: the range lies inside `storage`, which this process owns and nothing
            // reads yet; the advice changes how its pages are backed, never their contents.
            // A refusal (a kernel without transparent huge pages) leaves the pages as they are.
            let _ = unsafe {
                rustix::mm::madvise(
                    first as *mut std::ffi::c_void,
                    last - first,
                    rustix::mm::Advice::LinuxHugepage,
                )
            };
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = storage;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_page_vectors_hold_what_plain_ones_do() {
        // Large enough to span whole 2 MiB pages, from a short vector and from an empty one.
        let n = 3 << 20;
        for start in [vec![1u64, 2, 3], Vec::new()] {
            let mut plain = start.clone();
            plain.resize(n, 7);
            let mut huge = start;
            resize_on(Pages::Huge, &mut huge, n, 7);
            assert_eq!(huge, plain);
            assert_eq!(to_vec_on_huge_pages(&huge), plain);
            resize_on(Pages::Huge, &mut huge, 2, 9);
            assert_eq!(huge, plain[..2]);
        }
    }
}
