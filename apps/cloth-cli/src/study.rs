//! `cloth study accuracy`: what accuracy costs in time.
//!
//! Sweeps integrator × substeps per frame (and f32/f64 on the CPU) over a fixed simulated time,
//! and compares every run with a reference run: the f64 CPU reference with RK4 and 8 times the
//! finest step of the sweep. Prints a table, writes a CSV, and measures each integrator's largest
//! stable step by bisection against the bound the core predicts.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use cloth_backends as backends;
use cloth_core::{
    ClothModel, ClothState, CpuSimulatorF64, Energy, Integrator, Scene, SimError, Simulator, Substeps, stability,
};

/// Options of `cloth study accuracy`.
#[derive(clap::Args)]
pub struct AccuracyArgs {
    /// Scene to study (default: scenes/hanging.ron, smooth and without contact).
    scene: Option<PathBuf>,
    /// Backends to time (comma-separated): `cpu` runs f32 and `cpu-f64` f64.
    #[arg(long, value_delimiter = ',', default_values_t = vec!["cpu".to_string(), "cpu-f64".to_string()])]
    backends: Vec<String>,
    /// Simulated time of every run, s.
    #[arg(long, default_value_t = 0.5)]
    duration: f64,
    /// Substeps per frame to sweep (comma-separated).
    #[arg(long, value_delimiter = ',', default_values_t = vec![4u32, 8, 16, 32, 64])]
    substeps: Vec<u32>,
    /// Grid resolution override, e.g. 16x16.
    #[arg(long, value_parser = crate::parse_grid)]
    grid: Option<[u32; 2]>,
    /// CSV output.
    #[arg(long, default_value = "out/accuracy.csv")]
    csv: PathBuf,
}

struct Row {
    backend: String,
    integrator: Integrator,
    substeps: u32,
    dt: f64,
    rms_error_m: f64,
    max_error_m: f64,
    energy_drift: f64,
    max_strain: f64,
    max_penetration_m: f64,
    finite: bool,
    ms_per_simulated_s: f64,
}

fn max_strain(model: &ClothModel, state: &ClothState) -> f64 {
    model
        .springs
        .iter()
        .map(|s| {
            let (a, b) = (state.positions[s.a as usize], state.positions[s.b as usize]);
            let l = (0..3).map(|k| (a[k] as f64 - b[k] as f64).powi(2)).sum::<f64>().sqrt();
            (l / s.rest_length - 1.0).abs()
        })
        .fold(0.0, f64::max)
}

/// The result of one run: positions in f64 (exact for the f64 reference; the f32 read-back
/// otherwise), the state, max penetration and wall time.
struct Outcome {
    positions: Vec<[f64; 3]>,
    state: ClothState,
    max_penetration_m: f64,
    seconds: f64,
}

/// Runs `scene` for `frames` frames on a backend. The `cpu-f64` backend is run directly so its
/// positions keep all 53 bits (the trait's read-back is f32).
fn run(backend: &backends::Backend, scene: &Scene, frames: u32) -> Result<Outcome, SimError> {
    if backend.name == "cpu-f64" {
        let mut sim = CpuSimulatorF64::new(scene)?;
        let start = Instant::now();
        sim.advance(frames)?;
        let seconds = start.elapsed().as_secs_f64();
        let positions = sim.positions().iter().map(|p| p.to_f64()).collect();
        return Ok(Outcome {
            positions,
            state: sim.read_state()?,
            max_penetration_m: sim.diagnostics()?.max_penetration_m,
            seconds,
        });
    }
    let mut sim = (backend.create)(scene, None)?;
    let start = Instant::now();
    sim.advance(frames)?;
    let state = sim.read_state()?;
    let seconds = start.elapsed().as_secs_f64();
    let positions = state.positions.iter().map(|p| p.map(f64::from)).collect();
    Ok(Outcome { positions, state, max_penetration_m: sim.diagnostics()?.max_penetration_m, seconds })
}

