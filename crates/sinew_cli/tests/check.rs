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
