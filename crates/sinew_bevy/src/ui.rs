//! The tuning panel (feature `ui`): [`SinewUiPlugin`].
//!
//! One egui window with the play controls, the global solver settings, a
//! live per-block timing chart, the debug-view toggles and every muscle's
//! parameters. Every edit lands in a component or resource and takes effect
//! on the next frame without a rebuild.

use crate::ResetSimulation;
use crate::capture::SinewScreenshotPlugin;
use crate::components::{FiberMode, Muscle, MuscleState};
use crate::save::SaveScene;
use crate::scene::SinewSceneRoot;
use crate::settings::{Method, SimulationState, SinewClock, SinewSettings, SinewTimings};
use bevy::prelude::*;
pub use bevy_egui;
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};
use sinew_core::SweepSchedule;

/// Adds the egui panel (and `EguiPlugin` if the app has none),
/// [`SinewScreenshotPlugin`] (screenshots on request) and the mouse
/// controls of [`OrbitCamera`](crate::orbit::OrbitCamera)s.
#[derive(Clone, Debug, Default)]
pub struct SinewUiPlugin;

impl Plugin for SinewUiPlugin {
    fn build(&self, app: &mut App) {
        if !app.is_plugin_added::<EguiPlugin>() {
            app.add_plugins(EguiPlugin::default());
        }
        if !app.is_plugin_added::<SinewScreenshotPlugin>() {
            app.add_plugins(SinewScreenshotPlugin);
        }
        app.register_type::<crate::orbit::OrbitCamera>()
            .add_systems(EguiPrimaryContextPass, panel)
            .add_systems(Update, crate::orbit::orbit_cameras);
    }
}

/// Colours of the timing chart's blocks.
const BLOCK_COLORS: [egui::Color32; 7] = [
    egui::Color32::from_rgb(120, 120, 120),
    egui::Color32::from_rgb(90, 160, 220),
    egui::Color32::from_rgb(110, 200, 120),
    egui::Color32::from_rgb(230, 170, 60),
    egui::Color32::from_rgb(220, 90, 80),
    egui::Color32::from_rgb(170, 110, 210),
    egui::Color32::from_rgb(200, 200, 90),
];

