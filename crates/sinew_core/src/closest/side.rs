//! Which side of a rigid target a point is on.
//!
//! A hit's normal is interpolated from area-weighted vertex normals: smooth,
//! what Sliding wants to slide along, but at a sharp feature of a thin bone
//! (a rib's edge) the vertex normals average faces that face opposite
//! ways, and a point outside the bone reads as behind it. And scanned bones
//! are not clean: the full body's torso, head and neck have hundreds of
//! open edges, some flipped triangles and loose sheets (the skull's inner
//! pieces). On the fitted MakeHuman character a skin vertex 13 mm outside
//! the ribs, and another 15 mm outside the skull, read as inside every few
//! frames at rest: Sliding pulled each onto the bone and its binding pulled
//! it back, a 13 mm flicker.
//!
//! So a bone's side is read from the pseudo-normal of the feature the
//! closest point lies on (Bærentzen and Aanæs 2005): the face normal inside
//! a triangle, the sum of the two face normals on an edge, the
//! angle-weighted normal at a vertex; for a closed, consistently wound
//! surface `pseudo-normal · (query − closest point)` has the sign of the
//! side, exactly. A bone that is not closed and consistent is first wound
//! consistently and its triangles classified (the `faces` module): walls,
//! and loose sheets outside or inside it. Its features between two walls
//! keep their exact pseudo-normals; anywhere else (an open edge, a sheet, a
//! vertex touching one), and for any "inside" on such a bone, the bone's
//! winding number at the query decides (the `winding` module), remembered
//! per vertex by the caller ([`SideMemo`]).
//!
//! An interpolated normal that reads outside and leans less than 60° off
//! the direction to the query is taken at its word: a small motion cannot
//! turn it, and a wrong "outside" leaves a vertex where it is, where a wrong
//! "inside" throws it through the bone. Otherwise, where the side found
//! disagrees with the interpolated normal or it leans further, the hit's
//! normal becomes the direction from the closest point to the query,
//! pointing out of the surface: the gradient of the signed distance. Only rigid targets
//! carry this: it is computed once; a muscle's surface is smooth and
//! re-published every iteration; a flat one (a ground plane) has one exact
//! normal and no inside, and carries none. The solver reads sides this way
//! where a vertex was outside the bone at rest: a contact layer's (skin's)
//! closest data and bone contacts, and a muscle's bone contacts more than
//! `solver::bone_contacts::SIDE_READ_BEYOND` from the bone (read from the
//! interpolated normal, T5's brachialis ended its flexions thrown through a
//! bone, 18.8 mm from its rest shape 2 s after the motion stopped; 2.6 mm
//! read from the features).

use super::faces::{self, FaceKind};
use super::winding::WindingTree;
use super::{ClosestHit, TargetSurface, TriangleBvh};
use glam::{Vec3, Vec3A};

/// Face kinds and pseudo-normals of a rigid target, in its local frame
/// (empty for a deforming target).
#[derive(Clone, Debug, Default)]
pub(super) struct PseudoNormals {
    /// Unit outward normal of each wall (zero for a sheet).
    face: Vec<Vec3>,
    /// Angle-weighted unit normal of each vertex over its walls; zero where
    /// the vertex's fan is not closed (an open edge, a sheet or a third
    /// triangle on one of its edges), where no pseudo-normal is exact.
    vertex: Vec<Vec3>,
    /// Per triangle, bit `k`: its edge `k` has exactly one other triangle,
    /// a wall (its pseudo-normal is exact).
    closed_edges: Vec<u8>,
    /// What each triangle is.
    kind: Vec<FaceKind>,
    /// For a surface that is not closed and consistent: its triangles wound
    /// consistently and their winding number's dipoles, for the features
    /// no pseudo-normal decides.
    winding: Option<(Vec<[u32; 3]>, WindingTree)>,
}

/// Whether every triangle of the surface lies in one plane, facing one way.
fn is_flat(positions: &[Vec3], triangles: &[[u32; 3]]) -> bool {
    let normal = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        (b - a).cross(c - a).normalize_or_zero()
    };
    let Some(first) = triangles.first().map(normal) else {
        return false;
    };
    let origin = positions[triangles[0][0] as usize];
    let size = positions
        .iter()
        .map(|p| p.distance(origin))
        .fold(0.0f32, f32::max);
    first != Vec3::ZERO
        && triangles.iter().all(|t| normal(t).dot(first) > 1.0 - 1e-6)
        && positions
            .iter()
            .all(|p| (*p - origin).dot(first).abs() <= 1e-6 * size)
}

