//! `cloth bench`: throughput of each backend on the drape scene at several grid sizes and steps
//! (GPU and CPU time per frame, vertex-substeps per second, the fraction of the device's
//! memory-bandwidth ceiling, submissions and waits per frame), and with `--effects`, what each
//! effect of a scene costs (the bare cloth, then each effect added).
//!
//! A benchmark, not a test: it prints figures and writes a CSV, and asserts nothing about speed.

use anyhow::{Context, Result};
use cloth_backends::effect_cost;
use cloth_backends::throughput::{
    self, MIN_BYTES_PER_VERTEX_SUBSTEP, PACKED_BYTES_PER_VERTEX_SUBSTEP, StepRule, ThroughputRow,
};
use cloth_core::budget::WorkPlan;
use cloth_core::{Scene, SimError, Substeps};
use indicatif::{ProgressBar, ProgressStyle};

use cloth_backends as backends;

/// Options of `cloth bench`.
#[derive(clap::Args)]
pub struct BenchArgs {
    /// Backends to measure, comma-separated (default: every backend that can start here).
    #[arg(long, value_delimiter = ',')]
    backends: Vec<String>,
    /// Grid sides to measure (square grids), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = vec![32u32, 128, 512])]
    grids: Vec<u32>,
    /// Substeps per frame, comma-separated: numbers, or `scaled` for the resolution-scaled step
    /// dt = 0.04/n (default 16,64,scaled; with `--effects`, one number, default the scene's own).
    #[arg(long, value_delimiter = ',')]
    substeps: Vec<StepRule>,
    /// Integrators to time, comma-separated (euler, verlet, rk4, xpbd, backward-euler, vbd; the
    /// implicit ones at their default solver settings).
    #[arg(long, value_delimiter = ',', default_value = "euler", value_parser = crate::parse_integrator)]
    integrators: Vec<cloth_core::Integrator>,
    /// Frames of each timing (after one warm-up frame), at least 1.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..))]
    frames: u32,
    /// Timings of each row (`--frames` frames each); the table gives their median and spread
    /// (the interquartile range). At least 1, and at least 3 with `--effects`, whose rows are
    /// timed in alternating order and compared pairwise.
    #[arg(long, default_value_t = cloth_backends::timing::DEFAULT_REPEATS, value_parser = clap::value_parser!(u32).range(1..))]
    repeats: u32,
    /// Also write the rows to this CSV file.
    #[arg(long)]
    csv: Option<std::path::PathBuf>,
    #[command(flatten)]
    tuning: crate::tuning::TuningArgs,
    /// Instead, print what each effect costs: the bare cloth, then each effect of the scene
    /// added in turn (ms per frame per backend, at each of `--grids`; the scene's own
    /// substeps unless `--substeps` is given).
    #[arg(long)]
    effects: bool,
    /// The scene of `--effects` (default: scenes/flag.ron, which has every effect but
    /// self-collision).
    #[arg(long, requires = "effects")]
    scene: Option<std::path::PathBuf>,
}

/// The default scene of `--effects`: every effect but self-collision at once (a copy of
/// `scenes/flag.ron`).
const FLAG_SCENE: &str = include_str!("../../../scenes/flag.ron");

/// One row `cloth bench` will time, or the reason it is refused (it does not fit its
/// backend's budget alone).
pub(crate) struct PlannedRow {
    backend: usize,
    n: u32,
    rule: StepRule,
    integrator: cloth_core::Integrator,
    refused: Option<cloth_core::Problem>,
}

/// One breakdown `cloth bench --effects` will measure: the scene resized to a grid, or the
/// reason it is refused.
pub(crate) struct PlannedBreakdown {
    backend: usize,
    n: u32,
    scene: Scene,
    refused: Option<cloth_core::Problem>,
}

/// What `cloth bench` will run, decided before anything runs: the backends, each row (or
/// breakdown) with its refusal if it does not fit its budget alone, and the work of all of them,
/// which must fit the budgets together.
pub(crate) struct Plan {
    backends: Vec<backends::Backend>,
    rows: Vec<PlannedRow>,
    breakdowns: Vec<PlannedBreakdown>,
    pub(crate) work: WorkPlan,
}

impl Plan {
    /// Why each refused row or breakdown is refused.
    #[cfg(test)]
    pub(crate) fn refusals(&self) -> impl Iterator<Item = &cloth_core::Problem> {
        self.rows
            .iter()
            .filter_map(|r| r.refused.as_ref())
            .chain(self.breakdowns.iter().filter_map(|b| b.refused.as_ref()))
    }
}

