//! One constraint of a muscle by type and index, and what every method
//! asks of it through its type's batch: the particles it moves, whether it
//! is switched off, its projection and the commit of that projection.

use crate::constraints::{ConstraintBatch, ConstraintKind, Correction};
use crate::muscle::Muscle;

/// One constraint of a muscle: its type and index in that type's batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ConstraintRef {
    /// Constraint type.
    pub kind: ConstraintKind,
    /// Index in the batch of `kind`.
    pub index: u32,
}

/// The particles constraint `c` of `m` moves (targets are read-only).
pub fn particles_of(m: &Muscle, c: ConstraintRef) -> [Option<u32>; 2] {
    match c.kind {
        ConstraintKind::Volume => [None, None],
        ConstraintKind::Branch | ConstraintKind::Internal | ConstraintKind::Fiber => {
            batch_particles(m, c).map(Some)
        }
        _ => [Some(batch_particles(m, c)[0]), None],
    }
}

/// Every particle-index array of `m`'s constraints (Volume, which moves
/// every particle, apart), batch by batch in a fixed order.
pub(super) fn particle_indices(m: &Muscle) -> [&[u32]; 11] {
    let k = &m.constraints;
    [
        &k.attach.particle,
        &k.branch_attach.particle,
        &k.hard.particle,
        &k.soft.particle,
        &k.sliding.particle,
        &k.branch.a,
        &k.branch.b,
        &k.internal.a,
        &k.internal.b,
        &k.fiber.a,
        &k.fiber.b,
    ]
}

/// The per-constraint compliances of `m`'s batches that have them, batch
/// by batch: a constraint with a non-finite one is switched off (weight 0)
/// and does nothing.
pub(super) fn compliances(m: &Muscle) -> [&[f32]; 5] {
    let k = &m.constraints;
    [
        &k.attach.compliance,
        &k.branch_attach.compliance,
        &k.hard.compliance,
        &k.soft.compliance,
        &k.sliding.compliance,
    ]
}

/// Whether constraint `c` of `m` is switched off (see [`compliances`]).
pub(super) fn is_off(m: &Muscle, c: ConstraintRef) -> bool {
    // The position of `c`'s batch in `compliances`.
    let batch = match c.kind {
        ConstraintKind::Attach => 0,
        ConstraintKind::BranchAttach => 1,
        ConstraintKind::Hard => 2,
        ConstraintKind::Soft => 3,
        ConstraintKind::Sliding => 4,
        _ => return false,
    };
    !compliances(m)[batch][c.index as usize].is_finite()
}

/// Every constraint of `m` except Volume, type by type in `order`.
pub fn constraints_in_order(m: &Muscle, order: &[ConstraintKind]) -> Vec<ConstraintRef> {
    let k = &m.constraints;
    let mut out = Vec::new();
    for &kind in order {
        let len = match kind {
            ConstraintKind::Attach => k.attach.particle.len(),
            ConstraintKind::BranchAttach => k.branch_attach.particle.len(),
            ConstraintKind::Hard => k.hard.particle.len(),
            ConstraintKind::Soft => k.soft.particle.len(),
            ConstraintKind::Sliding => k.sliding.particle.len(),
            ConstraintKind::Branch => k.branch.len(),
            ConstraintKind::Internal => k.internal.len(),
            ConstraintKind::Fiber => k.fiber.len(),
            ConstraintKind::Volume => 0,
        };
        out.extend((0..len as u32).map(|index| ConstraintRef { kind, index }));
    }
    out
}

/// The particles constraint `c` of `m` moves, as its batch gives them
/// (`[p, p]` for one particle; Volume has none).
pub(super) fn batch_particles(m: &Muscle, c: ConstraintRef) -> [u32; 2] {
    let k = &m.constraints;
    let i = c.index as usize;
    match c.kind {
        ConstraintKind::Attach => k.attach.particles(i),
        ConstraintKind::BranchAttach => k.branch_attach.particles(i),
        ConstraintKind::Hard => k.hard.particles(i),
        ConstraintKind::Soft => k.soft.particles(i),
        ConstraintKind::Sliding => k.sliding.particles(i),
        ConstraintKind::Branch => k.branch.particles(i),
        ConstraintKind::Internal => k.internal.particles(i),
        ConstraintKind::Fiber => k.fiber.particles(i),
        ConstraintKind::Volume => unreachable!("Volume is solved apart"),
    }
}

/// Projection of constraint `c` of `m` at the current predictions, not yet
/// written (Volume has none: it is solved apart).
pub fn correction(m: &Muscle, c: ConstraintRef, inv_h2: f32) -> Option<Correction> {
    let (k, p, w, i) = (&m.constraints, &m.p, &m.w, c.index as usize);
    match c.kind {
        ConstraintKind::Attach => k.attach.correction(i, p, w, inv_h2),
        ConstraintKind::BranchAttach => k.branch_attach.correction(i, p, w, inv_h2),
        ConstraintKind::Hard => k.hard.correction(i, p, w, inv_h2),
        ConstraintKind::Soft => k.soft.correction(i, p, w, inv_h2),
        ConstraintKind::Sliding => k.sliding.correction(i, p, w, inv_h2),
        ConstraintKind::Branch => k.branch.correction(i, p, w, inv_h2),
        ConstraintKind::Internal => k.internal.correction(i, p, w, inv_h2),
        ConstraintKind::Fiber => k.fiber.correction(i, p, w, inv_h2),
        ConstraintKind::Volume => None,
    }
}

/// Writes a correction of constraint `c` of `m`.
pub fn commit(m: &mut Muscle, c: ConstraintRef, correction: &Correction) {
    let (k, p, i) = (&mut m.constraints, &mut m.p, c.index as usize);
    match c.kind {
        ConstraintKind::Attach => k.attach.commit(i, correction, p),
        ConstraintKind::BranchAttach => k.branch_attach.commit(i, correction, p),
        ConstraintKind::Hard => k.hard.commit(i, correction, p),
        ConstraintKind::Soft => k.soft.commit(i, correction, p),
        ConstraintKind::Sliding => k.sliding.commit(i, correction, p),
        ConstraintKind::Branch => k.branch.commit(i, correction, p),
        ConstraintKind::Internal => k.internal.commit(i, correction, p),
        ConstraintKind::Fiber => k.fiber.commit(i, correction, p),
        ConstraintKind::Volume => {}
    }
}
