//! The skin's figures: vertices inside what they slide on, distance from
//! the plain skinned position, and the bulge over active muscles.

use super::inside_by;
use crate::closest::{TargetSource, TargetSurface};
use crate::muscle::Muscle;
use crate::solver::Solver;
use glam::{Affine3A, Vec3};

/// The skins ([`Muscle::is_skin`]), with their indices.
fn skins(solver: &Solver) -> impl Iterator<Item = (usize, &Muscle)> {
    solver
        .muscles()
        .iter()
        .enumerate()
        .filter(|(_, m)| m.is_skin())
}

/// The target surfaces body `body` slides on (the solver's own resolution).
fn targets_of(solver: &Solver, body: usize) -> Vec<&TargetSurface> {
    solver.workspaces()[body]
        .target_ids
        .iter()
        .map(|t| &solver.targets()[t.index()])
        .collect()
}

/// Per skin, `(body, surface vertices inside one of its
/// own targets — a muscle or a bone it slides on —, surface vertices)`;
/// other bodies are left out.
pub fn skin_inside_vertices(solver: &Solver) -> Vec<(usize, usize, usize)> {
    skins(solver)
        .map(|(i, m)| {
            let targets = targets_of(solver, i);
            let inside = m.x[..m.surface_count]
                .iter()
                .filter(|&&x| targets.iter().any(|t| inside_by(t, x, 0.0)))
                .count();
            (i, inside, m.surface_count)
        })
        .collect()
}

/// How far one skin is from where its binding puts it ([`skin_bind_distances`]).
///
/// Judged where no muscle is active: a skin vertex whose nearest target is a
/// muscle with an activation above zero is meant to move with that muscle's
/// bulge, and is reported apart (`active_*`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkinBindDistance {
    /// The skin body.
    pub skin: usize,
    /// Largest distance of a bound vertex from its skinned position, of
    /// those not over an active muscle. Units: m.
    pub max: f32,
    /// The vertex of the largest.
    pub vertex: u32,
    /// Bound vertices not over an active muscle farther than the limit
    /// asked for.
    pub over: usize,
    /// Bound vertices not over an active muscle.
    pub bound: usize,
    /// Bound vertices over an active muscle (nearest target a muscle with
    /// an activation above zero), left out of `max`, `over` and `bound`.
    pub active_bound: usize,
    /// Largest distance from the skinned position of a vertex over an
    /// active muscle. Units: m.
    pub active_max: f32,
}

/// Per skin, how far its bound vertices are from their skinned positions
/// for the bones' current poses: the largest and how many are farther
/// than `limit` (m), over the vertices where no muscle is active, and the
/// largest over active muscles apart ([`SkinBindDistance`]).
pub fn skin_bind_distances(solver: &Solver, limit: f32) -> Vec<SkinBindDistance> {
    let pose = |b: usize| solver.bones()[b].transform;
    let muscles = solver.muscles();
    skins(solver)
        .map(|(i, m)| {
            let targets = targets_of(solver, i);
            let mut d = SkinBindDistance {
                skin: i,
                max: 0.0,
                vertex: 0,
                over: 0,
                bound: 0,
                active_bound: 0,
                active_max: 0.0,
            };
            for b in &m.binding {
                let x = m.x[b.vertex.index()];
                let far = (x - b.goal(&pose)).length() / m.length_unit;
                let over_active = nearest_target(&targets, x).is_some_and(|t| {
                    matches!(targets[t].source,
                        TargetSource::Muscle(j) if muscles[j].params.activation > 0.0)
                });
                if over_active {
                    d.active_bound += 1;
                    d.active_max = d.active_max.max(far);
                    continue;
                }
                d.bound += 1;
                d.over += usize::from(far > limit);
                if far > d.max {
                    (d.max, d.vertex) = (far, b.vertex.raw());
                }
            }
            d
        })
        .collect()
}

