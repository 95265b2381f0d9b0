//! One run of the study: an integrator at a step on a backend, its error against the reference
//! and its cost.

use std::time::Instant;

use cloth_backends::Backend;
use cloth_core::{ClothModel, CpuSimulatorF64, Energy, Integrator, Scene, SimError, Simulator, Substeps};

/// The reference run: f64 CPU, RK4, a step far below the sweep's.
pub struct Reference {
    positions: Vec<[f64; 3]>,
    /// Total energy at the end of the reference run, J.
    energy_j: f64,
    /// Scale of the energy drift: the magnitude of the initial total energy, J.
    energy_scale_j: f64,
    model: ClothModel,
}

impl Reference {
    /// Runs the reference for `frames` frames of `substeps` RK4 substeps in f64.
    pub fn new(base: &Scene, frames: u32, substeps: u32) -> anyhow::Result<Self> {
        let mut sim = CpuSimulatorF64::new(&with(base, Integrator::RungeKutta4, substeps))?;
        sim.advance(frames)?;
        let model = ClothModel::new(base);
        let energy_j = Energy::of(&model, &sim.read_state()?).total();
        let initial = Energy::of(&model, &CpuSimulatorF64::new(base)?.read_state()?).total();
        Ok(Self {
            positions: sim.positions().iter().map(|p| p.to_f64()).collect(),
            energy_j,
            energy_scale_j: initial.abs().max(1e-9),
            model,
        })
    }
}

/// The scene with another integrator and fixed substeps per frame.
pub fn with(base: &Scene, integrator: Integrator, substeps: u32) -> Scene {
    let mut s = base.clone();
    s.integrator = integrator;
    s.time.substeps = Substeps::Fixed(substeps);
    s
}

/// One row of the study.
#[derive(Clone, Debug)]
pub struct Row {
    /// The scene's name.
    pub scene: String,
    pub backend: String,
    pub integrator: Integrator,
    pub substeps: u32,
    /// Substep, s.
    pub dt: f64,
    /// RMS over the vertices of the distance to the reference's position, m.
    pub rms_error_m: f64,
    /// Largest such distance, m (NaN when any position is not finite).
    pub max_error_m: f64,
    /// (final total energy − the reference's) / |initial total energy|.
    pub energy_drift: f64,
    /// Energy the method dissipated beyond the reference's, J: the reference's final total
    /// energy minus the run's (negative when the run ends with more).
    pub energy_dissipated_j: f64,
    /// Solver iterations per substep, averaged over the run: conjugate-gradient iterations for
    /// backward Euler (over all its Newton iterations), sweeps for VBD; `None` for the others.
    pub solver_iterations_per_substep: Option<f64>,
    /// Largest |L/L0 − 1| over the springs at the end.
    pub max_strain: f64,
    /// Deepest penetration into a sphere over the run, m.
    pub max_penetration_m: f64,
    /// Every position and velocity finite at the end.
    pub finite: bool,
    /// Not finite, or the RMS error larger than the cloth's diagonal: the run blew up (an
    /// explicit integrator beyond its stable step ends with finite but meaningless positions).
    pub diverged: bool,
    /// Wall-clock time per simulated second, ms: from the first advance to the read-back.
    pub wall_ms_per_simulated_s: f64,
    /// GPU time per simulated second from timestamp queries, ms (GPU backends that have them).
    pub gpu_ms_per_simulated_s: Option<f64>,
}

impl Row {
    pub const CSV_HEADER: &str = "backend,integrator,substeps_per_frame,dt_s,rms_error_m,max_error_m,energy_drift,\
                                  max_strain,max_penetration_m,finite,cost_ms_per_simulated_s,cost_clock,\
                                  wall_ms_per_simulated_s,gpu_ms_per_simulated_s,scene,energy_dissipated_j,\
                                  solver_iterations_per_substep,diverged";

    /// The cost the study plots: GPU time where measured, wall-clock time otherwise.
    pub fn cost_ms(&self) -> f64 {
        self.gpu_ms_per_simulated_s.unwrap_or(self.wall_ms_per_simulated_s)
    }

    /// Which clock [`Row::cost_ms`] comes from.
    pub fn cost_clock(&self) -> &'static str {
        if self.gpu_ms_per_simulated_s.is_some() { "gpu" } else { "wall" }
    }

    /// Whether the run is usable on an error-against-cost plot.
    pub fn plottable(&self) -> bool {
        !self.diverged && self.rms_error_m.is_finite() && self.rms_error_m > 0.0 && self.cost_ms() > 0.0
    }

    pub fn csv(&self) -> String {
        format!(
            "{},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{},{:.4},{},{:.4},{},{},{:.6e},{},{}",
            self.backend,
            self.integrator.name(),
            self.substeps,
            self.dt,
            self.rms_error_m,
            self.max_error_m,
            self.energy_drift,
            self.max_strain,
            self.max_penetration_m,
            self.finite,
            self.cost_ms(),
            self.cost_clock(),
            self.wall_ms_per_simulated_s,
            self.gpu_ms_per_simulated_s.map(|g| format!("{g:.4}")).unwrap_or_default(),
            self.scene.replace(',', ";"),
            self.energy_dissipated_j,
            self.solver_iterations_per_substep.map(|n| format!("{n:.2}")).unwrap_or_default(),
            self.diverged
        )
    }

    pub fn print(&self) -> std::io::Result<()> {
        let gpu = self.gpu_ms_per_simulated_s.map(|g| format!("{g:.2}")).unwrap_or_else(|| "-".into());
        out!(
            "{:<8} {:<14} {:>8} {:>10.3e} {:>11.3e} {:>11.3e} {:>12.3e} {:>10.3e} {:>11.3e} {:>7} {:>11.2} {:>11} {:>8}",
            self.backend,
            self.integrator.name(),
            self.substeps,
            self.dt,
            self.rms_error_m,
            self.max_error_m,
            self.energy_drift,
            self.max_strain,
            self.max_penetration_m,
            self.finite,
            self.wall_ms_per_simulated_s,
            gpu,
            self.solver_iterations_per_substep.map(|n| format!("{n:.1}")).unwrap_or_else(|| "-".into())
        )
    }
}

