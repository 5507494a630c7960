//! The nine MSXPBD constraint types, stored as structure-of-arrays batches.
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
//! | Attach, BranchAttach, Soft, Hard | [`PointBatch`] | `|p − q| − d0` |
//! | Sliding | [`SlidingBatch`] | `|p − c| − d0`, or `n·(p − c) − d0` inside |
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

mod distance;
mod point;
mod sliding;
mod volume;

pub use distance::{ActivationRest, ActivationScale, DistanceBatch, FiberMode};
pub use point::PointBatch;
pub use sliding::{SlidingBatch, SlidingMode};
pub use volume::{VolumeConstraint, VolumeParams};

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// The constraint types, in the canonical projection order (SPEC §4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ConstraintKind {
    /// Surface vertex ↔ attachment point.
    Attach,
    /// Internal point ↔ attachment point.
    BranchAttach,
    /// Vertex ↔ its rest transform on a target triangle.
    Hard,
    /// Vertex ↔ its rest point on a target triangle (a spring).
    Soft,
    /// Vertex ↔ closest point on the closest target (gap kept, free to slide).
    Sliding,
    /// Internal point ↔ internal point.
    Branch,
    /// Surface vertex ↔ its internal point.
    Internal,
    /// One per polygon edge; rest length shrinks along the fibres with activation.
    Fiber,
    /// One per muscle; enclosed volume with activation-driven gain.
    Volume,
}

impl ConstraintKind {
    /// All kinds in the canonical projection order.
    pub const CANONICAL_ORDER: [ConstraintKind; 9] = [
        Self::Attach,
        Self::BranchAttach,
        Self::Hard,
        Self::Soft,
        Self::Sliding,
        Self::Branch,
        Self::Internal,
        Self::Fiber,
        Self::Volume,
    ];

    /// The layout of the thesis' Tables 5.1–5.4.
    pub const TABLE_ORDER: [ConstraintKind; 9] = [
        Self::Fiber,
        Self::Attach,
        Self::BranchAttach,
        Self::Sliding,
        Self::Soft,
        Self::Hard,
        Self::Internal,
        Self::Branch,
        Self::Volume,
    ];

    /// Short name as printed in the thesis' tables.
    pub fn label(self) -> &'static str {
        match self {
            Self::Attach => "Attach",
            Self::BranchAttach => "BrAttach",
            Self::Hard => "Hard",
            Self::Soft => "Soft",
            Self::Sliding => "Sliding",
            Self::Branch => "Branch",
            Self::Internal => "Internal",
            Self::Fiber => "Fiber",
            Self::Volume => "Volume",
        }
    }
}

/// The multipliers of a muscle's eight batched constraint types, taken out
/// for a parallel sweep, indexed by [`ConstraintKind`] (Volume apart).
pub(crate) type MuscleLambdas = [Vec<f32>; 8];

/// Constraint counts per type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ConstraintCounts(pub [usize; 9]);

impl ConstraintCounts {
    /// Count of one type.
    pub fn get(&self, kind: ConstraintKind) -> usize {
        self.0[kind as usize]
    }

    /// Sum over all types.
    pub fn total(&self) -> usize {
        self.0.iter().sum()
    }
}

impl std::ops::AddAssign for ConstraintCounts {
    fn add_assign(&mut self, rhs: Self) {
        for (a, b) in self.0.iter_mut().zip(rhs.0) {
            *a += b;
        }
    }
}

/// The outcome of projecting one constraint, computed without writing: the
/// multiplier increment and the new positions of the (at most two) particles
/// it moves. Gauss–Seidel commits it at once; a colour group computes all its
/// corrections first (in parallel) and then commits them, which gives the
/// same bits because the group's constraints share no particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// Multiplier increment.
    pub dlambda: f32,
    /// `(particle, new position)`; the first `count` entries are used.
    pub moves: [(u32, Vec3); 2],
    /// Number of particles moved.
    pub count: u8,
}

impl Correction {
    /// One particle moved.
    pub fn one(dlambda: f32, particle: u32, to: Vec3) -> Self {
        Self {
            dlambda,
            moves: [(particle, to), (particle, to)],
            count: 1,
        }
    }

    /// Two particles moved.
    pub fn two(dlambda: f32, a: (u32, Vec3), b: (u32, Vec3)) -> Self {
        Self {
            dlambda,
            moves: [a, b],
            count: 2,
        }
    }

    /// Writes the new positions.
    pub fn write(&self, p: &mut [Vec3]) {
        for &(k, x) in &self.moves[..self.count as usize] {
            p[k as usize] = x;
        }
    }
}

/// Read access to particle positions: a slice, or the disjoint view a
/// parallel colour sweep hands each of its threads.
pub trait Particles {
    /// Position of particle `i`.
    fn at(&self, i: usize) -> Vec3;
}

impl Particles for [Vec3] {
    #[inline(always)]
    fn at(&self, i: usize) -> Vec3 {
        self[i]
    }
}

/// A batch of constraints of one type, projected one at a time
/// (Gauss–Seidel, [`ConstraintBatch::solve`]) or a colour group at a time
/// (compute every [`Correction`], then [`ConstraintBatch::commit`] them).
pub trait ConstraintBatch {
    /// Number of constraints.
    fn count(&self) -> usize;

    /// The particles constraint `i` moves: `[a, b]` for a pair, `[p, p]`
    /// for a single particle (targets are read-only).
    fn particles(&self, i: usize) -> [u32; 2];

    /// Projection of constraint `i` with accumulated multiplier `lambda` at
    /// positions `p`, moving `particles` (what [`ConstraintBatch::particles`]
    /// gives, or a colour plan's copy of it), not yet written (`None`:
    /// nothing to do). The kernel every method shares; a correction moves
    /// only `particles`.
    fn correction_with<P: Particles + ?Sized>(
        &self,
        i: usize,
        particles: [u32; 2],
        lambda: f32,
        p: &P,
        w: &[f32],
        inv_dt2: f32,
    ) -> Option<Correction>;

    /// [`ConstraintBatch::correction_with`] on the batch's own particles.
    #[inline(always)]
    fn correction_at<P: Particles + ?Sized>(
        &self,
        i: usize,
        lambda: f32,
        p: &P,
        w: &[f32],
        inv_dt2: f32,
    ) -> Option<Correction> {
        self.correction_with(i, self.particles(i), lambda, p, w, inv_dt2)
    }

    /// Projection of constraint `i` at `p` with its own multiplier, not yet
    /// written (`None`: nothing to do).
    #[inline]
    fn correction(&self, i: usize, p: &[Vec3], w: &[f32], inv_dt2: f32) -> Option<Correction> {
        self.correction_at(i, self.lambdas()[i], p, w, inv_dt2)
    }

    /// The accumulated multipliers.
    fn lambdas(&self) -> &[f32];

    /// The accumulated multipliers, to write.
    fn lambdas_mut(&mut self) -> &mut [f32];

    /// Writes a correction of constraint `i`.
    fn commit(&mut self, i: usize, c: &Correction, p: &mut [Vec3]) {
        self.lambdas_mut()[i] += c.dlambda;
        c.write(p);
    }

    /// One Gauss–Seidel pass over the batch.
    fn solve(&mut self, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        for i in 0..self.count() {
            if let Some(c) = self.correction(i, p, w, inv_dt2) {
                self.commit(i, &c, p);
            }
        }
    }
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
