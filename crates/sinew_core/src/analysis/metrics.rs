//! [`RunMetrics`]: the figures of a run, gathered one frame at a time.

use super::shape::{RestDeviation, ShapeReference};
use super::{
    SkinBulge, attachment_errors, belly_cross_section, penetrating_vertices, skin_bulges,
    skin_inside_vertices,
};
use crate::solver::Solver;
use glam::{Affine3A, Vec3};
use std::collections::VecDeque;

/// Running figures over a simulation, one [`RunMetrics::observe`] per frame.
#[derive(Clone, Debug)]
pub struct RunMetrics {
    /// Frames observed.
    pub frames: u32,
    /// First frame with a NaN or infinite position, if any.
    pub first_non_finite: Option<u32>,
    /// Muscle frames the run-time guard put back during the run (a NaN, an
    /// infinity or a particle over the speed limit, see
    /// [`crate::solver::Fault`]), and the first of them.
    pub faults: (u64, Option<String>),
    /// The solver's fault count when observing started.
    faults_before: u64,
    /// Sum of attachment errors (for the mean). Units: m.
    pub attachment_error_sum: f64,
    /// Attachment error samples.
    pub attachment_samples: u64,
    /// Largest attachment error. Units: m.
    pub attachment_error_max: f32,
    /// Largest share of surface vertices deeper than [`RunMetrics::depth`] inside a bone.
    pub penetration_max: f32,
    /// Frame of that share.
    pub penetration_frame: u32,
    /// Penetration depth counted. Units: m.
    pub depth: f32,
    /// Largest share of skin vertices (bodies with a skin binding) inside a
    /// muscle or bone they slide on, in a checked frame (`None`: no skin).
    pub skin_inside_max: Option<f32>,
    /// Frame of that share.
    pub skin_inside_frame: u32,
    /// Per muscle under a skin that reached [`RunMetrics::bulge_activation`]
    /// in a checked frame: the skin's largest bulge over it
    /// ([`SkinBulge`]) and that frame, in the order first seen.
    pub skin_bulges: Vec<(SkinBulge, u32)>,
    /// Activation from which a muscle's skin bulge is measured. Default: `0.8`.
    pub bulge_activation: f32,
    /// Per muscle: (min, max) of volume / rest volume.
    pub volume_ratio: Vec<(f64, f64)>,
    /// Per muscle: largest activation seen.
    pub activation_max: Vec<f32>,
    /// Per muscle: the smallest and largest [`super::attachment_span`]
    /// over the run (`None`: attached to fewer than two bones).
    pub attachment_span: Vec<Option<(f32, f32)>>,
    /// Per muscle: the pairs its attachments force a strain through
    /// ([`super::ForcedStrain`]).
    pub forced: Vec<super::ForcedStrain>,
    /// Per muscle: the largest strain its attachments forced in a frame
    /// (a lower bound on its largest edge strain then; `None`: attached to
    /// fewer than two bones).
    pub forced_strain_max: Vec<Option<f32>>,
    /// Per muscle: belly cross-section at rest. Units: m².
    pub rest_section: Vec<f32>,
    /// Per muscle: (activation, section / rest section) at its most active frame.
    pub section_at_peak: Vec<(f32, f32)>,
    /// Check penetration every this many frames (1 = every frame).
    pub penetration_every: u32,
    /// Per muscle: largest attachment error. Units: m.
    pub muscle_attachment_max: Vec<f32>,
    /// Per muscle: largest share of its vertices deeper than `depth` in a bone.
    pub muscle_penetration_max: Vec<f32>,
    /// Per muscle: the extremes of its edge strain over the run.
    pub strain: Vec<StrainExtremes>,
    /// Per muscle: the most flipped triangles (folded or inverted, see
    /// [`super::ShapeReference`]) in one frame, and that frame.
    pub flipped_max: Vec<(usize, u32)>,
    /// Frames the rest figures ([`RunMetrics::recent_motion`]) cover: one
    /// second of simulated time.
    pub window: usize,
    /// When set (`None` by default: each read projects a copy of the
    /// muscle once per constraint type), each muscle's constraint
    /// residuals at the frame of its worst edge strain
    /// ([`super::ResidualsAtWorst`]).
    pub residuals: Option<super::ResidualsAtWorst>,
    /// Muscle of each attachment, in [`attachment_errors`] order.
    attachment_owner: Vec<usize>,
    /// Jiggle: sum of squared surface-vertex accelerations measured in the
    /// frame of each muscle's first attached bone, and the sample count.
    jiggle_sum: f64,
    jiggle_samples: u64,
    /// The last two frames' vertex positions in those bone frames.
    history: [Vec<Vec3>; 2],
    /// Per muscle, the rest shape the shape figures compare with.
    shapes: Vec<ShapeReference>,
    /// Per frame of the last `window`, per muscle: its surface's motion.
    recent: VecDeque<Vec<MotionSample>>,
    scratch: Vec<f32>,
}

