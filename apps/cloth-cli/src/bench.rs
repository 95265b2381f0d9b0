//! `cloth bench`: cost per frame of each backend on the drape scene at several grid sizes.
//!
//! A benchmark, not a test: it prints figures and writes a CSV, and asserts nothing about speed.

use std::io::Write;
use std::time::Instant;

use anyhow::{Context, Result};
use cloth_core::{Scene, SimError, Substeps};

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
    /// Substeps per frame.
    #[arg(long, default_value_t = 16)]
    substeps: u32,
    /// Frames timed per row (after one warm-up frame).
    #[arg(long, default_value_t = 10)]
    frames: u32,
    /// Adapter name filter for GPU backends.
    #[arg(long)]
    adapter: Option<String>,
    /// Also write the rows to this CSV file.
    #[arg(long)]
    csv: Option<std::path::PathBuf>,
}

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
    println!(
        "{:<8} {:>6} {:>9} {:>12} {:>16} {:>12} {:>11}  adapter",
        "backend", "grid", "substeps", "ms/frame", "vertex-substep/s", "submits/frm", "waits/frm"
    );
    let mut rows = Vec::new();
    for backend in chosen {
        for &n in &args.grids {
            let mut scene = Scene::default();
            scene.cloth.resolution = [n, n];
            scene.time.substeps = Substeps::Fixed(args.substeps);
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
                substeps: args.substeps,
                ms_per_frame: seconds * 1e3 / frames,
                vertex_substeps_per_s: (n as f64 * n as f64) * args.substeps as f64 * frames / seconds,
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
