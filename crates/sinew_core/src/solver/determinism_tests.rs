//! The methods give the same bits on any number of threads, and their
//! colour plans are sound.

use super::*;
use crate::constraints::ParticleId;
use crate::muscle::ConstraintKind;
use crate::scene::builtin;
use glam::Vec3;

/// Positions after `frames` frames of a built-in scene with `threads` workers.
fn positions_with_threads(scene: &str, threads: u32, frames: usize) -> Vec<u32> {
    positions(scene, SolverMethod::Sequential, threads, frames)
}

/// Positions (as bits) after `frames` frames of a built-in scene under gravity.
fn positions(scene: &str, method: SolverMethod, threads: u32, frames: usize) -> Vec<u32> {
    positions_with(scene, frames, |s| {
        s.threads = threads;
        s.method = method;
    })
}

/// Positions (as bits) after `frames` frames of a built-in scene under
/// gravity, with `edit` applied to its settings.
fn positions_with(scene: &str, frames: usize, edit: impl FnOnce(&mut SolverSettings)) -> Vec<u32> {
    let mut scene = builtin(scene).unwrap();
    scene.settings.gravity = Vec3::new(0.0, -9.81, 0.0);
    // Small scenes too split over the threads they are given.
    scene.settings.parallel_threshold = 0;
    edit(&mut scene.settings);
    let mut s = scene.instantiate(std::path::Path::new(".")).unwrap();
    for _ in 0..frames {
        s.step();
    }
    s.muscles()
        .iter()
        .flat_map(|m| m.x.iter().flat_map(|p| p.to_array().map(f32::to_bits)))
        .collect()
}

#[test]
fn sequential_is_bit_identical_for_1_2_and_8_threads() {
    for scene in ["P2", "P3"] {
        let one = positions_with_threads(scene, 1, 30);
        assert_eq!(
            one,
            positions_with_threads(scene, 2, 30),
            "{scene}: 2 threads"
        );
        assert_eq!(
            one,
            positions_with_threads(scene, 8, 30),
            "{scene}: 8 threads"
        );
        assert_eq!(
            one,
            positions_with_threads(scene, 0, 30),
            "{scene}: every core"
        );
    }
}

#[test]
fn changing_the_thread_count_between_frames_changes_nothing() {
    let reference = positions_with_threads("P3", 1, 20);
    let mut scene = builtin("P3").unwrap();
    scene.settings.gravity = Vec3::new(0.0, -9.81, 0.0);
    scene.settings.parallel_threshold = 0;
    let mut s = scene.instantiate(std::path::Path::new(".")).unwrap();
    for frame in 0..20 {
        s.settings.threads = [1, 3, 0, 2][frame % 4];
        s.step();
    }
    let got: Vec<u32> = s
        .muscles()
        .iter()
        .flat_map(|m| m.x.iter().flat_map(|p| p.to_array().map(f32::to_bits)))
        .collect();
    assert_eq!(reference, got);
}

fn colored(threads: u32, scene: &str, frames: usize) -> Vec<u32> {
    let method = SolverMethod::Colored {
        scope: ColorScope::PerMuscle,
    };
    positions(scene, method, threads, frames)
}

#[test]
fn colored_is_bit_identical_for_1_2_and_8_threads() {
    let one = colored(1, "P3", 30);
    assert_eq!(one, colored(2, "P3", 30));
    assert_eq!(one, colored(8, "P3", 30));
    // It is a different Gauss–Seidel order from Sequential, not a copy of it.
    assert_ne!(one, positions_with_threads("P3", 1, 30));
}

