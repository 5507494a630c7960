//! A muscle's bones' world boxes for its bone contacts
//! ([`super::bone_contacts`]), packed four to a quad, coordinate by
//! coordinate in SIMD lanes: a vertex tests four boxes in one go and gets
//! back which of them hold it and how far it is from the others, where a
//! box at a time cost a square root and a branch on it each, and a loop
//! whose length changes from muscle to muscle (the branches the processor
//! guessed wrong most often in the bone contacts' loop).
//!
//! The distance from a point to a box is the length of how far it is past
//! each face, `((lo − q) max (q − hi) max 0)`, in the same operations and
//! order as [`box_distance`], so a lane reads the bits a box at a time
//! read.

use glam::{Vec3A, Vec4};

/// Bone boxes per group: a vertex first tests the box around a group's
/// boxes and skips the whole group when it is farther than its margin (a
/// skin vertex has every bone of a body as a target; a group of
/// consecutive bones, a hand's or a leg's, lies together).
const BOX_GROUP: usize = 8;

/// Distance from `q` to the box `[lo, hi]` (0 inside).
pub(super) fn box_distance(q: Vec3A, lo: Vec3A, hi: Vec3A) -> f32 {
    (lo - q).max(q - hi).max(Vec3A::ZERO).length()
}

/// Four bones' boxes, coordinate by coordinate; an empty lane's box is
/// inverted (from +∞ to −∞), infinitely far from every point.
#[derive(Clone, Debug)]
pub(super) struct BoxQuad {
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    /// Each lane's target slot (`usize::MAX` in an empty lane).
    slots: [usize; 4],
    /// Bit `k`: lane `k` holds a box.
    filled: u32,
}

impl BoxQuad {
    const EMPTY: Self = Self {
        lo: [Vec4::INFINITY; 3],
        hi: [Vec4::NEG_INFINITY; 3],
        slots: [usize::MAX; 4],
        filled: 0,
    };

    /// Which of the four boxes hold `q`, and how far `q` is from the
    /// others (module docs: each lane's bits are [`box_distance`]'s).
    #[inline]
    pub(super) fn test(&self, q: Vec3A) -> QuadHits {
        let past = |axis: usize| {
            let q = Vec4::splat(q[axis]);
            (self.lo[axis] - q).max(q - self.hi[axis]).max(Vec4::ZERO)
        };
        let (x, y, z) = (past(0), past(1), past(2));
        let squared = x * x + y * y + z * z;
        let outside = squared.cmpgt(Vec4::ZERO);
        // A point of no position (NaN) is past no face, in every lane:
        // only lanes that hold a box can hold it.
        QuadHits {
            inside: !outside.bitmask() & self.filled,
            outside: Vec4::select(outside, crate::lanes::sqrt(squared), Vec4::INFINITY),
        }
    }

    /// The target slot of the box in lane `k`.
    pub(super) fn slot(&self, k: usize) -> usize {
        self.slots[k]
    }

    /// Puts box `[lo, hi]` of target `slot` in lane `k`.
    fn set(&mut self, k: usize, slot: usize, lo: Vec3A, hi: Vec3A) {
        for axis in 0..3 {
            self.lo[axis][k] = lo[axis];
            self.hi[axis][k] = hi[axis];
        }
        self.slots[k] = slot;
        self.filled |= 1 << k;
    }
}

/// What a vertex's test of a quad found.
#[derive(Clone, Copy, Debug)]
pub(super) struct QuadHits {
    /// Bit `k`: the box in lane `k` holds the vertex.
    pub inside: u32,
    /// The vertex's distance from each lane's box: +∞ in a lane whose box
    /// holds it or that is empty.
    pub outside: Vec4,
}

/// A group of boxes: the box around them and where its quads end.
#[derive(Clone, Copy, Debug)]
struct BoxGroup {
    lo: Vec3A,
    hi: Vec3A,
    quads_end: usize,
}

/// A muscle's bones' world boxes (module docs): rebuilt in a substep's
/// first iteration (bones are posed once per substep) and after a relink
/// (emptied).
#[derive(Clone, Debug, Default)]
pub(crate) struct BoneBoxes {
    groups: Vec<BoxGroup>,
    quads: Vec<BoxQuad>,
}

impl BoneBoxes {
    /// Whether it holds no box.
    pub(super) fn is_empty(&self) -> bool {
        self.groups.is_empty()
    }

    /// Forgets every box.
    pub(crate) fn clear(&mut self) {
        self.groups.clear();
        self.quads.clear();
    }

