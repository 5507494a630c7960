//! `sinew bench`: per-block ms/frame, medians of several runs.

use crate::commands::{load_scene, truncate};
use sinew_core::glam::Vec3;
use sinew_core::{ColorScope, Solver, SolverMethod, StepTimings, SweepSchedule};
use std::error::Error;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Median (mean of the middle two for an even count; 0 when empty).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// What one run measured.
struct RunResult {
    /// Per-block ms/frame.
    blocks: [f64; 7],
    /// Wall ms/frame.
    wall: f64,
    /// Constraints in the scene.
    constraints: usize,
    /// Global iterations.
    iterations: usize,
    /// Timer clock reads in the last frame.
    clock_reads: u32,
    /// Worker threads setting (0 = every core).
    threads: u32,
    /// Projection method.
    method: SolverMethod,
}

/// A projection method named on the command line.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Method {
    /// Gauss–Seidel, the reference.
    Sequential,
    /// Per-muscle colour groups, one constraint at a time (the thesis).
    Colored,
    /// Clustered colouring, colour by colour across every muscle.
    ColoredGlobal,
    /// Jacobi averaging with over-relaxation `--omega`.
    Jacobi,
    /// Colour groups of at least `--min-group` constraints Gauss–Seidel, the
    /// rest Jacobi with `--omega`.
    Hybrid,
}

impl Method {
    /// The solver method this names, with the given parameters.
    pub fn solver_method(self, omega: f32, min_group: u32) -> SolverMethod {
        match self {
            Method::Sequential => SolverMethod::Sequential,
            Method::Colored => SolverMethod::Colored {
                scope: ColorScope::PerMuscle,
            },
            Method::ColoredGlobal => SolverMethod::Colored {
                scope: ColorScope::Global,
            },
            Method::Jacobi => SolverMethod::Jacobi { omega },
            Method::Hybrid => SolverMethod::Hybrid { min_group, omega },
        }
    }
}

/// Settings a benchmark or check overrides in the scene.
#[derive(Clone, Copy, Debug, clap::Args)]
pub struct Overrides {
    /// Global iteration count (default: the scene's).
    #[arg(long)]
    pub iterations: Option<u32>,
    /// Worker threads, 0 = every core (default: the scene's).
    #[arg(long)]
    pub threads: Option<u32>,
    /// Projection method (default: the scene's).
    #[arg(long, value_enum)]
    pub method: Option<Method>,
    /// Jacobi over-relaxation ω in [1, 2].
    #[arg(long, default_value_t = 1.5)]
    pub omega: f32,
    /// Hybrid: smallest colour group solved Gauss–Seidel.
    #[arg(long, default_value_t = 32)]
    pub min_group: u32,
    /// How coloured methods use the threads (default: the scene's, `auto`).
    #[arg(long, value_enum)]
    pub schedule: Option<Schedule>,
}

/// [`SweepSchedule`] on the command line.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Schedule {
    /// By colour when splitting by muscle would leave threads idle.
    Auto,
    /// Whole muscles per thread.
    ByMuscle,
    /// Colour by colour across muscles.
    ByColor,
}

impl Overrides {
    /// Applies the overrides to a solver and checks the settings they make
    /// (an iteration count of 0, 100 000 threads, ω outside [1, 2] are
    /// refused by name).
    pub fn apply(&self, solver: &mut Solver) -> Result<(), sinew_core::BuildError> {
        if let Some(i) = self.iterations {
            solver.settings.iterations = i;
        }
        if let Some(t) = self.threads {
            solver.settings.threads = t;
        }
        if let Some(m) = self.method {
            solver.settings.method = m.solver_method(self.omega, self.min_group);
        }
        if let Some(s) = self.schedule {
            solver.settings.schedule = match s {
                Schedule::Auto => SweepSchedule::Auto,
                Schedule::ByMuscle => SweepSchedule::ByMuscle,
                Schedule::ByColor => SweepSchedule::ByColor,
            };
        }
        solver.settings.validate()
    }
}

