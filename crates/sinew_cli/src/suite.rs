//! `sinew suite`: the thesis' timing tables side by side with ours.
//!
//! For each scene (P1, P2, P3, P4 = the 17-muscle arm at 5 iterations, T7 =
//! the full body at 10), each method and each thread count: per-block
//! ms/frame (median of the runs), fps, the active constraints (switched-off
//! ones reported apart), ns per active constraint-iteration and, in the same
//! process, the [coloured reference sweep](crate::reference_kernel) over as
//! many constraints on as many threads, timed after each run, with the
//! median of the runs' ratios to it ([`PairedRuns`]). P1–P4 are
//! timed from their first frame; T7 in a walk window (frames 120–239) and a
//! run window (420–539), stepped to from the start. Also the colour counts
//! and group-size distribution of each colouring (the thesis' Appendix A)
//! and the measured cost of one parallel sweep's synchronisation. Writes
//! `suite.json` and PNG plots into the output folder.

use crate::bench::{Method, active_work, median, rayon_cores, runs_parallel, time_frames};
use crate::commands::load_solver;
use crate::reference_kernel::PairedRuns;
use serde::Serialize;
use sinew_core::solver::coloring::{ColorPlan, PlanKind};
use sinew_core::{Solver, SolverMethod, StepTimings};
use std::error::Error;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

mod plot;
use plot::plot;

/// What `sinew suite` runs.
#[derive(Clone, Debug, clap::Args)]
pub struct SuiteArgs {
    /// Output folder for `suite.json` and the plots.
    #[arg(long, default_value = "target/bench")]
    pub out: PathBuf,
    /// Timed runs per configuration (the median is reported).
    #[arg(long, default_value_t = 5)]
    pub runs: u32,
    /// Scenes (built-in names or files); default P1 P2 P3 P4 T7.
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<String>,
    /// Methods; default all five.
    #[arg(long, value_delimiter = ',', value_enum)]
    pub methods: Vec<Method>,
    /// Thread counts; default 1, the powers of two below the core count, and
    /// every core.
    #[arg(long, value_delimiter = ',')]
    pub threads: Vec<u32>,
    /// Jacobi and Hybrid over-relaxation ω.
    #[arg(long, default_value_t = 1.5)]
    pub omega: f32,
    /// Hybrid: smallest colour group solved Gauss–Seidel.
    #[arg(long, default_value_t = 32)]
    pub min_group: u32,
    /// Simulated work per run, in active constraint-iterations (sets the
    /// frame count of scenes timed from their start; T7's windows are
    /// fixed).
    #[arg(long, default_value_t = 3_000_000, value_parser = clap::value_parser!(u64).range(1..))]
    pub work: u64,
}

/// A reference scene of the thesis: where it lives and how it was timed.
struct Reference {
    name: &'static str,
    path: &'static str,
    iterations: u32,
    /// The thesis' ms/frame: SST, SMT-J, SMT-G, SMT-G* (Tab 7.5, 7.8).
    thesis: [Option<f64>; 4],
    /// Timed windows; none: from the first frame, as long as `--work` asks.
    windows: &'static [Window],
}

/// A timed stretch of a scene's animation, stepped to from the start.
struct Window {
    /// What happens in it.
    name: &'static str,
    /// First timed frame.
    from: u32,
    /// Timed frames (split evenly between the runs).
    frames: u32,
}

/// T7's windows: the walk and the run, where the body works.
const T7_WINDOWS: [Window; 2] = [
    Window {
        name: "walk",
        from: 120,
        frames: 120,
    },
    Window {
        name: "run",
        from: 420,
        frames: 120,
    },
];

const REFERENCES: [Reference; 5] = [
    Reference {
        name: "P1",
        path: "P1",
        iterations: 5,
        thesis: [Some(11.32), Some(7.30), Some(14.36), Some(8.28)],
        windows: &[],
    },
    Reference {
        name: "P2",
        path: "P2",
        iterations: 5,
        thesis: [Some(24.57), Some(12.89), Some(30.80), Some(13.37)],
        windows: &[],
    },
    Reference {
        name: "P3",
        path: "P3",
        iterations: 5,
        thesis: [Some(71.49), Some(32.74), Some(69.38), Some(26.26)],
        windows: &[],
    },
    Reference {
        name: "P4",
        path: "assets/scenes/t5.ron",
        iterations: 5,
        thesis: [Some(531.92), Some(198.96), Some(406.68), Some(152.49)],
        windows: &[],
    },
    Reference {
        name: "T7",
        path: "assets/scenes/t7.ron",
        iterations: 10,
        thesis: [Some(1414.0), Some(685.0), Some(1138.0), None],
        windows: &T7_WINDOWS,
    },
];

