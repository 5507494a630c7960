//! Pacing: how many solver steps an app update runs. In real time (the
//! default) the simulation follows Bevy's [`Time`] with a fixed-step
//! accumulator — every step is `dt` long, an update runs as many steps as
//! the time since the last one holds — so muscles keep pace with bones
//! animated by `Time` at any display rate.

use crate::settings::{SimulationState, SinewClock};
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use std::time::Duration;

/// How the simulation follows the app's updates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
pub enum PacingMode {
    /// Steps of [`crate::SinewSettings::dt`] as Bevy's virtual [`Time`]
    /// advances (so pausing `Time<Virtual>` or changing its speed applies):
    /// one update may run no step (a 144 Hz display at 60 Hz steps) or
    /// several (a 30 Hz display).
    #[default]
    RealTime,
    /// One step per app update, whatever time it took: offline rendering,
    /// batch runs and tests that compare frame by frame.
    EveryUpdate,
    /// One step per app update, and Bevy's virtual clock advances by
    /// exactly the step's time per update (the plug-in sets
    /// [`TimeUpdateStrategy::ManualDuration`]): clips played by
    /// `bevy_animation` and the simulation stay in step whatever an update
    /// costs — slow motion where the machine cannot keep up, real time
    /// where it can (a 60 Hz display with vsync at the default `dt`). A
    /// DCC's "play every frame".
    Lockstep,
}

/// How the simulation follows Bevy's clock (a resource; the plug-in's
/// [`crate::SinewPlugin::pacing`] sets it).
///
/// When an update owes more than `max_steps_per_update` steps (a hitch, a
/// breakpoint, a slow machine), it runs that many and drops the rest of the
/// owed time ([`SinewClock::dropped`] adds it up): the simulation slows down
/// rather than spiralling into ever longer updates.
#[derive(Resource, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct SimulationPacing {
    /// Real time or one step per update. Default: [`PacingMode::RealTime`].
    pub mode: PacingMode,
    /// The most steps one update runs. Default: `4`.
    pub max_steps_per_update: u32,
}

impl Default for SimulationPacing {
    fn default() -> Self {
        Self {
            mode: PacingMode::RealTime,
            max_steps_per_update: 4,
        }
    }
}

/// A step is due when the owed time is within this share of `dt` (so
/// rounding a display interval to nanoseconds never skips a step).
const DUE_TOLERANCE: f64 = 1e-4;

impl SimulationPacing {
    /// How many steps this update runs: the owed time (`clock.owed` plus
    /// `elapsed`) in whole steps of `step` seconds, at most
    /// `max_steps_per_update`; updates `clock` (what stays owed, what was
    /// dropped). Paused: none, and nothing is owed (playing again does not
    /// catch up). Stepping once: one.
    pub fn steps(
        &self,
        state: SimulationState,
        elapsed: Duration,
        step: f32,
        clock: &mut SinewClock,
    ) -> u32 {
        match (state, self.mode) {
            (SimulationState::Paused, _) => {
                clock.owed = Duration::ZERO;
                0
            }
            (SimulationState::StepOnce, _)
            | (_, PacingMode::EveryUpdate)
            | (_, PacingMode::Lockstep) => 1,
            (SimulationState::Playing, PacingMode::RealTime) => {
                let step = f64::from(step);
                let owed = clock.owed.as_secs_f64() + elapsed.as_secs_f64();
                let due = ((owed / step) + DUE_TOLERANCE).floor().max(0.0);
                let run = due.min(f64::from(self.max_steps_per_update.max(1)));
                if due > run {
                    clock.dropped += Duration::from_secs_f64((due - run) * step);
                }
                clock.owed = Duration::from_secs_f64((owed - due * step).max(0.0));
                run as u32
            }
        }
    }
}

/// In [`PacingMode::Lockstep`], makes Bevy's clock advance by one step's
/// time per update; gives the app its own [`TimeUpdateStrategy`] back when
/// the mode changes.
pub(crate) fn lock_time_to_steps(
    pacing: Res<SimulationPacing>,
    settings: Res<crate::settings::SinewSettings>,
    strategy: Option<ResMut<TimeUpdateStrategy>>,
    mut own: Local<Option<TimeUpdateStrategy>>,
) {
    let Some(mut strategy) = strategy else {
        return;
    };
    if pacing.mode == PacingMode::Lockstep {
        let step = f64::from(settings.dt) * f64::from(settings.time_scale);
        if step.is_finite() && step > 0.0 {
            let wanted = Duration::from_secs_f64(step);
            if !matches!(*strategy, TimeUpdateStrategy::ManualDuration(d) if d == wanted) {
                let before =
                    std::mem::replace(&mut *strategy, TimeUpdateStrategy::ManualDuration(wanted));
                own.get_or_insert(before);
            }
        }
    } else if let Some(before) = own.take() {
        *strategy = before;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(pacing: SimulationPacing, frame: Duration, updates: usize) -> (u32, SinewClock) {
        let mut clock = SinewClock::default();
        let steps = (0..updates)
            .map(|_| pacing.steps(SimulationState::Playing, frame, 1.0 / 60.0, &mut clock))
            .sum();
        (steps, clock)
    }

    #[test]
    fn one_second_of_time_is_sixty_steps_at_any_rate() {
        let pacing = SimulationPacing::default();
        for hz in [30.0, 60.0, 144.0, 240.0] {
            let (steps, clock) = run(pacing, Duration::from_secs_f64(1.0 / hz), hz as usize);
            assert_eq!(steps, 60, "{hz} Hz");
            assert_eq!(clock.dropped, Duration::ZERO);
            assert!(
                clock.owed < Duration::from_millis(1),
                "{hz} Hz owes {:?}",
                clock.owed
            );
        }
    }

    #[test]
    fn falling_behind_drops_time_beyond_the_cap() {
        let pacing = SimulationPacing::default();
        let (steps, clock) = run(pacing, Duration::from_millis(500), 2);
        assert_eq!(steps, 8);
        // 2 × 30 steps owed, 8 run: 52 dropped.
        let dropped = clock.dropped.as_secs_f64() * 60.0;
        assert!((dropped - 52.0).abs() < 1e-3, "{dropped} steps dropped");
    }

    #[test]
    fn paused_owes_nothing_and_stepping_once_is_one_step() {
        let pacing = SimulationPacing::default();
        let mut clock = SinewClock::default();
        let second = Duration::from_secs(1);
        assert_eq!(
            pacing.steps(SimulationState::Paused, second, 0.1, &mut clock),
            0
        );
        assert_eq!(clock.owed, Duration::ZERO);
        assert_eq!(
            pacing.steps(SimulationState::StepOnce, second, 0.1, &mut clock),
            1
        );
        let every = SimulationPacing {
            mode: PacingMode::EveryUpdate,
            ..pacing
        };
        assert_eq!(
            every.steps(SimulationState::Playing, Duration::ZERO, 0.1, &mut clock),
            1
        );
    }
}
