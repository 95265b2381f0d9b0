//! A quick accuracy study run in the background on any backend, and the last CLI study's CSV.
//!
//! The full study is `cloth study accuracy` (docs/accuracy.md); this one sweeps a small copy of
//! the current scene so a student sees, in seconds, how each integrator's error falls with cost.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use cloth_core::{CpuSimulatorF64, Integrator, Scene, Simulator, Substeps};

/// One point of a study: an integrator at one step, its cost and its error.
#[derive(Clone, Debug, PartialEq)]
pub struct StudyPoint {
    /// Series label, e.g. "cpu euler".
    pub series: String,
    /// Cost: ms per simulated second (GPU timestamps where the backend has them, else wall clock).
    pub ms_per_simulated_s: f64,
    /// RMS position error against the reference, m.
    pub rms_error_m: f64,
}

/// Progress shared with the background thread.
#[derive(Clone, Debug, Default)]
pub struct StudyProgress {
    /// Runs finished.
    pub done: usize,
    /// Runs in all.
    pub total: usize,
    /// Points measured so far (finite runs only).
    pub points: Vec<StudyPoint>,
    /// Set when the study cannot run, with the reason.
    pub error: Option<String>,
}

/// Substeps per frame of the quick sweep.
const QUICK_SUBSTEPS: [u32; 3] = [8, 16, 32];

/// Runs the quick study on a copy of `scene` (at most 12 x 12, 0.25 s) on `backend`, updating
/// `progress`.
pub fn quick_study(scene: &Scene, backend: &str, tuning: &cloth_gpu::GpuTuning, progress: &Mutex<StudyProgress>) {
    let mut base = scene.clone();
    base.cloth.resolution = [base.cloth.resolution[0].min(12), base.cloth.resolution[1].min(12)];
    let frames = (0.25 / base.time.frame_dt).round().max(1.0) as u32;
    let with = |integrator, n| Scene {
        integrator,
        time: cloth_core::scene::TimeSpec { substeps: Substeps::Fixed(n), ..base.time.clone() },
        ..base.clone()
    };
    let set = |f: &dyn Fn(&mut StudyProgress)| {
        if let Ok(mut p) = progress.lock() {
            f(&mut p);
        }
    };
    set(&|p| *p = StudyProgress { total: 1 + Integrator::ALL.len() * QUICK_SUBSTEPS.len(), ..Default::default() });
    // The reference and every run, within the work budgets alone and together (a scene with a
    // tiny frame step makes 0.25 s many frames).
    let mut work = cloth_core::budget::WorkPlan::default();
    let planned = work
        .add("cpu-f64", &with(Integrator::RungeKutta4, 8 * QUICK_SUBSTEPS[2]), frames)
        .and_then(|_| {
            Integrator::ALL
                .iter()
                .flat_map(|&i| QUICK_SUBSTEPS.map(move |n| (i, n)))
                .try_for_each(|(i, n)| work.add(backend, &with(i, n), frames).map(|_| ()))
        })
        .and_then(|()| work.check("time.frame_dt", "use a longer frame step for the quick study"));
    if let Err(p) = planned {
        let message = format!("the quick study is too much work: {p}");
        set(&|p| p.error = Some(message.clone()));
        return;
    }
    let reference = match CpuSimulatorF64::new(&with(Integrator::RungeKutta4, 8 * QUICK_SUBSTEPS[2])) {
        Ok(mut sim) => {
            let _ = sim.advance(frames);
            sim.positions().iter().map(|p| p.to_f64()).collect::<Vec<_>>()
        }
        Err(e) => {
            let message = e.to_string();
            set(&|p| p.error = Some(message.clone()));
            return;
        }
    };
    set(&|p| p.done += 1);
    let factory = match cloth_backends::find(backend) {
        Ok(b) => b.create,
        Err(e) => {
            set(&|p| p.error = Some(e.clone()));
            return;
        }
    };
    for integrator in Integrator::ALL {
        for n in QUICK_SUBSTEPS {
            let point = factory(&with(integrator, n), tuning).ok().and_then(|mut sim| {
                let timed = sim.set_gpu_timing(true);
                let start = Instant::now();
                for _ in 0..frames {
                    sim.advance(1).ok()?;
                }
                let state = sim.read_state().ok()?;
                let wall = start.elapsed().as_secs_f64();
                let seconds = if timed { sim.take_gpu_seconds().ok().flatten().unwrap_or(wall) } else { wall };
                let sum: f64 = state
                    .positions
                    .iter()
                    .zip(&reference)
                    .map(|(p, q)| (0..3).map(|k| (p[k] as f64 - q[k]).powi(2)).sum::<f64>())
                    .sum();
                let rms = (sum / reference.len().max(1) as f64).sqrt();
                rms.is_finite().then(|| StudyPoint {
                    series: format!("{backend} {}", integrator.name()),
                    ms_per_simulated_s: seconds * 1e3 / (frames as f64 * base.time.frame_dt),
                    rms_error_m: rms,
                })
            });
            set(&|p| {
                p.done += 1;
                if let Some(point) = &point {
                    p.points.push(point.clone());
                }
            });
        }
    }
}

