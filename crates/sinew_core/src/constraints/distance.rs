//! Distance-type constraints: Fiber (SPEC §5.1), Internal (§5.3), Branch (§5.4).
//!
//! ```text
//! C = |p_a − p_b| − σ̂(a)          ∇_a C = n, ∇_b C = −n, n = (p_a − p_b)/|p_a − p_b|
//! ```
//! The rest length `σ̂` depends on activation for fibres (and, optionally,
//! branches and internal links):
//!
//! ```text
//! PaperExact (Eq. 2.13–2.15):  φ = |u|,  ε = e ⊘ (1 − a0 φ),  σ̂ = |ε ∘ (1 − c a φ)|
//! RotationInvariant:           σ̂ = sqrt((β |e_⊥|)² + (λ e·u)²)
//!                              λ = (1 − c a)/(1 − c a0),  β = sqrt(k_p(a)/k_p(a0) / λ)
//! ```
//! with `e = r_a − r_b`, `u` the sign-aligned mean fibre of the two ends and `c`
//! the maximum contraction (1 in the paper). The paper formula scales the
//! *world-axis* components of `e`, so a diagonal fibre also shortens edges
//! across it; the rotation-invariant form scales only the component along the
//! fibre and equals the paper whenever `u` is axis-aligned. It is the default
//! because a muscle must contract the same way whatever its orientation in the
//! world (a bone rotating a muscle by 45° must not change how it contracts).
//!
//! `β` is the *bulge*: in the paper, edges across the fibres keep their rest
//! length, so a ring's circumference cannot grow and the volume gain can only
//! be reached by stretching them against their stiffness (and one linearised
//! volume projection per iteration then overshoots). Scaling the across-fibre
//! component by `β` makes the rest shape itself shorter by `λ` and thicker by
//! `β`, with volume ratio `λβ² = k_p`, so fibres, internal links and the volume
//! constraint agree. `β = 1` (no bulge) when [`ActivationScale::bulge`] is 1.

use super::{
    ConstraintBatch, Correction, Gathered, MAX_PARTICLES, ParticleId, Particles, delta_lambda,
};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// How fibre rest lengths depend on activation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum FiberMode {
    /// Eq. 2.12–2.15 as written (component-wise; not rotation-invariant).
    PaperExact,
    /// Only the edge component along the fibre shortens. Default.
    #[default]
    RotationInvariant,
}

/// Rest data for an activation-dependent rest length.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ActivationRest {
    /// Rest edge vector `r_a − r_b` ([`ActivationRest::push`]).
    edge: Vec<Vec3>,
    /// Unit fibre direction `u` of the edge (sign-aligned mean of the two
    /// ends).
    fiber: Vec<Vec3>,
    /// `e · u` of each edge: its length along the fibre at rest.
    along: Vec<f32>,
    /// `|e − (e · u) u|²` of each edge: its squared length across the
    /// fibre at rest. With `along`, what the rotation-invariant rest length
    /// reads of the edge, taken once rather than every time the activation
    /// changes (the same operations: the same bits).
    across_squared: Vec<f32>,
    /// How contractile each constraint is, `k` in `[0, 1]` (1 minus its
    /// ends' mean tendon mask): its shortening and bulge are `1 + (λ − 1) k`
    /// and `1 + (β − 1) k` (its contraction `c k` in the paper's formula).
    /// Empty: every constraint fully contractile.
    pub contractile: Vec<f32>,
    /// The fibre mode and activation scale the batch's rest lengths were
    /// last set for ([`DistanceBatch::update_rest`]); `None` in a batch
    /// just built.
    applied: Option<(FiberMode, ActivationScale)>,
}

impl ActivationRest {
    /// Adds a constraint's rest data: its rest edge `r_a − r_b` and the
    /// unit fibre across it (see [`ActivationRest::edge_fiber`]).
    pub fn push(&mut self, edge: Vec3, fiber: Vec3) {
        let along = edge.dot(fiber);
        self.edge.push(edge);
        self.fiber.push(fiber);
        self.along.push(along);
        self.across_squared
            .push((edge - along * fiber).length_squared());
    }

    /// Puts the data of constraint `order[k]` at index `k` (what
    /// [`DistanceBatch::arrange_in_runs`] does to the whole batch).
    fn permute(&mut self, order: &[u32]) {
        permute(&mut self.edge, order);
        permute(&mut self.fiber, order);
        permute(&mut self.along, order);
        permute(&mut self.across_squared, order);
        permute(&mut self.contractile, order);
    }

    /// Unit fibre of an edge from its two end fibres (SPEC §5.1 guards 1–2).
    pub fn edge_fiber(fa: Vec3, fb: Vec3) -> Vec3 {
        let fb = if fa.dot(fb) < 0.0 { -fb } else { fb };
        (fa + fb).try_normalize().unwrap_or(fa)
    }

