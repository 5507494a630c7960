//! The constraint types — MSXPBD's nine and sinew's Bind (a skin held to
//! its skinned position) — stored as structure-of-arrays batches.
//!
//! Every constraint is solved with the XPBD update (SPEC §3.1, Macklin's sign):
//!
//! ```text
//! α̃  = α / Δt²                         α = compliance = 1/k
//! Δλ = (−C − α̃ λ) / (Σ_i w_i |∇_i C|² + α̃)
//! λ += Δλ ;  p_i += w_i ∇_i C Δλ        (Gauss–Seidel: applied at once)
//! ```
//!
//! | Type | Batch | C |
//! |---|---|---|
//! | Fiber, Internal, Branch | [`DistanceBatch`] | `|p_a − p_b| − σ̂(a)` |
//! | Attach, BranchAttach, Bind, Soft, Hard | [`PointBatch`] | `|p − q| − d0` |
//! | Sliding | [`SlidingBatch`] | `|p − c| − d0`, or `n·(p − c) − d0` inside |
//! | Area | [`AreaBatch`] | `A(p_a, p_b, p_c) − A0`, or `min(·, 0)` ([`AreaMode::NoShrink`]) |
//! | Volume | [`VolumeConstraint`] | `V(p) − k_p(a) V0` |
//!
//! A connection to another muscle (Sliding, Soft, Hard) is a two-body
//! constraint between a vertex and a point `c = Σ βₖ qₖ` of the other
//! muscle's surface. Each muscle solves only its own side, reading the other
//! through its snapshot, but with the pair's effective mass: the sum gains
//! the target point's generalised inverse mass `w_c = Σ βₖ² wₖ`, so two
//! muscles that target each other together move by the violation once, not
//! twice (see ARCHITECTURE.md, "Connections"). Bones have `w_c = 0`.
//!
//! # References
//! - Macklin, Müller, Chentanez, *XPBD*, 2016.
//! - Romeo, Monteagudo, Sánchez-Quirós, *Muscle Simulation with XPBD*, CEIG 2018.

mod area;
mod distance;
mod distance_lanes;
mod ids;
mod point;
mod runs;
mod sliding;
mod volume;
mod volume_lanes;
mod volume_terms;

pub use area::{AreaBatch, AreaMode};
pub use distance::{ActivationRest, ActivationScale, DistanceBatch, FiberMode};
pub use distance_lanes::{DistanceLanes, LANES};
pub use ids::{ParticleId, TargetId, TargetSlot};
pub use point::PointBatch;
pub use runs::{OPEN_RUNS, RUN};
pub(crate) use sliding::outside_at_rest;
pub use sliding::{SlidingBatch, SlidingContact, SlidingMode};
pub use volume::{VolumeConstraint, VolumeParams, VolumeProjection};
pub use volume_lanes::{VolumeLanes, volumes_share_topology};

use glam::Vec3;

/// Most particles one batched constraint moves: a triangle's three
/// ([`AreaBatch`]); a pair moves two, a vertex pulled toward a goal one.
pub const MAX_PARTICLES: usize = 3;

/// The particles one constraint moves, in slot order, padded to
/// [`MAX_PARTICLES`] by repeating the last (only the first
/// [`ConstraintBatch::particles_per_constraint`] are used).
pub type Particles = [ParticleId; MAX_PARTICLES];

/// The outcome of projecting one constraint, computed without writing: the
/// multiplier increment and the new positions of the (at most
/// [`MAX_PARTICLES`]) particles it moves, in the slot order of
/// [`ConstraintBatch::particles`].
/// Gauss–Seidel commits it at once; a colour sweep writes it where the
/// plan says the constraint's particles are; Jacobi gathers it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// Multiplier increment.
    pub dlambda: f32,
    /// New position per slot; the first `count` are used.
    pub to: [Vec3; MAX_PARTICLES],
    /// Number of particles moved (1 to [`MAX_PARTICLES`]).
    pub count: u8,
}

impl Correction {
    /// One particle moved.
    pub fn one(dlambda: f32, to: Vec3) -> Self {
        Self {
            dlambda,
            to: [to; MAX_PARTICLES],
            count: 1,
        }
    }

    /// Two particles moved.
    pub fn two(dlambda: f32, a: Vec3, b: Vec3) -> Self {
        Self {
            dlambda,
            to: [a, b, b],
            count: 2,
        }
    }

    /// Three particles moved.
    pub fn three(dlambda: f32, a: Vec3, b: Vec3, c: Vec3) -> Self {
        Self {
            dlambda,
            to: [a, b, c],
            count: 3,
        }
    }

    /// Writes the new positions of `particles` (slot order) into `p`.
    #[inline(always)]
    pub fn write(&self, particles: Particles, p: &mut [Vec3]) {
        for (&to, &k) in self.to[..self.count as usize].iter().zip(&particles) {
            p[k.index()] = to;
        }
    }
}