pub fn print_header() -> std::io::Result<()> {
    out!(
        "{:<8} {:<14} {:>8} {:>10} {:>11} {:>11} {:>12} {:>10} {:>11} {:>7} {:>11} {:>11} {:>8}",
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
        "wall ms/s",
        "GPU ms/s",
        "iter/sub"
    )
}

/// Why a run did not give a row.
pub enum RunError {
    /// The backend cannot run this here (no adapter, or something it does not support).
    Skipped(String),
    /// Anything else: the study stops.
    Failed(anyhow::Error),
}

impl From<SimError> for RunError {
    fn from(e: SimError) -> Self {
        match e {
            SimError::Unsupported { .. } | SimError::Unavailable { .. } => RunError::Skipped(e.to_string()),
            e => RunError::Failed(e.into()),
        }
    }
}

/// Frames between two reads of the GPU timer: the device holds 256 advances' timestamps.
const TIMER_READ_EVERY: u32 = 200;

/// Runs `integrator` at `substeps` per frame for `frames` frames, one advance per frame (one
/// submission each on the GPU, as an interactive application runs), and measures it. Returns
/// the row and the adapter in words.
pub fn run(
    backend: &Backend,
    tuning: &cloth_gpu::GpuTuning,
    base: &Scene,
    integrator: Integrator,
    substeps: u32,
    frames: u32,
    reference: &Reference,
) -> Result<(Row, String), RunError> {
    let scene = with(base, integrator, substeps);
    // The f64 backend is driven as its own type so its positions keep all 53 bits (the trait's
    // read-back is f32).
    let mut f64_sim = None;
    let mut any_sim = None;
    let sim: &mut dyn Simulator = if backend.name == "cpu-f64" {
        f64_sim.insert(CpuSimulatorF64::new(&scene)?)
    } else {
        any_sim.insert((backend.create)(&scene, tuning)?).as_mut()
    };
    let adapter_name = sim.adapter_name();
    let timed = sim.set_gpu_timing(true);
    let mut gpu_seconds = 0.0;
    let start = Instant::now();
    for frame in 1..=frames {
        sim.advance(1)?;
        if timed && frame % TIMER_READ_EVERY == 0 {
            gpu_seconds += sim.take_gpu_seconds()?.unwrap_or(0.0);
        }
    }
    let state = sim.read_state()?;
    let seconds = start.elapsed().as_secs_f64();
    if timed {
        gpu_seconds += sim.take_gpu_seconds()?.unwrap_or(0.0);
    }
    let diagnostics = sim.diagnostics()?;
    let penetration = diagnostics.max_penetration_m;
    let solver_iterations_per_substep = diagnostics.solver.filter(|s| s.substeps > 0).and_then(|s| match integrator {
        Integrator::BackwardEuler => Some(s.cg as f64 / s.substeps as f64),
        Integrator::Vbd => Some(s.vbd as f64 / s.substeps as f64),
        _ => None,
    });
    let positions: Vec<[f64; 3]> = match &f64_sim {
        Some(f64_sim) => f64_sim.positions().iter().map(|p| p.to_f64()).collect(),
        None => state.positions.iter().map(|p| p.map(f64::from)).collect(),
    };
    let errors: Vec<f64> = positions
        .iter()
        .zip(&reference.positions)
        .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt())
        .collect();
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt();
    // NaN-propagating maximum: a blown-up run must not report a small error.
    let max_error =
        errors.iter().copied().fold(0.0, |a: f64, e| if e.is_nan() || a.is_nan() { f64::NAN } else { a.max(e) });
    let simulated_s = frames as f64 * base.time.frame_dt;
    let energy = Energy::of(&reference.model, &state).total();
    let finite = state.non_finite_count() == 0;
    let row = Row {
        scene: base.name.clone(),
        backend: backend.name.to_string(),
        integrator,
        substeps,
        dt: scene.substep_dt(),
        rms_error_m: rms,
        max_error_m: max_error,
        energy_drift: (energy - reference.energy_j) / reference.energy_scale_j,
        energy_dissipated_j: reference.energy_j - energy,
        solver_iterations_per_substep,
        max_strain: reference.model.max_strain(&state),
        max_penetration_m: penetration,
        finite,
        diverged: !finite || rms.is_nan() || rms > base.cloth.size[0].hypot(base.cloth.size[1]),
        wall_ms_per_simulated_s: seconds * 1e3 / simulated_s,
        gpu_ms_per_simulated_s: timed.then(|| gpu_seconds * 1e3 / simulated_s),
    };
    Ok((row, adapter_name))
}
