//! The inspector application: persisted state, runtime resources, and the frame loop.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use cloth_core::{ClothModel, ClothState, CpuSimulator, Energy, Problem, Scene, SimError, Simulator, SpringKind};
use cloth_gpu::GpuTuning;
use cloth_wgpu::{GpuContext, WgpuBackend, WgpuSimulator};
use eframe::egui;

use crate::commands::Command;
use crate::panels::{self, PanelContext, backend::BackendStatus, scene::FileBrowser};
use crate::render::{ColorMode, Source, ViewInputs, ViewRenderer};
use crate::state::PersistedState;
use crate::stats::{Sample, Stats};

/// Frames between two read-backs for the plots when the cloth is drawn from the GPU buffer.
const SAMPLE_EVERY_GPU_FRAMES: u32 = 6;

/// The running simulator: the wgpu backend shares eframe's device (drawn without read-back),
/// the others are boxed behind the trait.
pub enum Sim {
    /// WGSL backend on eframe's own device.
    Shared(Box<WgpuSimulator>),
    /// Any other backend.
    Boxed(Box<dyn Simulator>),
}

impl Sim {
    /// The simulator behind the trait.
    pub fn get(&mut self) -> &mut dyn Simulator {
        match self {
            Sim::Shared(s) => s.as_mut(),
            Sim::Boxed(s) => s.as_mut(),
        }
    }

    fn scene(&self) -> &Scene {
        match self {
            Sim::Shared(s) => s.scene(),
            Sim::Boxed(s) => s.scene(),
        }
    }

    fn backend_name(&self) -> &'static str {
        match self {
            Sim::Shared(s) => s.backend_name(),
            Sim::Boxed(s) => s.backend_name(),
        }
    }
}