/// What a kernel is given of the particles one constraint moves, by value
/// and in the slot order of [`ConstraintBatch::particles`] (a single-particle
/// constraint reads slot 0, a pair slots 0 and 1; unused slots are zero):
/// their positions and inverse masses, nothing else. A kernel cannot read a
/// particle it does not move, which is what lets the colour sweeps
/// (`solver::sweep`) run constraints of one colour on several threads with
/// only their own particles in hand.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gathered {
    /// Positions.
    pub at: [Vec3; MAX_PARTICLES],
    /// Inverse masses. Units: 1/kg.
    pub w: [f32; MAX_PARTICLES],
}

impl Gathered {
    /// The first `count` of `particles`, of positions `p` and inverse
    /// masses `w` (`count` is a batch's
    /// [`ConstraintBatch::particles_per_constraint`], a constant once the
    /// kernel is inlined: no other slot is read).
    #[inline(always)]
    pub fn from_slices(particles: Particles, count: usize, p: &[Vec3], w: &[f32]) -> Self {
        Self::from_fn(particles, count, |k| (p[k], w[k]))
    }

    /// The first `count` of `particles`, each read by `read(index)` as
    /// `(position, inverse mass)`.
    #[inline(always)]
    pub fn from_fn(
        particles: Particles,
        count: usize,
        mut read: impl FnMut(usize) -> (Vec3, f32),
    ) -> Self {
        let mut g = Self {
            at: [Vec3::ZERO; MAX_PARTICLES],
            w: [0.0; MAX_PARTICLES],
        };
        for (slot, k) in particles.iter().enumerate().take(count) {
            (g.at[slot], g.w[slot]) = read(k.index());
        }
        g
    }
}

/// A batch of constraints of one type, projected one at a time
/// (Gauss–Seidel, [`ConstraintBatch::solve`]) or a colour group at a time.
pub trait ConstraintBatch {
    /// Number of constraints.
    fn count(&self) -> usize;

    /// The particles constraint `i` moves: `[a, b, c]` for a triangle,
    /// `[a, b, b]` for a pair, `[p, p, p]` for a single particle (targets
    /// are read-only).
    fn particles(&self, i: usize) -> Particles;

    /// Particles each constraint moves: 1 (a particle and a target), 2 (a
    /// pair) or 3 (a triangle). A constant of the type: kernels' loops
    /// read and write only that many slots.
    fn particles_per_constraint(&self) -> usize;

    /// The batch's particle-index arrays, one per slot (empty past
    /// [`ConstraintBatch::particles_per_constraint`]): what a colour plan
    /// compares to see whether it still fits.
    fn index_arrays(&self) -> [&[ParticleId]; MAX_PARTICLES];

    /// Whether constraint `i` is switched off (a connection of weight 0:
    /// non-finite compliance); every method skips it. Default: never.
    fn is_off(&self, _i: usize) -> bool {
        false
    }

    /// Whether `flags` holds [`ConstraintBatch::is_off`] of every
    /// constraint of the batch, in order, in one call: what a colour plan
    /// compares in the first iteration of each substep, serially in its
    /// muscle's task (a skin's 90 000 constraints had been one virtual
    /// call apiece). Default: no flag set.
    fn off_flags_are(&self, flags: &[bool]) -> bool {
        flags.len() == self.count() && !flags.contains(&true)
    }

    /// The indices of the constraints that are on (not
    /// [`ConstraintBatch::is_off`]), in order, into `list`, in one call:
    /// what each muscle lists in the first iteration of each substep.
    /// Default: asks [`ConstraintBatch::is_off`] of each constraint, so
    /// it agrees with it for any batch; a batch overrides it to list
    /// faster.
    fn list_on(&self, list: &mut Vec<u32>) {
        list.clear();
        list.extend(
            (0..self.count())
                .filter(|&i| !self.is_off(i))
                .map(|i| i as u32),
        );
    }

    /// The multipliers' storage, to move out for a parallel sweep and back.
    fn lambda_storage(&mut self) -> &mut Vec<f32>;

    /// The constraints in the order they were created, as their indices in
    /// the batch, where the batch keeps them in another (a
    /// [`DistanceBatch`] in Gauss–Seidel runs); empty where the batch's
    /// order is the creation order. Default: empty.
    fn creation_order(&self) -> &[u32] {
        &[]
    }

    /// Projection of constraint `i` with accumulated multiplier `lambda`,
    /// given its particles ([`Gathered`]), not yet written (`None`: nothing
    /// to do). The kernel every method shares.
    fn correction_of(
        &self,
        i: usize,
        lambda: f32,
        at: Gathered,
        inv_dt2: f32,
    ) -> Option<Correction>;

    /// Projection of constraint `i` at positions `p` with its own
    /// multiplier, not yet written (`None`: nothing to do).
    #[inline(always)]
    fn correction(&self, i: usize, p: &[Vec3], w: &[f32], inv_dt2: f32) -> Option<Correction> {
        let at = Gathered::from_slices(self.particles(i), self.particles_per_constraint(), p, w);
        self.correction_of(i, self.lambdas()[i], at, inv_dt2)
    }

