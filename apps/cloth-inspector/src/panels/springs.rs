//! Springs panel: each kind on/off with its stiffness and damping.

use cloth_core::{Effect, SpringKind};
use eframe::egui;

use super::{PanelContext, problems_for, quantity};

pub fn show(ui: &mut egui::Ui, ctx: &mut PanelContext<'_>) {
    for kind in SpringKind::ALL {
        let mut on = ctx.scene.effects.contains(kind.effect());
        if ui.checkbox(&mut on, format!("{} springs (on/off rebuilds)", kind.name())).changed() {
            ctx.scene.effects.set(kind.effect(), on);
        }
        let spec = match kind {
            SpringKind::Structural => &mut ctx.scene.springs.structural,
            SpringKind::Shear => &mut ctx.scene.springs.shear,
            SpringKind::Bend => &mut ctx.scene.springs.bend,
        };
        ui.indent(kind.name(), |ui| {
            quantity(ui, "stiffness k", &mut spec.stiffness, "N/m", 1.0);
            quantity(ui, "damping c_d", &mut spec.damping, "N·s/m", 0.001);
        });
        problems_for(ui, ctx.problems, &format!("springs.{}", kind.name()));
    }
    let mut damping = ctx.scene.effects.contains(Effect::SpringDamping);
    if ui.checkbox(&mut damping, "spring damping").changed() {
        ctx.scene.effects.set(Effect::SpringDamping, damping);
    }
    if ui.small_button("Stiffness ×10").on_hover_text("Multiply every stiffness by 10").clicked() {
        ctx.scene.springs.structural.stiffness *= 10.0;
        ctx.scene.springs.shear.stiffness *= 10.0;
        ctx.scene.springs.bend.stiffness *= 10.0;
    }
}