/// The plan of `args`.
///
/// # Errors
/// An unknown backend, too few repeats for `--effects`, an invalid scene, or rows that together
/// exceed a budget.
pub(crate) fn plan(args: &BenchArgs) -> Result<Plan> {
    let chosen: Vec<backends::Backend> = if args.backends.is_empty() {
        backends::all().into_iter().filter(|b| b.name != "cpu-f64").collect()
    } else {
        args.backends.iter().map(|n| backends::find(n).map_err(anyhow::Error::msg)).collect::<Result<_>>()?
    };
    let mut plan = Plan { backends: Vec::new(), rows: Vec::new(), breakdowns: Vec::new(), work: WorkPlan::default() };
    if args.effects {
        if args.repeats < effect_cost::MIN_REPEATS {
            anyhow::bail!(
                "--repeats {} is too few for --effects: an effect's cost is read from at least {} timings of each row \
                 (use --repeats {} or more)",
                args.repeats,
                effect_cost::MIN_REPEATS,
                effect_cost::MIN_REPEATS
            );
        }
        let base = match &args.scene {
            Some(path) => Scene::load(path).with_context(|| format!("cannot use scene {}", path.display()))?,
            None => Scene::from_ron_str(FLAG_SCENE).context("the built-in flag scene")?,
        };
        for (k, backend) in chosen.iter().enumerate() {
            for &n in &args.grids {
                let mut scene = base.clone();
                // Square cells: the longer side gets `n` vertices.
                let [w, h] = scene.cloth.size;
                scene.cloth.resolution = if w >= h {
                    [n, ((n as f64 * h / w).round() as u32).max(2)]
                } else {
                    [((n as f64 * w / h).round() as u32).max(2), n]
                };
                match args.substeps.as_slice() {
                    [] => {}
                    [StepRule::Fixed(k)] => scene.time.substeps = Substeps::Fixed(*k),
                    _ => anyhow::bail!("--effects takes one number of substeps (or none: the scene's own)"),
                }
                scene.validate().with_context(|| format!("the scene '{}' at grid {n}", scene.name))?;
                // Each row's warm-up and timed frames, over every row.
                let rows = effect_cost::steps(&scene).len() as u32;
                let frames = args.frames.saturating_mul(args.repeats).saturating_add(1).saturating_mul(rows);
                let refused = plan.work.add(backend.name, &scene, frames).err();
                plan.breakdowns.push(PlannedBreakdown { backend: k, n, scene, refused });
            }
        }
    } else {
        let rules = if args.substeps.is_empty() {
            vec![StepRule::Fixed(16), StepRule::Fixed(64), StepRule::Scaled]
        } else {
            args.substeps.clone()
        };
        for (k, backend) in chosen.iter().enumerate() {
            for &n in &args.grids {
                for &integrator in &args.integrators {
                    for &rule in &rules {
                        // The warm-up frame and the timed ones.
                        let frames = args.frames.saturating_mul(args.repeats).saturating_add(1);
                        let scene = throughput::bench_scene_with(n, rule, integrator);
                        let refused = plan.work.add(backend.name, &scene, frames).err();
                        plan.rows.push(PlannedRow { backend: k, n, rule, integrator, refused });
                    }
                }
            }
        }
    }
    plan.work
        .check("--grids", "time fewer rows (--grids, --substeps, --backends), fewer --frames or --repeats")
        .map_err(anyhow::Error::msg)?;
    plan.backends = chosen;
    Ok(plan)
}

