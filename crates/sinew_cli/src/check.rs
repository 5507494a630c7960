//! `check`: run a scene and judge the figures it is held to — finiteness,
//! attachment, penetration, volume, shape (edge strain, flipped triangles)
//! and, once the motion has stopped, rest (velocity, jiggle, deviation from
//! the rest shape). Exits non-zero when a judged figure is out of range.

use crate::bench::Overrides;
use crate::commands::{load_scene, write_stdout};
use sinew_core::Solver;
use sinew_core::analysis::{ResidualsAtWorst, RunMetrics, Thresholds, Verdict};
use sinew_core::scene::Scene;
use std::error::Error;
use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

mod scatter;
mod tables;

type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// The ranges `check` judges against (see [`Thresholds`] for the meaning
/// of each).
#[derive(Clone, Copy, Debug, clap::Args)]
pub struct Limits {
    /// Largest attachment error, in millimetres.
    #[arg(long, default_value_t = 1.0, value_parser = crate::args::non_negative)]
    pub max_attachment_mm: f32,
    /// Largest share of surface vertices inside a bone in a checked frame, in percent.
    #[arg(long, default_value_t = 2.0, value_parser = crate::args::non_negative)]
    pub max_penetration_pct: f32,
    /// Smallest edge length / rest length in any frame.
    #[arg(long, default_value_t = 0.6, value_parser = crate::args::non_negative)]
    pub min_strain: f32,
    /// Largest edge length / rest length in any frame.
    #[arg(long, default_value_t = 1.6, value_parser = crate::args::non_negative)]
    pub max_strain: f32,
    /// Most flipped (folded or inverted) triangles of a muscle in any frame.
    #[arg(long, default_value_t = 0)]
    pub max_flipped: usize,
    /// At rest: largest RMS surface velocity over the last second, in mm/s.
    #[arg(long, default_value_t = 1.0, value_parser = crate::args::non_negative)]
    pub max_rest_velocity_mm_s: f32,
    /// At rest: largest RMS surface acceleration over the last second, in m/s².
    #[arg(long, default_value_t = 0.1, value_parser = crate::args::non_negative)]
    pub max_rest_jiggle: f32,
    /// At rest: smallest edge length / rest length over the last second.
    #[arg(long, default_value_t = 0.8, value_parser = crate::args::non_negative)]
    pub min_rest_strain: f32,
    /// At rest: largest edge length / rest length over the last second.
    #[arg(long, default_value_t = 1.25, value_parser = crate::args::non_negative)]
    pub max_rest_strain: f32,
    /// At rest: largest vertex distance from its rest position, in millimetres.
    #[arg(long, default_value_t = 3.0, value_parser = crate::args::non_negative)]
    pub max_rest_deviation_mm: f32,
    /// Seconds after the scene's last motion key from which the end of the
    /// run counts as at rest (the rest figures are judged only then).
    #[arg(long, default_value_t = 2.0, value_parser = crate::args::non_negative)]
    pub settle: f32,
    /// Largest share of skin vertices inside a muscle or bone in a checked
    /// frame, in percent (scenes with a skin).
    #[arg(long, default_value_t = 0.5, value_parser = crate::args::non_negative)]
    pub max_skin_inside_pct: f32,
    /// At rest: largest distance of a skin vertex from its skinned
    /// position, in millimetres (scenes with a skin).
    #[arg(long, default_value_t = 2.0, value_parser = crate::args::non_negative)]
    pub max_skin_bind_mm: f32,
    /// Smallest skin bulge over a muscle active at `--bulge-activation` or
    /// more: the skin's largest outward displacement from the plain skinned
    /// surface over it, in millimetres (scenes with a skin).
    #[arg(long, default_value_t = 5.0, value_parser = crate::args::non_negative)]
    pub min_skin_bulge_mm: f32,
    /// Activation from which a muscle's skin bulge is measured (0–1).
    #[arg(long, default_value_t = 0.8, value_parser = crate::args::unit_interval)]
    pub bulge_activation: f32,
}

impl From<Limits> for Thresholds {
    fn from(l: Limits) -> Self {
        Self {
            attachment: l.max_attachment_mm * 1e-3,
            penetration: l.max_penetration_pct * 1e-2,
            strain: [l.min_strain, l.max_strain],
            flipped: l.max_flipped,
            rest_velocity: l.max_rest_velocity_mm_s * 1e-3,
            rest_jiggle: l.max_rest_jiggle,
            rest_strain: [l.min_rest_strain, l.max_rest_strain],
            rest_deviation: l.max_rest_deviation_mm * 1e-3,
            settle: l.settle,
            skin_inside: l.max_skin_inside_pct * 1e-2,
            skin_bind: l.max_skin_bind_mm * 1e-3,
            skin_bulge: l.min_skin_bulge_mm * 1e-3,
            ..Self::default()
        }
    }
}

