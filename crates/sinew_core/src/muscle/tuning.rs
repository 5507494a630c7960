//! A built muscle's parameters pushed into its constraint batches: the
//! activation into rest lengths and the volume ratio, compliances (and a
//! held shape's release) into the batches, connection weights per vertex,
//! and pinned attachments.

use super::*;

impl Muscle {
    /// Applies the current activation: clamps it (reporting once), then updates
    /// fibre / branch / internal rest lengths and the volume ratio. Returns a
    /// warning when the activation had to be clamped for the first time.
    pub fn update_activation(&mut self) -> Option<String> {
        let raw = self.params.activation;
        let mut warning = None;
        if !(0.0..=1.0).contains(&raw) {
            if !self.activation_reported {
                warning = Some(format!(
                    "muscle '{}': activation {raw} outside [0, 1], clamped",
                    self.name
                ));
                self.activation_reported = true;
            }
            self.params.activation = if raw.is_nan() {
                0.0
            } else {
                raw.clamp(0.0, 1.0)
            };
        }
        let p = &self.params;
        let (a, a0) = (p.activation, p.rest_activation.min(0.95));
        let bulge = p.bulge.then(|| p.volume.activation_ratio(a, a0));
        let scale = ActivationScale::new(a, a0, p.max_contraction, bulge);
        let k = &mut self.constraints;
        k.fiber.update_rest(p.fiber_mode, &scale);
        k.branch.update_rest(p.fiber_mode, &scale);
        k.internal.update_rest(p.fiber_mode, &scale);
        if let Some(v) = &mut k.volume {
            v.ratio = p.volume.ratio(a, a0);
        }
        if self.holds_shape() {
            self.apply_bind_compliances();
        }
        warning
    }

    /// Whether this muscle's shape is held on its bones
    /// ([`MuscleParams::hold_shape`]): bound, and no skin.
    pub fn holds_shape(&self) -> bool {
        !self.binding.is_empty() && !self.params.is_surface_layer()
    }

    /// The Bind compliance of a bound vertex of `strength`: the type's
    /// compliance (for a muscle that holds its shape ÷
    /// [`MuscleParams::hold_strength`] at its activation) ÷ the strength.
    pub fn bind_compliance(&self, strength: f32) -> f32 {
        self.bind_compliance_per_strength() / strength
    }

    /// [`Muscle::bind_compliance`] of a vertex of strength 1.
    fn bind_compliance_per_strength(&self) -> f32 {
        let hold = if self.holds_shape() {
            self.params.hold_strength(self.params.activation)
        } else {
            1.0
        };
        self.params.compliance.bind / hold
    }

    /// Writes [`Muscle::bind_compliance`] into every Bind constraint.
    fn apply_bind_compliances(&mut self) {
        let base = self.bind_compliance_per_strength();
        let k = &mut self.constraints.bind;
        for (c, b) in k.compliance.iter_mut().zip(&self.binding) {
            *c = base / b.strength;
        }
    }

    /// Pushes per-type compliances from `params` into the batches (after a
    /// parameter edit; no rebuild needed).
    pub fn apply_compliances(&mut self) {
        let p = self.params.compliance;
        let area = self.area_compliance();
        let k = &mut self.constraints;
        k.fiber.compliance = p.fiber;
        k.branch.compliance = p.branch;
        k.internal.compliance = p.internal;
        k.area.compliance = area;
        k.attach.compliance.fill(p.attach);
        k.branch_attach.compliance.fill(p.branch_attach);
        self.apply_bind_compliances();
        let volume = self.volume_compliance();
        if let Some(v) = &mut self.constraints.volume {
            v.compliance = volume;
        }
        self.pin_attachments();
        self.relink_weights();
    }

    /// Gives particles held with zero compliance an inverse mass of 0 (they
    /// move with their bone, see [`Muscle::place_pinned`]) and restores the
    /// others' masses. A hard attachment then holds exactly whatever the other
    /// constraints do after it in the iteration.
    pub fn pin_attachments(&mut self) {
        for a in &self.attachments {
            let v = a.vertex.index();
            self.w[v] = self.free_w[v];
            if let Some(ip) = a.internal_particle {
                self.w[ip.index()] = self.free_w[ip.index()];
            }
        }
        for a in &self.attachments {
            if self.params.compliance.attach == 0.0 {
                self.w[a.vertex.index()] = 0.0;
            }
            if let Some(ip) = a.internal_particle
                && self.params.compliance.branch_attach == 0.0
            {
                self.w[ip.index()] = 0.0;
            }
        }
    }