/// Options from the command line.
#[derive(Clone, Debug, Default)]
pub struct LaunchOptions {
    /// Scene file to open (instead of the remembered one).
    pub scene: Option<PathBuf>,
    /// Backend to start on.
    pub backend: Option<String>,
    /// Headless run: simulate this many frames, write a screenshot, quit.
    pub screenshot: Option<(u32, PathBuf)>,
    /// Cloth colouring to start with.
    pub color: Option<ColorMode>,
    /// Measure the cost of each effect at start (a headless run waits for it and logs it).
    pub measure_effects: bool,
    /// A headless run profiles its last frame (and logs the profile).
    pub profile_frame: bool,
    /// Set when a headless run fails to write its screenshot, so the process exits non-zero.
    pub headless_failed: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

/// Runtime resources: never persisted.
pub struct Runtime {
    sim: Option<Sim>,
    model: ClothModel,
    /// Last state read back: drawn for host backends, and the last good state to fall back to.
    host_state: Option<ClothState>,
    /// The triangles crossed by a cloth edge in the last sampled state, drawn red.
    crossed_triangles: Vec<[u32; 3]>,
    backends: Vec<BackendStatus>,
    renderer: Option<ViewRenderer>,
    render_state: Option<eframe::egui_wgpu::RenderState>,
    stats: Stats,
    problems: Vec<Problem>,
    /// An edited scene the backend refused (e.g. too large for the device): not retried until
    /// the scene changes again.
    rejected: Option<(Scene, Problem)>,
    notices: Vec<String>,
    commands: Vec<Command>,
    browser: FileBrowser,
    frame_accumulator: f32,
    frames_since_sample: u32,
    frames_run: u32,
    /// Simulated time of the running cloth, s: counted per frame, set from every state read back.
    sim_time_s: f64,
    screenshot: Option<(u32, PathBuf)>,
    screenshot_done: Arc<Mutex<Option<Result<(), String>>>>,
    headless_failed: Arc<std::sync::atomic::AtomicBool>,
    screenshot_requested: bool,
    confirm_quit: bool,
    allow_close: bool,
    study: panels::study::StudyPanel,
    export: panels::export::ExportPanel,
    effect_costs: panels::effect_costs::EffectCostsPanel,
    /// The last profiled frame.
    profile: Option<panels::profile::FrameProfile>,
    /// Whether a profile came since the panels were last drawn (its section opens to show it).
    profile_fresh: bool,
    /// Whether a headless run profiles its last frame.
    profile_last_frame: bool,
    /// How the GPU backends lay their work out, and the draft the tuning panel edits.
    tuning: GpuTuning,
    tuning_draft: GpuTuning,
    /// The collider shift-drag moves (an index into the scene's colliders).
    dragged_collider: usize,
}

/// The inspector.
pub struct InspectorApp {
    state: PersistedState,
    runtime: Runtime,
}

fn availability(render_state: Option<&eframe::egui_wgpu::RenderState>) -> Vec<BackendStatus> {
    cloth_backends::all()
        .into_iter()
        .map(|b| {
            let availability = match (b.name, render_state) {
                ("wgpu", Some(rs)) => {
                    Ok(format!("{} (eframe's device, drawn without read-back)", rs.adapter.get_info().name))
                }
                _ => (b.adapters)().and_then(|list| list.into_iter().next().ok_or_else(|| "no adapter".to_string())),
            };
            BackendStatus { name: b.name, description: b.description, availability }
        })
        .collect()
}

impl InspectorApp {
    /// Builds the app; restores the persisted state unless the command line says otherwise.
    pub fn new(cc: &eframe::CreationContext<'_>, options: LaunchOptions) -> Self {
        let headless = options.screenshot.is_some();
        let mut state: PersistedState = if headless {
            PersistedState::default()
        } else {
            cc.storage.and_then(|s| eframe::get_value(s, eframe::APP_KEY)).unwrap_or_default()
        };
        let mut notices = Vec::new();
        if let Some(path) = &options.scene {
            match Scene::load(path) {
                Ok(scene) => {
                    state.scene = scene.clone();
                    state.saved_scene = scene;
                    state.scene_path = Some(path.clone());
                }
                Err(e) => notices.push(format!("{}: {e}", path.display())),
            }
        }
        if let Some(b) = &options.backend {
            state.backend = b.clone();
        }
        if let Some(c) = options.color {
            state.color_mode = c;
        }
        if headless {
            state.playing = true;
            state.speed = 1.0;
        }
        if state.scene.validate().is_err() {
            notices.push("the remembered scene is invalid; starting from the default scene".into());
            state.scene = Scene::default();
        }
        let render_state = cc.wgpu_render_state.clone();
        let renderer = render_state.as_ref().map(ViewRenderer::new);
        let backends = availability(render_state.as_ref());
        let mut app = Self {
            runtime: Runtime {
                sim: None,
                model: ClothModel::new(&state.scene),
                host_state: None,
                crossed_triangles: Vec::new(),
                backends,
                renderer,
                render_state,
                stats: Stats::default(),
                problems: Vec::new(),
                rejected: None,
                notices,
                commands: Vec::new(),
                browser: FileBrowser::default(),
                frame_accumulator: 0.0,
                frames_since_sample: 0,
                frames_run: 0,
                sim_time_s: 0.0,
                screenshot: options.screenshot,
                screenshot_done: Arc::new(Mutex::new(None)),
                headless_failed: options.headless_failed,
                screenshot_requested: false,
                confirm_quit: false,
                allow_close: false,
                study: Default::default(),
                export: Default::default(),
                effect_costs: Default::default(),
                profile: None,
                profile_fresh: false,
                profile_last_frame: options.profile_frame,
                tuning: GpuTuning::default(),
                tuning_draft: GpuTuning::default(),
                dragged_collider: 0,
            },
            state,
        };
        app.rebuild();
        if options.measure_effects {
            let backend = app.state.backend.clone();
            app.runtime.effect_costs.start(&app.state.scene, &backend, &app.runtime.tuning);
        }
        app
    }

    /// Creates a simulator of backend `name` for the current scene.
    fn create(&self, name: &str) -> Result<Sim, SimError> {
        let scene = &self.state.scene;
        one_frame_fits(scene, name)?;
        if name == "wgpu"
            && let Some(rs) = &self.runtime.render_state
        {
            let context = GpuContext {
                device: rs.device.clone(),
                queue: rs.queue.clone(),
                adapter_description: format!("{} (eframe's device)", rs.adapter.get_info().name),
                device_type: rs.adapter.get_info().device_type,
            };
            let sim = WgpuSimulator::on_backend(scene, WgpuBackend::on(context), &self.runtime.tuning)?;
            return Ok(Sim::Shared(Box::new(sim)));
        }
        let backend =
            cloth_backends::find(name).map_err(|reason| SimError::Unavailable { backend: "inspector", reason })?;
        Ok(Sim::Boxed((backend.create)(scene, &self.runtime.tuning)?))
    }