pub fn run(args: BenchArgs) -> Result<()> {
    let plan = plan(&args)?;
    if let Some(path) = &args.csv {
        cloth_backends::output::check_writable(path)?;
    }
    if args.effects {
        return effects(&args, &plan);
    }
    // The ceiling: the device's copy bandwidth, measured by the copy kernel of the first GPU
    // backend listed, at the least a substep must move per vertex.
    let tuning = args.tuning.tuning();
    let measured_by = plan.backends.iter().find_map(|b| b.copy_bandwidth.map(|measure| (b.name, measure)));
    let bandwidth = match measured_by.map(|(name, measure)| (name, measure(&tuning))) {
        Some((name, Ok(b))) => {
            out!(
                "device copy bandwidth: {:.3} TB/s (a vec4 copy kernel through {name}; {} copies of {} MiB, bytes read \
                 + written, on {})",
                b.bytes_per_s / 1e12,
                b.copies,
                b.copy_bytes >> 20,
                b.adapter
            )?;
            out!(
                "ceiling at {MIN_BYTES_PER_VERTEX_SUBSTEP} bytes per vertex-substep (read and write one position and \
                 one velocity vec4): {:.2} G vertex-substeps/s (semi-implicit Euler's packed state moves \
                 {PACKED_BYTES_PER_VERTEX_SUBSTEP}: {:.2} G vertex-substeps/s)\n",
                b.bytes_per_s / MIN_BYTES_PER_VERTEX_SUBSTEP / 1e9,
                b.bytes_per_s / PACKED_BYTES_PER_VERTEX_SUBSTEP / 1e9
            )?;
            Some(b)
        }
        Some((_, Err(e))) => {
            out!("device copy bandwidth: not measured ({e})\n")?;
            None
        }
        None => None,
    };
    out!(
        "{:<8} {:<14} {:>6} {:>9} {:>5} {:>5} {:>10} {:>10} {:>8} {:>10} {:>10} {:>9} {:>8} {:>8} {:>6}",
        "backend",
        "integrator",
        "grid",
        "substeps",
        "fused",
        "state",
        "dt (s)",
        "GPU ms/f",
        "spread",
        "CPU ms/f",
        "wall ms/f",
        "Gvs/s",
        "ceiling",
        "sub/w",
        "finite"
    )?;
    let bar = ProgressBar::new(plan.rows.len() as u64).with_style(
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} rows")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut rows: Vec<ThroughputRow> = Vec::new();
    let mut adapters: Vec<String> = Vec::new();
    let mut unavailable = vec![false; plan.backends.len()];
    for planned in &plan.rows {
        let (backend, n, rule) = (&plan.backends[planned.backend], planned.n, planned.rule);
        let integrator = planned.integrator;
        bar.inc(1);
        if unavailable[planned.backend] {
            continue;
        }
        bar.set_message(format!("{} {n}² {rule} {}", backend.name, integrator.name()));
        if let Some(p) = &planned.refused {
            bar.suspend(|| out!("{:<8} {:>6} {rule:>9} refused: {p}", backend.name, format!("{n}²")))?;
            continue;
        }
        let row = match throughput::measure(backend, &tuning, n, (rule, integrator), args.frames, args.repeats) {
            Ok(row) => row,
            Err(SimError::Unavailable { reason, .. }) => {
                bar.suspend(|| out!("{:<8} skipped: {reason}", backend.name))?;
                unavailable[planned.backend] = true;
                continue;
            }
            Err(e) => {
                bar.suspend(|| out!("{:<8} {:>6} {rule:>9} refused: {e}", backend.name, format!("{n}²")))?;
                continue;
            }
        };
        let gpu = row.gpu_ms_per_frame.map_or("-".to_string(), |ms| format!("{ms:.3}"));
        // The spread of the timer the throughput comes from.
        let spread = format!("{:.3}", row.gpu_ms_spread.unwrap_or(row.wall_ms_spread));
        let ceiling = match (&bandwidth, row.gpu_ms_per_frame) {
            (Some(b), Some(_)) => format!("{:.1}%", 100.0 * row.ceiling_fraction(b.bytes_per_s)),
            _ => "-".to_string(),
        };
        bar.suspend(|| {
            out!(
                "{:<8} {:<14} {:>6} {:>9} {:>5} {:>5} {:>10.3e} {:>10} {:>8} {:>10.3} {:>10.3} {:>9.3} {:>8} {:>8} {:>6}",
                row.backend,
                row.integrator.name(),
                format!("{n}²"),
                row.substeps,
                row.fused_substeps,
                row.state_bytes.map_or("-".to_string(), |b| format!("{b} B")),
                row.substep_dt,
                gpu,
                spread,
                row.cpu_ms_per_frame,
                row.wall_ms_per_frame,
                row.vertex_substeps_per_s / 1e9,
                ceiling,
                format!("{:.0}/{:.2}", row.submissions_per_frame, row.host_waits_per_frame),
                if row.finite { "yes" } else { "NaN" }
            )
        })?;
        if !adapters.contains(&row.adapter) {
            adapters.push(row.adapter.clone());
        }
        rows.push(row);
    }
    bar.finish_and_clear();
    if rows.is_empty() {
        anyhow::bail!("no row was measured: every backend listed was skipped or refused (see above)");
    }
    for a in &adapters {
        out!("adapter: {a}")?;
    }
    out!(
        "fused: substeps per dispatch (the tiled Euler kernel fuses several); state: bytes a vertex the substeps hand each \
         other (24: semi-implicit Euler's packed state, 32: two vec4s; on the packed state the substeps take the grid's \
         blocks forward and backward by turns where a substep moves {} to {} MB, --block-order); times are the medians \
         of {} timings of {} frames; GPU ms/f: GPU time per frame (timestamp queries); spread: the interquartile range \
         of the GPU time (of the wall time without one); CPU ms/f: host time in advance(); wall ms/f: to the end \
         of the work; Gvs/s: 1e9 vertex-substeps per second (from the GPU time where there is one); ceiling: that \
         throughput times {MIN_BYTES_PER_VERTEX_SUBSTEP} bytes over the copy bandwidth; sub/w: submissions and host \
         waits per frame (the wait that ends the measurement included).",
        cloth_gpu::geometry::ALTERNATE_ORDER_MIN_SUBSTEP_BYTES / 1_000_000,
        cloth_gpu::geometry::ALTERNATE_ORDER_MAX_SUBSTEP_BYTES / 1_000_000,
        args.repeats,
        args.frames
    )?;
    if let Some(path) = &args.csv {
        let b = bandwidth.as_ref().map(|b| b.bytes_per_s);
        let mut csv = String::from(
            "backend,adapter,integrator,grid,step_rule,substeps,substep_dt_s,frames,repeats,gpu_ms_per_frame,gpu_ms_spread,\
             cpu_ms_per_frame,wall_ms_per_frame,wall_ms_spread,vertex_substeps_per_s,ceiling_fraction,copy_bandwidth_bytes_per_s,\
             submissions_per_frame,host_waits_per_frame,finite,fused_substeps,state_bytes_per_vertex\n",
        );
        for r in &rows {
            csv += &format!(
                "{},\"{}\",{},{},{},{},{:.6e},{},{},{},{},{:.6},{:.6},{:.6},{:.6e},{},{},{:.3},{:.3},{},{},{}\n",
                r.backend,
                r.adapter.replace('"', "'"),
                r.integrator.name(),
                r.grid,
                r.rule,
                r.substeps,
                r.substep_dt,
                r.frames,
                r.repeats,
                r.gpu_ms_per_frame.map_or(String::new(), |x| format!("{x:.6}")),
                r.gpu_ms_spread.map_or(String::new(), |x| format!("{x:.6}")),
                r.cpu_ms_per_frame,
                r.wall_ms_per_frame,
                r.wall_ms_spread,
                r.vertex_substeps_per_s,
                match (b, r.gpu_ms_per_frame) {
                    (Some(b), Some(_)) => format!("{:.4}", r.ceiling_fraction(b)),
                    _ => String::new(),
                },
                b.map_or(String::new(), |b| format!("{b:.6e}")),
                r.submissions_per_frame,
                r.host_waits_per_frame,
                r.finite,
                r.fused_substeps,
                r.state_bytes.map_or(String::new(), |b| b.to_string())
            );
        }
        cloth_backends::output::write_atomically(path, csv.as_bytes())?;
        out!("wrote {}", path.display())?;
    }
    Ok(())
}

