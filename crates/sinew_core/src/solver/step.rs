//! [`Solver::step`]: the frame loop over the solver's own muscles, built
//! from the passes of [`super::passes`] (the Bevy systems run the same).

use super::Solver;
use super::params::{FrameParams, IterationParams, Parallelism, SubstepParams};
use super::passes;
use super::pipeline;
use super::timings::{StepTimings, Stopwatch, TaskSplit};
use crate::animation::interpolate_rigid;
use crate::closest::TargetSource;
use crate::muscle::Muscle;
use glam::Affine3A;
use std::sync::Mutex;

impl Solver {
    /// Advances one frame. With worker threads the whole frame runs on
    /// one of them, so its passes reach the others without a cross-thread
    /// hand-off each — unless the scene is small enough to run on the
    /// calling thread anyway ([`Parallelism`]), which then saves the
    /// hand-off (≈ 15 µs: P1 on 2 threads went from 0.047 to 0.032 ms).
    pub fn step(&mut self) {
        let frame = self.begin_step();
        let parallel = frame.parallelism.muscles || frame.parallelism.particles;
        match self.pool.threads() {
            Some(threads) if parallel => threads.install(|| self.run_frame(&frame)),
            _ => self.run_frame(&frame),
        }
    }

    /// The frame loop (SPEC §4; the module docs of [`super`]).
    fn run_frame(&mut self, frame: &FrameParams) {
        let mut clock = Stopwatch::new(self.valid.timers);
        let mut timings = StepTimings::default();
        self.read_inputs(frame);
        clock.lap(&mut timings.read_inputs);
        let iterations = frame.iterations_for(&self.muscles);
        for s in 0..frame.substeps {
            let sub = frame.substep(s);
            self.pose_bones(&sub);
            clock.lap(&mut timings.update_targets);
            if s == 0 {
                self.begin_frame(&sub, &mut clock, &mut timings);
            } else {
                self.begin_substep(&sub);
                clock.lap(&mut timings.integrate);
            }
            // In blocks of `snapshot_interval` iterations, each against the
            // snapshots published at its start.
            for block in sub.blocks(iterations) {
                self.publish(&block);
                clock.lap(&mut timings.update_targets);
                self.iterate(&block, &mut clock, &mut timings);
            }
            if s + 1 == frame.substeps {
                self.end_frame(&sub, &mut clock, &mut timings);
            } else {
                self.end_substep(&sub);
                clock.lap(&mut timings.apply);
            }
        }
        self.time += frame.dt;
        self.frame += 1;
        timings.clock_reads = clock.reads();
        self.timings = timings;
    }

    /// The last substep's end and the run-time guard over every muscle in
    /// one pass ([`passes::end_frame_all`]), its time split between the
    /// apply and write-back blocks: a muscle that blew up is put back to
    /// its last good frame and reported.
    fn end_frame(&mut self, sub: &SubstepParams, clock: &mut Stopwatch, t: &mut StepTimings) {
        let unit = self.valid.length_unit;
        let max_speed = self.valid.max_speed * unit;
        let first_new = self.faults.len();
        let split = TaskSplit::new(clock.is_running());
        let pairs = self.muscles.iter_mut().zip(&mut self.workspaces);
        self.pairs.with(pairs, |muscles| {
            passes::end_frame_all(
                &self.pool,
                muscles,
                sub,
                max_speed,
                unit,
                &mut self.faults,
                &split,
            );
        });
        let slots = [&mut t.apply, &mut t.write_back];
        clock.lap_split(slots, split.shares(), split.reads());
        for fault in &self.faults[first_new..] {
            if fault.count == 1 {
                self.warnings.push(fault.to_string());
            }
            self.fault_history.0 += 1;
            self.fault_history.1.get_or_insert_with(|| fault.clone());
        }
    }

    /// Validates the settings (keeping the last valid ones, with a warning,
    /// when they fail), syncs the pool, links new targets and decides where
    /// the work runs.
    fn begin_step(&mut self) -> FrameParams {
        if self.settings != self.valid && self.rejected.as_ref() != Some(&self.settings) {
            match self.settings.validate() {
                Ok(()) => {
                    self.valid.clone_from(&self.settings);
                    self.rejected = None;
                }
                Err(e) => {
                    self.warnings.push(format!(
                        "settings rejected, keeping the last valid ones: {e}"
                    ));
                    self.rejected = Some(self.settings.clone());
                }
            }
        }
        self.pool.sync(self.valid.threads);
        self.prepare();
        let parallelism = Parallelism::decide(&self.valid, self.pool.is_some(), &self.muscles);
        FrameParams::new(&self.valid, self.frame, parallelism)
    }

    /// Bone poses at the frame's end (skeleton, tracks) and activations
    /// (curves, then sensors → triggers → layers); the rest lengths follow
    /// them in the first substep's start ([`Solver::begin_frame`]).
    fn read_inputs(&mut self, frame: &FrameParams) {
        let end_time = self.time + frame.dt;
        if let Some(sk) = &mut self.skeleton {
            sk.pose_at(end_time);
        }
        for b in &mut self.bones {
            b.previous = b.transform;
            if let (Some(body), Some(sk)) = (b.body, &self.skeleton) {
                b.transform = sk.world[body];
            } else if !b.track.keys.is_empty() {
                b.transform = b.track.sample(end_time);
            }
        }
        for (m, curve) in self.muscles.iter_mut().zip(&self.curves) {
            if let Some(c) = curve {
                m.params.activation = c.sample(end_time);
            }
        }
        if let Some(rig) = &mut self.activation_rig {
            // The substep buffer holds the frame-end poses until the first substep.
            self.substep_poses.clear();
            self.substep_poses
                .extend(self.bones.iter().map(|b| b.transform));
            let muscles = &mut self.muscles;
            rig.update(&self.substep_poses, end_time, frame.dt, |m, a| {
                if let Some(m) = muscles.get_mut(m) {
                    m.params.activation = a;
                }
            });
        }
    }

