//! The internal structure ("ring medulla", SPEC §7.2, PROPOSED there).
//!
//! ```text
//! 1. level ℓ(v): BFS hops over mesh edges from the root vertices
//! 2. bands S_ℓ = {v : ℓ(v) = ℓ}, split into connected components K
//! 3. one internal point per component with |K| ≥ min_ring, at its centroid,
//!    unless the centroid lies near one of its vertices (a strip or an arc
//!    of a ring, where bands from two roots meet: a point on the surface
//!    holds nothing, and a zero-length link has no direction)
//! 4. Branch edges: P(K) — P(K') for K' at ℓ−1 sharing a mesh edge with K
//!    (across point-less levels to the nearest lower level with points);
//!    optionally link siblings (same level, common parent or child)
//! 5. Internal links: every vertex → its component's point; tips (point-less
//!    components) → the nearest point one ring beyond the nearest points
//! ```
//! A UV sphere with a pole root gives one point per latitude ring: 9 points,
//! 8 Branch and 92 Internal for the thesis' oval (Table 5.1).

use crate::mesh::SurfaceMesh;
use glam::Vec3;
use std::collections::BTreeSet;

/// Options for [`InternalStructure::build`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InternalStructureParams {
    /// Build the structure at all (the thesis' SMT-G* build turns it off). Default: `true`.
    pub enabled: bool,
    /// Components smaller than this get no point (poles, tendon tips). Default: `3`.
    pub min_ring: u32,
    /// Add Branch edges between sibling points (SPEC §7.2 `link_siblings`). Default: `true`.
    pub link_siblings: bool,
}

impl Default for InternalStructureParams {
    fn default() -> Self {
        Self {
            enabled: true,
            min_ring: 3,
            link_siblings: true,
        }
    }
}

/// The generated medulla of one muscle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InternalStructure {
    /// Rest positions of the internal points.
    pub points: Vec<Vec3>,
    /// BFS level of each point's ring.
    pub levels: Vec<u32>,
    /// Branch edges between internal points (point indices).
    pub branches: Vec<[u32; 2]>,
    /// For every surface vertex, the internal point it is linked to.
    pub vertex_point: Vec<u32>,
    /// Unit branch tangent per point (its own fibre direction).
    pub tangents: Vec<Vec3>,
    /// Number of points where the tree splits (three or more tree edges).
    pub bifurcations: usize,
}

