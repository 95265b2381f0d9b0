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
        let s = &mut ctx.scene.self_collision;
        ui.horizontal(|ui| {
            use cloth_core::self_collision::Thickness;
            ui.label("thickness r");
            let (mut value, spacings) = match s.thickness {
                Thickness::Spacings(f) => (f, true),
                Thickness::Meters(m) => (m, false),
            };
            let unit = if spacings { " grid spacings" } else { " m" };
            let drag = egui::DragValue::new(&mut value).speed(0.01).suffix(unit).max_decimals(4);
            let mut changed = ui.add(drag).on_hover_text("Vertices closer than this repel (live)").changed();
            let mut in_spacings = spacings;
            changed |=
                ui.checkbox(&mut in_spacings, "in spacings").on_hover_text("Keeps its meaning at any grid").changed();
            if changed {
                s.thickness = match (in_spacings, spacings) {
                    (true, true) | (false, false) => {
                        if in_spacings {
                            Thickness::Spacings(value)
                        } else {
                            Thickness::Meters(value)
                        }
                    }
                    // Switching the unit keeps the thickness in metres.
                    (true, false) => Thickness::Spacings(value / spacing_of(&ctx.scene.cloth)),
                    (false, true) => Thickness::Meters(value * spacing_of(&ctx.scene.cloth)),
                };
            }
        });
        let s = &mut ctx.scene.self_collision;
        quantity(ui, "stiffness k_s", &mut s.stiffness, "N/m", 1.0);
        quantity(ui, "damping c_s", &mut s.damping, "N·s/m", 0.001);
        quantity(ui, "friction μ", &mut s.friction, "", 0.01);
        quantity(ui, "speed limit s_max", &mut s.max_speed, "m/s", 0.05);
        let mut interval = s.rebuild_interval as f64;
        if quantity(ui, "hash rebuilt every", &mut interval, "substeps (rebuilds)", 0.1) {
            s.rebuild_interval = interval.round().clamp(0.0, u32::MAX as f64) as u32;
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