/// The extremes of a muscle's edge strain (length / rest length) over a
/// run, each with the frame it was seen in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrainExtremes {
    /// Shortest edge.
    pub min: (f32, u32),
    /// Longest edge.
    pub max: (f32, u32),
    /// Lowest 1st percentile of a frame.
    pub p1: (f32, u32),
    /// Highest 99th percentile of a frame.
    pub p99: (f32, u32),
}

impl Default for StrainExtremes {
    fn default() -> Self {
        Self {
            min: (1.0, 0),
            max: (1.0, 0),
            p1: (1.0, 0),
            p99: (1.0, 0),
        }
    }
}

/// A muscle's surface motion, in the frame of its first attached bone (so
/// the bone's own motion does not count), summed over vertices and frames,
/// and the extremes of its edge strain over those frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionSample {
    /// Σ |v|² over vertices and frames. Units: m²/s².
    pub velocity2: f64,
    /// Σ |a|² over vertices and frames. Units: m²/s⁴.
    pub acceleration2: f64,
    /// Σ ½ m |v|² over frames (vertex masses). Units: J.
    pub kinetic_energy: f64,
    /// Velocity samples (vertices × frames).
    pub samples: u64,
    /// Acceleration samples.
    pub acceleration_samples: u64,
    /// Frames summed.
    pub frames: u32,
    /// Smallest edge length / rest length in those frames.
    pub strain_min: f32,
    /// Largest edge length / rest length in those frames.
    pub strain_max: f32,
}

impl Default for MotionSample {
    fn default() -> Self {
        Self {
            velocity2: 0.0,
            acceleration2: 0.0,
            kinetic_energy: 0.0,
            samples: 0,
            acceleration_samples: 0,
            frames: 0,
            strain_min: f32::INFINITY,
            strain_max: f32::NEG_INFINITY,
        }
    }
}

impl MotionSample {
    /// RMS surface velocity. Units: m/s.
    pub fn rms_velocity(&self) -> f32 {
        (self.velocity2 / self.samples.max(1) as f64).sqrt() as f32
    }

    /// RMS surface acceleration (jiggle). Units: m/s².
    pub fn rms_acceleration(&self) -> f32 {
        (self.acceleration2 / self.acceleration_samples.max(1) as f64).sqrt() as f32
    }

    /// Mean kinetic energy of the surface per frame. Units: J.
    pub fn mean_kinetic_energy(&self) -> f32 {
        (self.kinetic_energy / f64::from(self.frames.max(1))) as f32
    }

    fn add(&mut self, other: &Self) {
        self.velocity2 += other.velocity2;
        self.acceleration2 += other.acceleration2;
        self.kinetic_energy += other.kinetic_energy;
        self.samples += other.samples;
        self.acceleration_samples += other.acceleration_samples;
        self.frames += other.frames;
        self.strain_min = self.strain_min.min(other.strain_min);
        self.strain_max = self.strain_max.max(other.strain_max);
    }
}