/// Every constraint of every plan kind's colouring is solved exactly once per
/// iteration (in a unit or in the Jacobi tail), and the units of a colour
/// share no particle: checked here from scratch, not by the plan's own
/// constructor.
#[test]
fn every_plan_solves_each_constraint_once_and_no_colour_shares_a_particle() {
    let mut solver = builtin("P3")
        .unwrap()
        .instantiate(std::path::Path::new("."))
        .unwrap();
    // Link the target constraints (Sliding, Soft, Hard) first.
    solver.prepare();
    let kinds = [
        coloring::PlanKind::PerConstraint,
        coloring::PlanKind::Clustered,
        coloring::PlanKind::Hybrid { min_group: 32 },
    ];
    for m in solver.muscles() {
        for kind in kinds {
            let plan = coloring::ColorPlan::build(m, &ConstraintKind::CANONICAL_ORDER, kind);
            let mut solved = std::collections::HashMap::new();
            for c in 0..plan.color_count() {
                let mut owner = std::collections::HashMap::new();
                for (u, unit) in plan.units_of(c).enumerate() {
                    for &r in unit {
                        *solved.entry(r).or_insert(0) += 1;
                        for p in coloring::particles_of(m, r).into_iter().flatten() {
                            let first = *owner.entry(p).or_insert(u);
                            assert_eq!(first, u, "{kind:?} colour {c}: particle {p} in two units");
                        }
                    }
                }
            }
            for &r in plan.tail() {
                *solved.entry(r).or_insert(0) += 1;
            }
            let counts = m.counts();
            let expected = counts.total() - counts.get(ConstraintKind::Volume);
            assert_eq!(
                solved.len(),
                expected,
                "{kind:?}: every constraint but Volume"
            );
            assert!(solved.values().all(|&n| n == 1), "{kind:?}: once each");
        }
    }
}

#[test]
fn global_colouring_and_hybrid_are_bit_identical_for_1_2_and_8_threads() {
    let methods = [
        SolverMethod::Colored {
            scope: ColorScope::Global,
        },
        SolverMethod::Hybrid {
            min_group: 32,
            omega: 1.5,
        },
    ];
    for method in methods {
        let one = positions("P3", method, 1, 30);
        assert_eq!(one, positions("P3", method, 2, 30), "{method:?}: 2 threads");
        assert_eq!(one, positions("P3", method, 8, 30), "{method:?}: 8 threads");
        for schedule in [SweepSchedule::ByColor, SweepSchedule::ByMuscle] {
            let got = positions_with("P3", 30, |s| {
                s.threads = 2;
                s.method = method;
                s.schedule = schedule;
            });
            assert_eq!(one, got, "{method:?}: {schedule:?}");
        }
        assert!(one.iter().all(|&b| f32::from_bits(b).is_finite()));
        assert_ne!(one, colored(1, "P3", 30), "{method:?} is its own order");
    }
}

/// P1 with a 40 × 40 oval: its colours hold thousands of constraints, so
/// threads split them into chunks (and Jacobi its passes).
#[test]
fn chunks_of_a_large_muscle_give_the_same_bits_on_threads() {
    use crate::mesh::primitives::MeshGenerator;
    use crate::scene::MeshSource;
    let run = |method, threads| {
        let mut scene = builtin("P1").unwrap();
        scene.muscles[0].mesh = MeshSource::Generator(MeshGenerator::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::new(0.06, 0.025, 0.025),
            segments: 40,
            stacks: 40,
        });
        scene.muscles[0].attachments.truncate(1);
        scene.settings.method = method;
        scene.settings.schedule = SweepSchedule::ByColor;
        scene.settings.threads = threads;
        scene.settings.gravity = Vec3::new(0.0, -9.81, 0.0);
        let mut s = scene.instantiate(std::path::Path::new(".")).unwrap();
        for _ in 0..5 {
            s.step();
        }
        let m = &s.muscles()[0];
        if let Some(plan) = s.workspaces()[0].plan() {
            let chunks = (0..plan.color_count()).map(|c| plan.chunk_count(c)).max();
            assert!(chunks > Some(1), "{method:?}: no colour was split");
            // Colours of a thousand constraints and more run in parallel.
            let sweep = plan.sweep();
            let sizes: Vec<usize> = (0..sweep.color_count())
                .map(|c| sweep.color_op_count(c))
                .collect();
            assert_eq!(sizes.iter().sum::<usize>(), sweep.op_count());
            let large = sizes
                .iter()
                .any(|&n| n >= super::coloring::TASK_CONSTRAINTS);
            assert!(large, "{method:?}: no colour large enough to split");
        }
        let bits: Vec<u32> =
            m.x.iter()
                .flat_map(|p| p.to_array().map(f32::to_bits))
                .collect();
        bits
    };
    let split = SolverMethod::EVERY
        .into_iter()
        .filter(|&m| m != SolverMethod::Sequential);
    for method in split {
        assert_eq!(run(method, 1), run(method, 4), "{method:?}");
    }
}

