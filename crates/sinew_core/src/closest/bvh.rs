//! A bounding-volume hierarchy over the triangles of one target, built once
//! and refitted in place.
//!
//! Targets keep their topology for the whole simulation; only positions
//! change. So the tree is built once (median split on the longest axis of
//! the triangle centroids, up to [`LEAF_SIZE`] triangles per leaf) and stored
//! with every child after its parent, which makes a refit one reverse sweep:
//! leaf boxes from their triangles, inner boxes from their two children.
//! That is about 40 instructions per triangle; parry3d's general-purpose
//! refit, which P3 used to call every frame, cost ≈ 15 times more.

use glam::{Vec3, Vec3A};

/// Most triangles in a leaf.
pub const LEAF_SIZE: usize = 4;

/// A box and its contents, 32 bytes (two to a cache line): the full
/// searches are bound by loading nodes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Node {
    min: Vec3,
    /// Leaf: first slot in `order`. Inner: index of the left child (the right
    /// child follows it).
    start: u32,
    max: Vec3,
    /// Leaf: number of triangles (≥ 1). Inner: 0.
    count: u32,
}

impl Node {
    /// The box corners, for SIMD arithmetic.
    #[inline(always)]
    fn corners(&self) -> (Vec3A, Vec3A) {
        (Vec3A::from(self.min), Vec3A::from(self.max))
    }

    /// Squared distance from `q` to the box grown by `slack`.
    #[inline(always)]
    fn distance_squared(&self, q: Vec3A, slack: f32) -> f32 {
        let (min, max) = self.corners();
        let outside = (min - q).max(q - max).max(Vec3A::ZERO);
        if slack == 0.0 {
            outside.length_squared()
        } else {
            (outside.length() - slack).max(0.0).powi(2)
        }
    }
}

/// What a node of a [`TriangleBvh`] holds.
pub(super) enum NodeContents<'a> {
    /// Triangles.
    Leaf(&'a [u32]),
    /// Two children: this node index and the next.
    Inner(usize),
}

/// Bounding-volume hierarchy over triangles (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct TriangleBvh {
    nodes: Vec<Node>,
    /// Triangle indices in leaf order.
    order: Vec<u32>,
}

fn triangle_box(p: &[Vec3], t: [u32; 3]) -> (Vec3A, Vec3A) {
    let (a, b, c) = (
        Vec3A::from(p[t[0] as usize]),
        Vec3A::from(p[t[1] as usize]),
        Vec3A::from(p[t[2] as usize]),
    );
    (a.min(b).min(c), a.max(b).max(c))
}