/// The thesis' method names, in [`Reference::thesis`] order.
const THESIS_METHODS: [&str; 4] = ["SST", "SMT-J", "SMT-G", "SMT-G*"];

#[derive(Serialize)]
struct Report {
    machine: Machine,
    /// One empty parallel sweep (fork + join on the pool), µs, per thread count.
    sync_us: Vec<(u32, f64)>,
    scenes: Vec<SceneReport>,
}

impl Report {
    /// The most threads any result used.
    fn max_threads(&self) -> u32 {
        self.scenes
            .iter()
            .flat_map(|s| &s.results)
            .map(|r| r.threads)
            .max()
            .unwrap_or(1)
    }
}

#[derive(Serialize)]
struct Machine {
    cores: usize,
    cpu: String,
}

/// One scene in one timed window.
#[derive(Clone, Serialize)]
struct SceneReport {
    /// The scene, with its window (`T7 walk`).
    name: String,
    source: String,
    /// First timed frame.
    from_frame: u32,
    muscles: usize,
    /// Every constraint, switched-off ones included.
    constraints: usize,
    /// Active constraints, mean over the window (median over the runs of
    /// every configuration).
    active_constraints: f64,
    iterations: u32,
    frames_per_run: u32,
    runs: u32,
    /// The thesis' ms/frame per method name.
    thesis_ms: Vec<(String, f64)>,
    colorings: Vec<ColoringReport>,
    results: Vec<ResultRow>,
}

#[derive(Clone, Serialize)]
struct ColoringReport {
    plan: String,
    /// Sweeps per iteration: the largest colour count over the muscles.
    sweeps: usize,
    /// Colours summed over the muscles.
    total_colors: usize,
    /// Colour sizes (constraints) over every muscle, as a histogram:
    /// `(upper bound of the bin, colours in it)`.
    size_histogram: Vec<(usize, usize)>,
    /// Constraints in the Jacobi tail (Hybrid).
    tail: usize,
}

#[derive(Clone, Serialize)]
struct ResultRow {
    method: String,
    threads: u32,
    /// Per-block ms/frame, named as [`StepTimings::NAMES`].
    blocks_ms: Vec<(String, f64)>,
    wall_ms: f64,
    wall_min_ms: f64,
    wall_max_ms: f64,
    fps: f64,
    /// Active constraints, mean over the timed frames.
    active_constraints: f64,
    /// Active constraint-iterations per frame.
    work: f64,
    ns_per_constraint_iteration: f64,
    /// The coloured reference sweep over as many constraints on as many
    /// threads (one where the scene stays on the calling thread, below
    /// `parallel_threshold`), ns per constraint-iteration: the median of
    /// its timings, one after each run.
    reference_ns: f64,
    /// The median of each run's ns per active constraint-iteration over
    /// the reference's timed right after it.
    ratio_to_reference: f64,
}

fn method_label(method: SolverMethod) -> String {
    match method {
        SolverMethod::Sequential => "Sequential".into(),
        SolverMethod::Colored { scope } => format!("Colored {scope:?}"),
        SolverMethod::Jacobi { omega } => format!("Jacobi ω={omega}"),
        SolverMethod::Hybrid { min_group, omega } => format!("Hybrid ≥{min_group} ω={omega}"),
    }
}

/// Colour statistics of every muscle of `solver` for one plan kind.
fn coloring(solver: &Solver, kind: PlanKind, label: &str) -> ColoringReport {
    let order = &solver.settings.projection_order;
    let plans: Vec<ColorPlan> = solver
        .muscles()
        .iter()
        .map(|m| ColorPlan::build(m, order, kind))
        .collect();
    let sizes: Vec<usize> = plans.iter().flat_map(ColorPlan::color_sizes).collect();
    let bins = [1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, usize::MAX];
    let size_histogram = bins
        .iter()
        .enumerate()
        .map(|(i, &hi)| {
            let lo = if i == 0 { 0 } else { bins[i - 1] };
            (hi, sizes.iter().filter(|&&s| s > lo && s <= hi).count())
        })
        .filter(|&(_, n)| n > 0)
        .collect();
    ColoringReport {
        plan: label.into(),
        sweeps: plans.iter().map(ColorPlan::color_count).max().unwrap_or(0),
        total_colors: sizes.len(),
        size_histogram,
        tail: plans.iter().map(|p| p.tail().len()).sum(),
    }
}

/// Median µs of one empty parallel sweep over `tasks` tasks on `threads` threads.
fn sync_cost_us(threads: u32, tasks: usize) -> f64 {
    use rayon::prelude::*;
    let Ok(pool) = rayon::ThreadPoolBuilder::new()
        .num_threads(threads as usize)
        .build()
    else {
        return f64::NAN;
    };
    let samples = (0..9)
        .map(|_| {
            let reps = 2000;
            let start = Instant::now();
            for _ in 0..reps {
                pool.install(|| {
                    (0..tasks).into_par_iter().for_each(|i| {
                        std::hint::black_box(i);
                    })
                });
            }
            start.elapsed().as_secs_f64() * 1e6 / reps as f64
        })
        .collect();
    median(samples)
}

