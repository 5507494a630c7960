//! Per-block timers (the thesis' execution blocks BE1–BE8, SPEC §10.3).

use std::time::{Duration, Instant};

/// Wall time spent in each block during the last step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepTimings {
    /// Activation, parameters, bone poses (BE1/BE2).
    pub read_inputs: Duration,
    /// Velocity/prediction integration (BE3).
    pub integrate: Duration,
    /// Bone poses for the substep, attachment goals, muscle snapshots (BE4/BE7).
    pub update_targets: Duration,
    /// Closest points and Soft/Hard goals (BE5).
    pub closest_data: Duration,
    /// Constraint projection (BE6).
    pub project: Duration,
    /// `v = (p − x)/Δt`, `x = p` (BE8).
    pub apply: Duration,
    /// Output normals for rendering / export.
    pub write_back: Duration,
    /// Clock reads the timers made during the step (0 with timers off).
    pub clock_reads: u32,
}

impl StepTimings {
    /// Block names, in order.
    pub const NAMES: [&'static str; 7] = [
        "read inputs",
        "integrate",
        "update targets",
        "closest data",
        "project",
        "apply",
        "write back",
    ];

    /// Durations in the order of [`StepTimings::NAMES`].
    pub fn as_array(&self) -> [Duration; 7] {
        [
            self.read_inputs,
            self.integrate,
            self.update_targets,
            self.closest_data,
            self.project,
            self.apply,
            self.write_back,
        ]
    }

    /// Sum of all blocks.
    pub fn total(&self) -> Duration {
        self.as_array().iter().sum()
    }
}

/// Chained lap timer: one `Instant::now()` per block boundary, none when off.
pub(crate) struct Stopwatch {
    last: Option<Instant>,
    reads: u32,
}

impl Stopwatch {
    pub(crate) fn new(enabled: bool) -> Self {
        Self {
            last: enabled.then(Instant::now),
            reads: u32::from(enabled),
        }
    }

    /// Adds the time since the previous lap to `slot`.
    #[inline]
    pub(crate) fn lap(&mut self, slot: &mut Duration) {
        if let Some(last) = &mut self.last {
            let now = Instant::now();
            *slot += now - *last;
            *last = now;
            self.reads += 1;
        }
    }

    /// Clock reads so far.
    pub(crate) fn reads(&self) -> u32 {
        self.reads
    }
}