impl TriangleBvh {
    /// Builds the tree over `triangles` at `positions`.
    pub fn new(positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let mut bvh = Self {
            nodes: Vec::with_capacity(2 * triangles.len().div_ceil(LEAF_SIZE)),
            order: (0..triangles.len() as u32).collect(),
        };
        if triangles.is_empty() {
            return bvh;
        }
        let centroids: Vec<Vec3A> = triangles
            .iter()
            .map(|t| {
                let (lo, hi) = triangle_box(positions, *t);
                (lo + hi) * 0.5
            })
            .collect();
        bvh.nodes.push(Node {
            min: Vec3::ZERO,
            max: Vec3::ZERO,
            start: 0,
            count: triangles.len() as u32,
        });
        // Split nodes breadth-first; children are always appended after their
        // parent, so a reverse sweep visits children before parents.
        let mut next = 0;
        while next < bvh.nodes.len() {
            let Node { start, count, .. } = bvh.nodes[next];
            if count as usize > LEAF_SIZE {
                let slots = &mut bvh.order[start as usize..(start + count) as usize];
                let (lo, hi) = slots.iter().fold(
                    (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN)),
                    |(lo, hi), &t| (lo.min(centroids[t as usize]), hi.max(centroids[t as usize])),
                );
                let extent = hi - lo;
                let axis = if extent.x >= extent.y && extent.x >= extent.z {
                    0
                } else if extent.y >= extent.z {
                    1
                } else {
                    2
                };
                let half = slots.len() / 2;
                slots.select_nth_unstable_by(half, |&a, &b| {
                    centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
                });
                let left = bvh.nodes.len() as u32;
                bvh.nodes[next].start = left;
                bvh.nodes[next].count = 0;
                for (s, c) in [
                    (start, half as u32),
                    (start + half as u32, count - half as u32),
                ] {
                    bvh.nodes.push(Node {
                        min: Vec3::ZERO,
                        max: Vec3::ZERO,
                        start: s,
                        count: c,
                    });
                }
            }
            next += 1;
        }
        bvh.refit(positions, triangles);
        bvh
    }

    /// Recomputes every box from `positions` (same triangles as at build).
    pub fn refit(&mut self, positions: &[Vec3], triangles: &[[u32; 3]]) {
        for i in (0..self.nodes.len()).rev() {
            let Node { start, count, .. } = self.nodes[i];
            let (min, max) = if count > 0 {
                self.order[start as usize..(start + count) as usize]
                    .iter()
                    .map(|&t| triangle_box(positions, triangles[t as usize]))
                    .fold(
                        (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN)),
                        |(lo, hi), (a, b)| (lo.min(a), hi.max(b)),
                    )
            } else {
                let (l, r) = (self.nodes[start as usize], self.nodes[start as usize + 1]);
                let ((lmin, lmax), (rmin, rmax)) = (l.corners(), r.corners());
                (lmin.min(rmin), lmax.max(rmax))
            };
            self.nodes[i].min = min.into();
            self.nodes[i].max = max.into();
        }
    }

    /// Number of nodes; node 0 is the root and every child comes after its
    /// parent.
    pub(super) fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Node `i`: its box and what it holds.
    pub(super) fn node(&self, i: usize) -> (Vec3A, Vec3A, NodeContents<'_>) {
        let n = &self.nodes[i];
        let (min, max) = n.corners();
        let contents = if n.count > 0 {
            NodeContents::Leaf(&self.order[n.start as usize..(n.start + n.count) as usize])
        } else {
            NodeContents::Inner(n.start as usize)
        };
        (min, max, contents)
    }

    /// The box around every triangle (`None` when there are none).
    pub fn root_box(&self) -> Option<(Vec3A, Vec3A)> {
        self.nodes.first().map(|n| n.corners())
    }

    /// Distance from `query` to the root box grown by `slack`: a lower bound
    /// on the distance to every triangle (`f32::MAX` for an empty tree).
    pub fn lower_bound(&self, query: Vec3, slack: f32) -> f32 {
        self.nodes.first().map_or(f32::MAX, |n| {
            let q = Vec3A::from(query);
            let (min, max) = n.corners();
            ((min - q).max(q - max).max(Vec3A::ZERO).length() - slack).max(0.0)
        })
    }

    /// The triangle minimising `leaf_distance` (a squared distance) among
    /// those whose box, grown by `slack`, is closer than `bound` (squared):
    /// `(triangle, squared distance, payload)`, or `None`.
    pub fn closest<T>(
        &self,
        query: Vec3,
        bound: f32,
        slack: f32,
        mut leaf_distance: impl FnMut(u32) -> (f32, T),
    ) -> Option<(u32, f32, T)> {
        let mut best: Option<(u32, f32, T)> = None;
        self.search_leaves(query, bound, slack, |_, list, bound| {
            for &t in list {
                let (dt, payload) = leaf_distance(t);
                if dt < *bound {
                    *bound = dt;
                    best = Some((t, dt, payload));
                }
            }
        });
        best
    }

    /// The nearest-first descent under [`TriangleBvh::closest`]: `leaf` is
    /// given each leaf whose box, grown by `slack`, is closer than the
    /// bound (squared; `bound` at first), with its node index and
    /// triangles, and lowers the bound to what it found.
    pub(super) fn search_leaves(
        &self,
        query: Vec3,
        bound: f32,
        slack: f32,
        mut leaf: impl FnMut(usize, &[u32], &mut f32),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let q = Vec3A::from(query);
        let box_distance = |n: &Node| n.distance_squared(q, slack);
        let mut bound = bound;
        let mut stack: [(u32, f32); 64] = [(0, 0.0); 64];
        stack[0] = (0, box_distance(&self.nodes[0]));
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (i, d) = stack[top];
            if d >= bound {
                continue;
            }
            let node = &self.nodes[i as usize];
            if node.count > 0 {
                let list = &self.order[node.start as usize..(node.start + node.count) as usize];
                leaf(i as usize, list, &mut bound);
                continue;
            }
            let (l, r) = (node.start, node.start + 1);
            let (dl, dr) = (
                box_distance(&self.nodes[l as usize]),
                box_distance(&self.nodes[r as usize]),
            );
            // Near child on top of the stack; the depth of a median-split tree
            // is log2(n / LEAF_SIZE) + 1, far below the stack size.
            let (near, far) = if dl <= dr {
                ((l, dl), (r, dr))
            } else {
                ((r, dr), (l, dl))
            };
            if far.1 < bound && top < stack.len() {
                stack[top] = far;
                top += 1;
            }
            if near.1 < bound && top < stack.len() {
                stack[top] = near;
                top += 1;
            }
        }
    }
}
