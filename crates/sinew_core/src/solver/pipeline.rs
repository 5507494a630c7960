//! The frame loop's per-muscle phases, the only copy of the loop's logic.
//! [`super::passes`] runs them over every muscle for both drivers (the
//! plain [`super::Solver`] and the Bevy systems). A muscle's step is
//!
//! ```text
//! read inputs        (driver) bone poses, activation; link(m, ws, targets) when targets change
//! per substep        update_attachment_goals(m, pose)  the bones' poses at the substep
//!                    begin_substep(m, ws, s)           integrate, pins, λ = 0
//!   per iteration    publish(snapshot, m, it)          for the muscles others target
//!                    iterate(m, ws, targets, it)       closest data, then project:
//!                                                        sweep(m, ws, it)  the method's pass
//!                                                        finish(m, ws, targets, it)
//!                                                          Hybrid tail, Volume, bone contacts
//!                                                        stage_snapshot(m, ws, targets)
//!                                                          the next iteration's snapshot,
//!                                                          when the driver stages
//!                    (by colour: closest(..) of every muscle, then colour c of every
//!                     muscle's plan_for(..) for each c, then finish(..) of every muscle)
//!                    end_substep(m, ws, s)             v = (p − x)/h, x = p
//! ```
//!
//! A muscle reads other muscles only through snapshots published at the
//! start of the iteration, so the order and thread of muscles do not change
//! the result. Targets are looked up through [`TargetSet`], the driver's
//! table, which [`MuscleWorkspace::target_ids`] index in the muscle's own
//! target order.

use super::bone_contacts::bone_contacts;
use super::coloring::{ColorPlan, PlanKind};
use super::jacobi::{self, JacobiState};
use super::momentum;
use super::params::{IterationParams, SubstepParams};
use super::settings::{ColorScope, SolverMethod};
use super::sweep::{self, SweepPlan};
use super::timings::TaskSplit;
use super::workspace::{MuscleWorkspace, SwitchedOn};
use crate::closest::{TargetSet, TargetSurface};
use crate::constraints::{BatchFnMut, ConstraintBatch, VolumeProjection};
use crate::muscle::ConstraintKind;
use crate::muscle::{LineShape, Muscle};
use glam::{Affine3A, Vec3};

pub use super::closest_data::closest_data;
pub use super::link::link;

/// Starts a substep of `m` (after [`update_attachment_goals`]): predicted
/// positions (gravity, damping `e^(−c h)`), pinned particles on
/// their goals, multipliers zeroed, and a free muscle's momentum recorded.
pub fn begin_substep(m: &mut Muscle, ws: &mut MuscleWorkspace, p: &SubstepParams) {
    integrate(m, p.frame.gravity, p.h);
    m.place_pinned();
    m.constraints.clear_lambdas();
    ws.momentum = momentum::is_free(m).then(|| momentum::measure(m));
}

/// Ends a substep of `m`: velocities from the corrections, positions
/// accepted, and the momentum [`begin_substep`] recorded restored.
pub fn end_substep(m: &mut Muscle, ws: &mut MuscleWorkspace, p: &SubstepParams) {
    let inv_h = 1.0 / p.h;
    for i in 0..m.x.len() {
        m.v[i] = (m.p[i] - m.x[i]) * inv_h;
        m.x[i] = m.p[i];
    }
    if let Some(reference) = ws.momentum {
        momentum::restore(m, reference, p.h);
    }
}

/// Publishes `m`'s predictions into `target`, the snapshot other muscles
/// read it through; the first iteration of a frame also updates its
/// normals, its particles' inverse masses and (when its slack asks) its BVH.
pub fn publish(target: &mut TargetSurface, m: &Muscle, p: &IterationParams) {
    publish_at(target, m, p.first_of_frame());
}

/// [`publish`] with the first-of-frame work chosen by hand (`true` before
/// linking against the snapshot).
pub fn publish_at(target: &mut TargetSurface, m: &Muscle, first_of_frame: bool) {
    target.publish(&m.p[..m.surface_count]);
    if first_of_frame {
        target.update_normals();
        target.refit(false);
        target.set_inverse_masses(&m.w[..m.surface_count]);
    }
}

