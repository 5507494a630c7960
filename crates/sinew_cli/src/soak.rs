//! `soak`: a long run that must stay finite, still and flat in memory — a
//! scene held at rest (`--still`) or looping its motion (`--loop-motion`)
//! for tens of thousands of frames. Reports the drift between a reference
//! frame and the end, relative to the scene's size, the guard's faults, and
//! the process's memory at the reference frame and at the end.

use crate::commands::{Result, load_scene};
use std::fmt::Write as _;
use std::process::ExitCode;
use std::time::Instant;

/// What `soak` runs and judges.
#[derive(Clone, Debug, clap::Args)]
pub struct SoakArgs {
    /// Scene file or built-in name.
    pub scene: String,
    /// Frames to run.
    #[arg(long, default_value_t = 100_000, value_parser = clap::value_parser!(u64).range(2..))]
    pub frames: u64,
    /// Frame the drift and memory are measured from (the scene has settled).
    #[arg(long, default_value_t = 1_000, value_parser = clap::value_parser!(u64).range(1..))]
    pub reference: u64,
    /// Hold every track, joint motion and activation curve at its first
    /// value: the scene at rest, where the drift is judged.
    #[arg(long, conflicts_with = "loop_motion")]
    pub still: bool,
    /// Loop the scene's motion: the clock goes back to 0 two seconds after
    /// the last motion key.
    #[arg(long)]
    pub loop_motion: bool,
    /// Largest drift at rest from the reference frame to the end, as a
    /// share of the scene's size (the diagonal of its muscles' box).
    #[arg(long, default_value_t = 1e-5, value_parser = crate::args::non_negative)]
    pub max_drift: f32,
    /// Largest growth of the resident memory from the reference frame to
    /// the end, in percent.
    #[arg(long, default_value_t = 5.0, value_parser = crate::args::non_negative)]
    pub max_memory_growth_pct: f32,
}

/// The process's resident memory and its peak (`VmRSS`, `VmHWM` in
/// `/proc/self/status`), in KiB; `None` where the system has no such file.
pub(crate) fn memory_kib() -> Option<(u64, u64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}

fn surface(solver: &sinew_core::Solver) -> Vec<sinew_core::glam::Vec3> {
    solver
        .muscles()
        .iter()
        .flat_map(|m| m.surface_positions().iter().copied())
        .collect()
}

/// Runs the soak and prints its report; non-zero exit when a figure fails.
pub fn run(args: &SoakArgs) -> Result<ExitCode> {
    let (mut scene, base) = load_scene(&args.scene)?;
    if args.still {
        scene.hold_first_pose();
    }
    let period = scene.motion_end() + 2.0;
    let mut solver = scene.instantiate(&base)?;
    let reference_frame = args.reference.min(args.frames - 1);
    let start = Instant::now();
    let mut reference = None;
    for frame in 1..=args.frames {
        solver.step();
        if args.loop_motion && solver.time() >= period {
            solver.set_time(solver.time() - period);
        }
        if frame == reference_frame {
            reference = Some((surface(&solver), memory_kib()));
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let (at_reference, memory_reference) = reference.expect("the reference frame was run");
    let end = surface(&solver);
    let memory_end = memory_kib();
    let (lo, hi) = at_reference.iter().fold(
        (
            sinew_core::glam::Vec3::INFINITY,
            sinew_core::glam::Vec3::NEG_INFINITY,
        ),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let size = (hi - lo).length();
    let (worst, drift) = at_reference
        .iter()
        .zip(&end)
        .map(|(a, b)| a.distance(*b))
        .enumerate()
        .fold(
            (0, 0.0f32),
            |best, (i, d)| if d > best.1 { (i, d) } else { best },
        );
    // The muscle and vertex that drifted most.
    let (mut muscle, mut vertex) = (0, worst);
    while let Some(m) = solver.muscles().get(muscle)
        && vertex >= m.surface_positions().len()
    {
        vertex -= m.surface_positions().len();
        muscle += 1;
    }
    let worst_name = solver.muscles().get(muscle).map_or("", |m| m.name.as_str());
    let relative = drift / size;
    let finite = end.iter().all(|p| p.is_finite());
    let (faults, first) = solver.fault_history();
    let mut out = String::new();
    writeln!(
        out,
        "scene {}: {} frames ({:.0} s simulated{}) in {seconds:.1} s",
        scene.name,
        args.frames,
        args.frames as f32 * solver.settings.step_time(),
        if args.still {
            ", held still"
        } else if args.loop_motion {
            ", motion looped"
        } else {
            ""
        }
    )?;
    let mut failed = Vec::new();
    writeln!(
        out,
        "finite      {}  {faults} fault(s){}",
        if finite && faults == 0 {
            "ok  "
        } else {
            "FAIL"
        },
        first.map_or(String::new(), |f| format!("; first: {f}"))
    )?;
    if !finite || faults > 0 {
        failed.push("finite");
    }
    let drift_ok = relative <= args.max_drift;
    writeln!(
        out,
        "drift       {}  {:.3e} m ({worst_name} vertex {vertex}) from frame {reference_frame} to {} = {relative:.2e} of the scene's size ({size:.3} m; limit {:.0e}{})",
        match (args.still, drift_ok) {
            (false, _) => "-   ",
            (true, true) => "ok  ",
            (true, false) => "FAIL",
        },
        drift,
        args.frames,
        args.max_drift,
        if args.still {
            ""
        } else {
            ", judged with --still"
        }
    )?;
    if args.still && !drift_ok {
        failed.push("drift");
    }
    match (memory_reference, memory_end) {
        (Some((rss_a, peak_a)), Some((rss_b, peak_b))) => {
            let growth = 100.0 * (rss_b as f64 - rss_a as f64) / rss_a as f64;
            let ok = growth <= f64::from(args.max_memory_growth_pct);
            writeln!(
                out,
                "memory      {}  resident {:.1} MiB at frame {reference_frame}, {:.1} MiB at {} ({growth:+.1} %); peak {:.1} / {:.1} MiB",
                if ok { "ok  " } else { "FAIL" },
                rss_a as f64 / 1024.0,
                rss_b as f64 / 1024.0,
                args.frames,
                peak_a as f64 / 1024.0,
                peak_b as f64 / 1024.0
            )?;
            if !ok {
                failed.push("memory");
            }
        }
        _ => writeln!(out, "memory      -     not measured (no /proc/self/status)")?,
    }
    print!("{out}");
    if failed.is_empty() {
        println!("soak passed");
        Ok(ExitCode::SUCCESS)
    } else {
        println!("soak FAILED: {}", failed.join(", "));
        Ok(ExitCode::FAILURE)
    }
}
