//! Rest lengths that follow the held shape
//! ([`super::MuscleParams::rest_follows_hold`]).
//!
//! ```text
//! g_i       particle i's held-shape goal (HoldLine::goal_of its rest position)
//! r₀        a Fiber, Branch or Internal constraint's rest length in the rest shape
//! ℓ         its rest length from the activation (DistanceBatch::own_rest), f = ℓ / r₀
//! q         |g_a − g_b| / r₀: how the held shape stretches it
//! λ         the activation's shortening along the fibres
//! rest      r₀ min(q, f max(q, 1))   where f < 1 (the activation shortens it: along the fibres)
//!           r₀ q f √λ                where f ≥ 1 (it lengthens it: across them)
//! ```
//!
//! Along the fibres the activation shortens a fibre to `f` of the longer
//! of its rest and held lengths, and never makes it longer than the held
//! shape: a muscle the bones stretch (`q > 1`, the triceps in a flexion)
//! is pulled taut by `f` against its held length; one they shorten
//! (`q < 1`, the flexors) shortens to `f` of its rest length, or follows
//! the held shape where the bones shortened it further still. Taking `f`
//! of the held length there too compounded the two: on T5 at full flexion
//! the brachialis' fibres (`q` ≈ 0.71, `f` = 0.65) wanted ×0.46 of their
//! rest length, and the flexors' held ends took the difference, the
//! biceps' long head's edges ×0.49–×1.96 and the brachioradialis'
//! ×0.40–×1.80 (now ×0.49–×1.46 and ×0.51–×1.54).
//!
//! Across the fibres the activation's bulge `β = √(G/λ)` keeps the volume
//! gain `G` of a muscle free to shorten to `λ`; held between its bones it
//! keeps the held line's length, so the section that keeps `G` is `√G`
//! wider: `β √λ`. Along them `λ` shortens the held length, which pulls the
//! muscle taut between its tendons.

use super::Muscle;
use crate::constraints::{ActivationScale, DistanceBatch};

impl Muscle {
    /// For a muscle whose rest lengths follow its held shape: every
    /// particle's goal in the pose its line last took
    /// ([`super::HoldLine::pose_kept`]; the Bind goals among them) and the
    /// Fiber, Branch and Internal rest lengths from them.
    pub(crate) fn follow_held_shape(&mut self) {
        let hold = self.hold_line.as_mut();
        let Some(goals) = hold.and_then(|h| h.kept_goals(&self.rest)) else {
            return;
        };
        let c = &mut self.constraints;
        for (goal, b) in c.bind.goal.iter_mut().zip(&self.binding) {
            *goal = goals[b.vertex.index()];
        }
        let p = &self.params;
        let a0 = p.rest_activation.min(0.95);
        let lambda = ActivationScale::new(p.activation, a0, p.max_contraction, None).shortening;
        let across = lambda.max(0.0).sqrt();
        for batch in [&mut c.fiber, &mut c.branch, &mut c.internal] {
            follow(batch, &self.rest, goals, across);
        }
    }

    /// Gives the Fiber, Branch and Internal batches their activation's
    /// rest lengths back once they no longer follow the held shape.
    pub(crate) fn release_held_rest(&mut self) {
        let c = &mut self.constraints;
        for batch in [&mut c.fiber, &mut c.branch, &mut c.internal] {
            if !batch.own_rest.is_empty() {
                batch.rest.copy_from_slice(&batch.own_rest);
                batch.own_rest.clear();
            }
            batch.shape_length.clear();
        }
    }
}

/// One batch's rest lengths from the goals `goals` (see the module docs;
/// `across` is `√λ`); `r₀` of each constraint, the distance of its
/// particles at `rest`, is taken the first time and kept in the batch.
fn follow(batch: &mut DistanceBatch, rest: &[glam::Vec3], goals: &[glam::Vec3], across: f32) {
    if batch.own_rest.len() != batch.rest.len() {
        batch.own_rest.clone_from(&batch.rest);
    }
    if batch.shape_length.len() != batch.rest.len() {
        batch.shape_length = (batch.a.iter().zip(&batch.b))
            .map(|(a, b)| rest[a.index()].distance(rest[b.index()]))
            .collect();
    }
    let n = batch.rest.len();
    let (a, b, r0s) = (&batch.a[..n], &batch.b[..n], &batch.shape_length[..n]);
    let (own, rests) = (&batch.own_rest[..n], &mut batch.rest[..n]);
    for k in 0..n {
        let r0 = r0s[k];
        if r0 <= 0.0 {
            continue;
        }
        let q = goals[a[k].index()].distance(goals[b[k].index()]) / r0;
        rests[k] = followed_rest(r0, own[k], q, across);
    }
}

