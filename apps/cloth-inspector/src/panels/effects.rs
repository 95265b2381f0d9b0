//! Effects panel: what the scene simulates (absent effects are compiled out of the shaders).

use cloth_core::Effect;
use eframe::egui;

use super::{PanelContext, problems_for, quantity, vector};

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
}
