//! One constraint of a muscle by type and index, and what every method
//! asks of it through the constraint table
//! ([`crate::muscle::MuscleConstraints`]): the particles it moves, whether
//! it is switched off, its projection and the commit of that projection.

use crate::constraints::{
    BatchFn, BatchFnMut, ConstraintBatch, Correction, MAX_PARTICLES, ParticleId, Particles,
};
use crate::muscle::ConstraintKind;
use crate::muscle::{Muscle, MuscleConstraints};
use glam::Vec3;

/// One constraint of a muscle: its type and index in that type's batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ConstraintRef {
    /// Constraint type.
    pub kind: ConstraintKind,
    /// Index in the batch of `kind`.
    pub index: u32,
}

/// The particles constraint `c` of `m` moves, in slot order, `None` past
/// its batch's [`ConstraintBatch::particles_per_constraint`] (targets are
/// read-only).
pub fn particles_of(m: &Muscle, c: ConstraintRef) -> [Option<ParticleId>; MAX_PARTICLES] {
    let Some(batch) = m.constraints.batch(c.kind) else {
        return [None; MAX_PARTICLES];
    };
    let (moved, count) = (
        batch.particles(c.index as usize),
        batch.particles_per_constraint(),
    );
    std::array::from_fn(|slot| (slot < count).then_some(moved[slot]))
}

/// Every particle-index array of `m`'s batches (Volume, which moves every
/// particle, apart), in table order.
pub(super) fn index_arrays(m: &Muscle) -> impl Iterator<Item = &[ParticleId]> {
    let k = &m.constraints;
    MuscleConstraints::BATCHED
        .iter()
        .filter_map(|&kind| k.batch(kind))
        .flat_map(|b| b.index_arrays())
}

/// Whether each constraint of `m`'s batches is switched off (weight 0),
/// in table order.
pub(super) fn off_flags(m: &Muscle) -> impl Iterator<Item = bool> + '_ {
    let k = &m.constraints;
    MuscleConstraints::BATCHED
        .iter()
        .filter_map(|&kind| k.batch(kind))
        .flat_map(|b| (0..b.count()).map(move |i| b.is_off(i)))
}

/// Whether `flags` is [`off_flags`] of `m` (batch by batch, each batch
/// compared in one call: [`ConstraintBatch::off_flags_are`]).
pub(super) fn off_flags_match(m: &Muscle, flags: &[bool]) -> bool {
    let k = &m.constraints;
    let mut rest = flags;
    MuscleConstraints::BATCHED
        .iter()
        .filter_map(|&kind| k.batch(kind))
        .all(|b| {
            let Some((these, after)) = rest.split_at_checked(b.count()) else {
                return false;
            };
            rest = after;
            b.off_flags_are(these)
        })
        && rest.is_empty()
}

/// Whether constraint `c` of `m` is switched off (a connection of weight 0).
pub(super) fn is_off(m: &Muscle, c: ConstraintRef) -> bool {
    m.constraints
        .batch(c.kind)
        .is_some_and(|b| b.is_off(c.index as usize))
}

/// Every constraint of `m` except Volume, type by type in `order`, each
/// type's in creation order ([`ConstraintBatch::creation_order`]: a
/// distance batch's Gauss–Seidel runs change no colouring).
pub fn constraints_in_order(m: &Muscle, order: &[ConstraintKind]) -> Vec<ConstraintRef> {
    let mut out = Vec::new();
    for &kind in order {
        let Some(batch) = m.constraints.batch(kind) else {
            continue;
        };
        let reference = |index| ConstraintRef { kind, index };
        match batch.creation_order() {
            [] => out.extend((0..batch.count() as u32).map(reference)),
            created => out.extend(created.iter().copied().map(reference)),
        }
    }
    out
}

/// The particles constraint `c` of `m` moves, as its batch gives them
/// (padded by repeating the last: `[p, p, p]` for one particle).
///
/// # Panics
/// For Volume, which is solved apart.
pub(super) fn batch_particles(m: &Muscle, c: ConstraintRef) -> Particles {
    m.constraints
        .batch(c.kind)
        .expect("Volume is solved apart")
        .particles(c.index as usize)
}

/// A projection at the current predictions, for [`correction`].
struct Project<'a> {
    i: usize,
    p: &'a [Vec3],
    w: &'a [f32],
    inv_h2: f32,
}

impl BatchFn for Project<'_> {
    type Output = Option<Correction>;

    #[inline(always)]
    fn call<B: ConstraintBatch>(self, batch: &B) -> Self::Output {
        batch.correction(self.i, self.p, self.w, self.inv_h2)
    }
}

/// Projection of constraint `c` of `m` at the current predictions, not yet
/// written (Volume has none: it is solved apart).
#[inline]
pub fn correction(m: &Muscle, c: ConstraintRef, inv_h2: f32) -> Option<Correction> {
    correction_with_weights(m, c, &m.w, inv_h2)
}

/// [`correction`] with the particles' inverse masses `w` in place of the
/// muscle's own (Jacobi's split masses).
#[inline]
pub fn correction_with_weights(
    m: &Muscle,
    c: ConstraintRef,
    w: &[f32],
    inv_h2: f32,
) -> Option<Correction> {
    let project = Project {
        i: c.index as usize,
        p: &m.p,
        w,
        inv_h2,
    };
    m.constraints.with_batch(c.kind, project).flatten()
}

/// A correction to write, for [`commit`].
struct Commit<'a> {
    i: usize,
    correction: &'a Correction,
    p: &'a mut [Vec3],
}

impl BatchFnMut for Commit<'_> {
    type Output = ();

    #[inline(always)]
    fn call<B: ConstraintBatch>(self, batch: &mut B) {
        batch.commit(self.i, self.correction, self.p);
    }
}

/// Writes a correction of constraint `c` of `m`.
#[inline]
pub fn commit(m: &mut Muscle, c: ConstraintRef, correction: &Correction) {
    let write = Commit {
        i: c.index as usize,
        correction,
        p: &mut m.p,
    };
    m.constraints.with_batch_mut(c.kind, write);
}
