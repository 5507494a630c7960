//! Typed handles: what the constraint batches, plans and links store instead
//! of bare integers, so that a particle, a slot in a muscle's own target
//! list and an entry of the driver's target table cannot be mixed up.
//!
//! Each is a `u32` underneath (`#[repr(transparent)]`): a batch of them is
//! as compact as the bare indices it replaces, and the kernels compile to
//! the same code.

/// A particle of one body: an index into its positions, surface vertices
/// first (`0..surface_count`), then internal points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(transparent)]
pub struct ParticleId(u32);

impl ParticleId {
    /// The particle at `index`.
    #[inline(always)]
    pub const fn new(index: u32) -> Self {
        Self(index)
    }

    /// The particle at `index` (panics past `u32::MAX`: no body has that many).
    #[inline(always)]
    pub fn from_index(index: usize) -> Self {
        Self(u32::try_from(index).expect("particle index fits in u32"))
    }

    /// Its index into the body's positions.
    #[inline(always)]
    pub const fn index(self) -> usize {
        self.0 as usize
    }

    /// Its index as stored.
    #[inline(always)]
    pub const fn raw(self) -> u32 {
        self.0
    }
}

impl std::fmt::Display for ParticleId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "particle {}", self.0)
    }
}

/// A slot in one muscle's own target list ([`crate::muscle::Muscle::targets`]):
/// what its Sliding, Soft and Hard connections name the target they hold to.
/// [`TargetSlot::NONE`] marks "no target within reach".
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(transparent)]
pub struct TargetSlot(u32);

impl TargetSlot {
    /// No target (a Sliding vertex with nothing within reach this iteration).
    pub const NONE: Self = Self(u32::MAX);

    /// Slot `index` of the muscle's target list.
    #[inline(always)]
    pub fn new(index: usize) -> Self {
        let raw = u32::try_from(index).expect("target slot fits in u32");
        debug_assert!(raw != u32::MAX, "u32::MAX is TargetSlot::NONE");
        Self(raw)
    }

    /// Its index into the muscle's target list, `None` for [`TargetSlot::NONE`].
    #[inline(always)]
    pub const fn get(self) -> Option<usize> {
        if self.0 == u32::MAX {
            None
        } else {
            Some(self.0 as usize)
        }
    }

    /// Its index into the muscle's target list (panics on
    /// [`TargetSlot::NONE`]: only for slots known to name a target).
    #[inline(always)]
    pub fn index(self) -> usize {
        self.get().expect("TargetSlot::NONE names no target")
    }
}

impl Default for TargetSlot {
    fn default() -> Self {
        Self::NONE
    }
}

/// An entry of the driver's table of every target surface (bones with a
/// surface, then muscles): where a muscle's target slots are looked up
/// ([`crate::solver::MuscleWorkspace::target_ids`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(transparent)]
pub struct TargetId(u32);

impl TargetId {
    /// Entry `index` of the driver's target table.
    #[inline(always)]
    pub fn new(index: usize) -> Self {
        Self(u32::try_from(index).expect("target id fits in u32"))
    }

    /// Its index into the driver's target table.
    #[inline(always)]
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handles_round_trip_and_none_is_apart() {
        assert_eq!(ParticleId::from_index(7).index(), 7);
        assert_eq!(ParticleId::new(7).raw(), 7);
        assert_eq!(TargetSlot::new(3).get(), Some(3));
        assert_eq!(TargetSlot::NONE.get(), None);
        assert_eq!(TargetSlot::default(), TargetSlot::NONE);
        assert_eq!(TargetId::new(5).index(), 5);
        assert_eq!(std::mem::size_of::<ParticleId>(), 4);
        assert_eq!(std::mem::size_of::<TargetSlot>(), 4);
    }
}
