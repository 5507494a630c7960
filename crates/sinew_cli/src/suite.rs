//! `sinew suite`: the thesis' timing tables side by side with ours.
//!
//! For each scene (P1, P2, P3, P4 = the 17-muscle arm at 5 iterations, T7 =
//! the full body at 10), each method and each thread count: per-block
//! ms/frame (median of the runs after a warm-up frame), fps, ns per
//! constraint-iteration, and in the same run a bare XPBD distance loop over
//! the same constraint count with the ratio to it. Also the colour counts
//! and group-size distribution of each colouring (the thesis' Appendix A)
//! and the measured cost of one parallel sweep's synchronisation. Writes
//! `suite.json` and PNG plots into the output folder.

use crate::bench::{Method, bare_kernel_ns, median, rayon_cores, time_frames};
use crate::commands::load_solver;
use plotters::prelude::*;
use serde::Serialize;
use sinew_core::solver::coloring::{ColorPlan, PlanKind};
use sinew_core::{Solver, SolverMethod, StepTimings};
use std::error::Error;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

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
    /// Simulated work per run, in constraint-iterations (sets the frame count).
    #[arg(long, default_value_t = 3_000_000)]
    pub work: u64,
}

/// A reference scene of the thesis: where it lives and how it was timed.
struct Reference {
    name: &'static str,
    path: &'static str,
    iterations: u32,
    /// The thesis' ms/frame: SST, SMT-J, SMT-G, SMT-G* (Tab 7.5, 7.8).
    thesis: [Option<f64>; 4],
}

const REFERENCES: [Reference; 5] = [
    Reference {
        name: "P1",
        path: "P1",
        iterations: 5,
        thesis: [Some(11.32), Some(7.30), Some(14.36), Some(8.28)],
    },
    Reference {
        name: "P2",
        path: "P2",
        iterations: 5,
        thesis: [Some(24.57), Some(12.89), Some(30.80), Some(13.37)],
    },
    Reference {
        name: "P3",
        path: "P3",
        iterations: 5,
        thesis: [Some(71.49), Some(32.74), Some(69.38), Some(26.26)],
    },
    Reference {
        name: "P4",
        path: "assets/scenes/t5.ron",
        iterations: 5,
        thesis: [Some(531.92), Some(198.96), Some(406.68), Some(152.49)],
    },
    Reference {
        name: "T7",
        path: "assets/scenes/t7.ron",
        iterations: 10,
        thesis: [Some(1414.0), Some(685.0), Some(1138.0), None],
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

#[derive(Serialize)]
struct SceneReport {
    name: String,
    source: String,
    muscles: usize,
    constraints: usize,
    iterations: u32,
    frames_per_run: u32,
    runs: u32,
    /// The thesis' ms/frame per method name.
    thesis_ms: Vec<(String, f64)>,
    /// The bare distance loop, ns per constraint-iteration.
    bare_kernel_ns: f64,
    colorings: Vec<ColoringReport>,
    results: Vec<ResultRow>,
}

#[derive(Serialize)]
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

#[derive(Serialize)]
struct ResultRow {
    method: String,
    threads: u32,
    /// Per-block ms/frame, named as [`StepTimings::NAMES`].
    blocks_ms: Vec<(String, f64)>,
    wall_ms: f64,
    wall_min_ms: f64,
    wall_max_ms: f64,
    fps: f64,
    ns_per_constraint_iteration: f64,
    ratio_to_bare: f64,
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
        let (_, mut solver) = load_solver(reference.path)?;
        solver.settings.iterations = reference.iterations;
        solver.prepare();
        let constraints: usize = solver.muscles().iter().map(|m| m.counts().total()).sum();
        let work = constraints as u64 * reference.iterations as u64;
        let frames = (args.work / work.max(1)).clamp(5, 240) as u32;
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
        eprintln!(
            "{}: {constraints} constraints, {} iterations, {frames} frames × {runs} runs",
            reference.name, reference.iterations
        );
        let bare = bare_kernel_ns(constraints, reference.iterations as usize);
        let mut results = Vec::new();
        for &method in &methods {
            let method = method.solver_method(args.omega, args.min_group);
            for &t in &threads {
                let (_, mut solver) = load_solver(reference.path)?;
                solver.settings.iterations = reference.iterations;
                solver.settings.method = method;
                solver.settings.threads = t;
                solver.step();
                let mut blocks: Vec<Vec<f64>> = vec![Vec::new(); 7];
                let mut walls = Vec::new();
                for _ in 0..runs {
                    let (b, wall) = time_frames(&mut solver, frames);
                    for (k, v) in b.iter().enumerate() {
                        blocks[k].push(*v);
                    }
                    walls.push(wall);
                }
                let (lo, hi) = walls
                    .iter()
                    .fold((f64::MAX, 0.0f64), |(lo, hi), &w| (lo.min(w), hi.max(w)));
                let wall = median(walls);
                let ns = wall * 1e6 / work.max(1) as f64;
                let row = ResultRow {
                    method: method_label(method),
                    threads: t,
                    blocks_ms: StepTimings::NAMES
                        .iter()
                        .zip(blocks)
                        .map(|(n, v)| (n.to_string(), median(v)))
                        .collect(),
                    wall_ms: wall,
                    wall_min_ms: lo,
                    wall_max_ms: hi,
                    fps: 1e3 / wall,
                    ns_per_constraint_iteration: ns,
                    ratio_to_bare: ns / bare,
                };
                eprintln!(
                    "  {:<22} {t:>2} threads  {wall:>9.3} ms/frame  {:>7.1} fps  {ns:>7.1} ns/ci  ×{:.2} bare",
                    row.method, row.fps, row.ratio_to_bare
                );
                results.push(row);
            }
        }
        scenes.push(SceneReport {
            name: reference.name.into(),
            source: reference.path.into(),
            muscles: solver.muscles().len(),
            constraints,
            iterations: reference.iterations,
            frames_per_run: frames,
            runs,
            thesis_ms: THESIS_METHODS
                .iter()
                .zip(reference.thesis)
                .filter_map(|(n, v)| v.map(|v| (n.to_string(), v)))
                .collect(),
            bare_kernel_ns: bare,
            colorings,
            results,
        });
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

/// The summary table: ours (best method per thread count) next to the thesis.
fn print_table(report: &Report) {
    println!(
        "\n{:<5}{:>12}{:>6}  {:<24}{:>8}{:>11}{:>9}{:>10}{:>8}   thesis best",
        "scene", "constraints", "iter", "method", "threads", "ms/frame", "fps", "ns/ci", "×bare"
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
                    "{:<5}{:>12}{:>6}  {:<24}{:>8}{:>11.3}{:>9.1}{:>10.1}{:>8.2}   {thesis}",
                    s.name,
                    s.constraints,
                    s.iterations,
                    r.method,
                    t,
                    r.wall_ms,
                    r.fps,
                    r.ns_per_constraint_iteration,
                    r.ratio_to_bare
                );
            }
        }
        let sweeps: Vec<String> = s
            .colorings
            .iter()
            .map(|c| format!("{} {} sweeps", c.plan, c.sweeps))
            .collect();
        println!("      colourings: {}", sweeps.join(", "));
    }
    for (t, us) in &report.sync_us {
        println!("sync: one parallel sweep on {t} threads costs {us:.2} µs");
    }
}

