//! Four values side by side in one SSE register (glam's `Vec4`), for
//! kernels that run four muscles of one topology at once
//! ([`crate::constraints::DistanceLanes`]): glam gives the lane-wise
//! arithmetic, this module the lanes built from four muscles' values
//! (`of`, and `of3` / `transpose_in` for vectors, `transpose_out` back)
//! and the square root, which glam takes
//! lane by lane.
//! With `prefetch` and `solver::sweep` the crate's only `unsafe`.
#![expect(
    unsafe_code,
    reason = "SSE's packed square root is an intrinsic; SSE2 is part of every x86_64 processor"
)]

use glam::{Mat4, Vec3, Vec4};

/// Lane `k` of `f(k)` for each of the four lanes.
#[inline(always)]
pub(crate) fn of(f: impl Fn(usize) -> f32) -> Vec4 {
    Vec4::new(f(0), f(1), f(2), f(3))
}

/// The coordinates of `f(k)` in lane `k` for each of the four lanes: four
/// vectors turned into an x, a y and a z of four lanes each.
#[inline(always)]
pub(crate) fn of3(f: impl Fn(usize) -> Vec3) -> (Vec4, Vec4, Vec4) {
    transpose_in([f(0), f(1), f(2), f(3)])
}

/// Four vectors as an x, a y and a z of four lanes each (vector `k` in
/// lane `k`): the vectors as the columns of a 4 × 4 matrix, transposed in
/// registers (shuffles, not one float at a time).
#[inline(always)]
pub(crate) fn transpose_in(v: [Vec3; 4]) -> (Vec4, Vec4, Vec4) {
    let [a, b, c, d] = v.map(|v| v.extend(0.0));
    let rows = Mat4::from_cols(a, b, c, d).transpose();
    (rows.x_axis, rows.y_axis, rows.z_axis)
}

/// The four vectors whose coordinates lanes `x`, `y` and `z` hold (lane
/// `k` vector `k`): [`transpose_in`] undone.
#[inline(always)]
pub(crate) fn transpose_out(x: Vec4, y: Vec4, z: Vec4) -> [Vec3; 4] {
    let columns = Mat4::from_cols(x, y, z, Vec4::ZERO).transpose();
    [
        columns.x_axis,
        columns.y_axis,
        columns.z_axis,
        columns.w_axis,
    ]
    .map(Vec4::truncate)
}

/// The square root of each lane, rounded as `f32::sqrt` rounds it (IEEE
/// square roots are exact to the half ulp in both forms).
#[inline(always)]
pub(crate) fn sqrt(v: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_sqrt_ps};
        // SAFETY: SSE is enabled on every x86_64 target; the intrinsic
        // reads only its argument.
        Vec4::from(unsafe { _mm_sqrt_ps(__m128::from(v)) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    v.sqrt()
}

#[cfg(test)]
mod tests {
    /// The packed root is each lane's `f32::sqrt`, to the bit (zero, a
    /// negative lane's NaN, infinity, a subnormal).
    #[test]
    fn packed_roots_are_the_scalar_roots() {
        let v = glam::Vec4::new(2.0, 0.0, -1.0, f32::INFINITY);
        let roots = super::sqrt(v).to_array();
        for (lane, (&r, x)) in roots.iter().zip(v.to_array()).enumerate() {
            let want = x.sqrt();
            assert!(
                r.to_bits() == want.to_bits() || r.is_nan() && want.is_nan(),
                "lane {lane}"
            );
        }
        let tiny = glam::Vec4::splat(1e-40);
        assert_eq!(super::sqrt(tiny).x.to_bits(), 1e-40f32.sqrt().to_bits());
    }
}
