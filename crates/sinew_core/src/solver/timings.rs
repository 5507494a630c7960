//! Per-block timers (the thesis' execution blocks BE1–BE8, SPEC §10.3).

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
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
    /// Iterations whose colour sweeps ran colour by colour across muscles
    /// ([`super::SweepSchedule::ByColor`], or chosen by `Auto`) instead of
    /// muscle by muscle.
    pub sweeps_by_color: u32,
    /// The surface layers' (a skin's) own tasks inside closest data and
    /// project, by phase.
    pub layers: LayerTimings,
}

/// Wall time of the surface layers' (a skin's: see
/// [`crate::muscle::MuscleParams::is_surface_layer`]) own tasks in the
/// closest-data and project blocks, by phase, summed over the layers and
/// their iterations. A layer's task runs its iterations one after another
/// (its phases fork onto the threads inside), so where it is as long as
/// the two blocks together the layer is what the frame waits for: the
/// figure a many-core run needs to tell (README "On 16 cores"). Taken when
/// a sweep runs muscle by muscle (not across muscles colour by colour:
/// then zero), with the timers on.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LayerTimings {
    /// Closest data: the Sliding constraints' closest points.
    pub closest_data: Duration,
    /// The colour sweep over its distance, Area, Bind and Sliding constraints.
    pub sweep: Duration,
    /// The end of each iteration: bone contacts, and the snapshot staged
    /// for the muscles that slide on it.
    pub finish: Duration,
}

impl LayerTimings {
    /// The three phases in order (closest data, sweep, finish).
    pub fn as_array(&self) -> [Duration; 3] {
        [self.closest_data, self.sweep, self.finish]
    }

    /// The layers' tasks in all.
    pub fn total(&self) -> Duration {
        self.as_array().iter().sum()
    }
}

impl std::ops::AddAssign for LayerTimings {
    fn add_assign(&mut self, other: Self) {
        self.closest_data += other.closest_data;
        self.sweep += other.sweep;
        self.finish += other.finish;
    }
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
/// A driver starts one per step (or per system) and laps it into the
/// [`StepTimings`] block that just ran.
#[derive(Debug)]
pub struct Stopwatch {
    last: Option<Instant>,
    reads: u32,
}

impl Stopwatch {
    /// A stopwatch started now, or one that reads no clock when `!enabled`.
    pub fn new(enabled: bool) -> Self {
        Self {
            last: enabled.then(Instant::now),
            reads: u32::from(enabled),
        }
    }

    /// Adds the time since the previous lap to `slot`.
    #[inline]
    pub fn lap(&mut self, slot: &mut Duration) {
        if let Some(last) = &mut self.last {
            let now = Instant::now();
            *slot += now - *last;
            *last = now;
            self.reads += 1;
        }
    }

    /// Whether it reads the clock (timers on).
    pub fn is_running(&self) -> bool {
        self.last.is_some()
    }

    /// Clock reads so far.
    pub fn reads(&self) -> u32 {
        self.reads
    }
}

impl Stopwatch {
    /// Splits the time since the previous lap between `slots` in
    /// proportion to `shares` (evenly when every share is zero), and counts
    /// `reads` clock reads made elsewhere (by a [`TaskSplit`]).
    pub fn lap_split<const N: usize>(
        &mut self,
        slots: [&mut Duration; N],
        shares: [Duration; N],
        reads: u32,
    ) {
        let mut pass = Duration::ZERO;
        self.lap(&mut pass);
        self.reads += reads;
        let total: Duration = shares.iter().sum();
        for (slot, share) in slots.into_iter().zip(shares) {
            *slot += if total.is_zero() {
                pass / N as u32
            } else {
                pass.mul_f64(share.as_secs_f64() / total.as_secs_f64())
            };
        }
    }
}

/// Time that the tasks of one parallel pass spend in each of two parts,
/// summed over tasks and threads; the pass's wall time is then split in
/// that proportion. Nothing is read when off.
#[derive(Debug)]
pub struct TaskSplit {
    enabled: bool,
    nanos: [AtomicU64; 2],
    /// The surface layers' tasks by phase ([`LayerTimings`]).
    layer_nanos: [AtomicU64; 3],
    reads: AtomicU32,
}

impl TaskSplit {
    /// A split that measures when `enabled`.
    pub fn new(enabled: bool) -> Self {
        Self {
            enabled,
            nanos: [AtomicU64::new(0), AtomicU64::new(0)],
            layer_nanos: [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)],
            reads: AtomicU32::new(0),
        }
    }

    /// The start of a task's first part, or any other instant a task
    /// reads for [`TaskSplit::add_layer`] (`None` when off).
    #[inline]
    pub fn start(&self) -> Option<Instant> {
        self.enabled.then(|| {
            self.reads.fetch_add(1, Ordering::Relaxed);
            Instant::now()
        })
    }

    /// Adds the time since `since` to part `part`; returns now, the start
    /// of the next part.
    #[inline]
    pub fn lap(&self, since: Option<Instant>, part: usize) -> Option<Instant> {
        since.map(|since| {
            let now = Instant::now();
            let spent = (now - since).as_nanos() as u64;
            self.nanos[part].fetch_add(spent, Ordering::Relaxed);
            self.reads.fetch_add(1, Ordering::Relaxed);
            now
        })
    }

    /// Adds a surface layer's phases to [`TaskSplit::layers`]: closest
    /// data from `start` to `middle`, the sweep from `middle` to `swept`,
    /// the finish from `swept` to `end` (instants of the same task).
    pub fn add_layer(&self, [start, middle, swept, end]: [Option<Instant>; 4]) {
        if let (Some(a), Some(b), Some(c), Some(d)) = (start, middle, swept, end) {
            for (slot, (from, to)) in self.layer_nanos.iter().zip([(a, b), (b, c), (c, d)]) {
                slot.fetch_add((to - from).as_nanos() as u64, Ordering::Relaxed);
            }
        }
    }

    /// The surface layers' phases, over every task.
    pub fn layers(&self) -> LayerTimings {
        let [closest_data, sweep, finish] = self
            .layer_nanos
            .each_ref()
            .map(|n| Duration::from_nanos(n.load(Ordering::Relaxed)));
        LayerTimings {
            closest_data,
            sweep,
            finish,
        }
    }

    /// The time spent in each part, over every task.
    pub fn shares(&self) -> [Duration; 2] {
        self.nanos
            .each_ref()
            .map(|n| Duration::from_nanos(n.load(Ordering::Relaxed)))
    }

    /// Clock reads made.
    pub fn reads(&self) -> u32 {
        self.reads.load(Ordering::Relaxed)
    }
}