    /// (Re)creates the simulator of the current backend from the scene's initial state. Falls
    /// back to the CPU when the backend cannot start.
    /// Counts the self-intersections of `state` and keeps the crossed triangles to draw, or
    /// `None` (and nothing to draw) above [`MAX_COUNTED_VERTICES`] or for a cloth torn across
    /// itself ([`cloth_core::intersections::TooTangled`]).
    fn count_crossings(&mut self, state: &ClothState) -> Option<usize> {
        let [nx, ny] = [self.runtime.model.grid.nx, self.runtime.model.grid.ny];
        self.runtime.crossed_triangles.clear();
        if state.positions.len() > MAX_COUNTED_VERTICES || state.positions.len() != (nx * ny) as usize {
            return None;
        }
        let crossings = cloth_core::intersections::crossings(&state.positions, nx, ny).ok()?;
        let triangles = cloth_core::intersections::triangles(nx, ny);
        let mut crossed: Vec<u32> = crossings.iter().map(|c| c.triangle).collect();
        crossed.sort_unstable();
        crossed.dedup();
        self.runtime.crossed_triangles = crossed.into_iter().map(|t| triangles[t as usize]).collect();
        Some(crossings.len())
    }

    fn rebuild(&mut self) {
        let name = self.state.backend.clone();
        let sim = match self.create(&name) {
            Ok(sim) => Ok(sim),
            Err(e) => {
                self.runtime.notices.push(format!("{name} cannot run this scene: {e}; using the CPU backend"));
                self.state.backend = "cpu".into();
                self.create("cpu")
            }
        };
        match sim {
            Ok(mut sim) => {
                self.runtime.model = ClothModel::new(sim.scene());
                self.runtime.host_state = sim.get().read_state().ok();
                self.runtime.sim_time_s = self.runtime.host_state.as_ref().map_or(0.0, |s| s.time_s);
                self.runtime.sim = Some(sim);
            }
            Err(e) => self.runtime.notices.push(format!("cannot start any backend: {e}")),
        }
        self.runtime.stats.clear();
        self.runtime.crossed_triangles.clear();
    }

    /// Hands the running cloth to another backend: read its state, start the new backend, write
    /// the state into it. The motion continues without a jump. Returns whether it switched.
    pub fn switch_backend(&mut self, name: &str) -> bool {
        let state =
            self.runtime.sim.as_mut().and_then(|s| s.get().read_state().ok()).or(self.runtime.host_state.clone());
        match self.create(name) {
            Ok(mut sim) => {
                if let Some(s) = &state
                    && let Err(e) = hand_over(s, sim.get())
                {
                    self.runtime.notices.push(format!("could not hand the state to {name}: {e}"));
                    return false;
                }
                self.state.backend = name.to_string();
                if let Some(s) = &state {
                    self.runtime.sim_time_s = s.time_s;
                }
                self.runtime.host_state = state;
                self.runtime.sim = Some(sim);
                true
            }
            Err(e) => {
                self.runtime.notices.push(format!("cannot switch to {name}: {e}"));
                false
            }
        }
    }

    fn apply(&mut self, command: Command) {
        match command {
            Command::Reset => self.rebuild(),
            Command::SwitchBackend(name) => {
                self.switch_backend(&name);
            }
            Command::StepOnce => self.advance(1),
            Command::ProfileFrame => self.profile_frame(),
            Command::ApplyTuning(tuning) => {
                let previous = std::mem::replace(&mut self.runtime.tuning, tuning);
                let name = self.state.backend.clone();
                if !self.switch_backend(&name) {
                    self.runtime.tuning = previous;
                }
            }
            Command::OpenScene(path) => match Scene::load(&path) {
                Ok(scene) => {
                    self.state.scene = scene.clone();
                    self.state.saved_scene = scene;
                    self.state.scene_path = Some(path);
                    self.rebuild();
                }
                Err(e) => self.runtime.notices.push(format!("{} was not opened: {e}", path.display())),
            },
            Command::SaveScene(path) => match save_atomically(&self.state.scene, &path) {
                Ok(()) => {
                    self.state.saved_scene = self.state.scene.clone();
                    self.state.scene_path = Some(path);
                }
                Err(e) => self.runtime.notices.push(format!("the scene was not saved: {e}")),
            },
        }
    }