#[allow(clippy::too_many_arguments)]
fn panel(
    mut contexts: EguiContexts,
    mut settings: ResMut<SinewSettings>,
    mut state: ResMut<SimulationState>,
    clock: Res<SinewClock>,
    timings: Res<SinewTimings>,
    (mut reset, mut save): (MessageWriter<ResetSimulation>, MessageWriter<SaveScene>),
    scenes: Query<(Entity, &SinewSceneRoot)>,
    mut muscles: Query<(Entity, &mut Muscle, Option<&MuscleState>)>,
    log: Res<crate::events::SinewLog>,
    mut layers_view: Option<ResMut<crate::view::SinewView>>,
    #[cfg(feature = "debug")] mut view: Option<ResMut<crate::debug::SinewDebugView>>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    egui::Window::new("sinew")
        .default_width(330.0)
        .default_height(690.0)
        .default_pos([10.0, 10.0])
        .vscroll(true)
        .show(ctx, |ui| {
            controls(ui, &mut state, &clock, &timings, &mut reset);
            // Scenes loaded from files are saved back to them, tuned.
            let files: Vec<Entity> = scenes
                .iter()
                .filter(|(_, s)| matches!(s, SinewSceneRoot::Asset(_)))
                .map(|(e, _)| e)
                .collect();
            if !files.is_empty()
                && ui
                    .button("💾 Save tuned scene")
                    .on_hover_text(
                        "muscle parameters and solver settings, back to the scene's RON file",
                    )
                    .clicked()
            {
                for root in files {
                    save.write(SaveScene { root, path: None });
                }
            }
            if let Some(layers_view) = layers_view.as_mut() {
                egui::CollapsingHeader::new("View")
                    .default_open(true)
                    .show(ui, |ui| view_toggles(ui, layers_view));
            }
            let is_layer =
                |s: Option<&MuscleState>| s.is_some_and(|s| s.muscle.params.is_surface_layer());
            let mut layers: Vec<_> = muscles.iter_mut().filter(|(.., s)| is_layer(*s)).collect();
            if !layers.is_empty() {
                layers.sort_by_key(|(e, ..)| *e);
                egui::CollapsingHeader::new("Skin")
                    .default_open(true)
                    .show(ui, |ui| {
                        for (_, mut layer, state) in layers {
                            if let Some(state) = state {
                                ui.label(&state.muscle.name);
                            }
                            skin_panel(ui, &mut layer);
                        }
                    });
            }
            ui.separator();
            egui::CollapsingHeader::new("Solver")
                .default_open(true)
                .show(ui, |ui| solver(ui, &mut settings));
            egui::CollapsingHeader::new("Timings")
                .default_open(true)
                .show(ui, |ui| chart(ui, &timings));
            #[cfg(feature = "debug")]
            if let Some(view) = view.as_deref_mut() {
                egui::CollapsingHeader::new("Debug view")
                    .default_open(false)
                    .show(ui, |ui| debug_toggles(ui, view));
            }
            let count = muscles.iter().filter(|(.., s)| !is_layer(*s)).count();
            egui::CollapsingHeader::new(format!("Muscles ({count})"))
                .default_open(true)
                .show(ui, |ui| {
                    let mut list: Vec<_> =
                        muscles.iter_mut().filter(|(.., s)| !is_layer(*s)).collect();
                    list.sort_by_key(|(e, ..)| *e);
                    for (entity, mut muscle, built) in list {
                        let name = built.map_or_else(
                            || format!("{entity} (building)"),
                            |s| s.muscle.name.clone(),
                        );
                        egui::CollapsingHeader::new(name)
                            .id_salt(entity)
                            .show(ui, |ui| muscle_panel(ui, &mut muscle));
                    }
                });
            egui::CollapsingHeader::new(format!("Messages ({})", log.lines.len()))
                .default_open(false)
                .show(ui, |ui| {
                    // Newest first: builds, failed builds, rejected settings.
                    for line in log.lines.iter().rev().take(12) {
                        ui.label(line);
                    }
                });
        });
    Ok(())
}

fn controls(
    ui: &mut egui::Ui,
    state: &mut SimulationState,
    clock: &SinewClock,
    timings: &SinewTimings,
    reset: &mut MessageWriter<ResetSimulation>,
) {
    ui.horizontal(|ui| {
        let playing = *state == SimulationState::Playing;
        if ui
            .button(if playing { "⏸ Pause" } else { "▶ Play" })
            .clicked()
        {
            *state = if playing {
                SimulationState::Paused
            } else {
                SimulationState::Playing
            };
        }
        if ui.button("⏭ Step").clicked() {
            *state = SimulationState::StepOnce;
        }
        if ui.button("⟲ Reset").clicked() {
            reset.write(ResetSimulation);
        }
    });
    let ms = timings.total.as_secs_f64() * 1e3;
    let median = timings.median_total_ms().unwrap_or(0.0);
    let fps = if median > 0.0 { 1e3 / median } else { 0.0 };
    ui.label(format!(
        "frame {}   t = {:.3} s   solver {:.2} ms, median {:.2} ms ({:.0} fps)",
        clock.frame, clock.time, ms, median, fps
    ));
}