/// The bits of the skin (`segments` × `stacks`, over P1's oval) after
/// `steps` steps under `Sequential` on `threads` threads, after `inspect`
/// has looked at the solver.
fn layer_bits(
    (segments, stacks): (u32, u32),
    threads: u32,
    steps: usize,
    inspect: impl Fn(&Solver),
) -> Vec<u32> {
    let params = crate::muscle::MuscleParams::surface_layer(2.2, 0.01);
    let mut scene = super::tests::p1_with_skin(segments, stacks, params);
    scene.settings.threads = threads;
    scene.settings.parallel_threshold = 0;
    let mut s = scene.instantiate(std::path::Path::new(".")).unwrap();
    for _ in 0..steps {
        s.step();
    }
    inspect(&s);
    s.muscles()[1]
        .x
        .iter()
        .flat_map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

/// `Sequential` projects a surface layer in its colour groups' order, in
/// chunks on the threads: a 40 × 40 skin over P1's oval gives the same bits
/// on 1 and 4 threads, its plan splits a colour, and the muscle under it
/// keeps its plain Gauss–Seidel pass (no plan).
#[test]
fn sequential_splits_a_surface_layer_by_colour_with_the_same_bits() {
    let split = |s: &Solver| {
        assert!(s.workspaces()[0].plan().is_none(), "the muscle has a plan");
        let plan = s.workspaces()[1].plan().expect("the layer's colour plan");
        let chunks = (0..plan.color_count()).map(|c| plan.chunk_count(c)).max();
        assert!(chunks > Some(1), "no colour of the layer was split");
    };
    assert_eq!(
        layer_bits((40, 40), 1, 5, split),
        layer_bits((40, 40), 4, 5, split)
    );
}

/// A skin big enough that its colours give each of four threads less
/// than a task's worth is swept by the threads as one team
/// (`sweep::runs_as_team`: one fork, a wait at each colour): the same
/// bits on 1 and 4 threads, and on 2, where the colours fork one by one.
#[test]
fn a_surface_layer_swept_as_a_team_gives_the_same_bits() {
    let team = |s: &Solver| {
        let plan = s.workspaces()[1].plan().expect("the layer's colour plan");
        assert!(
            super::sweep::runs_as_team(plan.sweep(), 4),
            "no team on 4 threads"
        );
        assert!(!super::sweep::runs_as_team(plan.sweep(), 1));
    };
    let one = layer_bits((110, 90), 1, 2, team);
    assert_eq!(one, layer_bits((110, 90), 4, 2, team));
    assert_eq!(one, layer_bits((110, 90), 2, 2, team));
}

#[test]
fn a_plan_is_rebuilt_when_a_constraint_moves_other_particles() {
    let mut scene = builtin("P1").unwrap();
    scene.settings.method = SolverMethod::Colored {
        scope: ColorScope::Global,
    };
    scene.settings.threads = 2;
    let mut s = scene.instantiate(std::path::Path::new(".")).unwrap();
    s.step();
    let m = s.muscle_mut(0);
    // Retie the first fibre to another particle: the units of its colour may
    // now share it, so the plan must not be reused.
    let f = &mut m.constraints.fiber;
    let other = (0..m.surface_count as u32)
        .map(ParticleId::new)
        .find(|&p| p != f.a[0] && p != f.b[0]);
    f.b[0] = other.unwrap();
    assert!(!s.workspaces()[0].plan().unwrap().fits(&s.muscles()[0]));
    s.step();
    let m = &s.muscles()[0];
    assert!(s.workspaces()[0].plan().unwrap().fits(m));
    assert!(m.x.iter().all(|p| p.is_finite()));
}

#[test]
fn jacobi_is_bit_identical_for_1_2_and_8_threads() {
    let method = SolverMethod::Jacobi { omega: 1.5 };
    let one = positions("P3", method, 1, 30);
    assert_eq!(one, positions("P3", method, 2, 30));
    assert_eq!(one, positions("P3", method, 8, 30));
    let finite = one.iter().all(|&b| f32::from_bits(b).is_finite());
    assert!(finite);
}
