//! Solver settings: the projection method, the sweep schedule, and every
//! global tunable with its unit and default.

use crate::error::BuildError;
use crate::muscle::ConstraintKind;
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// How constraints are projected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum SolverMethod {
    /// Gauss–Seidel, one muscle after another, in the canonical order. The
    /// reference: bit-identical run to run. A surface layer (a skin: one
    /// body of some 90 000 constraints over a whole character) is projected
    /// in the order of its greedy first-fit colour groups instead: still
    /// Gauss–Seidel, each constraint seeing the corrections before it, but
    /// the constraints of a group share no particle, so the layer splits
    /// over the threads (same bits for any thread count) instead of being
    /// one thread's serial work while the muscles wait; where the groups
    /// are small for the thread count, the threads run the whole pass as
    /// one team, waiting for each other between groups instead of forking
    /// each one.
    #[default]
    Sequential,
    /// Graph colouring (SPEC §9.3, the thesis' SMT-G): each muscle's
    /// constraints in greedy first-fit colour groups, the groups one after
    /// the other and each group's constraints in parallel. Volume and the
    /// bone contacts are solved after the groups, as in `Sequential`.
    Colored {
        /// Which constraints are coloured together.
        scope: ColorScope,
    },
    /// Jacobi (SPEC §9.2, the thesis' SMT-J): the attachments solved
    /// Gauss–Seidel first, every other constraint (but Volume) computed from
    /// the same positions, in parallel, and each particle moved by `omega`
    /// times the mean of its corrections. The per-particle sum is a gather in
    /// a fixed order (no float atomics), so any thread count gives the same
    /// bits. Volume and the bone contacts follow, as in `Sequential`.
    Jacobi {
        /// Over-relaxation ω ∈ [1, 2].
        omega: f32,
    },
    /// Hybrid (Fratarcangeli & Pellacini 2015): the per-muscle colour groups
    /// with at least `min_group` constraints are solved Gauss–Seidel, group by
    /// group; the small, high-degree tail (the internal points' links) is
    /// solved by one Jacobi pass after them, with over-relaxation `omega`.
    /// Volume and the bone contacts follow. Bit-identical for any thread count.
    Hybrid {
        /// Smallest colour group solved Gauss–Seidel (≥ 1).
        min_group: u32,
        /// Over-relaxation ω ∈ [1, 2] of the Jacobi tail.
        omega: f32,
    },
}

impl SolverMethod {
    /// Every method, with the parameters the shipped scenes use (Jacobi and
    /// Hybrid ω 1.5, Hybrid's smallest Gauss–Seidel group 32): what tests
    /// that hold for every method iterate over.
    pub const EVERY: [SolverMethod; 5] = [
        SolverMethod::Sequential,
        SolverMethod::Colored {
            scope: ColorScope::PerMuscle,
        },
        SolverMethod::Colored {
            scope: ColorScope::Global,
        },
        SolverMethod::Jacobi { omega: 1.5 },
        SolverMethod::Hybrid {
            min_group: 32,
            omega: 1.5,
        },
    ];
}

/// What a colouring spans.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ColorScope {
    /// One colouring per muscle, one constraint at a time (the thesis): the
    /// internal points make it long (24 groups per arm muscle).
    #[default]
    PerMuscle,
    /// Clustered colouring (see [`crate::solver::coloring::ColorPlan::clustered`]): the
    /// single-particle constraints of a vertex and the links of an internal
    /// point are units one thread solves in order, which cuts the colours to
    /// an edge colouring's. The solver runs colour `c` of every muscle in one
    /// parallel sweep, split into chunks, so a large muscle spreads over
    /// every thread.
    Global,
}

/// How the solver spreads a coloured method's sweeps over its threads. Both
/// give the same bits; only the speed differs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SweepSchedule {
    /// Colour by colour across muscles when splitting by muscle would leave
    /// threads idle (one muscle much larger than its share), else by muscle.
    #[default]
    Auto,
    /// Each thread takes whole muscles: one synchronisation per iteration.
    ByMuscle,
    /// Colour `c` of every muscle in one parallel sweep of (muscle, chunk)
    /// tasks: balanced, one synchronisation per colour. Only for
    /// `Colored { scope: Global }` and `Hybrid`.
    ByColor,
}

