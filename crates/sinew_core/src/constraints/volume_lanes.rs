//! The Volume constraints of four muscles of one surface topology,
//! projected side by side: muscle `k` in lane `k` of every value, each
//! polygon of the shared index arrays once for all four, as
//! [`super::DistanceLanes`] does for the distance constraints.
//!
//! Each lane takes the steps [`VolumeConstraint::solve_with`] takes for its
//! muscle ([`VolumeProjection`]: one, or Newton steps until close), a lane
//! that has stopped left as it is while the others go on; every sum is its
//! muscle's own, in its order and precision (f32 products, f64 sums), so
//! each muscle gets the bits its own projection gives. A cross product in
//! lanes is six products and three differences, with none of the shuffles
//! a `Vec3A` cross product takes.

use super::{LANES, VolumeConstraint, VolumeProjection, delta_lambda};
use crate::lanes;
use glam::{Vec3, Vec4};

/// Three coordinates of four muscles' vectors.
#[derive(Clone, Copy, Debug, Default)]
struct Lanes3 {
    x: Vec4,
    y: Vec4,
    z: Vec4,
}

impl Lanes3 {
    /// Lane `k` of `f(k)` for each of the four lanes.
    #[inline(always)]
    fn of(f: impl Fn(usize) -> Vec3) -> Self {
        let (x, y, z) = lanes::of3(f);
        Self { x, y, z }
    }

    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    #[inline(always)]
    fn scale(self, s: Vec4) -> Self {
        Self {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }

    #[inline(always)]
    fn neg(self) -> Self {
        Self {
            x: -self.x,
            y: -self.y,
            z: -self.z,
        }
    }

    /// `self × o`, each component the products and difference glam's
    /// `Vec3A::cross` forms for it.
    #[inline(always)]
    fn cross(self, o: Self) -> Self {
        Self {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }

    /// `self · o`, the lanes added in glam's order, `(x + y) + z`.
    #[inline(always)]
    fn dot(self, o: Self) -> Vec4 {
        (self.x * o.x + self.y * o.y) + self.z * o.z
    }
}

/// Workspace of a group's Volume projection (module docs).
#[derive(Clone, Debug, Default)]
pub struct VolumeLanes {
    /// The surface positions relative to each muscle's first.
    relative: Vec<Lanes3>,
    /// Each surface vertex's gradient.
    gradient: Vec<Lanes3>,
}

/// Whether four Volume constraints can be projected in lanes: one surface
/// topology of triangles and quads.
pub fn volumes_share_topology(volumes: [&VolumeConstraint; LANES]) -> bool {
    let first = volumes[0];
    let small = first.polygon_offsets.len() <= VolumeConstraint::BLOCKED_POLYGONS;
    let sizes = first
        .polygon_offsets
        .windows(2)
        .all(|o| matches!(o[1] - o[0], 3 | 4));
    small
        && first.surface_count > 0
        && sizes
        && volumes.iter().all(|v| {
            v.surface_count == first.surface_count
                && v.polygon_offsets == first.polygon_offsets
                && v.polygon_indices == first.polygon_indices
        })
}

impl VolumeLanes {
    /// Each muscle's `(C, Σ w |∇C|²)` at `p`, the gradients in
    /// `self.gradient`: [`VolumeConstraint::evaluate`] in four lanes.
    fn evaluate(
        &mut self,
        volumes: &[&mut VolumeConstraint; LANES],
        p: &[&mut [Vec3]; LANES],
        w: [&[f32]; LANES],
    ) -> ([f64; LANES], [f64; LANES]) {
        let first = &*volumes[0];
        let n = first.surface_count;
        let o = Lanes3::of(|k| p[k][0]);
        let [p0, p1, p2, p3] = p.each_ref().map(|p| &p[..n]);
        self.relative.clear();
        self.relative
            .extend(p0.iter().zip(p1).zip(p2).zip(p3).map(|(((a, b), c), d)| {
                let (x, y, z) = lanes::transpose_in([*a, *b, *c, *d]);
                Lanes3 { x, y, z }.sub(o)
            }));
        self.gradient.clear();
        self.gradient.resize(n, Lanes3::default());
        let (r, g) = (&self.relative[..n], &mut self.gradient[..n]);
        let mut six_v = [0.0f64; LANES];
        let quarter = Vec4::splat(0.25);
        for o in first.polygon_offsets.windows(2) {
            let six = match first.polygon_indices[o[0] as usize..o[1] as usize] {
                [a, b, c] => {
                    let (a, b, c) = (a as usize, b as usize, c as usize);
                    let bc = r[b].cross(r[c]);
                    let six = r[a].dot(bc);
                    g[a] = g[a].add(bc);
                    g[b] = g[b].add(r[c].cross(r[a]));
                    g[c] = g[c].add(r[a].cross(r[b]));
                    six
                }
                [a, b, c, d] => {
                    let (a, b, c, d) = (a as usize, b as usize, c as usize, d as usize);
                    let m = r[a].add(r[b]).add(r[c]).add(r[d]).scale(quarter);
                    let area = r[c].sub(r[a]).cross(r[d].sub(r[b]));
                    let six = area.dot(m);
                    let share = area.scale(quarter);
                    let across_bd = m.cross(r[b].sub(r[d]));
                    let across_ca = m.cross(r[c].sub(r[a]));
                    g[a] = g[a].add(across_bd.neg().add(share));
                    g[b] = g[b].add(across_ca.neg().add(share));
                    g[c] = g[c].add(across_bd.add(share));
                    g[d] = g[d].add(across_ca.add(share));
                    six
                }
                // Checked by `volumes_share_topology`.
                _ => Vec4::ZERO,
            };
            for (sum, six) in six_v.iter_mut().zip(six.to_array()) {
                *sum += six as f64;
            }
        }
        let mut wg = [0.0f64; LANES];
        let sixth = Vec4::splat(6.0);
        let [w0, w1, w2, w3] = w.map(|w| &w[..n]);
        let masses = w0.iter().zip(w1).zip(w2).zip(w3);
        for (g, (((&w0, &w1), &w2), &w3)) in g.iter_mut().zip(masses) {
            *g = Lanes3 {
                x: g.x / sixth,
                y: g.y / sixth,
                z: g.z / sixth,
            };
            let weighted = Vec4::new(w0, w1, w2, w3) * g.dot(*g);
            for (sum, t) in wg.iter_mut().zip(weighted.to_array()) {
                *sum += t as f64;
            }
        }
        let c = std::array::from_fn(|k| {
            six_v[k] / 6.0 - volumes[k].ratio as f64 * volumes[k].rest_volume
        });
        (c, wg)
    }

    /// One projection of each muscle's Volume constraint (`members[k]`:
    /// muscle `k`'s, with its positions and inverse masses), as far as
    /// `how` says for it: [`VolumeConstraint::solve_with`] (serial) in four
    /// lanes, with the same bits. The constraints share one topology
    /// ([`volumes_share_topology`]).
    pub fn solve(
        &mut self,
        members: [(&mut VolumeConstraint, &mut [Vec3], &[f32]); LANES],
        inv_dt2: f32,
        how: [VolumeProjection; LANES],
    ) {
        let [a, b, c, d] = members;
        let (volumes, mut p, w) = (
            [a.0, b.0, c.0, d.0],
            [a.1, b.1, c.1, d.1],
            [a.2, b.2, c.2, d.2],
        );
        let n = volumes[0].surface_count;
        let alpha: [f32; LANES] = std::array::from_fn(|k| volumes[k].compliance * inv_dt2);
        let scale: [f64; LANES] =
            std::array::from_fn(|k| volumes[k].rest_volume.abs().max(f64::MIN_POSITIVE));
        let mut limit = how.map(VolumeProjection::steps_at_most);
        let mut step = [0usize; LANES];
        let mut done = [false; LANES];
        loop {
            let going: [bool; LANES] = std::array::from_fn(|k| !done[k] && step[k] < limit[k]);
            if !going.contains(&true) {
                break;
            }
            let (c, wg) = self.evaluate(&volumes, &p, w);
            // Each going lane's step: its multiplier's change, or none.
            let mut dl = [0.0f32; LANES];
            let mut moves = [false; LANES];
            for k in (0..LANES).filter(|&k| going[k]) {
                step[k] += 1;
                if how[k] == VolumeProjection::Converge
                    && (c[k] / scale[k]).abs() > VolumeConstraint::FAR
                {
                    limit[k] = VolumeConstraint::MAX_NEWTON_STEPS_FAR;
                }
                dl[k] = delta_lambda(c[k] as f32, volumes[k].lambda, wg[k] as f32, alpha[k]);
                if dl[k] == 0.0 {
                    done[k] = true;
                    continue;
                }
                volumes[k].lambda += dl[k];
                moves[k] = true;
                if (c[k] / scale[k]).abs() < VolumeConstraint::CLOSE {
                    done[k] = true;
                }
            }
            self.step_positions(&mut p, w, n, dl, moves);
        }
    }

    /// Moves each lane `k` that `moves` along its gradient by `dl[k]`
    /// times each vertex's inverse mass (`p += w · dl · ∇C`, as the
    /// serial projection moves it); the lanes that do not move keep their
    /// positions' bits (adding a zero would turn a −0 into +0). All four
    /// at once, vertex by vertex, where all four move (most steps).
    fn step_positions(
        &self,
        p: &mut [&mut [Vec3]; LANES],
        w: [&[f32]; LANES],
        n: usize,
        dl: [f32; LANES],
        moves: [bool; LANES],
    ) {
        let g = &self.gradient[..n];
        if moves == [true; LANES] {
            let dl = Vec4::from_array(dl);
            let [p0, p1, p2, p3] = p;
            let [w0, w1, w2, w3] = w.map(|w| &w[..n]);
            let masses = w0.iter().zip(w1).zip(w2).zip(w3);
            let positions =
                (p0.iter_mut().zip(p1.iter_mut())).zip(p2.iter_mut().zip(p3.iter_mut()));
            for ((g, (((&w0, &w1), &w2), &w3)), ((a, b), (c, d))) in
                g.iter().zip(masses).zip(positions)
            {
                let s = Vec4::new(w0, w1, w2, w3) * dl;
                let (x, y, z) = (g.x * s, g.y * s, g.z * s);
                let [sa, sb, sc, sd] = lanes::transpose_out(x, y, z);
                *a += sa;
                *b += sb;
                *c += sc;
                *d += sd;
            }
            return;
        }
        for k in (0..LANES).filter(|&k| moves[k]) {
            let lane = |v: Vec4| v.to_array()[k];
            for ((p, g), &wv) in p[k][..n].iter_mut().zip(g).zip(w[k]) {
                let s = wv * dl[k];
                *p += Vec3::new(lane(g.x) * s, lane(g.y) * s, lane(g.z) * s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::primitives::MeshGenerator;

    /// Four Volume constraints over one ellipsoid's topology (quads and
    /// triangle fans), each muscle its own positions, masses, targets
    /// and compliance, one far from its target (Newton steps past two).
    fn four_volumes() -> [(VolumeConstraint, Vec<Vec3>, Vec<f32>); LANES] {
        let mesh = MeshGenerator::Ellipsoid {
            center: Vec3::new(0.1, 0.2, -0.1),
            radii: Vec3::new(0.03, 0.12, 0.03),
            segments: 10,
            stacks: 14,
        }
        .build("muscle")
        .unwrap();
        std::array::from_fn(|k| {
            let n = mesh.positions.len();
            let p: Vec<Vec3> = (mesh.positions.iter().enumerate())
                .map(|(i, &x)| {
                    let t = (i * (k + 3)) as f32;
                    x + 2e-3 * Vec3::new(t.sin(), (1.3 * t).cos(), (0.7 * t).sin())
                })
                .collect();
            let volume = VolumeConstraint {
                polygon_offsets: mesh.polygon_offsets.clone(),
                polygon_indices: mesh.polygon_indices.clone(),
                surface_count: n,
                rest_volume: mesh.volume(),
                ratio: [1.0, 1.05, 1.2, 0.97][k],
                compliance: [0.0, 1e-9, 0.0, 1e-10][k],
                ..Default::default()
            };
            let w = (0..n)
                .map(|i| if i % 11 == k { 0.0 } else { 1.0 })
                .collect();
            (volume, p, w)
        })
    }

    /// Each lane's steps, multiplier and positions are its muscle's own
    /// projection's, to the bit, one step or to convergence.
    #[test]
    fn lanes_give_each_volume_the_bits_of_its_own_projection() {
        for how in [
            [VolumeProjection::Step; LANES],
            [
                VolumeProjection::Converge,
                VolumeProjection::Step,
                VolumeProjection::Converge,
                VolumeProjection::Converge,
            ],
        ] {
            let mut own = four_volumes();
            for (k, (v, p, w)) in own.iter_mut().enumerate() {
                v.solve_with(p, w, 3600.0, false, how[k]);
            }
            let mut laned = four_volumes();
            let [a, b, c, d] = &mut laned;
            assert!(volumes_share_topology([&a.0, &b.0, &c.0, &d.0]));
            let members = [a, b, c, d].map(|(v, p, w)| (v, &mut p[..], &w[..]));
            VolumeLanes::default().solve(members, 3600.0, how);
            let bits = |v: &[Vec3]| {
                v.iter()
                    .map(|p| p.to_array().map(f32::to_bits))
                    .collect::<Vec<_>>()
            };
            for k in 0..LANES {
                assert_eq!(
                    laned[k].0.lambda.to_bits(),
                    own[k].0.lambda.to_bits(),
                    "lane {k}"
                );
                assert_eq!(bits(&laned[k].1), bits(&own[k].1), "lane {k}");
                assert_ne!(
                    bits(&laned[k].1),
                    bits(&four_volumes()[k].1),
                    "lane {k} moved"
                );
            }
        }
    }
}
