//! The bent line a held shape follows ([`super::MuscleParams::hold_bend`]):
//! a cubic Hermite centre line from one attachment group to the other that
//! leaves each along the direction its bone (turned by the tendon pivot)
//! carries the muscle's rest axis, with frames carried along it, and the
//! rest surface laid on it by arc length.
//!
//! ```text
//! c(τ)      Hermite: c(0) = O, c(1) = I, c'(0) = k L F_O a₀, c'(1) = k L F_I a₀
//!           (k = hold_bend, L = |I − O|, F_e the end's frame: its bone's
//!           rotation since rest, turned by the tendon pivot)
//! Q(τ)      F_O carried along c by the shortest arc between successive
//!           tangents, then turned about the tangent by the share τ of the
//!           twist that is left between Q(1) and F_I
//! σ         arc length of c over L₀ (the stretch along)
//! goal(u)   for a rest offset u = r − O₀ with along = a₀·u, t = along/L₀:
//!           c at arc fraction t + Q there · (u − along a₀) · across(t),
//!           across(t) = 1 + (w/√σ − 1) ramp(t): thinned as the line
//!           stretches (and swollen by w, LineShape::swell), but not at
//!           the held rings (ramp 0 at the ends,
//!           1 beyond END_ZONE of the length from them); beyond the ends
//!           the offset is carried rigidly by the end's frame
//! ```
//!
//! A straight line between the groups turns the whole surface onto the
//! chord, while the held rings stay where their bones carry them: at a
//! bent elbow the rings next to them take the whole turn (T5 at 120°:
//! the triceps' necks folded, edges ×2.4). The curve spreads that turn
//! over the belly.

use super::LineShape;
use super::hold_line::RestOffset;
use glam::{Quat, Vec3};

/// Samples along the curve (the goal interpolates between them).
const SAMPLES: usize = 48;

/// Share of the line's length, from each end, over which the section goes
/// from the held rings' (unthinned) to the stretched belly's.
const END_ZONE: f32 = 0.15;

/// One sample of the curve: its point, frame (taking the rest axis onto
/// the tangent) and arc-length fraction from the first end.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Sample {
    point: Vec3,
    frame: Quat,
    arc: f32,
}

/// The bent line in one pose (see the module docs). Fixed arrays: built
/// for every held muscle in every substep, without allocating.
#[derive(Clone, Debug, PartialEq)]
pub struct BentLine {
    samples: [Sample; SAMPLES + 1],
    /// For each of [`SAMPLES`] even steps `j / SAMPLES` of the arc
    /// fraction, the first sample at or past it: where the search for a
    /// fraction in the next step starts ([`BentLine::segment`]).
    first_past: [u8; SAMPLES],
    /// The belly's section scale, [`LineShape::swell`] ÷ `√σ`.
    belly: f32,
}

