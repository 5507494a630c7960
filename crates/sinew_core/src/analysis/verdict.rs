//! Judging a run: the ranges its figures must stay in, and a verdict per
//! figure. `sinew check` prints them and exits non-zero when one fails.

use super::RunMetrics;
use crate::solver::Solver;

/// The ranges a run's figures must stay in. The rest figures are judged
/// only once the run has gone on for [`Thresholds::settle`] past the
/// scene's last motion key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    /// Largest attachment error. Units: m. Default: `0.001`.
    pub attachment: f32,
    /// Largest share of all surface vertices deeper than
    /// [`RunMetrics::depth`] inside a bone, in a checked frame. Default: `0.02`.
    pub penetration: f32,
    /// Smallest volume / rest volume. Default: `0.95`.
    pub volume_min: f64,
    /// Largest volume / (rest volume × the muscle's full volume gain),
    /// `G · max(R, 1)`. Default: `1.05`.
    pub volume_max: f64,
    /// Edge length / rest length in every frame: `[min, max]`. Default:
    /// `[0.6, 1.6]` (fibres shorten to 0.65 at full activation).
    pub strain: [f32; 2],
    /// Most flipped triangles (folded or inverted) of a muscle in any
    /// frame. Default: `0`.
    pub flipped: usize,
    /// At rest: RMS surface velocity over the last second. Units: m/s.
    /// Default: `0.001`.
    pub rest_velocity: f32,
    /// At rest: RMS surface acceleration over the last second. Units: m/s².
    /// Default: `0.1`.
    pub rest_jiggle: f32,
    /// At rest: edge length / rest length over the last second, `[min, max]`.
    /// Default: `[0.8, 1.25]`.
    pub rest_strain: [f32; 2],
    /// At rest: largest distance of a surface vertex from its rest position
    /// (carried by its home bone) at the end of the run. Units: m. Default: `0.003`.
    pub rest_deviation: f32,
    /// Time after the scene's last motion key after which the end of a run
    /// counts as at rest. Units: s. Default: `2`.
    pub settle: f32,
    /// Largest share of skin vertices inside a muscle or bone, in a checked
    /// frame. Default: `0.005`.
    pub skin_inside: f32,
    /// At rest: largest distance of a skin vertex from its skinned position.
    /// Units: m. Default: `0.002`.
    pub skin_bind: f32,
    /// Smallest skin bulge over an active muscle (the largest outward
    /// displacement from the plain skinned surface, see
    /// [`super::SkinBulge`]), judged when a muscle under a skin reached
    /// [`RunMetrics::bulge_activation`]. Units: m. Default: `0.005`.
    pub skin_bulge: f32,
}

impl Default for Thresholds {
    fn default() -> Self {
        Self {
            attachment: 0.001,
            penetration: 0.02,
            volume_min: 0.95,
            volume_max: 1.05,
            strain: [0.6, 1.6],
            flipped: 0,
            rest_velocity: 0.001,
            rest_jiggle: 0.1,
            rest_strain: [0.8, 1.25],
            rest_deviation: 0.003,
            settle: 2.0,
            skin_inside: 0.005,
            skin_bind: 0.002,
            skin_bulge: 0.005,
        }
    }
}

/// One judged figure.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// What is judged.
    pub figure: &'static str,
    /// The worst value and where it was seen.
    pub value: String,
    /// The worst values of `value`'s text as numbers: what a comparison of
    /// runs reads (`sinew check --perturb` prints their ranges). Empty
    /// where the run gave none (no muscle reached the bulge activation).
    pub measured: Vec<Measured>,
    /// The range it must be in.
    pub limit: String,
    /// `None`: not judged (the scene was still moving); else whether it passed.
    pub pass: Option<bool>,
}

/// One number of a [`Verdict`], in the units its text gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured {
    /// What it is, where the figure has more than one (`"min"`, `"max"`);
    /// empty for a figure's one value.
    pub name: &'static str,
    /// The value.
    pub value: f64,
    /// Its unit (`"mm"`, `"%"`), empty for a ratio or a count.
    pub unit: &'static str,
}

impl Measured {
    /// `value` named `name` (may be empty), in `unit` (may be empty).
    pub fn new(name: &'static str, value: f64, unit: &'static str) -> Self {
        Self { name, value, unit }
    }
}

impl RunMetrics {
    /// Whether the end of the run counts as at rest: it lies at least
    /// `settle` seconds after `motion_end`, the scene's last motion key.
    pub fn at_rest(&self, solver: &Solver, motion_end: f32, settle: f32) -> bool {
        let dt = solver.settings.step_time();
        self.frames as f32 * dt >= motion_end + settle - 0.5 * dt
    }

