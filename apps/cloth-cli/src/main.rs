//! `cloth`: the headless command-line front end of the cloth workbench.
//!
//! * `cloth run [SCENE]`: simulate and summarise (text or `--json`), optionally render a PNG and
//!   write the final mesh as an OBJ;
//! * `cloth check SCENE`: validate, and print spring counts, memory and the stable substep;
//! * `cloth backends`: the backends compiled in and the adapters each can use;
//! * `cloth bench`: ms per frame and vertex-substeps per second of each backend;
//! * `cloth profile [SCENE]`: where a GPU frame's time goes, pass by pass;
//! * `cloth study accuracy`: what accuracy costs in time;
//! * `cloth view FILE.glb`: a run exported as glTF read back, and a kept frame drawn;
//! * `cloth figure`: the pictures of docs/model.md.

/// Writes a line to standard output and returns the error instead of panicking on it (a full
/// disk, a closed pipe): `out!(...)?`.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout(), $($arg)*)
            .map_err(|e| std::io::Error::new(e.kind(), format!("cannot write to standard output: {e}")))
    }};
}

mod bench;
mod figure;
mod picture;
mod profile;
mod render;
mod report;
mod study;
mod tuning;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use cloth_backends as backends;
use cloth_core::budget::{WorkBudget, WorkPlan};
use cloth_core::{ClothModel, Energy, Integrator, Scene, Substeps, intersections, stability};
use cloth_gpu::memory::MemoryEstimate;
use indicatif::{ProgressBar, ProgressStyle};

#[derive(Parser)]
#[command(name = "cloth", version, about = "Mass-spring cloth simulation workbench (headless)")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scene and print a summary.
    Run(RunArgs),
    /// Validate a scene and print its spring counts, memory and stability bound.
    Check {
        /// RON scene file.
        scene: PathBuf,
        /// Override the grid resolution, e.g. 64x48.
        #[arg(long, value_parser = parse_grid)]
        grid: Option<[u32; 2]>,
        /// Override the substeps per frame (a number, or `auto`).
        #[arg(long, value_parser = parse_substeps)]
        substeps: Option<Substeps>,
        /// The backend whose work budget to check the scene's run against.
        #[arg(long, default_value = "cpu")]
        backend: String,
    },
    /// List the backends compiled in and the adapters each can use.
    Backends,
    /// Measure ms per frame and vertex-substeps per second of each backend (prints a table).
    Bench(bench::BenchArgs),
    /// Where a GPU frame's time goes: each pass's dispatches and GPU time (a timestamp after
    /// every dispatch).
    Profile(profile::ProfileArgs),
    /// Studies (`cloth study accuracy`).
    #[command(subcommand)]
    Study(StudyCommand),
    /// Read back a run exported to a .glb file: print what it holds, and draw a kept frame.
    View(ViewArgs),
    /// Draw a picture of the model (docs/model.md's figures) as SVG.
    Figure {
        /// Which picture: the 12-spring stencil, or the friction decomposition.
        #[arg(value_enum)]
        figure: figure::Figure,
        /// The SVG file to write.
        out: PathBuf,
    },
}

#[derive(Subcommand)]
enum StudyCommand {
    /// What accuracy costs in time: integrator × substeps against an f64 RK4 reference.
    Accuracy(study::AccuracyArgs),
}

