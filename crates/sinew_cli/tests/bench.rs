//! `sinew bench` reports, besides the frame's blocks, the memory the
//! process held at its peak: what a crowd costs beside its time.

use std::process::Command;

/// `sinew bench ARGS` on T3 (an arm with its bones), one frame: its
/// report.
fn bench_t3(args: &[&str]) -> String {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/scenes/t3.ron");
    let out = Command::new(env!("CARGO_BIN_EXE_sinew"))
        .args(["bench", scene, "--frames", "1", "--runs", "1"])
        .args(args)
        .output()
        .expect("sinew runs");
    let report = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{report}");
    report
}

/// The maximum resident memory a report gives, in MiB.
fn peak_mib(report: &str) -> f64 {
    let line = (report.lines())
        .find_map(|l| l.strip_prefix("memory: "))
        .unwrap_or_else(|| panic!("no memory line in\n{report}"));
    let mib = line.strip_suffix(" MiB maximum resident (the process)");
    let mib = mib.unwrap_or_else(|| panic!("memory line '{line}'"));
    mib.parse()
        .unwrap_or_else(|_| panic!("memory line '{line}'"))
}

#[test]
fn the_report_gives_the_peak_memory_and_a_crowd_holds_more() {
    let one = bench_t3(&[]);
    if cfg!(target_os = "linux") {
        let crowd = bench_t3(&["--instances", "4"]);
        let (one, four) = (peak_mib(&one), peak_mib(&crowd));
        // T3's solver is a few MiB: a figure in KiB or bytes is far off.
        assert!((2.0..200.0).contains(&one), "one T3: {one} MiB");
        assert!(four > one, "four T3s {four} MiB, one {one} MiB");
    } else {
        assert!(one.contains("memory: not measured"), "{one}");
    }
}
