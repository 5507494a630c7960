//! Momentum restoration for free muscles.
//!
//! Every MSXPBD constraint is internal to its muscle and invariant under rigid
//! motion, so in continuous time it exerts no net force or torque. XPBD's
//! position-level projection keeps that only to first order in `h`: the
//! velocity `v = (p − x)/h` taken after Gauss–Seidel sweeps carries a small
//! spurious spin whose sign follows the sweep order. A muscle held by
//! attachments or targets never notices, because those external connections
//! own its rigid modes. A *free* muscle (T1) has nothing to stop it: over one
//! activation cycle the oval spun ≈ 10° about its fibre axis and never came
//! back. For muscles with no attachments and no targets the solver therefore
//! records linear and angular momentum after integration and, after applying
//! the predictions, removes the difference with a rigid velocity field
//! `δv = δV + δω × r` (also applied to the new positions as `h δv`). A rigid
//! correction leaves every constraint value unchanged to first order.

use crate::muscle::Muscle;
use glam::{Mat3, Vec3};

/// Linear and angular momentum of a free muscle about its centre of mass,
/// recorded at the start of a substep (see [`super::pipeline::begin_substep`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidMomentum {
    linear: Vec3,
    angular: Vec3,
}

/// Whether the solver conserves `m`'s momentum explicitly: no attachments,
/// no skin binding (both tie it to the bones), no targets, and every
/// particle dynamic.
pub(crate) fn is_free(m: &Muscle) -> bool {
    m.attachments.is_empty()
        && m.binding.is_empty()
        && m.targets.is_empty()
        && m.w.iter().all(|&w| w > 0.0)
}

fn centre_of_mass(m: &Muscle) -> (f32, Vec3) {
    let mut mass = 0.0;
    let mut moment = Vec3::ZERO;
    for (x, &w) in m.x.iter().zip(&m.w) {
        let mi = 1.0 / w;
        mass += mi;
        moment += mi * *x;
    }
    (mass, moment / mass)
}

impl RigidMomentum {
    /// `(linear, angular)`.
    #[cfg(test)]
    pub(crate) fn parts(self) -> (Vec3, Vec3) {
        (self.linear, self.angular)
    }
}

/// Momentum of `m` from its current positions `x` and velocities `v`.
pub(crate) fn measure(m: &Muscle) -> RigidMomentum {
    measure_about(m, centre_of_mass(m).1)
}

/// Momentum of `m`, the angular part about `c` (its centre of mass).
fn measure_about(m: &Muscle, c: Vec3) -> RigidMomentum {
    let mut linear = Vec3::ZERO;
    let mut angular = Vec3::ZERO;
    for ((x, v), &w) in m.x.iter().zip(&m.v).zip(&m.w) {
        let mi = 1.0 / w;
        linear += mi * *v;
        angular += mi * (*x - c).cross(*v);
    }
    RigidMomentum { linear, angular }
}

/// Adds the rigid velocity field that brings `m`'s momentum back to
/// `reference`, and moves the positions by `h` times the same field. Moving
/// the positions changes the lever arms, so a second pass removes the
/// (second-order) remainder; without it the spin creeps up by ≈ 1e-3 of the
/// motion's scale over a T1 cycle.
pub(crate) fn restore(m: &mut Muscle, reference: RigidMomentum, h: f32) {
    for _ in 0..2 {
        restore_once(m, reference, h);
    }
}

fn restore_once(m: &mut Muscle, reference: RigidMomentum, h: f32) {
    let (mass, c) = centre_of_mass(m);
    let now = measure_about(m, c);
    let mut inertia = Mat3::ZERO;
    for (x, &w) in m.x.iter().zip(&m.w) {
        let r = *x - c;
        inertia += (1.0 / w) * (Mat3::from_diagonal(Vec3::splat(r.length_squared())) - outer(r, r));
    }
    let dv = (reference.linear - now.linear) / mass;
    // A uniform δv adds no angular momentum about the centre of mass.
    // Skip the angular part for a (near) collinear particle set.
    let trace = inertia.x_axis.x + inertia.y_axis.y + inertia.z_axis.z;
    let dw = if inertia.determinant() > 1e-9 * trace * trace * trace {
        inertia.inverse() * (reference.angular - now.angular)
    } else {
        Vec3::ZERO
    };
    if !(dv.is_finite() && dw.is_finite()) {
        return;
    }
    for (x, v) in m.x.iter_mut().zip(m.v.iter_mut()) {
        let dvi = dv + dw.cross(*x - c);
        *v += dvi;
        *x += h * dvi;
    }
}

fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}
