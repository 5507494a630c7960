//! `check`'s per-muscle tables: volume, activation, attachment and
//! penetration; shape and rest; and, with `--residuals`, what one more
//! projection of each constraint type would move.

use super::Result;
use sinew_core::analysis::{ResidualsAtWorst, RunMetrics};
use std::fmt::Write as _;

/// Per muscle: volume, activation and bulge, attachment and penetration;
/// then shape and rest.
pub(super) fn muscle_tables(
    out: &mut String,
    metrics: &RunMetrics,
    solver: &sinew_core::Solver,
) -> Result<()> {
    writeln!(
        out,
        "{:<12}{:>9}{:>9}{:>9}{:>11}{:>10}{:>12}{:>11}{:>14}{:>10}{:>9}",
        "muscle",
        "vol min",
        "vol max",
        "act max",
        "section×",
        "at act",
        "attach mm",
        "inside %",
        "span×",
        "forced×",
        "crossed"
    )?;
    for (i, m) in solver.muscles().iter().enumerate() {
        let (lo, hi) = metrics.volume_ratio[i];
        let (a, section) = metrics.section_at_peak[i];
        let span = metrics.attachment_span[i]
            .map_or("-".to_string(), |(lo, hi)| format!("{lo:.2}–{hi:.2}"));
        let forced = metrics.forced_strain_max[i].map_or("-".to_string(), |s| format!("{s:.2}"));
        writeln!(
            out,
            "{:<12}{:>9.3}{:>9.3}{:>9.2}{:>11.3}{:>10.2}{:>12.2}{:>11.2}{:>14}{:>10}{:>9}",
            m.name,
            lo,
            hi,
            metrics.activation_max[i],
            section,
            a,
            metrics.muscle_attachment_max[i] * 1e3,
            metrics.muscle_penetration_max[i] * 100.0,
            span,
            forced,
            m.mesh.self_crossings(&m.rest)
        )?;
    }
    writeln!(
        out,
        "{:<12}{:>8}{:>8}{:>8}{:>8}{:>9}{:>11}{:>10}{:>10}{:>10}",
        "muscle", "strain", "p1", "p99", "max", "flipped", "v mm/s", "KE J", "jiggle", "dev mm"
    )?;
    let motion = metrics.recent_motion();
    let deviation = metrics.rest_deviation(solver);
    for (i, m) in solver.muscles().iter().enumerate() {
        let s = metrics.strain[i];
        writeln!(
            out,
            "{:<12}{:>8.3}{:>8.3}{:>8.3}{:>8.3}{:>9}{:>11.3}{:>10.2e}{:>10.4}{:>10.3}",
            m.name,
            s.min.0,
            s.p1.0,
            s.p99.0,
            s.max.0,
            metrics.flipped_max[i].0,
            motion[i].rms_velocity() * 1e3,
            motion[i].mean_kinetic_energy(),
            motion[i].rms_acceleration(),
            deviation[i].max * 1e3
        )?;
    }
    writeln!(
        out,
        "(span: distance between the muscle's two farthest attachment groups over its rest value, extremes over the run: the mean strain along a straight line between them; forced: the largest, over the run, of an attached pair's distance over its shortest rest path along the mesh's edges (pairs on different bones): the largest edge strain is at least this, whatever the solver does; crossed: pairs of the rest surface's triangles that pass through each other (a surface crumpled into itself at rest: its strain is measured against edges that must stretch many times over to straighten); strain: edge length / rest length, extremes over the run; v, KE and jiggle: the last second, in the first attached bone's frame; dev: distance from the rest shape now)"
    )?;
    Ok(())
}

/// Per muscle, at the frame of its worst edge strain: the largest surface
/// displacement one more projection of each constraint type alone would
/// make (the types that move some muscle by a micrometre or more).
pub(super) fn residual_table(
    out: &mut String,
    residuals: &ResidualsAtWorst,
    solver: &sinew_core::Solver,
) -> Result<()> {
    let order = &solver.settings.projection_order;
    let shown: Vec<usize> = (0..order.len())
        .filter(|&k| {
            residuals
                .muscles
                .iter()
                .flatten()
                .any(|(_, _, r)| r[k].max >= 1e-6)
        })
        .collect();
    write!(out, "{:<12}{:>7}{:>8}", "muscle", "frame", "strain")?;
    for &k in &shown {
        write!(out, "{:>10}", order[k].label())?;
    }
    writeln!(out, "   largest at")?;
    for (m, worst) in solver.muscles().iter().zip(&residuals.muscles) {
        let Some((frame, strain, r)) = worst else {
            continue;
        };
        write!(out, "{:<12}{frame:>7}{strain:>8.3}", m.name)?;
        for &k in &shown {
            write!(out, "{:>10.2}", r[k].max * 1e3)?;
        }
        let top = shown
            .iter()
            .map(|&k| &r[k])
            .max_by(|a, b| a.max.total_cmp(&b.max));
        match top {
            Some(top) => writeln!(out, "   {} vertex {}", top.kind.label(), top.vertex)?,
            None => writeln!(out)?,
        }
    }
    writeln!(
        out,
        "(residuals: at each muscle's worst edge strain, how far one more projection of each constraint type on its own, in the projection order, would move its surface, largest over its vertices in mm: two or more types reading millimetres at the same vertices is a shape held between constraints that cannot all hold)"
    )?;
    Ok(())
}