/// Starts the quick study on `backend` on a background thread; the returned progress fills as
/// it runs.
pub fn spawn_quick_study(scene: &Scene, backend: &str, tuning: &cloth_gpu::GpuTuning) -> Arc<Mutex<StudyProgress>> {
    let progress = Arc::new(Mutex::new(StudyProgress::default()));
    let (scene, backend, shared, tuning) = (scene.clone(), backend.to_string(), progress.clone(), tuning.clone());
    std::thread::spawn(move || quick_study(&scene, &backend, &tuning, &shared));
    progress
}

/// The last study's CSV: `out/accuracy.csv` (the last `cloth study accuracy` run here) if it
/// exists, else `docs/accuracy.csv` (the one the report in the docs shows).
pub fn last_study_csv() -> Option<PathBuf> {
    let docs = crate::panels::scene::scenes_dir().join("../docs/accuracy.csv");
    [Path::new("out/accuracy.csv").to_path_buf(), docs].into_iter().find(|p| p.is_file())
}

/// A study's CSV as the panel shows it.
#[derive(Debug)]
pub struct LoadedStudy {
    /// The scene the points are of: the file's first (a study of several scenes writes them in
    /// turn); `None` for a CSV without a `scene` column.
    pub scene: Option<String>,
    pub points: Vec<StudyPoint>,
}