impl RunMetrics {
    /// Starts measuring `solver` in its current (rest) state.
    pub fn new(solver: &Solver, depth: f32) -> Self {
        let n = solver.muscles().len();
        let dt = solver.settings.step_time();
        Self {
            frames: 0,
            first_non_finite: None,
            faults: (0, None),
            faults_before: solver.fault_history().0,
            attachment_error_sum: 0.0,
            attachment_samples: 0,
            attachment_error_max: 0.0,
            penetration_max: 0.0,
            penetration_frame: 0,
            depth,
            skin_inside_max: None,
            skin_inside_frame: 0,
            skin_bulges: Vec::new(),
            bulge_activation: 0.8,
            volume_ratio: vec![(f64::INFINITY, f64::NEG_INFINITY); n],
            activation_max: vec![0.0; n],
            attachment_span: solver
                .muscles()
                .iter()
                .map(|m| super::attachment_span(m).map(|s| (s, s)))
                .collect(),
            forced: solver
                .muscles()
                .iter()
                .map(super::ForcedStrain::new)
                .collect(),
            forced_strain_max: vec![None; n],
            rest_section: (0..n).map(|m| belly_cross_section(solver, m)).collect(),
            section_at_peak: vec![(0.0, 1.0); n],
            penetration_every: 1,
            muscle_attachment_max: vec![0.0; n],
            muscle_penetration_max: vec![0.0; n],
            strain: vec![StrainExtremes::default(); n],
            flipped_max: vec![(0, 0); n],
            window: ((1.0 / dt).round() as usize).max(1),
            attachment_owner: solver
                .muscles()
                .iter()
                .enumerate()
                .flat_map(|(i, m)| std::iter::repeat_n(i, m.attachments.len()))
                .collect(),
            jiggle_sum: 0.0,
            jiggle_samples: 0,
            history: [Vec::new(), Vec::new()],
            shapes: solver
                .muscles()
                .iter()
                .map(|m| ShapeReference::new(m, solver.bones()))
                .collect(),
            recent: VecDeque::new(),
            scratch: Vec::new(),
            residuals: None,
        }
    }

    /// Records the state after a step.
    pub fn observe(&mut self, solver: &Solver) {
        let frame = self.frames;
        self.frames += 1;
        let (faults, first) = solver.fault_history();
        self.faults.0 = faults - self.faults_before;
        if self.faults.0 > 0 && self.faults.1.is_none() {
            self.faults.1 = first.map(|f| f.to_string());
        }
        let finite = solver
            .muscles()
            .iter()
            .all(|m| m.x.iter().all(|p| p.is_finite()));
        if !finite && self.first_non_finite.is_none() {
            self.first_non_finite = Some(frame);
        }
        if !finite {
            return;
        }
        let strains = self.observe_shape(solver, frame);
        self.observe_motion(solver, &strains);
        for (i, e) in attachment_errors(solver).enumerate() {
            self.attachment_error_sum += f64::from(e);
            self.attachment_samples += 1;
            self.attachment_error_max = self.attachment_error_max.max(e);
            let m = self.attachment_owner[i];
            self.muscle_attachment_max[m] = self.muscle_attachment_max[m].max(e);
        }
        if frame.is_multiple_of(self.penetration_every.max(1)) {
            let inside = penetrating_vertices(solver, self.depth);
            let total: usize = solver.muscles().iter().map(|m| m.surface_count).sum();
            let share = inside.iter().sum::<usize>() as f32 / total.max(1) as f32;
            if share > self.penetration_max {
                self.penetration_max = share;
                self.penetration_frame = frame;
            }
            for ((worst, &n), m) in self
                .muscle_penetration_max
                .iter_mut()
                .zip(&inside)
                .zip(solver.muscles())
            {
                *worst = worst.max(n as f32 / m.surface_count.max(1) as f32);
            }
            let skins = skin_inside_vertices(solver);
            if !skins.is_empty() {
                let (inside, all) = skins.iter().fold((0, 0), |(i, a), s| (i + s.1, a + s.2));
                let share = inside as f32 / all.max(1) as f32;
                if self.skin_inside_max.is_none_or(|worst| share > worst) {
                    self.skin_inside_max = Some(share);
                    self.skin_inside_frame = frame;
                }
                self.observe_bulges(solver, frame);
            }
        }
        for (i, m) in solver.muscles().iter().enumerate() {
            let ratio = m.volume() / m.rest_volume();
            let (lo, hi) = &mut self.volume_ratio[i];
            *lo = lo.min(ratio);
            *hi = hi.max(ratio);
            if let (Some((lo, hi)), Some(span)) =
                (&mut self.attachment_span[i], super::attachment_span(m))
            {
                (*lo, *hi) = (lo.min(span), hi.max(span));
            }
            if let Some(forced) = self.forced[i].at(&m.x) {
                let worst = &mut self.forced_strain_max[i];
                *worst = Some(worst.map_or(forced, |w| w.max(forced)));
            }
            let a = m.params.activation;
            if a > self.activation_max[i] {
                self.activation_max[i] = a;
                let section = belly_cross_section(solver, i);
                self.section_at_peak[i] = (a, section / self.rest_section[i].max(1e-12));
            }
        }
    }