fn default_threads() -> Vec<u32> {
    let cores = rayon_cores() as u32;
    let mut t: Vec<u32> = std::iter::successors(Some(1u32), |n| Some(n * 2))
        .take_while(|&n| n < cores)
        .collect();
    t.push(cores);
    t.dedup();
    t
}

fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

/// Runs the suite (see the module docs).
pub fn run(args: &SuiteArgs) -> Result<ExitCode, Box<dyn Error>> {
    let methods = if args.methods.is_empty() {
        vec![
            Method::Sequential,
            Method::Colored,
            Method::ColoredGlobal,
            Method::Jacobi,
            Method::Hybrid,
        ]
    } else {
        args.methods.clone()
    };
    let threads = if args.threads.is_empty() {
        default_threads()
    } else {
        args.threads.clone()
    };
    let runs = args.runs.max(1);
    std::fs::create_dir_all(&args.out)?;
    let mut scenes = Vec::new();
    let wanted: Vec<&Reference> = if args.scenes.is_empty() {
        REFERENCES.iter().collect()
    } else {
        args.scenes
            .iter()
            .map(|s| {
                REFERENCES
                    .iter()
                    .find(|r| r.name.eq_ignore_ascii_case(s))
                    .ok_or_else(|| format!("unknown suite scene '{s}' (P1, P2, P3, P4, T7)"))
            })
            .collect::<Result<_, _>>()?
    };
    for reference in wanted {
        scenes.extend(run_scene(reference, &methods, &threads, runs, args)?);
    }
    let tasks = scenes.iter().map(|s| s.muscles).max().unwrap_or(1);
    let report = Report {
        machine: Machine {
            cores: rayon_cores(),
            cpu: cpu_name(),
        },
        sync_us: threads
            .iter()
            .filter(|&&t| t > 1)
            .map(|&t| (t, sync_cost_us(t, tasks)))
            .collect(),
        scenes,
    };
    print_table(&report);
    let json = args.out.join("suite.json");
    std::fs::write(&json, serde_json::to_string_pretty(&report)?)?;
    plot(&report, &args.out)?;
    println!(
        "\nwrote {} and the plots blocks_*.png, scaling.png, speedup.png in {}",
        json.display(),
        args.out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Times one reference scene with every method and thread count: a report
/// per window.
fn run_scene(
    reference: &Reference,
    methods: &[Method],
    threads: &[u32],
    runs: u32,
    args: &SuiteArgs,
) -> Result<Vec<SceneReport>, Box<dyn Error>> {
    let (_, mut solver) = load_solver(reference.path)?;
    solver.settings.iterations = reference.iterations;
    solver.prepare();
    let constraints: usize = solver.muscles().iter().map(|m| m.counts().total()).sum();
    let windows: Vec<(String, u32, u32)> = if reference.windows.is_empty() {
        let (_, work) = active_work(&solver);
        let per_run = (args.work as f64 / work.max(1.0)).clamp(5.0, 240.0) as u32;
        vec![(reference.name.to_string(), 1, per_run * runs)]
    } else {
        reference
            .windows
            .iter()
            .map(|w| (format!("{} {}", reference.name, w.name), w.from, w.frames))
            .collect()
    };
    let colorings = vec![
        coloring(&solver, PlanKind::PerConstraint, "per muscle (thesis)"),
        coloring(&solver, PlanKind::Clustered, "clustered (global)"),
        coloring(
            &solver,
            PlanKind::Hybrid {
                min_group: args.min_group,
            },
            "hybrid",
        ),
    ];
    let mut reports: Vec<SceneReport> = windows
        .iter()
        .map(|(name, from, frames)| SceneReport {
            name: name.clone(),
            source: reference.path.into(),
            from_frame: *from,
            muscles: solver.muscles().len(),
            constraints,
            active_constraints: 0.0,
            iterations: reference.iterations,
            frames_per_run: (frames / runs).max(1),
            runs,
            thesis_ms: THESIS_METHODS
                .iter()
                .zip(reference.thesis)
                .filter_map(|(n, v)| v.map(|v| (n.to_string(), v)))
                .collect(),
            colorings: colorings.clone(),
            results: Vec::new(),
        })
        .collect();
    for r in &reports {
        eprintln!(
            "{}: {constraints} constraints, {} iterations, frames {}.. in {runs} runs of {}",
            r.name, reference.iterations, r.from_frame, r.frames_per_run
        );
    }
    for &method in methods {
        let method = method.solver_method(args.omega, args.min_group);
        for &t in threads {
            let (_, mut solver) = load_solver(reference.path)?;
            solver.settings.iterations = reference.iterations;
            solver.settings.method = method;
            solver.settings.threads = t;
            let mut frame = 0;
            for report in &mut reports {
                // Untimed up to the window (at least one warm-up frame).
                while frame < report.from_frame.max(1) {
                    solver.step();
                    frame += 1;
                }
                // Each run followed by the reference sweep over its work.
                let reference_threads = if runs_parallel(&solver) { t } else { 1 };
                let mut paired = PairedRuns::default();
                let timed: Vec<_> = (0..runs)
                    .map(|_| {
                        let f = time_frames(&mut solver, report.frames_per_run);
                        paired.push(&f, reference_threads);
                        f
                    })
                    .collect();
                frame += runs * report.frames_per_run;
                let row = result_row(method, t, &timed, &paired);
                eprintln!(
                    "  {:<10} {:<22} {t:>2} threads  {:>9.3} ms/frame  {:>7.0} active  {:>7.1} ns/ci  ×{:.2} reference",
                    report.name,
                    row.method,
                    row.wall_ms,
                    row.active_constraints,
                    row.ns_per_constraint_iteration,
                    row.ratio_to_reference
                );
                report.results.push(row);
            }
        }
    }
    for report in &mut reports {
        report.active_constraints = median(
            report
                .results
                .iter()
                .map(|r| r.active_constraints)
                .collect(),
        );
    }
    Ok(reports)
}

/// The medians of `timed` runs of one configuration on `threads` threads,
/// with the reference sweep timed after each (`paired`).
fn result_row(
    method: SolverMethod,
    threads: u32,
    timed: &[crate::bench::FrameTimes],
    paired: &PairedRuns,
) -> ResultRow {
    let walls: Vec<f64> = timed.iter().map(|f| f.wall).collect();
    let (lo, hi) = walls
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), &w| (lo.min(w), hi.max(w)));
    let wall = median(walls);
    let active = median(timed.iter().map(|f| f.active).collect());
    let work = median(timed.iter().map(|f| f.work).collect());
    let ns = wall * 1e6 / work.max(1.0);
    ResultRow {
        method: method_label(method),
        threads,
        blocks_ms: StepTimings::NAMES
            .iter()
            .enumerate()
            .map(|(k, n)| {
                (
                    n.to_string(),
                    median(timed.iter().map(|f| f.blocks[k]).collect()),
                )
            })
            .collect(),
        wall_ms: wall,
        wall_min_ms: lo,
        wall_max_ms: hi,
        fps: 1e3 / wall,
        active_constraints: active,
        work,
        ns_per_constraint_iteration: ns,
        reference_ns: paired.reference_ns(),
        ratio_to_reference: paired.ratio(),
    }
}