impl InternalStructure {
    /// Builds the structure from root vertices (assumed in range and non-empty).
    pub fn build(mesh: &SurfaceMesh, roots: &[u32], params: &InternalStructureParams) -> Self {
        let n = mesh.vertex_count();
        // 1. BFS levels.
        let mut level = vec![u32::MAX; n];
        for (v, hops) in mesh.breadth_first(roots) {
            level[v as usize] = hops;
        }
        // Vertices unreachable from the roots (another shell) form their own levels.
        let max_level = level
            .iter()
            .filter(|&&l| l != u32::MAX)
            .max()
            .copied()
            .unwrap_or(0);
        for l in level.iter_mut().filter(|l| **l == u32::MAX) {
            *l = max_level + 1;
        }
        // 2. Components of each band (union-find over same-level edges).
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(parent: &mut [u32], mut x: u32) -> u32 {
            while parent[x as usize] != x {
                parent[x as usize] = parent[parent[x as usize] as usize];
                x = parent[x as usize];
            }
            x
        }
        for &[a, b] in &mesh.edges {
            if level[a as usize] == level[b as usize] {
                let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
                if ra != rb {
                    parent[ra.max(rb) as usize] = ra.min(rb);
                }
            }
        }
        let mut component_of = vec![u32::MAX; n];
        let mut components: Vec<Vec<u32>> = Vec::new();
        let mut root_component = std::collections::HashMap::new();
        for v in 0..n as u32 {
            let r = find(&mut parent, v);
            let c = *root_component.entry(r).or_insert_with(|| {
                components.push(Vec::new());
                components.len() as u32 - 1
            });
            components[c as usize].push(v);
            component_of[v as usize] = c;
        }
        let comp_level: Vec<u32> = components.iter().map(|k| level[k[0] as usize]).collect();
        // Component adjacency split into lower / upper neighbours.
        let nc = components.len();
        let mut lower: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); nc];
        let mut upper: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); nc];
        for &[a, b] in &mesh.edges {
            let (ca, cb) = (component_of[a as usize], component_of[b as usize]);
            if ca == cb {
                continue;
            }
            let (la, lb) = (comp_level[ca as usize], comp_level[cb as usize]);
            if la < lb {
                upper[ca as usize].insert(cb);
                lower[cb as usize].insert(ca);
            } else if lb < la {
                upper[cb as usize].insert(ca);
                lower[ca as usize].insert(cb);
            }
        }
        // 3. Points, processed level by level.
        let mut order: Vec<u32> = (0..nc as u32).collect();
        order.sort_by_key(|&c| (comp_level[c as usize], c));
        let mut point_of = vec![u32::MAX; nc];
        let mut anchors: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); nc];
        let mut s = Self::default();
        let mut branch_set = BTreeSet::new();
        for &c in &order {
            let k = &components[c as usize];
            let inherited: BTreeSet<u32> = lower[c as usize]
                .iter()
                .flat_map(|&p| anchors[p as usize].iter().copied())
                .collect();
            let centroid =
                k.iter().map(|&v| mesh.positions[v as usize]).sum::<Vec3>() / k.len() as f32;
            if k.len() >= params.min_ring as usize && surrounds(mesh, k, centroid) {
                let id = s.points.len() as u32;
                s.points.push(centroid);
                s.levels.push(comp_level[c as usize]);
                point_of[c as usize] = id;
                for &a in &inherited {
                    branch_set.insert([a.min(id), a.max(id)]);
                }
                anchors[c as usize] = BTreeSet::from([id]);
            } else {
                anchors[c as usize] = inherited;
            }
        }
        // Bifurcations: points where the tree splits (≥ 3 tree edges).
        let mut degree = vec![0usize; s.points.len()];
        for &[a, b] in &branch_set {
            degree[a as usize] += 1;
            degree[b as usize] += 1;
        }
        s.bifurcations = degree.iter().filter(|&&d| d >= 3).count();
        // Sibling links: same level, a common lower or upper point.
        let tree_edges: Vec<[u32; 2]> = branch_set.iter().copied().collect();
        if params.link_siblings {
            let np = s.points.len();
            let mut adj: Vec<Vec<u32>> = vec![Vec::new(); np];
            for &[a, b] in &tree_edges {
                adj[a as usize].push(b);
                adj[b as usize].push(a);
            }
            for p in 0..np {
                for &q in &adj[p] {
                    let siblings: Vec<u32> = adj[q as usize]
                        .iter()
                        .copied()
                        .filter(|&r| r as usize != p && s.levels[r as usize] == s.levels[p])
                        .collect();
                    for r in siblings {
                        branch_set.insert([(p as u32).min(r), (p as u32).max(r)]);
                    }
                }
            }
        }
        s.branches = branch_set.into_iter().collect();
        // 5. Internal links.
        s.vertex_point = vec![0; n];
        for (c, k) in components.iter().enumerate() {
            let candidates = if point_of[c] != u32::MAX {
                vec![point_of[c]]
            } else {
                nearest_points(c as u32, &lower, &upper, &point_of)
            };
            for &v in k {
                let pv = mesh.positions[v as usize];
                s.vertex_point[v as usize] = candidates
                    .iter()
                    .copied()
                    .min_by(|&a, &b| {
                        let da = s.points[a as usize].distance_squared(pv);
                        let db = s.points[b as usize].distance_squared(pv);
                        da.total_cmp(&db).then(a.cmp(&b))
                    })
                    .unwrap_or(0);
            }
        }
        s.tangents = tangents(&s.points, &s.levels, &tree_edges);
        s
    }
}

/// Whether a component's centroid lies inside it rather than on it: every
/// vertex at least [`SURROUND`] of the mean vertex distance away. A ring's
/// vertices are all about equally far; a strip of three vertices in a row
/// has its centroid on the middle one.
fn surrounds(mesh: &SurfaceMesh, component: &[u32], centroid: Vec3) -> bool {
    let distance = |&v: &u32| mesh.positions[v as usize].distance(centroid);
    let mean = component.iter().map(distance).sum::<f32>() / component.len() as f32;
    component.iter().all(|v| distance(v) >= SURROUND * mean)
}

