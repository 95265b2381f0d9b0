//! `cloth study accuracy`: what accuracy costs in time.
//!
//! For each scene (by default a smooth hanging cloth, the drape with contact and friction, and
//! the drape with springs 100 times stiffer), sweeps backend × integrator × substeps per frame
//! over a fixed simulated time and compares every run's final positions with a reference run:
//! the f64 CPU reference with RK4 at 8 times the finest step of the sweep, or finer where RK4
//! needs it to be stable ([`measure`]). Prints a table, writes one CSV and one plot of error
//! against cost with a panel per scene (SVG and PNG, [`plot`]), measures each integrator's
//! largest stable step by bisection against the bound the core predicts ([`bisection`]), and
//! with `--report` writes the Markdown report ([`report`]) that `docs/accuracy.md` is.

mod bisection;
mod measure;
pub(crate) mod plot;
mod report;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use cloth_backends as backends;
use cloth_core::budget::{MAX_FRAMES, MAX_SUBSTEPS_PER_FRAME, WorkPlan};
use cloth_core::{Integrator, Scene};
use indicatif::{ProgressBar, ProgressStyle};

pub use measure::Row;

/// The scenes studied when none is named: a smooth cloth without contact, the drape (contact
/// and friction) and the drape with springs 100 times stiffer (where the explicit integrators
/// need ten times the substeps).
pub const DEFAULT_SCENES: [&str; 3] = ["scenes/hanging.ron", "scenes/drape.ron", "scenes/stiff_drape.ron"];

/// Options of `cloth study accuracy`.
#[derive(clap::Args)]
pub struct AccuracyArgs {
    /// Scenes to study, each on its own (default: scenes/hanging.ron, scenes/drape.ron and
    /// scenes/stiff_drape.ron).
    scenes: Vec<PathBuf>,
    /// Backends to measure (comma-separated): `cpu` runs f32, `cpu-f64` f64, `wgpu` and `vulkano`
    /// the GPU kernels.
    #[arg(long, alias = "backend", value_delimiter = ',', default_values_t = vec!["cpu".to_string(), "cpu-f64".to_string()])]
    backends: Vec<String>,
    /// Integrators to sweep (comma-separated: euler, verlet, rk4, xpbd, backward-euler, vbd).
    #[arg(long, value_delimiter = ',', default_values_t = Integrator::ALL.map(|i| i.name().to_string()).to_vec())]
    integrators: Vec<String>,
    /// Simulated time of every run, s.
    #[arg(long, default_value_t = 0.5)]
    duration: f64,
    /// Substeps per frame to sweep (comma-separated).
    #[arg(long, value_delimiter = ',', default_values_t = vec![1u32, 2, 4, 8, 16, 32, 64])]
    substeps: Vec<u32>,
    /// Grid resolution override for every scene, e.g. 16x16.
    #[arg(long, value_parser = crate::parse_grid)]
    grid: Option<[u32; 2]>,
    /// The implicit integrators' solver settings for every scene instead of its own, written as
    /// the scene's `solver` field, e.g. '(chebyshev_rho: 0.8)' (fields left out take their
    /// defaults; see docs/model.md).
    #[arg(long, value_parser = crate::parse_solver)]
    solver: Option<cloth_core::solver::SolverSpec>,
    /// RMS error, m, a run must stay within for the report's largest step with a bounded error.
    #[arg(long, default_value_t = 1e-2)]
    error_bound: f64,
    /// Frame-time budgets, ms per frame, of the report's two-budget table (comma-separated).
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.05, 0.2, 1.0, 16.7])]
    frame_budgets: Vec<f64>,
    #[command(flatten)]
    tuning: crate::tuning::TuningArgs,
    /// CSV output; the plot is written beside it (same name, .svg and .png).
    #[arg(long, default_value = "out/accuracy.csv")]
    csv: PathBuf,
    /// Also write the Markdown report to this file (e.g. docs/accuracy.md), with the CSV and
    /// the plot copied beside it.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Skip the bisection of the largest stable step.
    #[arg(long)]
    no_bisection: bool,
}