    /// Keeps the boxes `(target slot, min, max)`, in their order, in groups
    /// of [`BOX_GROUP`].
    pub(super) fn rebuild(&mut self, boxes: impl Iterator<Item = (usize, Vec3A, Vec3A)>) {
        self.clear();
        for (n, (slot, lo, hi)) in boxes.enumerate() {
            if n % BOX_GROUP == 0 {
                self.groups.push(BoxGroup {
                    lo: Vec3A::INFINITY,
                    hi: Vec3A::NEG_INFINITY,
                    quads_end: self.quads.len(),
                });
            }
            let group = self.groups.last_mut().expect("pushed above");
            (group.lo, group.hi) = (group.lo.min(lo), group.hi.max(hi));
            let k = n % BOX_GROUP % 4;
            if k == 0 {
                self.quads.push(BoxQuad::EMPTY);
                group.quads_end += 1;
            }
            self.quads
                .last_mut()
                .expect("pushed above")
                .set(k, slot, lo, hi);
        }
    }

    /// Each group's box `(min, max)` and its quads.
    pub(super) fn groups(&self) -> impl Iterator<Item = (Vec3A, Vec3A, &[BoxQuad])> {
        let mut start = 0;
        self.groups.iter().map(move |g| {
            let quads = &self.quads[std::mem::replace(&mut start, g.quads_end)..g.quads_end];
            (g.lo, g.hi, quads)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eleven boxes in two groups (8 + 3: two quads and one with a lane
    /// left empty), and points inside, on and around them: each lane reads
    /// the bits of `box_distance`, a box holds a point where that distance
    /// is 0, an empty lane holds nothing and is infinitely far, and each
    /// group's box holds its boxes. Seen to fail with the lanes' sum of
    /// squares taken in another order (z first), with an empty lane left at
    /// zero size, and with an empty lane holding a NaN point (the fuzzed
    /// scene reader's finding: an empty lane's slot taken as a target).
    #[test]
    fn each_lane_reads_the_distance_of_its_box() {
        let boxes: Vec<(usize, Vec3A, Vec3A)> = (0..11)
            .map(|n| {
                let lo = Vec3A::new(0.37 * n as f32, -0.11 * n as f32, 0.013 * (n * n) as f32);
                let size = Vec3A::new(0.3 + 0.01 * n as f32, 0.2, 0.1 + 0.07 * n as f32);
                (2 * n + 1, lo, lo + size)
            })
            .collect();
        let mut packed = BoneBoxes::default();
        packed.rebuild(boxes.iter().copied());
        let groups: Vec<_> = packed.groups().collect();
        assert_eq!(groups.iter().map(|g| g.2.len()).collect::<Vec<_>>(), [2, 1]);
        let mut points: Vec<Vec3A> = boxes
            .iter()
            .flat_map(|&(_, lo, hi)| [lo, hi, (lo + hi) * 0.5, lo - Vec3A::splat(0.05)])
            .collect();
        points.extend((0..40).map(|k| {
            let k = k as f32;
            Vec3A::new(
                (k * 0.713).sin() * 4.0,
                (k * 1.37).cos(),
                (k * 0.291).sin() * 2.0,
            )
        }));
        let (mut inside, mut outside) = (0, 0);
        for q in points {
            let mut n = 0;
            for (glo, ghi, quads) in packed.groups() {
                for quad in quads {
                    let hits = quad.test(q);
                    for k in 0..4 {
                        let Some(&(slot, lo, hi)) = boxes.get(n) else {
                            assert_eq!(quad.slot(k), usize::MAX);
                            assert_eq!(hits.outside[k], f32::INFINITY);
                            assert_eq!(hits.inside >> k & 1, 0);
                            continue;
                        };
                        assert!(glo.cmple(lo).all() && ghi.cmpge(hi).all());
                        assert_eq!(quad.slot(k), slot);
                        let d = box_distance(q, lo, hi);
                        if d > 0.0 {
                            assert_eq!(hits.outside[k].to_bits(), d.to_bits(), "box {n} at {q}");
                            assert_eq!(hits.inside >> k & 1, 0);
                            outside += 1;
                        } else {
                            assert_eq!(hits.outside[k], f32::INFINITY);
                            assert_eq!(hits.inside >> k & 1, 1, "box {n} at {q}");
                            inside += 1;
                        }
                        n += 1;
                    }
                }
            }
            assert_eq!(n, boxes.len());
        }
        assert!(
            inside >= 33 && outside > 300,
            "{inside} inside, {outside} outside"
        );
        // A point with no position (a blown-up vertex, NaN) reads inside
        // every box, as `box_distance` reads 0, but not inside an empty
        // lane: the slot of one is no target.
        let nan = Vec3A::splat(f32::NAN);
        let quads: Vec<_> = packed.groups().flat_map(|g| g.2).collect();
        let masks: Vec<u32> = quads.iter().map(|q| q.test(nan).inside).collect();
        assert_eq!(box_distance(nan, boxes[0].1, boxes[0].2), 0.0);
        assert_eq!(masks, [0b1111, 0b1111, 0b0111]);
    }
}