/// The summary table: ours (best method per thread count) next to the thesis.
fn print_table(report: &Report) {
    println!(
        "\n{:<9}{:>13}{:>6}  {:<24}{:>8}{:>11}{:>9}{:>10}{:>9}{:>8}   thesis best",
        "scene",
        "active/all",
        "iter",
        "method",
        "threads",
        "ms/frame",
        "fps",
        "ns/ci",
        "ref ns",
        "×ref"
    );
    for s in &report.scenes {
        let thesis = s
            .thesis_ms
            .iter()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(n, v)| format!("{v:.2} ms ({n})"))
            .unwrap_or_default();
        let mut threads: Vec<u32> = s.results.iter().map(|r| r.threads).collect();
        threads.sort_unstable();
        threads.dedup();
        for t in threads {
            let best = s
                .results
                .iter()
                .filter(|r| r.threads == t)
                .min_by(|a, b| a.wall_ms.total_cmp(&b.wall_ms));
            if let Some(r) = best {
                println!(
                    "{:<9}{:>13}{:>6}  {:<24}{:>8}{:>11.3}{:>9.1}{:>10.2}{:>9.2}{:>8.2}   {thesis}",
                    s.name,
                    format!("{:.0}/{}", r.active_constraints, s.constraints),
                    s.iterations,
                    r.method,
                    t,
                    r.wall_ms,
                    r.fps,
                    r.ns_per_constraint_iteration,
                    r.reference_ns,
                    r.ratio_to_reference
                );
            }
        }
        let sweeps: Vec<String> = s
            .colorings
            .iter()
            .map(|c| format!("{} {} sweeps", c.plan, c.sweeps))
            .collect();
        println!("          colourings: {}", sweeps.join(", "));
    }
    for (t, us) in &report.sync_us {
        println!("sync: one parallel sweep on {t} threads costs {us:.2} µs");
    }
}