impl BentLine {
    /// The curve from `o` to `i` leaving them along `frames[e] · axis`
    /// (`axis` the rest axis `a₀`), end tangents `shape.bend` chord
    /// lengths long, the belly swollen by `shape.swell`; `rest_length` is
    /// `L₀`, `max_stretch` bounds `σ` both ways.
    pub fn new(
        o: Vec3,
        i: Vec3,
        frames: [Quat; 2],
        axis: Vec3,
        rest_length: f32,
        shape: LineShape,
        max_stretch: f32,
    ) -> Self {
        let chord = o.distance(i);
        let [t0, t1] = frames.map(|f| f * axis * (shape.bend * chord));
        let point = |t: f32| {
            let (t2, t3) = (t * t, t * t * t);
            o * (2.0 * t3 - 3.0 * t2 + 1.0)
                + t0 * (t3 - 2.0 * t2 + t)
                + i * (3.0 * t2 - 2.0 * t3)
                + t1 * (t3 - t2)
        };
        let fallback = (i - o).try_normalize().unwrap_or(frames[0] * axis);
        let tangent = |t: f32| {
            let t2 = t * t;
            let d = (o - i) * (6.0 * t2 - 6.0 * t)
                + t0 * (3.0 * t2 - 4.0 * t + 1.0)
                + t1 * (3.0 * t2 - 2.0 * t);
            d.try_normalize().unwrap_or(fallback)
        };
        let mut previous = tangent(0.0);
        let mut frame =
            (Quat::from_rotation_arc(frames[0] * axis, previous) * frames[0]).normalize();
        let mut last = o;
        let mut length = 0.0;
        let mut samples = [Sample {
            point: o,
            frame,
            arc: 0.0,
        }; SAMPLES + 1];
        for (n, sample) in samples.iter_mut().enumerate().skip(1) {
            let t = n as f32 / SAMPLES as f32;
            let p = point(t);
            length += p.distance(last);
            last = p;
            let along = tangent(t);
            frame = (Quat::from_rotation_arc(previous, along) * frame).normalize();
            previous = along;
            *sample = Sample {
                point: p,
                frame,
                arc: length,
            };
        }
        // The twist left between the carried frame and the far end's,
        // about the end tangent, spread along the arc.
        let far = (Quat::from_rotation_arc(frames[1] * axis, previous) * frames[1]).normalize();
        let (twist_axis, angle) = (far * frame.inverse()).normalize().to_axis_angle();
        let angle = if angle > std::f32::consts::PI {
            angle - std::f32::consts::TAU
        } else {
            angle
        };
        let twist = if twist_axis.dot(previous) < 0.0 {
            -angle
        } else {
            angle
        };
        for s in &mut samples {
            s.arc = if length > 0.0 { s.arc / length } else { 0.0 };
            let along = s.frame * axis;
            s.frame = (Quat::from_axis_angle(along, twist * s.arc) * s.frame).normalize();
        }
        let stretch = if rest_length > 0.0 {
            (length / rest_length).clamp(1.0 / max_stretch, max_stretch)
        } else {
            1.0
        };
        let first_past = std::array::from_fn(|j| {
            let step = j as f32 / SAMPLES as f32;
            samples.partition_point(|s| s.arc < step) as u8
        });
        Self {
            samples,
            first_past,
            belly: shape.swell / stretch.sqrt(),
        }
    }

    /// The sample ending the segment arc fraction `t` (in `(0, 1)`) lies
    /// in: the first at or past `t`, at least 1 and at most [`SAMPLES`].
    /// It starts from the sample [`BentLine::first_past`] gives for the
    /// step below `t`'s and walks on (one or two samples where the
    /// samples are spread evenly by arc), where a binary search over the
    /// samples took six unpredictable steps for every particle.
    fn segment(&self, t: f32) -> usize {
        // A whole step below `t`: its start is never past the answer.
        let below = (t * SAMPLES as f32) as usize;
        let step = below.saturating_sub(1).min(SAMPLES - 1);
        let mut k = usize::from(self.first_past[step]);
        while k <= SAMPLES && self.samples[k].arc < t {
            k += 1;
        }
        k.clamp(1, SAMPLES)
    }

