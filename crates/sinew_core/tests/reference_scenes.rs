//! Constraint counts of the reference scenes against the thesis' Tables 5.1–5.3,
//! and the committed RON scenes against the generators.

use sinew_core::Solver;
use sinew_core::muscle::{ConstraintCounts, ConstraintKind as K};
use sinew_core::scene::{BUILTIN_SCENES, Scene, builtin};
use std::path::Path;

fn solver(name: &str) -> Solver {
    builtin(name).unwrap().instantiate(Path::new(".")).unwrap()
}

fn totals(s: &Solver) -> ConstraintCounts {
    let mut c = ConstraintCounts::default();
    for m in s.muscles() {
        c += m.counts();
    }
    c
}

#[test]
fn p1_matches_table_5_1_exactly() {
    let s = solver("P1");
    let c = totals(&s);
    let expected = [
        (K::Fiber, 190),
        (K::Attach, 2),
        (K::BranchAttach, 2),
        (K::Sliding, 92),
        (K::Soft, 92),
        (K::Hard, 92),
        (K::Internal, 92),
        (K::Branch, 8),
        (K::Volume, 1),
    ];
    for (kind, n) in expected {
        assert_eq!(c.get(kind), n, "{kind:?}");
    }
    assert_eq!(c.total(), 571);
    let m = &s.muscles()[0];
    assert_eq!(m.surface_count, 92);
    assert_eq!(m.mesh.edges.len(), 190);
    // SPEC §7.2: from a pole root, 9 internal points, 8 Branch, 92 Internal.
    assert_eq!(m.roots, vec![0]);
    assert_eq!(m.structure.points.len(), 9);
    assert_eq!(m.structure.branches.len(), 8);
}

fn within(actual: usize, expected: usize, tolerance: f64) -> bool {
    (actual as f64 - expected as f64).abs() <= tolerance * expected as f64
}

#[test]
fn p2_within_two_percent_of_table_5_2() {
    let s = solver("P2");
    let c = totals(&s);
    assert!(within(c.total(), 1040, 0.02), "P2 total {}", c.total());
    assert_eq!(c.get(K::Attach), 2);
    assert_eq!(c.get(K::Volume), 2);
    assert_eq!(c.get(K::Sliding), 172);
    // Each muscle targets the other and the plane.
    for m in s.muscles() {
        assert_eq!(m.targets.len(), 2);
    }
}

#[test]
fn p3_within_five_percent_of_table_5_3_with_a_real_bifurcation() {
    let s = solver("P3");
    let c = totals(&s);
    assert!(within(c.total(), 4035, 0.05), "P3 total {}", c.total());
    let biceps = &s.muscles()[0];
    let brachialis = &s.muscles()[1];
    assert_eq!(biceps.surface_count, 496);
    assert_eq!(brachialis.surface_count, 170);
    assert_eq!(c.get(K::Attach), 6);
    assert_eq!(c.get(K::Sliding), 666);
    assert!(
        biceps.structure.bifurcations >= 1,
        "two heads must join one belly"
    );
    assert!(biceps.mesh.check_closed_manifold().is_ok());
}

#[test]
fn t1_has_no_targets_and_an_activation_cycle() {
    let scene = builtin("T1").unwrap();
    let curve = scene.muscles[0].activation.clone().unwrap();
    assert_eq!(curve.sample(0.0), 0.0);
    assert_eq!(curve.sample(1.0), 1.0);
    assert_eq!(curve.sample(2.0), 0.0);
    let s = scene.instantiate(Path::new(".")).unwrap();
    assert_eq!(totals(&s).get(K::Sliding), 0);
}

#[test]
fn committed_scenes_equal_the_generators() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes");
    for name in BUILTIN_SCENES {
        let file = dir.join(format!("{}.ron", name.to_lowercase()));
        let loaded = Scene::load(&file).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            loaded,
            builtin(name).unwrap(),
            "{} is stale: regenerate with `cargo run -p sinew_cli -- scene {name} --out {}`",
            file.display(),
            file.display()
        );
    }
}