#[derive(clap::Args)]
struct RunArgs {
    /// RON scene file (default: the built-in drape scene, as in scenes/drape.ron).
    scene: Option<PathBuf>,
    /// Backend to run on (see `cloth backends`).
    #[arg(long, default_value = "cpu")]
    backend: String,
    #[command(flatten)]
    tuning: tuning::TuningArgs,
    /// Frames to simulate, at least 1 (default: the scene's `time.frames`).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    frames: Option<u32>,
    /// Grid resolution NXxNY, e.g. 64x48 (vertices along each side).
    #[arg(long, value_parser = parse_grid)]
    grid: Option<[u32; 2]>,
    /// Substeps per frame (a number, or `auto`).
    #[arg(long, value_parser = parse_substeps)]
    substeps: Option<Substeps>,
    /// Time integrator instead of the scene's: euler, verlet, rk4, xpbd, backward-euler or vbd
    /// (the implicit ones take their iterations from the scene's `solver` field).
    #[arg(long, value_parser = parse_integrator)]
    integrator: Option<Integrator>,
    /// The implicit integrators' solver settings instead of the scene's, written as the scene's
    /// `solver` field, e.g. '(newton_iterations: 8)' (fields left out take their defaults; see
    /// docs/model.md).
    #[arg(long, value_parser = parse_solver)]
    solver: Option<cloth_core::solver::SolverSpec>,
    /// Print one JSON object instead of the text summary.
    #[arg(long)]
    json: bool,
    /// Draw the final state into this PNG file, with the inspector's renderer (offscreen, on the
    /// first Vulkan device; the CPU rasteriser where there is none, and the run says so).
    #[arg(long)]
    png: Option<PathBuf>,
    /// Draw the run as an animated GIF into this file: about 40 pictures over the run, played at
    /// the simulated pace.
    #[arg(long)]
    gif: Option<PathBuf>,
    /// Colour of the cloth in the pictures: plain, strain (structural), shear, bend, contact or
    /// speed.
    #[arg(long, default_value = "plain", value_parser = cloth_view::ColorMode::NAMES)]
    color: String,
    /// Write the final cloth mesh to this Wavefront OBJ file (vertices, normals, two triangles a
    /// cell; no collider).
    #[arg(long)]
    obj: Option<PathBuf>,
    /// Export the run: to FILE.glb, one binary glTF 2.0 file (the cloth, its motion as an
    /// animation on the simulated clock, every collider); to DIR/ (a folder, created if missing),
    /// one OBJ per kept frame, the colliders' OBJ and a CSV of the per-frame diagnostics.
    #[arg(long, value_name = "FILE.glb|DIR/")]
    export: Option<PathBuf>,
    /// Keep every Nth frame in the export (the start is always kept).
    #[arg(long, default_value_t = 1, value_name = "N", requires = "export")]
    every: u32,
    /// Count the cloth's self-intersections every N frames (1: every frame; 0: the final state
    /// only). Each count reads the positions back and, on two CPU cores, takes about as long as
    /// a CPU frame of 16 to 30 substeps: on large grids a larger N keeps the run fast, and the
    /// reported maxima (the crossings, the total energy) are then over the frames read back.
    #[arg(long, default_value_t = 1)]
    count_every: u32,
}

#[derive(clap::Args)]
struct ViewArgs {
    /// A .glb file written by `cloth run --export`.
    file: PathBuf,
    /// The kept frame to draw (0: the start; default: the last).
    #[arg(long)]
    frame: Option<usize>,
    /// Draw the frame into this PNG file, with the inspector's renderer.
    #[arg(long)]
    png: Option<PathBuf>,
    /// Colour of the cloth: plain, strain (structural), shear, bend, contact or speed (the speed
    /// from the kept frames' differences).
    #[arg(long, default_value = "plain", value_parser = cloth_view::ColorMode::NAMES)]
    color: String,
}

/// `cloth view`: the export read back ([`cloth_export::read`]) and drawn as `cloth run` draws.
fn view(args: ViewArgs) -> Result<()> {
    if let Some(png) = &args.png {
        backends::output::check_writable(png)?;
    }
    let run = cloth_export::read::read_glb(&args.file)?;
    let scene = &run.scene;
    let [nx, ny] = scene.cloth.resolution;
    let last = run.frames.len() - 1;
    let (first, end) = (run.frames[0].0, run.frames[last].0);
    out!("scene       {} ({nx} x {ny} vertices), run on {}", scene.name, run.backend)?;
    out!("frames      {} kept, t = {first:.4} to {end:.4} s", run.frames.len())?;
    let k = args.frame.unwrap_or(last);
    if k > last {
        bail!("--frame {k}: the export keeps frames 0 to {last}");
    }
    let (time_s, positions) = run.frames[k].clone();
    // Velocities from the kept frames around it (what the speed and contact colours read).
    let velocities = match (k.checked_sub(1).map(|j| &run.frames[j]), run.frames.get(k + 1)) {
        (Some((t0, x0)), _) | (None, Some((t0, x0))) if *t0 != time_s => {
            let dt = (time_s - t0) as f32;
            positions.iter().zip(x0).map(|(x, y)| [0, 1, 2].map(|c| (x[c] - y[c]) / dt)).collect()
        }
        _ => vec![[0.0; 3]; positions.len()],
    };
    let state = cloth_core::ClothState { time_s, positions, velocities };
    let crossings = intersections::count(&state.positions, nx, ny).ok();
    out!(
        "frame       {k} at t = {time_s:.4} s: centroid {:.4?} m; {} edge-triangle crossings of the cloth through itself",
        state.centroid(),
        crossings.map_or("uncounted".to_string(), |c| c.to_string())
    )?;
    if let Some(png) = &args.png {
        let color = cloth_view::ColorMode::from_name(&args.color).expect("clap checks the name");
        let mut painter = picture::Painter::new();
        let size = [800, 600];
        let pixels = painter.draw(&ClothModel::new(scene), &state, color, size)?;
        backends::output::write_atomically(
            png,
            &picture::encode_png(&pixels, size[0], size[1], png::ColorType::Rgba)?,
        )?;
        out!("picture     {} (drawn by {})", png.display(), painter.description())?;
    }
    Ok(())
}

