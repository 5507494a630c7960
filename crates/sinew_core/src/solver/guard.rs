//! The run-time guard: after every frame each muscle's state is checked —
//! positions and velocities finite, no particle faster than
//! [`super::SolverSettings::max_speed`]. A muscle that fails is put back to
//! its last good frame (the others keep running) and a [`Fault`] names the
//! muscle, the particle and the constraint that went bad first. Both drivers
//! (the plain [`super::Solver`] and the Bevy systems) call [`guard`] once per
//! muscle per frame.

use super::constraint_ref::ConstraintRef;
use super::workspace::MuscleWorkspace;
use crate::constraints::ParticleId;
use crate::muscle::{ConstraintKind, Muscle};
use glam::Vec3;
use std::fmt;

/// Why a muscle's frame was rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FaultKind {
    /// A position or velocity is NaN or infinite.
    NonFinite,
    /// A particle moved faster than the limit. Units: m/s.
    TooFast {
        /// Its speed. Units: m/s.
        speed: f32,
        /// The limit ([`super::SolverSettings::max_speed`]). Units: m/s.
        limit: f32,
    },
}

/// A muscle whose frame blew up, as [`guard`] found it; the muscle was put
/// back to its last good frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Fault {
    /// The frame that blew up (the solver's frame count after it).
    pub frame: u64,
    /// The muscle's index.
    pub muscle: usize,
    /// The muscle's name.
    pub name: String,
    /// The first bad particle: the first non-finite one, else the fastest.
    pub particle: u32,
    /// What was wrong.
    pub kind: FaultKind,
    /// The constraint that went bad first: in projection order, the first
    /// whose multiplier is not finite, else the one moving `particle` with
    /// the largest multiplier (`None`: no constraint moves it).
    pub constraint: Option<ConstraintRef>,
    /// How many frames of this muscle have been rejected so far.
    pub count: u32,
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "frame {}: muscle '{}' ", self.frame, self.name)?;
        match self.kind {
            FaultKind::NonFinite => write!(f, "went non-finite at particle {}", self.particle)?,
            FaultKind::TooFast { speed, limit } => write!(
                f,
                "particle {} moved at {speed:.3e} m/s (limit {limit} m/s)",
                self.particle
            )?,
        }
        match self.constraint {
            Some(c) => write!(f, ", first in {} constraint {}", c.kind.label(), c.index)?,
            None => write!(f, ", moved by no constraint")?,
        }
        write!(
            f,
            "; put back to its last good frame ({} rejected so far)",
            self.count
        )
    }
}

/// The last good state of a muscle, kept by [`guard`] in its workspace.
#[derive(Clone, Debug, Default)]
pub(crate) struct LastGood {
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    /// Frames rejected so far.
    faults: u32,
}

/// Checks `m` after a frame. A good state is kept as the last good one; a
/// bad one is replaced by the last good state (or, before any, the rest
/// pose at rest) and reported. `max_speed` is in scene units per second
/// (the setting times the length unit), `length_unit` converts it back for
/// the report, `order` is the projection order.
pub fn guard(
    m: &mut Muscle,
    ws: &mut MuscleWorkspace,
    frame: u64,
    muscle: usize,
    max_speed: f32,
    length_unit: f32,
    order: &[ConstraintKind],
) -> Option<Fault> {
    let bad = first_bad(m, max_speed);
    let good = &mut ws.last_good;
    let Some((particle, kind)) = bad else {
        good.x.clone_from(&m.x);
        good.v.clone_from(&m.v);
        return None;
    };
    let kind = match kind {
        FaultKind::TooFast { speed, limit } => FaultKind::TooFast {
            speed: speed / length_unit,
            limit: limit / length_unit,
        },
        non_finite => non_finite,
    };
    let constraint = culprit(m, particle, order);
    if good.x.len() == m.x.len() {
        m.x.copy_from_slice(&good.x);
        m.v.copy_from_slice(&good.v);
    } else {
        m.x.copy_from_slice(&m.rest);
        m.v.fill(Vec3::ZERO);
    }
    m.p.copy_from_slice(&m.x);
    m.constraints.clear_lambdas();
    good.faults += 1;
    Some(Fault {
        frame,
        muscle,
        name: m.name.clone(),
        particle,
        kind,
        constraint,
        count: good.faults,
    })
}

/// The first non-finite particle, else the fastest one over `max_speed`.
fn first_bad(m: &Muscle, max_speed: f32) -> Option<(u32, FaultKind)> {
    if let Some(i) = (0..m.x.len()).find(|&i| !(m.x[i].is_finite() && m.v[i].is_finite())) {
        return Some((i as u32, FaultKind::NonFinite));
    }
    let limit_sq = max_speed * max_speed;
    let (i, speed_sq) =
        m.v.iter()
            .map(|v| v.length_squared())
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
    (speed_sq > limit_sq).then(|| {
        let kind = FaultKind::TooFast {
            speed: speed_sq.sqrt(),
            limit: max_speed,
        };
        (i as u32, kind)
    })
}

/// The constraint that went bad first (see [`Fault::constraint`]).
fn culprit(m: &Muscle, particle: u32, order: &[ConstraintKind]) -> Option<ConstraintRef> {
    let batches = || {
        order
            .iter()
            .filter_map(|&kind| m.constraints.batch(kind).map(|b| (kind, b)))
    };
    let non_finite = batches().find_map(|(kind, batch)| {
        let index = batch.lambdas().iter().position(|l| !l.is_finite())?;
        Some(ConstraintRef {
            kind,
            index: index as u32,
        })
    });
    non_finite.or_else(|| {
        batches()
            .flat_map(|(kind, batch)| {
                let moved = batch.particles_per_constraint();
                (0..batch.count())
                    .filter(move |&i| {
                        batch.particles(i)[..moved].contains(&ParticleId::new(particle))
                    })
                    .map(move |i| (kind, i, batch.lambdas()[i].abs()))
            })
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .map(|(kind, index, _)| ConstraintRef {
                kind,
                index: index as u32,
            })
    })
}
