//! Contact panel: spheres (centre, radius, k_c, c_f, damping, motion), contact and friction on/off.

use cloth_core::Effect;
use cloth_core::scene::SphereSpec;
use eframe::egui;

use super::{PanelContext, motion, problems_for, quantity, vector};

pub fn show(ui: &mut egui::Ui, ctx: &mut PanelContext<'_>) {
    for (effect, label) in [(Effect::SphereContact, "sphere contact"), (Effect::Friction, "friction")] {
        let mut on = ctx.scene.effects.contains(effect);
        if ui.checkbox(&mut on, format!("{label} (on/off rebuilds)")).changed() {
            ctx.scene.effects.set(effect, on);
        }
    }
    problems_for(ui, ctx.problems, "effects");
    let moving = ctx.scene.effects.contains(Effect::MovingSpheres);
    let mut remove = None;
    for (k, sphere) in ctx.scene.spheres.iter_mut().enumerate() {
        ui.separator();
        ui.horizontal(|ui| {
            ui.strong(format!("Sphere {k}"));
            if ui.small_button("remove").clicked() {
                remove = Some(k);
            }
        });
        vector(ui, "centre", &mut sphere.center, "m", 0.01);
        quantity(ui, "radius", &mut sphere.radius, "m", 0.005);
        quantity(ui, "contact stiffness k_c", &mut sphere.stiffness, "N/m", 10.0);
        quantity(ui, "friction c_f", &mut sphere.friction, "", 0.01);
        quantity(ui, "contact damping", &mut sphere.damping, "N·s/m", 0.01);
        if moving {
            motion(ui, "motion from the centre", &mut sphere.motion);
        }
        problems_for(ui, ctx.problems, &format!("spheres[{k}]"));
    }
    if let Some(k) = remove {
        ctx.scene.spheres.remove(k);
    }
    if ui.button("Add a sphere (rebuilds)").clicked() {
        ctx.scene.spheres.push(SphereSpec::default());
    }
    ui.label(egui::RichText::new("Shift-drag in the view moves sphere 0.").weak());
    if !moving {
        ui.label(egui::RichText::new("Turn on MovingSpheres (Effects) to animate a sphere.").weak());
    }
}