/// Longest frame time step [`SolverSettings::validate`] accepts. Units: s.
pub const MAX_DT: f32 = 1.0;
/// Most iterations per (sub)step [`SolverSettings::validate`] accepts.
pub const MAX_ITERATIONS: u32 = 10_000;
/// Most substeps per frame [`SolverSettings::validate`] accepts.
pub const MAX_SUBSTEPS: u32 = 1_000;
/// Most worker threads [`SolverSettings::validate`] accepts (each is an OS
/// thread with its own stack: a typo such as `100000` would exhaust the
/// machine).
pub const MAX_THREADS: u32 = 1_024;
/// Largest gravity magnitude [`SolverSettings::validate`] accepts
/// (≈ 100 g). Units: m/s².
pub const MAX_GRAVITY: f32 = 1_000.0;

/// Global solver settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverSettings {
    /// Frame time step. Units: s. Default: `1/60`.
    pub dt: f32,
    /// Global iterations per (sub)step; each muscle runs `min(own, N)`. Default: `10`.
    pub iterations: u32,
    /// Substeps per frame (Small Steps). Default: `1`.
    pub substeps: u32,
    /// Gravity as an acceleration, in real units. Units: m/s². Default: `(0, 0, 0)`.
    pub gravity: Vec3,
    /// Multiplies `dt` (slow motion < 1). Default: `1`.
    pub time_scale: f32,
    /// Scene units per metre (`100` for a scene in centimetres): the one
    /// unit of length. Geometry (meshes, bone tracks, attachment points) is
    /// in scene units; every physical parameter is SI and converted by it —
    /// gravity (m/s²) and velocities scale by it, densities (kg/m³, kg/m²)
    /// are divided by its cube and square, Volume's compliance (m³/N) is
    /// multiplied by its fourth power, lengths such as
    /// [`crate::muscle::MuscleParams::contact_reach`] (m) by it. Distance
    /// compliances (m/N = s²/kg), masses (kg) and damping (1/s) are
    /// independent of it. A scene authored in centimetres with `100` moves
    /// as the same scene in metres, ×100. Default: `1` (metres).
    #[serde(alias = "space_scale")]
    pub length_unit: f32,
    /// Projection method. Default: [`SolverMethod::Sequential`].
    pub method: SolverMethod,
    /// Order in which constraint types are projected: every type once, in
    /// any order (a scene written before a type existed must add it; the
    /// error names it). Default: SPEC §4.3, with Bind before the target
    /// connections and Area after Fiber.
    pub projection_order: Vec<ConstraintKind>,
    /// Measure per-block time. Default: `true`.
    pub timers: bool,
    /// Every this many frames each vertex runs the full (BVH) closest-point
    /// search on each target, staggered over vertices; in between, the
    /// closest point walks over the target from last iteration's triangle
    /// (see [`crate::closest`]). `1` = a full search every frame. Default: `16`.
    pub full_search_interval: u32,
    /// Every this many frames each vertex re-chooses the target it slides
    /// on among the targets within its contact band (staggered over
    /// vertices, and always with a full search); in between it keeps its
    /// target and checks only the bones whose boxes it is in (it may have
    /// entered one). A vertex switches only to a target it has come nearer
    /// to *relative to its rest gap* by a tenth of the band (see
    /// `pipeline::closest`). `1` = every frame. Default: `4`.
    pub choose_interval: u32,
    /// In the iterations of a substep that do not walk (see
    /// `walk_interval`), project each vertex onto the face plane, edge or
    /// corner of the triangle the last walk found (the triangle's corners
    /// read, its plane kept from the walk) instead of re-projecting onto
    /// the triangle (a triangle test and its interpolated normal). Exact
    /// while the vertex stays in that feature's region. A contact layer (a
    /// skin) always re-projects onto the triangle: on the fitted character
    /// the features flipped 320 of its triangles (ARCHITECTURE.md, the
    /// skin's closest data). Default: `false`.
    pub feature_contacts: bool,
    /// Sliding's closest data walks over the targets in every this many
    /// iterations of a substep — the first, every `k`-th after it — and in
    /// between re-projects onto what the last walk found (see
    /// `feature_contacts`), so the contact point slides from triangle to
    /// triangle as the vertex does. Walking only in a substep's first
    /// iteration left the constraint on one triangle's plane until the next
    /// substep's walk moved it to the neighbour, a kick that kept T5 at rest
    /// moving at 1.14 mm/s RMS (0.053 walking in every iteration, and
    /// 0.053 in every 4th with `feature_contacts`: T7's recipe, whose
    /// closest data it took from 26 % of the step to 21 %, and its worst
    /// penetration over sixteen perturbed runs from 0.636 to 0.670 % of
    /// the surface vertices; ARCHITECTURE.md, "Walks every few
    /// iterations"). A contact layer walks in a substep's first iteration
    /// only. Scenes written with the flag this replaced read
    /// `walk_every_iteration: true` as `1` and `false` as once per substep.
    /// `1` = every iteration. Units: iterations. Default: `1`.
    #[serde(
        alias = "walk_every_iteration",
        deserialize_with = "walk_interval_or_flag"
    )]
    pub walk_interval: u32,
    /// A muscle's bone contacts (a vertex inside a bone put back on its
    /// surface, after each iteration's projections) run in every this many
    /// iterations of a substep — the first, every `k`-th after it — and
    /// always in the muscle's last: every substep still ends with no vertex
    /// inside a bone, and in between Sliding keeps vertices out as it does
    /// off every other target. A surface layer (a skin) keeps them in every
    /// iteration. On T7 they were a quarter of the frame; at `3` its walk
    /// took ×0.93 of the instructions (×0.94–0.99 of the time on one
    /// thread), and its worst share of vertices inside a bone went from
    /// 0.50 % to 0.51 % (ARCHITECTURE.md,
    /// "Bone contacts every few iterations"). `1` = every iteration.
    /// Units: iterations. Default: `1`.
    pub bone_contact_interval: u32,
    /// Iterations between two publications of the muscles' snapshots
    /// (the surfaces other muscles and skins slide on): a substep's
    /// iterations run in blocks of `k`, each muscle a block's iterations
    /// back to back in one task, reading the snapshots published at the
    /// block's start — Jacobi between muscles over a block, Gauss–Seidel
    /// within each. A muscle's data then stays in cache from one iteration
    /// to the next (from L3 on the development machine it is reloaded at
    /// every iteration otherwise): at `5` T7's walk took ×0.72–0.79 of the
    /// time on one thread and 10.1–10.7 → 7.5–8.1 ms on two, its check
    /// figures within their run-to-run scatter, and the fitted character's
    /// skin figures the same (ARCHITECTURE.md, "Snapshots every few
    /// iterations"). Bones are posed per substep and are not affected;
    /// closest points are still found in every iteration. `1` = every
    /// iteration (the thesis).
    /// Units: iterations. Default: `1`.
    pub snapshot_interval: u32,
    /// Worker threads for closest data and projection, split by muscle
    /// (SPEC §9.1): `1` spawns none, `0` uses every core. Muscles read each
    /// other only through published snapshots, so the result is bit-identical
    /// for any count. Default: `0` (every core).
    pub threads: u32,
    /// How coloured methods use the threads. Default: [`SweepSchedule::Auto`].
    pub schedule: SweepSchedule,
    /// Scenes with fewer constraints than this run their passes over
    /// muscles on the calling thread, and scenes with fewer particles their
    /// per-particle passes (integration, goals, publishing; a particle whose
    /// goal follows a held line counts
    /// [`crate::solver::Parallelism::HELD_LINE_WEIGHT`] times), whatever
    /// `threads` says: a fork and join (≈ 10 µs on the 2-core development
    /// machine) costs more than the split saves. The same bits either way.
    /// Default: `8192` (P2 ran 3× and P3 1.2× slower on two threads than on
    /// one without it; P4 and T7 split, P4's per-particle passes as well).
    pub parallel_threshold: usize,
    /// The run-time guard's speed limit: after each frame a muscle with a
    /// particle faster than this (or a NaN or infinite one) is put back to
    /// its last good frame and reported ([`crate::solver::Fault`]), while
    /// the others run on. Muscles in a sprint move at a few m/s; a blow-up
    /// reaches thousands. Units: m/s. Default: `100`.
    pub max_speed: f32,
}