/// See [`surrounds`].
const SURROUND: f32 = 0.3;

/// Component-graph layers [`nearest_points`] searches (the reference scenes
/// and the anatomy find their points within a few).
const NEAREST_SEARCH_LAYERS: usize = 64;

/// Points for a point-less component (a tip): those of the *second* layer of
/// point-bearing components by component-graph distance, or the first when
/// there is no second. A tip and its neighbouring ring are nearly coplanar with
/// that ring's centroid, so a link there cannot resist the tip folding through
/// the ring (every length is preserved by that reflection); a link one ring
/// further gives it a lever. The search stops after [`NEAREST_SEARCH_LAYERS`]
/// layers: on a mesh whose bands are arcs rather than rings (quads far longer
/// around than along, where most components get no point) an unbounded
/// search from every component made the build quadratic — a fusiform of
/// 48 000 vertices took 262 s (fuzzing found a 786 000-vertex one running
/// for over 20 minutes).
fn nearest_points(
    start: u32,
    lower: &[BTreeSet<u32>],
    upper: &[BTreeSet<u32>],
    point_of: &[u32],
) -> Vec<u32> {
    let mut seen = BTreeSet::from([start]);
    let mut frontier = vec![start];
    let mut first: Option<Vec<u32>> = None;
    for _ in 0..NEAREST_SEARCH_LAYERS {
        if frontier.is_empty() {
            break;
        }
        let mut next = Vec::new();
        for c in frontier {
            for &d in lower[c as usize].iter().chain(upper[c as usize].iter()) {
                if seen.insert(d) {
                    next.push(d);
                }
            }
        }
        let found: Vec<u32> = next
            .iter()
            .filter(|&&d| point_of[d as usize] != u32::MAX)
            .map(|&d| point_of[d as usize])
            .collect();
        if !found.is_empty() {
            if first.is_some() {
                return found;
            }
            first = Some(found);
        }
        if next.is_empty() {
            break;
        }
        frontier = next;
    }
    first.unwrap_or_default()
}

/// Branch tangent per point: mean of upper neighbours minus mean of lower ones
/// (one-sided at the ends). Points without neighbours get +X.
fn tangents(points: &[Vec3], levels: &[u32], edges: &[[u32; 2]]) -> Vec<Vec3> {
    let np = points.len();
    let mut up = vec![(Vec3::ZERO, 0u32); np];
    let mut down = vec![(Vec3::ZERO, 0u32); np];
    for &[a, b] in edges {
        let (a, b) = (a as usize, b as usize);
        let (lo, hi) = if levels[a] <= levels[b] {
            (a, b)
        } else {
            (b, a)
        };
        up[lo].0 += points[hi];
        up[lo].1 += 1;
        down[hi].0 += points[lo];
        down[hi].1 += 1;
    }
    (0..np)
        .map(|i| {
            let next = if up[i].1 > 0 {
                up[i].0 / up[i].1 as f32
            } else {
                points[i]
            };
            let prev = if down[i].1 > 0 {
                down[i].0 / down[i].1 as f32
            } else {
                points[i]
            };
            (next - prev).try_normalize().unwrap_or(Vec3::X)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use crate::scene::builtin;
    use std::path::Path;

    #[test]
    fn no_vertex_sits_on_its_internal_point() {
        // P3's biceps: bands from its head and belly roots meet near the
        // junction, where a band component was a strip whose centroid lay on
        // a vertex (an Internal link of rest length 1e-9 m).
        let solver = builtin("P3").unwrap().instantiate(Path::new(".")).unwrap();
        for m in solver.muscles() {
            let s = &m.structure;
            let links: Vec<f32> = (0..m.surface_count)
                .map(|v| m.rest[v].distance(s.points[s.vertex_point[v] as usize]))
                .collect();
            let mean = links.iter().sum::<f32>() / links.len() as f32;
            let shortest = links.iter().copied().fold(f32::INFINITY, f32::min);
            assert!(
                shortest > 0.1 * mean,
                "{}: {shortest} vs mean {mean}",
                m.name
            );
        }
    }
}
