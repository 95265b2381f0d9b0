//! `cloth-inspector`: see the cloth, edit every parameter live, switch backends at runtime.
//!
//! `cloth-inspector --scene FILE --backend NAME --frames N --screenshot OUT.png` runs without
//! user input and writes the window's image.

mod app;
mod commands;
mod panels;
mod render;
mod state;
mod stats;
mod study;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Result, anyhow, bail};
use clap::Parser;

#[derive(Parser)]
#[command(name = "cloth-inspector", version, about = "Interactive inspector of the cloth simulation")]
struct Args {
    /// RON scene to open (default: the scene of the last session, or the drape scene).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Backend to start on: cpu, cpu-f64, wgpu or vulkano.
    #[arg(long)]
    backend: Option<String>,
    /// With --screenshot: frames to simulate before taking it.
    #[arg(long, default_value_t = 120)]
    frames: u32,
    /// Simulate, write the window's image to this PNG, and quit (no user input needed).
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Colour the cloth by: plain, strain (structural), shear, bend, contact or speed.
    #[arg(long, value_parser = cloth_view::ColorMode::NAMES)]
    color: Option<String>,
    /// Measure what each effect of the scene costs on the backend at start (the stats panel shows
    /// it; with --screenshot the run waits for it and prints it).
    #[arg(long)]
    measure_effects: bool,
    /// With --screenshot: profile the last frame on a GPU backend (the stats panel shows it, and
    /// the run prints it).
    #[arg(long)]
    profile_frame: bool,
}

/// Runs the inspector; an error ends it with its message and exit code 1 (a headless run also
/// when its screenshot could not be written).
fn main() -> std::process::ExitCode {
    if let Some(dir) = cloth_backends::private_runtime_dir(std::env::var_os("XDG_RUNTIME_DIR").as_deref()) {
        // SAFETY: at start-up, before any thread is spawned.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", dir) };
    }
    let failed = Arc::new(AtomicBool::new(false));
    match inspect(Args::parse(), failed.clone()) {
        Ok(()) if !failed.load(Ordering::SeqCst) => std::process::ExitCode::SUCCESS,
        Ok(()) => std::process::ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn inspect(args: Args, headless_failed: Arc<AtomicBool>) -> Result<()> {
    if let Some(path) = &args.screenshot {
        // The headless run's frames, within the work budget of the backend it runs on, and its
        // picture's path, checked before anything runs.
        let scene = match &args.scene {
            Some(path) => cloth_core::Scene::load(path).map_err(|e| anyhow!("{}: {e}", path.display()))?,
            None => cloth_core::Scene::default(),
        };
        let budget = cloth_core::budget::WorkBudget::for_backend(args.backend.as_deref().unwrap_or("cpu"));
        budget.check(&scene, args.frames).map_err(|p| anyhow!("--{p}"))?;
        cloth_backends::output::check_writable(path)?;
    }
    if std::env::var_os("DISPLAY").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        bail!(
            "no display (neither DISPLAY nor WAYLAND_DISPLAY is set): run it on a desktop, under Xvfb \
             (xvfb-run -a cloth-inspector ...), or use the headless `cloth run --png` instead"
        );
    }
    if let Some(b) = &args.backend {
        cloth_backends::find(b).map_err(|e| anyhow!(e))?;
    }
    let options = app::LaunchOptions {
        scene: args.scene,
        backend: args.backend,
        screenshot: args.screenshot.map(|p| (args.frames, p)),
        color: args.color.and_then(|c| cloth_view::ColorMode::from_name(&c)),
        measure_effects: args.measure_effects,
        profile_frame: args.profile_frame,
        headless_failed,
    };
    let native = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_inner_size([1280.0, 800.0])
            .with_title("Cloth inspector"),
        persist_window: options.screenshot.is_none(),
        wgpu_options: wgpu_options(),
        ..Default::default()
    };
    eframe::run_native("cloth-inspector", native, Box::new(move |cc| Ok(Box::new(app::InspectorApp::new(cc, options)))))
        .map_err(|e| anyhow!("the inspector window failed: {e}"))
}

/// eframe's device, opened with what the wgpu simulator needs (it runs on the same device and
/// draws from its buffers without a copy) as well as what the drawing needs.
fn wgpu_options() -> eframe::egui_wgpu::WgpuConfiguration {
    use eframe::egui_wgpu::{WgpuConfiguration, WgpuSetup, WgpuSetupCreateNew};
    let mut setup = WgpuSetupCreateNew::without_display_handle();
    let drawing = setup.device_descriptor.clone();
    setup.device_descriptor = std::sync::Arc::new(move |adapter| {
        let base = drawing(adapter);
        let (features, limits) = cloth_wgpu::device_requirements(adapter);
        eframe::wgpu::DeviceDescriptor {
            required_features: base.required_features | features,
            required_limits: eframe::wgpu::Limits {
                max_texture_dimension_2d: base.required_limits.max_texture_dimension_2d,
                ..limits
            },
            ..base
        }
    });
    WgpuConfiguration { wgpu_setup: WgpuSetup::CreateNew(setup), ..Default::default() }
}