impl PseudoNormals {
    /// The face kinds and pseudo-normals of a surface with BVH `bvh`; none
    /// for a flat one (a ground plane), whose one normal is exact
    /// everywhere and which has no inside for a winding number to find.
    pub(super) fn new(positions: &[Vec3], triangles: &[[u32; 3]], bvh: &TriangleBvh) -> Self {
        if is_flat(positions, triangles) {
            return Self::default();
        }
        let edges = faces::edge_table(triangles);
        let (kind, oriented, winding) = if faces::closed_and_consistent(&edges) {
            (vec![FaceKind::Wall; triangles.len()], triangles, None)
        } else {
            let oriented = faces::orient(triangles, &edges);
            let tree = WindingTree::new(bvh, positions, &oriented);
            let kind = faces::classify(positions, &oriented, &tree);
            (kind, triangles, Some((oriented, tree)))
        };
        let oriented = winding.as_ref().map_or(oriented, |(o, _)| o.as_slice());
        // Unit outward normal of each wall.
        let face: Vec<Vec3> = oriented
            .iter()
            .zip(&kind)
            .map(|(t, k)| match k {
                FaceKind::Wall => {
                    let [a, b, c] = t.map(|i| positions[i as usize]);
                    (b - a).cross(c - a).normalize_or_zero()
                }
                FaceKind::Outside | FaceKind::Inside => Vec3::ZERO,
            })
            .collect();
        // An edge with exactly two triangles, both walls, has an exact
        // pseudo-normal; a vertex on any other edge has none.
        let closed = |a: u32, b: u32| {
            let on = &edges[&(a.min(b), a.max(b))];
            on.len() == 2 && on.iter().all(|&(t, _)| kind[t as usize] == FaceKind::Wall)
        };
        let closed_edges: Vec<u8> = triangles
            .iter()
            .map(|t| {
                (0..3).fold(0u8, |bits, e| {
                    bits | u8::from(closed(t[e], t[(e + 1) % 3])) << e
                })
            })
            .collect();
        let mut open = vec![false; positions.len()];
        for (t, bits) in triangles.iter().zip(&closed_edges) {
            for e in (0..3).filter(|e| bits >> e & 1 == 0) {
                open[t[e] as usize] = true;
                open[t[(e + 1) % 3] as usize] = true;
            }
        }
        let mut vertex = vec![Vec3::ZERO; positions.len()];
        for (t, n) in triangles.iter().zip(&face) {
            let p = t.map(|i| positions[i as usize]);
            for k in 0..3 {
                let angle = (p[(k + 1) % 3] - p[k]).angle_between(p[(k + 2) % 3] - p[k]);
                if angle.is_finite() {
                    vertex[t[k] as usize] += *n * angle;
                }
            }
        }
        for (n, open) in vertex.iter_mut().zip(open) {
            *n = if open {
                Vec3::ZERO
            } else {
                n.normalize_or_zero()
            };
        }
        Self {
            face,
            vertex,
            closed_edges,
            kind,
            winding,
        }
    }

    /// Whether there are none (a deforming target).
    pub(super) fn is_empty(&self) -> bool {
        self.kind.is_empty()
    }

    /// Which side of the surface a point whose closest point has barycentric
    /// `bary` in triangle `t` is on, from `offset` = query − closest point
    /// (local frame): positive outside, negative inside, 0 undecided;
    /// `None` where the feature has no exact pseudo-normal (the winding
    /// number decides). `corners` are `t`'s vertices, `across` the
    /// triangles across its edges.
    fn side(
        &self,
        t: u32,
        corners: [u32; 3],
        across: [u32; 3],
        bary: Vec3,
        offset: Vec3,
    ) -> Option<f32> {
        let face = self.face[t as usize];
        let closed = self.closed_edges[t as usize];
        let edge = |k: usize| (closed >> k & 1 == 1).then(|| face + self.face[across[k] as usize]);
        let vertex = |k: usize| Some(self.vertex[corners[k] as usize]).filter(|n| *n != Vec3::ZERO);
        let pseudo = match (bary.x > 0.0, bary.y > 0.0, bary.z > 0.0) {
            (true, true, false) => edge(0),
            (false, true, true) => edge(1),
            (true, false, true) => edge(2),
            (true, false, false) => vertex(0),
            (false, true, false) => vertex(1),
            (false, false, true) => vertex(2),
            // Inside the triangle (or a degenerate one): a wall's plane; a
            // sheet's (or a duplicate's) is no evidence either way.
            _ => (self.kind[t as usize] == FaceKind::Wall).then_some(face),
        };
        pseudo.map(|n| n.dot(offset))
    }
}

