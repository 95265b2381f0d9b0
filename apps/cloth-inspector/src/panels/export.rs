//! Export panel: the scene run from its start and written as one glTF file (`.glb`) or a folder
//! of OBJ frames with a CSV of diagnostics, in the background with a progress bar
//! ([`cloth_export`]; the same choices as `cloth run --export FILE.glb|DIR/ --every N`).

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use cloth_core::Scene;
use eframe::egui;

/// Progress shared with the background export.
#[derive(Clone, Debug, Default)]
pub struct ExportProgress {
    /// Frames simulated.
    pub done: u32,
    /// Frames to simulate.
    pub total: u32,
    /// How it ended: what was written, or why not.
    pub outcome: Option<Result<String, String>>,
}

/// A background export: its progress and the flag that cancels it.
pub struct ExportJob {
    pub progress: Arc<Mutex<ExportProgress>>,
    pub cancel: Arc<AtomicBool>,
}

/// What to export: `frames` frames of `scene` from its start on `backend`, to `path` (a `.glb`
/// file or a folder), keeping every `every`-th.
#[derive(Clone)]
pub struct ExportRequest {
    pub scene: Scene,
    pub backend: String,
    pub tuning: cloth_gpu::GpuTuning,
    pub path: PathBuf,
    pub frames: u32,
    pub every: u32,
}

/// Runs `request` on a background thread. The plan is checked first (the target, the format's
/// limits); the files are written whole, and a cancelled or failed export leaves no file under
/// the final name.
pub fn spawn_export(request: ExportRequest) -> ExportJob {
    let progress = Arc::new(Mutex::new(ExportProgress { total: request.frames, ..Default::default() }));
    let cancel = Arc::new(AtomicBool::new(false));
    let job = ExportJob { progress: progress.clone(), cancel: cancel.clone() };
    std::thread::spawn(move || {
        let outcome = export(&request, &progress, &cancel);
        if let Ok(mut p) = progress.lock() {
            p.outcome = Some(outcome);
        }
    });
    job
}

fn export(request: &ExportRequest, progress: &Mutex<ExportProgress>, cancel: &AtomicBool) -> Result<String, String> {
    let ExportRequest { scene, backend, tuning, path, frames, every } = request;
    let plan = cloth_export::ExportPlan::new(path, scene, *frames, *every).map_err(|e| e.to_string())?;
    let mut work = cloth_core::budget::WorkPlan::default();
    work.add(backend, scene, *frames).map_err(|p| format!("frames: {p}"))?;
    let factory = cloth_backends::find(backend)?.create;
    let mut sim = factory(scene, tuning).map_err(|e| format!("cannot start the {backend} backend: {e}"))?;
    let summary = cloth_export::run(&plan, scene, sim.as_mut(), |done| {
        if let Ok(mut p) = progress.lock() {
            p.done = done;
        }
        !cancel.load(Ordering::Relaxed)
    })
    .map_err(|e| e.to_string())?;
    Ok(format!(
        "wrote {} ({} frames, {:.1} MiB) on {backend}",
        summary.path.display(),
        summary.frames,
        summary.bytes as f64 / f64::from(1 << 20)
    ))
}

/// What the panel holds between frames.
#[derive(Default)]
pub struct ExportPanel {
    /// The file (`.glb`) or folder (ending in `/`) typed; empty until first shown.
    target: String,
    frames: u32,
    every: u32,
    job: Option<ExportJob>,
    message: Option<Result<String, String>>,
}

impl ExportPanel {
    /// `backend` is the one running now: the export runs the scene from its start there.
    pub fn show(&mut self, ui: &mut egui::Ui, scene: &Scene, backend: &str, tuning: &cloth_gpu::GpuTuning) {
        if self.target.is_empty() {
            self.target = format!("out/{}.glb", scene.name.replace(|c: char| !c.is_ascii_alphanumeric(), "_"));
            self.frames = scene.time.frames;
            self.every = 1;
        }
        ui.horizontal(|ui| {
            ui.label("To");
            ui.text_edit_singleline(&mut self.target).on_hover_text(
                "FILE.glb: one binary glTF 2.0 file (Blender: File > Import > glTF 2.0). DIR/: one OBJ per kept \
                 frame, the colliders' OBJ and diagnostics.csv",
            );
        });
        ui.horizontal(|ui| {
            ui.label("frames");
            ui.add(egui::DragValue::new(&mut self.frames).range(1..=cloth_core::budget::MAX_FRAMES));
            ui.label("keep every");
            ui.add(egui::DragValue::new(&mut self.every).range(1..=u32::MAX)).on_hover_text("The start is always kept");
        });
        let idle = self.job.is_none();
        ui.horizontal(|ui| {
            let button = egui::Button::new(format!("Export… ({backend})"));
            if ui
                .add_enabled(idle, button)
                .on_hover_text("Runs the scene from its start on this backend in the background and writes the files")
                .clicked()
            {
                self.job = Some(spawn_export(ExportRequest {
                    scene: scene.clone(),
                    backend: backend.to_string(),
                    tuning: tuning.clone(),
                    path: PathBuf::from(self.target.trim()),
                    frames: self.frames,
                    every: self.every,
                }));
                self.message = None;
            }
            if let Some(job) = &self.job
                && ui.button("Cancel").clicked()
            {
                job.cancel.store(true, Ordering::Relaxed);
            }
        });
        if let Some(job) = &self.job {
            let p = job.progress.lock().map(|p| p.clone()).unwrap_or_default();
            ui.add(
                egui::ProgressBar::new(p.done as f32 / p.total.max(1) as f32)
                    .text(format!("{} / {} frames", p.done, p.total)),
            );
            match p.outcome {
                Some(outcome) => {
                    self.message = Some(outcome);
                    self.job = None;
                }
                None => ui.ctx().request_repaint(),
            }
        }
        match &self.message {
            Some(Ok(text)) => {
                ui.label(text);
            }
            Some(Err(text)) => {
                ui.colored_label(egui::Color32::RED, text);
            }
            None => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wait(job: &ExportJob) -> Result<String, String> {
        loop {
            if let Some(outcome) = job.progress.lock().unwrap().outcome.clone() {
                return outcome;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
    }

    #[test]
    fn an_export_runs_in_the_background_and_a_cancelled_one_leaves_no_file() {
        let mut scene = Scene::load(&crate::panels::scene::scenes_dir().join("drape.ron")).unwrap();
        scene.cloth.resolution = [10, 10];
        let dir = std::env::temp_dir().join(format!("cloth-inspector-export-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("drape.glb");
        let request = |path: &std::path::Path, frames, every| ExportRequest {
            scene: scene.clone(),
            backend: "cpu".into(),
            tuning: Default::default(),
            path: path.to_path_buf(),
            frames,
            every,
        };
        let job = spawn_export(request(&path, 6, 2));
        let message = wait(&job).unwrap();
        assert!(message.contains("(4 frames,") && path.is_file(), "{message}");
        std::fs::remove_file(&path).unwrap();
        let job = spawn_export(request(&path, 1000, 1));
        job.cancel.store(true, Ordering::Relaxed);
        let message = wait(&job).unwrap_err();
        assert!(message.contains("cancelled"), "{message}");
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert!(left.is_empty(), "{left:?}");
        let message = wait(&spawn_export(request(&dir.join("x.obj"), 6, 1))).unwrap_err();
        assert!(message.contains("give a file ending in .glb"), "{message}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