/// Steps `frames` frames: per-block ms/frame and wall ms/frame.
pub fn time_frames(solver: &mut Solver, frames: u32) -> ([f64; 7], f64) {
    let frames = frames.max(1);
    let mut blocks = [Duration::ZERO; 7];
    let start = Instant::now();
    for _ in 0..frames {
        solver.step();
        let t: &StepTimings = solver.timings();
        for (b, d) in blocks.iter_mut().zip(t.as_array()) {
            *b += d;
        }
    }
    let wall = start.elapsed().as_secs_f64() * 1e3 / frames as f64;
    (blocks.map(|d| d.as_secs_f64() * 1e3 / frames as f64), wall)
}

/// Which bodies of the scene a run steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Bodies {
    /// Everything.
    All,
    /// The muscles alone: surface layers (a skin) left out.
    WithoutLayers,
}

/// The names of the scene's surface layers (skin, fat: muscles whose
/// parameters are [`sinew_core::muscle::MuscleParams::is_surface_layer`]).
fn surface_layers(scene: &sinew_core::scene::Scene) -> Vec<String> {
    scene
        .muscles
        .iter()
        .filter(|m| m.params.is_surface_layer())
        .map(|m| m.name.clone())
        .collect()
}

/// One run: per-block ms/frame and wall ms/frame.
fn run_once(
    scene: &str,
    frames: u32,
    overrides: Overrides,
    timers: bool,
    bodies: Bodies,
) -> Result<RunResult, Box<dyn Error>> {
    let (mut spec, base) = load_scene(scene)?;
    if bodies == Bodies::WithoutLayers {
        let layers = surface_layers(&spec);
        spec.muscles.retain(|m| !layers.contains(&m.name));
        for m in &mut spec.muscles {
            m.targets.retain(|t| !layers.contains(t));
        }
    }
    let mut solver = spec.instantiate(&base)?;
    overrides.apply(&mut solver)?;
    solver.settings.timers = timers;
    // Warm-up frame links targets and faults pages in.
    solver.step();
    let (per_frame, wall) = time_frames(&mut solver, frames);
    let constraints = solver.muscles().iter().map(|m| m.counts().total()).sum();
    Ok(RunResult {
        blocks: per_frame,
        wall,
        constraints,
        iterations: solver.settings.iterations as usize,
        clock_reads: solver.timings().clock_reads,
        threads: solver.settings.threads,
        method: solver.settings.method,
    })
}

/// Cost of one `Instant::now()` on this machine, in ns (median of 9 batches).
fn clock_read_ns() -> f64 {
    const N: u32 = 100_000;
    let batches = (0..9)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..N {
                std::hint::black_box(Instant::now());
            }
            start.elapsed().as_secs_f64() * 1e9 / N as f64
        })
        .collect();
    median(batches)
}

/// A bare XPBD distance loop over `n` constraints on a chain: the practical
/// lower bound per constraint-iteration on this machine. Returns ns.
pub fn bare_kernel_ns(n: usize, iterations: usize) -> f64 {
    let particles = n + 1;
    let mut p: Vec<Vec3> = (0..particles)
        .map(|i| Vec3::new(i as f32 * 0.01, 0.0, 0.0))
        .collect();
    let w = vec![1.0f32; particles];
    let a: Vec<u32> = (0..n as u32).collect();
    let b: Vec<u32> = (1..=n as u32).collect();
    let rest = vec![0.009f32; n];
    let mut lambda = vec![0.0f32; n];
    let alpha = 1e-5f32 * 3600.0;
    let reps = (2_000_000 / (n * iterations).max(1)).max(3);
    let mut samples = Vec::new();
    for _ in 0..reps {
        lambda.fill(0.0);
        let t = Instant::now();
        for _ in 0..iterations {
            for i in 0..n {
                let (ia, ib) = (a[i] as usize, b[i] as usize);
                let d = p[ia] - p[ib];
                let len = d.length();
                if len < 1e-9 {
                    continue;
                }
                let dl = (-(len - rest[i]) - alpha * lambda[i]) / (w[ia] + w[ib] + alpha);
                lambda[i] += dl;
                let g = d * (dl / len);
                p[ia] += w[ia] * g;
                p[ib] -= w[ib] * g;
            }
        }
        samples.push(t.elapsed().as_secs_f64() * 1e9 / (n * iterations) as f64);
    }
    std::hint::black_box(&p);
    median(samples)
}