/// What the last winding-number decisions of a vertex's sides of its
/// bones cover, kept by the caller per vertex for
/// [`TargetSurface::settle_side`]: for each, the bone (the caller's name
/// for it), the point it was taken at (the bone's frame) and its exact
/// distance from the bone, signed (positive outside). A point within that
/// distance of one is on the same side: the bone is rigid and no closer
/// there. Several, because a vertex at rest visits two places each step
/// (where gravity predicts it, g·dt² lower, 2.7 mm at 60 Hz, and where its
/// constraints put it back), and a vertex near a joint is near two bones,
/// which its closest data and its bone contacts both ask about.
///
/// Beside them, balls reached from one (`reached`): a point whose own ball
/// free of the bone overlaps a decision's is on the same side too (the two
/// balls make one region the surface does not cross), which one bounded
/// closest-point search tells, for a fifth of a winding number's cost. A
/// vertex that sinks into a bone and is put back on it every few
/// iterations asks again each time a few millimetres from where it last
/// asked, out of that ball but most often within reach of it. Only a
/// winding number's ball is reached from, so a side is never carried
/// further than two balls from where a winding number read it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SideMemo {
    /// `(bone, point, signed distance)` decided by a winding number, the
    /// newest first; `u32::MAX`: empty.
    taken: [(u32, Vec3, f32); SideMemo::ENTRIES],
    /// `(bone, point, signed radius)` of balls reached from one of `taken`,
    /// the newest first; `u32::MAX`: empty.
    reached: [(u32, Vec3, f32); SideMemo::REACHED],
}

impl Default for SideMemo {
    fn default() -> Self {
        const EMPTY: (u32, Vec3, f32) = (u32::MAX, Vec3::ZERO, 0.0);
        Self {
            taken: [EMPTY; SideMemo::ENTRIES],
            reached: [EMPTY; SideMemo::REACHED],
        }
    }
}

impl SideMemo {
    /// Winding-number decisions remembered per vertex.
    pub const ENTRIES: usize = 8;

    /// Balls reached from them remembered per vertex.
    pub const REACHED: usize = 4;

    /// The side of `bone` it remembers at local point `q` (positive
    /// outside), if `q` is within a ball it holds.
    fn side_at(&self, bone: u32, q: Vec3) -> Option<f32> {
        self.taken
            .iter()
            .chain(&self.reached)
            .find(|&&(b, at, clearance)| {
                b == bone && q.distance_squared(at) < clearance * clearance
            })
            .map(|&(.., clearance)| clearance)
    }

