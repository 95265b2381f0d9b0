//! The largest stable substep of an integrator on a backend, found by bisection, against the
//! bounds the core predicts.

use cloth_backends::Backend;
use cloth_core::{ClothModel, Integrator, Scene, SimError, Substeps, stability};

/// Substeps a trial of an explicit integrator runs from the scene's start.
const TRIAL_SUBSTEPS: u32 = 2000;
/// Substeps a trial of an integrator without a stability limit (XPBD, backward Euler, VBD) runs:
/// at 10 to 1000 times the explicit limit that is already seconds to hours of simulated time,
/// and each of their substeps is tens to hundreds of dispatches, or of solver iterations.
const UNLIMITED_TRIAL_SUBSTEPS: u32 = 200;
/// Substeps per `advance` call of a trial (one command buffer each on the GPU).
const CHUNK_SUBSTEPS: u32 = 100;
/// Bisection steps (geometric, between a quarter and 8 times the prediction).
const BISECTION_STEPS: u32 = 14;
/// Multiples of the explicit (Euler) limit XPBD is tried at.
const XPBD_MULTIPLES: [f64; 3] = [10.0, 100.0, 1000.0];

/// What the bisection found for one integrator on one backend.
pub struct Limit {
    pub backend: String,
    pub integrator: Integrator,
    /// `λ_max(M⁻¹K)` estimate by power iteration, turned into a step bound, s (∞ for XPBD).
    pub spectral_s: f64,
    /// Gershgorin bound used by validation and `Auto` substeps, s (∞ for XPBD).
    pub safe_s: f64,
    pub outcome: Outcome,
}

/// The measured side of a [`Limit`].
pub enum Outcome {
    /// Largest stable substep found, s.
    Measured(f64),
    /// Unstable even at a quarter of the prediction.
    UnstableBelowBracket,
    /// No limit predicted: stable at every multiple of the explicit limit tried (the largest, ×).
    StableAt(f64),
    /// Diverged at this multiple of the explicit limit.
    DivergedAt(f64),
    /// The backend could not run it, with the reason.
    Skipped(String),
}

impl std::fmt::Display for Limit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let head = format!("{:<8} {:<7}", self.backend, self.integrator.name());
        match &self.outcome {
            Outcome::Measured(h) => write!(
                f,
                "{head} spectral {:.3e} s, measured {h:.3e} s (ratio {:.2}); safe bound {:.3e} s (ratio {:.2})",
                self.spectral_s,
                h / self.spectral_s,
                self.safe_s,
                h / self.safe_s
            ),
            Outcome::UnstableBelowBracket => {
                write!(f, "{head} unstable even at a quarter of the spectral bound {:.3e} s", self.spectral_s)
            }
            Outcome::StableAt(m) => write!(f, "{head} no limit predicted; stable at {m}x the explicit limit"),
            Outcome::DivergedAt(m) => write!(f, "{head} no limit predicted, yet diverged at {m}x the explicit limit"),
            Outcome::Skipped(reason) => write!(f, "{head} skipped: {reason}"),
        }
    }
}

/// At most the vertex-substeps [`largest_stable_substep`] runs for `integrator` on `scene`: the
/// bracket's first trial and every bisection step (or one trial per multiple where no limit is
/// predicted, fewer), each a fresh run of `TRIAL_SUBSTEPS` substeps (`UNLIMITED_TRIAL_SUBSTEPS`
/// for the integrators without a stability limit).
pub fn planned_vertex_substeps(scene: &Scene, integrator: Integrator) -> u64 {
    let substeps = if integrator.unconditionally_stable() { UNLIMITED_TRIAL_SUBSTEPS } else { TRIAL_SUBSTEPS };
    let trials = (1 + BISECTION_STEPS).max(XPBD_MULTIPLES.len() as u32);
    (scene.vertex_count() as u64).saturating_mul(u64::from(trials) * u64::from(substeps))
}

/// Whether a trial (`TRIAL_SUBSTEPS`, or `UNLIMITED_TRIAL_SUBSTEPS`, substeps of `h` from the scene's
/// start) stays finite and within 1 km.
fn stable(
    backend: &Backend,
    tuning: &cloth_gpu::GpuTuning,
    base: &Scene,
    integrator: Integrator,
    h: f64,
) -> Result<bool, SimError> {
    let mut scene = base.clone();
    scene.integrator = integrator;
    scene.time.frame_dt = h;
    scene.time.substeps = Substeps::Fixed(1);
    let mut sim = match (backend.create)(&scene, tuning) {
        Ok(sim) => sim,
        // Validation refuses a step it predicts unstable only as a warning; anything else stops.
        Err(e @ (SimError::Unsupported { .. } | SimError::Unavailable { .. })) => return Err(e),
        Err(SimError::Scene(_)) => return Ok(false),
        Err(e) => return Err(e),
    };
    let substeps = if integrator.unconditionally_stable() { UNLIMITED_TRIAL_SUBSTEPS } else { TRIAL_SUBSTEPS };
    for _ in 0..substeps / CHUNK_SUBSTEPS {
        sim.advance(CHUNK_SUBSTEPS)?;
    }
    let state = sim.read_state()?;
    Ok(state.positions.iter().all(|p| p.iter().all(|c| c.is_finite() && c.abs() < 1e3)))
}

/// Bisects the largest stable substep of `integrator` on `backend`.
pub fn largest_stable_substep(
    backend: &Backend,
    tuning: &cloth_gpu::GpuTuning,
    base: &Scene,
    integrator: Integrator,
) -> anyhow::Result<Limit> {
    let mut scene = base.clone();
    scene.integrator = integrator;
    let spectral_s = stability::spectral_stable_substep(&ClothModel::new(&scene));
    let safe_s = stability::stable_substep(&scene);
    let limit = |outcome| Limit { backend: backend.name.to_string(), integrator, spectral_s, safe_s, outcome };
    let trial = |h: f64| stable(backend, tuning, base, integrator, h);
    let skipped = |e: SimError| -> anyhow::Result<Limit> {
        match e {
            SimError::Unsupported { .. } | SimError::Unavailable { .. } => Ok(limit(Outcome::Skipped(e.to_string()))),
            e => Err(e.into()),
        }
    };
    if !spectral_s.is_finite() {
        let explicit = stability::spectral_stable_substep(&ClothModel::new(&Scene {
            integrator: Integrator::SemiImplicitEuler,
            ..scene.clone()
        }));
        let mut largest = 0.0;
        for m in XPBD_MULTIPLES {
            match trial(m * explicit) {
                Ok(true) => largest = m,
                Ok(false) => return Ok(limit(Outcome::DivergedAt(m))),
                Err(e) => return skipped(e),
            }
        }
        return Ok(limit(Outcome::StableAt(largest)));
    }
    let (mut lo, mut hi) = (0.25 * spectral_s, 8.0 * spectral_s);
    match trial(lo) {
        Ok(true) => {}
        Ok(false) => return Ok(limit(Outcome::UnstableBelowBracket)),
        Err(e) => return skipped(e),
    }
    for _ in 0..BISECTION_STEPS {
        let mid = (lo * hi).sqrt();
        match trial(mid) {
            Ok(true) => lo = mid,
            Ok(false) => hi = mid,
            Err(e) => return skipped(e),
        }
    }
    Ok(limit(Outcome::Measured(lo)))
}
