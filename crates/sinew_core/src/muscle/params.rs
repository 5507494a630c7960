//! Per-muscle parameters. Every tunable states its unit and default.

use super::internal::InternalStructureParams;
use super::{Compliances, ConstraintKind};
use crate::constraints::{AreaMode, FiberMode, SlidingMode, VolumeParams};
use crate::error::BuildError;
use serde::{Deserialize, Serialize};

/// Most fibre smoothing passes [`MuscleParams::validate`] accepts.
pub const MAX_FIBER_SMOOTHING: u32 = 1_000;

/// Default weights of the three target connections, normalised per vertex
/// when `normalize` is set (as AdonisFX does). A weight of 0 disables that
/// connection for the vertex (the constraint exists but is skipped).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ConnectionWeights {
    /// Sliding weight. Default: `1.0`.
    pub sliding: f32,
    /// Soft weight. Default: `0.5`.
    pub soft: f32,
    /// Hard weight. Default: `0.25`.
    pub hard: f32,
    /// Divide the three weights by their sum per vertex. Default: `true`.
    pub normalize: bool,
}

impl Default for ConnectionWeights {
    fn default() -> Self {
        Self {
            sliding: 1.0,
            soft: 0.5,
            hard: 0.25,
            normalize: true,
        }
    }
}

/// How particle masses are assigned.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum MassMode {
    /// Every particle has this mass. Units: kg.
    Uniform(f32),
    /// `ρ V_rest`, lumped as a solid's: with an internal structure, each
    /// surface triangle's tetrahedron to the medulla gives a quarter of its
    /// mass to each corner (see `muscle::mass`); without one, spread over the
    /// surface by one-ring area. Units: kg/m³. Muscle: 1060.
    Density(f32),
    /// `σ A` for a thin layer (skin, fat, fascia: a surface with no
    /// volume of its own): each vertex carries a third of the area of its
    /// triangles. Units: kg/m² (skin 1.1 kg/m² per millimetre of thickness).
    AreaDensity(f32),
}

impl Default for MassMode {
    /// Density of muscle, 1060 kg/m³: in SI units a uniform 1 kg per vertex (the
    /// spec's fallback) would make a 12 cm oval weigh 92 kg.
    fn default() -> Self {
        Self::Density(1060.0)
    }
}

