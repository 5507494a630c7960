//! An orbit camera for viewports (feature `ui`): drag with the left mouse
//! button to turn around a focus point, scroll to come closer or back off;
//! the panel keeps the mouse while the pointer is over it.
//! [`SinewUiPlugin`](crate::ui::SinewUiPlugin) moves every camera with an
//! [`OrbitCamera`].

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;
use bevy_egui::EguiContexts;

/// A camera that turns around `focus`: put it on a [`Camera3d`] entity;
/// its [`Transform`] is rewritten from these every frame.
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component, Default)]
#[require(Transform)]
pub struct OrbitCamera {
    /// The point looked at. Units: m (world). Default: the origin.
    pub focus: Vec3,
    /// Turn about the vertical, from looking along −Z. Units: rad.
    /// Default: 0.
    pub yaw: f32,
    /// Turn up (negative: looking down), clamped to ±1.5. Units: rad.
    /// Default: 0.
    pub pitch: f32,
    /// Distance from the focus, kept in `[min_distance, max_distance]`.
    /// Units: m. Default: 2.
    pub distance: f32,
    /// Closest approach. Units: m. Default: 0.1.
    pub min_distance: f32,
    /// Farthest distance. Units: m. Default: 20.
    pub max_distance: f32,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        Self {
            focus: Vec3::ZERO,
            yaw: 0.0,
            pitch: 0.0,
            distance: 2.0,
            min_distance: 0.1,
            max_distance: 20.0,
        }
    }
}

impl OrbitCamera {
    /// The camera's transform: `distance` from `focus`, looking at it.
    pub fn transform(&self) -> Transform {
        let rotation = Quat::from_euler(EulerRot::YXZ, self.yaw, self.pitch, 0.0);
        Transform::from_translation(self.focus + rotation * Vec3::Z * self.distance)
            .looking_at(self.focus, Vec3::Y)
    }

    /// Aims at the middle of the box `[lo, hi]` from far enough to see all
    /// of it (Bevy's default 45° field of view, with a margin).
    pub fn frame(&mut self, lo: Vec3, hi: Vec3) {
        self.focus = (lo + hi) * 0.5;
        // A 45° vertical field of view sees 0.83 × the distance.
        self.distance = ((hi - lo).length() * 1.25).clamp(self.min_distance, self.max_distance);
    }
}

/// Turns and zooms the orbit cameras with the mouse.
pub(crate) fn orbit_cameras(
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut egui: EguiContexts,
    mut cameras: Query<(&mut OrbitCamera, &mut Transform)>,
) {
    let panel_has_mouse = egui.ctx_mut().is_ok_and(|c| c.egui_wants_pointer_input());
    for (mut orbit, mut transform) in &mut cameras {
        if !panel_has_mouse {
            if buttons.pressed(MouseButton::Left) {
                orbit.yaw -= motion.delta.x * 0.005;
                orbit.pitch = (orbit.pitch - motion.delta.y * 0.005).clamp(-1.5, 1.5);
            }
            let zoomed = orbit.distance * (1.0 - scroll.delta.y * 0.1);
            orbit.distance = zoomed.clamp(orbit.min_distance, orbit.max_distance);
        }
        transform.set_if_neq(orbit.transform());
    }
}