    /// Keeps, per active muscle under a skin, the frame of the skin's
    /// largest bulge over it.
    fn observe_bulges(&mut self, solver: &Solver, frame: u32) {
        for bulge in skin_bulges(solver, self.bulge_activation) {
            let seen = self
                .skin_bulges
                .iter_mut()
                .find(|(b, _)| (b.skin, b.muscle) == (bulge.skin, bulge.muscle));
            match seen {
                Some(peak) if peak.0.max >= bulge.max => {}
                Some(peak) => *peak = (bulge, frame),
                None => self.skin_bulges.push((bulge, frame)),
            }
        }
    }

    /// Secondary motion: the RMS acceleration of surface vertices in the frame
    /// of their muscle's first attached bone (so the bone's own motion does not
    /// count), by second differences over frames, over the whole run. 0 for a
    /// muscle that moves rigidly with its bone. Units: m/s².
    pub fn jiggle_rms(&self) -> f32 {
        (self.jiggle_sum / self.jiggle_samples.max(1) as f64).sqrt() as f32
    }

    /// Per muscle, its surface motion over the last [`RunMetrics::window`]
    /// frames (one second): RMS velocity, kinetic energy and RMS
    /// acceleration in its first attached bone's frame.
    pub fn recent_motion(&self) -> Vec<MotionSample> {
        let n = self.volume_ratio.len();
        let mut total = vec![MotionSample::default(); n];
        for frame in &self.recent {
            for (t, s) in total.iter_mut().zip(frame) {
                t.add(s);
            }
        }
        total
    }

    /// [`RunMetrics::recent_motion`] of every muscle together.
    pub fn recent_motion_total(&self) -> MotionSample {
        let mut total = MotionSample::default();
        for s in self.recent_motion() {
            total.add(&s);
        }
        total.frames = self.recent.len() as u32;
        total
    }

    /// Per muscle, how far its surface is from its rest shape now (each
    /// vertex's rest position carried by the bone of its nearest attachment).
    pub fn rest_deviation(&self, solver: &Solver) -> Vec<RestDeviation> {
        self.shapes
            .iter()
            .zip(solver.muscles())
            .map(|(s, m)| s.rest_deviation(m, solver.bones()))
            .collect()
    }

    /// Mean attachment error. Units: m.
    pub fn attachment_error_mean(&self) -> f32 {
        (self.attachment_error_sum / self.attachment_samples.max(1) as f64) as f32
    }

    /// Records the shape figures of this frame; returns each muscle's
    /// (min, max) edge strain.
    fn observe_shape(&mut self, solver: &Solver, frame: u32) -> Vec<(f32, f32)> {
        let mut strains = Vec::with_capacity(self.shapes.len());
        for (i, m) in solver.muscles().iter().enumerate() {
            let s = self.shapes[i].sample(m, &mut self.scratch);
            strains.push((s.strain_min, s.strain_max));
            let e = &mut self.strain[i];
            let lower = |slot: &mut (f32, u32), value: f32| {
                if value < slot.0 {
                    *slot = (value, frame);
                }
            };
            lower(&mut e.min, s.strain_min);
            lower(&mut e.p1, s.strain_p1);
            let upper = |slot: &mut (f32, u32), value: f32| {
                if value > slot.0 {
                    *slot = (value, frame);
                }
            };
            upper(&mut e.max, s.strain_max);
            upper(&mut e.p99, s.strain_p99);
            if s.flipped > self.flipped_max[i].0 {
                self.flipped_max[i] = (s.flipped, frame);
            }
            if let Some(residuals) = &mut self.residuals {
                residuals.observe(solver, i, &s, frame);
            }
        }
        strains
    }

