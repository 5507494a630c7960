//! The constraint table: every constraint type of a muscle, one line each.
//!
//! [`constraint_types!`](crate::constraint_types) holds the table. Each line
//! gives a type's [`ConstraintKind`] variant, its field in
//! [`MuscleConstraints`] and in [`Compliances`], its batch type, its label,
//! its default compliance, its column in the thesis' tables and where its
//! constraints are made. From it this file generates [`ConstraintKind`]
//! (with [`ConstraintKind::CANONICAL_ORDER`], [`ConstraintKind::TABLE_ORDER`]
//! and labels), [`Compliances`] (with defaults), [`MuscleConstraints`] and
//! its dispatch — as a `dyn` [`ConstraintBatch`] for code that runs once per
//! batch ([`MuscleConstraints::batch`], [`MuscleConstraints::for_each_batch`])
//! or statically typed for the kernels' loops
//! ([`MuscleConstraints::with_batch`]) — and [`Muscle::build`] calls each
//! line's builder. The Bevy plug-in generates its reflectable compliance
//! component from the same table. Every method (sequential, colours, Jacobi)
//! reaches the batches only through this dispatch, so a new type is solved
//! by all of them once it has its line (see ARCHITECTURE.md, "How to add a
//! constraint").

use super::{Muscle, SurfaceAnchor};
use crate::constraints::{BatchFn, BatchFnMut, ConstraintBatch};
use serde::{Deserialize, Serialize};

/// The constraint table. Calls `$callback!` with every constraint type:
/// the batched types (one constraint per vertex, edge or link, in a batch),
/// in the canonical projection order (SPEC §4.3), then the whole-body type
/// (Volume, one constraint over the whole surface, solved apart).
///
/// A line reads `Kind => field: Batch, "Label", compliance C, column N,
/// made (…);`: the [`ConstraintKind`](crate::muscle::ConstraintKind) variant,
/// the field of `MuscleConstraints` and `Compliances`, the batch type, the
/// label printed in tables, the default compliance (m/N; Volume m³/N), the
/// column in the thesis' Tables 5.1–5.4, and who makes the constraints:
/// `made (by f)` (`f(&Muscle) -> Batch`, called by `Muscle::build` once the
/// particles, structure and fibres exist) or `made (when linked)` (by
/// attachments and by linking the muscle to its targets).
///
/// Code that must list every type (the plug-in's compliance component)
/// expands from here instead of repeating the list.
#[macro_export]
macro_rules! constraint_types {
    ($callback:ident) => {
        $callback! {
            batched {
                /// Attach: surface vertex ↔ attachment point.
                Attach => attach: $crate::constraints::PointBatch,
                    "Attach", compliance 0.0, column 1, made (when linked);
                /// BranchAttach: internal point ↔ attachment point.
                BranchAttach => branch_attach: $crate::constraints::PointBatch,
                    "BrAttach", compliance 0.0, column 2, made (when linked);
                /// Bind: surface vertex ↔ its linear-blend skinned position
                /// (a skin layer following its skeleton; a soft spring).
                Bind => bind: $crate::constraints::PointBatch,
                    "Bind", compliance 0.05, column 8, made (by $crate::muscle::bind_constraints);
                /// Hard: vertex ↔ its rest transform on a target triangle.
                Hard => hard: $crate::constraints::PointBatch,
                    "Hard", compliance 5e-3, column 5, made (when linked);
                /// Soft: vertex ↔ its rest point on a target triangle (a spring).
                Soft => soft: $crate::constraints::PointBatch,
                    "Soft", compliance 2e-3, column 4, made (when linked);
                /// Sliding: vertex ↔ closest point on the closest target
                /// (gap kept, free to slide).
                Sliding => sliding: $crate::constraints::SlidingBatch,
                    "Sliding", compliance 1e-3, column 3, made (when linked);
                /// Branch: internal point ↔ internal point.
                Branch => branch: $crate::constraints::DistanceBatch,
                    "Branch", compliance 2e-5, column 7, made (by $crate::muscle::branch_links);
                /// Internal: surface vertex ↔ its internal point.
                Internal => internal: $crate::constraints::DistanceBatch,
                    "Internal", compliance 2e-4, column 6, made (by $crate::muscle::internal_links);
                /// Fiber: one per polygon edge; its rest length shrinks
                /// along the fibres with activation.
                Fiber => fiber: $crate::constraints::DistanceBatch,
                    "Fiber", compliance 2e-5, column 0, made (by $crate::muscle::fiber_edges);
                /// Area: one per triangle of a surface layer's mesh (skin,
                /// fat), keeping its area against shear and folds (a muscle
                /// keeps its shape by volume and internal structure and has
                /// none). Units: m³/N.
                Area => area: $crate::constraints::AreaBatch,
                    "Area", compliance 1e-7, column 10, made (by $crate::muscle::area_triangles);
            }
            whole {
                /// Volume: one per muscle; enclosed volume with
                /// activation-driven gain (0 compliance: the gain is
                /// reached exactly).
                Volume => volume: $crate::constraints::VolumeConstraint,
                    "Volume", compliance 0.0, column 9;
            }
        }
    };
}

