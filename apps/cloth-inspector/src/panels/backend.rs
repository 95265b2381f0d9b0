//! Backend panel: choose cpu, wgpu or vulkano at runtime; unavailable ones are disabled with the
//! reason.

use eframe::egui;

use crate::commands::Command;

/// A backend and whether it can run here.
pub struct BackendStatus {
    /// Name, as in `cloth backends`.
    pub name: &'static str,
    /// What it is.
    pub description: &'static str,
    /// The adapter it would use, or why it cannot run.
    pub availability: Result<String, String>,
}

pub fn show(ui: &mut egui::Ui, backends: &[BackendStatus], current: &str, adapter: &str, commands: &mut Vec<Command>) {
    for b in backends {
        let selected = b.name == current;
        let enabled = b.availability.is_ok();
        let response = ui.add_enabled(enabled, egui::RadioButton::new(selected, b.name));
        let hover = match &b.availability {
            Ok(a) => format!("{}\n{a}", b.description),
            Err(why) => format!("unavailable: {why}"),
        };
        if response
            .on_hover_text(hover)
            .on_disabled_hover_text(b.availability.clone().err().unwrap_or_default())
            .clicked()
            && !selected
        {
            commands.push(Command::SwitchBackend(b.name.to_string()));
        }
        if let Err(why) = &b.availability {
            ui.indent(b.name, |ui| ui.label(egui::RichText::new(why).small().weak()));
        }
    }
    ui.label(egui::RichText::new(format!("running on: {adapter}")).small());
}