/// What `check` runs: the scene, its length and what it measures.
#[derive(Clone, Debug, clap::Args)]
pub struct CheckArgs {
    /// Scene file or built-in name.
    pub scene: String,
    /// Frames to simulate (default: the scene's).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Check penetration every N frames (≥ 1).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub every: u32,
    /// Penetration depth counted, in millimetres.
    #[arg(long, default_value_t = 2.0, value_parser = crate::args::non_negative)]
    pub depth_mm: f32,
    /// Hold every bone track, joint motion and activation curve at its first
    /// value: the scene at rest.
    #[arg(long)]
    pub still: bool,
    /// Switch every muscle off: activation 0, no activation curve, no
    /// sensor drive (e.g. with `--still`: the skin at rest with no muscle
    /// active).
    #[arg(long)]
    pub relaxed: bool,
    /// Also list, per muscle at the frame of its worst edge strain, how far
    /// one more projection of each constraint type on its own would move
    /// its surface: which constraints its shape is a compromise between
    /// (slower: each new worst frame projects a copy of the muscle once
    /// per type).
    #[arg(long)]
    pub residuals: bool,
    /// Also run the scene N more times with its time step nudged by one,
    /// two, … units in the last place (up, then down: +1, −1, +2, …),
    /// which changes the bits of every freely moving vertex and nothing of
    /// the physics, and
    /// print each judged figure's range over all the runs: the scatter
    /// that a change which alters the bits is judged against (slower:
    /// N + 1 runs).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub perturb: u32,
    #[command(flatten)]
    pub limits: Limits,
    #[command(flatten)]
    pub overrides: Overrides,
}

