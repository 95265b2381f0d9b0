//! Effect costs panel: what each effect of the scene on screen costs on the running backend —
//! the bare cloth, then each effect added (`cloth_backends::effect_cost`, the breakdown that
//! `cloth bench --effects` prints), measured in the background with a progress bar.

use std::sync::{Arc, Mutex};

use cloth_backends::effect_cost::{self, Breakdown};
use cloth_core::Scene;
use eframe::egui;

/// Frames of each timing.
const FRAMES: u32 = 10;

/// Timings of each row, in alternating order (`cloth_backends::timing`).
const REPEATS: u32 = cloth_backends::timing::DEFAULT_REPEATS;

/// Progress shared with the background thread.
#[derive(Clone, Debug, Default)]
struct Progress {
    done: usize,
    total: usize,
    result: Option<Result<Breakdown, String>>,
}

/// What the panel shows.
#[derive(Default)]
pub struct EffectCostsPanel {
    running: Option<Arc<Mutex<Progress>>>,
    /// The last breakdown, with the scene and backend it was measured for.
    last: Option<(Breakdown, Scene, String)>,
    message: Option<String>,
}

impl EffectCostsPanel {
    /// Starts measuring `scene` on `backend` in the background.
    pub fn start(&mut self, scene: &Scene, backend: &str, tuning: &cloth_gpu::GpuTuning) {
        // Every row's warm-up frame and timings, within the backend's work budget, or not at all.
        let steps = effect_cost::steps(scene);
        let rows = steps.len() as u32;
        let frames = (FRAMES * REPEATS + 1).saturating_mul(rows);
        let whole = steps.last().map(|step| effect_cost::row_scene(scene, step)).unwrap_or_else(|| scene.clone());
        if let Err(p) = cloth_core::budget::WorkBudget::for_backend(backend).check(&whole, frames) {
            self.message = Some(format!(
                "not measured: {rows} rows of {} frames each on {backend} are too much work ({}); use a smaller grid \
                 or fewer substeps",
                FRAMES * REPEATS + 1,
                p.message
            ));
            return;
        }
        let progress = Arc::new(Mutex::new(Progress::default()));
        let (shared, scene, name, tuning) = (progress.clone(), scene.clone(), backend.to_string(), tuning.clone());
        std::thread::spawn(move || {
            let result = cloth_backends::find(&name).and_then(|b| {
                effect_cost::measure(&scene, &b, &tuning, FRAMES, REPEATS, |done, total| {
                    if let Ok(mut p) = shared.lock() {
                        (p.done, p.total) = (done, total);
                    }
                })
                .map_err(|e| e.to_string())
            });
            if let Ok(mut p) = shared.lock() {
                p.result = Some(result);
            }
        });
        self.running = Some(progress);
        self.message = None;
    }

    /// Whether a measurement is under way.
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// The last breakdown (or the error it ended with) as lines of text, for a headless run's log.
    pub fn summary(&self) -> Vec<String> {
        let mut lines: Vec<String> = self.message.iter().map(|m| format!("effect costs failed: {m}")).collect();
        if let Some((breakdown, _, backend)) = &self.last {
            lines.push(format!(
                "effect costs on {backend} ({}, {} substeps per frame, median of {} timings, {}):",
                breakdown.adapter,
                breakdown.substeps,
                breakdown.repeats,
                breakdown.timer()
            ));
            for r in &breakdown.rows {
                lines.push(format!(
                    "  {:<22} {:>10.3} ms/frame (spread {:.3}) | {}",
                    r.label(),
                    r.ms_per_frame.median(),
                    r.ms_per_frame.spread(),
                    r.added_text()
                ));
            }
        }
        lines
    }

