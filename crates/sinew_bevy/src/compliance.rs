//! [`Compliance`]: the reflectable mirror of the core's
//! [`Compliances`], generated from the core's constraint table
//! ([`sinew_core::constraint_types!`]) so that a new constraint type
//! appears here, in the panel and in saved scenes without an edit.

use bevy::prelude::*;
use sinew_core::muscle::Compliances;

/// Generates [`Compliance`] and its conversions from the table.
macro_rules! compliance_component {
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
    };
}

sinew_core::constraint_types!(compliance_component);

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
