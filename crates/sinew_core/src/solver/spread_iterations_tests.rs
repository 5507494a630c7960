//! Which iterations of a substep a muscle runs ([`IterationParams::runs`]):
//! a muscle its own count's first ones (the thesis' rule), a surface layer
//! with fewer iterations than the substep spread evenly over it, with its
//! last iteration, its staging in blocks and its bone contacts following.

use super::*;
use crate::muscle::MassMode;
use crate::scene::builtin;

/// P3's biceps with its own iteration count `own`, as a surface layer
/// (mass per area) when `layer`.
fn body(own: Option<u32>, layer: bool) -> Muscle {
    let solver = builtin("P3")
        .unwrap()
        .instantiate(std::path::Path::new("."))
        .unwrap();
    let mut m = solver.muscles()[0].clone();
    m.params.iterations = own;
    if layer {
        m.params.mass = MassMode::AreaDensity(1.1);
    }
    assert_eq!(m.params.is_surface_layer(), layer);
    m
}

/// The iterations of a substep of `count` (`snapshot_interval` 5) that `m`
/// runs, and those among them that `keep` keeps.
fn iterations(m: &Muscle, count: u32, keep: impl Fn(&IterationParams) -> bool) -> Vec<u32> {
    let settings = SolverSettings {
        iterations: count,
        snapshot_interval: 5,
        ..SolverSettings::default()
    };
    let frame = FrameParams::new(&settings, 0, Parallelism::default());
    let sub = frame.substep(0);
    (0..count)
        .map(|i| sub.iteration(i, count))
        .filter(|it| it.runs(m) && keep(it))
        .map(|it| it.index)
        .collect()
}

/// Four of ten: a muscle runs the first four, a layer 0, 3, 5 and 8; a
/// layer with the substep's count runs every one, with one only the first.
#[test]
fn a_layer_spreads_its_iterations_and_a_muscle_runs_its_first() {
    let all = |_: &IterationParams| true;
    assert_eq!(iterations(&body(Some(4), false), 10, all), [0, 1, 2, 3]);
    assert_eq!(iterations(&body(Some(4), true), 10, all), [0, 3, 5, 8]);
    assert_eq!(iterations(&body(Some(3), true), 7, all), [0, 3, 5]);
    assert_eq!(
        iterations(&body(Some(10), true), 10, all),
        Vec::from_iter(0..10)
    );
    assert_eq!(iterations(&body(None, true), 6, all), Vec::from_iter(0..6));
    assert_eq!(iterations(&body(Some(1), true), 10, all), [0]);
    // A count of 0, set past validation, runs nothing.
    assert!(iterations(&body(Some(0), true), 10, all).is_empty());
    assert!(iterations(&body(Some(0), false), 10, all).is_empty());
}

/// A layer's last iteration is its last spread one (Volume converges
/// there, bone contacts run there); its bone contacts run in each of its
/// iterations; in blocks of five it stages its snapshot after its last
/// iteration in each block.
#[test]
fn a_spread_layer_ends_stages_and_contacts_bones_on_its_own_iterations() {
    let layer = body(Some(4), true);
    let last = |it: &IterationParams| it.last_for(&layer);
    assert_eq!(iterations(&layer, 10, last), [8]);
    let contacts = |it: &IterationParams| it.contacts_bones(&layer);
    assert_eq!(iterations(&layer, 10, contacts), [0, 3, 5, 8]);
    let stages = |it: &IterationParams| it.stages_for(&layer, (it.index / 5 + 1) * 5);
    assert_eq!(iterations(&layer, 10, stages), [3, 8]);
    // A muscle that ends inside the first block stages there.
    let muscle = body(Some(4), false);
    let stages = |it: &IterationParams| it.stages_for(&muscle, (it.index / 5 + 1) * 5);
    assert_eq!(iterations(&muscle, 10, stages), [3]);
    let last = |it: &IterationParams| it.last_for(&muscle);
    assert_eq!(iterations(&muscle, 10, last), [3]);
}

/// For every count up to 16 and every own count up to it, a layer runs
/// exactly its own count of iterations, the first at 0, its `j`-th at
/// `⌈j · count / own⌉`, the gaps between them differing by at most one.
#[test]
fn spread_iterations_are_as_many_as_asked_and_evenly_apart() {
    for count in 1..=16u32 {
        for own in 1..=count {
            let run = iterations(&body(Some(own), true), count, |_| true);
            assert_eq!(run.len(), own as usize, "{own} of {count}");
            for (j, &i) in run.iter().enumerate() {
                assert_eq!(i, (j as u32 * count).div_ceil(own), "{own} of {count}");
            }
            let gaps: Vec<u32> = run.windows(2).map(|w| w[1] - w[0]).collect();
            let (lo, hi) = (gaps.iter().min(), gaps.iter().max());
            assert!(hi.zip(lo).is_none_or(|(h, l)| h - l <= 1), "{gaps:?}");
        }
    }
}
