//! The yardstick of `sinew bench` and `sinew suite`: a coloured,
//! structure-of-arrays XPBD distance sweep over as many independent
//! constraints as the scene has active ones, on as many threads (one where
//! the scene is below `parallel_threshold` and sinew keeps it on the calling
//! thread), with as many iterations, chunked as sinew chunks its colours. What is left
//! between it and sinew is the model (other constraint types, targets,
//! closest data, integration) and the orchestration, not the machine.
//!
//! The constraints form a chain: constraint `i` joins particles `i` and
//! `i + 1`, so the even ones share no particle, nor do the odd ones — two
//! colours, each swept in chunks of [`TASK_CONSTRAINTS`] that threads take
//! whole, one fork and join per colour, as sinew's colour sweeps take a
//! colour with chunks enough for every thread.
//! Positions are three `f32` arrays, and within a colour the particles are
//! read in order: the friendliest memory pattern a sweep can have, so the
//! ratio to it is an upper bound of sinew's overhead.

use crate::bench::{FrameTimes, median};
use rayon::prelude::*;
use sinew_core::solver::coloring::TASK_CONSTRAINTS;
use std::time::Instant;

/// The chain's state, structure of arrays.
struct Chain {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    inverse_mass: Vec<f32>,
    rest: Vec<f32>,
    lambda: Vec<f32>,
}

impl Chain {
    fn new(constraints: usize) -> Self {
        let particles = constraints + 1;
        // A slightly stretched, wavy chain: every constraint has work to do.
        let x = (0..particles).map(|i| i as f32 * 0.0101).collect();
        let y = (0..particles)
            .map(|i| 0.001 * (i as f32 * 0.7).sin())
            .collect();
        Self {
            x,
            y,
            z: vec![0.0; particles],
            inverse_mass: vec![1.0; particles],
            rest: vec![0.01; constraints],
            lambda: vec![0.0; constraints],
        }
    }
}

/// Projects one colour's chunk: constraint `j` (even) of the slices joins
/// particles `j` and `j + 1`; `alpha` is the compliance divided by h².
#[inline(always)]
fn project(
    (x, y, z, inverse_mass): (&mut [f32], &mut [f32], &mut [f32], &[f32]),
    (lambda, rest): (&mut [f32], &[f32]),
    alpha: f32,
) {
    let pairs = x
        .chunks_exact_mut(2)
        .zip(y.chunks_exact_mut(2))
        .zip(z.chunks_exact_mut(2))
        .zip(inverse_mass.chunks_exact(2));
    let multipliers = lambda.iter_mut().step_by(2).zip(rest.iter().step_by(2));
    for ((((x, y), z), w), (l, &rest)) in pairs.zip(multipliers) {
        let (dx, dy, dz) = (x[0] - x[1], y[0] - y[1], z[0] - z[1]);
        let length = (dx * dx + dy * dy + dz * dz).sqrt();
        if length > 1e-9 {
            let dl = (-(length - rest) - alpha * *l) / (w[0] + w[1] + alpha);
            *l += dl;
            let s = dl / length;
            x[0] += w[0] * s * dx;
            y[0] += w[0] * s * dy;
            z[0] += w[0] * s * dz;
            x[1] -= w[1] * s * dx;
            y[1] -= w[1] * s * dy;
            z[1] -= w[1] * s * dz;
        }
    }
}

/// One iteration: colour 0 (even constraints), then colour 1 (odd), each in
/// chunks of [`TASK_CONSTRAINTS`] constraints, in parallel on the current
/// pool when `parallel`. Chunk `k` of colour `c` holds the chain's
/// constraints `c + k·span ..` below `(k + 1)·span` (span = twice the chunk
/// size) and the particles from `c + k·span` on: contiguous ranges that no
/// other chunk of the colour touches.
fn iterate(chain: &mut Chain, alpha: f32, parallel: bool) {
    let span = 2 * TASK_CONSTRAINTS;
    for c in 0..2 {
        let Chain {
            x,
            y,
            z,
            inverse_mass,
            rest,
            lambda,
        } = chain;
        let (x, y, z, w) = (&mut x[c..], &mut y[c..], &mut z[c..], &inverse_mass[c..]);
        let (lambda, rest) = (&mut lambda[c..], &rest[c..]);
        if parallel && lambda.len() > span {
            let particles = (
                x.par_chunks_mut(span),
                y.par_chunks_mut(span),
                z.par_chunks_mut(span),
                w.par_chunks(span),
            );
            let multipliers = (lambda.par_chunks_mut(span), rest.par_chunks(span));
            (particles, multipliers)
                .into_par_iter()
                .for_each(|(p, m)| project(p, m, alpha));
        } else {
            let particles = x
                .chunks_mut(span)
                .zip(y.chunks_mut(span))
                .zip(z.chunks_mut(span))
                .zip(w.chunks(span));
            let multipliers = lambda.chunks_mut(span).zip(rest.chunks(span));
            for ((((x, y), z), w), m) in particles.zip(multipliers) {
                project((x, y, z, w), m, alpha);
            }
        }
    }
}

/// Frames the reference sweep runs untimed before the timed ones: a new
/// pool's threads are woken, and the chain brought into the cache.
const WARM_UP_FRAMES: usize = 3;