/// The block of iterations `p` starts ([`IterationParams::block`]: one
/// iteration unless [`crate::SolverSettings::snapshot_interval`] says
/// more) of `m`, back to back in one task: each its closest data, then
/// its projection ([`sweep`] and [`finish`]), against the snapshots
/// published before `p`; `m`'s last iteration in the block stages its
/// snapshot for the next block ([`IterationParams::stages_for`]). The
/// iterations `m` does not run ([`IterationParams::runs`]: past its own
/// count, or between a surface layer's spread ones) it sits out. `timer`
/// splits the task's time between closest data and projection, and takes
/// a surface layer's phases ([`super::timings::LayerTimings`]).
pub fn iterate<T: TargetSet + Sync + ?Sized>(
    m: &mut Muscle,
    ws: &mut MuscleWorkspace,
    targets: &T,
    p: &IterationParams,
    timer: &TaskSplit,
) {
    let end = p.block_end();
    for p in p.block() {
        if !p.runs(m) {
            continue;
        }
        let layer = m.params.is_surface_layer();
        let start = timer.start();
        closest_data(m, ws, targets, p.closest());
        let middle = timer.lap(start, 0);
        sweep(m, ws, &p);
        let swept = if layer { timer.start() } else { None };
        finish(m, ws, targets, &p);
        if p.stages_for(m, end) {
            stage_snapshot(m, ws, targets, &p);
        }
        let done = timer.lap(middle, 1);
        if layer {
            timer.add_layer([start, middle, swept, done]);
        }
    }
}

/// Stages `m`'s surface for its snapshot in the iteration after `p`, in
/// the muscle's own task, when the driver publishes by staging (it has set
/// the muscle's own target in the workspace; the plain solver does for
/// every muscle another targets): the copy and the slack's pass over the
/// vertices move into the task, and the driver's publish becomes a swap of
/// buffers (see [`crate::closest::TargetSurface::publish_staged`]).
/// Nothing after a substep's last iteration: the next substep's first
/// publishes its predictions in a pass.
pub fn stage_snapshot<T: TargetSet + ?Sized>(
    m: &Muscle,
    ws: &mut MuscleWorkspace,
    targets: &T,
    p: &IterationParams,
) {
    let staged = &mut ws.staged;
    let Some(id) = staged.target.filter(|_| !p.last_of_substep()) else {
        return;
    };
    staged.positions.clear();
    staged.positions.extend_from_slice(&m.p[..m.surface_count]);
    staged.moved_squared = targets.target(id).moved_squared(&staged.positions);
    staged.ready = true;
}

/// Closest data of `m` for iteration `p` (BE5), when `m` runs it.
pub fn closest<T: TargetSet + Sync + ?Sized>(
    m: &mut Muscle,
    ws: &mut MuscleWorkspace,
    targets: &T,
    p: &IterationParams,
) {
    if p.runs(m) {
        closest_data(m, ws, targets, p.closest());
    }
}

/// The method's pass over every constraint of `m` but those [`finish`]
/// runs: Gauss–Seidel in the projection order (a surface layer's in its
/// greedy colour groups' order, see [`SolverMethod::Sequential`]), the
/// colour plan's sweeps, or the Jacobi pass.
pub fn sweep(m: &mut Muscle, ws: &mut MuscleWorkspace, p: &IterationParams) {
    let f = &p.substep.frame;
    let (order, inv_h2, split) = (f.order.as_slice(), p.substep.inv_h2, f.parallelism.muscles);
    match (f.method, plan_kind_of(m, f.method)) {
        (SolverMethod::Jacobi { omega }, _) => {
            let state = jacobi_for(m, ws, order);
            jacobi::project_jacobi(m, state, inv_h2, omega, split);
        }
        (_, Some(_)) => {
            let plan = plan_for(m, ws, p);
            sweep::sweep_muscle(m, plan.sweep(), inv_h2, split);
        }
        (_, None) => {
            let on = Some(&ws.switched_on);
            let volume = p.volume_projection(m);
            gauss_seidel_over(m, split_volume(order).0, inv_h2, on, volume)
        }
    }
}

/// The colour plan `m` runs this iteration ([`plan_kind_of`]), built when
/// the workspace has none of that kind for `m`'s current topology. The
/// first iteration of a substep also compares the plan with the muscle's
/// index arrays ([`ColorPlan::fits`]): a host may have retied a constraint
/// through the public batches without [`Muscle::touch_topology`].
pub fn plan_for<'w>(
    m: &Muscle,
    ws: &'w mut MuscleWorkspace,
    p: &IterationParams,
) -> &'w mut ColorPlan {
    let f = &p.substep.frame;
    let (kind, _) = plan_kind_of(m, f.method).expect("a coloured method or a surface layer");
    let topology = m.topology();
    let fresh = matches!(&ws.plan, Some((t, plan))
        if *t == topology && plan.kind() == kind && (!p.first_of_substep() || plan.fits(m)));
    if !fresh {
        ws.plan = Some((topology, ColorPlan::build(m, f.order.as_slice(), kind)));
    }
    &mut ws.plan.as_mut().expect("just built").1
}