    /// Velocities and accelerations of the surface vertices in each muscle's
    /// first attached bone's frame, by differences over frames.
    fn observe_motion(&mut self, solver: &Solver, strains: &[(f32, f32)]) {
        let dt = solver.settings.step_time();
        let mut local = Vec::with_capacity(self.history[1].len());
        let mut ranges = Vec::with_capacity(solver.muscles().len());
        for m in solver.muscles() {
            let frame = m
                .attachments
                .first()
                .and_then(|a| a.bone)
                .map_or(Affine3A::IDENTITY, |b| solver.bones()[b].transform)
                .inverse();
            let start = local.len();
            local.extend(
                m.x[..m.surface_count]
                    .iter()
                    .map(|&x| frame.transform_point3(x)),
            );
            ranges.push(start..local.len());
        }
        let [older, old] = &self.history;
        let has_velocity = old.len() == local.len();
        let has_acceleration = has_velocity && older.len() == local.len();
        let mut samples = Vec::with_capacity(ranges.len());
        for ((m, range), &(strain_min, strain_max)) in
            solver.muscles().iter().zip(ranges).zip(strains)
        {
            let mut s = MotionSample {
                frames: 1,
                strain_min,
                strain_max,
                ..MotionSample::default()
            };
            if has_velocity {
                for (k, i) in range.clone().enumerate() {
                    let v = (local[i] - old[i]) / (dt * m.length_unit);
                    let mass = 1.0 / m.free_w[k].max(f32::MIN_POSITIVE);
                    s.velocity2 += f64::from(v.length_squared());
                    s.kinetic_energy += 0.5 * f64::from(mass) * f64::from(v.length_squared());
                    s.samples += 1;
                    if has_acceleration {
                        let a = (local[i] - 2.0 * old[i] + older[i]) / (dt * dt * m.length_unit);
                        s.acceleration2 += f64::from(a.length_squared());
                        s.acceleration_samples += 1;
                    }
                }
            }
            self.jiggle_sum += s.acceleration2;
            self.jiggle_samples += s.acceleration_samples;
            samples.push(s);
        }
        self.recent.push_back(samples);
        while self.recent.len() > self.window {
            self.recent.pop_front();
        }
        let older = std::mem::take(&mut self.history[1]);
        self.history = [older, local];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jiggle_is_zero_at_rest_and_positive_when_the_muscle_swings() {
        let mut still = crate::scene::builtin("P1").unwrap();
        still.settings.gravity = Vec3::ZERO;
        let mut solver = still.instantiate(std::path::Path::new(".")).unwrap();
        let mut metrics = RunMetrics::new(&solver, 0.002);
        for _ in 0..20 {
            solver.step();
            metrics.observe(&solver);
        }
        assert!(metrics.jiggle_rms() < 1e-3, "{}", metrics.jiggle_rms());
        let rest = metrics.recent_motion_total();
        assert!(rest.rms_velocity() < 1e-4, "{rest:?}");
        let mut moving = crate::scene::builtin("T1").unwrap();
        moving.settings.gravity = Vec3::new(0.0, -9.81, 0.0);
        let mut solver = moving.instantiate(std::path::Path::new(".")).unwrap();
        let mut metrics = RunMetrics::new(&solver, 0.002);
        for _ in 0..30 {
            solver.step();
            metrics.observe(&solver);
        }
        assert!(metrics.jiggle_rms() > 0.1, "{}", metrics.jiggle_rms());
        // T1 falls freely: after 0.5 s its surface moves at about g·t.
        let falling = metrics.recent_motion_total();
        assert!(falling.rms_velocity() > 1.0, "{falling:?}");
        assert!(falling.mean_kinetic_energy() > 0.0);
    }
}