/// `cloth bench --effects`: the per-effect breakdown of a scene on each backend and grid.
fn effects(args: &BenchArgs, plan: &Plan) -> Result<()> {
    let mut csv = String::from(
        "backend,adapter,grid,substeps,frames,repeats,row,effects,ms_per_frame,ms_spread,added,added_ms,\
         added_low_ms,added_high_ms,timer,timed_frames,checks,rebuilds,overflowed_lists\n",
    );
    let mut measured = 0;
    let mut unavailable = vec![false; plan.backends.len()];
    for planned in &plan.breakdowns {
        let (backend, n, scene) = (&plan.backends[planned.backend], planned.n, &planned.scene);
        if unavailable[planned.backend] {
            continue;
        }
        if let Some(p) = &planned.refused {
            out!("{:<8} {n} refused: {p}", backend.name)?;
            continue;
        }
        let rows = effect_cost::steps(scene).len() as u32;
        let [nx, ny] = scene.cloth.resolution;
        let bar = ProgressBar::new(u64::from(rows) * u64::from(args.repeats)).with_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} timings")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_message(format!("{} {nx}x{ny}", backend.name));
        let tuning = args.tuning.tuning();
        let breakdown = match effect_cost::measure(scene, backend, &tuning, args.frames, args.repeats, |done, _| {
            bar.set_position(done as u64)
        }) {
            Ok(rows) => rows,
            Err(SimError::Unavailable { reason, .. }) => {
                bar.finish_and_clear();
                out!("{:<8} skipped: {reason}", backend.name)?;
                unavailable[planned.backend] = true;
                continue;
            }
            Err(e) => {
                bar.finish_and_clear();
                out!("{:<8} {nx}x{ny} refused: {e}", backend.name)?;
                continue;
            }
        };
        bar.finish_and_clear();
        measured += 1;
        let (adapter, substeps, timer, rows) =
            (&breakdown.adapter, breakdown.substeps, breakdown.timer(), &breakdown.rows);
        out!(
            "\n{} on {adapter}: scene '{}', {nx}x{ny} vertices, {substeps} substeps per frame, {} timings of {} \
                 frames per row in alternating order, {timer}",
            backend.name,
            scene.name,
            args.repeats,
            args.frames
        )?;
        out!("  {:<22} {:>10} {:>8}  {:<40} share of the whole", "row", "ms/frame", "spread", "added")?;
        let whole = breakdown.whole_ms().max(f64::MIN_POSITIVE);
        let timed_frames = breakdown.frames * breakdown.repeats;
        for r in rows {
            let ms = r.ms_per_frame.median();
            // Only a cost that stands out of the noise gets a bar and a share.
            let share = match r.added_cost {
                None => Some(ms / whole),
                Some(d) => d.cost().map(|c| c / whole),
            };
            let share = share
                .map_or(String::new(), |s| format!("{} {:.0}%", "#".repeat((s * 40.0).round() as usize), s * 100.0));
            out!("  {:<22} {:>10.3} {:>8.3}  {:<40} {share}", r.label(), ms, r.ms_per_frame.spread(), r.added_text())?;
            let (verdict, added_ms, (low, high)) = match r.added_cost {
                None => ("", String::new(), (String::new(), String::new())),
                Some(d) => (
                    d.verdict(),
                    d.outside_noise().map_or(String::new(), |c| format!("{c:.6}")),
                    (format!("{:.6}", d.range().0), format!("{:.6}", d.range().1)),
                ),
            };
            let lists = r
                .candidate_lists
                .map_or(",,".to_string(), |l| format!("{},{},{}", l.checks, l.rebuilds, l.overflowed_lists));
            csv += &format!(
                "{},\"{}\",{nx}x{ny},{substeps},{},{},{},{},{ms:.6},{:.6},{verdict},{added_ms},{low},{high},{timer},{},{lists}\n",
                backend.name,
                adapter.replace('"', "'"),
                args.frames,
                args.repeats,
                r.label(),
                r.step.effects.iter().map(|e| format!("{e:?}")).collect::<Vec<_>>().join(" "),
                r.ms_per_frame.spread(),
                timed_frames
            );
        }
        for r in rows {
            if let Some(l) = r.candidate_lists {
                let per_frame = |n: u64| n as f64 / f64::from(timed_frames.max(1));
                out!(
                    "  self-collision's candidate lists over the {} timed frames of row '{}': {} checks ({:.1} a \
                     frame), {} rebuilds ({:.1} a frame), {} lists overflowed (a vertex whose list overflows \
                     searches the hash at every substep until the next rebuild)",
                    timed_frames,
                    r.label(),
                    l.checks,
                    per_frame(l.checks),
                    l.rebuilds,
                    per_frame(l.rebuilds),
                    l.overflowed_lists
                )?;
            }
        }
        out!(
            "  ms/frame: the median of the timings; spread: their interquartile range; added: the median of the \
                 paired differences with the row above where their middle half is above zero, else the range of that \
                 middle half (inside the noise)"
        )?;
    }
    if measured == 0 {
        anyhow::bail!("no breakdown was measured: every backend listed was skipped or refused (see above)");
    }
    if let Some(path) = &args.csv {
        cloth_backends::output::write_atomically(path, csv.as_bytes())?;
        out!("wrote {}", path.display())?;
    }
    Ok(())
}