    /// Rest length of constraint `i` for the given activation scale.
    pub fn rest_length(&self, i: usize, mode: FiberMode, s: &ActivationScale) -> f32 {
        match self.contractile.get(i) {
            None => self.scaled_length(i, mode, s),
            Some(&k) => {
                let partial = ActivationScale {
                    contraction: s.contraction * k,
                    shortening: 1.0 + (s.shortening - 1.0) * k,
                    bulge: 1.0 + (s.bulge - 1.0) * k,
                    ..*s
                };
                self.scaled_length(i, mode, &partial)
            }
        }
    }

    /// [`ActivationRest::rest_length`] of every constraint, into `rest`.
    /// The rotation-invariant lengths are written out in one loop over the
    /// arrays, which the compiler packs four or eight to a square root
    /// (the same operations: the same bits); T7 sets 55 000 a frame.
    fn rest_lengths(&self, mode: FiberMode, s: &ActivationScale, rest: &mut [f32]) {
        let n = rest.len();
        // Contractile values for some constraints only: each its own reading.
        let partial = !self.contractile.is_empty() && self.contractile.len() < n;
        if mode != FiberMode::RotationInvariant || partial {
            for (i, r) in rest.iter_mut().enumerate() {
                *r = self.rest_length(i, mode, s);
            }
            return;
        }
        let (along, across_squared) = (&self.along[..n], &self.across_squared[..n]);
        let contractile = (!self.contractile.is_empty()).then(|| &self.contractile[..n]);
        let length = |shortening: f32, bulge: f32, along: f32, across_squared: f32| {
            ((bulge * bulge) * across_squared + (shortening * along).powi(2)).sqrt()
        };
        match contractile {
            Some(k) => {
                for i in 0..n {
                    let shortening = 1.0 + (s.shortening - 1.0) * k[i];
                    let bulge = 1.0 + (s.bulge - 1.0) * k[i];
                    rest[i] = length(shortening, bulge, along[i], across_squared[i]);
                }
            }
            None => {
                for i in 0..n {
                    rest[i] = length(s.shortening, s.bulge, along[i], across_squared[i]);
                }
            }
        }
    }

    fn scaled_length(&self, i: usize, mode: FiberMode, s: &ActivationScale) -> f32 {
        match mode {
            FiberMode::PaperExact => {
                let (e, u) = (self.edge[i], self.fiber[i]);
                let phi = u.abs();
                let eps = e / (Vec3::ONE - s.a0 * s.contraction * phi);
                (eps * (Vec3::ONE - s.a * s.contraction * phi)).length()
            }
            FiberMode::RotationInvariant => {
                let (along, across_squared) = (self.along[i], self.across_squared[i]);
                ((s.bulge * s.bulge) * across_squared + (s.shortening * along).powi(2)).sqrt()
            }
        }
    }
}

/// Activation-derived factors shared by every rest length of a muscle in a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActivationScale {
    /// Activation, clamped to [0, 1].
    pub a: f32,
    /// Rest activation, clamped to [0, 0.95].
    pub a0: f32,
    /// Maximum contraction `c`.
    pub contraction: f32,
    /// `λ = (1 − c a)/(1 − c a0)`: length ratio along the fibres.
    pub shortening: f32,
    /// `β`: length ratio across the fibres (1 = no bulge).
    pub bulge: f32,
}

impl ActivationScale {
    /// Factors for activation `a`; `volume_ratio` is `k_p(a)/k_p(a0)` when the
    /// rest shape should bulge to that volume, or `None` for no bulge.
    pub fn new(a: f32, a0: f32, contraction: f32, volume_ratio: Option<f32>) -> Self {
        let a = a.clamp(0.0, 1.0);
        let a0 = a0.clamp(0.0, 0.95);
        let shortening = (1.0 - contraction * a) / (1.0 - contraction * a0);
        let bulge = volume_ratio.map_or(1.0, |r| (r / shortening.max(1e-3)).sqrt());
        Self {
            a,
            a0,
            contraction,
            shortening,
            bulge,
        }
    }
}