/// Reads the points of a CSV written by `cloth study accuracy`: the rows of its first scene that
/// neither are non-finite nor diverged (the cost is column 11, `cost_ms_per_simulated_s`; `scene`
/// and `diverged` are found by their header names). A file that does not end its last row, or a
/// row with fewer columns than the header, is refused whole rather than shown in part: it is not
/// a complete study.
pub fn load_csv(path: &Path) -> Result<LoadedStudy, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let header: Vec<&str> = text.lines().next().map_or(Vec::new(), |h| h.split(',').collect());
    let columns = header.len().max(11);
    let scene_column = header.iter().position(|h| *h == "scene");
    let diverged_column = header.iter().position(|h| *h == "diverged");
    if !text.ends_with('\n') {
        return Err(format!("{} is incomplete (its last row is cut): not shown", path.display()));
    }
    let mut points = Vec::new();
    let mut scene: Option<String> = None;
    for (n, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() < columns {
            return Err(format!("{} line {}: expected {columns} columns, found {}", path.display(), n + 1, f.len()));
        }
        if let Some(c) = scene_column {
            match &scene {
                None => scene = Some(f[c].to_string()),
                Some(first) if first != f[c] => continue,
                Some(_) => {}
            }
        }
        if diverged_column.is_some_and(|c| f[c] == "true") {
            continue;
        }
        let number = |s: &str| s.parse::<f64>().map_err(|e| format!("{} line {}: '{s}': {e}", path.display(), n + 1));
        let (error, cost) = (number(f[4])?, number(f[10])?);
        if f[9] == "true" && error.is_finite() && error > 0.0 {
            points.push(StudyPoint {
                series: format!("{} {}", f[0], f[1]),
                ms_per_simulated_s: cost,
                rms_error_m: error,
            });
        }
    }
    Ok(LoadedStudy { scene, points })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quick_study_measures_every_integrator_and_higher_order_is_more_accurate() {
        let progress = Mutex::new(StudyProgress::default());
        let scene = Scene::load(&crate::panels::scene::scenes_dir().join("hanging.ron")).unwrap();
        quick_study(&scene, "cpu", &Default::default(), &progress);
        let p = progress.lock().unwrap();
        // The reference run, then every integrator at each of the three substep counts.
        assert_eq!((p.done, p.total, p.error.clone()), (p.total, 1 + 3 * Integrator::ALL.len(), None));
        for integrator in Integrator::ALL {
            let series = format!("cpu {}", integrator.name());
            assert!(p.points.iter().any(|q| q.series == series), "{series} missing from {:?}", p.points);
        }
        let error = |series: &str| p.points.iter().find(|q| q.series == series).map(|q| q.rms_error_m).unwrap();
        assert!(error("cpu rk4") < error("cpu verlet") && error("cpu verlet") < error("cpu euler"), "{:?}", p.points);
    }

    #[test]
    fn a_quick_study_beyond_the_work_budget_is_not_run() {
        // 0.25 s of 1e-7 s frames on 12 x 12: the reference alone fits the CPU's budget (9.2e10
        // vertex-substeps), the reference and the runs together do not.
        let progress = Mutex::new(StudyProgress::default());
        let mut scene = Scene::load(&crate::panels::scene::scenes_dir().join("hanging.ron")).unwrap();
        scene.time.frame_dt = 1e-7;
        quick_study(&scene, "cpu", &Default::default(), &progress);
        let p = progress.lock().unwrap();
        let error = p.error.clone().unwrap_or_default();
        assert!(error.contains("the quick study is too much work") && error.contains("add up to"), "{error}");
        assert_eq!(p.done, 0);
    }

    #[test]
    fn a_study_csv_cut_short_is_not_shown() {
        let path = crate::panels::scene::scenes_dir().join("../docs/accuracy.csv");
        let text = std::fs::read_to_string(&path).unwrap();
        let cut = std::env::temp_dir().join(format!("cloth-cut-study-{}.csv", std::process::id()));
        for end in [text.len() - 1, text.len() / 2] {
            std::fs::write(&cut, &text[..end]).unwrap();
            let err = load_csv(&cut).unwrap_err();
            assert!(err.contains("incomplete") || err.contains("columns"), "{err}");
        }
        std::fs::remove_file(&cut).unwrap();
    }

    #[test]
    fn a_study_of_several_scenes_shows_its_first_without_the_diverged_runs() {
        let header = "backend,integrator,substeps_per_frame,dt_s,rms_error_m,max_error_m,energy_drift,max_strain,\
                      max_penetration_m,finite,cost_ms_per_simulated_s,cost_clock,wall_ms_per_simulated_s,\
                      gpu_ms_per_simulated_s,scene,energy_dissipated_j,solver_iterations_per_substep,diverged";
        let rows = [
            "cpu,euler,1,1e-2,3e5,1e6,1e9,40,0,true,1.0,wall,1.0,,hanging,-1e9,,true",
            "cpu,euler,8,2e-3,1e-3,2e-3,0,0.01,0,true,2.0,wall,2.0,,hanging,0.1,,false",
            "cpu,vbd,8,2e-3,2e-3,3e-3,0,0.01,0,true,3.0,wall,3.0,,hanging,0.2,10.00,false",
            "cpu,euler,8,2e-3,5e-3,6e-3,0,0.01,0,true,2.5,wall,2.5,,drape,0.1,,false",
        ];
        let path = std::env::temp_dir().join(format!("cloth-scenes-study-{}.csv", std::process::id()));
        std::fs::write(&path, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
        let study = load_csv(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(study.scene.as_deref(), Some("hanging"));
        let errors: Vec<f64> = study.points.iter().map(|p| p.rms_error_m).collect();
        assert_eq!(errors, [1e-3, 2e-3], "the hanging cloth's two runs that did not diverge");
    }

    #[test]
    fn the_committed_study_csv_loads() {
        let path = crate::panels::scene::scenes_dir().join("../docs/accuracy.csv");
        let study = load_csv(&path).unwrap();
        let points = &study.points;
        assert!(points.iter().any(|p| p.series.ends_with("xpbd")), "{points:?}");
        assert!(points.iter().all(|p| p.ms_per_simulated_s > 0.0 && p.rms_error_m > 0.0));
    }
}
