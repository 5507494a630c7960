//! The distance constraints of four muscles of one topology, projected
//! side by side: muscle `k` in lane `k` of every value (glam's `Vec4`, one
//! SSE register), each constraint of the shared index arrays once for all
//! four.
//!
//! A muscle's Gauss–Seidel pass over its distance runs
//! ([`ConstraintBatch::solve`](super::ConstraintBatch::solve)) projects one constraint at a time, a square
//! root and two divisions each, on scalars. Muscles swept from one recipe
//! (all 144 of T7's, all 17 of T5's) share their particle indices, so the
//! same pass over four of them is the same sequence of operations in four
//! lanes: each lane gives the bits its muscle's own pass gives (the same
//! IEEE operations in the same order; a lane whose constraint has
//! coincident particles keeps its values, as the scalar pass skips it),
//! for a quarter of the instructions. The positions go into lanes before
//! the distance batches and back after them, in each iteration (the other
//! constraint types move them one muscle at a time); the rest lengths and
//! multipliers stay in lanes for a block of iterations.

use super::DistanceBatch;
use crate::lanes;
use glam::{Vec3, Vec4};

/// Muscles a [`DistanceLanes`] holds.
pub const LANES: usize = 4;

/// Distance batches of [`LANES`] muscles of one topology, lane by lane
/// (module docs).
#[derive(Clone, Debug, Default)]
pub struct DistanceLanes {
    /// Each particle's coordinates and inverse mass, one lane per muscle.
    particles: Vec<LaneParticle>,
    /// Each constraint's rest length, batch after batch.
    rest: Vec<Vec4>,
    /// Each constraint's multiplier, batch after batch.
    lambda: Vec<Vec4>,
    /// Each batch's compliance.
    compliance: Vec<Vec4>,
    /// Where each batch's constraints start in `rest` and `lambda`.
    starts: Vec<usize>,
}

/// One particle of four muscles: its coordinates and inverse mass, muscle
/// `k` in lane `k`, in one cache line. A constraint's projection reads and
/// writes its two particles whole: apart, the four arrays were four cache
/// lines per particle and twelve bounds checks per constraint (the same
/// bits either way).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct LaneParticle {
    x: Vec4,
    y: Vec4,
    z: Vec4,
    w: Vec4,
}

impl DistanceLanes {
    /// Particles the lanes hold (0 before any load).
    pub fn particles(&self) -> usize {
        self.particles.len()
    }

    /// Takes the muscles' inverse masses and their distance batches' rest
    /// lengths, multipliers and compliances (`batches[k]`: muscle `k`'s,
    /// in projection order, with the index arrays of every other's): at
    /// the start of a block of iterations.
    pub fn load_batches(&mut self, w: [&[f32]; LANES], batches: [&[&DistanceBatch]; LANES]) {
        let particles = w.iter().map(|w| w.len()).min().unwrap_or(0);
        self.particles.resize(particles, LaneParticle::default());
        for (particle, w) in self
            .particles
            .iter_mut()
            .zip(zip4(w.map(|w| &w[..particles])))
        {
            particle.w = w;
        }
        self.rest.clear();
        self.lambda.clear();
        self.compliance.clear();
        self.starts.clear();
        for (b, first) in batches[0].iter().enumerate() {
            let n = first.len();
            let batch = batches.map(|batches| batches[b]);
            self.starts.push(self.rest.len());
            self.rest.extend(zip4(batch.map(|b| &b.rest[..n])));
            self.lambda.extend(zip4(batch.map(|b| &b.lambda[..n])));
            self.compliance.push(lanes::of(|k| batch[k].compliance));
        }
    }

    /// Gives muscle `lane` the multipliers of its batch `batch` (its
    /// `batch`-th as given to [`DistanceLanes::load_batches`]) back: at the
    /// end of the block.
    pub fn store_lambdas(&self, lane: usize, batch: usize, lambda: &mut [f32]) {
        let start = self.starts[batch];
        for (lambda, lanes) in lambda.iter_mut().zip(&self.lambda[start..]) {
            *lambda = lanes[lane];
        }
    }

