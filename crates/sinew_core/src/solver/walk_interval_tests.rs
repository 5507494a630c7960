//! [`SolverSettings::walk_interval`]: which iterations walk, and how scenes
//! written with the flag it replaced read.

use super::params::FrameParams;
use super::{Parallelism, SolverSettings};

/// The iterations of each substep whose closest data walks, under
/// `interval`, for `substeps` substeps of `iterations`.
fn walking_iterations(interval: u32, iterations: u32, substeps: u32) -> Vec<Vec<u32>> {
    let settings = SolverSettings {
        walk_interval: interval,
        iterations,
        substeps,
        ..SolverSettings::default()
    };
    let frame = FrameParams::new(&settings, 0, Parallelism::default());
    (0..substeps)
        .map(|s| {
            let sub = frame.substep(s);
            (0..iterations)
                .map(|i| sub.iteration(i, iterations))
                .filter(|it| it.closest().walk)
                .map(|it| it.index)
                .collect()
        })
        .collect()
}

/// Closest data walks in each substep's first iteration and every
/// `walk_interval`-th after it (bones were just posed in the first).
#[test]
fn walks_run_in_each_substeps_first_iteration_and_every_interval() {
    assert_eq!(walking_iterations(1, 10, 1), [(0..10).collect::<Vec<_>>()]);
    assert_eq!(walking_iterations(5, 10, 1), [[0, 5]]);
    assert_eq!(walking_iterations(3, 10, 1), [[0, 3, 6, 9]]);
    assert_eq!(walking_iterations(10, 10, 1), [[0]]);
    assert_eq!(walking_iterations(u32::MAX, 10, 1), [[0]]);
    assert_eq!(walking_iterations(2, 4, 2), [[0, 2], [0, 2]]);
}

/// A scene's settings as RON, with `field` set to `value`.
fn read(field: &str, value: &str) -> Result<SolverSettings, ron::error::SpannedError> {
    ron::from_str(&format!("SolverSettings({field}: {value})"))
}

/// `walk_interval` reads a count; the flag it replaced reads as every
/// iteration (`true`) or once per substep (`false`); anything else, and a
/// count of 0, is refused with the setting's name.
#[test]
fn the_former_flag_reads_as_an_interval_and_bad_values_are_refused() {
    assert_eq!(read("walk_interval", "5").unwrap().walk_interval, 5);
    assert_eq!(
        read("walk_every_iteration", "true").unwrap().walk_interval,
        1
    );
    let once = read("walk_every_iteration", "false").unwrap();
    assert_eq!(once.walk_interval, u32::MAX);
    assert!(once.validate().is_ok());
    assert_eq!(SolverSettings::default().walk_interval, 1);
    for bad in ["-1", "5000000000", "1.5", "\"5\""] {
        let error = read("walk_interval", bad).expect_err(bad).to_string();
        assert!(error.contains("true / false"), "{bad}: {error}");
    }
    let zero = read("walk_interval", "0").unwrap().validate();
    let error = zero.expect_err("0 refused").to_string();
    assert!(error.contains("walk_interval"), "{error}");
}
