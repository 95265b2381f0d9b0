//! Effects panel: what the scene simulates (absent effects are compiled out of the shaders),
//! gravity, air drag, wind and the pins' motion.

use cloth_core::Effect;
use eframe::egui;

use super::{PanelContext, motion, problems_for, quantity, vector};

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
    if ctx.scene.effects.contains(Effect::MovingPins) {
        ui.separator();
        ui.strong("Moving pins (every pin from where it starts)");
        motion(ui, "pin motion", &mut ctx.scene.cloth.pin_motion);
        problems_for(ui, ctx.problems, "cloth.pin_motion");
    }
}