/// All parameters of one muscle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MuscleParams {
    /// Activation `a ∈ [0, 1]` (dynamic; clamped and reported once when outside).
    /// Default: `0`.
    pub activation: f32,
    /// Rest activation `a0` of the modelled shape, clamped to ≤ 0.95. Default: `0`.
    pub rest_activation: f32,
    /// Fraction of fibre length lost at full activation (`c` in the rest-length
    /// formulas; the paper's value is 1). Default: `0.35`.
    pub max_contraction: f32,
    /// Solver iterations for this muscle; `None` uses the global count. A
    /// muscle runs the substep's first ones, a surface layer its own spread
    /// evenly over the substep's ([`crate::solver::IterationParams::runs`]).
    /// Default: `None`.
    pub iterations: Option<u32>,
    /// Fibre rest-length formula. Default: [`FiberMode::RotationInvariant`].
    pub fiber_mode: FiberMode,
    /// Compliance per constraint type.
    pub compliance: Compliances,
    /// Volume constraint and activation gain.
    pub volume: VolumeParams,
    /// Branch rest lengths follow activation along the branch (SPEC §5.4). Default: `true`.
    pub branch_follows_activation: bool,
    /// Internal rest lengths follow activation (SPEC §5.3 option): shorter along
    /// the fibre, longer across it with `bulge`. Default: `true`.
    pub internal_follows_activation: bool,
    /// Rotation-invariant mode: the across-fibre part of every rest length grows
    /// by `β = sqrt(k_p / λ)` so the activated rest shape has the activated
    /// volume (see [`crate::constraints::ActivationScale`]). Default: `true`.
    pub bulge: bool,
    /// Default target-connection weights.
    pub weights: ConnectionWeights,
    /// Contact band: the largest rest gap at which a surface vertex slides on
    /// a target (Sliding is contact), and at which Soft and Hard tie it to
    /// another *muscle*. Soft and Hard tie a vertex to its nearest *bone* at
    /// any gap: a bone does not deform, so a tie to it a few centimetres
    /// away holds. A connection with no target in its band stays switched
    /// off. Units: m (scene units). Default: `0.003`. See ARCHITECTURE.md,
    /// "Connections".
    pub contact_reach: f32,
    /// Sliding behaviour. Default: [`SlidingMode::KeepGap`].
    pub sliding_mode: SlidingMode,
    /// A surface layer's Area constraints: both ways, or only against
    /// shrinking ([`AreaMode`]). Default: [`AreaMode::Keep`] (`sinew
    /// fit`'s skin: [`AreaMode::NoShrink`]).
    #[serde(skip_serializing_if = "is_default_area_mode")]
    pub area_mode: AreaMode,
    /// Velocity damping rate `c`: over a substep of `h` seconds the
    /// velocity keeps `e^(−c h)`, the same decay per second at any frame
    /// rate or substep count (`3.08` keeps 95 % per 1/60 s, what `0.05`
    /// per frame was at 60 Hz). Units: 1/s. Range `[0, 1000]`. Default:
    /// `3.08`.
    pub damping: f32,
    /// Mass assignment. Default: density 1060 kg/m³.
    pub mass: MassMode,
    /// Internal structure options.
    pub internal: InternalStructureParams,
    /// Laplacian smoothing passes of the fibre field. Range `[0, 1000]`.
    /// Default: `3`.
    pub fiber_smoothing: u32,
    /// Holds the muscle's shape on its bones: each surface vertex is bound
    /// softly (the Bind constraint, compliance [`Compliances::bind`] ÷ its
    /// strength) to its rest position carried by the bones around it — its
    /// attachment bones and the bones it targets — blended by the inverse
    /// square of its distance to each
    /// ([`crate::muscle::SkinBindingDesc::holding_shape`]; a muscle built
    /// on its own, without the solver's bone surfaces, by its distance to
    /// each attachment bone's held vertices) — what fascia and the tissue
    /// around a muscle do.
    /// Without it, a region that no target is within reach of hangs on the
    /// muscle's own edges and sags under gravity (the edges of a forearm
    /// muscle stretch ×24 in 10 frames on T7). The fibres and the volume
    /// still shorten and bulge the muscle; how much the hold lets go of a
    /// contracting muscle is [`Self::hold_release`]. Ignored for a muscle
    /// given an explicit binding, and for one with no attachment on a bone.
    /// Default: `false` (`sinew fit` turns it on).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub hold_shape: bool,
    /// What is left of a held shape's pull ([`Self::hold_shape`]) at full
    /// activation: the hold is a relaxed muscle's, and weakens as the
    /// muscle contracts (its compliance ÷ `max(1 − a, hold_release)`), so
    /// that an active muscle slides and bulges between its bones and the
    /// hold brings it back to its rest shape once it relaxes. `1` holds
    /// whatever the activation. T5's loosely packed arm needs `0.1`: held
    /// at full strength the biceps' long head, dragged with the bones
    /// through the flexion, fell to ×0.60 of its belly section (×1.23 with
    /// `0.1`); `0.1` still carries an active muscle against gravity (a
    /// 24 cm spindle held only at its ends sags ≤ 20 mm fully active).
    /// Under a skin, `sinew fit` holds a muscle its anatomy does not hold
    /// with `0.2`, along the line of action
    /// ([`crate::character::fit::HELD_UNDER_SKIN`]). Range `[0.01, 1]`.
    /// Default: `1`.
    #[serde(skip_serializing_if = "is_one")]
    pub hold_release: f32,
    /// What carries a held shape ([`Self::hold_shape`]) with the bones:
    /// their blend around each vertex, or the muscle's line of action from
    /// one attachment bone to the other ([`HoldFrame`]). Default:
    /// [`HoldFrame::Bones`].
    #[serde(skip_serializing_if = "is_default_hold_frame")]
    pub hold_frame: HoldFrame,
    /// How a held shape's line ([`HoldFrame::Line`]) bends at its ends: `0`
    /// runs it straight from one attachment group to the other; above
    /// `0` it is a cubic curve that leaves each group along the direction
    /// its bone carries the muscle's rest axis (turned by
    /// [`Self::tendon_pivot`]), with end tangents this many chord lengths
    /// long — so the belly bends over a span of its length where a
    /// straight line turns it all at the rings next to the held ones
    /// ([`crate::muscle::HoldLine`]). T5 uses `1`. Unitless, range
    /// `[0, 4]`. Default: `0`.
    #[serde(skip_serializing_if = "is_zero")]
    pub hold_bend: f32,
    /// How far each attachment group of a muscle whose held shape follows
    /// its line ([`HoldFrame::Line`]) turns about its tendon's tip towards
    /// that line: the group's held vertices — the tendon's end rings — are
    /// carried by their bone and then turned about the tip (the group's
    /// vertex farthest out along the line, which stays where its bone
    /// carries it) by this fraction of the angle between the bone-carried
    /// rest axis and the line, as a tendon bends where it inserts. `0`
    /// holds every ring as its bone carries it; `1` turns it onto the
    /// line. T5 uses `0.7`. Unitless, range `[0, 1]`. Default: `0`.
    #[serde(skip_serializing_if = "is_zero")]
    pub tendon_pivot: f32,
    /// Whether the rest lengths of a muscle whose held shape follows its
    /// line ([`HoldFrame::Line`]) follow that held shape: each Fiber,
    /// Branch and Internal constraint's rest length becomes its length in
    /// the held shape, shortened by the activation where the activation
    /// shortens it (along the fibres, to its share of the longer of the
    /// rest and held lengths and never beyond the held one: the muscle
    /// pulls taut between its tendons, and a flexor its joint shortens is
    /// not shortened twice) and, where the activation lengthens it (across them),
    /// swollen by the volume gain alone — the held line, not the muscle,
    /// sets the muscle's length, so the bulge that keeps the volume at a
    /// shortened length would wrinkle it. The held shape itself then
    /// swells with the volume gain, as the Volume constraint asks
    /// ([`crate::muscle::LineShape::swell`]). Without it the rest lengths
    /// are the rest shape's and the stretch the line imposes piles up at
    /// the held rings (T5's triceps ×1.87; with it ×1.54). Default: `false`.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub rest_follows_hold: bool,
}