    /// The winding-number decision about `bone` whose ball is nearest
    /// local point `q` (outside all of them): how far `q` is from that ball,
    /// and its signed distance.
    fn nearest_decision(&self, bone: u32, q: Vec3) -> Option<(f32, f32)> {
        self.taken
            .iter()
            .filter(|&&(b, _, clearance)| b == bone && clearance != 0.0)
            .map(|&(_, at, clearance)| (q.distance(at) - clearance.abs(), clearance))
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// Remembers a decision about `bone` at `q` with signed distance
    /// `clearance`, forgetting the oldest.
    fn take(&mut self, bone: u32, q: Vec3, clearance: f32) {
        self.taken.copy_within(..Self::ENTRIES - 1, 1);
        self.taken[0] = (bone, q, clearance);
    }

    /// Remembers a ball of signed radius `radius` around `q`, reached from
    /// a decision about `bone`, forgetting the oldest such ball.
    fn reach(&mut self, bone: u32, q: Vec3, radius: f32) {
        self.reached.copy_within(..Self::REACHED - 1, 1);
        self.reached[0] = (bone, q, radius);
    }
}

impl TargetSurface {
    /// `hit`, a closest point of this target to world `query`, with its side
    /// settled on a rigid target (module docs): a hit whose interpolated
    /// normal reads outside within 60° of the direction to the query is
    /// returned as it is; any other has its side read from the feature it
    /// lies on, and its normal turned to the direction from the point to
    /// the query where the interpolated one reads the other side or leans
    /// further. A deforming target's hit is returned as it is.
    ///
    /// Cheap where the feature has an exact pseudo-normal. Elsewhere (an
    /// open or non-manifold part of a scanned bone, or an "inside" on one)
    /// it costs a winding number and a full closest-point search,
    /// remembered in `memo` (per vertex, see [`SideMemo`]) under `bone`,
    /// the caller's name for this target: the next call about it from
    /// within that distance reuses the answer. Callers ask only where the
    /// side matters: a vertex outside the bone at rest.
    pub fn settle_side(
        &self,
        query: Vec3,
        hit: ClosestHit,
        memo: &mut SideMemo,
        bone: u32,
    ) -> ClosestHit {
        let p = &self.geometry.pseudo_normals;
        // A deforming target; or a smooth normal that reads outside and
        // leans less than 60° off the direction to the query, which a small
        // motion cannot turn (wrong, it leaves a vertex inside where it is;
        // a wrong "inside" throws one through the bone).
        if p.is_empty() || hit.signed_distance >= 0.5 * hit.distance {
            return hit;
        }
        let q = self.to_local(query);
        let t = hit.triangle as usize;
        let exact = p.side(
            hit.triangle,
            self.geometry.triangles[t],
            self.geometry.across_edge[t],
            hit.barycentric.into(),
            q - self.to_local(hit.point.into()),
        );
        let side = match (exact, &p.winding) {
            // Outside, or a clean surface's exact answer.
            (Some(side), _) if side > 0.0 => side,
            (Some(side), None) => side,
            (None, None) => 0.0,
            // A broken surface's "inside" (or no answer): a wrong "inside"
            // throws the vertex through the bone, so the winding number
            // decides, remembered for the next call nearby.
            (_, Some((_, tree))) => match memo.side_at(bone, q) {
                Some(side) => side,
                None => match self.reached_side(query, q, hit, memo, bone) {
                    Ok(side) => side,
                    Err(searched) => {
                        let side = tree.side(q);
                        let distance = searched.unwrap_or_else(|| self.exact_distance(query, hit));
                        memo.take(bone, q, distance.copysign(side));
                        side
                    }
                },
            },
        };
        with_side(hit, query, side)
    }
}

#[cfg(test)]
impl SideMemo {
    /// The newest winding-number decision and the newest ball reached
    /// (which changed tells what a call did).
    pub(super) fn newest(&self) -> [(u32, Vec3, f32); 2] {
        [self.taken[0], self.reached[0]]
    }
}

impl TargetSurface {
    /// The exact distance from world `query` to the surface, `hit` being a
    /// closest point found so far (a walk's): the search starts from its
    /// triangle, whose distance then bounds it.
    fn exact_distance(&self, query: Vec3, hit: ClosestHit) -> f32 {
        self.closest_within(query, Some(hit.triangle), f32::MAX)
            .map_or(0.0, |h| h.distance)
    }

    /// The side of world `query` (local `q`, whose closest point found so
    /// far is `hit`) as a ball free of the surface reaching the nearest of
    /// `memo`'s winding-number decisions about `bone` tells it
    /// ([`SideMemo`]), remembered in `memo`. `Err` where no decision is
    /// near enough for one bounded search to tell, with the exact distance
    /// where that search ran (the winding-number decision that follows
    /// needs it).
    fn reached_side(
        &self,
        query: Vec3,
        q: Vec3,
        hit: ClosestHit,
        memo: &mut SideMemo,
        bone: u32,
    ) -> Result<f32, Option<f32>> {
        let (gap, side) = memo.nearest_decision(bone, q).ok_or(None)?;
        // A ball a little larger than the gap overlaps the decision's.
        if hit.distance <= gap * (1.0 + 1e-3) + 1e-7 {
            return Err(None);
        }
        let exact = self.exact_distance(query, hit);
        if exact <= gap * (1.0 + 1e-3) + 1e-7 {
            return Err(Some(exact));
        }
        let radius = exact.copysign(side);
        memo.reach(bone, q, radius);
        Ok(radius)
    }
}

/// `hit` with its side set by `side` (positive outside, negative inside, 0
/// undecided): where the hit's interpolated normal reads the other side, or
/// leans more than 60° off the direction from the point to the query (a
/// point a centimetre from a rib's edge whose normal is nearly
/// perpendicular to it reads the other side after a millimetre's motion),
/// the normal becomes that unit direction, signed to point out of the
/// surface, and the signed distance follows (module docs).
fn with_side(mut hit: ClosestHit, query: Vec3, side: f32) -> ClosestHit {
    let agrees = side * hit.signed_distance > 0.0 || side == 0.0;
    if agrees && hit.signed_distance.abs() >= 0.5 * hit.distance {
        return hit;
    }
    let Some(direction) = (Vec3A::from(query) - hit.point).try_normalize() else {
        return hit;
    };
    let sign = if side != 0.0 {
        side.signum()
    } else {
        hit.signed_distance.signum()
    };
    if sign == 0.0 {
        return hit;
    }
    hit.normal = direction * sign;
    hit.signed_distance = hit.distance * sign;
    hit
}
