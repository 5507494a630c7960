use super::*;
use crate::scene::builtin;
use std::collections::HashSet;

/// The muscles of `scene` after one step, with a contact band wide
/// enough that every connection holds.
fn muscles(scene: &str) -> Vec<Muscle> {
    let mut scene = builtin(scene).unwrap();
    for m in &mut scene.muscles {
        m.params.contact_reach = 1.0;
    }
    let mut solver = scene.instantiate(std::path::Path::new(".")).unwrap();
    // One step links the target connections (Sliding, Soft, Hard).
    solver.step();
    solver.muscles().to_vec()
}

#[test]
fn no_group_shares_a_particle_and_every_constraint_is_in_exactly_one() {
    for scene in ["P1", "P2", "P3"] {
        for m in muscles(scene) {
            let order = ConstraintKind::CANONICAL_ORDER;
            let colors = ColorGroups::greedy(&m, &order);
            for (g, group) in colors.groups.iter().enumerate() {
                let mut seen = HashSet::new();
                for &c in group {
                    for p in particles_of(&m, c).into_iter().flatten() {
                        assert!(
                            seen.insert(p),
                            "{scene}: group {g} moves particle {p} twice"
                        );
                    }
                }
            }
            let all: Vec<ConstraintRef> = colors.groups.concat();
            let unique: HashSet<ConstraintRef> = all.iter().copied().collect();
            assert_eq!(
                all.len(),
                unique.len(),
                "{scene}: a constraint in two groups"
            );
            let expected = m.counts().total() - usize::from(m.constraints.volume.is_some());
            assert_eq!(all.len(), expected, "{scene}: constraints missing");
        }
    }
}

#[test]
fn switched_off_constraints_are_skipped_and_switching_one_makes_the_plan_stale() {
    for mut m in muscles("P3") {
        let order = ConstraintKind::CANONICAL_ORDER;
        let all = ColorPlan::clustered(&m, &order);
        assert!(all.fits(&m));
        assert_eq!(all.sweep.op_count(), all.refs.len());
        // Weight 0 on a Soft and a Sliding constraint: the old plan no
        // longer fits, the new one leaves both out of its runs.
        let on = (
            m.constraints.soft.compliance[0],
            m.constraints.sliding.compliance[1],
        );
        m.constraints.soft.compliance[0] = f32::INFINITY;
        m.constraints.sliding.compliance[1] = f32::INFINITY;
        assert!(!all.fits(&m));
        let fewer = ColorPlan::clustered(&m, &order);
        assert!(fewer.fits(&m));
        assert_eq!(fewer.refs, all.refs, "the colouring itself is unchanged");
        assert_eq!(fewer.sweep.op_count(), all.sweep.op_count() - 2);
        let planned = |kind, index| {
            fewer.sweep.segments().iter().any(|s| {
                s.kind == kind
                    && fewer
                        .sweep
                        .segment_ops(s)
                        .iter()
                        .any(|op| op.index == index)
            })
        };
        assert!(!planned(ConstraintKind::Soft, 0));
        assert!(!planned(ConstraintKind::Sliding, 1));
        assert!(planned(ConstraintKind::Soft, 1));
        // Either one back on: the plan without it is stale, the first one
        // fits only when both are.
        m.constraints.sliding.compliance[1] = on.1;
        assert!(!fewer.fits(&m) && !all.fits(&m));
        m.constraints.soft.compliance[0] = on.0;
        assert!(!fewer.fits(&m) && all.fits(&m));
    }
}

#[test]
fn group_count_is_bounded_below_by_the_busiest_particle() {
    // A particle moved by d constraints needs d different groups; greedy
    // first-fit never needs more than (max constraints sharing a particle
    // with one constraint) + 1.
    for m in muscles("P3") {
        let refs = constraints_in_order(&m, &ConstraintKind::CANONICAL_ORDER);
        let mut degree = vec![0usize; m.x.len()];
        for &c in &refs {
            for p in particles_of(&m, c).into_iter().flatten() {
                degree[p.index()] += 1;
            }
        }
        let max_degree = *degree.iter().max().unwrap();
        let colors = ColorGroups::greedy(&m, &ConstraintKind::CANONICAL_ORDER);
        assert!(colors.len() >= max_degree);
        let max_conflicts = refs
            .iter()
            .map(|&c| {
                particles_of(&m, c)
                    .into_iter()
                    .flatten()
                    .map(|p| degree[p.index()] - 1)
                    .sum::<usize>()
            })
            .max()
            .unwrap();
        assert!(colors.len() <= max_conflicts + 1);
    }
}

/// A muscle's distance batches are in Gauss–Seidel runs, not in the order
/// their constraints were created; every colouring reads them in creation
/// order, so it is the one the batches in creation order give: the same
/// particles, colour by colour and constraint by constraint.
#[test]
fn colourings_do_not_depend_on_the_runs() {
    let order = ConstraintKind::CANONICAL_ORDER;
    for m in muscles("P3") {
        let mut created = m.clone();
        let k = &mut created.constraints;
        for batch in [&mut k.fiber, &mut k.internal, &mut k.branch] {
            batch.in_creation_order();
        }
        assert_ne!(m.constraints.fiber.a, created.constraints.fiber.a);
        let tied = |m: &Muscle, colors: Vec<Vec<ConstraintRef>>| -> Vec<Vec<_>> {
            let pair = |c: ConstraintRef| (c.kind, particles_of(m, c));
            colors
                .into_iter()
                .map(|g| g.into_iter().map(pair).collect())
                .collect()
        };
        let greedy = |m: &Muscle| tied(m, ColorGroups::greedy(m, &order).groups);
        assert_eq!(greedy(&m), greedy(&created));
        let plan = |m: &Muscle, kind| {
            let plan = ColorPlan::build(m, &order, kind);
            let units = plan.units.windows(2).map(|u| u[0] as usize..u[1] as usize);
            let units: Vec<Vec<ConstraintRef>> = units.map(|u| plan.refs[u].to_vec()).collect();
            (tied(m, units), plan.colors.clone())
        };
        for kind in [
            PlanKind::PerConstraint,
            PlanKind::Clustered,
            PlanKind::Hybrid { min_group: 8 },
        ] {
            assert_eq!(plan(&m, kind), plan(&created, kind), "{kind:?}");
        }
    }
}
