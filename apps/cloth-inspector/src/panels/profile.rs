//! Frame profile panel: where one GPU frame's time goes, pass by pass (`Simulator::profile_frame`,
//! what `cloth profile` prints), as a bar per pass.

use cloth_core::PassTime;
use eframe::egui;

use crate::commands::Command;

/// A profiled frame: its passes, the backend and device it ran on, and the simulated time it
/// ended at, s.
#[derive(Clone, Debug)]
pub struct FrameProfile {
    pub passes: Vec<PassTime>,
    pub backend: String,
    pub adapter: String,
    pub time_s: f64,
}

impl FrameProfile {
    /// The frame's GPU time, s: its passes' together.
    pub fn seconds(&self) -> f64 {
        self.passes.iter().map(|p| p.seconds).sum()
    }

    /// One line a pass, for a headless run's log.
    pub fn summary(&self) -> Vec<String> {
        let total = self.seconds();
        let mut lines = vec![format!(
            "frame profile on {} ({}), the frame ending at {:.3} s: {:.3} ms",
            self.backend,
            self.adapter,
            self.time_s,
            total * 1e3
        )];
        for p in &self.passes {
            lines.push(format!(
                "  {:<36} {:>4} dispatches {:>9.3} ms {:>5.1}% ({:.1} to {:.1} µs each)",
                p.name,
                p.dispatches,
                p.seconds * 1e3,
                100.0 * p.seconds / total,
                p.shortest_s * 1e6,
                p.longest_s * 1e6
            ));
        }
        lines
    }
}

/// The button that profiles the next frame (GPU backends), and the last profile as a bar a pass:
/// its share of the frame, its time and its dispatches.
pub fn show(ui: &mut egui::Ui, last: Option<&FrameProfile>, backend: &str, commands: &mut Vec<Command>) {
    let gpu = backend == "wgpu" || backend == "vulkano";
    let button = ui
        .add_enabled(gpu, egui::Button::new("Profile the next frame"))
        .on_hover_text("Runs one frame with a GPU timestamp after every dispatch (as `cloth profile` does)")
        .on_disabled_hover_text("Only the GPU backends have passes to profile");
    if button.clicked() {
        commands.push(Command::ProfileFrame);
    }
    let Some(profile) = last else { return };
    let total = profile.seconds();
    ui.label(format!(
        "{} ({}), the frame ending at {:.2} s: {:.3} ms of GPU time",
        profile.backend,
        profile.adapter,
        profile.time_s,
        total * 1e3
    ));
    for p in &profile.passes {
        let share = if total > 0.0 { (p.seconds / total) as f32 } else { 0.0 };
        let each = if p.dispatches > 1 {
            format!("{:.1} to {:.1} µs a dispatch", p.shortest_s * 1e6, p.longest_s * 1e6)
        } else {
            String::new()
        };
        ui.horizontal(|ui| {
            ui.label(&p.name);
            ui.weak(each);
        });
        ui.add(egui::ProgressBar::new(share).text(format!(
            "{:.3} ms, {} dispatch{} ({:.0}%)",
            p.seconds * 1e3,
            p.dispatches,
            if p.dispatches == 1 { "" } else { "es" },
            100.0 * share
        )));
    }
    ui.small(
        "A pass's time runs from the timestamp after the dispatch before it, barrier included; \
         the timestamps may hold the dispatches back a little.",
    );
}
