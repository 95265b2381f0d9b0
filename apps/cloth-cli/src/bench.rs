//! `cloth bench`: cost per frame of each backend on the drape scene at several grid sizes, and
//! with `--effects`, what each effect of a scene costs (the bare cloth, then each effect added).
//!
//! A benchmark, not a test: it prints figures and writes a CSV, and asserts nothing about speed.

use std::io::Write;
use std::time::Instant;

use anyhow::{Context, Result};
use cloth_backends::effect_cost;
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
    /// Substeps per frame (default 16; with `--effects`, the scene's own).
    #[arg(long)]
    substeps: Option<u32>,
    /// Frames timed per row (after one warm-up frame).
    #[arg(long, default_value_t = 10)]
    frames: u32,
    /// Adapter name filter for GPU backends.
    #[arg(long)]
    adapter: Option<String>,
    /// Also write the rows to this CSV file.
    #[arg(long)]
    csv: Option<std::path::PathBuf>,
    /// Instead, print what each effect costs: the bare cloth, then each effect of the scene
    /// added in turn (ms per frame per backend, at each of `--grids`; the scene's own
    /// substeps unless `--substeps` is given).
    #[arg(long)]
    effects: bool,
    /// The scene of `--effects` (default: scenes/flag.ron, which has every effect).
    #[arg(long, requires = "effects")]
    scene: Option<std::path::PathBuf>,
}

/// The default scene of `--effects`: every effect at once (a copy of `scenes/flag.ron`).
const FLAG_SCENE: &str = include_str!("../../../scenes/flag.ron");

struct Row {
    backend: String,
    adapter: String,
    grid: u32,
    substeps: u32,
    ms_per_frame: f64,
    vertex_substeps_per_s: f64,
    submissions_per_frame: f64,
    host_waits_per_frame: f64,
}

