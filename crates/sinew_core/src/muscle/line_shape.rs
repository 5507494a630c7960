//! How a held line ([`super::HoldLine`]) is shaped beyond its rest map
//! ([`LineShape`]: bend, tendon pivot, swell), and the attachment goals a
//! pivoting tendon turns ([`HoldLine::turn_attachments`]).

use super::params::MuscleParams;
use super::{Attachment, HoldLine, LinePose};
use glam::{Quat, Vec3};

/// How a held line is shaped: [`MuscleParams::hold_bend`],
/// [`MuscleParams::tendon_pivot`] and the swell
/// [`MuscleParams::rest_follows_hold`] brings (read every substep, so a
/// live edit takes effect at once). The default is the straight,
/// unturned, unswollen line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineShape {
    /// Tangent length at the ends, in chord lengths (0: straight).
    pub bend: f32,
    /// Share of the turn onto the line each end group takes about its tip.
    pub pivot: f32,
    /// How much wider the held shape is across the line than the rest
    /// shape's stretch gives: `√` of the volume ratio at the muscle's
    /// activation when its rest lengths follow the held shape
    /// ([`MuscleParams::rest_follows_hold`]; its Volume constraint then
    /// asks the held shape's volume), 1 otherwise.
    pub swell: f32,
}

impl Default for LineShape {
    fn default() -> Self {
        Self {
            bend: 0.0,
            pivot: 0.0,
            swell: 1.0,
        }
    }
}

impl LineShape {
    /// The shape `params` ask for.
    pub fn of(params: &MuscleParams) -> Self {
        let swell = if params.rest_follows_hold && params.volume.enabled {
            let a0 = params.rest_activation.min(0.95);
            params.volume.ratio(params.activation, a0).max(0.0).sqrt()
        } else {
            1.0
        };
        Self {
            bend: params.hold_bend,
            pivot: params.tendon_pivot,
            swell,
        }
    }
}

impl HoldLine {
    /// Turns the attachment goals of each end group about its tip by the
    /// pose's tendon turn: `goals[i]` and `internal_goals` (one per
    /// attachment with an internal particle, in order) are where the
    /// bones carry `attachments` now. An end whose tip is not attached
    /// (detached at run time) stays as its bone carries it.
    pub fn turn_attachments(
        &self,
        line: &LinePose,
        attachments: &[Attachment],
        goals: &mut [Vec3],
        internal_goals: &mut [Vec3],
    ) {
        for (end, turn) in self.ends.iter().zip(line.turns) {
            if turn == Quat::IDENTITY {
                continue;
            }
            let Some(tip) = attachments
                .iter()
                .position(|a| a.vertex.index() == end.tip as usize)
                .map(|i| goals[i])
            else {
                continue;
            };
            let mut k = 0;
            for (i, a) in attachments.iter().enumerate() {
                let turned = end.held.binary_search(&(a.vertex.index() as u32)).is_ok();
                if turned {
                    goals[i] = tip + turn * (goals[i] - tip);
                }
                if a.internal_particle.is_some() {
                    if turned {
                        internal_goals[k] = tip + turn * (internal_goals[k] - tip);
                    }
                    k += 1;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::muscle::hold_line::tests::bar;
    use glam::Affine3A;

    #[test]
    fn a_pivoting_tendon_turns_its_group_about_the_tip_towards_the_line() {
        // End 0 holds vertices 0 (its tip, farthest out) and 4; end 1 holds 1.
        let (mut positions, _) = bar();
        positions.push(Vec3::new(0.1, 0.05, 0.0));
        let held = [(Some(0), 0), (Some(0), 4), (Some(1), 1)];
        let line = HoldLine::new(&positions, &held, &|_| Affine3A::IDENTITY).unwrap();
        let attachments: Vec<Attachment> = held
            .iter()
            .map(|&(bone, v)| Attachment {
                bone,
                vertex: crate::constraints::ParticleId::from_index(v as usize),
                internal_particle: None,
                vertex_local: positions[v as usize],
                internal_local: Vec3::ZERO,
            })
            .collect();
        let goals_at = |pose: &dyn Fn(usize) -> Affine3A| -> Vec<Vec3> {
            held.iter()
                .map(|&(b, v)| pose(b.unwrap()).transform_point3(positions[v as usize]))
                .collect()
        };
        let shape = LineShape {
            pivot: 0.5,
            ..LineShape::default()
        };
        // At rest nothing turns.
        let rest = |_: usize| Affine3A::IDENTITY;
        let mut goals = goals_at(&rest);
        line.turn_attachments(&line.pose(&rest, shape), &attachments, &mut goals, &mut []);
        assert_eq!(goals, goals_at(&rest));
        // Bone 1 swung about the origin by 90°: the chord now runs up +Y.
        let swung = |b: usize| {
            if b == 1 {
                Affine3A::from_rotation_z(std::f32::consts::FRAC_PI_2)
            } else {
                Affine3A::IDENTITY
            }
        };
        let carried = goals_at(&swung);
        let mut goals = carried.clone();
        let now = line.pose(&swung, shape);
        line.turn_attachments(&now, &attachments, &mut goals, &mut []);
        assert_eq!(goals[0], carried[0], "the tip stays on its bone");
        assert_eq!(goals[2], carried[2], "end 1's tip stays on its bone");
        let (before, after) = (carried[1] - carried[0], goals[1] - goals[0]);
        assert!((before.length() - after.length()).abs() < 1e-6);
        // The chord from end 0's centroid to end 1's turned by ~85° from
        // the rest axis; half of that is the group's turn.
        let chord = (carried[2] - (carried[0] + carried[1]) / 2.0).normalize();
        let full = Quat::from_rotation_arc(line.axis, chord).to_axis_angle().1;
        let turned = before.angle_between(after);
        assert!((turned - full / 2.0).abs() < 1e-4, "{turned} vs {full}");
        assert!(after.normalize().dot(chord) > before.normalize().dot(chord));
    }

    #[test]
    fn a_held_shape_swells_with_the_volume_gain_only_when_the_rest_lengths_follow_it() {
        let mut params = MuscleParams::default();
        params.volume.activation_gain = 1.21;
        params.activation = 1.0;
        assert_eq!(LineShape::of(&params).swell, 1.0);
        params.rest_follows_hold = true;
        assert!((LineShape::of(&params).swell - 1.1).abs() < 1e-6);
        // The straight line's section widens by it.
        let (positions, held) = bar();
        let line = HoldLine::new(&positions, &held, &|_| Affine3A::IDENTITY).unwrap();
        let shape = LineShape::of(&params);
        let pose = line.pose(&|_| Affine3A::IDENTITY, shape);
        let g = line.goal(&pose, 2);
        assert!((g.y - 0.2 * 1.1).abs() < 1e-5, "{g}");
    }
}