pub fn accuracy(args: AccuracyArgs) -> Result<()> {
    let path = args.scene.clone().unwrap_or_else(|| PathBuf::from("scenes/hanging.ron"));
    let mut base = Scene::load(&path).with_context(|| format!("cannot use scene {}", path.display()))?;
    if let Some(g) = args.grid {
        base.cloth.resolution = g;
    }
    let frames = (args.duration / base.time.frame_dt).round().max(1.0) as u32;
    let finest = args.substeps.iter().copied().max().unwrap_or(64);
    let with = |integrator: Integrator, substeps: u32| {
        let mut s = base.clone();
        s.integrator = integrator;
        s.time.substeps = Substeps::Fixed(substeps);
        s
    };
    eprintln!(
        "reference: f64 CPU, RK4, {} substeps per frame, {frames} frames of {:.4} s",
        finest * 8,
        base.time.frame_dt
    );
    let reference_scene = with(Integrator::RungeKutta4, finest * 8);
    let mut reference_sim = CpuSimulatorF64::new(&reference_scene)?;
    reference_sim.advance(frames)?;
    let reference = reference_sim.read_state()?;
    let reference_positions: Vec<[f64; 3]> = reference_sim.positions().iter().map(|p| p.to_f64()).collect();
    let model = ClothModel::new(&base);
    let e0 = Energy::of(&model, &CpuSimulatorF64::new(&base)?.read_state()?).total();
    let e_ref = Energy::of(&model, &reference).total();
    let energy_scale = e0.abs().max(1e-9);

    println!(
        "{:<8} {:<7} {:>8} {:>10} {:>11} {:>11} {:>12} {:>10} {:>11} {:>7} {:>12}",
        "backend",
        "method",
        "substeps",
        "dt (s)",
        "rms err (m)",
        "max err (m)",
        "energy drift",
        "max strain",
        "max pen (m)",
        "finite",
        "ms / sim s"
    );
    let mut rows = Vec::new();
    for name in &args.backends {
        let backend = backends::find(name).map_err(anyhow::Error::msg)?;
        for integrator in Integrator::ALL {
            for &n in &args.substeps {
                let scene = with(integrator, n);
                let Outcome { positions, state, max_penetration_m: penetration, seconds } =
                    match run(&backend, &scene, frames) {
                        Ok(r) => r,
                        Err(e @ (SimError::Unsupported { .. } | SimError::Unavailable { .. })) => {
                            println!("{:<8} {:<7} skipped: {e}", name, integrator.name());
                            break;
                        }
                        Err(e) => return Err(e.into()),
                    };
                let errors: Vec<f64> = positions
                    .iter()
                    .zip(&reference_positions)
                    .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt())
                    .collect();
                let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
                // NaN-propagating maximum: a blown-up run must not report a small error.
                let max_error = errors
                    .iter()
                    .copied()
                    .fold(0.0, |a: f64, e| if e.is_nan() || a.is_nan() { f64::NAN } else { a.max(e) });
                let row = Row {
                    backend: name.clone(),
                    integrator,
                    substeps: n,
                    dt: scene.substep_dt(),
                    rms_error_m: rms,
                    max_error_m: max_error,
                    energy_drift: (Energy::of(&model, &state).total() - e_ref) / energy_scale,
                    max_strain: max_strain(&model, &state),
                    max_penetration_m: penetration,
                    finite: state.non_finite_count() == 0,
                    ms_per_simulated_s: seconds * 1e3 / (frames as f64 * base.time.frame_dt),
                };
                println!(
                    "{:<8} {:<7} {:>8} {:>10.3e} {:>11.3e} {:>11.3e} {:>12.3e} {:>10.3e} {:>11.3e} {:>7} {:>12.2}",
                    row.backend,
                    row.integrator.name(),
                    row.substeps,
                    row.dt,
                    row.rms_error_m,
                    row.max_error_m,
                    row.energy_drift,
                    row.max_strain,
                    row.max_penetration_m,
                    row.finite,
                    row.ms_per_simulated_s
                );
                rows.push(row);
            }
        }
    }

    println!(
        "\nlargest stable substep (bisection, 2000 substeps from rest, CPU f64) against the predictions: \
         the spectral estimate (power iteration on M⁻¹K) and the safe Gershgorin bound:"
    );
    for integrator in Integrator::ALL {
        let mut scene = with(integrator, 1);
        let predicted = stability::spectral_stable_substep(&ClothModel::new(&scene));
        let safe = stability::stable_substep(&scene);
        if !predicted.is_finite() {
            println!("  {:<7} unconditionally stable (no bound to test)", integrator.name());
            continue;
        }
        let mut stable = |h: f64| {
            scene.time.frame_dt = h;
            let Ok(mut sim) = CpuSimulatorF64::new(&scene) else { return false };
            if sim.advance(2000).is_err() {
                return false;
            }
            sim.positions().iter().all(|p| p.is_finite() && p.length() < 1e3)
        };
        let (mut lo, mut hi) = (0.25 * predicted, 8.0 * predicted);
        if !stable(lo) {
            println!("  {:<7} unstable even at a quarter of the bound {predicted:.3e} s", integrator.name());
            continue;
        }
        for _ in 0..14 {
            let mid = (lo * hi).sqrt();
            if stable(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        println!(
            "  {:<7} spectral {predicted:.3e} s, measured {lo:.3e} s (ratio {:.2}); safe bound {safe:.3e} s (ratio {:.2})",
            integrator.name(),
            lo / predicted,
            lo / safe
        );
    }

    if let Some(dir) = args.csv.parent() {
        std::fs::create_dir_all(dir).ok();
    }
    let mut f = std::fs::File::create(&args.csv).with_context(|| format!("cannot create {}", args.csv.display()))?;
    writeln!(
        f,
        "backend,integrator,substeps_per_frame,dt_s,rms_error_m,max_error_m,energy_drift,max_strain,max_penetration_m,finite,ms_per_simulated_s"
    )?;
    for r in &rows {
        writeln!(
            f,
            "{},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{},{:.4}",
            r.backend,
            r.integrator.name(),
            r.substeps,
            r.dt,
            r.rms_error_m,
            r.max_error_m,
            r.energy_drift,
            r.max_strain,
            r.max_penetration_m,
            r.finite,
            r.ms_per_simulated_s
        )?;
    }
    println!("wrote {}", args.csv.display());
    let svg = args.csv.with_extension("svg");
    plot(&rows, &svg)?;
    println!("wrote {}", svg.display());
    Ok(())
}

/// Indices of the rows on the Pareto front: no other finite row is both cheaper and more
/// accurate.
fn pareto_front(rows: &[Row]) -> Vec<usize> {
    let ok = |r: &Row| r.finite && r.rms_error_m.is_finite() && r.rms_error_m > 0.0;
    (0..rows.len())
        .filter(|&i| {
            ok(&rows[i])
                && !rows.iter().any(|o| {
                    ok(o)
                        && o.ms_per_simulated_s <= rows[i].ms_per_simulated_s
                        && o.rms_error_m <= rows[i].rms_error_m
                        && (o.ms_per_simulated_s < rows[i].ms_per_simulated_s || o.rms_error_m < rows[i].rms_error_m)
                })
        })
        .collect()
}

/// Error against cost, log–log, one curve per backend and integrator, the Pareto front circled.
fn plot(rows: &[Row], path: &std::path::Path) -> Result<()> {
    use plotters::prelude::*;
    let finite: Vec<&Row> =
        rows.iter().filter(|r| r.finite && r.rms_error_m.is_finite() && r.rms_error_m > 0.0).collect();
    if finite.is_empty() {
        return Ok(());
    }
    let (x0, x1) = finite
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), r| (a.min(r.ms_per_simulated_s), b.max(r.ms_per_simulated_s)));
    let (y0, y1) = finite.iter().fold((f64::MAX, f64::MIN), |(a, b), r| (a.min(r.rms_error_m), b.max(r.rms_error_m)));
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption("Error against cost (RMS position error vs an f64 RK4 reference)", ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0 * 0.8..x1 * 1.25).log_scale(), (y0 * 0.5..y1 * 2.0).log_scale())
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(240, 240, 240))
        .x_desc("wall ms per simulated second")
        .y_desc("RMS position error (m)")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // One colour per integrator; f32 runs solid, f64 runs lighter.
    let color_of = |r: &Row| {
        let base = match r.integrator {
            Integrator::SemiImplicitEuler => RGBColor(220, 30, 30),
            Integrator::VelocityVerlet => RGBColor(30, 60, 220),
            Integrator::RungeKutta4 => RGBColor(0, 150, 0),
            Integrator::Xpbd => RGBColor(255, 140, 0),
        };
        if r.backend == "cpu-f64" { base.mix(0.45).to_rgba() } else { base.to_rgba() }
    };
    /// One curve: its label, colour and (cost, error) points.
    type Series = (String, RGBAColor, Vec<(f64, f64)>);
    let mut series: Vec<Series> = Vec::new();
    for r in &finite {
        let key = format!("{} {}", r.backend, r.integrator.name());
        match series.iter_mut().find(|(k, _, _)| *k == key) {
            Some((_, _, points)) => points.push((r.ms_per_simulated_s, r.rms_error_m)),
            None => series.push((key, color_of(r), vec![(r.ms_per_simulated_s, r.rms_error_m)])),
        }
    }
    for (name, color, points) in &series {
        let color = *color;
        chart
            .draw_series(LineSeries::new(points.iter().copied(), color.stroke_width(2)))
            .map_err(|e| anyhow::anyhow!("{e}"))?
            .label(name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))
            .map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    chart
        .draw_series(
            pareto_front(rows)
                .into_iter()
                .map(|i| Circle::new((rows[i].ms_per_simulated_s, rows[i].rms_error_m), 9, BLACK.stroke_width(2))),
        )
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .label("Pareto front")
        .legend(|(x, y)| Circle::new((x + 10, y), 6, BLACK.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}
