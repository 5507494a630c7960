//! Debug gizmos (feature `debug`): [`SinewDebugPlugin`].
//!
//! Draws, per muscle and as the [`SinewDebugView`] resource asks: fibre
//! directions coloured by activation, the internal structure (Internal and
//! Branch constraints), attachments and their goals, the Sliding / Soft /
//! Hard links to the targets, and the colour groups of the coloured method.

use crate::components::{MuscleState, SolverWorkspace};
use bevy::prelude::*;
use sinew_core::muscle::ConstraintKind;
use sinew_core::solver::coloring::{ColorPlan, PlanKind, particles_of};
use std::collections::HashMap;

/// Which debug views are drawn.
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Resource)]
pub struct SinewDebugView {
    /// Fibre direction at each surface vertex, coloured by activation.
    pub fibers: bool,
    /// Internal points and their Internal / Branch constraints.
    pub internal: bool,
    /// Attachment particles and their goals on the bones.
    pub attachments: bool,
    /// Sliding: particle → closest point on its target.
    pub sliding: bool,
    /// Soft: particle → its goal on the target.
    pub soft: bool,
    /// Hard: particle → its goal in the target's local frame.
    pub hard: bool,
    /// Constraints coloured by colour group.
    pub colors: bool,
}

impl Default for SinewDebugView {
    fn default() -> Self {
        Self {
            fibers: false,
            internal: false,
            attachments: true,
            sliding: false,
            soft: false,
            hard: false,
            colors: false,
        }
    }
}

/// Adds [`SinewDebugView`] and the gizmo system.
#[derive(Clone, Debug, Default)]
pub struct SinewDebugPlugin;

impl Plugin for SinewDebugPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<SinewDebugView>()
            .register_type::<SinewDebugView>()
            .add_systems(PostUpdate, draw.after(crate::SinewSystems::Step));
    }
}

fn hue(i: usize) -> Color {
    Color::hsl((i as f32 * 137.508) % 360.0, 0.85, 0.55)
}

fn draw(
    view: Res<SinewDebugView>,
    muscles: Query<(Entity, &MuscleState, &SolverWorkspace)>,
    mut gizmos: Gizmos,
    mut plans: Local<HashMap<Entity, ColorPlan>>,
) {
    let v = *view;
    for (entity, state, workspace) in &muscles {
        let m = &state.muscle;
        let k = &m.constraints;
        let p = &m.x;
        if v.fibers {
            let a = m.params.activation.clamp(0.0, 1.0);
            let color = Color::srgb(0.3, 0.5, 1.0).mix(&Color::srgb(1.0, 0.25, 0.1), a);
            let length = mean_edge(m) * 0.6;
            for (x, f) in p.iter().zip(&m.fibers).take(m.surface_count) {
                gizmos.line(*x - *f * length * 0.5, *x + *f * length * 0.5, color);
            }
        }
        if v.internal {
            for (batch, color) in [
                (&k.internal, Color::srgba(0.6, 0.8, 1.0, 0.35)),
                (&k.branch, Color::srgb(1.0, 1.0, 0.3)),
            ] {
                for (&a, &b) in batch.a.iter().zip(&batch.b) {
                    gizmos.line(p[a.index()], p[b.index()], color);
                }
            }
        }
        if v.attachments {
            for batch in [&k.attach, &k.branch_attach] {
                for (&i, goal) in batch.particle.iter().zip(&batch.goal) {
                    gizmos.line(p[i.index()], *goal, Color::srgb(0.1, 1.0, 0.3));
                    gizmos.sphere(*goal, 0.0015, Color::srgb(0.1, 1.0, 0.3));
                }
            }
        }
        if v.sliding {
            for (&i, contact) in k.sliding.particle.iter().zip(&k.sliding.contact) {
                gizmos.line(p[i.index()], contact.point, Color::srgb(0.2, 0.8, 1.0));
            }
        }
        for (on, batch, color) in [
            (v.soft, &k.soft, Color::srgb(1.0, 0.6, 0.9)),
            (v.hard, &k.hard, Color::srgb(1.0, 0.2, 0.2)),
        ] {
            if on {
                for (i, (&particle, goal)) in batch.particle.iter().zip(&batch.goal).enumerate() {
                    if batch.compliance[i].is_finite() {
                        gizmos.line(p[particle.index()], *goal, color);
                    }
                }
            }
        }
        if v.colors {
            // The plan the solver runs on, else the thesis' colouring.
            let plan = match workspace.0.plan() {
                Some(plan) => plan,
                None => plans.entry(entity).or_insert_with(|| {
                    ColorPlan::build(m, &ConstraintKind::CANONICAL_ORDER, PlanKind::PerConstraint)
                }),
            };
            // A pair as its edge, a triangle as its outline.
            let mut edge = |c, color| match particles_of(m, c) {
                [Some(a), Some(b), None] => gizmos.line(p[a.index()], p[b.index()], color),
                [Some(a), Some(b), Some(d)] => {
                    let [a, b, d] = [a, b, d].map(|k| p[k.index()]);
                    gizmos.linestrip([a, b, d, a], color);
                }
                _ => {}
            };
            for color in 0..plan.color_count() {
                for &c in plan.units_of(color).flatten() {
                    edge(c, hue(color));
                }
            }
            // Hybrid's Jacobi tail in grey.
            for &c in plan.tail() {
                edge(c, Color::srgb(0.5, 0.5, 0.5));
            }
        }
    }
    if !v.colors {
        plans.clear();
    }
}

fn mean_edge(m: &sinew_core::muscle::Muscle) -> f32 {
    let f = &m.constraints.fiber;
    if f.is_empty() {
        return 0.01;
    }
    f.a.iter()
        .zip(&f.b)
        .map(|(&a, &b)| m.x[a.index()].distance(m.x[b.index()]))
        .sum::<f32>()
        / f.len() as f32
}
