//! What `cloth bench` measures: how many vertex-substeps per second a backend runs on the drape
//! scene at a given grid and step, the GPU and CPU time per frame, the submissions and host waits
//! per frame, and how close that comes to the device's memory-bandwidth ceiling.

use std::time::Instant;

use cloth_core::scene::Substeps;
use cloth_core::{Scene, SimError};

use crate::Backend;
use crate::timing::Samples;

/// The bytes per vertex a force-based substep moves at least in the layout the backends share:
/// read its position and velocity (two 16-byte `vec4`s) and write them (two more). Everything
/// else (neighbours, parameters, springs) can come from caches. At a copy bandwidth of `B`
/// bytes/s the ceiling is `B / 64` vertex-substeps per second. Semi-implicit Euler's packed state
/// (`cloth_gpu::geometry`)
/// moves 48 bytes (six floats in, six out: [`PACKED_BYTES_PER_VERTEX_SUBSTEP`]) in the substeps
/// inside a submission, so it can pass this ceiling; the fraction is still computed against 64,
/// so rows stay comparable.
pub const MIN_BYTES_PER_VERTEX_SUBSTEP: f64 = 64.0;

/// Bytes per vertex a substep on semi-implicit Euler's packed state moves: 24 read, 24 written.
pub const PACKED_BYTES_PER_VERTEX_SUBSTEP: f64 = 2.0 * cloth_gpu::geometry::PACKED_VERTEX_BYTES as f64;

/// The resolution-scaled step is `dt = SCALED_STEP_TIMES_N / n` s on an `n × n` grid: with the
/// cloth's size and total mass fixed, a vertex's mass goes as `1/n²` and the stable step as `1/n`.
pub const SCALED_STEP_TIMES_N: f64 = 0.04;

/// How a benchmark row picks its substeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepRule {
    /// This many substeps per frame.
    Fixed(u32),
    /// The resolution-scaled step `dt = 0.04/n`: `round(frame_dt · n / 0.04)` substeps per frame
    /// (53 on a 128² grid at 60 frames per second).
    Scaled,
}

impl std::str::FromStr for StepRule {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "scaled" => Ok(Self::Scaled),
            _ => match s.parse::<u32>() {
                Ok(n) if n > 0 => Ok(Self::Fixed(n)),
                _ => Err(format!("'{s}' is neither a positive number of substeps nor 'scaled'")),
            },
        }
    }
}

impl std::fmt::Display for StepRule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Fixed(n) => write!(f, "{n}"),
            Self::Scaled => write!(f, "scaled"),
        }
    }
}

/// Mass of each vertex of the benchmark's cloth, kg. The drape's fixed total mass (0.5 kg) makes a
/// vertex lighter as the grid grows and its stable step shrink faster than `1/n` (2e-6 s at 1024²,
/// where the scaled step is 4e-5 s): the rows would time NaN. At 10 g a vertex, with the drape's
/// springs, the largest stable step is 2.4e-3 s at every grid, so 16, 64 and the scaled
/// substeps all stay stable.
pub const BENCH_VERTEX_MASS_KG: f64 = 0.01;

/// The benchmark's scene: the default drape on an `n × n` grid with [`BENCH_VERTEX_MASS_KG`] per
/// vertex, with the substeps of `rule`, under semi-implicit Euler.
pub fn bench_scene(n: u32, rule: StepRule) -> Scene {
    bench_scene_with(n, rule, cloth_core::Integrator::SemiImplicitEuler)
}

/// [`bench_scene`] under `integrator` (the implicit ones with their default solver settings).
pub fn bench_scene_with(n: u32, rule: StepRule, integrator: cloth_core::Integrator) -> Scene {
    let mut scene = Scene { integrator, ..Scene::default() };
    scene.cloth.resolution = [n, n];
    scene.cloth.mass = cloth_core::scene::Mass::PerVertex(BENCH_VERTEX_MASS_KG);
    let substeps = match rule {
        StepRule::Fixed(k) => k,
        StepRule::Scaled => ((scene.time.frame_dt * n as f64 / SCALED_STEP_TIMES_N).round() as u32).max(1),
    };
    scene.time.substeps = Substeps::Fixed(substeps);
    scene
}

