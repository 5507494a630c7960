//! `check`: run a scene and report the figures the anatomy scenes are judged
//! by (finiteness, attachment error, penetration, volume, activation, bulge).

use crate::bench::Overrides;
use crate::commands::{load_solver, write_stdout};
use sinew_core::analysis::RunMetrics;
use std::error::Error;
use std::fmt::Write as _;
use std::process::ExitCode;
use std::time::Instant;

type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// Runs `frames` frames (default: the scene's) and prints the report.
/// `every` checks penetration on every n-th frame.
pub fn run(
    scene: &str,
    frames: Option<u32>,
    every: u32,
    depth_mm: f32,
    overrides: Overrides,
) -> Result<ExitCode> {
    let (scene, mut solver) = load_solver(scene)?;
    overrides.apply(&mut solver);
    let frames = frames.unwrap_or(scene.frames.max(1));
    let mut metrics = RunMetrics::new(&solver, depth_mm * 1e-3);
    metrics.penetration_every = every.max(1);
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
    let seconds = start.elapsed().as_secs_f64();
    let mut out = String::new();
    writeln!(
        out,
        "scene {}: {frames} frames in {seconds:.1} s",
        scene.name
    )?;
    match metrics.first_non_finite {
        None => writeln!(out, "finite                 yes (every frame)")?,
        Some(f) => writeln!(out, "finite                 NO: first NaN/inf at frame {f}")?,
    }
    writeln!(
        out,
        "attachment error       mean {:.3} mm, max {:.3} mm",
        metrics.attachment_error_mean() * 1e3,
        metrics.attachment_error_max * 1e3
    )?;
    writeln!(
        out,
        "jiggle                 {:.3} m/s² RMS surface acceleration in the bone frame",
        metrics.jiggle_rms()
    )?;
    writeln!(
        out,
        "penetration > {depth_mm} mm     max {:.2} % of surface vertices (frame {}, checked every {} frame(s))",
        metrics.penetration_max * 100.0,
        metrics.penetration_frame,
        metrics.penetration_every
    )?;
    writeln!(
        out,
        "{:<12}{:>9}{:>9}{:>9}{:>9}{:>11}{:>10}{:>12}{:>11}",
        "muscle",
        "vol min",
        "vol max",
        "allowed",
        "act max",
        "section×",
        "at act",
        "attach mm",
        "inside %"
    )?;
    let mut within = true;
    for (i, m) in solver.muscles().iter().enumerate() {
        let (lo, hi) = metrics.volume_ratio[i];
        let gain = f64::from(m.params.volume.gain * m.params.volume.activation_gain.max(1.0));
        let ok = lo >= 0.95 && hi <= gain * 1.05;
        within &= ok;
        let (a, section) = metrics.section_at_peak[i];
        writeln!(
            out,
            "{:<12}{:>9.3}{:>9.3}{:>9}{:>9.2}{:>11.3}{:>10.2}{:>12.2}{:>11.2}",
            m.name,
            lo,
            hi,
            format!("{:.2}{}", gain * 1.05, if ok { "" } else { "!" }),
            metrics.activation_max[i],
            section,
            a,
            metrics.muscle_attachment_max[i] * 1e3,
            metrics.muscle_penetration_max[i] * 100.0
        )?;
    }
    writeln!(
        out,
        "volume                 {} muscles within [0.95, gain × 1.05]",
        if within { "all" } else { "NOT all" }
    )?;
    for (name, value, velocity) in &sensor_ranges {
        writeln!(
            out,
            "sensor {name:<15} value [{:.3}, {:.3}]  velocity [{:.2}, {:.2}]",
            value[0], value[1], velocity[0], velocity[1]
        )?;
    }
    write_stdout(&out)?;
    Ok(if metrics.first_non_finite.is_none() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