/// Everything one scene's study measured, for the plot and the report.
pub struct Study {
    /// The scene every run starts from (its grid overridden if asked).
    pub scene: Scene,
    /// Where the scene came from.
    pub scene_path: PathBuf,
    /// Frames of every run.
    pub frames: u32,
    /// Substeps per frame of the reference run.
    pub reference_substeps: u32,
    /// Every run, in sweep order.
    pub rows: Vec<Row>,
    /// `(backend, adapter in words)` for each backend that ran.
    pub adapters: Vec<(String, String)>,
    /// Runs that could not start, `(backend, integrator, reason)`.
    pub skipped: Vec<(String, String, String)>,
    /// The largest stable step of each integrator on each backend.
    pub limits: Vec<bisection::Limit>,
}

/// What the report is asked to judge the runs by.
pub struct Budgets {
    /// RMS error a run must stay within for the largest step with a bounded error, m.
    pub error_bound_m: f64,
    /// Frame-time budgets of the two-budget table, ms per frame.
    pub frame_ms: Vec<f64>,
}

fn parse_integrators(names: &[String]) -> Result<Vec<Integrator>> {
    names.iter().map(|n| crate::parse_integrator(n).map_err(anyhow::Error::msg)).collect()
}

fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{msg:>32} [{bar:30}] {pos}/{len} runs (eta {eta})")
            .expect("progress template is valid")
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// One scene of the plan.
pub(crate) struct PlannedScene {
    path: PathBuf,
    base: Scene,
    frames: u32,
    reference_substeps: u32,
}

/// What `cloth study accuracy` will run, decided before anything runs or is written.
pub(crate) struct Plan {
    scenes: Vec<PlannedScene>,
    integrators: Vec<Integrator>,
    backends: Vec<backends::Backend>,
    budgets: Budgets,
    /// Every run, the references and the bisections, within the budgets alone and together.
    pub(crate) work: WorkPlan,
}

/// Substeps per frame of the reference run of `scene`: 8 times the finest of the sweep, or more
/// where RK4 needs a smaller step to be stable (half its predicted bound, the stiff drape's case).
fn reference_substeps(scene: &Scene, finest: u32) -> f64 {
    let rk4 = Scene { integrator: Integrator::RungeKutta4, ..scene.clone() };
    let stable = (scene.time.frame_dt / (0.5 * cloth_core::stability::stable_substep(&rk4))).ceil();
    (8.0 * f64::from(finest)).max(if stable.is_finite() { stable } else { 1.0 })
}

