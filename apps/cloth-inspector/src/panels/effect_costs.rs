//! Effect costs panel: what each effect of the scene on screen costs on the running backend —
//! the bare cloth, then each effect added (`cloth_backends::effect_cost`, the breakdown that
//! `cloth bench --effects` prints), measured in the background with a progress bar.

use std::sync::{Arc, Mutex};

use cloth_backends::effect_cost::{self, Breakdown};
use cloth_core::Scene;
use eframe::egui;

/// Frames timed per row (the least of `effect_cost::REPEATS` timings is kept).
const FRAMES: u32 = 10;

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
        let progress = Arc::new(Mutex::new(Progress::default()));
        let (shared, scene, name, tuning) = (progress.clone(), scene.clone(), backend.to_string(), tuning.clone());
        std::thread::spawn(move || {
            let result = cloth_backends::find(&name).and_then(|b| {
                effect_cost::measure(&scene, &b, &tuning, FRAMES, |done, total| {
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
                "effect costs on {backend} ({}, {} substeps per frame, {}):",
                breakdown.adapter,
                breakdown.substeps,
                breakdown.timer()
            ));
            for r in &breakdown.rows {
                lines.push(format!("  {:<22} {:>10.3} ms/frame {:>+10.3} ms", r.label(), r.ms_per_frame, r.added_ms));
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
                 added in turn (in the background; GPU timestamps where the backend has them)"
            ))
            .clicked()
        {
            self.start(scene, backend, tuning);
        }
        if let Some(progress) = &self.running {
            let p = progress.lock().map(|p| p.clone()).unwrap_or_default();
            let total = p.total.max(effect_cost::steps(scene).len());
            ui.add(egui::ProgressBar::new(p.done as f32 / total as f32).text(format!("{} / {total} rows", p.done)));
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
                "{measured_backend} on {}: {nx}x{ny}, {} substeps per frame, {}",
                breakdown.adapter,
                breakdown.substeps,
                breakdown.timer()
            ))
            .small(),
        );
        if measured_scene != scene || measured_backend != backend {
            ui.label(egui::RichText::new("the scene or backend changed since: measure again").small().weak());
        }
        let whole = breakdown.rows.last().map_or(1.0, |r| r.ms_per_frame).max(f64::MIN_POSITIVE);
        egui::Grid::new("effect costs").num_columns(3).striped(true).show(ui, |ui| {
            for row in &breakdown.rows {
                let (ms, text) = match row.added {
                    None => (row.ms_per_frame, format!("{:.3} ms", row.ms_per_frame)),
                    Some(_) => (row.added_ms, format!("{:+.3} ms", row.added_ms)),
                };
                ui.label(row.label());
                ui.add(egui::ProgressBar::new((ms / whole).clamp(0.0, 1.0) as f32).desired_width(110.0));
                ui.label(text);
                ui.end_row();
            }
            ui.label("whole scene");
            ui.label("");
            ui.label(format!("{whole:.3} ms per frame"));
            ui.end_row();
        });
    }
}
