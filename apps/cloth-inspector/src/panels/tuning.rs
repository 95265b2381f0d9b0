//! GPU tuning panel: how the GPU backends lay their work out (`cloth_gpu::GpuTuning`). A tuning
//! is fixed for the life of a simulator, so "Apply" hands the running cloth to a new one with the
//! edited tuning, as a backend switch does; nothing but the speed changes.

use cloth_gpu::{BlockOrder, CandidateListing, GpuTuning, Tiling};
use eframe::egui;

use crate::commands::Command;

/// Shows `draft` for editing; "Apply" queues it when it differs from `running`.
pub fn show(ui: &mut egui::Ui, draft: &mut GpuTuning, running: &GpuTuning, commands: &mut Vec<Command>) {
    let sizes = [32u32, 64, 128, 256, 512, 1024];
    egui::ComboBox::from_label("workgroup size").selected_text(draft.workgroup_size.to_string()).show_ui(ui, |ui| {
        for n in sizes {
            ui.selectable_value(&mut draft.workgroup_size, n, n.to_string());
        }
    });
    egui::ComboBox::from_label("block width").selected_text(draft.block_width.to_string()).show_ui(ui, |ui| {
        ui.selectable_value(&mut draft.block_width, 0, "0 (rows)");
        for n in [1u32, 2, 4, 8, 16, 32, 64, 128, 256].into_iter().filter(|n| *n <= draft.workgroup_size) {
            ui.selectable_value(&mut draft.block_width, n, n.to_string());
        }
    });
    ui.horizontal(|ui| {
        ui.label("tiled Euler kernel");
        for (value, label) in [(Tiling::Auto, "auto"), (Tiling::On, "on"), (Tiling::Off, "off")] {
            ui.selectable_value(&mut draft.tiling, value, label);
        }
    });
    ui.checkbox(&mut draft.packed_state, "packed 24-byte state (Euler)");
    ui.horizontal(|ui| {
        ui.label("block order");
        for (value, label) in
            [(BlockOrder::Auto, "auto"), (BlockOrder::Forward, "forward"), (BlockOrder::Alternating, "alternating")]
        {
            ui.selectable_value(&mut draft.block_order, value, label);
        }
    });
    ui.horizontal(|ui| {
        ui.label("self-collision candidates");
        for (value, label) in [
            (CandidateListing::Auto, "auto"),
            (CandidateListing::Lanes, "in lanes"),
            (CandidateListing::OnePerVertex, "one per vertex"),
        ] {
            ui.selectable_value(&mut draft.candidate_listing, value, label);
        }
    });
    if let Err(e) = draft.check() {
        ui.colored_label(egui::Color32::from_rgb(220, 50, 50), format!("⚠ {e}"));
    }
    ui.horizontal(|ui| {
        let changed = draft != running;
        if ui.add_enabled(changed && draft.check().is_ok(), egui::Button::new("Apply")).clicked() {
            commands.push(Command::ApplyTuning(draft.clone()));
        }
        if ui.add_enabled(changed, egui::Button::new("Revert")).clicked() {
            *draft = running.clone();
        }
        if ui.button("Defaults").clicked() {
            *draft = GpuTuning { adapter: draft.adapter.clone(), ..GpuTuning::default() };
        }
    });
}
