//! Screenshots on request (feature `render`): with the environment variable
//! `SINEW_SCREENSHOT=out.png` set, an app with [`SinewUiPlugin`](crate::ui)
//! (or [`SinewScreenshotPlugin`]) saves its primary window once the
//! simulation has run `SINEW_SCREENSHOT_FRAME` steps (default 90) with
//! every scene spawned and every muscle built, and exits ten frames later
//! — how CI and the README's pictures capture the examples under Xvfb.
//! Without the variable it does nothing. The panel's solver readout (the
//! last step and the median over [`SinewTimings::history`], and the thread
//! setting) goes to the log as the screenshot is taken, for scripts that
//! compare runs.

use crate::components::{Muscle, MuscleState};
use crate::scene::SpawnedScene;
use crate::settings::{SinewClock, SinewSettings, SinewTimings};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};

/// Saves a screenshot and exits when `SINEW_SCREENSHOT` asks for one.
#[derive(Clone, Debug, Default)]
pub struct SinewScreenshotPlugin;

impl Plugin for SinewScreenshotPlugin {
    fn build(&self, app: &mut App) {
        if let Ok(path) = std::env::var("SINEW_SCREENSHOT") {
            let at = std::env::var("SINEW_SCREENSHOT_FRAME")
                .ok()
                .and_then(|f| f.parse().ok())
                .unwrap_or(90);
            app.insert_resource(ScreenshotRequest { path, at })
                .add_systems(Last, take_screenshot);
        }
    }
}

/// Where to save, and at which simulation frame.
#[derive(Resource)]
struct ScreenshotRequest {
    path: String,
    at: u64,
}

/// Muscles still building.
type Building = (With<Muscle>, Without<MuscleState>);

#[allow(clippy::too_many_arguments)]
fn take_screenshot(
    mut commands: Commands,
    request: Res<ScreenshotRequest>,
    clock: Res<SinewClock>,
    scenes: Query<&SpawnedScene>,
    building: Query<(), Building>,
    mut frames: Local<u32>,
    mut ready_at: Local<Option<u64>>,
    mut taken: Local<Option<u32>>,
    mut exit: MessageWriter<AppExit>,
    timings: Option<Res<SinewTimings>>,
    settings: Option<Res<SinewSettings>>,
) {
    *frames += 1;
    if ready_at.is_none() && building.is_empty() && scenes.iter().all(|s| s.done) {
        *ready_at = Some(clock.frame);
    }
    let Some(ready_at) = *ready_at else {
        return;
    };
    match *taken {
        None if clock.frame >= ready_at + request.at => {
            commands
                .spawn(Screenshot::primary_window())
                .observe(save_to_disk(request.path.clone()));
            // The panel's solver readout, in the log as well as the picture.
            if let (Some(t), Some(s)) = (timings, settings) {
                info!(
                    "screenshot at frame {}: solver {:.3} ms, median {:.3} ms over the last {} steps, threads {}",
                    clock.frame,
                    t.total.as_secs_f64() * 1e3,
                    t.median_total_ms().unwrap_or(0.0),
                    t.history.len(),
                    s.threads
                );
            }
            *taken = Some(*frames);
        }
        Some(t) if *frames > t + 10 => {
            exit.write(AppExit::Success);
        }
        _ => {}
    }
}