fn solver(ui: &mut egui::Ui, s: &mut SinewSettings) {
    egui::ComboBox::from_label("method")
        .selected_text(s.method.label())
        .show_ui(ui, |ui| {
            for m in Method::ALL {
                let selected = std::mem::discriminant(&s.method) == std::mem::discriminant(&m);
                if ui.selectable_label(selected, m.label()).clicked() && !selected {
                    s.method = m;
                }
            }
        });
    if let Method::Jacobi { omega } | Method::Hybrid { omega, .. } = &mut s.method {
        ui.add(egui::Slider::new(omega, 1.0..=2.0).text("ω (over-relaxation)"));
    }
    if let Method::Hybrid { min_group, .. } = &mut s.method {
        ui.add(egui::Slider::new(min_group, 1..=512).text("smallest Gauss–Seidel group"));
    }
    ui.add(egui::Slider::new(&mut s.iterations, 1..=50).text("iterations"));
    ui.add(egui::Slider::new(&mut s.substeps, 1..=16).text("substeps"));
    let most = s.iterations.max(1);
    ui.add(
        egui::Slider::new(&mut s.snapshot_interval, 1..=most).text("snapshots every (iterations)"),
    );
    ui.add(
        egui::Slider::new(&mut s.bone_contact_interval, 1..=most)
            .text("bone contacts every (iterations)"),
    );
    ui.add(egui::Slider::new(&mut s.walk_interval, 1..=most).text("walks every (iterations)"));
    ui.checkbox(
        &mut s.feature_contacts,
        "project onto the walk's feature between walks",
    );
    ui.add(egui::Slider::new(&mut s.time_scale, 0.05..=2.0).text("time scale"));
    ui.horizontal(|ui| {
        ui.label("gravity m/s²");
        ui.add(
            egui::DragValue::new(&mut s.gravity.x)
                .speed(0.1)
                .prefix("x "),
        );
        ui.add(
            egui::DragValue::new(&mut s.gravity.y)
                .speed(0.1)
                .prefix("y "),
        );
        ui.add(
            egui::DragValue::new(&mut s.gravity.z)
                .speed(0.1)
                .prefix("z "),
        );
    });
    ui.add(egui::Slider::new(&mut s.threads, 0..=16).text("threads (0 = all)"));
    let label = |schedule| match schedule {
        SweepSchedule::Auto => "auto",
        SweepSchedule::ByMuscle => "by muscle",
        SweepSchedule::ByColor => "by colour",
    };
    egui::ComboBox::from_label("colour sweeps")
        .selected_text(label(s.schedule))
        .show_ui(ui, |ui| {
            for schedule in [
                SweepSchedule::Auto,
                SweepSchedule::ByMuscle,
                SweepSchedule::ByColor,
            ] {
                ui.selectable_value(&mut s.schedule, schedule, label(schedule));
            }
        });
}