/// Reads [`SolverSettings::walk_interval`]: a count of iterations, or the
/// flag it replaced (`walk_every_iteration`): `true` walks in every
/// iteration (`1`), `false` once per substep (`u32::MAX`).
fn walk_interval_or_flag<'de, D: serde::Deserializer<'de>>(reader: D) -> Result<u32, D::Error> {
    struct IntervalOrFlag;
    impl serde::de::Visitor<'_> for IntervalOrFlag {
        type Value = u32;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("walk_interval: a count of iterations (≥ 1), or true / false")
        }
        fn visit_bool<E: serde::de::Error>(self, every: bool) -> Result<u32, E> {
            Ok(if every { 1 } else { u32::MAX })
        }
        fn visit_u64<E: serde::de::Error>(self, n: u64) -> Result<u32, E> {
            u32::try_from(n)
                .map_err(|_| E::invalid_value(serde::de::Unexpected::Unsigned(n), &self))
        }
        fn visit_i64<E: serde::de::Error>(self, n: i64) -> Result<u32, E> {
            u32::try_from(n).map_err(|_| E::invalid_value(serde::de::Unexpected::Signed(n), &self))
        }
    }
    reader.deserialize_any(IntervalOrFlag)
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            dt: 1.0 / 60.0,
            iterations: 10,
            substeps: 1,
            gravity: Vec3::ZERO,
            time_scale: 1.0,
            length_unit: 1.0,
            method: SolverMethod::Sequential,
            projection_order: ConstraintKind::CANONICAL_ORDER.to_vec(),
            timers: true,
            full_search_interval: 16,
            choose_interval: 4,
            feature_contacts: false,
            walk_interval: 1,
            bone_contact_interval: 1,
            snapshot_interval: 1,
            threads: 0,
            schedule: SweepSchedule::Auto,
            parallel_threshold: 8192,
            max_speed: 100.0,
        }
    }
}

