//! The constraint table: a muscle's batches, one line per batched type.
//!
//! [`MuscleConstraints`] and the ways to reach a batch by its
//! [`ConstraintKind`] — as a `dyn` [`ConstraintBatch`] for code that runs
//! once per batch ([`MuscleConstraints::batch`],
//! [`MuscleConstraints::for_each_batch`]), or statically typed for the
//! kernels' loops ([`MuscleConstraints::with_batch`]) — are generated from
//! the single list at the bottom of this file. Every method (sequential,
//! colours, Jacobi) reaches the batches only through them, so a new type
//! is solved by all of them once it has its line here (see
//! ARCHITECTURE.md, "How to add a constraint").

use super::SurfaceAnchor;
use crate::constraints::{
    BATCHED_KINDS, BatchFn, BatchFnMut, ConstraintBatch, ConstraintCounts, ConstraintKind,
    DistanceBatch, MuscleLambdas, PointBatch, SlidingBatch, VolumeConstraint,
};

/// Generates [`MuscleConstraints`] and its dispatch from the table.
macro_rules! constraint_table {
    ($($(#[$doc:meta])* $kind:ident => $field:ident: $batch:ty,)*) => {
        /// The constraint batches of a muscle, one per type, and its
        /// Volume constraint (solved apart: it moves every particle).
        #[derive(Clone, Debug, Default)]
        pub struct MuscleConstraints {
            $($(#[$doc])* pub $field: $batch,)*
            /// Volume (absent for open meshes allowed by the scene, and for
            /// surface layers).
            pub volume: Option<VolumeConstraint>,
            /// Rest anchors of `hard`.
            pub hard_anchor: Vec<SurfaceAnchor>,
            /// Rest anchors of `soft`.
            pub soft_anchor: Vec<SurfaceAnchor>,
        }

        impl MuscleConstraints {
            /// The batched types (every type but Volume), in table order.
            pub const BATCHED: &[ConstraintKind] = &[$(ConstraintKind::$kind),*];

            /// The batch of `kind` (`None` for Volume).
            pub fn batch(&self, kind: ConstraintKind) -> Option<&dyn ConstraintBatch> {
                match kind {
                    $(ConstraintKind::$kind => Some(&self.$field),)*
                    ConstraintKind::Volume => None,
                }
            }

            /// The batch of `kind`, to write (`None` for Volume).
            pub fn batch_mut(&mut self, kind: ConstraintKind) -> Option<&mut dyn ConstraintBatch> {
                match kind {
                    $(ConstraintKind::$kind => Some(&mut self.$field),)*
                    ConstraintKind::Volume => None,
                }
            }

            /// Runs `f` on the batch of `kind` with its concrete type, so
            /// that the kernel inlines into `f`'s loop (`None` for Volume).
            #[inline(always)]
            pub fn with_batch<F: BatchFn>(&self, kind: ConstraintKind, f: F) -> Option<F::Output> {
                match kind {
                    $(ConstraintKind::$kind => Some(f.call(&self.$field)),)*
                    ConstraintKind::Volume => None,
                }
            }

            /// [`MuscleConstraints::with_batch`], to write.
            #[inline(always)]
            pub fn with_batch_mut<F: BatchFnMut>(
                &mut self,
                kind: ConstraintKind,
                f: F,
            ) -> Option<F::Output> {
                match kind {
                    $(ConstraintKind::$kind => Some(f.call(&mut self.$field)),)*
                    ConstraintKind::Volume => None,
                }
            }

            /// Calls `f` on every batch, in table order.
            pub fn for_each_batch(&self, mut f: impl FnMut(ConstraintKind, &dyn ConstraintBatch)) {
                $(f(ConstraintKind::$kind, &self.$field);)*
            }

            /// Calls `f` on every batch, in table order, to write.
            pub fn for_each_batch_mut(
                &mut self,
                mut f: impl FnMut(ConstraintKind, &mut dyn ConstraintBatch),
            ) {
                $(f(ConstraintKind::$kind, &mut self.$field);)*
            }
        }
    };
}

impl MuscleConstraints {
    /// Counts per type.
    pub fn counts(&self) -> ConstraintCounts {
        let mut c = ConstraintCounts::default();
        self.for_each_batch(|kind, b| c.0[kind as usize] = b.count());
        c.0[ConstraintKind::Volume as usize] = usize::from(self.volume.is_some());
        c
    }

    /// Moves the multipliers of the batched types out (for a parallel
    /// sweep), indexed by [`ConstraintKind`]; the batches keep empty ones
    /// until [`MuscleConstraints::restore_lambdas`].
    pub(crate) fn take_lambdas(&mut self) -> MuscleLambdas {
        let mut out = MuscleLambdas::default();
        self.for_each_batch_mut(|kind, b| {
            out[kind as usize] = std::mem::take(b.lambda_storage());
        });
        out
    }

    /// Puts back what [`MuscleConstraints::take_lambdas`] took.
    pub(crate) fn restore_lambdas(&mut self, mut lambdas: MuscleLambdas) {
        self.for_each_batch_mut(|kind, b| {
            *b.lambda_storage() = std::mem::take(&mut lambdas[kind as usize]);
        });
    }

    /// Resets every λ to 0 (start of each frame or substep).
    pub fn clear_lambdas(&mut self) {
        self.for_each_batch_mut(|_, b| b.lambdas_mut().fill(0.0));
        if let Some(v) = &mut self.volume {
            v.lambda = 0.0;
        }
    }
}

// The table: one line per batched type — its kind, its field and its
// batch type. Volume, one constraint over the whole surface, is apart.
constraint_table! {
    /// Attach: surface vertex ↔ attachment point.
    Attach => attach: PointBatch,
    /// BranchAttach: internal point ↔ attachment point.
    BranchAttach => branch_attach: PointBatch,
    /// Hard: vertex ↔ its rest transform on a target triangle.
    Hard => hard: PointBatch,
    /// Soft: vertex ↔ its rest point on a target triangle.
    Soft => soft: PointBatch,
    /// Sliding: vertex ↔ closest point on the closest target.
    Sliding => sliding: SlidingBatch,
    /// Branch: internal point ↔ internal point.
    Branch => branch: DistanceBatch,
    /// Internal: surface vertex ↔ its internal point.
    Internal => internal: DistanceBatch,
    /// Fiber: one per polygon edge, activation-driven.
    Fiber => fiber: DistanceBatch,
}

// Every kind but Volume has a line, and Volume is the last kind (the
// multipliers taken out for a sweep are indexed by kind).
const _: () = assert!(
    MuscleConstraints::BATCHED.len() == BATCHED_KINDS
        && ConstraintKind::Volume as usize == BATCHED_KINDS
);