/// A constraint's rest length following the held shape (module docs): `r0`
/// its length in the rest shape, `own` its activation's rest length, `q`
/// the held shape's stretch of it, `across` `√λ`.
fn followed_rest(r0: f32, own: f32, q: f32, across: f32) -> f32 {
    let f = own / r0;
    if f < 1.0 {
        r0 * q.min(f * q.max(1.0))
    } else {
        own * q * across
    }
}

#[cfg(test)]
mod tests {
    use super::followed_rest;
    use crate::scene::Scene;
    use std::path::Path;

    /// Along the fibres (`own` < `r0`): stretched by the bones, `f` of the
    /// held length; shortened, `f` of the rest length, or the held length
    /// where that is shorter still; across them the bulge on the held length.
    #[test]
    fn the_activation_shortens_a_fibre_from_the_longer_of_its_rest_and_held_lengths() {
        let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
        // f = 0.65.
        assert!(close(followed_rest(1.0, 0.65, 1.3, 1.0), 0.65 * 1.3));
        assert!(close(followed_rest(1.0, 0.65, 0.8, 1.0), 0.65));
        assert!(close(followed_rest(1.0, 0.65, 0.5, 1.0), 0.5));
        assert!(close(followed_rest(2.0, 1.3, 0.8, 1.0), 1.3));
        // Across (f ≥ 1): the bulge on the held length.
        assert!(close(followed_rest(1.0, 1.2, 0.9, 0.8), 1.2 * 0.9 * 0.8));
    }

    /// Each rest length follows the goals through `r₀`, the distance of
    /// its particles at rest, taken at the first call and kept in the
    /// batch: the same lengths as `r₀` taken every time, over goals that
    /// change between calls, and taken again for a batch that grew.
    #[test]
    fn the_rest_shape_lengths_taken_once_are_the_rest_distances() {
        use super::follow;
        use crate::constraints::{DistanceBatch, ParticleId};
        use glam::Vec3;
        let rest: Vec<Vec3> = (0..6)
            .map(|i| Vec3::new(i as f32 * 0.3, (i % 2) as f32 * 0.2, (i * i) as f32 * 0.01))
            .collect();
        let mut batch = DistanceBatch::default();
        for (a, b) in [(0, 1), (1, 2), (2, 3), (0, 4), (4, 5)] {
            let length = rest[a].distance(rest[b]) * 0.8;
            batch.push(ParticleId::from_index(a), ParticleId::from_index(b), length);
        }
        let expected = |batch: &DistanceBatch, goals: &[Vec3], across: f32| -> Vec<f32> {
            (0..batch.len())
                .map(|k| {
                    let (a, b) = (batch.a[k].index(), batch.b[k].index());
                    let r0 = rest[a].distance(rest[b]);
                    let q = goals[a].distance(goals[b]) / r0;
                    followed_rest(r0, batch.own_rest[k], q, across)
                })
                .collect()
        };
        for (call, stretch) in [1.0f32, 1.3, 0.7].into_iter().enumerate() {
            let goals: Vec<Vec3> = rest.iter().map(|r| *r * stretch + Vec3::Y).collect();
            if call == 2 {
                batch.push(ParticleId::new(3), ParticleId::new(5), 0.5);
            }
            follow(&mut batch, &rest, &goals, 0.9);
            assert_eq!(batch.shape_length.len(), batch.len());
            assert_eq!(batch.rest, expected(&batch, &goals, 0.9), "call {call}");
        }
    }

    /// T5 at its first flexion's peak: with its rest lengths following the
    /// held shape, a triceps' edges take the line's stretch along their
    /// length (each Fiber rest length is its length in the goals), and
    /// switching it off gives every batch its activation's lengths back.
    #[test]
    fn rest_lengths_follow_the_held_shape_and_come_back_when_let_go() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/t5.ron");
        let mut scene = Scene::load(&path).unwrap();
        for m in &mut scene.muscles {
            m.params.rest_follows_hold = true;
        }
        let mut solver = scene.instantiate(path.parent().unwrap()).unwrap();
        for _ in 0..150 {
            solver.step();
        }
        let i = solver.muscle_index("TRIlong").unwrap();
        let m = &solver.muscles()[i];
        let fiber = &m.constraints.fiber;
        assert_eq!(fiber.own_rest.len(), fiber.rest.len());
        // The triceps are stretched over the flexed elbow: their rest
        // lengths, on average, too (the activation is low).
        let (now, own): (f32, f32) = (fiber.rest.iter().sum(), fiber.own_rest.iter().sum());
        assert!(now > 1.05 * own, "{now} vs {own}");
        let mut m = m.clone();
        m.params.rest_follows_hold = false;
        m.release_held_rest();
        assert!(m.constraints.fiber.own_rest.is_empty());
        let back: f32 = m.constraints.fiber.rest.iter().sum();
        assert_eq!(back, own);
    }
}