pub(crate) fn parse_grid(text: &str) -> Result<[u32; 2], String> {
    let (a, b) = text.split_once(['x', 'X']).ok_or_else(|| format!("'{text}' is not NXxNY (e.g. 64x48)"))?;
    let n =
        |s: &str| s.trim().parse::<u32>().map_err(|e| format!("'{s}' in '{text}': {e} (expected NXxNY, e.g. 64x48)"));
    Ok([n(a)?, n(b)?])
}

fn parse_substeps(text: &str) -> Result<Substeps, String> {
    if text.eq_ignore_ascii_case("auto") {
        return Ok(Substeps::Auto);
    }
    text.parse::<u32>().map(Substeps::Fixed).map_err(|e| format!("'{text}': {e} (expected a number or 'auto')"))
}

pub(crate) fn parse_integrator(text: &str) -> Result<Integrator, String> {
    Integrator::from_name(text).ok_or_else(|| {
        let all: Vec<&str> = Integrator::ALL.iter().map(|i| i.name()).collect();
        format!("unknown integrator '{text}': choose among {}", all.join(", "))
    })
}

pub(crate) fn parse_solver(text: &str) -> Result<cloth_core::solver::SolverSpec, String> {
    cloth_core::solver::SolverSpec::from_ron_str(text).map_err(|e| {
        format!(
            "'{text}': {e} (expected the scene's solver field, e.g. '(newton_iterations: 8, cg_max_iterations: 300)')"
        )
    })
}

fn load_scene(path: Option<&PathBuf>, grid: Option<[u32; 2]>, substeps: Option<Substeps>) -> Result<Scene> {
    load_scene_with(path, grid, substeps, None, None)
}