const PALETTE: [RGBColor; 7] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(127, 127, 127),
];

/// The thesis' methods' lines, in [`THESIS_METHODS`] order.
const THESIS_COLORS: [RGBColor; 4] = [
    RGBColor(0, 0, 0),
    RGBColor(110, 110, 110),
    RGBColor(170, 170, 170),
    RGBColor(200, 140, 20),
];

/// A method's label short enough for a bar.
fn short_label(method: &str) -> String {
    let word = |w: &str| method.split_whitespace().any(|m| m == w);
    match method.split_whitespace().next().unwrap_or("") {
        "Colored" if word("Global") => "Col/G".into(),
        "Colored" => "Col/M".into(),
        "Sequential" => "Seq".into(),
        "Jacobi" => "Jac".into(),
        "Hybrid" => "Hyb".into(),
        other => other.into(),
    }
}

/// Registers the plot font (plotters draws text with `ab_glyph`, no system fonts).
fn register_font() -> Result<(), Box<dyn Error>> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::UBUNTU_LIGHT,
    )
    .map_err(|_| "the plot font could not be loaded".into())
}

fn plot(report: &Report, out: &Path) -> Result<(), Box<dyn Error>> {
    register_font()?;
    for s in &report.scenes {
        plot_blocks(s, &out.join(format!("blocks_{}.png", s.name)))?;
    }
    plot_scaling(report, &out.join("scaling.png"))?;
    plot_speedup(report, &out.join("speedup.png"))?;
    Ok(())
}

/// Stacked per-block ms/frame, one bar per (method, threads).
fn plot_blocks(s: &SceneReport, path: &Path) -> Result<(), Box<dyn Error>> {
    let root = BitMapBackend::new(path, (1200, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let top = s.results.iter().map(|r| r.wall_ms).fold(0.0, f64::max) * 1.15;
    let labels: Vec<String> = s
        .results
        .iter()
        .map(|r| format!("{} ×{}", short_label(&r.method), r.threads))
        .collect();
    let n = s.results.len();
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "{}: {} constraints, {} iterations — ms/frame by block",
                s.name, s.constraints, s.iterations
            ),
            ("sans-serif", 26),
        )
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.5f64..n as f64 - 0.5, 0.0..top.max(1e-3))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n)
        .x_label_formatter(&|x| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 {
                labels.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .x_label_style(("sans-serif", 15))
        .y_desc("ms/frame")
        .draw()?;
    for (b, name) in StepTimings::NAMES.iter().enumerate() {
        let color = PALETTE[b % PALETTE.len()];
        chart
            .draw_series(s.results.iter().enumerate().map(|(i, r)| {
                let below: f64 = r.blocks_ms[..b].iter().map(|(_, v)| v).sum();
                let x = i as f64;
                Rectangle::new(
                    [(x - 0.35, below), (x + 0.35, below + r.blocks_ms[b].1)],
                    color.filled(),
                )
            }))?
            .label(*name)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], color.filled()));
    }
    legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present()?;
    Ok(())
}