    /// The accumulated multipliers.
    fn lambdas(&self) -> &[f32];

    /// The accumulated multipliers, to write.
    fn lambdas_mut(&mut self) -> &mut [f32];

    /// Writes a correction of constraint `i`.
    #[inline(always)]
    fn commit(&mut self, i: usize, c: &Correction, p: &mut [Vec3]) {
        self.lambdas_mut()[i] += c.dlambda;
        c.write(self.particles(i), p);
    }

    /// One Gauss–Seidel pass over the batch (the kernel inlined into the
    /// loop: this is the Sequential method's whole projection).
    fn solve(&mut self, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        for i in 0..self.count() {
            self.solve_at(i, p, w, inv_dt2);
        }
    }

    /// [`ConstraintBatch::solve`] over the constraints listed in `on`
    /// (ascending) only: the same pass where every other constraint is off
    /// ([`ConstraintBatch::is_off`]), without visiting those.
    fn solve_listed(&mut self, on: &[u32], p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        for &i in on {
            self.solve_at(i as usize, p, w, inv_dt2);
        }
    }

    /// Projects constraint `i` and writes it: one step of
    /// [`ConstraintBatch::solve`].
    #[inline(always)]
    fn solve_at(&mut self, i: usize, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        let particles = self.particles(i);
        let at = Gathered::from_slices(particles, self.particles_per_constraint(), p, w);
        if let Some(c) = self.correction_of(i, self.lambdas()[i], at, inv_dt2) {
            self.lambdas_mut()[i] += c.dlambda;
            c.write(particles, p);
        }
    }
}

/// Code run on one batch with its concrete type (a closure generic over the
/// batch type): what [`crate::muscle::MuscleConstraints::with_batch`] calls,
/// so that a loop over a batch's constraints is compiled once per type with
/// the kernel inlined.
pub trait BatchFn {
    /// What the call returns.
    type Output;
    /// Runs on `batch`.
    fn call<B: ConstraintBatch>(self, batch: &B) -> Self::Output;
}

/// [`BatchFn`] for a batch to write
/// ([`crate::muscle::MuscleConstraints::with_batch_mut`]).
pub trait BatchFnMut {
    /// What the call returns.
    type Output;
    /// Runs on `batch`.
    fn call<B: ConstraintBatch>(self, batch: &mut B) -> Self::Output;
}

/// The XPBD multiplier increment (SPEC §3.1). Returns 0 for a singular system.
#[inline(always)]
pub fn delta_lambda(c: f32, lambda: f32, weighted_gradient_sq: f32, alpha_tilde: f32) -> f32 {
    let denom = weighted_gradient_sq + alpha_tilde;
    if denom > 0.0 {
        (-c - alpha_tilde * lambda) / denom
    } else {
        0.0
    }
}

/// The indices of the finite entries of `compliance`, in order, into
/// `list`: [`ConstraintBatch::list_on`] of a batch that is off exactly
/// where its compliance is not finite. Blocks of 64 with none finite are
/// passed over in one vector test each: T7's Soft and Hard (a third of its
/// constraints, weight 0 throughout) had been one compare and branch a
/// constraint in each frame's first iteration.
pub(crate) fn list_finite(compliance: &[f32], list: &mut Vec<u32>) {
    const BLOCK: usize = 64;
    list.clear();
    for (b, block) in compliance.chunks(BLOCK).enumerate() {
        if !block.iter().fold(false, |any, c| any | c.is_finite()) {
            continue;
        }
        let on = block.iter().enumerate().filter(|(_, c)| c.is_finite());
        list.extend(on.map(|(i, _)| (b * BLOCK + i) as u32));
    }
}

#[cfg(test)]
mod list_tests {
    use super::list_finite;

    /// The finite entries' indices, block boundaries, NaN and both
    /// infinities included; seen to fail with a block's last entry left out.
    #[test]
    fn list_finite_lists_exactly_the_finite_entries() {
        for len in [0, 1, 63, 64, 65, 130, 257] {
            let compliance: Vec<f32> = (0..len)
                .map(|i| match i % 7 {
                    0 | 3 => 1e-6 * i as f32,
                    1 => f32::NAN,
                    2 if i % 64 == 63 => 0.0,
                    5 => f32::NEG_INFINITY,
                    _ => f32::INFINITY,
                })
                .collect();
            // Whole blocks off, and one entry on at a block's end.
            let mut sparse = vec![f32::INFINITY; len];
            if len > 64 {
                sparse[63] = 0.5;
            }
            for compliance in [compliance, sparse] {
                let expected: Vec<u32> = (0..len as u32)
                    .filter(|&i| compliance[i as usize].is_finite())
                    .collect();
                let mut list = vec![7, 7];
                list_finite(&compliance, &mut list);
                assert_eq!(list, expected, "length {len}");
            }
        }
    }
}