/// How far a skin stands out of its plain skinned surface over one active
/// muscle: the skin's bulge, what a muscle simulation adds to linear-blend
/// skinning ([`skin_bulges`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkinBulge {
    /// The skin body.
    pub skin: usize,
    /// The muscle under it.
    pub muscle: usize,
    /// The muscle's activation.
    pub activation: f32,
    /// Skin vertices over the muscle: bound vertices whose nearest target
    /// (of those the skin slides on) is this muscle.
    pub vertices: usize,
    /// Largest outward displacement of one of them from its skinned
    /// position, along the skinned surface's normal there. Units: m.
    pub max: f32,
    /// Median of those displacements. Units: m.
    pub median: f32,
    /// The skin vertex of the largest.
    pub vertex: u32,
}

/// The bulge of every skin over each muscle under it with an activation of
/// at least `min_activation` ([`SkinBulge`]); muscles with no skin vertex
/// over them are left out. A positive figure is skin pushed out of the
/// skinned surface. Measured at the bones' current poses.
pub fn skin_bulges(solver: &Solver, min_activation: f32) -> Vec<SkinBulge> {
    let muscles = solver.muscles();
    let active = |t: &TargetSurface| match t.source {
        TargetSource::Muscle(j) => (muscles[j].params.activation >= min_activation).then_some(j),
        TargetSource::Bone(_) => None,
    };
    let pose = |b: usize| solver.bones()[b].transform;
    let mut out = Vec::new();
    for (skin, m) in skins(solver) {
        let targets = targets_of(solver, skin);
        if !targets.iter().any(|t| active(t).is_some()) {
            continue;
        }
        let skinned = skinned_surface(m, &pose);
        // Per active muscle, `(displacement, vertex)` of the vertices over it.
        let mut over: Vec<(usize, Vec<(f32, u32)>)> = Vec::new();
        for b in &m.binding {
            let v = b.vertex.index();
            let (goal, normal) = skinned[v];
            let Some(t) = nearest_target(&targets, m.x[v]) else {
                continue;
            };
            let Some(j) = active(targets[t]) else {
                continue;
            };
            let outward = (m.x[v] - goal).dot(normal) / m.length_unit;
            match over.iter_mut().find(|(k, _)| *k == j) {
                Some((_, list)) => list.push((outward, v as u32)),
                None => over.push((j, vec![(outward, v as u32)])),
            }
        }
        for (muscle, mut list) in over {
            list.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (max, vertex) = *list.last().expect("a muscle is listed with a vertex");
            out.push(SkinBulge {
                skin,
                muscle,
                activation: muscles[muscle].params.activation,
                vertices: list.len(),
                max,
                median: list[list.len() / 2].0,
                vertex,
            });
        }
    }
    out
}

/// Per surface vertex of a skin `m`, its linear-blend skinned position for
/// the bone poses `pose` (solver bone index → world from bone) and the
/// skinned surface's unit normal there (area-weighted over its triangles):
/// the character's plain skinning, what the simulated skin is compared
/// with. An unbound vertex keeps its current position.
pub fn skinned_surface(m: &Muscle, pose: &impl Fn(usize) -> Affine3A) -> Vec<(Vec3, Vec3)> {
    let mut goal: Vec<Vec3> = m.x[..m.surface_count].to_vec();
    for b in &m.binding {
        goal[b.vertex.index()] = b.goal(pose);
    }
    let mut normal = vec![Vec3::ZERO; goal.len()];
    for t in &m.mesh.triangles {
        let [a, b, c] = t.map(|i| i as usize);
        let n = (goal[b] - goal[a]).cross(goal[c] - goal[a]);
        for k in [a, b, c] {
            normal[k] += n;
        }
    }
    goal.into_iter()
        .zip(normal)
        .map(|(g, n)| (g, n.normalize_or_zero()))
        .collect()
}

/// Index in `targets` of the target nearest to `x`, if any has triangles.
fn nearest_target(targets: &[&TargetSurface], x: Vec3) -> Option<usize> {
    let mut best: Option<(f32, usize)> = None;
    for (i, t) in targets.iter().enumerate() {
        let bound = best.map_or(f32::INFINITY, |b| b.0);
        if t.lower_bound(x) >= bound {
            continue;
        }
        if let Some(hit) = t.closest_within(x, None, bound)
            && hit.distance < bound
        {
            best = Some((hit.distance, i));
        }
    }
    best.map(|b| b.1)
}