/// A batch of distance constraints of one type.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DistanceBatch {
    /// First particle.
    pub a: Vec<ParticleId>,
    /// Second particle.
    pub b: Vec<ParticleId>,
    /// Current rest length (updated once per frame from activation).
    pub rest: Vec<f32>,
    /// Accumulated multipliers (reset every frame / substep).
    pub lambda: Vec<f32>,
    /// Present when the rest length follows activation.
    pub activation: Option<ActivationRest>,
    /// Compliance α = 1/k. Units: m/N. `0` is rigid.
    pub compliance: f32,
    /// The constraints in the order they were created, as their indices
    /// in the batch, once [`DistanceBatch::arrange_in_runs`] has put the
    /// batch in another (runs that share no particle, for Gauss–Seidel);
    /// empty (or, set by hand, not as long as the batch) while the batch is
    /// taken to be in creation order. The colourings read the
    /// constraints in creation order
    /// ([`ConstraintBatch::creation_order`]), so the runs change no other
    /// method's colouring.
    pub creation_order: Vec<u32>,
    /// The rest lengths the activation gives, kept apart while something
    /// else sets `rest` from them (a muscle whose rest lengths follow its
    /// held shape, [`crate::muscle::MuscleParams::rest_follows_hold`]);
    /// empty otherwise.
    pub own_rest: Vec<f32>,
    /// Each constraint's length in the muscle's rest shape (`r₀` of a
    /// rest length that follows the held shape), taken once while `rest`
    /// follows it; empty otherwise. Units: m (scene units).
    pub shape_length: Vec<f32>,
}

/// Puts `values[order[k]]` at index `k`, where `values` holds one value
/// per constraint (an optional array, left empty, is left alone).
fn permute<T: Copy>(values: &mut Vec<T>, order: &[u32]) {
    if values.len() == order.len() {
        *values = order.iter().map(|&i| values[i as usize]).collect();
    }
}

impl DistanceBatch {
    /// Puts constraint `order[k]` (every per-constraint array's entry) at
    /// index `k`; `order` is a permutation of the batch's indices. The
    /// creation order is the caller's to update.
    pub(super) fn permute(&mut self, order: &[u32]) {
        debug_assert_eq!(order.len(), self.len());
        permute(&mut self.a, order);
        permute(&mut self.b, order);
        permute(&mut self.rest, order);
        permute(&mut self.lambda, order);
        permute(&mut self.own_rest, order);
        permute(&mut self.shape_length, order);
        if let Some(act) = &mut self.activation {
            act.permute(order);
        }
    }

    /// Number of constraints.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    /// Adds a constraint with the given fixed rest length, after the
    /// others (last in creation order too).
    pub fn push(&mut self, a: ParticleId, b: ParticleId, rest: f32) {
        if !self.creation_order.is_empty() {
            self.creation_order.push(self.a.len() as u32);
        }
        self.a.push(a);
        self.b.push(b);
        self.rest.push(rest);
        self.lambda.push(0.0);
    }

    /// Recomputes activation-dependent rest lengths (once per frame, SPEC
    /// §5.1 caching). They depend on the mode and the scale alone: for the
    /// ones they were last set for (a skin, a muscle at rest) they are kept,
    /// to the bit, without a pass over the batch.
    pub fn update_rest(&mut self, mode: FiberMode, scale: &ActivationScale) {
        if let Some(act) = &mut self.activation
            && act.applied != Some((mode, *scale))
        {
            act.rest_lengths(mode, scale, &mut self.rest);
            act.applied = Some((mode, *scale));
            if !self.own_rest.is_empty() {
                self.own_rest.clone_from(&self.rest);
            }
        }
    }

    /// Constraint value `C` for constraint `i`.
    pub fn value(&self, i: usize, p: &[Vec3]) -> f32 {
        (p[self.a[i].index()] - p[self.b[i].index()]).length() - self.rest[i]
    }
}

impl ConstraintBatch for DistanceBatch {
    fn count(&self) -> usize {
        self.a.len()
    }

    #[inline(always)]
    fn lambdas_mut(&mut self) -> &mut [f32] {
        &mut self.lambda
    }

    #[inline(always)]
    fn lambdas(&self) -> &[f32] {
        &self.lambda
    }

    #[inline(always)]
    fn particles_per_constraint(&self) -> usize {
        2
    }

    fn index_arrays(&self) -> [&[ParticleId]; MAX_PARTICLES] {
        [&self.a, &self.b, &[]]
    }

    fn lambda_storage(&mut self) -> &mut Vec<f32> {
        &mut self.lambda
    }

    #[inline(always)]
    fn particles(&self, i: usize) -> Particles {
        [self.a[i], self.b[i], self.b[i]]
    }

    /// In the batch's order ([`DistanceBatch::arrange_in_runs`]).
    fn solve(&mut self, p: &mut [Vec3], w: &[f32], inv_dt2: f32) {
        self.solve_in_order(p, w, inv_dt2);
    }

    fn creation_order(&self) -> &[u32] {
        if self.creation_order.len() == self.len() {
            &self.creation_order
        } else {
            &[]
        }
    }

    #[inline(always)]
    fn correction_of(
        &self,
        i: usize,
        lambda: f32,
        Gathered {
            at: [pa, pb, _],
            w: [wa, wb, _],
        }: Gathered,
        inv_dt2: f32,
    ) -> Option<Correction> {
        let alpha = self.compliance * inv_dt2;
        let (dl, to_a, to_b) = project_pair([pa, pb], [wa, wb], self.rest[i], lambda, alpha)?;
        Some(Correction::two(dl, to_a, to_b))
    }
}