/// One row of the benchmark.
#[derive(Clone, Debug, PartialEq)]
pub struct ThroughputRow {
    /// Backend name.
    pub backend: String,
    /// Adapter, in words.
    pub adapter: String,
    /// Vertices along each side.
    pub grid: u32,
    /// How the substeps were chosen.
    pub rule: StepRule,
    /// The time integrator.
    pub integrator: cloth_core::Integrator,
    /// Substeps per frame.
    pub substeps: u32,
    /// Substep length, s.
    pub substep_dt: f64,
    /// Frames of each timing.
    pub frames: u32,
    /// Timings of `frames` frames each; the times below are their medians
    /// ([`crate::timing`]).
    pub repeats: u32,
    /// GPU time per frame from timestamp queries, ms, the median of the repeats (`None` without
    /// a GPU timer).
    pub gpu_ms_per_frame: Option<f64>,
    /// Spread (interquartile range) of the GPU time per frame over the repeats, ms.
    pub gpu_ms_spread: Option<f64>,
    /// Host time per frame spent in `advance` (recording and submitting), ms, the median.
    pub cpu_ms_per_frame: f64,
    /// Wall-clock time per frame from a timing's first `advance` to the end of its work, ms,
    /// the median.
    pub wall_ms_per_frame: f64,
    /// Spread (interquartile range) of the wall-clock time per frame over the repeats, ms.
    pub wall_ms_spread: f64,
    /// Vertex-substeps per second, from the median GPU time where there is one, else the wall
    /// clock's.
    pub vertex_substeps_per_s: f64,
    /// Command submissions per frame.
    pub submissions_per_frame: f64,
    /// Host waits per frame, the one that ends the measurement included.
    pub host_waits_per_frame: f64,
    /// Substeps one dispatch advanced ([`cloth_core::Simulator::fused_substeps`]: more than 1
    /// where the backend fuses them with its tiled kernel).
    pub fused_substeps: u32,
    /// Bytes a vertex of the state the substeps handed each other
    /// ([`cloth_core::Simulator::substep_state_bytes`]: 24 on semi-implicit Euler's packed
    /// state, 32 on the two `vec4`s, `None` on the CPU).
    pub state_bytes: Option<u32>,
    /// Whether the state was still finite at the end (a fixed step too long for a fine grid
    /// blows up; its timing is still the kernel's, but the row says so).
    pub finite: bool,
}

impl ThroughputRow {
    /// Fraction of the ceiling `bytes_per_s / MIN_BYTES_PER_VERTEX_SUBSTEP` this row reaches.
    pub fn ceiling_fraction(&self, bytes_per_s: f64) -> f64 {
        self.vertex_substeps_per_s * MIN_BYTES_PER_VERTEX_SUBSTEP / bytes_per_s
    }
}

