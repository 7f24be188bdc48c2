//! Large arrays: on huge pages, and written past the caches.
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
//!
//! An array written once and not read again soon (a large batch trace's results) is written
//! with [`store_streaming`]: an ordinary store first reads the line it writes into the cache
//! (a read the writer does not need), and the line later goes back to memory; a streaming
//! store sends whole lines to memory without reading them.

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

/// `*destination = *source`, written with streaming (non-temporal) stores where the machine
/// has them and both arrays start on 16 bytes (x86-64: SSE2, which every x86-64 processor has),
/// with ordinary stores otherwise. The stores bypass the caches: for arrays the program will
/// not read again before they would have left the caches anyway. Call [`fence_streaming_stores`]
/// before another thread reads what was written.
#[inline(always)]
pub(crate) fn store_streaming<T: Copy, const N: usize>(destination: &mut [T; N], source: &[T; N]) {
    #[cfg(target_arch = "x86_64")]
    {
        const STORE_BYTES: usize = 16;
        let bytes = std::mem::size_of::<[T; N]>();
        let to = destination.as_mut_ptr().cast::<u8>();
        let from = source.as_ptr().cast::<u8>();
        if bytes.is_multiple_of(STORE_BYTES)
            && (to as usize).is_multiple_of(STORE_BYTES)
            && (from as usize).is_multiple_of(STORE_BYTES)
        {
            for offset in (0..bytes).step_by(STORE_BYTES) {
                // SAFETY: both pointers are 16-byte aligned and `offset + 16 <= bytes`, so each
                // access stays inside its array; the arrays do not overlap (one is borrowed
                // mutably). The copy goes through assembly, byte for byte, rather than an
                // intrinsic's integer vector because `T` may have padding, which Rust code may
                // not read as integers; the destination ends up holding the source's bytes,
                // hence valid `T`s.
                unsafe {
                    std::arch::asm!(
                        "movdqa {piece}, xmmword ptr [{from}]",
                        "movntdq xmmword ptr [{to}], {piece}",
                        from = in(reg) from.add(offset),
                        to = in(reg) to.add(offset),
                        piece = out(xmm_reg) _,
                        options(nostack, preserves_flags),
                    );
                }
            }
            return;
        }
    }
    *destination = *source;
}

/// Makes the streaming stores this thread has issued visible to other threads before any store
/// it makes after (x86-64: `sfence`; streaming stores are not ordered with other stores
/// otherwise).
#[inline]
pub(crate) fn fence_streaming_stores() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `sfence` only orders stores; SSE, which has it, is part of x86-64.
    unsafe {
        std::arch::x86_64::_mm_sfence();
    }
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

    #[test]
    fn streaming_stores_copy_every_byte_aligned_or_not() {
        #[repr(C, align(16))]
        struct Aligned([f64; 34]);
        let source = Aligned(std::array::from_fn(|i| i as f64 * 1.5 - 7.0));
        let mut destination = Aligned([0.0; 34]);
        // Aligned: the streaming path. Off by 8 bytes: the ordinary one.
        for start in [0, 1] {
            destination.0 = [0.0; 34];
            let from: &[f64; 32] = source.0[start..start + 32].try_into().unwrap();
            let to: &mut [f64; 32] = (&mut destination.0[start..start + 32]).try_into().unwrap();
            store_streaming(to, from);
            fence_streaming_stores();
            assert_eq!(
                destination.0[start..start + 32],
                source.0[start..start + 32]
            );
            assert!(destination.0[..start].iter().all(|&v| v == 0.0));
            assert!(destination.0[start + 32..].iter().all(|&v| v == 0.0));
        }
        // An enum with padding (the outcomes a batch trace streams).
        let outcomes: [crate::trace::Outcome; 8] = std::array::from_fn(|i| match i % 4 {
            0 => crate::trace::Outcome::Ok,
            1 => crate::trace::Outcome::Vignetted { surface: i },
            2 => crate::trace::Outcome::Tir { surface: i + 100 },
            _ => crate::trace::Outcome::Missed {
                surface: usize::MAX - i,
            },
        });
        #[repr(C, align(16))]
        struct AlignedOutcomes([crate::trace::Outcome; 8]);
        let source = AlignedOutcomes(outcomes);
        let mut destination = AlignedOutcomes([crate::trace::Outcome::Ok; 8]);
        store_streaming(&mut destination.0, &source.0);
        fence_streaming_stores();
        assert_eq!(destination.0, outcomes);
    }
}