    /// Applies the edited scene: invalid edits are shown, not applied; structural ones rebuild.
    fn apply_edits(&mut self) {
        let Some(sim) = self.runtime.sim.as_mut() else { return };
        if self.state.scene == *sim.scene() {
            self.runtime.problems.clear();
            return;
        }
        match self.state.scene.validate() {
            Err(e) => self.runtime.problems = e.problems().to_vec(),
            Ok(_) => {
                self.runtime.problems.clear();
                if sim.scene().rebuild_reason(&self.state.scene).is_some() {
                    self.rebuild_for_edit();
                } else if let Err(e) = sim.get().update_parameters(&self.state.scene) {
                    self.runtime.notices.push(format!("could not apply the change: {e}"));
                } else {
                    // The springs and grid are unchanged; the drawing and the energy read the
                    // new parameters (a moved sphere is drawn where it now is).
                    self.runtime.model.scene = self.state.scene.clone();
                }
            }
        }
    }

    /// Rebuilds for an edit that needs it. If the backend refuses the new scene (too large for the
    /// device, say), the running simulation is kept and the reason is shown next to the field.
    fn rebuild_for_edit(&mut self) {
        if let Some((scene, problem)) = &self.runtime.rejected
            && *scene == self.state.scene
        {
            self.runtime.problems = vec![problem.clone()];
            return;
        }
        let name = self.state.backend.clone();
        match self.create(&name) {
            Ok(mut sim) => {
                self.runtime.rejected = None;
                self.runtime.model = ClothModel::new(sim.scene());
                self.runtime.host_state = sim.get().read_state().ok();
                self.runtime.sim_time_s = self.runtime.host_state.as_ref().map_or(0.0, |s| s.time_s);
                self.runtime.sim = Some(sim);
                self.runtime.stats.clear();
                self.runtime.crossed_triangles.clear();
            }
            Err(e) => {
                let (field, fix) = match e {
                    SimError::Unsupported { .. } => ("integrator", "choose another integrator, or the cpu backend"),
                    _ => ("cloth.resolution", "use a smaller grid, or another backend"),
                };
                let problem = Problem {
                    field: field.into(),
                    message: format!("the {name} backend cannot run this scene: {e}"),
                    fix: fix.into(),
                };
                self.runtime.problems = vec![problem.clone()];
                self.runtime.rejected = Some((self.state.scene.clone(), problem));
            }
        }
    }

    /// Advances one frame with a timestamp after every dispatch and keeps where its GPU time went
    /// (the plots catch up at their next sample).
    fn profile_frame(&mut self) {
        let Some(sim) = self.runtime.sim.as_mut() else { return };
        let (backend, adapter) = (sim.get().backend_name().to_string(), sim.get().adapter_name());
        match sim.get().profile_frame() {
            Ok(Some(passes)) => {
                self.runtime.sim_time_s += sim.scene().time.frame_dt;
                self.runtime.frames_since_sample += 1;
                let time_s = self.runtime.sim_time_s;
                self.runtime.profile = Some(panels::profile::FrameProfile { passes, backend, adapter, time_s });
                self.runtime.profile_fresh = true;
            }
            Ok(None) => self.runtime.notices.push(format!("{backend} on {adapter} has no GPU passes to profile")),
            Err(e) => self.runtime.notices.push(format!("the frame's profile failed on {backend}: {e}")),
        }
    }