/// Runs the scene and prints the report (with `--perturb`, the scatter of
/// its figures over the nudged runs after it); the exit code is non-zero
/// when a judged figure is out of range in any run.
pub fn run(args: &CheckArgs) -> Result<ExitCode> {
    let a = args.limits.bulge_activation;
    if !(0.0..=1.0).contains(&a) {
        return Err(format!("--bulge-activation {a}: an activation is in [0, 1]").into());
    }
    let (scene, base) = load_scene(&args.scene)?;
    let first = simulate(args, &scene, &base, 0)?;
    let mut out = String::new();
    let verdicts = first.report(&mut out, args)?;
    let mut failed = failed_figures(&verdicts, 0, &[]);
    if args.perturb > 0 {
        let mut runs = vec![(0, verdicts)];
        for ulps in scatter::nudges(args.perturb) {
            eprintln!("check: the time step {ulps:+} ulp");
            let run = simulate(args, &scene, &base, ulps)?;
            let verdicts = run.verdicts(args);
            failed.extend(failed_figures(&verdicts, ulps, &runs[0].1));
            runs.push((ulps, verdicts));
        }
        scatter::table(&mut out, scene.settings.dt, &runs)?;
    }
    if failed.is_empty() {
        writeln!(out, "check passed")?;
    } else {
        writeln!(out, "check FAILED: {}", failed.join(", "))?;
    }
    write_stdout(&out)?;
    Ok(if failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// The figures of `verdicts` that failed, named with the nudge of their
/// run where it was nudged, but for those that failed in `as_is` too (the
/// run as it is names them once).
fn failed_figures(verdicts: &[Verdict], ulps: i32, as_is: &[Verdict]) -> Vec<String> {
    let failed_as_is = |figure| {
        as_is
            .iter()
            .any(|v| v.figure == figure && v.pass == Some(false))
    };
    let failed = verdicts
        .iter()
        .filter(|v| v.pass == Some(false) && !failed_as_is(v.figure));
    match ulps {
        0 => failed.map(|v| v.figure.to_string()).collect(),
        _ => failed
            .map(|v| format!("{} (time step {ulps:+} ulp)", v.figure))
            .collect(),
    }
}

/// One simulated run: the solver at its end and what was measured.
struct CheckRun {
    scene: Scene,
    solver: Solver,
    frames: u32,
    metrics: RunMetrics,
    /// Per sensor: its name and the `[min, max]` of its value and velocity.
    sensor_ranges: Vec<(String, [f32; 2], [f32; 2])>,
    seconds: f64,
}

/// Runs `scene` (loaded, its files relative to `base`) as `args` say, its
/// time step nudged by `ulps` units in the last place (0: as it is).
fn simulate(args: &CheckArgs, scene: &Scene, base: &Path, ulps: i32) -> Result<CheckRun> {
    let mut scene = scene.clone();
    if args.still {
        scene.hold_first_pose();
    }
    if args.relaxed {
        scene.relax_muscles();
    }
    scene.settings.dt = scatter::nudged(scene.settings.dt, ulps);
    let mut solver = scene.instantiate(base)?;
    args.overrides.apply(&mut solver)?;
    let frames = args.frames.unwrap_or(scene.frames.max(1));
    let mut metrics = RunMetrics::new(&solver, args.depth_mm * 1e-3);
    metrics.penetration_every = args.every.max(1);
    metrics.bulge_activation = args.limits.bulge_activation;
    if args.residuals {
        metrics.residuals = Some(ResidualsAtWorst::new(solver.muscles().len()));
    }
    let mut sensor_ranges: Vec<(String, [f32; 2], [f32; 2])> = Vec::new();
    let start = Instant::now();
    for _ in 0..frames {
        solver.step();
        metrics.observe(&solver);
        if let Some(rig) = solver.activation_rig() {
            for (i, (name, [value, velocity, _])) in rig.readings().enumerate() {
                if sensor_ranges.len() <= i {
                    sensor_ranges.push((name.to_string(), [value; 2], [velocity; 2]));
                }
                let r = &mut sensor_ranges[i];
                r.1 = [r.1[0].min(value), r.1[1].max(value)];
                r.2 = [r.2[0].min(velocity), r.2[1].max(velocity)];
            }
        }
    }
    Ok(CheckRun {
        scene,
        solver,
        frames,
        metrics,
        sensor_ranges,
        seconds: start.elapsed().as_secs_f64(),
    })
}

impl CheckRun {
    /// Every figure judged against `args`' limits.
    fn verdicts(&self, args: &CheckArgs) -> Vec<Verdict> {
        let limits = Thresholds::from(args.limits);
        (self.metrics).verdicts(&self.solver, &limits, self.scene.motion_end())
    }

    /// Writes the run's report (every table, then the verdicts) into
    /// `out` and returns the verdicts.
    fn report(&self, out: &mut String, args: &CheckArgs) -> Result<Vec<Verdict>> {
        let (metrics, solver) = (&self.metrics, &self.solver);
        let dt = solver.settings.step_time();
        let motion_end = self.scene.motion_end();
        writeln!(
            out,
            "scene {}: {} frames ({:.2} s simulated, last motion key at {motion_end:.2} s) in {:.1} s",
            self.scene.name,
            self.frames,
            self.frames as f32 * dt,
            self.seconds
        )?;
        writeln!(
            out,
            "jiggle                 {:.3} m/s² RMS surface acceleration in the bone frame (whole run)",
            metrics.jiggle_rms()
        )?;
        tables::muscle_tables(out, metrics, solver)?;
        if let Some(residuals) = &metrics.residuals {
            tables::residual_table(out, residuals, solver)?;
        }
        let muscles = solver.muscles();
        for (b, frame) in &metrics.skin_bulges {
            writeln!(
                out,
                "bulge of {} over {:<12} a {:.2}  max {:.2} mm (vertex {})  median {:.2} mm over {} vertices  (frame {frame})",
                muscles[b.skin].name,
                muscles[b.muscle].name,
                b.activation,
                b.max * 1e3,
                b.vertex,
                b.median * 1e3,
                b.vertices
            )?;
        }
        for (name, value, velocity) in &self.sensor_ranges {
            writeln!(
                out,
                "sensor {name:<15} value [{:.3}, {:.3}]  velocity [{:.2}, {:.2}]",
                value[0], value[1], velocity[0], velocity[1]
            )?;
        }
        let verdicts = self.verdicts(args);
        writeln!(out, "{:<19}{:<6}{:<22}value", "figure", "", "range")?;
        for v in &verdicts {
            let mark = match v.pass {
                Some(true) => "ok",
                Some(false) => "FAIL",
                None => "-",
            };
            writeln!(out, "{:<19}{:<6}{:<22}{}", v.figure, mark, v.limit, v.value)?;
        }
        let settle = args.limits.settle;
        if !metrics.at_rest(solver, motion_end, settle) {
            writeln!(
                out,
                "rest figures not judged: the run ends before {:.2} s (the last motion key + {settle} s settle)",
                motion_end + settle,
            )?;
        }
        Ok(verdicts)
    }
}