    /// Every figure against `limits`. `solver` is in the run's final state;
    /// `motion_end` is the scene's last motion key (seconds,
    /// [`crate::scene::Scene::motion_end`]).
    pub fn verdicts(&self, solver: &Solver, limits: &Thresholds, motion_end: f32) -> Vec<Verdict> {
        let muscles = solver.muscles();
        let name = |i: usize| muscles.get(i).map_or("-", |m| m.name.as_str());
        let worst = |values: &mut dyn Iterator<Item = f64>| {
            values
                .enumerate()
                .fold((0usize, f64::NEG_INFINITY), |best, (i, v)| {
                    if v > best.1 { (i, v) } else { best }
                })
        };
        let mut out = Vec::new();
        let mut push = |figure, value: String, measured, limit: String, pass| {
            out.push(Verdict {
                figure,
                value,
                measured,
                limit,
                pass,
            });
        };
        push(
            "finite",
            match (self.first_non_finite, &self.faults) {
                (Some(f), _) => format!("NaN/inf at frame {f}"),
                (None, (0, _)) => "every frame".into(),
                (None, (n, first)) => format!(
                    "{n} muscle frame(s) blew up and were put back; first: {}",
                    first.as_deref().unwrap_or("?")
                ),
            },
            vec![
                Measured::new(
                    "frames not finite",
                    f64::from(u8::from(self.first_non_finite.is_some())),
                    "",
                ),
                Measured::new("faults", self.faults.0 as f64, ""),
            ],
            "every frame, no fault".into(),
            Some(self.first_non_finite.is_none() && self.faults.0 == 0),
        );
        let (i, e) = worst(&mut self.muscle_attachment_max.iter().map(|&e| f64::from(e)));
        push(
            "attachment error",
            format!("{:.3} mm ({})", e.max(0.0) * 1e3, name(i)),
            vec![Measured::new("", e.max(0.0) * 1e3, "mm")],
            format!("≤ {} mm", limits.attachment * 1e3),
            Some(e <= f64::from(limits.attachment)),
        );
        push(
            "penetration",
            format!(
                "{:.2} % of surface vertices (frame {})",
                self.penetration_max * 100.0,
                self.penetration_frame
            ),
            vec![Measured::new(
                "",
                f64::from(self.penetration_max) * 100.0,
                "%",
            )],
            format!("≤ {} %", limits.penetration * 100.0),
            Some(self.penetration_max <= limits.penetration),
        );
        if let Some(share) = self.skin_inside_max {
            push(
                "skin inside",
                format!(
                    "{:.2} % of skin vertices in a muscle or bone (frame {})",
                    share * 100.0,
                    self.skin_inside_frame
                ),
                vec![Measured::new("", f64::from(share) * 100.0, "%")],
                format!("≤ {} %", limits.skin_inside * 100.0),
                Some(share <= limits.skin_inside),
            );
            let peak = self
                .skin_bulges
                .iter()
                .max_by(|a, b| a.0.max.total_cmp(&b.0.max));
            push(
                "skin bulge",
                match peak {
                    Some((b, frame)) => format!(
                        "{:.2} mm over {} (a {:.2}, frame {}; median {:.2} mm over {} vertices)",
                        b.max * 1e3,
                        name(b.muscle),
                        b.activation,
                        frame,
                        b.median * 1e3,
                        b.vertices
                    ),
                    None => format!(
                        "no muscle under the skin reached a ≥ {}",
                        self.bulge_activation
                    ),
                },
                peak.map(|(b, _)| Measured::new("", f64::from(b.max) * 1e3, "mm"))
                    .into_iter()
                    .collect(),
                format!("≥ {:.1} mm", limits.skin_bulge * 1e3),
                peak.map(|(b, _)| b.max >= limits.skin_bulge),
            );
        }
        let gain = |i: usize| {
            let v = &muscles[i].params.volume;
            f64::from(v.gain * v.activation_gain.max(1.0))
        };
        // Bodies without a volume constraint (a skin) keep no volume.
        let kept = |i: usize| muscles[i].params.volume.enabled;
        let (lo_i, lo) = worst(
            &mut self
                .volume_ratio
                .iter()
                .enumerate()
                .map(|(i, r)| if kept(i) { -r.0 } else { f64::NEG_INFINITY }),
        );
        let (hi_i, hi) = worst(&mut self.volume_ratio.iter().enumerate().map(|(i, r)| {
            if kept(i) {
                r.1 / gain(i)
            } else {
                f64::NEG_INFINITY
            }
        }));
        push(
            "volume",
            format!(
                "min {:.3} ({}), max {:.3} of the gain ({})",
                -lo,
                name(lo_i),
                hi,
                name(hi_i)
            ),
            vec![
                Measured::new("min", -lo, ""),
                Measured::new("max", hi, "of the gain"),
            ],
            format!("[{}, gain × {}]", limits.volume_min, limits.volume_max),
            Some(muscles.is_empty() || (-lo >= limits.volume_min && hi <= limits.volume_max)),
        );
        let (min_i, min) = worst(&mut self.strain.iter().map(|s| -f64::from(s.min.0)));
        let (max_i, max) = worst(&mut self.strain.iter().map(|s| f64::from(s.max.0)));
        push(
            "edge strain",
            format!(
                "min {:.3} ({}, frame {}), max {:.3} ({}, frame {}{})",
                -min,
                name(min_i),
                self.strain.get(min_i).map_or(0, |s| s.min.1),
                max,
                name(max_i),
                self.strain.get(max_i).map_or(0, |s| s.max.1),
                // What its attachments force of that muscle (a lower bound
                // on its largest strain): whether the solver or the
                // attachments stretched it.
                self.forced_strain_max
                    .get(max_i)
                    .copied()
                    .flatten()
                    .map_or(String::new(), |f| format!(
                        "; its attachments force ×{f:.2}"
                    ))
            ),
            vec![
                Measured::new("min", -min, ""),
                Measured::new("max", max, ""),
            ],
            format!("[{}, {}]", limits.strain[0], limits.strain[1]),
            Some(
                muscles.is_empty()
                    || (-min >= f64::from(limits.strain[0]) && max <= f64::from(limits.strain[1])),
            ),
        );
        let (f_i, flipped) = worst(&mut self.flipped_max.iter().map(|f| f.0 as f64));
        push(
            "flipped triangles",
            format!(
                "{} ({}, frame {})",
                flipped.max(0.0),
                name(f_i),
                self.flipped_max.get(f_i).map_or(0, |f| f.1)
            ),
            vec![Measured::new("", flipped.max(0.0), "")],
            format!("≤ {}", limits.flipped),
            Some(flipped <= limits.flipped as f64),
        );
        let at_rest = self.at_rest(solver, motion_end, limits.settle);
        let judged = |pass: bool| at_rest.then_some(pass);
        let motion = self.recent_motion();
        let total = self.recent_motion_total();
        let (v_i, _) = worst(&mut motion.iter().map(|m| f64::from(m.rms_velocity())));
        push(
            "rest velocity",
            format!(
                "{:.3} mm/s RMS over the last second (worst {}: {:.3})",
                total.rms_velocity() * 1e3,
                name(v_i),
                motion.get(v_i).map_or(0.0, |m| m.rms_velocity() * 1e3)
            ),
            vec![Measured::new(
                "",
                f64::from(total.rms_velocity()) * 1e3,
                "mm/s",
            )],
            format!("< {} mm/s", limits.rest_velocity * 1e3),
            judged(total.rms_velocity() < limits.rest_velocity),
        );
        let (a_i, _) = worst(&mut motion.iter().map(|m| f64::from(m.rms_acceleration())));
        push(
            "rest jiggle",
            format!(
                "{:.4} m/s² RMS over the last second (worst {}: {:.4})",
                total.rms_acceleration(),
                name(a_i),
                motion.get(a_i).map_or(0.0, |m| m.rms_acceleration())
            ),
            vec![Measured::new(
                "",
                f64::from(total.rms_acceleration()),
                "m/s²",
            )],
            format!("< {} m/s²", limits.rest_jiggle),
            judged(total.rms_acceleration() < limits.rest_jiggle),
        );
        let (lo_i, _) = worst(&mut motion.iter().map(|m| -f64::from(m.strain_min)));
        let (hi_i, _) = worst(&mut motion.iter().map(|m| f64::from(m.strain_max)));
        push(
            "rest strain",
            format!(
                "min {:.3} ({}), max {:.3} ({}) over the last second",
                total.strain_min,
                name(lo_i),
                total.strain_max,
                name(hi_i)
            ),
            vec![
                Measured::new("min", f64::from(total.strain_min), ""),
                Measured::new("max", f64::from(total.strain_max), ""),
            ],
            format!("[{}, {}]", limits.rest_strain[0], limits.rest_strain[1]),
            judged(
                muscles.is_empty()
                    || total.strain_min >= limits.rest_strain[0]
                        && total.strain_max <= limits.rest_strain[1],
            ),
        );
        let deviation = self.rest_deviation(solver);
        let (d_i, d) = worst(&mut deviation.iter().map(|d| f64::from(d.max)));
        push(
            "rest deviation",
            format!(
                "{:.3} mm ({} vertex {})",
                d.max(0.0) * 1e3,
                name(d_i),
                deviation.get(d_i).map_or(0, |d| d.worst_vertex)
            ),
            vec![Measured::new("", d.max(0.0) * 1e3, "mm")],
            format!("≤ {} mm", limits.rest_deviation * 1e3),
            judged(d <= f64::from(limits.rest_deviation)),
        );
        let binds = super::skin_bind_distances(solver, limits.skin_bind);
        if let Some(d) = binds.iter().max_by(|a, b| a.max.total_cmp(&b.max)) {
            push(
                "rest skin bind",
                format!(
                    "{:.3} mm from the skinned position ({} vertex {}); {} of {} vertices farther than {} mm where no muscle is active (over active muscles, {} vertices: up to {:.3} mm)",
                    d.max * 1e3,
                    name(d.skin),
                    d.vertex,
                    d.over,
                    d.bound,
                    limits.skin_bind * 1e3,
                    d.active_bound,
                    d.active_max * 1e3
                ),
                vec![
                    Measured::new("", f64::from(d.max) * 1e3, "mm"),
                    Measured::new("", d.over as f64, "vertices farther where no muscle acts"),
                ],
                format!("≤ {} mm", limits.skin_bind * 1e3),
                judged(d.max <= limits.skin_bind),
            );
        }
        out
    }
}
