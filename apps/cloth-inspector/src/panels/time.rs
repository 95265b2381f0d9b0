//! Time panel: frame length, substeps (fixed or auto), play/pause/step, speed.

use cloth_core::{Integrator, Substeps, stability};
use eframe::egui;

use super::{PanelContext, problems_for, quantity};
use crate::commands::Command;

pub fn show(ui: &mut egui::Ui, ctx: &mut PanelContext<'_>, playing: &mut bool, speed: &mut f32) {
    ui.horizontal(|ui| {
        if ui.button(if *playing { "Pause" } else { "Play" }).clicked() {
            *playing = !*playing;
        }
        if ui.add_enabled(!*playing, egui::Button::new("Step")).on_hover_text("Advance one frame").clicked() {
            ctx.commands.push(Command::StepOnce);
        }
        ui.add(egui::Slider::new(speed, 0.25..=4.0).text("× speed").logarithmic(true));
    });
    let time = &mut ctx.scene.time;
    quantity(ui, "frame Δt", &mut time.frame_dt, "s", 0.0005);
    let mut auto = time.substeps == Substeps::Auto;
    let mut n = match time.substeps {
        Substeps::Fixed(n) => n,
        Substeps::Auto => ctx.scene.substeps_per_frame(),
    };
    let time = &mut ctx.scene.time;
    ui.horizontal(|ui| {
        ui.checkbox(&mut auto, "auto substeps");
        ui.add_enabled(!auto, egui::DragValue::new(&mut n).range(0..=10_000).suffix(" substeps/frame"));
    });
    time.substeps = if auto { Substeps::Auto } else { Substeps::Fixed(n) };
    problems_for(ui, ctx.problems, "time");
    ui.horizontal(|ui| {
        ui.label("integrator");
        egui::ComboBox::from_id_salt("integrator").selected_text(format!("{:?}", ctx.scene.integrator)).show_ui(
            ui,
            |ui| {
                for integrator in Integrator::ALL {
                    ui.selectable_value(&mut ctx.scene.integrator, integrator, format!("{integrator:?}"));
                }
            },
        );
    });
    problems_for(ui, ctx.problems, "integrator");
    if ctx.problems.is_empty() {
        let bound = stability::stable_substep(ctx.scene);
        ui.label(format!(
            "substep {:.3e} s, stable bound {:.3e} s ({} per frame)",
            ctx.scene.substep_dt(),
            bound,
            ctx.scene.substeps_per_frame()
        ));
    }
}