/// The plan of `args`.
///
/// # Errors
/// An unreadable or invalid scene, a bad flag, or runs that exceed a budget, alone or together.
pub(crate) fn plan(args: &AccuracyArgs) -> Result<Plan> {
    let paths: Vec<PathBuf> =
        if args.scenes.is_empty() { DEFAULT_SCENES.iter().map(PathBuf::from).collect() } else { args.scenes.clone() };
    if !(args.duration.is_finite() && args.duration > 0.0) {
        bail!("--duration must be a positive number of seconds (got {:?})", args.duration);
    }
    if args.substeps.is_empty() || args.substeps.contains(&0) {
        bail!("--substeps needs at least one count, each at least 1 (got {:?})", args.substeps);
    }
    if !(args.error_bound.is_finite() && args.error_bound > 0.0) {
        bail!("--error-bound must be a positive RMS error in m (got {:?})", args.error_bound);
    }
    if args.frame_budgets.is_empty() || args.frame_budgets.iter().any(|b| !(b.is_finite() && *b > 0.0)) {
        bail!("--frame-budgets needs at least one budget, each a positive number of ms (got {:?})", args.frame_budgets);
    }
    let integrators = parse_integrators(&args.integrators)?;
    let chosen: Vec<backends::Backend> =
        args.backends.iter().map(|n| backends::find(n).map_err(anyhow::Error::msg)).collect::<Result<_>>()?;
    let finest = args.substeps.iter().copied().max().unwrap_or(64);
    let mut scenes = Vec::new();
    // The references, every run and every bisection fit the budgets, alone and together,
    // before anything runs.
    let mut work = WorkPlan::default();
    for path in paths {
        let mut base = Scene::load(&path).with_context(|| format!("cannot use scene {}", path.display()))?;
        if let Some(g) = args.grid {
            base.cloth.resolution = g;
            base.validate().with_context(|| format!("{} with --grid is invalid", path.display()))?;
        }
        if let Some(solver) = args.solver {
            base.solver = solver;
            // The solver's fields are checked for the integrators that read them.
            for &integrator in &integrators {
                let scene = Scene { integrator, ..base.clone() };
                scene.validate().with_context(|| {
                    format!("{} with --solver is invalid for {}", path.display(), integrator.name())
                })?;
            }
        }
        let frames = (args.duration / base.time.frame_dt).round().max(1.0);
        if frames > MAX_FRAMES as f64 {
            bail!(
                "--duration {:?} s is more than the {MAX_FRAMES} frames of {} s one command may run: ask for at most \
                 {:.0} s",
                args.duration,
                base.time.frame_dt,
                (MAX_FRAMES as f64 * base.time.frame_dt).floor()
            );
        }
        let frames = frames as u32;
        let reference = reference_substeps(&base, finest);
        if reference > MAX_SUBSTEPS_PER_FRAME as f64 {
            bail!(
                "the f64 reference of {} would need {reference:.0} substeps per frame (8 times the finest of \
                 --substeps, or what RK4 needs to be stable on its springs), more than the {MAX_SUBSTEPS_PER_FRAME} \
                 a frame may take: sweep fewer --substeps, or a scene with softer springs",
                path.display()
            );
        }
        let reference_substeps = reference as u32;
        let mut reference_scene = base.clone();
        reference_scene.time.substeps = cloth_core::Substeps::Fixed(reference_substeps);
        work.add("cpu-f64", &reference_scene, frames)
            .map_err(|p| anyhow::anyhow!("the f64 reference of {}: {p}", path.display()))?;
        for backend in &chosen {
            for &n in &args.substeps {
                for _ in &integrators {
                    let mut run = base.clone();
                    run.time.substeps = cloth_core::Substeps::Fixed(n);
                    work.add(backend.name, &run, frames).map_err(|p| anyhow::anyhow!("{}: {p}", backend.name))?;
                }
            }
            if !args.no_bisection {
                for &integrator in &integrators {
                    let trials = bisection::planned_vertex_substeps(&base, integrator);
                    work.add_work(backend.name, 1, 0, trials);
                }
            }
        }
        scenes.push(PlannedScene { path, base, frames, reference_substeps });
    }
    work.check(
        "--substeps",
        "sweep fewer scenes, --substeps, --integrators or --backends, a shorter --duration, a smaller --grid, or \
         --no-bisection",
    )
    .map_err(anyhow::Error::msg)?;
    let budgets = Budgets { error_bound_m: args.error_bound, frame_ms: args.frame_budgets.clone() };
    Ok(Plan { scenes, integrators, backends: chosen, budgets, work })
}