    /// The goal of a rest point whose offset from the line's rest origin
    /// is `offset` (`axis` and `rest_length` as given to [`BentLine::new`],
    /// the offset taken about them).
    pub fn goal(&self, axis: Vec3, rest_length: f32, offset: &RestOffset) -> Vec3 {
        let u = offset.u;
        let along = axis.dot(u);
        let across = u - along * axis;
        let [first, last] = [self.samples[0], self.samples[SAMPLES]];
        if along <= 0.0 || rest_length <= 0.0 {
            return first.point + first.frame * u;
        }
        if along >= rest_length {
            return last.point + last.frame * (u - rest_length * axis);
        }
        // `along / rest_length`, within (0, 1) here, which its clamp in
        // the offset leaves as it is; and the section's ramp there.
        let t = offset.t;
        let scale = 1.0 + (self.belly - 1.0) * offset.ramp;
        let k = self.segment(t);
        let (a, b) = (self.samples[k - 1], self.samples[k]);
        let f = if b.arc > a.arc {
            ((t - a.arc) / (b.arc - a.arc)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        // Neighbouring samples' frames differ by a few degrees at most (a
        // half turn over 48 samples): their normalised blend (glam's
        // `lerp`) is within 1e-5 rad of their slerp, at a fraction of its
        // cost.
        let frame = a.frame.lerp(b.frame, f);
        a.point.lerp(b.point, f) + frame * (across * scale)
    }
}

/// How far the section at fraction `t` of the line has gone from the held
/// rings' to the belly's: 0 at the ends, 1 beyond [`END_ZONE`] of the
/// length from them (see the module docs).
pub(super) fn section_ramp(t: f32) -> f32 {
    smoothstep(t.min(1.0 - t) / END_ZONE)
}

/// `3x² − 2x³` on `[0, 1]`, clamped outside.
fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

#[cfg(test)]
mod tests {
    use super::*;

    const AXIS: Vec3 = Vec3::X;
    const BENT: LineShape = LineShape {
        bend: 1.0,
        pivot: 0.0,
        swell: 1.0,
    };

    /// The goal from an offset taken once (its fraction along the line
    /// and section ramp) is, to the bit, the goal formed from the offset
    /// alone, as every call formed it before: `t = a₀·u / L₀` and the ramp
    /// at `t`, over a bent, twisted, stretched line and its ends. Seen to
    /// fail with the ramp taken without the end zone's scale.
    #[test]
    fn the_goal_from_an_offset_taken_once_is_the_goal_from_the_offset() {
        let axis = Vec3::new(0.8, 0.6, 0.0);
        let rest_length = 0.37;
        let shape = LineShape {
            bend: 0.8,
            pivot: 0.0,
            swell: 1.15,
        };
        let frames = [Quat::from_rotation_z(0.3), Quat::from_rotation_y(-0.5)];
        let o = Vec3::new(0.1, -0.2, 0.05);
        let line = BentLine::new(
            o,
            o + Vec3::new(0.2, 0.35, 0.1),
            frames,
            axis,
            rest_length,
            shape,
            4.0,
        );
        // The goal as formed from `u` alone.
        let formed = |u: Vec3| {
            let along = axis.dot(u);
            let across = u - along * axis;
            let [first, last] = [line.samples[0], line.samples[SAMPLES]];
            if along <= 0.0 {
                return first.point + first.frame * u;
            }
            if along >= rest_length {
                return last.point + last.frame * (u - rest_length * axis);
            }
            let t = along / rest_length;
            let ramp = smoothstep(t.min(1.0 - t) / END_ZONE);
            let scale = 1.0 + (line.belly - 1.0) * ramp;
            let k = line.segment(t);
            let (a, b) = (line.samples[k - 1], line.samples[k]);
            let f = if b.arc > a.arc {
                ((t - a.arc) / (b.arc - a.arc)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            a.point.lerp(b.point, f) + a.frame.lerp(b.frame, f) * (across * scale)
        };
        for i in 0..400 {
            let k = i as f32;
            let side = Vec3::new((k * 1.3).sin(), (k * 2.7).cos(), (k * 0.7).sin()) * 0.05;
            let u = axis * (rest_length * (k / 400.0 * 1.4 - 0.2)) + side;
            let offset = RestOffset::new(u, axis, rest_length);
            assert_eq!(line.goal(axis, rest_length, &offset), formed(u), "{u}");
        }
    }

    #[test]
    fn unturned_ends_give_the_straight_rest_line() {
        let line = BentLine::new(
            Vec3::ZERO,
            Vec3::X,
            [Quat::IDENTITY; 2],
            AXIS,
            1.0,
            BENT,
            4.0,
        );
        for u in [
            Vec3::new(-0.1, 0.2, 0.0),
            Vec3::new(0.3, 0.0, 0.1),
            Vec3::new(0.5, -0.2, 0.05),
            Vec3::new(1.2, 0.1, 0.0),
        ] {
            assert!(
                line.goal(AXIS, 1.0, &RestOffset::new(u, AXIS, 1.0))
                    .distance(u)
                    < 1e-4,
                "{u}"
            );
        }
    }

    #[test]
    fn the_line_leaves_each_end_along_its_frame_and_is_carried_rigidly_beyond() {
        // The far end's bone turned 90° about Z and moved to (0, 1, 0):
        // its rest axis now points along +Y.
        let turn = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let i = Vec3::new(0.7, 0.7, 0.0);
        let line = BentLine::new(Vec3::ZERO, i, [Quat::IDENTITY, turn], AXIS, 1.0, BENT, 4.0);
        // Near the first end the line runs along +X, near the far end along +Y.
        let near_o = line.goal(
            AXIS,
            1.0,
            &RestOffset::new(Vec3::new(0.01, 0.0, 0.0), AXIS, 1.0),
        );
        assert!(near_o.y.abs() < 1e-3 && near_o.x > 0.0, "{near_o}");
        let before_i = line.goal(
            AXIS,
            1.0,
            &RestOffset::new(Vec3::new(0.99, 0.0, 0.0), AXIS, 1.0),
        );
        let d = (i - before_i).normalize();
        assert!(d.dot(Vec3::Y) > 0.99, "{d}");
        // Beyond the far end an offset is carried by that end's frame.
        let beyond = line.goal(
            AXIS,
            1.0,
            &RestOffset::new(Vec3::new(1.1, 0.05, 0.0), AXIS, 1.0),
        );
        assert!(
            beyond.distance(i + turn * Vec3::new(0.1, 0.05, 0.0)) < 1e-3,
            "{beyond}"
        );
        // The held rings keep their section; the belly thins as the line stretches.
        // `BENT` does not swell: the belly's scale is 1 ÷ √σ, σ > 1.
        assert!(line.belly < 1.0, "{}", line.belly);
        let ring = line.goal(
            AXIS,
            1.0,
            &RestOffset::new(Vec3::new(0.5, 0.1, 0.0), AXIS, 1.0),
        );
        let centre = line.goal(
            AXIS,
            1.0,
            &RestOffset::new(Vec3::new(0.5, 0.0, 0.0), AXIS, 1.0),
        );
        let radius = ring.distance(centre);
        assert!((radius - 0.1 * line.belly).abs() < 1e-3, "{radius}");
    }

    /// The segment found from the steps' table is the binary search's
    /// over the samples, for fractions on, just before and just after
    /// every sample and in between, on a line bent hard enough that its
    /// samples are spread unevenly by arc.
    #[test]
    fn the_segment_from_the_steps_is_the_searched_one() {
        let turn = Quat::from_rotation_z(2.5);
        let shape = LineShape { bend: 3.0, ..BENT };
        let i = Vec3::new(0.3, 0.2, 0.0);
        let line = BentLine::new(Vec3::ZERO, i, [Quat::IDENTITY, turn], AXIS, 1.0, shape, 4.0);
        let gaps: Vec<f32> = (line.samples.windows(2))
            .map(|w| w[1].arc - w[0].arc)
            .collect();
        let (least, most) =
            (gaps.iter()).fold((f32::MAX, 0.0f32), |(l, m), &g| (l.min(g), m.max(g)));
        assert!(most > 2.0 * least, "{least} … {most}");
        let mut fractions: Vec<f32> = (1..10_000).map(|i| i as f32 / 10_000.0).collect();
        for s in &line.samples {
            fractions.extend([s.arc.next_down(), s.arc, s.arc.next_up()]);
        }
        for t in fractions.into_iter().filter(|t| *t > 0.0 && *t < 1.0) {
            let searched = line
                .samples
                .partition_point(|s| s.arc < t)
                .clamp(1, SAMPLES);
            assert_eq!(line.segment(t), searched, "{t}");
        }
    }

    #[test]
    fn a_twist_between_the_end_frames_is_spread_along_the_line() {
        // The far end twisted 90° about the axis: half of it at the middle.
        let twist = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
        let line = BentLine::new(
            Vec3::ZERO,
            Vec3::X,
            [Quat::IDENTITY, twist],
            AXIS,
            1.0,
            BENT,
            4.0,
        );
        let side = line.goal(
            AXIS,
            1.0,
            &RestOffset::new(Vec3::new(0.5, 0.1, 0.0), AXIS, 1.0),
        ) - Vec3::new(0.5, 0.0, 0.0);
        let half = Quat::from_rotation_x(std::f32::consts::FRAC_PI_4) * Vec3::new(0.0, 0.1, 0.0);
        assert!(side.distance(half) < 1e-3, "{side} vs {half}");
    }
}