/// The series legend in a framed box.
fn legend<'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, CT>,
    position: SeriesLabelPosition,
) -> Result<(), Box<dyn Error>> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// A labelled polyline with a dot at each point.
fn line_with_points<'a, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, CT>,
    points: Vec<(f64, f64)>,
    color: RGBColor,
    label: impl Into<String>,
) -> Result<(), Box<dyn Error>> {
    chart
        .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
    chart.draw_series(
        points
            .into_iter()
            .map(|p| Circle::new(p, 4, color.filled())),
    )?;
    Ok(())
}

/// Methods in first-seen order.
fn methods_of(report: &Report) -> Vec<String> {
    let mut methods: Vec<String> = Vec::new();
    for r in report.scenes.iter().flat_map(|s| &s.results) {
        if !methods.contains(&r.method) {
            methods.push(r.method.clone());
        }
    }
    methods
}

/// ms/frame against constraint count (log–log), every method at the most
/// threads, with the thesis' SST for reference.
fn plot_scaling(report: &Report, path: &Path) -> Result<(), Box<dyn Error>> {
    let root = BitMapBackend::new(path, (1100, 750)).into_drawing_area();
    root.fill(&WHITE)?;
    let max_threads = report.max_threads();
    let (mut lo_x, mut hi_x) = (f64::MAX, 1.0f64);
    let (mut lo_y, mut hi_y) = (f64::MAX, 1e-3f64);
    for s in &report.scenes {
        lo_x = lo_x.min(s.constraints as f64);
        hi_x = hi_x.max(s.constraints as f64);
        for v in s
            .results
            .iter()
            .map(|r| r.wall_ms)
            .chain(s.thesis_ms.iter().map(|t| t.1))
        {
            lo_y = lo_y.min(v);
            hi_y = hi_y.max(v);
        }
    }
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("ms/frame vs constraints ({max_threads} threads; thesis dashed)"),
            ("sans-serif", 26),
        )
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (lo_x * 0.7..hi_x * 1.4).log_scale(),
            (lo_y * 0.5..hi_y * 2.0).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("constraints")
        .y_desc("ms/frame")
        .draw()?;
    for (i, method) in methods_of(report).iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let points: Vec<(f64, f64)> = report
            .scenes
            .iter()
            .filter_map(|s| {
                s.results
                    .iter()
                    .find(|r| &r.method == method && r.threads == max_threads)
                    .map(|r| (s.constraints as f64, r.wall_ms))
            })
            .collect();
        line_with_points(&mut chart, points, color, method.as_str())?;
    }
    for (k, name) in THESIS_METHODS.iter().enumerate() {
        let points: Vec<(f64, f64)> = report
            .scenes
            .iter()
            .filter_map(|s| {
                s.thesis_ms
                    .iter()
                    .find(|t| t.0 == *name)
                    .map(|t| (s.constraints as f64, t.1))
            })
            .collect();
        let color = THESIS_COLORS[k].mix(0.8);
        chart
            .draw_series(DashedLineSeries::new(points, 6, 4, color.stroke_width(2)))?
            .label(format!("thesis {name}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}

/// Speed-up over one thread against the thread count, per scene (its best
/// method at one thread).
fn plot_speedup(report: &Report, path: &Path) -> Result<(), Box<dyn Error>> {
    let root = BitMapBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let max_threads = report.max_threads() as f64;
    let mut series = Vec::new();
    for s in &report.scenes {
        let best = s
            .results
            .iter()
            .filter(|r| r.threads == 1)
            .min_by(|a, b| a.wall_ms.total_cmp(&b.wall_ms));
        let Some(best) = best else { continue };
        let points: Vec<(f64, f64)> = s
            .results
            .iter()
            .filter(|r| r.method == best.method)
            .map(|r| (r.threads as f64, best.wall_ms / r.wall_ms))
            .collect();
        series.push((format!("{} ({})", s.name, best.method), points));
    }
    let top = series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.1))
        .fold(max_threads, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption("speed-up over 1 thread (ideal dashed)", ("sans-serif", 26))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5..max_threads + 0.5, 0.0..top * 1.1)?;
    chart
        .configure_mesh()
        .x_desc("threads")
        .y_desc("speed-up")
        .draw()?;
    chart.draw_series(DashedLineSeries::new(
        vec![(1.0, 1.0), (max_threads, max_threads)],
        6,
        4,
        BLACK.mix(0.5).stroke_width(1),
    ))?;
    for (i, (label, points)) in series.into_iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        line_with_points(&mut chart, points, color, label)?;
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present()?;
    Ok(())
}