/// Median ns per constraint-iteration of the reference sweep over
/// `constraints` constraints, `iterations` iterations per frame, on
/// `threads` threads (1: the calling thread; 0: every core).
pub fn reference_ns(constraints: usize, iterations: usize, threads: u32) -> f64 {
    let constraints = constraints.max(2);
    let iterations = iterations.max(1);
    let mut chain = Chain::new(constraints);
    let alpha = 1e-5 * 3600.0;
    let pool = (threads != 1)
        .then(|| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads as usize)
                .build()
                .ok()
        })
        .flatten();
    // At least 20 timed frames (T7's 72 718 × 10 gave 5, whose median
    // still held the new pool's first wake-ups: its 2-thread figure read
    // 2.9–5.3 ns in one afternoon), after a few untimed ones.
    let frames = (20_000_000 / (constraints * iterations)).clamp(20, 2000);
    let mut time = || {
        chain.lambda.fill(0.0);
        let start = Instant::now();
        for _ in 0..iterations {
            iterate(&mut chain, alpha, pool.is_some());
        }
        start.elapsed().as_secs_f64() * 1e9 / (constraints * iterations) as f64
    };
    let mut timed = || -> Vec<f64> {
        for _ in 0..WARM_UP_FRAMES {
            time();
        }
        (0..frames).map(|_| time()).collect()
    };
    let samples = match &pool {
        Some(pool) => pool.install(timed),
        None => timed(),
    };
    std::hint::black_box(&chain.x);
    median(samples)
}

/// [`reference_ns`] for a measured frame: `active` constraints (a mean,
/// rounded) and `work` constraint-iterations per frame, on `threads`.
pub fn reference_for(active: f64, work: f64, threads: u32) -> f64 {
    reference_ns(
        active.round() as usize,
        (work / active.max(1.0)).round() as usize,
        threads,
    )
}

/// Sinew's runs, each with the reference sweep timed right after it over
/// the same work. The machine's speed drifts by a third within minutes,
/// so a ratio of sinew's median to a reference timed once, after all the
/// runs, held that drift; each run's ratio to its own neighbour does not
/// (`scripts/ab_bench.py`'s reason for pairing runs).
#[derive(Clone, Debug, Default)]
pub struct PairedRuns {
    /// Each run's ns per active constraint-iteration.
    ns: Vec<f64>,
    /// The reference's, timed right after that run.
    reference: Vec<f64>,
}

impl PairedRuns {
    /// Records a run that measured `times`, and times the reference over
    /// its active constraints and constraint-iterations on `threads` right
    /// after it.
    pub fn push(&mut self, times: &FrameTimes, threads: u32) {
        let ns = times.wall * 1e6 / times.work.max(1.0);
        self.push_timed(ns, reference_for(times.active, times.work, threads));
    }

    /// Records a run of `ns` and the reference's `reference` ns after it.
    fn push_timed(&mut self, ns: f64, reference: f64) {
        self.ns.push(ns);
        self.reference.push(reference);
    }

    /// The reference's median ns per constraint-iteration over the runs.
    pub fn reference_ns(&self) -> f64 {
        median(self.reference.clone())
    }

    /// The median of each run's ratio to the reference timed after it.
    pub fn ratio(&self) -> f64 {
        let ratios = (self.ns.iter().zip(&self.reference)).map(|(ns, r)| ns / r);
        median(ratios.collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A machine that slows down run after run slows each run's reference
    /// alike: the paired ratio keeps the true one, where the median run
    /// against a reference timed once at the end would read 20 / 15.
    #[test]
    fn paired_runs_cancel_the_machines_drift() {
        let mut paired = PairedRuns::default();
        for slowdown in [1.0, 2.0, 3.0] {
            paired.push_timed(10.0 * slowdown, 5.0 * slowdown);
        }
        assert_eq!(paired.ratio(), 2.0);
        assert_eq!(paired.reference_ns(), 10.0);
        // One run disturbed (another tenant during it alone) moves the
        // median of the ratios no further than its neighbours'.
        paired.push_timed(80.0, 5.0);
        paired.push_timed(12.0, 5.0);
        assert_eq!(paired.ratio(), 2.0);
    }

    /// The parallel sweep is the serial one: chunks of a colour share nothing.
    #[test]
    fn threads_do_not_change_the_sweep() {
        let run = |parallel: bool| {
            let mut chain = Chain::new(10_000);
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(4)
                .build()
                .unwrap();
            pool.install(|| {
                for _ in 0..5 {
                    iterate(&mut chain, 0.036, parallel);
                }
            });
            (chain.x, chain.y, chain.lambda)
        };
        assert_eq!(run(false), run(true));
    }

    /// The sweep does XPBD's work: after an iteration with zero compliance
    /// the colour projected last (odd constraints, independent of each
    /// other) is exactly at rest length, and every constraint was moved.
    #[test]
    fn the_last_colour_ends_at_rest_length() {
        // Short enough that f32 positions (up to 5 m) resolve 1 µm.
        let n = 500;
        let mut chain = Chain::new(n);
        let error = |c: &Chain, i: usize| {
            let d = [
                c.x[i] - c.x[i + 1],
                c.y[i] - c.y[i + 1],
                c.z[i] - c.z[i + 1],
            ];
            ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - c.rest[i]).abs()
        };
        assert!((0..n).all(|i| error(&chain, i) > 1e-5));
        iterate(&mut chain, 0.0, false);
        let worst = (1..n)
            .step_by(2)
            .map(|i| error(&chain, i))
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-6, "{worst}");
        assert!(chain.lambda.iter().all(|&l| l != 0.0));
    }

    #[test]
    fn it_reports_a_time() {
        let ns = reference_ns(5000, 2, 2);
        assert!(ns.is_finite() && ns > 0.0, "{ns}");
    }
}
