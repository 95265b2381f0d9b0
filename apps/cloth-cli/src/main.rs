//! `cloth`: the headless command-line front end of the cloth workbench.
//!
//! * `cloth run [SCENE]`: simulate and summarise (text or `--json`), optionally render a PNG;
//! * `cloth check SCENE`: validate, and print spring counts, memory and the stable substep;
//! * `cloth backends`: the backends compiled in and the adapters each can use;
//! * `cloth bench`: ms per frame and vertex-substeps per second of each backend;
//! * `cloth study accuracy`: what accuracy costs in time;
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
mod output;
mod render;
mod report;
mod study;
mod tuning;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use cloth_backends as backends;
use cloth_core::budget::WorkBudget;
use cloth_core::{ClothModel, Energy, Scene, Substeps, stability};
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
    /// Studies (`cloth study accuracy`).
    #[command(subcommand)]
    Study(StudyCommand),
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
    /// Print one JSON object instead of the text summary.
    #[arg(long)]
    json: bool,
    /// Render the final state to this PNG file.
    #[arg(long)]
    png: Option<PathBuf>,
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

fn load_scene(path: Option<&PathBuf>, grid: Option<[u32; 2]>, substeps: Option<Substeps>) -> Result<Scene> {
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
            std::process::ExitCode::from(2)
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// `cloth check` of a valid scene whose substep exceeds the stable bound: exit code 2 (1 is an
/// invalid scene or another error).
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

fn check(path: &PathBuf, grid: Option<[u32; 2]>, substeps: Option<Substeps>, backend: &str) -> Result<()> {
    let scene = load_scene(Some(path), grid, substeps)?;
    let backend = backends::find(backend).map_err(anyhow::Error::msg)?;
    let budget = WorkBudget::for_backend(backend.name);
    let work = budget.check(&scene, scene.time.frames).map_err(|p| anyhow::anyhow!("time.{p}"))?;
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

fn run(args: RunArgs) -> Result<()> {
    let scene = load_scene(args.scene.as_ref(), args.grid, args.substeps)?;
    let backend = backends::find(&args.backend).map_err(anyhow::Error::msg)?;
    if let Some(png) = &args.png {
        output::check_writable(png)?;
    }
    let frames = args.frames.unwrap_or(scene.time.frames);
    WorkBudget::for_backend(backend.name).check(&scene, frames).map_err(|p| anyhow::anyhow!("--{p}"))?;
    let mut sim = (backend.create)(&scene, &args.tuning.tuning())
        .with_context(|| format!("cannot start the {} backend", backend.name))?;

    let progress = if args.json || frames < 30 { ProgressBar::hidden() } else { ProgressBar::new(frames as u64) };
    progress.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} frames ({per_sec}, eta {eta})")
            .expect("progress template is valid")
            .progress_chars("=> "),
    );
    progress.set_message(format!("{} on {}", scene.name, sim.backend_name()));
    let start = Instant::now();
    let mut counts = cloth_core::AdvanceCounts::default();
    for done in 0..frames {
        sim.advance(1).with_context(|| format!("the {} backend failed at frame {done}", backend.name))?;
        let c = sim.last_advance_counts();
        counts.frames += c.frames;
        counts.submissions += c.submissions;
        counts.host_waits += c.host_waits;
        progress.set_position(done as u64 + 1);
    }
    let state = sim.read_state()?;
    let wall = start.elapsed();
    progress.finish_and_clear();
    let diagnostics = sim.diagnostics()?;
    let model = ClothModel::new(&scene);
    let energy = Energy::of(&model, &state);
    let measured =
        report::Measured { state: &state, diagnostics: &diagnostics, counts: &counts, energy: &energy, frames, wall };
    let report = report::Report::new(&*sim, &model, &measured);
    if args.json {
        out!("{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        report.print_text()?;
    }
    if let Some(png) = &args.png {
        render::write_png(&model, &state, png, 800, 600)?;
        if !args.json {
            out!("picture     {}", png.display())?;
        }
    }
    if report.nan_count > 0 {
        bail!(
            "{} vertices became NaN or infinite: the step is probably unstable (run `cloth check` and raise the substeps)",
            report.nan_count
        );
    }
    Ok(())
}