fn chart(ui: &mut egui::Ui, timings: &SinewTimings) {
    for (i, (name, d)) in timings.blocks().enumerate() {
        ui.horizontal(|ui| {
            ui.colored_label(BLOCK_COLORS[i], "■");
            ui.label(format!("{name:<15} {:7.3} ms", d.as_secs_f64() * 1e3));
        });
    }
    if let Some((layers, share)) = timings.layers() {
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        ui.label(format!(
            "skin's own task {:7.3} ms, {:.0} % of closest data + project",
            ms(layers.total()),
            100.0 * share
        ))
        .on_hover_text(format!(
            "closest data {:.3} ms, sweep {:.3} ms, bone contacts {:.3} ms: near 100 %, the skin is what the frame waits for",
            ms(layers.closest_data),
            ms(layers.sweep),
            ms(layers.finish)
        ));
    }
    let (rect, _) =
        ui.allocate_exact_size(egui::vec2(ui.available_width(), 90.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(24));
    let history = &timings.history;
    // Scale to the 95th percentile: a scene's first frame (links, colour
    // groups) would flatten everything else.
    let totals = timings.sorted_totals_ms();
    let peak = totals
        .get(totals.len() * 95 / 100)
        .map_or(0.1, |p| (p * 1.2).max(0.1));
    let n = SinewTimings::HISTORY.max(2) as f32;
    let x = |i: usize| rect.left() + rect.width() * i as f32 / (n - 1.0);
    let y = |ms: f32| rect.bottom() - rect.height() * (ms / peak).min(1.0);
    // Cumulative lines: block k is drawn at the sum of blocks 0..=k.
    for k in 0..7 {
        let points: Vec<egui::Pos2> = history
            .iter()
            .enumerate()
            .map(|(i, b)| egui::pos2(x(i), y(b[..=k].iter().sum())))
            .collect();
        if points.len() > 1 {
            painter.add(egui::Shape::line(
                points,
                egui::Stroke::new(1.5, BLOCK_COLORS[k]),
            ));
        }
    }
    painter.text(
        rect.left_top() + egui::vec2(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        format!("{peak:.2} ms"),
        egui::FontId::monospace(10.0),
        egui::Color32::LIGHT_GRAY,
    );
}

/// Which layers are drawn; see-through skin.
fn view_toggles(ui: &mut egui::Ui, view: &mut ResMut<crate::view::SinewView>) {
    // Edit a copy so an untouched panel does not mark the view changed.
    let mut edit = (**view).clone();
    ui.horizontal(|ui| {
        if edit.skin_layers > 0 {
            ui.checkbox(&mut edit.skin, "skin");
        }
        if edit.skinned > 0 {
            ui.checkbox(&mut edit.character_skin, "skinning only")
                .on_hover_text(
                    "the character's skin as its skeleton deforms it, without the simulation",
                );
        }
        ui.checkbox(&mut edit.muscles, "muscles");
        ui.checkbox(&mut edit.bones, "bones");
    });
    if edit.has_skin() {
        ui.horizontal(|ui| {
            ui.checkbox(&mut edit.xray, "x-ray");
            ui.add_enabled(
                edit.xray,
                egui::Slider::new(&mut edit.opacity, 0.0..=1.0).text("skin opacity"),
            );
        });
    }
    if edit != **view {
        **view = edit;
    }
}

/// A simulated skin's parameters: how closely it follows the skeleton,
/// how much it stretches and shears, how it slides on what is under it.
fn skin_panel(ui: &mut egui::Ui, m: &mut Mut<Muscle>) {
    let mut edit = (**m).clone();
    let c = &mut edit.compliance;
    // (label, compliance, smallest value the slider reaches, hint). Area's
    // compliance is m³/N: its default, 1e-7, sits below the others' range.
    for (name, value, smallest, hint) in [
        (
            "follow skeleton (bind)",
            &mut c.bind,
            1e-6,
            "compliance of the pull towards the skinned position: larger lets muscles move the skin more",
        ),
        (
            "stretch",
            &mut c.fiber,
            1e-6,
            "compliance of the skin's edges: larger stretches more",
        ),
        (
            "area m³/N",
            &mut c.area,
            1e-10,
            "compliance of each triangle's area: larger lets the skin gather into folds",
        ),
        (
            "slide",
            &mut c.sliding,
            1e-6,
            "compliance of the contact with the muscles and bones below",
        ),
    ] {
        let slider = egui::Slider::new(value, 0.0..=1.0)
            .logarithmic(true)
            .smallest_positive(smallest)
            .text(name);
        let slider = if smallest < 1e-6 {
            slider.custom_formatter(|v, _| format!("{v:.1e}"))
        } else {
            slider
        };
        ui.add(slider).on_hover_text(hint);
    }
    ui.add(egui::Slider::new(&mut edit.damping, 0.0..=40.0).text("damping 1/s"));
    let mut n = edit.iterations.unwrap_or(10);
    if ui
        .add(egui::Slider::new(&mut n, 1..=20).text("iterations"))
        .on_hover_text("the skin's own iteration count (the muscles keep theirs)")
        .changed()
    {
        edit.iterations = Some(n);
    }
    if edit != **m {
        **m = edit;
    }
}

#[cfg(feature = "debug")]
fn debug_toggles(ui: &mut egui::Ui, v: &mut crate::debug::SinewDebugView) {
    ui.checkbox(&mut v.fibers, "fibres (by activation)");
    ui.checkbox(&mut v.internal, "internal structure");
    ui.checkbox(&mut v.attachments, "attachments");
    ui.checkbox(&mut v.sliding, "sliding links");
    ui.checkbox(&mut v.soft, "soft links");
    ui.checkbox(&mut v.hard, "hard links");
    ui.checkbox(&mut v.colors, "colour groups");
}

fn muscle_panel(ui: &mut egui::Ui, m: &mut Mut<Muscle>) {
    // Edit a copy so an untouched panel does not mark the component changed.
    let mut edit = (**m).clone();
    ui.checkbox(&mut edit.driven, "driven by sensors / curve");
    ui.add_enabled(
        !edit.driven,
        egui::Slider::new(&mut edit.activation, 0.0..=1.0).text("activation"),
    );
    ui.add(egui::Slider::new(&mut edit.volume_gain, 0.5..=2.0).text("volume gain G"));
    ui.add(
        egui::Slider::new(&mut edit.activation_volume_gain, 0.5..=2.0)
            .text("overpressure R (gain at a = 1)"),
    );
    ui.add(egui::Slider::new(&mut edit.damping, 0.0..=20.0).text("damping 1/s"));
    ui.add(egui::Slider::new(&mut edit.max_contraction, 0.0..=0.9).text("max contraction"));
    ui.add(egui::Slider::new(&mut edit.rest_activation, 0.0..=0.95).text("rest activation"));
    ui.add(egui::Slider::new(&mut edit.hold_release, 0.01..=1.0).text("hold at full activation"))
        .on_hover_text(
            "a muscle that holds its shape on its bones: what is left of the hold when fully active",
        );
    ui.add(egui::Slider::new(&mut edit.hold_bend, 0.0..=4.0).text("held line bend"))
        .on_hover_text(
            "a muscle held along its line: how far the line leaves each end along its bone (chord lengths; 0 straight)",
        );
    ui.add(egui::Slider::new(&mut edit.tendon_pivot, 0.0..=1.0).text("tendon pivot"))
        .on_hover_text(
            "a muscle held along its line: how far its end rings turn about the tendon's tip towards the line",
        );
    ui.checkbox(
        &mut edit.rest_follows_hold,
        "rest lengths follow the held shape",
    )
    .on_hover_text(
        "a muscle held along its line: its edges and internal links take the held shape's lengths",
    );
    ui.label("connection weights (per vertex maps override)");
    let w = &mut edit.weights;
    for (name, value) in [
        ("sliding", &mut w.sliding),
        ("soft", &mut w.soft),
        ("hard", &mut w.hard),
    ] {
        ui.add(egui::Slider::new(value, 0.0..=1.0).text(name));
    }
    ui.checkbox(&mut w.normalize, "normalise per vertex");
    let mut own = edit.iterations.is_some();
    ui.horizontal(|ui| {
        ui.checkbox(&mut own, "own iterations");
        let mut n = edit.iterations.unwrap_or(10);
        ui.add_enabled(own, egui::Slider::new(&mut n, 1..=50));
        edit.iterations = own.then_some(n);
    });
    egui::ComboBox::from_id_salt(("fiber mode", ui.id()))
        .selected_text(format!("{:?}", edit.fiber_mode))
        .show_ui(ui, |ui| {
            ui.selectable_value(
                &mut edit.fiber_mode,
                FiberMode::RotationInvariant,
                "RotationInvariant",
            );
            ui.selectable_value(&mut edit.fiber_mode, FiberMode::PaperExact, "PaperExact");
        });
    ui.label("compliance α = 1/stiffness (0 = rigid)");
    let c = &mut edit.compliance;
    for (name, value) in [
        ("fiber", &mut c.fiber),
        ("internal", &mut c.internal),
        ("branch", &mut c.branch),
        ("volume", &mut c.volume),
        ("attach", &mut c.attach),
        ("branch attach", &mut c.branch_attach),
        ("sliding", &mut c.sliding),
        ("soft", &mut c.soft),
        ("hard", &mut c.hard),
    ] {
        ui.add(
            egui::Slider::new(value, 0.0..=1e-1)
                .logarithmic(true)
                .smallest_positive(1e-9)
                .text(name),
        );
    }
    if edit != **m {
        **m = edit;
    }
}