pub fn run(args: BenchArgs) -> Result<()> {
    let all = backends::all();
    let chosen: Vec<&backends::Backend> = if args.backends.is_empty() {
        all.iter().filter(|b| b.name != "cpu-f64").collect()
    } else {
        args.backends
            .iter()
            .map(|n| all.iter().find(|b| b.name == n).with_context(|| format!("unknown backend '{n}'")))
            .collect::<Result<_>>()?
    };
    if args.effects {
        return effects(&args, &chosen);
    }
    let substeps = args.substeps.unwrap_or(16);
    println!(
        "{:<8} {:>6} {:>9} {:>12} {:>16} {:>12} {:>11}  adapter",
        "backend", "grid", "substeps", "ms/frame", "vertex-substep/s", "submits/frm", "waits/frm"
    );
    let mut rows = Vec::new();
    for backend in chosen {
        for &n in &args.grids {
            let mut scene = Scene::default();
            scene.cloth.resolution = [n, n];
            scene.time.substeps = Substeps::Fixed(substeps);
            let mut sim = match (backend.create)(&scene, args.adapter.as_deref()) {
                Ok(sim) => sim,
                Err(SimError::Unavailable { reason, .. }) => {
                    println!("{:<8} skipped: {reason}", backend.name);
                    break;
                }
                Err(e) => {
                    println!("{:<8} {:>6} refused: {e}", backend.name, format!("{n}²"));
                    continue;
                }
            };
            // Warm-up: pipeline compilation, first-use allocations.
            sim.advance(1)?;
            sim.diagnostics()?;
            let mut submissions = 0u64;
            let mut waits = 0u64;
            let start = Instant::now();
            for _ in 0..args.frames {
                sim.advance(1)?;
                let counts = sim.last_advance_counts();
                submissions += counts.submissions as u64;
                waits += counts.host_waits as u64;
            }
            // One wait at the end so the time covers the work, not just its submission (counted
            // for GPU backends; the CPU has nothing to wait for).
            sim.diagnostics()?;
            if submissions > 0 {
                waits += 1;
            }
            let seconds = start.elapsed().as_secs_f64();
            let frames = args.frames.max(1) as f64;
            let row = Row {
                backend: backend.name.to_string(),
                adapter: sim.adapter_name(),
                grid: n,
                substeps,
                ms_per_frame: seconds * 1e3 / frames,
                vertex_substeps_per_s: (n as f64 * n as f64) * substeps as f64 * frames / seconds,
                submissions_per_frame: submissions as f64 / frames,
                host_waits_per_frame: waits as f64 / frames,
            };
            println!(
                "{:<8} {:>6} {:>9} {:>12.3} {:>16.3e} {:>12.2} {:>11.2}  {}",
                row.backend,
                format!("{n}²"),
                row.substeps,
                row.ms_per_frame,
                row.vertex_substeps_per_s,
                row.submissions_per_frame,
                row.host_waits_per_frame,
                row.adapter
            );
            rows.push(row);
        }
    }
    if let Some(path) = args.csv {
        let mut f = std::fs::File::create(&path).with_context(|| format!("cannot create {}", path.display()))?;
        writeln!(
            f,
            "backend,adapter,grid,substeps,ms_per_frame,vertex_substeps_per_s,submissions_per_frame,host_waits_per_frame"
        )?;
        for r in rows {
            writeln!(
                f,
                "{},\"{}\",{},{},{:.6},{:.6e},{:.3},{:.3}",
                r.backend,
                r.adapter.replace('"', "'"),
                r.grid,
                r.substeps,
                r.ms_per_frame,
                r.vertex_substeps_per_s,
                r.submissions_per_frame,
                r.host_waits_per_frame
            )?;
        }
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// `cloth bench --effects`: the per-effect breakdown of a scene on each backend and grid.
fn effects(args: &BenchArgs, chosen: &[&backends::Backend]) -> Result<()> {
    let base = match &args.scene {
        Some(path) => Scene::load(path).with_context(|| format!("cannot use scene {}", path.display()))?,
        None => Scene::from_ron_str(FLAG_SCENE).context("the built-in flag scene")?,
    };
    let mut csv = String::from("backend,adapter,grid,substeps,row,effects,ms_per_frame,added_ms,timer\n");
    for backend in chosen {
        for &n in &args.grids {
            let mut scene = base.clone();
            // Square cells: the longer side gets `n` vertices.
            let [w, h] = scene.cloth.size;
            scene.cloth.resolution = if w >= h {
                [n, ((n as f64 * h / w).round() as u32).max(2)]
            } else {
                [((n as f64 * w / h).round() as u32).max(2), n]
            };
            if let Some(substeps) = args.substeps {
                scene.time.substeps = Substeps::Fixed(substeps);
            }
            scene.validate().with_context(|| format!("the scene '{}' at grid {n}", scene.name))?;
            let [nx, ny] = scene.cloth.resolution;
            let bar = ProgressBar::new(effect_cost::steps(&scene).len() as u64).with_style(
                ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} rows")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar.set_message(format!("{} {nx}x{ny}", backend.name));
            let breakdown =
                match effect_cost::measure(&scene, backend, args.adapter.as_deref(), args.frames, |done, _| {
                    bar.set_position(done as u64)
                }) {
                    Ok(rows) => rows,
                    Err(SimError::Unavailable { reason, .. }) => {
                        bar.finish_and_clear();
                        println!("{:<8} skipped: {reason}", backend.name);
                        break;
                    }
                    Err(e) => {
                        bar.finish_and_clear();
                        println!("{:<8} {nx}x{ny} refused: {e}", backend.name);
                        continue;
                    }
                };
            bar.finish_and_clear();
            let (adapter, substeps, timer, rows) =
                (&breakdown.adapter, breakdown.substeps, breakdown.timer(), &breakdown.rows);
            println!(
                "\n{} on {adapter}: scene '{}', {nx}x{ny} vertices, {substeps} substeps per frame, {} frames, {timer}",
                backend.name, scene.name, args.frames
            );
            println!("  {:<22} {:>10} {:>10}  share of the whole", "row", "ms/frame", "added ms");
            let whole = rows.last().map_or(1.0, |r| r.ms_per_frame).max(f64::MIN_POSITIVE);
            for r in rows {
                let share = if r.added.is_some() { r.added_ms / whole } else { r.ms_per_frame / whole };
                let bar = "#".repeat((share.max(0.0) * 40.0).round() as usize);
                println!(
                    "  {:<22} {:>10.3} {:>+10.3}  {bar} {:.0}%",
                    r.label(),
                    r.ms_per_frame,
                    r.added_ms,
                    share * 100.0
                );
                csv += &format!(
                    "{},\"{}\",{nx}x{ny},{substeps},{},{},{:.6},{:.6},{timer}\n",
                    backend.name,
                    adapter.replace('"', "'"),
                    r.label(),
                    r.effects.iter().map(|e| format!("{e:?}")).collect::<Vec<_>>().join(" "),
                    r.ms_per_frame,
                    r.added_ms
                );
            }
        }
    }
    if let Some(path) = &args.csv {
        std::fs::write(path, csv).with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