/// The sweep plan of `m`'s workspace (after [`plan_for`]), for a driver
/// that runs colour sweeps across muscles.
pub fn sweep_plan(ws: &MuscleWorkspace) -> Option<&SweepPlan> {
    ws.plan.as_ref().map(|(_, plan)| plan.sweep())
}

/// The Jacobi incidence of `m`, built when missing or stale.
fn jacobi_for<'w>(
    m: &Muscle,
    ws: &'w mut MuscleWorkspace,
    order: &[ConstraintKind],
) -> &'w mut JacobiState {
    let topology = m.topology();
    if !matches!(&ws.jacobi, Some((t, _)) if *t == topology) {
        ws.jacobi = Some((topology, JacobiState::new(m, order)));
    }
    &mut ws.jacobi.as_mut().expect("just built").1
}

/// The end of an iteration's projection: Hybrid's Jacobi tail, a Volume
/// that a coloured or Jacobi pass left out from the middle of the order,
/// the bone contacts, then a trailing Volume.
pub fn finish<T: TargetSet + Sync + ?Sized>(
    m: &mut Muscle,
    ws: &mut MuscleWorkspace,
    targets: &T,
    p: &IterationParams,
) {
    let f = &p.substep.frame;
    let (order, inv_h2, split) = (f.order.as_slice(), p.substep.inv_h2, f.parallelism.muscles);
    let (_, trailing) = split_volume(order);
    let plan = plan_kind_of(m, f.method);
    // Only a plain Gauss–Seidel pass projected a Volume in the middle of
    // the order itself.
    let plain_gauss_seidel = plan.is_none() && f.method == SolverMethod::Sequential;
    if !plain_gauss_seidel {
        if let (Some((_, omega)), Some((_, plan))) = (plan, &mut ws.plan) {
            plan.project_tail(m, inv_h2, omega, split);
        }
        if !trailing && order.contains(&ConstraintKind::Volume) {
            project_volume(m, p, inv_h2, split);
        }
    }
    if p.contacts_bones(m) {
        bone_contacts(m, ws, targets, p.first_of_substep(), split);
    }
    if trailing {
        project_volume(m, p, inv_h2, split);
    }
}

/// The colour plan `m` runs on under `method` and its Jacobi ω: the
/// method's own ([`plan_kind`]), or for a surface layer under
/// `Sequential` the per-constraint colouring (see
/// [`SolverMethod::Sequential`]); `None`: a plain Gauss–Seidel pass, or
/// Jacobi.
pub fn plan_kind_of(m: &Muscle, method: SolverMethod) -> Option<(PlanKind, f32)> {
    match method {
        SolverMethod::Sequential if m.params.is_surface_layer() => {
            Some((PlanKind::PerConstraint, 1.0))
        }
        _ => plan_kind(method),
    }
}

/// The colour plan a method runs on and its Jacobi ω (1 without a tail);
/// `None` for the uncoloured methods.
pub fn plan_kind(method: SolverMethod) -> Option<(PlanKind, f32)> {
    match method {
        SolverMethod::Colored {
            scope: ColorScope::PerMuscle,
        } => Some((PlanKind::PerConstraint, 1.0)),
        SolverMethod::Colored {
            scope: ColorScope::Global,
        } => Some((PlanKind::Clustered, 1.0)),
        SolverMethod::Hybrid { min_group, omega } => Some((PlanKind::Hybrid { min_group }, omega)),
        SolverMethod::Sequential | SolverMethod::Jacobi { .. } => None,
    }
}

/// Moves every attachment goal of `m` to its bone's pose at the substep's
/// end (`pose(bone)`; `None`: the world) — its end groups turned about
/// their tendons' tips where the muscle's held line says
/// ([`crate::muscle::MuscleParams::tendon_pivot`]) — and every Bind goal to its
/// vertex's skinned position for the poses of the binding's bones
/// (`bind_pose(bone)`: a host that numbers a muscle's attachment bones on
/// their own, as the Bevy plug-in does, numbers the binding's apart).
pub fn update_attachment_goals(
    m: &mut Muscle,
    pose: &impl Fn(Option<usize>) -> Affine3A,
    bind_pose: &impl Fn(usize) -> Affine3A,
) {
    let mut k = 0;
    for (i, a) in m.attachments.iter().enumerate() {
        let t = pose(a.bone);
        m.constraints.attach.goal[i] = t.transform_point3(a.vertex_local);
        if a.internal_particle.is_some() {
            m.constraints.branch_attach.goal[k] = t.transform_point3(a.internal_local);
            k += 1;
        }
    }
    let shape = LineShape::of(&m.params);
    let line = m
        .hold_line
        .as_mut()
        .map(|line| line.pose_kept(bind_pose, shape));
    if let (Some(hold), Some(now)) = (&m.hold_line, &line) {
        let c = &mut m.constraints;
        hold.turn_attachments(
            now,
            &m.attachments,
            &mut c.attach.goal,
            &mut c.branch_attach.goal,
        );
    }
    crate::muscle::update_bind_goals_in(m, bind_pose, line.as_ref());
}

