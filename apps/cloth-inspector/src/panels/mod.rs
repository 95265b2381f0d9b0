//! The inspector's panels, one module each. A panel edits the scene draft and queues commands;
//! it never touches the simulator directly.

pub mod backend;
pub mod cloth;
pub mod contact;
pub mod effect_costs;
pub mod effects;
pub mod export;
pub mod profile;
pub mod scene;
pub mod springs;
pub mod stats;
pub mod study;
pub mod time;
pub mod tuning;

use cloth_core::{Problem, Scene};
use eframe::egui;

use crate::commands::Command;

/// What a panel may read and change.
pub struct PanelContext<'a> {
    /// The scene being edited.
    pub scene: &'a mut Scene,
    /// Validation problems of the edited scene (shown next to their fields; not applied).
    pub problems: &'a [Problem],
    /// Commands to apply after the frame.
    pub commands: &'a mut Vec<Command>,
}

/// A number with its unit; returns whether it changed.
pub fn quantity(ui: &mut egui::Ui, label: &str, value: &mut f64, unit: &str, speed: f64) -> bool {
    ui.horizontal(|ui| {
        ui.label(label);
        ui.add(egui::DragValue::new(value).speed(speed).suffix(format!(" {unit}")).max_decimals(6))
            .on_hover_text(format!("{label}, in {unit}"))
            .changed()
    })
    .inner
}

/// A prescribed motion `d(t) = velocity · t + amplitude · sin(2π f t)`: its three fields.
pub fn motion(ui: &mut egui::Ui, label: &str, value: &mut cloth_core::scene::Motion) -> bool {
    ui.label(egui::RichText::new(format!("{label}: d(t) = v·t + A·sin(2π f t)")).weak());
    let mut changed = vector(ui, "  velocity v", &mut value.velocity, "m/s", 0.01);
    changed |= vector(ui, "  amplitude A", &mut value.amplitude, "m", 0.005);
    changed | quantity(ui, "  frequency f", &mut value.frequency, "Hz", 0.01)
}

/// A pins' motion: the translation of [`motion`], and a rotation about a pivot it carries.
pub fn pin_motion(ui: &mut egui::Ui, label: &str, value: &mut cloth_core::scene::Motion) -> bool {
    let mut changed = motion(ui, label, value);
    ui.label(egui::RichText::new("  turning: x(t) = p(t) + R(ω t)(x₀ − pivot), p(t) = pivot + d(t)").weak());
    changed |= vector(ui, "  angular velocity ω", &mut value.angular_velocity, "rad/s", 0.01);
    changed | vector(ui, "  pivot", &mut value.pivot, "m", 0.01)
}

/// A 3-vector with its unit.
pub fn vector(ui: &mut egui::Ui, label: &str, value: &mut [f64; 3], unit: &str, speed: f64) -> bool {
    ui.horizontal(|ui| {
        ui.label(label);
        let mut changed = false;
        for (axis, v) in ["x", "y", "z"].iter().zip(value.iter_mut()) {
            changed |=
                ui.add(egui::DragValue::new(v).speed(speed).prefix(format!("{axis} ")).max_decimals(4)).changed();
        }
        ui.label(unit);
        changed
    })
    .inner
}

/// Shows, in red, the validation problems whose field path starts with `prefix`.
pub fn problems_for(ui: &mut egui::Ui, problems: &[Problem], prefix: &str) {
    for p in problems.iter().filter(|p| p.field.starts_with(prefix)) {
        ui.colored_label(egui::Color32::from_rgb(220, 50, 50), format!("⚠ {}: {} — {}", p.field, p.message, p.fix));
    }
}
