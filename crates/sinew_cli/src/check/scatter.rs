//! `check --perturb N`: the scatter of the judged figures over runs whose
//! time step is nudged by a few units in the last place.
//!
//! Nudging the time step by one ulp changes the bits of every vertex that
//! moves freely (every step multiplies by it; a pinned vertex or one held
//! on a plane keeps its coordinates) and nothing of the physics: the
//! figures then scatter as much as a run's chaotic parts (contacts, folds)
//! let them. A change that alters the bits (another order of operations,
//! one square root fewer) is within that scatter when its figures fall in
//! the ranges the nudged runs of the build before gave; a change of
//! physics falls outside.

use sinew_core::analysis::{Measured, Verdict};
use std::fmt::{self, Write as _};

/// The nudges of `n` runs, in ulps: +1, −1, +2, −2, …
pub(super) fn nudges(n: u32) -> impl Iterator<Item = i32> {
    (1..=n as i32).map(|k| {
        let step = (k + 1) / 2;
        if k % 2 == 1 { step } else { -step }
    })
}

/// `dt` moved by `ulps` units in the last place (up for positive).
pub(super) fn nudged(dt: f32, ulps: i32) -> f32 {
    let step = if ulps > 0 {
        f32::next_up
    } else {
        f32::next_down
    };
    (0..ulps.unsigned_abs()).fold(dt, |t, _| step(t))
}

/// Writes each figure's range over `runs` (the nudge in ulps and the
/// verdicts of each; the scene's time step `dt` in seconds) into `out`:
/// how many runs it passed in, and the smallest and largest of each of
/// its numbers.
pub(super) fn table(out: &mut String, dt: f32, runs: &[(i32, Vec<Verdict>)]) -> fmt::Result {
    let nudges: Vec<String> = runs
        .iter()
        .map(|(ulps, _)| match ulps {
            0 => "as it is".to_string(),
            u => format!("{u:+} ulp"),
        })
        .collect();
    writeln!(
        out,
        "scatter over {} runs, the time step ({dt} s) {} (the bits change, the physics does not):",
        runs.len(),
        nudges.join(", ")
    )?;
    writeln!(out, "{:<19}{:<9}range over the runs", "figure", "passed")?;
    let Some((_, first)) = runs.first() else {
        return Ok(());
    };
    for (k, verdict) in first.iter().enumerate() {
        let same = runs.iter().filter_map(|(_, v)| v.get(k));
        let judged: Vec<bool> = same.clone().filter_map(|v| v.pass).collect();
        let passed = match judged.len() {
            0 => "-".to_string(),
            n => format!("{} of {n}", judged.iter().filter(|&&p| p).count()),
        };
        let ranges = ranges(same.map(|v| v.measured.as_slice()));
        writeln!(out, "{:<19}{passed:<9}{ranges}", verdict.figure)?;
    }
    Ok(())
}

/// `lo–hi` of each number over the runs' lists (matched by position; a
/// run that measured fewer adds nothing to the rest), with its name and
/// unit: `min 0.612–0.640, max 1.504–1.582`, `0.412–0.433 mm`.
fn ranges<'a>(lists: impl Iterator<Item = &'a [Measured]>) -> String {
    let mut spans: Vec<(Measured, f64, f64)> = Vec::new();
    for list in lists {
        for (i, m) in list.iter().enumerate() {
            match spans.get_mut(i) {
                Some((_, lo, hi)) => (*lo, *hi) = (lo.min(m.value), hi.max(m.value)),
                None => spans.push((*m, m.value, m.value)),
            }
        }
    }
    if spans.is_empty() {
        return "-".to_string();
    }
    let span = |(m, lo, hi): &(Measured, f64, f64)| {
        let text = format!("{}–{} {}", number(*lo), number(*hi), m.unit);
        format!("{} {}", m.name, text.trim_end()).trim().to_string()
    };
    spans.iter().map(span).collect::<Vec<_>>().join(", ")
}

