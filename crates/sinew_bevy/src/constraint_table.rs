//! What the plug-in generates from the core's constraint table
//! ([`sinew_core::constraint_types!`]), so that a new constraint type
//! appears here, in the panel and in saved scenes without an edit:
//! [`Compliance`], the reflectable mirror of the core's [`Compliances`],
//! and [`ConstraintSets`], a muscle's constraint sets as a queryable
//! component.

use crate::components::MuscleState;
use bevy::prelude::*;
use sinew_core::muscle::{Compliances, ConstraintKind};

/// Generates [`Compliance`], [`ConstraintSets`] and their conversions from
/// the table.
macro_rules! table_components {
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
        /// Compliance `α = 1/k` per constraint type (as [`Compliances`],
        /// reflectable). `0` is rigid; larger is softer. Units: m/N
        /// (Volume: m³/N). Defaults: the core's.
        #[derive(Clone, Copy, Debug, PartialEq, Reflect)]
        pub struct Compliance {
            $($(#[$doc])* pub $field: f32,)*
            $(#[$wdoc])* pub $wfield: f32,
        }

        impl From<Compliances> for Compliance {
            fn from(c: Compliances) -> Self {
                Self {
                    $($field: c.$field,)*
                    $wfield: c.$wfield,
                }
            }
        }

        impl From<Compliance> for Compliances {
            fn from(c: Compliance) -> Self {
                Self {
                    $($field: c.$field,)*
                    $wfield: c.$wfield,
                }
            }
        }

        /// A muscle's constraint sets, one per type: how many constraints
        /// it has, how many act, and their compliance. Maintained by the
        /// plug-in: updated after a step in which they changed (a link, an
        /// attachment, a compliance edit); query it, e.g.
        /// `Query<(&Name, &ConstraintSets)>`.
        #[derive(Component, Clone, Copy, Debug, Default, PartialEq, Reflect)]
        #[reflect(Component, Default)]
        pub struct ConstraintSets {
            $($(#[$doc])* pub $field: ConstraintSet,)*
            $(#[$wdoc])* pub $wfield: ConstraintSet,
        }

        impl ConstraintSets {
            /// The set of `kind`.
            pub fn get(&self, kind: ConstraintKind) -> &ConstraintSet {
                match kind {
                    $(ConstraintKind::$kind => &self.$field,)*
                    ConstraintKind::$wkind => &self.$wfield,
                }
            }

            fn get_mut(&mut self, kind: ConstraintKind) -> &mut ConstraintSet {
                match kind {
                    $(ConstraintKind::$kind => &mut self.$field,)*
                    ConstraintKind::$wkind => &mut self.$wfield,
                }
            }
        }
    };
}

sinew_core::constraint_types!(table_components);

/// One constraint set of a muscle (see [`ConstraintSets`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Reflect)]
pub struct ConstraintSet {
    /// Constraints of this type.
    pub count: usize,
    /// Of them, those that act (a Sliding, Soft or Hard of weight 0, or
    /// out of every target's reach, does not).
    pub active: usize,
    /// The type's compliance (as [`Compliance`]). Units: m/N (Volume:
    /// m³/N).
    pub compliance: f32,
}

impl ConstraintSets {
    /// The sets of `state`'s muscle as it is now.
    pub fn of(state: &MuscleState) -> Self {
        let m = &state.muscle;
        let (counts, active) = (m.counts(), m.constraints.active_counts());
        let mut sets = Self::default();
        for kind in ConstraintKind::CANONICAL_ORDER {
            *sets.get_mut(kind) = ConstraintSet {
                count: counts.get(kind),
                active: active.get(kind),
                compliance: m.params.compliance.get(kind),
            };
        }
        sets
    }
}

/// Refreshes every muscle's [`ConstraintSets`] whose constraints changed
/// (their topology counter or their compliances) since it was last made.
pub(crate) fn report_constraint_sets(
    mut muscles: Query<(&MuscleState, &mut ConstraintSets, &mut SetsSeen)>,
) {
    for (state, mut sets, mut seen) in &mut muscles {
        let now = (state.muscle.topology(), state.muscle.params.compliance);
        if seen.0 != Some(now) {
            seen.0 = Some(now);
            sets.set_if_neq(ConstraintSets::of(state));
        }
    }
}

/// The topology counter and compliances a muscle's [`ConstraintSets`] were
/// made from.
#[derive(Component, Clone, Copy, Debug, Default)]
pub(crate) struct SetsSeen(Option<(u64, Compliances)>);

impl Default for Compliance {
    fn default() -> Self {
        Compliances::default().into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_the_core_type() {
        let core = Compliances {
            fiber: 1e-6,
            volume: 2e-6,
            sliding: 3e-3,
            ..Default::default()
        };
        let mirror = Compliance::from(core);
        assert_eq!(mirror.fiber, 1e-6);
        assert_eq!(mirror.sliding, 3e-3);
        assert_eq!(Compliances::from(mirror), core);
        assert_eq!(
            Compliances::from(Compliance::default()),
            Compliances::default()
        );
    }
}
