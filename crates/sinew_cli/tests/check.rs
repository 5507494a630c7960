//! `sinew check` judges its figures and says so in its exit code.

use std::process::Command;

fn check(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_sinew"))
        .arg("check")
        .args(args)
        .output()
        .expect("sinew runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

#[test]
fn p3_at_rest_passes_and_an_out_of_range_figure_fails_the_check() {
    let (ok, report) = check(&["P3", "--frames", "600", "--every", "600"]);
    assert!(ok, "{report}");
    assert!(report.contains("check passed"), "{report}");
    assert!(report.contains("rest velocity      ok"), "{report}");
    // The same run held to a 0.01 mm rest deviation: P3 sags more than that.
    let (ok, report) = check(&[
        "P3",
        "--frames",
        "600",
        "--every",
        "600",
        "--max-rest-deviation-mm",
        "0.01",
    ]);
    assert!(!ok, "{report}");
    assert!(report.contains("check FAILED: rest deviation"), "{report}");
}

#[test]
fn rest_figures_wait_for_the_motion_to_stop() {
    // T1 activates until its last key at 2 s: a one-second run is still moving.
    let (_, report) = check(&["T1", "--frames", "60"]);
    assert!(report.contains("rest figures not judged"), "{report}");
    assert!(report.contains("rest velocity      -"), "{report}");
}

#[test]
fn residuals_list_each_type_at_a_muscles_worst_strain() {
    // T1 contracts to full activation by frame 60: its worst strain is in
    // the run, and its fibres and volume have something left to project.
    let (_, report) = check(&["T1", "--frames", "60", "--residuals"]);
    let header = report
        .lines()
        .find(|l| l.starts_with("muscle") && l.contains("frame") && l.contains("largest at"))
        .unwrap_or_else(|| panic!("no residual table: {report}"));
    assert!(header.contains("Fiber"), "{header}");
    let row = report
        .lines()
        .skip_while(|l| *l != header)
        .nth(1)
        .expect("a row");
    let cells: Vec<&str> = row.split_whitespace().collect();
    let frame: u32 = cells[1].parse().expect("a frame");
    assert!((1..60).contains(&frame), "{row}");
    assert!(row.contains(" vertex "), "{row}");
    // Without the flag, no table.
    let (_, plain) = check(&["T1", "--frames", "60"]);
    assert!(!plain.contains("largest at"), "{plain}");
}

#[test]
fn a_bone_contact_interval_override_is_taken_and_zero_is_refused_by_name() {
    // T1 has no bones: any interval gives the same run, so the report is
    // the same line for line whatever the override says.
    let (ok, every) = check(&["T1", "--frames", "30"]);
    let (ok_3, third) = check(&["T1", "--frames", "30", "--bone-contact-interval", "3"]);
    assert_eq!(ok, ok_3);
    let figures = |r: &str| r.lines().skip(1).map(String::from).collect::<Vec<_>>();
    assert_eq!(figures(&every), figures(&third));
    let out = Command::new(env!("CARGO_BIN_EXE_sinew"))
        .args([
            "check",
            "T1",
            "--frames",
            "2",
            "--bone-contact-interval",
            "0",
        ])
        .output()
        .expect("sinew runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bone_contact_interval = 0"), "{err}");
}

/// `--walk-interval` and `--feature-contacts` reach the solver: on P3 (a
/// biceps sliding on its brachialis) walking every fourth iteration with
/// the features moves the muscles otherwise than walking in every one, and
/// an interval of 0 is refused by name.
#[test]
fn walk_interval_and_feature_contacts_overrides_are_taken_and_zero_is_refused() {
    let (_, every) = check(&["P3", "--frames", "30"]);
    let (_, fourth) = check(&[
        "P3",
        "--frames",
        "30",
        "--walk-interval",
        "4",
        "--feature-contacts",
        "true",
    ]);
    let figures = |r: &str| r.lines().skip(1).map(String::from).collect::<Vec<_>>();
    assert_ne!(figures(&every), figures(&fourth));
    let out = Command::new(env!("CARGO_BIN_EXE_sinew"))
        .args(["check", "T1", "--frames", "2", "--walk-interval", "0"])
        .output()
        .expect("sinew runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("walk_interval = 0"), "{err}");
}