/// A count as it is; any other value to four significant digits.
fn number(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 {
        format!("{x:.0}")
    } else {
        let digits = 3 - x.abs().log10().floor().clamp(-9.0, 3.0) as i32;
        format!("{x:.*}", digits.max(0) as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The nudges alternate up and down, growing by one ulp each pair, and
    /// each moves the time step by exactly that many representable values.
    #[test]
    fn nudges_step_the_time_step_by_whole_ulps_both_ways() {
        assert_eq!(nudges(5).collect::<Vec<_>>(), [1, -1, 2, -2, 3]);
        assert_eq!(nudges(0).count(), 0);
        let dt = 1.0f32 / 60.0;
        assert_eq!(nudged(dt, 0), dt);
        assert_eq!(nudged(dt, 1).to_bits(), dt.to_bits() + 1);
        assert_eq!(nudged(dt, -2).to_bits(), dt.to_bits() - 2);
        assert_eq!(nudged(dt, 3).to_bits(), dt.to_bits() + 3);
    }

    /// The premise of the scatter: P3 (under gravity, sagging onto its
    /// plane) with its time step one ulp up changes the bits of most
    /// coordinates within 60 frames (not those of pinned vertices and of
    /// vertices held on the plane), and moves none by a micrometre.
    #[test]
    fn a_nudged_time_step_changes_the_bits_and_not_the_physics() {
        let run = |ulps: i32| -> Vec<sinew_core::glam::Vec3> {
            let mut scene = sinew_core::scene::builtin("P3").expect("a built-in scene");
            scene.settings.dt = nudged(scene.settings.dt, ulps);
            let mut solver = scene.instantiate(std::path::Path::new(".")).unwrap();
            for _ in 0..60 {
                solver.step();
            }
            solver.muscles().iter().flat_map(|m| m.x.clone()).collect()
        };
        let (as_is, nudged_up) = (run(0), run(1));
        assert_eq!(as_is.len(), nudged_up.len());
        let coordinates = |p: &[sinew_core::glam::Vec3]| -> Vec<u32> {
            p.iter()
                .flat_map(|x| x.to_array().map(f32::to_bits))
                .collect()
        };
        let (a, b) = (coordinates(&as_is), coordinates(&nudged_up));
        let changed = a.iter().zip(&b).filter(|(a, b)| a != b).count();
        assert!(changed * 2 > a.len(), "{changed} of {}", a.len());
        let moved = as_is
            .iter()
            .zip(&nudged_up)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max);
        assert!(moved < 1e-6, "{moved} m");
    }

    fn verdict(figure: &'static str, pass: Option<bool>, measured: Vec<Measured>) -> Verdict {
        Verdict {
            figure,
            value: String::new(),
            measured,
            limit: String::new(),
            pass,
        }
    }

    /// Each number's smallest and largest over the runs, with its name and
    /// unit; the passes counted over the runs that judged the figure.
    #[test]
    fn the_table_gives_each_numbers_range_and_the_passes() {
        let run = |strain_max: f64, flipped: f64, pass: bool| {
            vec![
                verdict(
                    "edge strain",
                    Some(true),
                    vec![
                        Measured::new("min", 0.62, ""),
                        Measured::new("max", strain_max, ""),
                    ],
                ),
                verdict(
                    "flipped triangles",
                    Some(pass),
                    vec![Measured::new("", flipped, "")],
                ),
                verdict("rest jiggle", None, vec![Measured::new("", 0.01, "m/s²")]),
            ]
        };
        let runs = [
            (0, run(1.5, 127.0, true)),
            (1, run(1.583, 135.0, false)),
            (-1, run(1.51, 130.0, true)),
        ];
        let mut out = String::new();
        table(&mut out, 0.016666668, &runs).unwrap();
        let lines: Vec<&str> = out.lines().collect();
        assert!(lines[0].contains("3 runs") && lines[0].contains("+1 ulp, -1 ulp"));
        assert!(
            lines[2].ends_with("3 of 3   min 0.6200–0.6200, max 1.500–1.583"),
            "{}",
            lines[2]
        );
        assert!(lines[3].ends_with("2 of 3   127–135"), "{}", lines[3]);
        assert!(
            lines[4].ends_with("-        0.01000–0.01000 m/s²"),
            "{}",
            lines[4]
        );
    }
}