    /// Takes the muscles' positions into lanes, each particle's four
    /// positions transposed in registers.
    pub fn load_positions(&mut self, p: [&[Vec3]; LANES]) {
        let n = self.particles.len();
        let [p0, p1, p2, p3] = p.map(|p| &p[..n]);
        let muscles = p0.iter().zip(p1).zip(p2).zip(p3);
        for (particle, (((a, b), c), d)) in self.particles.iter_mut().zip(muscles) {
            (particle.x, particle.y, particle.z) = lanes::transpose_in([*a, *b, *c, *d]);
        }
    }

    /// Gives each muscle its positions back, each particle's lanes
    /// transposed in registers.
    pub fn store_positions(&self, p: [&mut [Vec3]; LANES]) {
        let [p0, p1, p2, p3] = p;
        let muscles = p0.iter_mut().zip(p1.iter_mut()).zip(p2.iter_mut());
        for (q, (((a, b), c), d)) in self.particles.iter().zip(muscles.zip(p3.iter_mut())) {
            [*a, *b, *c, *d] = lanes::transpose_out(q.x, q.y, q.z);
        }
    }

    /// One Gauss–Seidel pass over the batches in every lane, the
    /// constraints' particles from `topology` (the batches of any of the
    /// muscles: their index arrays are the same), each constraint as
    /// [`ConstraintBatch::solve`](super::ConstraintBatch::solve) projects it.
    pub fn solve(&mut self, topology: &[&DistanceBatch], inv_dt2: f32) {
        let tiny = Vec4::splat(1e-9);
        let particles = &mut self.particles;
        let batches = topology.iter().zip(&self.compliance).zip(&self.starts);
        for ((batch, &compliance), &at) in batches {
            let alpha = compliance * inv_dt2;
            let n = batch.len();
            let (a, b) = (&batch.a[..n], &batch.b[..n]);
            let rest = &self.rest[at..at + n];
            let lambda = &mut self.lambda[at..at + n];
            for i in 0..n {
                let (ia, ib) = (a[i].index(), b[i].index());
                let (pa, pb) = (particles[ia], particles[ib]);
                let (dx, dy, dz) = (pa.x - pb.x, pa.y - pb.y, pa.z - pb.z);
                let len = lanes::sqrt(dx * dx + dy * dy + dz * dz);
                // Coincident particles (no direction): the scalar pass
                // skips the constraint, and so does its lane.
                let moves = !len.cmplt(tiny);
                let denom = (pa.w + pb.w) + alpha;
                let dl = (-(len - rest[i]) - alpha * lambda[i]) / denom;
                let dl = Vec4::select(denom.cmpgt(Vec4::ZERO), dl, Vec4::ZERO);
                let s = dl / len;
                let (nx, ny, nz) = (dx * s, dy * s, dz * s);
                let moved_a = &mut particles[ia];
                moved_a.x = Vec4::select(moves, pa.x + pa.w * nx, pa.x);
                moved_a.y = Vec4::select(moves, pa.y + pa.w * ny, pa.y);
                moved_a.z = Vec4::select(moves, pa.z + pa.w * nz, pa.z);
                let moved_b = &mut particles[ib];
                moved_b.x = Vec4::select(moves, pb.x - pb.w * nx, pb.x);
                moved_b.y = Vec4::select(moves, pb.y - pb.w * ny, pb.y);
                moved_b.z = Vec4::select(moves, pb.z - pb.w * nz, pb.z);
                lambda[i] = Vec4::select(moves, lambda[i] + dl, lambda[i]);
            }
        }
    }
}