/// The projection of one distance constraint of rest length `rest`,
/// multiplier `lambda` and compliance `alpha` (÷ h²) on particles at `at`
/// with inverse masses `w`: the multiplier increment and the two new
/// positions, or `None` for coincident particles (no direction). The
/// kernel of [`DistanceBatch::correction_of`] and of the Gauss–Seidel pass
/// in runs.
#[inline(always)]
pub(super) fn project_pair(
    [pa, pb]: [Vec3; 2],
    [wa, wb]: [f32; 2],
    rest: f32,
    lambda: f32,
    alpha: f32,
) -> Option<(f32, Vec3, Vec3)> {
    let d = pa - pb;
    let len = d.length();
    if len < 1e-9 {
        return None;
    }
    let dl = delta_lambda(len - rest, lambda, wa + wb, alpha);
    let n = d * (dl / len);
    let mut to_a = pa;
    to_a += wa * n;
    let mut to_b = pb;
    to_b -= wb * n;
    Some((dl, to_a, to_b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rotation-invariant rest length from the parts taken at
    /// [`ActivationRest::push`] is, to the bit, the one formed from the
    /// edge and the fibre each time, for edges at every angle to their
    /// fibre, shortening, bulging, and partly contractile.
    #[test]
    fn the_rest_length_from_the_parts_is_the_one_from_the_edge() {
        let mut act = ActivationRest::default();
        let mut edges = Vec::new();
        for i in 0..64 {
            let k = i as f32;
            let edge = Vec3::new((k * 1.3).sin(), (k * 0.7).cos(), (k * 2.1).sin()) * 0.01;
            let a = Vec3::new((k * 0.9).cos(), (k * 1.9).sin(), 0.4).normalize();
            let b = Vec3::new((k * 0.3).sin(), 0.6, (k * 1.1).cos()).normalize();
            let fiber = ActivationRest::edge_fiber(a, b);
            act.push(edge, fiber);
            edges.push((edge, fiber));
        }
        act.contractile = (0..64).map(|i| (i % 5) as f32 / 4.0).collect();
        let mode = FiberMode::RotationInvariant;
        for (a, ratio) in [(0.0, None), (0.6, Some(1.2)), (1.0, Some(1.5))] {
            let s = ActivationScale::new(a, 0.1, 0.7, ratio);
            for (i, &(e, u)) in edges.iter().enumerate() {
                let k = act.contractile[i];
                let (shortening, bulge) =
                    (1.0 + (s.shortening - 1.0) * k, 1.0 + (s.bulge - 1.0) * k);
                let along = e.dot(u);
                let across = e - along * u;
                let formed = ((bulge * bulge) * across.length_squared()
                    + (shortening * along).powi(2))
                .sqrt();
                assert_eq!(
                    act.rest_length(i, mode, &s).to_bits(),
                    formed.to_bits(),
                    "{i}, a {a}"
                );
            }
        }
    }

    /// A batch's rest lengths, set in one pass ([`DistanceBatch::update_rest`]),
    /// are each constraint's [`ActivationRest::rest_length`] to the bit: in
    /// both fibre modes, with and without contractile values, and a batch of
    /// a length the packed loop does not divide.
    #[test]
    fn the_batch_pass_gives_each_constraints_rest_length() {
        for (n, contractile) in [(67, true), (67, false), (3, true)] {
            let mut batch = DistanceBatch::default();
            let mut act = ActivationRest::default();
            for i in 0..n {
                let k = i as f32;
                let edge = Vec3::new((k * 1.3).sin(), (k * 0.7).cos(), (k * 2.1).sin()) * 0.01;
                let fiber = Vec3::new((k * 0.9).cos(), (k * 1.9).sin(), 0.4).normalize();
                act.push(edge, fiber);
                let id = ParticleId::from_index;
                batch.push(id(i), id(i + 1), 0.0);
            }
            if contractile {
                act.contractile = (0..n).map(|i| (i % 5) as f32 / 4.0).collect();
            }
            batch.activation = Some(act.clone());
            for mode in [FiberMode::RotationInvariant, FiberMode::PaperExact] {
                for (a, ratio) in [(0.0, None), (0.6, Some(1.2)), (1.0, Some(1.5))] {
                    let s = ActivationScale::new(a, 0.1, 0.7, ratio);
                    batch.update_rest(mode, &s);
                    for i in 0..n {
                        assert_eq!(
                            batch.rest[i].to_bits(),
                            act.rest_length(i, mode, &s).to_bits(),
                            "{n} constraints, contractile {contractile}, {mode:?}, a {a}: {i}"
                        );
                    }
                }
            }
        }
    }
}