    /// Every bone at the substep's end time: skeleton bones from the
    /// skeleton itself, others interpolated rigidly between the frame's
    /// start and end poses; their targets moved there.
    fn pose_bones(&mut self, sub: &SubstepParams) {
        let alpha = sub.alpha;
        if alpha < 1.0
            && let Some(sk) = &mut self.skeleton
        {
            sk.pose_at(self.time + alpha * sub.frame.dt);
        }
        let sk = self.skeleton.as_ref();
        self.substep_poses.clear();
        self.substep_poses
            .extend(self.bones.iter().map(|b| match (b.body, sk) {
                (Some(body), Some(sk)) if alpha < 1.0 => sk.world[body],
                _ => interpolate_rigid(b.previous, b.transform, alpha),
            }));
        for (b, pose) in self.bones.iter().zip(&self.substep_poses) {
            if let Some(t) = b.target {
                self.targets[t].set_transform(*pose);
            }
        }
    }

    /// Every muscle's rest lengths from its activation, then the first
    /// substep's start ([`Solver::begin_substep`]), in one pass
    /// ([`passes::begin_frame_all`]), its time split between the
    /// read-inputs and integrate blocks.
    fn begin_frame(&mut self, sub: &SubstepParams, clock: &mut Stopwatch, t: &mut StepTimings) {
        let goals = attachment_goals(&self.substep_poses);
        let warnings = Mutex::new(&mut self.warnings);
        let warn = |w| warnings.lock().expect("not poisoned").push(w);
        let always = self.valid.parallel_threshold == 0;
        let split = TaskSplit::new(clock.is_running());
        let pairs = self.muscles.iter_mut().zip(&mut self.workspaces);
        self.pairs.with(pairs, |muscles| {
            passes::begin_frame_all(&self.pool, muscles, sub, always, warn, goals, &split);
        });
        let slots = [&mut t.read_inputs, &mut t.integrate];
        clock.lap_split(slots, split.shares(), split.reads());
    }

    /// Attachment goals, integration, pins, λ = 0 for every muscle, each
    /// muscle in one task.
    fn begin_substep(&mut self, sub: &SubstepParams) {
        let goals = attachment_goals(&self.substep_poses);
        let pairs = self.muscles.iter_mut().zip(&mut self.workspaces);
        self.pairs.with(pairs, |muscles| {
            passes::begin_substep_all(&self.pool, muscles, sub, goals);
        });
    }

    /// `v = (p − x)/h`, `x = p` for every muscle.
    fn end_substep(&mut self, sub: &SubstepParams) {
        let pairs = self.muscles.iter_mut().zip(&mut self.workspaces);
        self.pairs.with(pairs, |muscles| {
            passes::end_substep_all(&self.pool, muscles, sub);
        });
    }

    /// Publishes the targeted muscles' predictions as their snapshots: in
    /// a substep's first iteration by a pass over them (the frame's first
    /// also updates normals, BVHs and inverse masses), in the others by
    /// swapping in what each muscle's task staged at the end of the
    /// iteration before ([`pipeline::stage_snapshot`]: the same positions
    /// and slack, without a pass of its own on the threads).
    fn publish(&mut self, it: &IterationParams) {
        if !it.first_of_substep() {
            for &t in &self.published {
                if let TargetSource::Muscle(m) = self.targets[t].source {
                    let staged = &mut self.workspaces[m].staged;
                    if std::mem::take(&mut staged.ready) {
                        let moved = staged.moved_squared;
                        self.targets[t].publish_staged(&mut staged.positions, moved);
                    }
                }
            }
            return;
        }
        let (published, muscles) = (&self.published, &self.muscles);
        let snapshots = self
            .targets
            .iter_mut()
            .enumerate()
            .filter(|(t, _)| published.binary_search(t).is_ok())
            .filter_map(|(_, t)| match t.source {
                TargetSource::Muscle(m) => Some((t, &muscles[m])),
                TargetSource::Bone(_) => None,
            });
        self.snapshots.with(snapshots, |snapshots| {
            passes::publish_all(&self.pool, snapshots, it);
        });
    }

    /// Closest data and projection of every muscle over the block of
    /// iterations `it` starts.
    fn iterate(&mut self, it: &IterationParams, clock: &mut Stopwatch, t: &mut StepTimings) {
        let targets = self.targets.as_slice();
        let pairs = self.muscles.iter_mut().zip(&mut self.workspaces);
        self.pairs.with(pairs, |muscles| {
            passes::iterate_all(&self.pool, muscles, targets, it, clock, t);
        });
    }
}

/// Moves a muscle's attachment and Bind goals to the bones' substep poses
/// `poses` (a bone's index into them; no bone: the world), in the muscle's
/// own task ([`pipeline::update_attachment_goals`]).
fn attachment_goals(poses: &[Affine3A]) -> impl Fn(&mut Muscle) + Sync + Send + '_ {
    move |m| {
        let pose = |b: Option<usize>| b.map_or(Affine3A::IDENTITY, |b| poses[b]);
        pipeline::update_attachment_goals(m, &pose, &|b| poses[b]);
    }
}