/// Four muscles' values, item by item, as lanes (muscle `k`'s in lane
/// `k`), as long as the shortest.
fn zip4(v: [&[f32]; LANES]) -> impl Iterator<Item = Vec4> + '_ {
    let [a, b, c, d] = v;
    (a.iter().zip(b).zip(c).zip(d)).map(|(((a, b), c), d)| Vec4::new(*a, *b, *c, *d))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::{ConstraintBatch, ParticleId};

    /// A ring of `n` particles with chords to the next three, and four
    /// muscles' worth of positions, inverse masses, rest lengths and
    /// compliances around it (each muscle its own; one with a pinned
    /// particle, one with two particles at one place).
    fn four_muscles(n: usize) -> [(Vec<Vec3>, Vec<f32>, [DistanceBatch; 2]); LANES] {
        std::array::from_fn(|k| {
            let mut batches: [DistanceBatch; 2] = Default::default();
            for (j, batch) in batches.iter_mut().enumerate() {
                batch.compliance = [0.0, 1.3e-4][j] * (k + 1) as f32;
                for step in 1..=3 {
                    for i in 0..n {
                        let id = ParticleId::from_index;
                        let rest = 0.05 * step as f32 * (1.0 + 0.1 * k as f32 + 0.03 * j as f32);
                        batch.push(id(i), id((i + step + j) % n), rest);
                    }
                }
                batch.arrange_in_runs();
            }
            let mut p: Vec<Vec3> = (0..n)
                .map(|i| {
                    let t = i as f32 * 0.7 + k as f32;
                    Vec3::new(t.cos(), t.sin(), 0.01 * (i * k) as f32) * 0.1
                })
                .collect();
            if k == 2 {
                p[5] = p[6];
            }
            let w = (0..n)
                .map(|i| {
                    if k == 1 && i == 3 {
                        0.0
                    } else {
                        1.0 + 0.1 * (i % 5) as f32
                    }
                })
                .collect();
            (p, w, batches)
        })
    }

    /// Five passes in lanes leave every muscle's positions and multipliers
    /// with the bits of five passes of its own batches' Gauss–Seidel.
    #[test]
    fn lanes_give_each_muscle_the_bits_of_its_own_pass() {
        let inv_dt2 = 3600.0;
        let mut own = four_muscles(40);
        for (p, w, batches) in &mut own {
            for _ in 0..5 {
                for batch in batches.iter_mut() {
                    batch.solve(p, w, inv_dt2);
                }
            }
        }
        let mut laned = four_muscles(40);
        let mut lanes = DistanceLanes::default();
        {
            let refs: [[&DistanceBatch; 2]; LANES] =
                std::array::from_fn(|k| [&laned[k].2[0], &laned[k].2[1]]);
            let w = std::array::from_fn(|k| laned[k].1.as_slice());
            lanes.load_batches(w, std::array::from_fn(|k| refs[k].as_slice()));
        }
        for _ in 0..5 {
            lanes.load_positions(std::array::from_fn(|k| laned[k].0.as_slice()));
            let topology = [&laned[0].2[0], &laned[0].2[1]];
            lanes.solve(&topology, inv_dt2);
            let [a, b, c, d] = &mut laned;
            lanes.store_positions([&mut a.0, &mut b.0, &mut c.0, &mut d.0]);
        }
        for (k, (_, _, batches)) in laned.iter_mut().enumerate() {
            for (j, batch) in batches.iter_mut().enumerate() {
                lanes.store_lambdas(k, j, &mut batch.lambda);
            }
        }
        let bits = |v: &[Vec3]| {
            v.iter()
                .map(|p| p.to_array().map(f32::to_bits))
                .collect::<Vec<_>>()
        };
        for k in 0..LANES {
            assert_eq!(bits(&laned[k].0), bits(&own[k].0), "muscle {k}'s positions");
            for j in 0..2 {
                let lambdas =
                    |b: &DistanceBatch| b.lambdas().iter().map(|l| l.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    lambdas(&laned[k].2[j]),
                    lambdas(&own[k].2[j]),
                    "muscle {k}, batch {j}"
                );
            }
            assert_ne!(
                bits(&laned[k].0),
                bits(&four_muscles(40)[k].0),
                "muscle {k} moved"
            );
        }
    }
}