/// Measures one row: one warm-up frame (pipelines, first-use allocations), then `repeats`
/// timings of `frames` frames, each frame advanced by its own `advance(1)` (one submission, no
/// wait) with GPU timing on where the backend has it, and each timing ended by one wait for
/// the device. A GPU backend lays its work out as `tuning` says.
///
/// # Errors
/// [`SimError::InvalidOption`] for `frames` or `repeats` of 0; else what creating or running
/// the simulator returns (e.g. [`SimError::Unavailable`] without an adapter,
/// [`SimError::TooLarge`] for a grid the device cannot hold).
pub fn measure(
    backend: &Backend,
    tuning: &cloth_gpu::GpuTuning,
    n: u32,
    (rule, integrator): (StepRule, cloth_core::Integrator),
    frames: u32,
    repeats: u32,
) -> Result<ThroughputRow, SimError> {
    for (option, value) in [("frames", frames), ("repeats", repeats)] {
        if value == 0 {
            return Err(SimError::InvalidOption { option, value: "0".to_string(), expected: "at least 1".to_string() });
        }
    }
    let scene = bench_scene_with(n, rule, integrator);
    let mut sim = (backend.create)(&scene, tuning)?;
    sim.advance(1)?;
    sim.diagnostics()?;
    let gpu_timed = sim.set_gpu_timing(true);
    let (mut submissions, mut waits) = (0u64, 0u64);
    let f = frames as f64;
    let (mut gpu, mut host, mut wall) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..repeats {
        let mut host_s = 0.0;
        let start = Instant::now();
        for _ in 0..frames {
            let t = Instant::now();
            sim.advance(1)?;
            host_s += t.elapsed().as_secs_f64();
            let counts = sim.last_advance_counts();
            submissions += counts.submissions as u64;
            waits += counts.host_waits as u64;
        }
        // One wait at the end, so the wall clock covers the work and not only its submission.
        let gpu_seconds = if gpu_timed { sim.take_gpu_seconds()? } else { None };
        sim.diagnostics()?;
        wall.push(start.elapsed().as_secs_f64() * 1e3 / f);
        host.push(host_s * 1e3 / f);
        if submissions > 0 {
            waits += 1;
        }
        if let Some(s) = gpu_seconds {
            gpu.push(s * 1e3 / f);
        }
    }
    let finite = sim.read_state()?.non_finite_count() == 0;
    // GPU time only where every timing had it.
    let gpu = (gpu.len() == repeats as usize).then(|| Samples::new(gpu));
    let (host, wall) = (Samples::new(host), Samples::new(wall));
    let ms_per_frame = gpu.as_ref().map_or(wall.median(), Samples::median);
    let work_per_frame = n as f64 * n as f64 * scene.substeps_per_frame() as f64;
    let timed_frames = f * repeats as f64;
    Ok(ThroughputRow {
        backend: backend.name.to_string(),
        adapter: sim.adapter_name(),
        grid: n,
        rule,
        integrator,
        substeps: scene.substeps_per_frame(),
        substep_dt: scene.substep_dt(),
        frames,
        repeats,
        gpu_ms_per_frame: gpu.as_ref().map(Samples::median),
        gpu_ms_spread: gpu.as_ref().map(Samples::spread),
        cpu_ms_per_frame: host.median(),
        wall_ms_per_frame: wall.median(),
        wall_ms_spread: wall.spread(),
        vertex_substeps_per_s: work_per_frame / (ms_per_frame * 1e-3),
        submissions_per_frame: submissions as f64 / timed_frames,
        host_waits_per_frame: waits as f64 / timed_frames,
        fused_substeps: sim.fused_substeps(),
        state_bytes: sim.substep_state_bytes(),
        finite,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_row_of_the_benchmark_is_stable() {
        for n in [32, 128, 512, 1024, 2048] {
            for rule in [StepRule::Fixed(16), StepRule::Fixed(64), StepRule::Scaled] {
                let scene = bench_scene(n, rule);
                let margin = cloth_core::stability::stability_margin(&scene);
                assert!(margin < 0.8, "{n}² {rule}: margin {margin}");
            }
        }
    }

    #[test]
    fn the_scaled_step_gives_the_classic_53_substeps_at_128() {
        assert_eq!(bench_scene(128, StepRule::Scaled).substeps_per_frame(), 53);
        assert_eq!(bench_scene(1024, StepRule::Fixed(64)).substeps_per_frame(), 64);
        assert_eq!("scaled".parse::<StepRule>(), Ok(StepRule::Scaled));
        assert_eq!("16".parse::<StepRule>(), Ok(StepRule::Fixed(16)));
        assert!("0".parse::<StepRule>().is_err() && "fast".parse::<StepRule>().is_err());
    }

    #[test]
    fn a_cpu_row_counts_the_work_and_no_device_traffic() {
        let cpu = crate::find("cpu").unwrap();
        let row = measure(
            &cpu,
            &Default::default(),
            16,
            (StepRule::Fixed(4), cloth_core::Integrator::SemiImplicitEuler),
            3,
            4,
        )
        .unwrap();
        assert_eq!((row.grid, row.substeps, row.frames, row.repeats), (16, 4, 3, 4));
        assert!(row.wall_ms_spread >= 0.0 && row.gpu_ms_spread.is_none());
        assert!(row.finite && row.gpu_ms_per_frame.is_none());
        assert_eq!((row.submissions_per_frame, row.host_waits_per_frame), (0.0, 0.0));
        assert!(row.vertex_substeps_per_s > 0.0 && row.wall_ms_per_frame >= row.cpu_ms_per_frame * 0.5);
    }
}