pub fn accuracy(args: AccuracyArgs) -> Result<()> {
    let Plan { scenes, integrators, backends: chosen, budgets, work } = plan(&args)?;
    // The outputs, checked and claimed before the run: a second study writing the same files
    // in the same folder is refused rather than left to overwrite this one's.
    if let Some(dir) = args.csv.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let _claim = cloth_backends::output::OutputLock::claim(&args.csv)?;
    for path in [Some(&args.csv), args.report.as_ref()].into_iter().flatten() {
        cloth_backends::output::check_writable(path)?;
    }
    eprintln!(
        "{} scene(s); {} runs of {:.3e} vertex-substeps in all",
        scenes.len(),
        work.runs.len(),
        work.runs.iter().map(|r| r.3 as f64).sum::<f64>()
    );
    let runs = (scenes.len() * chosen.len() * integrators.len() * args.substeps.len()) as u64;
    let bar = progress_bar(runs, "runs");
    let mut studies = Vec::new();
    for planned in &scenes {
        let PlannedScene { path, base, frames, reference_substeps } = planned;
        let (frames, reference_substeps) = (*frames, *reference_substeps);
        bar.suspend(|| {
            out!(
                "\n{}: f64 CPU reference, RK4, {reference_substeps} substeps per frame, {frames} frames of {:.4} s",
                path.display(),
                base.time.frame_dt
            )
        })?;
        bar.set_message(format!("{} reference", base.name));
        let reference = measure::Reference::new(base, frames, reference_substeps)?;
        bar.suspend(measure::print_header)?;
        let mut study = Study {
            scene: base.clone(),
            scene_path: path.clone(),
            frames,
            reference_substeps,
            rows: Vec::new(),
            adapters: Vec::new(),
            skipped: Vec::new(),
            limits: Vec::new(),
        };
        for backend in &chosen {
            for &integrator in &integrators {
                for (done, &n) in args.substeps.iter().enumerate() {
                    bar.set_message(format!("{} {} {} {n}", base.name, backend.name, integrator.name()));
                    match measure::run(backend, &args.tuning.tuning(), base, integrator, n, frames, &reference) {
                        Ok((row, adapter)) => {
                            bar.suspend(|| row.print())?;
                            if !study.adapters.iter().any(|(b, _)| b == backend.name) {
                                study.adapters.push((backend.name.to_string(), adapter));
                            }
                            study.rows.push(row);
                        }
                        Err(measure::RunError::Skipped(reason)) => {
                            bar.suspend(|| out!("{:<8} {:<14} skipped: {reason}", backend.name, integrator.name()))?;
                            study.skipped.push((backend.name.to_string(), integrator.name().to_string(), reason));
                            bar.inc((args.substeps.len() - done) as u64);
                            break;
                        }
                        Err(measure::RunError::Failed(e)) => {
                            bar.finish_and_clear();
                            return Err(e.context(format!(
                                "{}: {} {} at {n} substeps",
                                path.display(),
                                backend.name,
                                integrator.name()
                            )));
                        }
                    }
                    bar.inc(1);
                }
            }
        }
        if !args.no_bisection {
            bar.suspend(|| {
                out!(
                    "\n{}: largest stable substep (bisection, 2000 substeps from the scene's start) against the \
                     predictions: the spectral estimate (power iteration on M⁻¹K) and the safe Gershgorin bound:",
                    path.display()
                )
            })?;
            for backend in &chosen {
                if study.skipped.iter().any(|(b, _, _)| b == backend.name)
                    && !study.adapters.iter().any(|(b, _)| b == backend.name)
                {
                    continue;
                }
                for &integrator in &integrators {
                    bar.set_message(format!("{} bisection {} {}", base.name, backend.name, integrator.name()));
                    let limit = bisection::largest_stable_substep(backend, &args.tuning.tuning(), base, integrator)?;
                    bar.suspend(|| out!("  {limit}"))?;
                    study.limits.push(limit);
                }
            }
        }
        studies.push(study);
    }
    bar.finish_and_clear();

    let rows: Vec<&Row> = studies.iter().flat_map(|s| &s.rows).collect();
    write_csv(&rows, &args.csv)?;
    out!("\nwrote {}", args.csv.display())?;
    let (svg, png) = (args.csv.with_extension("svg"), args.csv.with_extension("png"));
    plot::write(&studies, &svg, &png)?;
    out!("wrote {} and {}", svg.display(), png.display())?;
    if let Some(path) = &args.report {
        let dir = path.parent().unwrap_or(Path::new("."));
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("accuracy");
        let copy = |from: &Path, extension: &str| -> Result<String> {
            let name = format!("{stem}.{extension}");
            let bytes = std::fs::read(from).with_context(|| format!("cannot read {}", from.display()))?;
            cloth_backends::output::write_atomically(&dir.join(&name), &bytes)?;
            Ok(name)
        };
        let files = report::Files { csv: copy(&args.csv, "csv")?, svg: copy(&svg, "svg")?, png: copy(&png, "png")? };
        let text = report::markdown(&studies, &budgets, &files);
        cloth_backends::output::write_atomically(path, text.as_bytes())?;
        out!("wrote the report {} (with {}, {} and {})", path.display(), files.csv, files.svg, files.png)?;
    }
    Ok(())
}

fn write_csv(rows: &[&Row], path: &Path) -> Result<()> {
    let mut text = format!("{}\n", Row::CSV_HEADER);
    for r in rows {
        text += &format!("{}\n", r.csv());
    }
    Ok(cloth_backends::output::write_atomically(path, text.as_bytes())?)
}
