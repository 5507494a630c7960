//! Software prefetch: a hint to the processor that a value will be read
//! soon, so that its cache line is on its way while other work runs.
//!
//! Closest data visits a muscle's vertices in a contact band, a sparse few
//! of its vertices, each through a chain of loads (its index, its
//! position, its contact record, its bone cells, the corners of the
//! triangle it was on) that misses the cache on every link: a muscle's
//! data is evicted by the others' between its iterations, and each link
//! waited for the one before. Asking for the next vertices' lines while
//! one is worked on overlaps those waits (`solver::sliding_closest`). This
//! module, `lanes` and `solver::sweep` are the crate's only `unsafe`.
#![expect(
    unsafe_code,
    reason = "the prefetch intrinsic takes a raw pointer; a prefetch reads nothing into the program and never faults"
)]

/// Asks for the cache line holding `value` (a hint: no effect on results).
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: the address is a live reference's; a prefetch does not
        // access memory architecturally and cannot fault.
        unsafe { _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast::<i8>()) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