/// Generates the core's types from [`constraint_types!`](crate::constraint_types).
macro_rules! muscle_constraint_table {
    (
        batched { $(
            $(#[$doc:meta])* $kind:ident => $field:ident: $batch:ty,
                $label:literal, compliance $default:literal, column $column:literal,
                made $made:tt;
        )* }
        whole {
            $(#[$wdoc:meta])* $wkind:ident => $wfield:ident: $wbatch:ty,
                $wlabel:literal, compliance $wdefault:literal, column $wcolumn:literal;
        }
    ) => {
        /// The constraint types, in the canonical projection order (SPEC
        /// §4.3); Volume, solved apart, is last.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        pub enum ConstraintKind {
            $($(#[$doc])* $kind,)*
            $(#[$wdoc])* $wkind,
        }

        impl ConstraintKind {
            /// Number of types.
            pub const COUNT: usize = [$(stringify!($kind),)* stringify!($wkind)].len();

            /// All kinds in the canonical projection order.
            pub const CANONICAL_ORDER: [ConstraintKind; Self::COUNT] =
                [$(Self::$kind,)* Self::$wkind];

            /// The layout of the thesis' Tables 5.1–5.4 (the table's columns).
            pub const TABLE_ORDER: [ConstraintKind; Self::COUNT] =
                in_columns(Self::CANONICAL_ORDER, [$($column,)* $wcolumn]);

            /// Short name as printed in the thesis' tables.
            pub fn label(self) -> &'static str {
                match self {
                    $(Self::$kind => $label,)*
                    Self::$wkind => $wlabel,
                }
            }
        }

        /// Compliance `α = 1/k` per constraint type. `0` is rigid; larger is
        /// softer.
        ///
        /// Units: m/N for the distance-type constraints, m³/N for Volume.
        /// Tuning hint: with millimetre-to-centimetre edges and gram-scale
        /// particles at 60 Hz, `1e-6` is stiff, `1e-4` is soft rubber and
        /// `1e-2` is jelly. Sliding, Soft and Hard are divided by the
        /// painted weight of each vertex.
        #[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct Compliances {
            $(
                #[doc = concat!($label, ". Default: `", stringify!($default), "`.")]
                pub $field: f32,
            )*
            #[doc = concat!($wlabel, ". Default: `", stringify!($wdefault), "`.")]
            pub $wfield: f32,
        }

        impl Default for Compliances {
            fn default() -> Self {
                Self {
                    $($field: $default,)*
                    $wfield: $wdefault,
                }
            }
        }

        impl Compliances {
            /// Compliance of one type.
            pub fn get(&self, kind: ConstraintKind) -> f32 {
                match kind {
                    $(ConstraintKind::$kind => self.$field,)*
                    ConstraintKind::$wkind => self.$wfield,
                }
            }
        }

        /// The constraint batches of a muscle, one per type, and its
        /// Volume constraint (solved apart: it moves every particle).
        #[derive(Clone, Debug, Default)]
        pub struct MuscleConstraints {
            $($(#[$doc])* pub $field: $batch,)*
            /// Volume (absent for open meshes allowed by the scene, and for
            /// surface layers).
            pub $wfield: Option<$wbatch>,
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
                    ConstraintKind::$wkind => None,
                }
            }

            /// The batch of `kind`, to write (`None` for Volume).
            pub fn batch_mut(&mut self, kind: ConstraintKind) -> Option<&mut dyn ConstraintBatch> {
                match kind {
                    $(ConstraintKind::$kind => Some(&mut self.$field),)*
                    ConstraintKind::$wkind => None,
                }
            }

            /// Runs `f` on the batch of `kind` with its concrete type, so
            /// that the kernel inlines into `f`'s loop (`None` for Volume).
            #[inline(always)]
            pub fn with_batch<F: BatchFn>(&self, kind: ConstraintKind, f: F) -> Option<F::Output> {
                match kind {
                    $(ConstraintKind::$kind => Some(f.call(&self.$field)),)*
                    ConstraintKind::$wkind => None,
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
                    ConstraintKind::$wkind => None,
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

        impl Muscle {
            /// Makes the constraints of every type the table says
            /// `made by` a builder, from the muscle's particles, structure
            /// and fibres.
            pub(super) fn build_table_constraints(&mut self) {
                $(muscle_constraint_table!(@make self, $field, $made);)*
            }
        }
    };
    (@make $m:ident, $field:ident, (by $make:path)) => {
        $m.constraints.$field = $make(&$m);
    };
    (@make $m:ident, $field:ident, (when linked)) => {};
}

constraint_types!(muscle_constraint_table);

impl MuscleConstraints {
    /// Counts per type.
    pub fn counts(&self) -> ConstraintCounts {
        let mut c = ConstraintCounts::default();
        self.for_each_batch(|kind, b| c.0[kind as usize] = b.count());
        c.0[ConstraintKind::Volume as usize] = usize::from(self.volume.is_some());
        c
    }

    /// Counts per type of the constraints that act: those not switched off
    /// (a Sliding, Soft or Hard of weight 0 or out of every target's reach).
    pub fn active_counts(&self) -> ConstraintCounts {
        let mut c = ConstraintCounts::default();
        self.for_each_batch(|kind, b| {
            c.0[kind as usize] = (0..b.count()).filter(|&i| !b.is_off(i)).count();
        });
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

/// `kinds` (in canonical order) sorted by their `columns`.
const fn in_columns<const N: usize>(
    kinds: [ConstraintKind; N],
    columns: [usize; N],
) -> [ConstraintKind; N] {
    let mut out = kinds;
    let mut seen = [false; N];
    let mut k = 0;
    while k < N {
        assert!(
            columns[k] < N && !seen[columns[k]],
            "table columns must be 0..COUNT, each once"
        );
        seen[columns[k]] = true;
        out[columns[k]] = kinds[k];
        k += 1;
    }
    out
}

// Volume is the last kind (the multipliers taken out for a sweep are
// indexed by kind).
const _: () = assert!(
    MuscleConstraints::BATCHED.len() == BATCHED_KINDS
        && ConstraintKind::Volume as usize == BATCHED_KINDS
);

/// Number of batched constraint types (every type but Volume, which is
/// last in [`ConstraintKind`]).
pub(crate) const BATCHED_KINDS: usize = ConstraintKind::COUNT - 1;

/// The multipliers of a muscle's batched constraint types, taken out for a
/// parallel sweep, indexed by [`ConstraintKind`] (Volume apart).
pub(crate) type MuscleLambdas = [Vec<f32>; BATCHED_KINDS];

/// Constraint counts per type, indexed by [`ConstraintKind`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ConstraintCounts(pub [usize; ConstraintKind::COUNT]);

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