    /// Advances `frames` frames; a backend that fails falls back to the CPU with the last good
    /// state. Every `SAMPLE_EVERY_GPU_FRAMES` frames (every frame for host backends) the state is
    /// read back for the plots, and that frame is timed from an idle device to the end of its
    /// read-back.
    fn advance(&mut self, frames: u32) {
        let Some(sim) = self.runtime.sim.as_mut() else { return };
        if frames == 0 {
            return;
        }
        let host_backend = matches!(sim, Sim::Boxed(_));
        self.runtime.frames_since_sample += frames;
        let sample_now = host_backend || self.runtime.frames_since_sample >= SAMPLE_EVERY_GPU_FRAMES;
        let result = (|| {
            if !sample_now {
                return sim.get().advance(frames).map(|()| None);
            }
            if !host_backend {
                sim.get().diagnostics()?; // wait for earlier frames, so the timing is this frame's
            }
            let start = Instant::now();
            sim.get().advance(frames)?;
            let state = sim.get().read_state()?;
            let diagnostics = sim.get().diagnostics()?;
            Ok(Some((state, diagnostics, start.elapsed().as_secs_f64())))
        })();
        match result {
            Ok(Some((state, diagnostics, seconds))) => {
                let scene = sim.scene();
                let work = scene.vertex_count() as f64 * scene.substeps_per_frame() as f64;
                self.runtime.stats.record_timing(seconds, frames, work);
                let energy = Energy::of(&self.runtime.model, &state);
                // A backend tracks the deepest penetration since it was created; keep the running
                // maximum across backend switches.
                let previous = self.runtime.stats.samples.back().map_or(0.0, |s| s.max_penetration_m);
                let self_intersections = self.count_crossings(&state);
                self.runtime.stats.push(Sample {
                    time_s: state.time_s,
                    kinetic_j: energy.kinetic,
                    elastic_j: energy.elastic.iter().sum(),
                    max_penetration_m: diagnostics.max_penetration_m.max(previous),
                    self_intersections,
                    candidate_lists: diagnostics.candidate_lists,
                    solver: diagnostics.solver,
                });
                if state.non_finite_count() > 0 {
                    self.state.playing = false;
                    self.runtime.notices.push(
                        "the simulation blew up (NaN): paused. Raise the substeps or lower the stiffness, then Reset."
                            .into(),
                    );
                }
                self.runtime.sim_time_s = state.time_s;
                self.runtime.host_state = Some(state);
                self.runtime.frames_since_sample = 0;
            }
            Ok(None) => self.runtime.sim_time_s += frames as f64 * sim.scene().time.frame_dt,
            Err(e) => {
                let failed = sim.get().backend_name();
                self.runtime
                    .notices
                    .push(format!("{failed} failed ({e}); continuing on the CPU from the last good state"));
                let last = self.runtime.host_state.clone();
                match CpuSimulator::new(&self.state.scene) {
                    Ok(mut cpu) => {
                        if let Some(s) = &last {
                            let _ = cpu.write_state(s);
                            self.runtime.sim_time_s = s.time_s;
                        }
                        self.runtime.sim = Some(Sim::Boxed(Box::new(cpu)));
                        self.state.backend = "cpu".into();
                    }
                    Err(e) => self.runtime.notices.push(format!("the CPU backend cannot run either: {e}")),
                }
            }
        }
        self.runtime.frames_run += frames;
    }

    fn view(&mut self, ui: &mut egui::Ui) {
        let rect = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let camera = &mut self.state.camera;
        let shift = ui.input(|i| i.modifiers.shift);
        if response.dragged_by(egui::PointerButton::Primary) {
            let d = response.drag_delta();
            let dragged = self.runtime.dragged_collider;
            if shift && dragged < self.state.scene.colliders.len() {
                let (right, up) = camera.right_up();
                let scale = camera.distance as f64 * 0.0015;
                let step = [0, 1, 2].map(|k| (right[k] as f64 * d.x as f64 - up[k] as f64 * d.y as f64) * scale);
                self.state.scene.colliders[dragged].shape.translate(step);
            } else {
                camera.orbit(d.x, d.y);
            }
        }
        if response.dragged_by(egui::PointerButton::Secondary) || response.dragged_by(egui::PointerButton::Middle) {
            let d = response.drag_delta();
            camera.pan(d.x, d.y);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                camera.zoom(scroll);
            }
        }
        let (Some(renderer), Some(rs)) = (self.runtime.renderer.as_mut(), self.runtime.render_state.as_ref()) else {
            ui.put(rect, egui::Label::new("The 3D view needs eframe's wgpu renderer."));
            return;
        };
        let ppp = ui.ctx().pixels_per_point();
        let size = [(rect.width() * ppp).round().max(1.0) as u32, (rect.height() * ppp).round().max(1.0) as u32];
        let aspect = rect.width() / rect.height().max(1.0);
        let inputs_source = match self.runtime.sim.as_ref() {
            Some(Sim::Shared(s)) => {
                Some(Source::Device { positions: s.position_buffer(), velocities: s.velocity_buffer() })
            }
            _ => self.runtime.host_state.as_ref().map(Source::Host),
        };
        let Some(source) = inputs_source else { return };
        let inputs = ViewInputs {
            view_proj: self.state.camera.view_proj(aspect),
            eye: self.state.camera.eye(),
            color_mode: self.state.color_mode,
            wireframe: self.state.wireframe,
            source,
            time_s: self.runtime.sim_time_s,
            crossed_triangles: &self.runtime.crossed_triangles,
        };
        let texture = renderer.render(rs, size, &self.runtime.model, &inputs);
        ui.painter().image(
            texture,
            rect,
            egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
            egui::Color32::WHITE,
        );
        ui.painter().text(
            rect.left_bottom() + egui::vec2(8.0, -8.0),
            egui::Align2::LEFT_BOTTOM,
            "drag: orbit · right-drag: pan · scroll: zoom · shift-drag: move the collider chosen in Contact",
            egui::FontId::proportional(12.0),
            egui::Color32::from_gray(60),
        );
    }

