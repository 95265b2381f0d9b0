//! What each effect costs: one scene timed with no effect at all (the bare cloth: integration of
//! free point masses, pins held), then with the scene's effects added one at a time in the order
//! of [`Effect::ALL`], on one backend. `cloth bench --effects` prints it; the inspector's stats
//! panel shows it for the scene on screen.
//!
//! Every row runs the same number of substeps per frame (the scene's own, `Auto` resolved for
//! the whole scene), so a row differs from the one before only by the code of one effect.
//! Absent effects are compiled out of the kernels (see `shaders/`), which is what makes the
//! bare row cheaper; the cost of an effect is the difference between its row and the one before.

use std::time::Instant;

use cloth_core::{Effect, EffectSet, Scene, SimError, Substeps, stability};

use crate::Backend;

/// One row of the breakdown.
#[derive(Clone, Debug, PartialEq)]
pub struct EffectCost {
    /// The effect this row adds to the previous one (`None`: the bare cloth).
    pub added: Option<Effect>,
    /// The effects this row simulates.
    pub effects: EffectSet,
    /// Cost of one frame, ms: GPU execution time where the backend has timestamps, else wall
    /// clock to the end of the work. The least of [`REPEATS`] timings (the least disturbed).
    pub ms_per_frame: f64,
    /// Whether `ms_per_frame` is GPU time (timestamps) rather than wall clock.
    pub gpu_timed: bool,
    /// `ms_per_frame` minus the previous row's: what this effect costs, ms per frame (0 for the
    /// bare row). Differences below the timing noise can come out slightly negative.
    pub added_ms: f64,
}

impl EffectCost {
    /// `bare cloth` or `+ Wind`.
    pub fn label(&self) -> String {
        match self.added {
            None => "bare cloth".to_string(),
            Some(e) => format!("+ {e:?}"),
        }
    }
}

/// The breakdown of one scene on one backend.
#[derive(Clone, Debug, PartialEq)]
pub struct Breakdown {
    /// The adapter (or CPU) it ran on.
    pub adapter: String,
    /// Substeps per frame of every row.
    pub substeps: u32,
    /// The bare cloth, then each effect added.
    pub rows: Vec<EffectCost>,
}

impl Breakdown {
    /// `GPU timestamps` or `wall clock`: what the rows' times are.
    pub fn timer(&self) -> &'static str {
        if !self.rows.is_empty() && self.rows.iter().all(|r| r.gpu_timed) { "GPU timestamps" } else { "wall clock" }
    }
}

/// Timings of each row; the least is kept.
pub const REPEATS: u32 = 3;

/// The rows `measure` runs for `scene`: none, then each of its effects added in turn.
pub fn steps(scene: &Scene) -> Vec<(Option<Effect>, EffectSet)> {
    let mut effects = EffectSet::empty();
    let mut rows = vec![(None, effects)];
    for effect in Effect::ALL.into_iter().filter(|e| scene.effects.contains(*e)) {
        effects = effects.with(effect);
        rows.push((Some(effect), effects));
    }
    rows
}

/// Substeps per frame of every row: the scene's own (`Auto` resolved for the whole scene).
pub fn substeps(scene: &Scene) -> u32 {
    match scene.time.substeps {
        Substeps::Fixed(n) => n,
        Substeps::Auto => stability::auto_substeps(scene),
    }
}

/// The scene of one row: `scene` with `effects` and the substeps of the whole scene fixed.
pub fn row_scene(scene: &Scene, effects: EffectSet) -> Scene {
    let mut row = scene.clone();
    row.effects = effects;
    row.time.substeps = Substeps::Fixed(substeps(scene));
    row
}

/// Times `frames` frames of each row of [`steps`] on `backend` (laid out as `tuning` says),
/// calling `progress(done, total)` after each row.
///
/// # Errors
/// The first [`SimError`] of a row: the backend unavailable, the scene refused, a device error.
pub fn measure(
    scene: &Scene,
    backend: &Backend,
    tuning: &cloth_gpu::GpuTuning,
    frames: u32,
    mut progress: impl FnMut(usize, usize),
) -> Result<Breakdown, SimError> {
    let steps = steps(scene);
    let mut adapter_name = String::new();
    let frames = frames.max(1);
    let mut rows: Vec<EffectCost> = Vec::with_capacity(steps.len());
    for (k, (added, effects)) in steps.iter().enumerate() {
        let mut sim = (backend.create)(&row_scene(scene, *effects), tuning)?;
        adapter_name = sim.adapter_name();
        // Warm-up: pipeline compilation and first-use allocations, then wait for it.
        sim.advance(1)?;
        sim.diagnostics()?;
        let gpu_timed = sim.set_gpu_timing(true);
        let mut best = f64::INFINITY;
        for _ in 0..REPEATS {
            let start = Instant::now();
            sim.advance(frames)?;
            let seconds = match sim.take_gpu_seconds()? {
                Some(s) if gpu_timed => s,
                _ => {
                    // The wall clock to the end of the work: diagnostics waits for the device.
                    sim.diagnostics()?;
                    start.elapsed().as_secs_f64()
                }
            };
            best = best.min(seconds);
        }
        let ms_per_frame = best * 1e3 / frames as f64;
        let added_ms = rows.last().map_or(0.0, |previous| ms_per_frame - previous.ms_per_frame);
        rows.push(EffectCost { added: *added, effects: *effects, ms_per_frame, gpu_timed, added_ms });
        progress(k + 1, steps.len());
    }
    Ok(Breakdown { adapter: adapter_name, substeps: substeps(scene), rows })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_add_the_scenes_effects_one_at_a_time_and_keep_its_substeps() {
        let scene = Scene::default();
        let steps = steps(&scene);
        assert_eq!(steps[0], (None, EffectSet::empty()));
        assert_eq!(steps.len(), 1 + scene.effects.iter().count());
        assert_eq!(steps.last().unwrap().1, scene.effects);
        let auto =
            Scene { time: cloth_core::scene::TimeSpec { substeps: Substeps::Auto, ..scene.time.clone() }, ..scene };
        let bare = row_scene(&auto, EffectSet::empty());
        assert_eq!(bare.time.substeps, Substeps::Fixed(stability::auto_substeps(&auto)));
    }

    #[test]
    fn the_cpu_breakdown_has_a_timed_row_per_effect() {
        let mut scene = Scene::default();
        scene.cloth.resolution = [24, 24];
        scene.time.substeps = Substeps::Fixed(8);
        let cpu = crate::find("cpu").unwrap();
        let mut calls = 0;
        let breakdown = measure(&scene, &cpu, &Default::default(), 4, |done, total| {
            calls += 1;
            assert!(done <= total);
        })
        .unwrap();
        let rows = &breakdown.rows;
        assert_eq!((breakdown.substeps, breakdown.timer()), (8, "wall clock"));
        assert_eq!((rows.len(), calls), (steps(&scene).len(), rows.len()));
        // Timings themselves are the benchmark's to print, not a test's to assert.
        assert!(rows.iter().all(|r| r.ms_per_frame > 0.0 && r.ms_per_frame.is_finite() && !r.gpu_timed), "{rows:?}");
        assert_eq!(rows[0].added_ms, 0.0);
        let (first, last) = (rows[1].effects, rows.last().unwrap().effects);
        assert_eq!((first.iter().count(), last), (1, scene.effects));
    }
}