/// What carries a held shape ([`MuscleParams::hold_shape`]) as the bones
/// move.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum HoldFrame {
    /// Each vertex's rest position carried by the bones around it, blended
    /// by the inverse square of its distance to each
    /// ([`crate::muscle::SkinBindingDesc::holding_shape`]): a muscle that
    /// lies along its bones and moves with them.
    #[default]
    Bones,
    /// The rest surface carried by the muscle's line of action — from the
    /// centroid of its attachments on one bone to those on another —
    /// stretched along the line and thinned across it as the line
    /// lengthens, its twist graded from one end's bone to the other's
    /// ([`crate::muscle::HoldLine`]): a muscle that spans a joint and
    /// takes the chord when it bends, folding nothing where the bones'
    /// blend would fold its surface over itself. A muscle held on one bone
    /// only keeps [`HoldFrame::Bones`].
    Line,
}

/// Whether `frame` is the default (left out of scene files).
fn is_default_hold_frame(frame: &HoldFrame) -> bool {
    *frame == HoldFrame::default()
}

/// Whether `mode` is the default (left out of scene files).
fn is_default_area_mode(mode: &AreaMode) -> bool {
    *mode == AreaMode::default()
}

/// Whether `x` is 0 (a default left out of scene files).
fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

/// Whether `x` is 1 (a default left out of scene files).
fn is_one(x: &f32) -> bool {
    *x == 1.0
}

impl MuscleParams {
    /// The factor a held shape's pull has at activation `a`: `1 − a`, no
    /// less than [`Self::hold_release`].
    pub fn hold_strength(&self, a: f32) -> f32 {
        (1.0 - a.clamp(0.0, 1.0)).max(self.hold_release)
    }
}

impl Default for MuscleParams {
    fn default() -> Self {
        Self {
            activation: 0.0,
            rest_activation: 0.0,
            max_contraction: 0.35,
            iterations: None,
            fiber_mode: FiberMode::default(),
            compliance: Compliances::default(),
            volume: VolumeParams::default(),
            branch_follows_activation: true,
            internal_follows_activation: true,
            bulge: true,
            weights: ConnectionWeights::default(),
            contact_reach: 0.003,
            sliding_mode: SlidingMode::default(),
            area_mode: AreaMode::default(),
            damping: 3.08,
            mass: MassMode::default(),
            internal: InternalStructureParams::default(),
            fiber_smoothing: 3,
            hold_shape: false,
            hold_release: 1.0,
            hold_frame: HoldFrame::Bones,
            hold_bend: 0.0,
            tendon_pivot: 0.0,
            rest_follows_hold: false,
        }
    }
}