/// Explicit Euler prediction with gravity and damping: over a substep of
/// `h` seconds the velocity keeps `e^(−c h)` (`c` =
/// [`crate::muscle::MuscleParams::damping`], per second), so the decay per
/// second is the same at any frame rate and substep count.
/// A damping map ([`crate::muscle::VertexMaps::damping`]) scales `c` per
/// surface vertex.
fn integrate(m: &mut Muscle, gravity: Vec3, h: f32) {
    let keep = (-m.params.damping * h).exp();
    match m.maps.damping.as_deref() {
        None => {
            for i in 0..m.x.len() {
                let v = (m.v[i] + h * gravity) * keep;
                m.v[i] = v;
                m.p[i] = m.x[i] + h * v;
            }
        }
        Some(scale) => {
            for i in 0..m.x.len() {
                let keep = scale
                    .get(i)
                    .map_or(keep, |s| (-m.params.damping * s * h).exp());
                let v = (m.v[i] + h * gravity) * keep;
                m.v[i] = v;
                m.p[i] = m.x[i] + h * v;
            }
        }
    }
}

/// `order` without a trailing Volume, and whether it had one.
pub(super) fn split_volume(order: &[ConstraintKind]) -> (&[ConstraintKind], bool) {
    match order.split_last() {
        Some((ConstraintKind::Volume, rest)) => (rest, true),
        _ => (order, false),
    }
}

/// Projects the Volume constraint of `m`, if it has one, as far as
/// iteration `p` asks (a large mesh's evaluation as a parallel reduction
/// when `split`, same result).
pub(super) fn project_volume(m: &mut Muscle, p: &IterationParams, inv_h2: f32, split: bool) {
    let how = p.volume_projection(m);
    if let Some(v) = &mut m.constraints.volume {
        v.solve_with(&mut m.p, &m.w, inv_h2, split, how);
    }
}

/// One Gauss–Seidel pass over a batch, handed to the constraint table to
/// get its concrete type (the kernel inlined into the loop).
struct Solve<'a> {
    p: &'a mut [Vec3],
    w: &'a [f32],
    inv_h2: f32,
    /// The batch's constraints that are on, where a list is kept.
    on: Option<&'a [u32]>,
}

impl BatchFnMut for Solve<'_> {
    type Output = ();

    #[inline(always)]
    fn call<B: ConstraintBatch>(self, batch: &mut B) {
        match self.on {
            Some(on) => batch.solve_listed(on, self.p, self.w, self.inv_h2),
            None => batch.solve(self.p, self.w, self.inv_h2),
        }
    }
}

/// Projects every constraint of `m` once, type by type in `order` (BE6,
/// Gauss–Seidel; the Volume to convergence).
pub fn gauss_seidel(m: &mut Muscle, order: &[ConstraintKind], inv_h2: f32) {
    gauss_seidel_over(m, order, inv_h2, None, VolumeProjection::Converge);
}

/// [`gauss_seidel`] visiting only the Soft, Hard and Sliding constraints
/// listed in `on` (those that are on: the others are no-ops, and the
/// anatomy scenes have every Soft and Hard off, T7 2 × 20 448 of them,
/// and three Sliding vertices in four out of every contact band), and
/// the Volume as far as `volume` says.
pub(crate) fn gauss_seidel_over(
    m: &mut Muscle,
    order: &[ConstraintKind],
    inv_h2: f32,
    on: Option<&SwitchedOn>,
    volume: VolumeProjection,
) {
    let (p, w, c) = (&mut m.p, &m.w, &mut m.constraints);
    for &kind in order {
        let on = on.and_then(|on| on.of(kind));
        let solve = Solve { p, w, inv_h2, on };
        if c.with_batch_mut(kind, solve).is_none()
            && let Some(v) = &mut c.volume
        {
            v.solve_with(p, w, inv_h2, false, volume);
        }
    }
}
