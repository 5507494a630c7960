//! Which constraints a muscle's shape is a compromise between: from its
//! positions at the end of a frame, one more Gauss–Seidel pass in the
//! projection order, each constraint type on its own in turn, and how far
//! each type moves the surface.
//!
//! ```text
//! p ← x (a copy of the muscle; its goals, closest points, rest lengths and
//!        multipliers as the frame left them)
//! for kind in order:  before ← p;  project every constraint of kind once;
//!                     residual(kind) = max over surface vertices |p − before|
//! ```
//! A muscle at rest in its shape reads about zero for every type. A muscle
//! whose constraints agree only up to what the iterations left reads the
//! last iteration's corrections; one whose constraints cannot all hold —
//! a held shape the bones have carried away from where the edges keep the
//! surface, a contact gap two bodies cannot both keep — reads the same
//! millimetres frame after frame in two or more types at the same vertices:
//! what each still pulls, and where. Bone contacts (put back out of a bone
//! after the projections) are not a constraint type and are not read.

use super::ShapeSample;
use crate::muscle::{ConstraintKind, Muscle};
use crate::solver::pipeline::gauss_seidel;
use crate::solver::{FrameParams, Parallelism, Solver};

/// How far one more projection of one constraint type moves a muscle's
/// surface ([`constraint_residuals`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstraintResidual {
    /// The constraint type.
    pub kind: ConstraintKind,
    /// Largest surface-vertex displacement. Units: m (the scene's lengths
    /// over its length unit).
    pub max: f32,
    /// Root mean square over the surface vertices. Units: m.
    pub rms: f32,
    /// The surface vertex of `max`.
    pub vertex: u32,
}

/// Each type's residual in `order` for `m` as it stands (its positions
/// `x`, its constraints as the last step left them), projected with
/// `inv_h2` (1/h² of the solver's substep). Types that move nothing are
/// listed with zeros; `m` itself is not changed.
pub fn constraint_residuals(
    m: &Muscle,
    order: &[ConstraintKind],
    inv_h2: f32,
) -> Vec<ConstraintResidual> {
    let mut copy = m.clone();
    copy.p.clone_from(&copy.x);
    let n = copy.surface_count;
    let unit = copy.length_unit;
    let mut before = Vec::with_capacity(n);
    order
        .iter()
        .map(|&kind| {
            before.clear();
            before.extend_from_slice(&copy.p[..n]);
            gauss_seidel(&mut copy, &[kind], inv_h2);
            let mut residual = ConstraintResidual {
                kind,
                max: 0.0,
                rms: 0.0,
                vertex: 0,
            };
            let mut sum = 0.0f64;
            for (v, (now, was)) in copy.p[..n].iter().zip(&before).enumerate() {
                let d = now.distance(*was) / unit;
                sum += f64::from(d * d);
                if d > residual.max {
                    residual.max = d;
                    residual.vertex = v as u32;
                }
            }
            residual.rms = (sum / n.max(1) as f64).sqrt() as f32;
            residual
        })
        .collect()
}

/// Per muscle, the residuals at the frame of its worst edge strain so far
/// (the larger of its largest strain and the inverse of its smallest: how
/// far from 1 either way), for [`super::RunMetrics::residuals`].
#[derive(Clone, Debug, Default)]
pub struct ResidualsAtWorst {
    /// Per muscle: that frame, its strain (`> 1`: the largest; `< 1`: the
    /// smallest) and each type's residual then, in the projection order;
    /// `None` while no edge has left `[1/1.01, 1.01]`.
    pub muscles: Vec<Option<(u32, f32, Vec<ConstraintResidual>)>>,
}

/// `1/h²` of the solver's substeps, as its step computes it (the time
/// scale included).
fn substep_inv_h2(solver: &Solver) -> f32 {
    FrameParams::new(&solver.settings, 0, Parallelism::default())
        .substep(0)
        .inv_h2
}

/// A muscle's residuals are read again only when its worst strain has
/// grown by this factor since they were last read (each read projects a
/// copy of the muscle once per type).
const REREAD: f32 = 1.01;

impl ResidualsAtWorst {
    /// For a solver of `muscles` muscles.
    pub fn new(muscles: usize) -> Self {
        Self {
            muscles: vec![None; muscles],
        }
    }