impl MuscleParams {
    /// Parameters of a passive surface layer — skin, fat or fascia over
    /// the muscles, the second kind of deformable body: no internal
    /// structure, no volume constraint, no activation. Its edges keep their
    /// rest lengths (the fibre batch, plain distance constraints at
    /// activation 0) and every vertex slides on its targets at its rest
    /// gap, up to `reach` away (Sliding only: Soft and Hard weights 0).
    /// `area_density` is the layer's mass per area (kg/m²); `reach` is its
    /// [`Self::contact_reach`] (m, scene units): at least the layer's
    /// thickness over what it slides on.
    pub fn surface_layer(area_density: f32, reach: f32) -> Self {
        Self {
            volume: VolumeParams {
                enabled: false,
                ..Default::default()
            },
            internal: InternalStructureParams {
                enabled: false,
                ..Default::default()
            },
            bulge: false,
            branch_follows_activation: false,
            internal_follows_activation: false,
            weights: ConnectionWeights {
                sliding: 1.0,
                soft: 0.0,
                hard: 0.0,
                normalize: false,
            },
            contact_reach: reach,
            mass: MassMode::AreaDensity(area_density),
            fiber_smoothing: 0,
            ..Default::default()
        }
    }

    /// Whether these are a surface layer's parameters (skin, fat, fascia:
    /// mass per area, [`Self::surface_layer`]) rather than a muscle's.
    pub fn is_surface_layer(&self) -> bool {
        matches!(self.mass, MassMode::AreaDensity(_))
    }

    /// Rejects NaN, negative or out-of-range values with a typed error.
    pub fn validate(&self, muscle: &str) -> Result<(), BuildError> {
        let bad = |parameter: &str, value: f32, reason: &str| BuildError::InvalidParameter {
            muscle: muscle.to_string(),
            parameter: parameter.to_string(),
            value,
            reason: reason.to_string(),
        };
        for kind in ConstraintKind::CANONICAL_ORDER {
            let c = self.compliance.get(kind);
            if c.is_nan() || c < 0.0 {
                return Err(bad(
                    &format!("compliance.{}", kind.label()),
                    c,
                    "compliance must be ≥ 0 and not NaN (0 = rigid)",
                ));
            }
        }
        let checks = [
            ("activation", self.activation, 0.0, 1.0),
            ("rest_activation", self.rest_activation, 0.0, 1.0),
            ("max_contraction", self.max_contraction, 0.0, 1.0),
            ("damping", self.damping, 0.0, 1000.0),
            ("hold_release", self.hold_release, 0.01, 1.0),
            ("hold_bend", self.hold_bend, 0.0, 4.0),
            ("tendon_pivot", self.tendon_pivot, 0.0, 1.0),
            (
                "volume.gain",
                self.volume.gain,
                f32::MIN_POSITIVE,
                f32::INFINITY,
            ),
            (
                "volume.activation_gain",
                self.volume.activation_gain,
                f32::MIN_POSITIVE,
                f32::INFINITY,
            ),
            ("weights.sliding", self.weights.sliding, 0.0, f32::INFINITY),
            ("weights.soft", self.weights.soft, 0.0, f32::INFINITY),
            ("weights.hard", self.weights.hard, 0.0, f32::INFINITY),
            ("contact_reach", self.contact_reach, 0.0, f32::MAX),
        ];
        for (name, value, lo, hi) in checks {
            if value.is_nan() || value < lo || value > hi || value.is_infinite() {
                let expected = match (lo, hi) {
                    (f32::MIN_POSITIVE, f32::INFINITY) => "a finite value > 0".to_string(),
                    (lo, f32::INFINITY | f32::MAX) => format!("a finite value ≥ {lo}"),
                    (lo, hi) => format!("a value in [{lo}, {hi}]"),
                };
                return Err(bad(name, value, &format!("expected {expected}")));
            }
        }
        if let Some(iterations) = self.iterations
            && !(1..=crate::solver::MAX_ITERATIONS).contains(&iterations)
        {
            return Err(bad(
                "iterations",
                iterations as f32,
                &format!(
                    "expected None (the solver's count) or 1 to {}",
                    crate::solver::MAX_ITERATIONS
                ),
            ));
        }
        if self.fiber_smoothing > MAX_FIBER_SMOOTHING {
            return Err(bad(
                "fiber_smoothing",
                self.fiber_smoothing as f32,
                &format!("expected at most {MAX_FIBER_SMOOTHING} passes"),
            ));
        }
        match self.mass {
            MassMode::Uniform(m) | MassMode::Density(m) | MassMode::AreaDensity(m)
                if !(m > 0.0 && m.is_finite()) =>
            {
                Err(bad("mass", m, "mass and density must be finite and > 0"))
            }
            _ => Ok(()),
        }
    }
}