    fn handle_close(&mut self, ctx: &egui::Context) {
        if self.runtime.screenshot.is_some() {
            return;
        }
        if ctx.input(|i| i.viewport().close_requested()) && self.state.has_unsaved_edits() && !self.runtime.allow_close
        {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.runtime.confirm_quit = true;
        }
        if self.runtime.confirm_quit {
            egui::Modal::new(egui::Id::unique("confirm quit")).show(ctx, |ui| {
                ui.heading("Quit with unsaved edits?");
                ui.label("The scene has changed since it was last opened or saved.");
                ui.horizontal(|ui| {
                    if let Some(path) = self.state.scene_path.clone()
                        && ui.button(format!("Save to {} and quit", path.display())).clicked()
                    {
                        self.apply(Command::SaveScene(path));
                        self.runtime.allow_close = true;
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                    if ui.button("Quit without saving").clicked() {
                        self.runtime.allow_close = true;
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                    if ui.button("Cancel").clicked() {
                        self.runtime.confirm_quit = false;
                    }
                });
            });
        }
    }

    fn headless_step(&mut self, ctx: &egui::Context) {
        let Some((frames, path)) = self.runtime.screenshot.clone() else { return };
        if let Some(result) = self.runtime.screenshot_done.lock().ok().and_then(|mut r| r.take()) {
            match result {
                Ok(()) => {
                    // What a headless run needs to know: where it ran, and anything it was told.
                    let adapter = self.runtime.sim.as_mut().map(|s| s.get().adapter_name()).unwrap_or_default();
                    eprintln!("ran on the {} backend: {adapter}", self.state.backend);
                    for notice in &self.runtime.notices {
                        eprintln!("notice: {notice}");
                    }
                    for line in self.runtime.effect_costs.summary() {
                        eprintln!("{line}");
                    }
                    for line in self.runtime.profile.iter().flat_map(|p| p.summary()) {
                        eprintln!("{line}");
                    }
                    eprintln!("wrote {}", path.display());
                }
                Err(e) => {
                    eprintln!("error: the screenshot failed: {e}");
                    self.runtime.headless_failed.store(true, std::sync::atomic::Ordering::SeqCst);
                }
            }
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        if self.runtime.frames_run >= frames && self.runtime.profile_last_frame {
            // One more frame, profiled; the next drawing shows it, then the picture is taken.
            self.runtime.profile_last_frame = false;
            self.profile_frame();
            ctx.request_repaint();
            return;
        }
        // A measurement started at launch is waited for, so the picture shows it.
        let measuring = self.runtime.effect_costs.is_running();
        if self.runtime.frames_run >= frames && !measuring && !self.runtime.screenshot_requested {
            self.runtime.screenshot_requested = true;
            let done = self.runtime.screenshot_done.clone();
            ctx.request_screenshot(move |image| {
                let result = write_png(&image, &path);
                if let Ok(mut d) = done.lock() {
                    *d = Some(result);
                }
            });
        }
        ctx.request_repaint();
    }
}

/// Writes `state` into `to` (positions, velocities and time: exactly, bit for bit).
pub fn hand_over(state: &ClothState, to: &mut dyn Simulator) -> Result<(), SimError> {
    to.write_state(state)
}

/// Largest cloth whose self-intersections the inspector counts at every sample (512²): the count
/// runs on the UI thread, in time proportional to the vertices.
pub const MAX_COUNTED_VERTICES: usize = 512 * 512;

/// The inspector runs a frame at a time for as long as it is open: one frame of `scene` must be
/// work `backend` finishes in minutes (its work budget), or the window would stop answering.
///
/// # Errors
/// The budget's problem, as an invalid scene.
pub fn one_frame_fits(scene: &Scene, backend: &str) -> Result<(), SimError> {
    cloth_core::budget::WorkBudget::for_backend(backend)
        .check(scene, 1)
        .map(|_| ())
        .map_err(|p| SimError::Scene(cloth_core::SceneError::Invalid(vec![p])))
}

/// Writes the window's image as a PNG, whole or not at all (a temporary file renamed into place).
fn write_png(image: &egui::ColorImage, path: &Path) -> Result<(), String> {
    let [w, h] = image.size;
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, w as u32, h as u32);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    let pixels: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    writer.write_image_data(&pixels).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())?;
    cloth_backends::output::write_atomically(path, &bytes).map_err(|e| e.to_string())
}

/// Writes a scene whole or not at all, so a crash never leaves a half-written file.
pub fn save_atomically(scene: &Scene, path: &Path) -> std::io::Result<()> {
    cloth_backends::output::write_atomically(path, scene.to_ron_string().as_bytes())
}

impl eframe::App for InspectorApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        // Simulate.
        if self.state.playing {
            self.runtime.frame_accumulator += self.state.speed;
            let n = self.runtime.frame_accumulator.floor() as u32;
            self.runtime.frame_accumulator -= n as f32;
            self.advance(n);
            ctx.request_repaint();
        }
        let current = self.state.backend.clone();
        // The adapter, and how many substeps each dispatch advances where the backend fuses them,
        // or that it runs them on the packed state.
        let adapter = self
            .runtime
            .sim
            .as_mut()
            .map(|s| {
                let sim = s.get();
                match (sim.fused_substeps(), sim.substep_state_bytes()) {
                    (1, Some(24)) => format!("{} · packed state, 24 bytes a vertex", sim.adapter_name()),
                    (1, _) => sim.adapter_name(),
                    (n, _) => format!("{} · tiled kernel, {n} substeps per dispatch", sim.adapter_name()),
                }
            })
            .unwrap_or_default();
        egui::Panel::left("controls").resizable(true).default_size(340.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                let mut ctx_panel = PanelContext {
                    scene: &mut self.state.scene,
                    problems: &self.runtime.problems,
                    commands: &mut self.runtime.commands,
                };
                egui::CollapsingHeader::new("Scene").default_open(true).show(ui, |ui| {
                    panels::scene::show(ui, &mut ctx_panel, self.state.scene_path.as_deref(), &mut self.runtime.browser)
                });
                egui::CollapsingHeader::new("Backend").default_open(true).show(ui, |ui| {
                    panels::backend::show(ui, &self.runtime.backends, &current, &adapter, ctx_panel.commands)
                });
                if current == "wgpu" || current == "vulkano" {
                    let (draft, running) = (&mut self.runtime.tuning_draft, &self.runtime.tuning);
                    egui::CollapsingHeader::new("GPU tuning")
                        .show(ui, |ui| panels::tuning::show(ui, draft, running, ctx_panel.commands));
                }
                egui::CollapsingHeader::new("Time").default_open(true).show(ui, |ui| {
                    panels::time::show(ui, &mut ctx_panel, &mut self.state.playing, &mut self.state.speed)
                });
                egui::CollapsingHeader::new("Cloth").show(ui, |ui| panels::cloth::show(ui, &mut ctx_panel));
                egui::CollapsingHeader::new("Springs").show(ui, |ui| panels::springs::show(ui, &mut ctx_panel));
                egui::CollapsingHeader::new("Contact")
                    .show(ui, |ui| panels::contact::show(ui, &mut ctx_panel, &mut self.runtime.dragged_collider));
                egui::CollapsingHeader::new("Effects").show(ui, |ui| panels::effects::show(ui, &mut ctx_panel));
                egui::CollapsingHeader::new("View").default_open(true).show(ui, |ui| {
                    ui.horizontal_wrapped(|ui| {
                        for (mode, label) in [
                            (ColorMode::Plain, "plain"),
                            (ColorMode::Strain(SpringKind::Structural), "strain: structural"),
                            (ColorMode::Strain(SpringKind::Shear), "shear"),
                            (ColorMode::Strain(SpringKind::Bend), "bend"),
                            (ColorMode::Contact, "contact"),
                            (ColorMode::Speed, "speed"),
                        ] {
                            ui.selectable_value(&mut self.state.color_mode, mode, label);
                        }
                    });
                    ui.checkbox(&mut self.state.wireframe, "wireframe");
                });
            });
        });
        egui::Panel::right("stats").resizable(true).default_size(300.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                ui.heading("Stats");
                if let Some(sim) = self.runtime.sim.as_ref() {
                    panels::stats::show(ui, &self.runtime.stats, sim.scene());
                }
                let backend = self.runtime.sim.as_ref().map(Sim::backend_name).unwrap_or("cpu");
                if let Some(sim) = self.runtime.sim.as_ref() {
                    egui::CollapsingHeader::new("Cost of each effect")
                        .default_open(true)
                        .show(ui, |ui| self.runtime.effect_costs.show(ui, sim.scene(), backend, &self.runtime.tuning));
                }
                let mut header = egui::CollapsingHeader::new("Frame profile");
                if std::mem::take(&mut self.runtime.profile_fresh) {
                    header = header.open(Some(true));
                }
                header.show(ui, |ui| {
                    panels::profile::show(ui, self.runtime.profile.as_ref(), backend, &mut self.runtime.commands)
                });
                egui::CollapsingHeader::new("Accuracy study")
                    .show(ui, |ui| self.runtime.study.show(ui, &self.state.scene, backend, &self.runtime.tuning));
                egui::CollapsingHeader::new("Export")
                    .show(ui, |ui| self.runtime.export.show(ui, &self.state.scene, backend, &self.runtime.tuning));
            });
        });
        if !self.runtime.notices.is_empty() {
            egui::Panel::bottom("notices").show(ui, |ui| {
                let mut clear = false;
                for n in self.runtime.notices.iter().rev().take(4) {
                    ui.colored_label(egui::Color32::from_rgb(200, 80, 20), n);
                }
                if ui.small_button("dismiss").clicked() {
                    clear = true;
                }
                if clear {
                    self.runtime.notices.clear();
                }
            });
        }
        egui::CentralPanel::default().show(ui, |ui| self.view(ui));
        panels::scene::browser_window(&ctx, &mut self.runtime.browser, &mut self.runtime.commands);
        self.handle_close(&ctx);
        // Apply what the panels asked for, after the frame.
        self.apply_edits();
        for command in std::mem::take(&mut self.runtime.commands) {
            self.apply(command);
        }
        self.headless_step(&ctx);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        if self.runtime.screenshot.is_none() {
            eframe::set_value(storage, eframe::APP_KEY, &self.state);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scene_whose_one_frame_exceeds_the_budget_is_not_started() {
        let mut scene = Scene::default();
        scene.cloth.resolution = [2048, 2048];
        scene.time.substeps = cloth_core::Substeps::Fixed(100_000);
        // 4.2e11 vertex-substeps a frame: beyond the CPU's 1e11, within a GPU's 1e13.
        let e = one_frame_fits(&scene, "cpu").unwrap_err().to_string();
        assert!(e.contains("one frame alone is 4.194e11 vertex-substeps"), "{e}");
        assert!(one_frame_fits(&scene, "vulkano").is_ok());
        assert!(one_frame_fits(&Scene::default(), "cpu").is_ok());
    }

    #[test]
    fn saving_replaces_the_file_whole_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("cloth-inspector-save-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("scene.ron");
        std::fs::write(&path, "old contents").unwrap();
        let scene = Scene { name: "saved".into(), ..Default::default() };
        save_atomically(&scene, &path).unwrap();
        assert_eq!(Scene::load(&path).unwrap(), scene);
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["scene.ron"], "no temporary file is left");
        std::fs::remove_dir_all(dir).unwrap();
    }

    /// The handover used when switching backends preserves the state exactly, across every
    /// backend that can start here, and the motion continues from it.
    #[test]
    fn handover_between_backends_preserves_the_state_exactly() {
        let mut scene = Scene::default();
        scene.cloth.resolution = [12, 9];
        let mut from: Box<dyn Simulator> = Box::new(CpuSimulator::new(&scene).unwrap());
        from.advance(20).unwrap();
        for name in ["wgpu", "vulkano", "cpu", "cpu-f64", "cpu"] {
            let state = from.read_state().unwrap();
            let backend = cloth_backends::find(name).unwrap();
            let mut to = match (backend.create)(&scene, &GpuTuning::default()) {
                Ok(sim) => sim,
                Err(SimError::Unavailable { reason, .. }) if std::env::var_os("CI").is_none() => {
                    eprintln!("SKIPPED handover to {name}: {reason}");
                    continue;
                }
                Err(e) => panic!("{name}: {e}"),
            };
            hand_over(&state, to.as_mut()).unwrap();
            let back = to.read_state().unwrap();
            assert_eq!(back, state, "handover to {name} changed the state");
            to.advance(2).unwrap();
            let after = to.read_state().unwrap();
            assert!(
                after.time_s > state.time_s && after.centroid()[1] < state.centroid()[1],
                "{name} continues the fall"
            );
            from = to;
        }
    }
}