    /// Reads muscle `i`'s residuals if `sample` (its shape at `frame`) is
    /// its worst strain so far.
    pub fn observe(&mut self, solver: &Solver, i: usize, sample: &ShapeSample, frame: u32) {
        let (stretch, squeeze) = (sample.strain_max, sample.strain_min.max(1e-6).recip());
        let worst = stretch.max(squeeze);
        let before = self.muscles[i]
            .as_ref()
            .map_or(1.0, |w| w.1.max(w.1.recip()));
        if worst <= before * REREAD {
            return;
        }
        let residuals = constraint_residuals(
            &solver.muscles()[i],
            &solver.settings.projection_order,
            substep_inv_h2(solver),
        );
        let strain = if stretch >= squeeze {
            stretch
        } else {
            sample.strain_min
        };
        self.muscles[i] = Some((frame, strain, residuals));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;

    /// T1 (one oval, no targets, activating 0 → 1 → 0 over 120 frames)
    /// built and stepped `frames` times.
    fn t1(frames: usize) -> crate::solver::Solver {
        let scene = builtin("T1").expect("T1 is built in");
        let mut solver = scene.instantiate(std::path::Path::new(".")).unwrap();
        for _ in 0..frames {
            solver.step();
        }
        solver
    }

    #[test]
    fn residuals_are_projected_at_the_solvers_own_substep() {
        let mut scene = builtin("T1").expect("T1 is built in");
        scene.settings.time_scale = 0.5;
        scene.settings.substeps = 2;
        let solver = scene.instantiate(std::path::Path::new(".")).unwrap();
        let h = scene.settings.dt * 0.5 / 2.0;
        let inv_h2 = substep_inv_h2(&solver);
        assert!(
            (inv_h2 * h * h - 1.0).abs() < 1e-5,
            "{inv_h2} vs {}",
            1.0 / (h * h)
        );
    }

    #[test]
    fn a_muscle_in_its_rest_shape_has_nothing_left_to_project() {
        let solver = t1(0);
        let m = &solver.muscles()[0];
        let order = &solver.settings.projection_order;
        let residuals = constraint_residuals(m, order, substep_inv_h2(&solver));
        assert_eq!(residuals.len(), order.len());
        for r in &residuals {
            assert!(r.max < 1e-6, "{r:?}");
        }
    }

    #[test]
    fn a_displaced_vertex_is_pulled_back_by_its_edges_and_read_where_it_is() {
        let solver = t1(0);
        let mut m = solver.muscles()[0].clone();
        let free = (0..m.surface_count)
            .find(|&v| m.attachments.iter().all(|a| a.vertex.index() != v))
            .unwrap();
        m.x[free].y += 0.004;
        let residuals = constraint_residuals(&m, &[ConstraintKind::Fiber], substep_inv_h2(&solver));
        let fiber = residuals[0];
        // Rigid edges put a lone displaced vertex most of the way back.
        assert_eq!(fiber.vertex as usize, free, "{fiber:?}");
        assert!(fiber.max > 0.002 && fiber.max <= 0.004 + 1e-6, "{fiber:?}");
    }

    #[test]
    fn a_run_keeps_each_muscles_residuals_at_its_worst_strain() {
        let mut solver = t1(0);
        let mut metrics = super::super::RunMetrics::new(&solver, 0.002);
        metrics.residuals = Some(ResidualsAtWorst::new(1));
        for _ in 0..90 {
            solver.step();
            metrics.observe(&solver);
        }
        let (frame, strain, residuals) = metrics.residuals.as_ref().unwrap().muscles[0]
            .clone()
            .expect("T1 contracts: its edges leave [1/1.01, 1.01]");
        // Its worst either way (the bulge stretches its rings, the fibres
        // shorten), read within a re-read step of the run's extreme.
        let e = metrics.strain[0];
        let (worst, worst_frame) = if e.max.0 >= e.min.0.recip() {
            e.max
        } else {
            (e.min.0.recip(), e.min.1)
        };
        let read = strain.max(strain.recip());
        assert!(read > REREAD, "{strain}");
        assert!(
            read <= worst && read * REREAD >= worst,
            "{strain} vs {worst}"
        );
        assert!(frame <= worst_frame, "{frame} {worst_frame}");
        let order = &solver.settings.projection_order;
        assert_eq!(residuals.len(), order.len());
        assert!(
            residuals
                .iter()
                .all(|r| r.max.is_finite() && r.rms <= r.max)
        );
    }
}