impl SolverSettings {
    /// Simulated seconds one step covers, `dt × time_scale`: what every
    /// driver adds to its clock per step and what rates are measured over.
    pub fn step_time(&self) -> f32 {
        self.dt * self.time_scale
    }

    /// Rejects NaN and out-of-range values.
    pub fn validate(&self) -> Result<(), BuildError> {
        let bad = |setting: &str, value: f32, reason: &str| BuildError::InvalidSetting {
            setting: setting.into(),
            value,
            reason: reason.into(),
        };
        if !(self.dt > 0.0 && self.dt <= MAX_DT) {
            return Err(bad("dt", self.dt, "must be > 0 and at most 1 s"));
        }
        if let SolverMethod::Jacobi { omega } | SolverMethod::Hybrid { omega, .. } = self.method
            && !(1.0..=2.0).contains(&omega)
        {
            return Err(bad("method.omega", omega, "must be in [1, 2]"));
        }
        if let SolverMethod::Hybrid { min_group: 0, .. } = self.method {
            return Err(bad("method.min_group", 0.0, "must be ≥ 1"));
        }
        if !(self.time_scale > 0.0 && self.time_scale.is_finite()) {
            return Err(bad("time_scale", self.time_scale, "must be finite and > 0"));
        }
        if !(self.length_unit > 0.0 && self.length_unit.is_finite()) {
            return Err(bad(
                "length_unit",
                self.length_unit,
                "must be finite and > 0 (scene units per metre)",
            ));
        }
        if self.full_search_interval == 0 {
            return Err(bad("full_search_interval", 0.0, "must be ≥ 1"));
        }
        if self.choose_interval == 0 {
            return Err(bad("choose_interval", 0.0, "must be ≥ 1"));
        }
        if self.walk_interval == 0 {
            return Err(bad("walk_interval", 0.0, "must be ≥ 1"));
        }
        if self.bone_contact_interval == 0 {
            return Err(bad("bone_contact_interval", 0.0, "must be ≥ 1"));
        }
        if self.snapshot_interval == 0 {
            return Err(bad("snapshot_interval", 0.0, "must be ≥ 1"));
        }
        for (setting, value, most) in [
            ("iterations", self.iterations, MAX_ITERATIONS),
            ("substeps", self.substeps, MAX_SUBSTEPS),
            ("threads", self.threads, MAX_THREADS),
        ] {
            let least = u32::from(setting != "threads");
            if !(least..=most).contains(&value) {
                return Err(bad(
                    setting,
                    value as f32,
                    &format!("must be in [{least}, {most}]"),
                ));
            }
        }
        if !(self.max_speed > 0.0 && self.max_speed.is_finite()) {
            return Err(bad(
                "max_speed",
                self.max_speed,
                "must be finite and > 0 (m/s)",
            ));
        }
        let gravity = self.gravity.length();
        if gravity.is_nan() || gravity > MAX_GRAVITY {
            return Err(bad(
                "gravity",
                gravity,
                "its magnitude must be finite and at most 1000 m/s² (≈ 100 g; Earth's is 9.81)",
            ));
        }
        let listed = |k: &ConstraintKind| self.projection_order.iter().filter(|&o| o == k).count();
        let all = ConstraintKind::CANONICAL_ORDER;
        let missing: Vec<_> = all.into_iter().filter(|k| listed(k) == 0).collect();
        let repeated: Vec<_> = all.into_iter().filter(|k| listed(k) > 1).collect();
        if !missing.is_empty() || !repeated.is_empty() {
            return Err(BuildError::ProjectionOrder { missing, repeated });
        }
        Ok(())
    }
}