pub fn run(
    scene: &str,
    frames: u32,
    runs: u32,
    overrides: Overrides,
    timer_overhead: bool,
) -> Result<ExitCode, Box<dyn Error>> {
    let runs = runs.max(1);
    let mut blocks: Vec<Vec<f64>> = vec![Vec::new(); 7];
    let mut walls = Vec::new();
    let mut untimed = Vec::new();
    let (mut constraints, mut iters, mut reads_per_frame, mut threads) = (0, 0, 0, 1);
    let mut method = SolverMethod::Sequential;
    // A scene with surface layers is also run without them, interleaved:
    // the difference is the layers' own line.
    let layers = surface_layers(&load_scene(scene)?.0);
    let mut muscles_only: Vec<Vec<f64>> = vec![Vec::new(); 8];
    for _ in 0..runs {
        let r = run_once(scene, frames, overrides, true, Bodies::All)?;
        for (k, v) in r.blocks.iter().enumerate() {
            blocks[k].push(*v);
        }
        walls.push(r.wall);
        (constraints, iters, reads_per_frame, threads) =
            (r.constraints, r.iterations, r.clock_reads, r.threads);
        method = r.method;
        if timer_overhead {
            untimed.push(run_once(scene, frames, overrides, false, Bodies::All)?.wall);
        }
        if !layers.is_empty() {
            let r = run_once(scene, frames, overrides, true, Bodies::WithoutLayers)?;
            for (k, v) in r.blocks.iter().chain([&r.wall]).enumerate() {
                muscles_only[k].push(*v);
            }
        }
    }
    let wall = median(walls);
    println!(
        "scene {scene}: {constraints} constraints, {iters} iterations, {:?}, {frames} frames × {runs} runs (medians), {}",
        method,
        match threads {
            0 => format!("{} threads (every core)", rayon_cores()),
            1 => "1 thread".to_string(),
            n => format!("{n} threads"),
        }
    );
    let medians: Vec<f64> = blocks.into_iter().map(median).collect();
    let sum: f64 = medians.iter().sum();
    if layers.is_empty() {
        println!("{:<16}{:>12}{:>8}", "block", "ms/frame", "share");
        for (name, ms) in StepTimings::NAMES.iter().zip(&medians) {
            println!("{name:<16}{ms:>12.4}{:>7.1}%", 100.0 * ms / sum.max(1e-12));
        }
        println!("{:<16}{:>12.4}", "blocks total", sum);
    } else {
        // Per block: everything, the muscles alone, and the difference.
        let alone: Vec<f64> = muscles_only.into_iter().map(median).collect();
        println!(
            "{:<16}{:>12}{:>8}{:>12}{:>12}",
            "block",
            "ms/frame",
            "share",
            "muscles",
            truncate(&layers.join("+"), 11)
        );
        for (k, name) in StepTimings::NAMES.iter().enumerate() {
            let (ms, m) = (medians[k], alone[k]);
            println!(
                "{name:<16}{ms:>12.4}{:>7.1}%{m:>12.4}{:>12.4}",
                100.0 * ms / sum.max(1e-12),
                ms - m
            );
        }
        let m: f64 = alone[..7].iter().sum();
        println!(
            "{:<16}{sum:>12.4}{:>8}{m:>12.4}{:>12.4}",
            "blocks total",
            "",
            sum - m
        );
        println!(
            "surface layers ({}): {:.4} ms/frame of the wall time (muscles alone: {:.4}, interleaved runs without them)",
            layers.join(", "),
            wall - alone[7],
            alone[7]
        );
    }
    println!("{:<16}{:>12.4}   ({:.0} fps)", "wall", wall, 1e3 / wall);
    let ns = wall * 1e6 / (constraints * iters).max(1) as f64;
    let bare = bare_kernel_ns(constraints.max(1), iters.max(1));
    println!(
        "ns per constraint-iteration: {ns:.2} (bare XPBD distance loop: {bare:.2}, ratio {:.2})",
        ns / bare
    );
    if timer_overhead {
        let off = median(untimed);
        println!(
            "timers off: {off:.4} ms/frame; timed − untimed {:+.2}% (run-to-run noise included)",
            100.0 * (wall - off) / off
        );
        let (reads, ns) = (reads_per_frame, clock_read_ns());
        println!(
            "timer cost: {reads} clock reads/frame × {ns:.1} ns = {:.3}% of the frame",
            100.0 * reads as f64 * ns * 1e-6 / wall
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Cores the "every core" setting uses.
pub fn rayon_cores() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}
