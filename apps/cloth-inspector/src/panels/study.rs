//! Study panel: a quick accuracy study in the background (progress bar), or the last
//! `cloth study accuracy` CSV, plotted as error against cost.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use eframe::egui;
use egui_plot::{Legend, Line, Plot, PlotPoints, Points};

use crate::study::{StudyPoint, StudyProgress};

/// What the panel shows.
#[derive(Default)]
pub struct StudyPanel {
    running: Option<Arc<Mutex<StudyProgress>>>,
    points: Vec<StudyPoint>,
    message: Option<String>,
    /// Whether the last study's CSV was looked for (once, at the first show).
    looked_for_last: bool,
}

impl StudyPanel {
    fn load_last(&mut self) {
        match crate::study::last_study_csv() {
            Some(path) => match crate::study::load_csv(&path) {
                Ok(study) => {
                    self.points = study.points;
                    self.message = Some(match study.scene {
                        Some(scene) => format!("the last study: {} (its first scene, {scene})", path.display()),
                        None => format!("the last study: {}", path.display()),
                    });
                }
                Err(e) => self.message = Some(e),
            },
            None => self.message = Some("no study yet: run `cloth study accuracy`, or a quick study".into()),
        }
    }

    /// `backend` is the one running now: the quick study runs there.
    pub fn show(&mut self, ui: &mut egui::Ui, scene: &cloth_core::Scene, backend: &str, tuning: &cloth_gpu::GpuTuning) {
        if !self.looked_for_last {
            self.looked_for_last = true;
            self.load_last();
        }
        ui.horizontal(|ui| {
            let idle = self.running.is_none();
            let quick = egui::Button::new(format!("Quick study ({backend})"));
            if ui
                .add_enabled(idle, quick)
                .on_hover_text(
                    "Every integrator at 8, 16, 32 substeps on a small copy of this scene, on this backend, \
                     against an f64 RK4 reference (in the background)",
                )
                .clicked()
            {
                self.running = Some(crate::study::spawn_quick_study(scene, backend, tuning));
                self.message = None;
            }
            if ui
                .button("Last study")
                .on_hover_text("out/accuracy.csv (the last `cloth study accuracy` here), else docs/accuracy.csv")
                .clicked()
            {
                self.load_last();
            }
        });
        if let Some(progress) = &self.running {
            let p = progress.lock().map(|p| p.clone()).unwrap_or_default();
            ui.add(
                egui::ProgressBar::new(p.done as f32 / p.total.max(1) as f32)
                    .text(format!("{} / {} runs", p.done, p.total)),
            );
            self.points = p.points.clone();
            if let Some(e) = p.error {
                self.message = Some(e);
                self.running = None;
            } else if p.total > 0 && p.done == p.total {
                self.message = Some("quick study done".into());
                self.running = None;
            } else {
                ui.ctx().request_repaint();
            }
        }
        if let Some(m) = &self.message {
            ui.label(egui::RichText::new(m).small());
        }
        if self.points.is_empty() {
            return;
        }
        let mut series: BTreeMap<&str, Vec<[f64; 2]>> = BTreeMap::new();
        for p in &self.points {
            series.entry(&p.series).or_default().push([p.ms_per_simulated_s.log10(), p.rms_error_m.log10()]);
        }
        ui.label("log10 RMS error (m) against log10 ms per simulated second (GPU time on GPU backends)");
        Plot::new("study").height(180.0).legend(Legend::default()).show(ui, |plot| {
            for (name, points) in series {
                plot.line(Line::new(name.to_string(), PlotPoints::from(points.clone())));
                plot.points(Points::new(name.to_string(), PlotPoints::from(points)).radius(3.0));
            }
        });
    }
}