fn load_scene_with(
    path: Option<&PathBuf>,
    grid: Option<[u32; 2]>,
    substeps: Option<Substeps>,
    integrator: Option<Integrator>,
    solver: Option<cloth_core::solver::SolverSpec>,
) -> Result<Scene> {
    let mut scene = match path {
        Some(p) => Scene::load(p).with_context(|| format!("cannot use scene {}", p.display()))?,
        None => Scene::default(),
    };
    if let Some(g) = grid {
        scene.cloth.resolution = g;
    }
    if let Some(s) = substeps {
        scene.time.substeps = s;
    }
    if let Some(i) = integrator {
        scene.integrator = i;
    }
    if let Some(s) = solver {
        scene.solver = s;
    }
    let warnings = scene.validate().context("the scene with the command-line overrides is invalid")?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// Runs the command; an error ends it with its message and exit code 1, and a closed standard
/// output (`cloth ... | head`) ends it quietly, as Unix tools end (exit code 141, SIGPIPE's).
fn main() -> std::process::ExitCode {
    if let Some(dir) = backends::private_runtime_dir(std::env::var_os("XDG_RUNTIME_DIR").as_deref()) {
        // SAFETY: at start-up, before any thread is spawned.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", dir) };
    }
    match command(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if e.downcast_ref::<std::io::Error>().is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe) => {
            std::process::ExitCode::from(141)
        }
        Err(e) if e.downcast_ref::<Unstable>().is_some() => {
            eprintln!("{e}");
            std::process::ExitCode::from(3)
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// `cloth check` of a valid scene whose substep exceeds the stable bound: exit code 3 (1 is an
/// invalid scene or another error, 2 a command line that cannot be parsed).
#[derive(Debug, thiserror::Error)]
#[error("unstable: the substep is {margin:.2} times the largest stable substep; raise the substeps")]
struct Unstable {
    margin: f64,
}

fn command(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run(args) => run(args),
        Command::Check { scene, grid, substeps, backend } => check(&scene, grid, substeps, &backend),
        Command::Bench(args) => bench::run(args),
        Command::Profile(args) => profile::run(args),
        Command::View(args) => view(args),
        Command::Study(StudyCommand::Accuracy(args)) => study::accuracy(args),
        Command::Figure { figure, out } => {
            figure::write(figure, &out)?;
            out!("wrote {}", out.display())?;
            Ok(())
        }
        Command::Backends => {
            for b in backends::all() {
                out!("{:<8} {}", b.name, b.description)?;
                match (b.adapters)() {
                    Ok(list) if !list.is_empty() => list.iter().try_for_each(|a| out!("         - {a}")),
                    Ok(_) => out!("         (no adapter found)"),
                    Err(why) => out!("         unavailable: {why}"),
                }?;
            }
            Ok(())
        }
    }
}

/// What `cloth check` checks, decided before anything is built: the scene with its overrides,
/// the backend whose budget it is checked against, and the work of the scene's own frames.
fn plan_check(
    path: &PathBuf,
    grid: Option<[u32; 2]>,
    substeps: Option<Substeps>,
    backend: &str,
) -> Result<(Scene, backends::Backend, WorkPlan)> {
    let scene = load_scene(Some(path), grid, substeps)?;
    let backend = backends::find(backend).map_err(anyhow::Error::msg)?;
    let mut plan = WorkPlan::default();
    plan.add(backend.name, &scene, scene.time.frames).map_err(|p| anyhow::anyhow!("time.{p}"))?;
    Ok((scene, backend, plan))
}

fn check(path: &PathBuf, grid: Option<[u32; 2]>, substeps: Option<Substeps>, backend: &str) -> Result<()> {
    let (scene, backend, plan) = plan_check(path, grid, substeps, backend)?;
    let budget = WorkBudget::for_backend(backend.name);
    let work = plan.runs.iter().map(|r| r.3).sum::<u64>();
    let [nx, ny] = scene.cloth.resolution;
    let model = ClothModel::new(&scene);
    let [st, sh, be] = model.spring_counts();
    let memory = MemoryEstimate::of(&scene);
    let bound = stability::stable_substep(&scene);
    out!("scene      {} — {}", scene.name, scene.description)?;
    out!("grid       {nx} x {ny} = {} vertices", scene.vertex_count())?;
    out!("springs    {st} structural, {sh} shear, {be} bend ({} in all)", st + sh + be)?;
    out!("effects    {:?}", scene.effects)?;
    out!("mass       {:.4e} kg per vertex", scene.vertex_mass())?;
    out!(
        "memory     {:.2} MiB on the device ({:.2} MiB largest buffer)",
        mib(memory.device_bytes),
        mib(memory.largest_buffer_bytes)
    )?;
    out!(
        "substep    {:.3e} s ({} per frame of {:.4} s)",
        scene.substep_dt(),
        scene.substeps_per_frame(),
        scene.time.frame_dt
    )?;
    if bound.is_finite() {
        out!(
            "stability  largest stable substep {bound:.3e} s; margin {:.2} ({})",
            scene.substep_dt() / bound,
            if scene.substep_dt() <= bound { "stable" } else { "UNSTABLE: raise the substeps" }
        )?;
    } else {
        out!("stability  no bound: nothing in the scene (springs, contact, damping) limits the substep")?;
    }
    if scene.effects.contains(cloth_core::Effect::SelfCollision) {
        let q = cloth_core::self_collision::SelfCollisionQuantities::of(&scene);
        out!(
            "self       thickness {:.3e} m, margin {:.3e} m; on the GPU the candidate lists are checked every {} \
             substep(s), with a lookahead of {:.3e} m",
            q.thickness,
            q.margin,
            q.check_interval,
            q.lookahead
        )?;
        if q.every_check_rebuilds() {
            out!(
                "           every check rebuilds the lists, a rebuild a substep: the lookahead reaches the margin; \
                 a margin (self_collision.margin) above {:.3e} m, or a lower max_speed, leaves the cloth room to move",
                q.lookahead
            )?;
        }
    }
    out!(
        "work       {} frames are {work:.3e} vertex-substeps of the {:.0e} one command may run on {}",
        scene.time.frames,
        budget.max_vertex_substeps as f64,
        backend.name
    )?;
    if scene.substep_dt() > bound {
        return Err(Unstable { margin: scene.substep_dt() / bound }.into());
    }
    out!("ok")?;
    Ok(())
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1 << 20) as f64
}

/// What `cloth run` will simulate, decided before anything starts: the scene with its
/// overrides, the backend, the frames, their work within the backend's budget, and the export.
struct RunPlan {
    scene: Scene,
    backend: backends::Backend,
    frames: u32,
    /// Checked against the budgets when planned; the property test reads it back.
    #[cfg_attr(not(test), expect(dead_code, reason = "the run needs only the check"))]
    work: WorkPlan,
    export: Option<cloth_export::ExportPlan>,
}

fn plan_run(args: &RunArgs) -> Result<RunPlan> {
    let scene = load_scene_with(args.scene.as_ref(), args.grid, args.substeps, args.integrator, args.solver)?;
    let backend = backends::find(&args.backend).map_err(anyhow::Error::msg)?;
    let frames = args.frames.unwrap_or(scene.time.frames);
    let mut plan = WorkPlan::default();
    plan.add(backend.name, &scene, frames).map_err(|p| anyhow::anyhow!("--{p}"))?;
    // Checked before the run: the target, and that the run fits the format.
    let export =
        args.export.as_ref().map(|path| cloth_export::ExportPlan::new(path, &scene, frames, args.every)).transpose()?;
    Ok(RunPlan { scene, backend, frames, work: plan, export })
}

fn run(args: RunArgs) -> Result<()> {
    let RunPlan { scene, backend, frames, export, .. } = plan_run(&args)?;
    for path in [&args.png, &args.obj, &args.gif].into_iter().flatten() {
        backends::output::check_writable(path)?;
    }
    let color = cloth_view::ColorMode::from_name(&args.color).expect("clap checks the name");
    let mut painter = (args.png.is_some() || args.gif.is_some()).then(picture::Painter::new);
    // The GIF's pictures: about 40 over the run, the start included.
    let gif_every = (frames / 40).max(1);
    let (gif_size, mut gif_frames) = ([480, 360], Vec::new());
    let model = ClothModel::new(&scene);
    let mut sim = (backend.create)(&scene, &args.tuning.tuning())
        .with_context(|| format!("cannot start the {} backend", backend.name))?;

    let progress = if args.json || frames < 30 { ProgressBar::hidden() } else { ProgressBar::new(frames as u64) };
    progress.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} frames ({per_sec}, eta {eta})")
            .expect("progress template is valid")
            .progress_chars("=> "),
    );
    progress.set_message(format!("{} on {}", scene.name, sim.backend_name()));
    let mut exporter = match &export {
        Some(plan) => Some(cloth_export::Exporter::start(plan, &scene, &sim.read_state()?, sim.backend_name())?),
        None => None,
    };
    let initial_energy = Energy::of(&model, &sim.read_state()?).total();
    let mut energies = report::EnergyExtremes { initial_j: initial_energy, peak_j: initial_energy };
    let (mut exporting, mut exported) = (std::time::Duration::ZERO, None);
    let mut drawing = std::time::Duration::ZERO;
    let start = Instant::now();
    let mut counts = cloth_core::AdvanceCounts::default();
    let [nx, ny] = scene.cloth.resolution;
    let (mut most_crossings, mut counting) = (Some(0), std::time::Duration::ZERO);
    for done in 0..frames {
        sim.advance(1).with_context(|| format!("the {} backend failed at frame {done}", backend.name))?;
        let c = sim.last_advance_counts();
        counts.frames += c.frames;
        counts.submissions += c.submissions;
        counts.host_waits += c.host_waits;
        // One read-back serves the frame's count, picture and export. The count's read-back is
        // part of the simulation's time, as the report says; the counting, the drawing and the
        // export's writing are not (nor a read-back only they need).
        let counted = args.count_every > 0 && (done + 1) % args.count_every == 0;
        let drawn = args.gif.is_some() && (done + 1) % gif_every == 0;
        let kept = export.as_ref().is_some_and(|plan| plan.keeps(done + 1));
        if !(counted || drawn || kept) {
            progress.set_position(done as u64 + 1);
            continue;
        }
        let t = Instant::now();
        let state = sim.read_state()?;
        match (counted, kept) {
            (true, _) => {}
            (false, true) => exporting += t.elapsed(),
            (false, false) => drawing += t.elapsed(),
        }
        let t = Instant::now();
        energies.peak_j = energies.peak_j.max(Energy::of(&model, &state).total());
        counting += t.elapsed();
        if counted {
            let t = Instant::now();
            // A frame that cannot be counted leaves the maximum over the frames unknown.
            let crossings = intersections::count(&state.positions, nx, ny).ok();
            most_crossings = most_crossings.zip(crossings).map(|(a, b)| a.max(b));
            counting += t.elapsed();
        }
        if let (Some(painter), true) = (&mut painter, drawn) {
            let t = Instant::now();
            gif_frames.push(painter.draw(&model, &state, color, gif_size)?);
            drawing += t.elapsed();
        }
        if let (Some(exporter), true) = (&mut exporter, kept) {
            let t = Instant::now();
            exporter.record(&state)?;
            exporting += t.elapsed();
        }
        progress.set_position(done as u64 + 1);
    }
    if let Some(exporter) = exporter {
        let t = Instant::now();
        exported = Some(exporter.finish()?);
        exporting += t.elapsed();
    }
    let state = sim.read_state()?;
    let wall = start.elapsed().saturating_sub(counting).saturating_sub(exporting).saturating_sub(drawing);
    progress.finish_and_clear();
    let at_end = intersections::count(&state.positions, nx, ny).ok();
    let self_intersections =
        report::SelfIntersections { at_end, max: most_crossings.zip(at_end).map(|(a, b)| a.max(b)) };
    let diagnostics = sim.diagnostics()?;
    let energy = Energy::of(&model, &state);
    energies.peak_j = energies.peak_j.max(energy.total());
    let measured = report::Measured {
        state: &state,
        diagnostics: &diagnostics,
        counts: &counts,
        energy: &energy,
        frames,
        wall,
        self_intersections,
        energies,
    };
    let mut report = report::Report::new(&*sim, &model, &measured);
    report.export = exported.as_ref().map(|summary| report::Export {
        path: summary.path.display().to_string(),
        frames: summary.frames,
        bytes: summary.bytes,
        seconds: exporting.as_secs_f64(),
    });
    if args.json {
        out!("{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        report.print_text()?;
    }
    if let (Some(painter), Some(png)) = (&mut painter, &args.png) {
        let size = [800, 600];
        let pixels = painter.draw(&model, &state, color, size)?;
        backends::output::write_atomically(
            png,
            &picture::encode_png(&pixels, size[0], size[1], png::ColorType::Rgba)?,
        )?;
        if !args.json {
            out!("picture     {} (drawn by {})", png.display(), painter.description())?;
        }
    }
    if let (Some(painter), Some(gif)) = (&painter, &args.gif) {
        let delay = f64::from(gif_every) * scene.time.frame_dt;
        picture::write_gif(gif, &gif_frames, gif_size, delay)?;
        if !args.json {
            out!("animation   {} ({} pictures, drawn by {})", gif.display(), gif_frames.len(), painter.description())?;
        }
    }
    if let Some(obj) = &args.obj {
        let comment = format!(
            "cloth '{}': {nx} x {ny} vertices at t = {:.4} s on {}, m\ntwo triangles a cell, split along (i, j)-(i+1, j+1)",
            scene.name,
            state.time_s,
            sim.backend_name()
        );
        backends::output::write_atomically(
            obj,
            cloth_core::export::wavefront_obj(&state.positions, nx, ny, &comment).as_bytes(),
        )?;
        if !args.json {
            out!("mesh        {}", obj.display())?;
        }
    }
    if let Some(export) = &report.export
        && !args.json
    {
        out!(
            "export      {} ({} frames, {:.1} MiB, written in {:.2} s)",
            export.path,
            export.frames,
            mib(export.bytes),
            export.seconds
        )?;
    }
    if report.nan_count > 0 {
        bail!(
            "{} vertices became NaN or infinite: the step is probably unstable (run `cloth check` and raise the substeps)",
            report.nan_count
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    //! The command line under extreme input: every argument vector either fails to parse, is
    //! refused with a message, or plans work within the budgets, and none panics. The plans are
    //! the ones the commands themselves make before they run anything.

    use super::*;
    use cloth_core::budget::{MAX_FRAMES, MAX_SUBSTEPS_PER_FRAME};
    use proptest::prelude::*;

    /// What a command plans to run, from the same planning functions the commands call.
    fn preflight(cli: &Cli) -> Result<WorkPlan> {
        match &cli.command {
            Command::Run(args) => plan_run(args).map(|plan| plan.work),
            Command::Check { scene, grid, substeps, backend } => {
                plan_check(scene, *grid, *substeps, backend).map(|plan| plan.2)
            }
            Command::Bench(args) => bench::plan(args).map(|plan| plan.work),
            Command::Profile(args) => profile::plan(args).map(|plan| plan.work),
            Command::Study(StudyCommand::Accuracy(args)) => study::plan(args).map(|plan| plan.work),
            Command::Figure { .. } | Command::Backends | Command::View(_) => Ok(WorkPlan::default()),
        }
    }

    fn scene_path(name: &str) -> String {
        format!("{}/../../scenes/{name}", env!("CARGO_MANIFEST_DIR"))
    }

    /// A count as a user could type it: small, at a type's edge, far past it, negative, a float,
    /// not a number at all.
    fn count() -> impl Strategy<Value = String> {
        prop_oneof![
            4 => (0u64..64).prop_map(|n| n.to_string()),
            2 => (64u64..5000).prop_map(|n| n.to_string()),
            2 => any::<u32>().prop_map(|n| n.to_string()),
            1 => any::<u64>().prop_map(|n| n.to_string()),
            1 => prop::sample::select(vec![
                "4294967295", "4294967296", "18446744073709551615", "99999999999999999999999", "-1", "0", "1e9",
                "nan", "", "+7", " 8", "0x10",
            ])
            .prop_map(str::to_string),
        ]
    }

    /// A number of seconds: ordinary, extreme but finite, or not finite.
    fn seconds() -> impl Strategy<Value = String> {
        prop_oneof![
            3 => (1e-4f64..10.0).prop_map(|x| x.to_string()),
            2 => any::<f64>().prop_map(|x| x.to_string()),
            1 => prop::sample::select(vec!["1e308", "5e-324", "-0", "inf", "-inf", "NaN", "1e-300", "3.4e38"])
                .prop_map(str::to_string),
        ]
    }

    fn list(item: impl Strategy<Value = String>) -> impl Strategy<Value = String> {
        prop::collection::vec(item, 1..5).prop_map(|v| v.join(","))
    }

    fn grid() -> impl Strategy<Value = String> {
        (count(), count()).prop_map(|(a, b)| format!("{a}x{b}"))
    }

    fn substeps() -> impl Strategy<Value = String> {
        prop_oneof![4 => count(), 1 => Just("auto".to_string())]
    }

    fn step_rules() -> impl Strategy<Value = String> {
        list(prop_oneof![4 => count(), 1 => Just("scaled".to_string())])
    }

    fn backend() -> impl Strategy<Value = String> {
        prop::sample::select(vec!["cpu", "cpu-f64", "wgpu", "vulkano", "metal"]).prop_map(str::to_string)
    }

    fn scene() -> impl Strategy<Value = String> {
        prop::sample::select(vec!["drape.ron", "flag.ron", "hanging.ron", "hold.ron", "slide.ron"]).prop_map(scene_path)
    }

    /// `--flag value` when `value` is some.
    fn flag(name: &'static str, value: impl Strategy<Value = String>) -> impl Strategy<Value = Vec<String>> {
        prop::option::of(value).prop_map(move |v| v.map_or(vec![], |v| vec![name.to_string(), v]))
    }

    fn command() -> impl Strategy<Value = Vec<String>> {
        let run = (scene(), flag("--grid", grid()), flag("--substeps", substeps()), flag("--frames", count()))
            .prop_flat_map(|(scene, g, s, f)| {
                flag("--backend", backend())
                    .prop_map(move |b| [vec!["run".into(), scene.clone()], g.clone(), s.clone(), f.clone(), b].concat())
            });
        let check = (scene(), flag("--grid", grid()), flag("--substeps", substeps()), flag("--backend", backend()))
            .prop_map(|(scene, g, s, b)| [vec!["check".into(), scene], g, s, b].concat());
        let bench = (
            flag("--grids", list(count())),
            flag("--substeps", step_rules()),
            flag("--frames", count()),
            flag("--repeats", count()),
            flag("--backends", list(backend())),
            any::<bool>(),
        )
            .prop_map(|(g, s, f, r, b, effects)| {
                let mode = if effects { vec!["--effects".to_string()] } else { vec![] };
                [vec!["bench".into()], mode, g, s, f, r, b].concat()
            });
        let study = (
            scene(),
            flag("--grid", grid()),
            flag("--duration", seconds()),
            flag("--substeps", list(count())),
            flag("--backends", list(backend())),
            any::<bool>(),
        )
            .prop_map(|(scene, g, d, s, b, no_bisection)| {
                let skip = if no_bisection { vec!["--no-bisection".to_string()] } else { vec![] };
                [vec!["study".into(), "accuracy".into(), scene], g, d, s, b, skip].concat()
            });
        prop_oneof![run, check, bench, study]
    }

    /// How a case ended.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    enum Outcome {
        NotParsed,
        Refused,
        Planned,
    }

    /// Parses and plans `args`; on success, checks the plan against the budgets and the limits
    /// on substeps and frames.
    fn plans_within_budget(args: &[String]) -> Result<Outcome, TestCaseError> {
        let cli = match Cli::try_parse_from(std::iter::once("cloth".to_string()).chain(args.iter().cloned())) {
            Ok(cli) => cli,
            Err(e) => {
                prop_assert!(!e.to_string().trim().is_empty(), "a parse error without a message");
                return Ok(Outcome::NotParsed);
            }
        };
        match preflight(&cli) {
            Err(e) => {
                prop_assert!(!format!("{e:#}").trim().is_empty(), "a refusal without a message");
                Ok(Outcome::Refused)
            }
            Ok(plan) => {
                prop_assert!(plan.cpu <= WorkBudget::CPU.max_vertex_substeps, "{args:?}: {plan:?}");
                prop_assert!(plan.gpu <= WorkBudget::GPU.max_vertex_substeps, "{args:?}: {plan:?}");
                for (backend, substeps, frames, work) in &plan.runs {
                    prop_assert!(*substeps <= MAX_SUBSTEPS_PER_FRAME && *frames <= MAX_FRAMES, "{args:?}: {plan:?}");
                    prop_assert!(*work <= WorkBudget::for_backend(backend).max_vertex_substeps, "{args:?}");
                }
                Ok(Outcome::Planned)
            }
        }
    }

    #[test]
    fn every_accepted_command_plans_work_within_the_budgets() {
        // Bounded for CI: each case reads at most one scene file and plans; none runs a
        // simulation. A panic in parsing or planning fails the case like an assertion.
        let config = ProptestConfig { cases: 1000, failure_persistence: None, ..ProptestConfig::default() };
        let outcomes = std::cell::RefCell::new(Vec::new());
        proptest::test_runner::TestRunner::new(config)
            .run(&command(), |args| {
                outcomes.borrow_mut().push(plans_within_budget(&args)?);
                Ok(())
            })
            .unwrap_or_else(|e| panic!("{e}"));
        // The cases reach every outcome, so the property is not true of nothing.
        let outcomes = outcomes.into_inner();
        for outcome in [Outcome::NotParsed, Outcome::Refused, Outcome::Planned] {
            let share = outcomes.iter().filter(|&&o| o == outcome).count() as f64 / outcomes.len() as f64;
            eprintln!("{outcome:?}: {:.1}% of {} cases", share * 100.0, outcomes.len());
            assert!(share > 0.05, "{outcome:?} in only {:.1}% of {} cases", share * 100.0, outcomes.len());
        }
    }

    fn refusal(list: &[&str]) -> String {
        let cli = Cli::try_parse_from(std::iter::once("cloth").chain(list.iter().copied())).expect("parses");
        format!("{:#}", preflight(&cli).expect_err("refused"))
    }

    /// Cases the property found or that sit at its edges, kept as plain tests.
    #[test]
    fn sweeps_whose_runs_fit_alone_but_not_together_are_refused() {
        // 200 rows of 512² × 64 substeps × 5 timings of 10 frames: 1.3e11 vertex-substeps, within
        // a GPU's budget, beyond the CPU's.
        let grids = vec!["512"; 200].join(",");
        let bench = ["bench", "--grids", grids.as_str(), "--substeps", "64", "--backends"];
        let cli = Cli::try_parse_from([&["cloth"][..], &bench, &["wgpu"]].concat()).unwrap();
        assert_eq!(preflight(&cli).unwrap().gpu, 200 * 512 * 512 * 64 * 51);
        let message = refusal(&[&bench[..], &["cpu"]].concat());
        assert!(
            message.contains("the 200 runs of this command add up to 1.7") && message.contains("fewer"),
            "{message}"
        );
        // The f64 reference of a 64² study at 100000 substeps (9.8e10 vertex-substeps) and one run
        // (1.2e10) each fit the CPU's 1e11; together they do not.
        let hanging = scene_path("hanging.ron");
        let study = ["study", "accuracy", &hanging, "--grid", "64x64", "--substeps", "100000", "--backends", "cpu"];
        let message = refusal(&[&study[..], &["--integrators", "euler", "--no-bisection"]].concat());
        assert!(message.contains("the 2 runs of this command add up to 1.106e11"), "{message}");
        assert!(message.contains("sweep fewer scenes, --substeps"), "{message}");
    }

    #[test]
    fn cases_found_at_the_edges_are_refused_with_a_message() {
        // A row whose vertex-substeps overflow u64 is refused (and the command, with no row
        // left, ends with an error when run).
        let cli = Cli::try_parse_from(["cloth", "bench", "--grids", "536870912", "--substeps", "64"]).unwrap();
        let Command::Bench(bench_args) = &cli.command else { unreachable!() };
        let plan = bench::plan(bench_args).unwrap();
        let refusals: Vec<String> = plan.refusals().map(|p| p.to_string()).collect();
        assert!(
            !refusals.is_empty() && refusals.iter().all(|p| p.contains("9.408e20 vertex-substeps")),
            "{refusals:?}"
        );
        // A grid of 4294967295 vertices a row is refused by its resolution, before the flag's
        // pinned edge (32 GB of indices) would be listed.
        let message = refusal(&["bench", "--effects", "--grids", "4294967295"]);
        assert!(message.contains("cloth.resolution: grid 4294967295x"), "{message}");
        let message = refusal(&["bench", "--effects", "--grids", "16", "--repeats", "2"]);
        assert!(message.contains("--repeats 2 is too few"), "{message}");
        let message = refusal(&["run", "--frames", "4294967295", "--backend", "cpu"]);
        assert!(message.contains("--frames: 4294967295 frames is more than"), "{message}");
        let hanging = scene_path("hanging.ron");
        let message = refusal(&["study", "accuracy", &hanging, "--duration", "1e308"]);
        assert!(message.contains("--duration 1e308 s is more than the 10000000 frames"), "{message}");
    }
}