    /// `scene` is the one running on `backend` now.
    pub fn show(&mut self, ui: &mut egui::Ui, scene: &Scene, backend: &str, tuning: &cloth_gpu::GpuTuning) {
        let idle = self.running.is_none();
        let button = egui::Button::new(format!("Measure effect costs ({backend})"));
        if ui
            .add_enabled(idle, button)
            .on_hover_text(format!(
                "Times {FRAMES} frames of this scene on {backend} with no effect, then with each of its effects \
                 added in turn, {REPEATS} times in alternating order (in the background; GPU timestamps where the \
                 backend has them). A cost is shown where the paired timings agree on it, else as inside the noise"
            ))
            .clicked()
        {
            self.start(scene, backend, tuning);
        }
        if let Some(progress) = &self.running {
            let p = progress.lock().map(|p| p.clone()).unwrap_or_default();
            let total = p.total.max(effect_cost::steps(scene).len() * REPEATS as usize);
            ui.add(egui::ProgressBar::new(p.done as f32 / total as f32).text(format!("{} / {total} timings", p.done)));
            match p.result {
                Some(Ok(breakdown)) => {
                    self.last = Some((breakdown, scene.clone(), backend.to_string()));
                    self.running = None;
                }
                Some(Err(e)) => {
                    self.message = Some(e);
                    self.running = None;
                }
                None => ui.ctx().request_repaint(),
            }
        }
        if let Some(m) = &self.message {
            ui.colored_label(egui::Color32::from_rgb(220, 50, 50), m);
        }
        let Some((breakdown, measured_scene, measured_backend)) = &self.last else {
            ui.label(egui::RichText::new("not measured yet").weak());
            return;
        };
        let [nx, ny] = measured_scene.cloth.resolution;
        ui.label(
            egui::RichText::new(format!(
                "{measured_backend} on {}: {nx}x{ny}, {} substeps per frame, median of {} timings, {}",
                breakdown.adapter,
                breakdown.substeps,
                breakdown.repeats,
                breakdown.timer()
            ))
            .small(),
        );
        if measured_scene != scene || measured_backend != backend {
            ui.label(egui::RichText::new("the scene or backend changed since: measure again").small().weak());
        }
        let whole = breakdown.whole_ms().max(f64::MIN_POSITIVE);
        egui::Grid::new("effect costs").num_columns(3).striped(true).show(ui, |ui| {
            for row in &breakdown.rows {
                let median = row.ms_per_frame.median();
                // Only a time or a cost that stands out of the noise gets a bar.
                let (bar, text, noise) = match row.added_cost {
                    None => (Some(median), format!("{median:.3} ms"), false),
                    Some(d) => (d.cost(), d.describe("ms"), d.outside_noise().is_none()),
                };
                ui.label(row.label());
                match bar {
                    Some(ms) => {
                        ui.add(egui::ProgressBar::new((ms / whole).clamp(0.0, 1.0) as f32).desired_width(110.0))
                    }
                    None => ui.label(""),
                };
                let text = egui::RichText::new(text);
                ui.label(if noise { text.weak() } else { text }).on_hover_text(format!(
                    "row: median {median:.3} ms per frame, spread (interquartile range) {:.3} ms over {} timings",
                    row.ms_per_frame.spread(),
                    row.ms_per_frame.len()
                ));
                ui.end_row();
            }
            ui.label("whole scene");
            ui.label("");
            ui.label(format!("{whole:.3} ms per frame"));
            ui.end_row();
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_breakdown_beyond_the_work_budget_is_not_started() {
        // 512² vertices at 100000 substeps: one frame is 2.6e10 vertex-substeps, and the
        // breakdown's rows need hundreds of frames.
        let mut scene = Scene::default();
        scene.cloth.resolution = [512, 512];
        scene.time.substeps = cloth_core::Substeps::Fixed(100_000);
        let mut panel = EffectCostsPanel::default();
        panel.start(&scene, "cpu", &Default::default());
        assert!(!panel.is_running());
        let summary = panel.summary().join("\n");
        assert!(summary.contains("not measured: 8 rows of 51 frames each on cpu are too much work"), "{summary}");
    }
}
