//! `sinew bench`: per-block ms/frame, medians of several runs.

use crate::commands::{load_scene, truncate};
use crate::reference_kernel::PairedRuns;
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
    /// The frames' times and work.
    times: FrameTimes,
    /// Constraints in the scene, switched-off ones included.
    constraints: usize,
    /// Global iterations.
    iterations: usize,
    /// Timer clock reads in the last frame.
    clock_reads: u32,
    /// Worker threads setting (0 = every core).
    threads: u32,
    /// Whether the muscle passes ran on the worker threads.
    parallel: bool,
    /// Projection method.
    method: SolverMethod,
}

/// What `sinew bench` runs.
#[derive(Clone, Debug, clap::Args)]
pub struct BenchArgs {
    /// Scene file or built-in name.
    pub scene: String,
    /// Frames per run.
    #[arg(long, default_value_t = 120, value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: u32,
    /// Measured runs (the median is reported).
    #[arg(long, default_value_t = 7, value_parser = clap::value_parser!(u32).range(1..))]
    pub runs: u32,
    /// First timed frame: the frames before it are stepped untimed (a walk
    /// window of T7: `--from 120 --frames 120`). Default 1: after one
    /// warm-up frame.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub from: u32,
    /// Copies of the scene's body side by side in one solver, a crowd
    /// (`Scene::crowd`): each `--spacing` beside the one before and started
    /// `--delay` later, so the copies are in different phases of the
    /// animation. Default 1: the scene alone.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=sinew_core::scene::MAX_CROWD as i64))]
    pub instances: u32,
    /// Distance between copies, along X. Units: m (scaled by the scene's
    /// `length_unit`). Default 1.
    #[arg(long, default_value_t = 1.0, value_parser = crate::args::non_negative)]
    pub spacing: f32,
    /// How much later each copy starts its animation than the one before.
    /// Units: s. Default 0.25.
    #[arg(long, default_value_t = 0.25, value_parser = crate::args::non_negative)]
    pub delay: f32,
    #[command(flatten)]
    pub overrides: Overrides,
    /// Also time with block timers off, to show their overhead.
    #[arg(long)]
    pub timer_overhead: bool,
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
    /// Iterations between two bone-contact passes of a substep (the first
    /// and each muscle's last always have one; default: the scene's).
    #[arg(long)]
    pub bone_contact_interval: Option<u32>,
    /// Iterations between two publications of the muscles' snapshots: each
    /// muscle runs that many iterations back to back (default: the
    /// scene's).
    #[arg(long)]
    pub snapshot_interval: Option<u32>,
    /// Iterations between two walks of Sliding's closest data over the
    /// targets (a substep's first always walks; default: the scene's).
    #[arg(long)]
    pub walk_interval: Option<u32>,
    /// Whether the iterations between walks project onto the feature the
    /// last walk found (`true`) or onto its triangle (`false`; default:
    /// the scene's).
    #[arg(long)]
    pub feature_contacts: Option<bool>,
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
        if let Some(k) = self.bone_contact_interval {
            solver.settings.bone_contact_interval = k;
        }
        if let Some(k) = self.snapshot_interval {
            solver.settings.snapshot_interval = k;
        }
        if let Some(k) = self.walk_interval {
            solver.settings.walk_interval = k;
        }
        if let Some(on) = self.feature_contacts {
            solver.settings.feature_contacts = on;
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

/// What stepping a run of frames measured.
#[derive(Clone, Copy, Debug)]
pub struct FrameTimes {
    /// Per-block ms/frame, named as [`StepTimings::NAMES`].
    pub blocks: [f64; 7],
    /// Wall ms/frame (the steps alone).
    pub wall: f64,
    /// Active constraints (not switched off: a Sliding out of every
    /// target's reach, a Soft or Hard of weight 0), mean over the frames.
    pub active: f64,
    /// Constraint-iterations the frames projected, mean per frame: each
    /// muscle's active constraints × its iterations × the substeps.
    pub work: f64,
    /// The surface layers' own tasks, ms/frame, by phase
    /// ([`sinew_core::LayerTimings`]: closest data, sweep, finish).
    pub layers: [f64; 3],
}

/// Whether `solver` runs its muscle passes on its worker threads: a scene
/// below `parallel_threshold` stays on the calling thread (the reference
/// sweep is then timed on one thread too).
pub fn runs_parallel(solver: &Solver) -> bool {
    let threads = solver.settings.threads != 1;
    sinew_core::solver::Parallelism::decide(&solver.settings, threads, solver.muscles()).muscles
}

/// Constraints of `solver` that act now, and the constraint-iterations a
/// frame of them is.
pub fn active_work(solver: &Solver) -> (usize, f64) {
    let s = &solver.settings;
    solver.muscles().iter().fold((0, 0.0), |(n, w), m| {
        let active = m.constraints.active_counts().total();
        let iterations = m.params.iterations.unwrap_or(s.iterations);
        (
            n + active,
            w + (active as u64 * iterations as u64 * s.substeps as u64) as f64,
        )
    })
}

/// Steps `frames` frames, timing the steps alone (active constraints are
/// counted between them).
pub fn time_frames(solver: &mut Solver, frames: u32) -> FrameTimes {
    let frames = frames.max(1);
    let mut blocks = [Duration::ZERO; 7];
    let mut layers = [Duration::ZERO; 3];
    let mut wall = Duration::ZERO;
    let (mut active, mut work) = (0.0, 0.0);
    for _ in 0..frames {
        let start = Instant::now();
        solver.step();
        wall += start.elapsed();
        let t: &StepTimings = solver.timings();
        for (b, d) in blocks.iter_mut().zip(t.as_array()) {
            *b += d;
        }
        for (l, d) in layers.iter_mut().zip(t.layers.as_array()) {
            *l += d;
        }
        let (n, w) = active_work(solver);
        active += n as f64;
        work += w;
    }
    let per_frame = |d: Duration| d.as_secs_f64() * 1e3 / frames as f64;
    FrameTimes {
        blocks: blocks.map(per_frame),
        layers: layers.map(per_frame),
        wall: per_frame(wall),
        active: active / frames as f64,
        work: work / frames as f64,
    }
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

/// One run: steps to `args.from` untimed, then times `args.frames` frames.
fn run_once(args: &BenchArgs, timers: bool, bodies: Bodies) -> Result<RunResult, Box<dyn Error>> {
    let (mut spec, base) = load_scene(&args.scene)?;
    if args.instances > 1 {
        let spacing = Vec3::X * args.spacing * spec.settings.length_unit;
        spec = spec.crowd(args.instances, spacing, args.delay)?;
    }
    if bodies == Bodies::WithoutLayers {
        let layers = surface_layers(&spec);
        spec.muscles.retain(|m| !layers.contains(&m.name));
        for m in &mut spec.muscles {
            m.targets.retain(|t| !layers.contains(t));
        }
    }
    let mut solver = spec.instantiate(&base)?;
    args.overrides.apply(&mut solver)?;
    solver.settings.timers = timers;
    // At least one warm-up frame: it links targets and faults pages in.
    for _ in 0..args.from.max(1) {
        solver.step();
    }
    let times = time_frames(&mut solver, args.frames);
    let constraints = solver.muscles().iter().map(|m| m.counts().total()).sum();
    Ok(RunResult {
        times,
        constraints,
        iterations: solver.settings.iterations as usize,
        clock_reads: solver.timings().clock_reads,
        threads: solver.settings.threads,
        parallel: runs_parallel(&solver),
        method: solver.settings.method,
    })
}

/// The surface layers' own tasks by phase (medians over the runs, one list
/// per phase) against `iterate_ms`, the closest-data and project blocks
/// together: where the tasks take as long as those blocks, the layers are
/// what the frame waits for. Nothing when they were not timed (a sweep
/// colour by colour across muscles).
fn print_layer_tasks(phases: &[Vec<f64>], iterate_ms: f64) {
    let [closest, sweep, finish] = [0, 1, 2].map(|k| median(phases[k].clone()));
    let total = closest + sweep + finish;
    if total <= 0.0 {
        return;
    }
    println!(
        "surface layers' own tasks: {total:.4} ms/frame ({:.0} % of closest data + project, {iterate_ms:.4}): closest data {closest:.4}, sweep {sweep:.4}, bone contacts and staging {finish:.4}",
        100.0 * total / iterate_ms.max(1e-12)
    );
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

/// Runs `sinew bench`: the median of `args.runs` runs, per block, next to
/// the [reference sweep](crate::reference_kernel) over the same active
/// constraints on the same threads.
pub fn run(args: &BenchArgs) -> Result<ExitCode, Box<dyn Error>> {
    let runs = args.runs;
    let mut blocks: Vec<Vec<f64>> = vec![Vec::new(); 7];
    let (mut walls, mut actives, mut works) = (Vec::new(), Vec::new(), Vec::new());
    let mut untimed = Vec::new();
    let (mut constraints, mut iters, mut reads_per_frame, mut threads) = (0, 0, 0, 1);
    let mut parallel = false;
    let mut method = SolverMethod::Sequential;
    // A scene with surface layers is also run without them, interleaved:
    // the difference is the layers' own line.
    let layers = surface_layers(&load_scene(&args.scene)?.0);
    let mut muscles_only: Vec<Vec<f64>> = vec![Vec::new(); 8];
    let mut layer_phases: Vec<Vec<f64>> = vec![Vec::new(); 3];
    // Each run is followed by the reference sweep over its work.
    let mut paired = PairedRuns::default();
    for _ in 0..runs {
        let r = run_once(args, true, Bodies::All)?;
        paired.push(&r.times, if r.parallel { r.threads } else { 1 });
        for (k, v) in r.times.blocks.iter().enumerate() {
            blocks[k].push(*v);
        }
        for (k, v) in r.times.layers.iter().enumerate() {
            layer_phases[k].push(*v);
        }
        walls.push(r.times.wall);
        actives.push(r.times.active);
        works.push(r.times.work);
        (constraints, iters, reads_per_frame, threads) =
            (r.constraints, r.iterations, r.clock_reads, r.threads);
        parallel = r.parallel;
        method = r.method;
        if args.timer_overhead {
            untimed.push(run_once(args, false, Bodies::All)?.times.wall);
        }
        if !layers.is_empty() {
            let r = run_once(args, true, Bodies::WithoutLayers)?;
            for (k, v) in r.times.blocks.iter().chain([&r.times.wall]).enumerate() {
                muscles_only[k].push(*v);
            }
        }
    }
    let wall = median(walls);
    let (active, work) = (median(actives), median(works));
    let (scene, frames, from) = (&args.scene, args.frames, args.from);
    if args.instances > 1 {
        println!(
            "a crowd of {} copies, {} m apart, each started {} s after the one before",
            args.instances, args.spacing, args.delay
        );
    }
    println!(
        "scene {scene}: {constraints} constraints ({active:.0} active, {:.0} switched off), {iters} iterations, {:?}, frames {from}–{} × {runs} runs (medians), {}",
        constraints as f64 - active,
        method,
        from + frames - 1,
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
        print_layer_tasks(&layer_phases, medians[3] + medians[4]);
    }
    println!("{:<16}{:>12.4}   ({:.0} fps)", "wall", wall, 1e3 / wall);
    let ns = wall * 1e6 / work.max(1.0);
    println!(
        "ns per active constraint-iteration: {ns:.2} (coloured reference sweep over as many, on {}, timed after each run: {:.2}; ratio {:.2}, the median of the runs')",
        if parallel {
            "the same threads"
        } else {
            "one thread, as the scene runs"
        },
        paired.reference_ns(),
        paired.ratio()
    );
    // What a crowd costs in memory: the largest solver a run built (runs
    // load one at a time), plus what the process holds besides.
    match crate::soak::memory_kib() {
        Some((_, peak)) => println!(
            "memory: {:.1} MiB maximum resident (the process)",
            peak as f64 / 1024.0
        ),
        None => println!("memory: not measured (no /proc/self/status)"),
    }
    if args.timer_overhead {
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
