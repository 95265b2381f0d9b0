//! Effects panel: what the scene simulates (absent effects are compiled out of the shaders),
//! gravity, air drag, wind and the pins' motion.

use cloth_core::Effect;
use eframe::egui;

use super::{PanelContext, pin_motion, problems_for, quantity, vector};

pub fn show(ui: &mut egui::Ui, ctx: &mut PanelContext<'_>) {
    ui.label(
        egui::RichText::new("An effect left out costs nothing: its shader code is compiled out (rebuilds).").weak(),
    );
    for effect in Effect::ALL {
        let mut on = ctx.scene.effects.contains(effect);
        if ui.checkbox(&mut on, format!("{effect:?}")).changed() {
            ctx.scene.effects.set(effect, on);
        }
    }
    problems_for(ui, ctx.problems, "effects");
    vector(ui, "gravity g", &mut ctx.scene.gravity, "m/s²", 0.05);
    problems_for(ui, ctx.problems, "gravity");
    quantity(ui, "air drag γ", &mut ctx.scene.air_drag, "1/s", 0.01);
    problems_for(ui, ctx.problems, "air_drag");
    if ctx.scene.effects.contains(Effect::Wind) {
        ui.separator();
        ui.strong("Wind: w(t) = w₀ · (1 + a · sin(2π t / T))");
        let wind = &mut ctx.scene.wind;
        vector(ui, "mean velocity w₀", &mut wind.velocity, "m/s", 0.05);
        quantity(ui, "gust amplitude a", &mut wind.gust_amplitude, "", 0.01);
        quantity(ui, "gust period T", &mut wind.gust_period, "s", 0.01);
        quantity(ui, "coefficient", &mut wind.coefficient, "N·s/m³", 0.01);
        problems_for(ui, ctx.problems, "wind");
    }
    if ctx.scene.effects.contains(Effect::SelfCollision) {
        ui.separator();
        ui.strong("Self-collision: vertices closer than r push apart (F = k_s (r − d) + damping, friction μ)");
        let spacing = spacing_of(&ctx.scene.cloth);
        let s = &mut ctx.scene.self_collision;
        grid_length(ui, "thickness r", &mut s.thickness, spacing, "Vertices closer than this repel (live)");
        quantity(ui, "stiffness k_s", &mut s.stiffness, "N/m", 1.0);
        quantity(ui, "damping c_s", &mut s.damping, "N·s/m", 0.001);
        quantity(ui, "friction μ", &mut s.friction, "", 0.01);
        quantity(ui, "speed limit s_max", &mut s.max_speed, "m/s", 0.05);
        grid_length(
            ui,
            "margin W",
            &mut s.margin,
            spacing,
            "How far vertices may move against each other before the GPU's candidate lists are rebuilt (live)",
        );
        let q = cloth_core::self_collision::SelfCollisionQuantities::of(ctx.scene);
        ui.label(format!(
            "GPU: candidate lists checked every {} substep{} (a change of the interval rebuilds)",
            q.check_interval,
            if q.check_interval == 1 { "" } else { "s" }
        ))
        .on_hover_text(
            "The longest interval (at most 8) whose lookahead, 2 s_max Δt (C − 1 + σ), takes at most half the margin \
             (σ = 0 for semi-implicit Euler, 1 for the other integrators)",
        );
        if q.every_check_rebuilds() {
            ui.colored_label(
                egui::Color32::from_rgb(220, 150, 40),
                format!(
                    "every check rebuilds the lists (the lookahead, {:.2} mm, reaches the margin): \
                     a wider margin or a lower speed limit leaves room",
                    q.lookahead * 1e3
                ),
            );
        }
        problems_for(ui, ctx.problems, "self_collision");
    }
    if ctx.scene.effects.contains(Effect::MovingPins) {
        ui.separator();
        ui.strong("Moving pins (each group's pins from where they start)");
        pin_motion(ui, "pin motion (cloth.pins)", &mut ctx.scene.cloth.pin_motion);
        problems_for(ui, ctx.problems, "cloth.pin_motion");
        for (k, group) in ctx.scene.cloth.pin_groups.iter_mut().enumerate() {
            pin_motion(ui, &format!("pin group {k}"), &mut group.motion);
        }
        problems_for(ui, ctx.problems, "cloth.pin_groups");
    }
}

/// The larger grid spacing of `cloth`, m: what `Thickness::Spacings` multiplies.
fn spacing_of(cloth: &cloth_core::scene::ClothSpec) -> f64 {
    let [du, dv] = cloth.spacing();
    du.max(dv)
}

/// A length that scales with the grid or is fixed (`Thickness`), edited in grid spacings or in m;
/// switching the unit keeps the length in metres. `spacing`: the grid's larger spacing, m.
fn grid_length(
    ui: &mut egui::Ui,
    label: &str,
    length: &mut cloth_core::self_collision::Thickness,
    spacing: f64,
    hover: &str,
) {
    use cloth_core::self_collision::Thickness;
    ui.horizontal(|ui| {
        ui.label(label);
        let (mut value, spacings) = match *length {
            Thickness::Spacings(f) => (f, true),
            Thickness::Meters(m) => (m, false),
        };
        let unit = if spacings { " grid spacings" } else { " m" };
        let drag = egui::DragValue::new(&mut value).speed(0.01).suffix(unit).max_decimals(4);
        let mut changed = ui.add(drag).on_hover_text(hover).changed();
        let mut in_spacings = spacings;
        changed |=
            ui.checkbox(&mut in_spacings, "in spacings").on_hover_text("Keeps its meaning at any grid").changed();
        if changed {
            *length = match (in_spacings, spacings) {
                (true, true) => Thickness::Spacings(value),
                (false, false) => Thickness::Meters(value),
                (true, false) => Thickness::Spacings(value / spacing),
                (false, true) => Thickness::Meters(value * spacing),
            };
        }
    });
}