    /// Moves pinned particles' predictions to their attachment goals.
    pub fn place_pinned(&mut self) {
        let mut k = 0;
        for (i, a) in self.attachments.iter().enumerate() {
            if self.w[a.vertex.index()] == 0.0 {
                self.p[a.vertex.index()] = self.constraints.attach.goal[i];
            }
            if let Some(ip) = a.internal_particle {
                if self.w[ip.index()] == 0.0 {
                    self.p[ip.index()] = self.constraints.branch_attach.goal[k];
                }
                k += 1;
            }
        }
    }

    /// Per-vertex connection weights `(sliding, soft, hard)`, normalised if asked.
    pub fn connection_weights(&self, v: usize) -> (f32, f32, f32) {
        let d = self.params.weights;
        let pick = |map: &Option<Vec<f32>>, default: f32| map.as_ref().map_or(default, |m| m[v]);
        let (s, o, h) = (
            pick(&self.maps.sliding, d.sliding),
            pick(&self.maps.soft, d.soft),
            pick(&self.maps.hard, d.hard),
        );
        let sum = s + o + h;
        if d.normalize && sum > 0.0 {
            (s / sum, o / sum, h / sum)
        } else {
            (s, o, h)
        }
    }

    /// Recomputes the per-constraint compliances of Sliding / Soft / Hard from
    /// type compliances and weights (`α / weight`; weight 0 disables, and so
    /// does a vertex out of every target's reach).
    pub fn relink_weights(&mut self) {
        self.touch_topology();
        let comp = self.params.compliance;
        let weighted = |alpha: f32, w: f32| if w > 0.0 { alpha / w } else { f32::INFINITY };
        for i in 0..self.constraints.sliding.len() {
            let v = self.constraints.sliding.particle[i].index();
            let (s, o, h) = self.connection_weights(v);
            let c = &self.constraints;
            let on = |connected: Option<bool>, weight: f32| {
                if connected == Some(false) {
                    0.0
                } else {
                    weight
                }
            };
            let s = on(c.sliding.connected.get(i).copied(), s);
            let o = on(c.soft_anchor.get(i).map(|a| a.connected), o);
            let h = on(c.hard_anchor.get(i).map(|a| a.connected), h);
            self.constraints.sliding.compliance[i] = weighted(comp.sliding, s);
            self.constraints.soft.compliance[i] = weighted(comp.soft, o);
            self.constraints.hard.compliance[i] = weighted(comp.hard, h);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::FiberMode;
    use crate::scene::builtin;
    use std::path::Path;

    /// T1's oval as built, before any activation was applied.
    fn oval() -> Muscle {
        let solver = builtin("T1").unwrap().instantiate(Path::new(".")).unwrap();
        solver.muscles()[0].clone()
    }

    /// The Fiber, Branch and Internal rest lengths of `m` after applying
    /// `activation` and `mode`.
    fn rest_after(m: &mut Muscle, activation: f32, mode: FiberMode) -> Vec<f32> {
        m.params.activation = activation;
        m.params.fiber_mode = mode;
        m.update_activation();
        let k = &m.constraints;
        [&k.fiber.rest, &k.branch.rest, &k.internal.rest]
            .into_iter()
            .flatten()
            .copied()
            .collect()
    }

    #[test]
    fn rest_lengths_kept_for_an_unchanged_activation_are_those_it_would_compute() {
        let mode = FiberMode::RotationInvariant;
        let fresh = |a: f32, mode: FiberMode| rest_after(&mut oval(), a, mode);
        let mut m = oval();
        let contracted = rest_after(&mut m, 0.6, mode);
        assert_eq!(rest_after(&mut m, 0.6, mode), contracted);
        assert_eq!(contracted, fresh(0.6, mode));
        // A new activation, or the same one in another mode, recomputes.
        let relaxed = rest_after(&mut m, 0.0, mode);
        assert_ne!(relaxed, contracted);
        assert_eq!(relaxed, fresh(0.0, mode));
        let paper = rest_after(&mut m, 0.6, FiberMode::PaperExact);
        assert_eq!(paper, fresh(0.6, FiberMode::PaperExact));
        assert_ne!(paper, contracted);
        assert_eq!(rest_after(&mut m, 0.6, mode), contracted);
        // A batch built anew starts from its build's lengths and is set
        // again for the same activation.
        m.constraints.fiber = crate::muscle::fiber_edges(&m);
        assert_eq!(rest_after(&mut m, 0.6, mode), contracted);
    }
}
