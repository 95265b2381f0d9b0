//! What each effect costs: one scene timed with no effect at all (the bare cloth: integration of
//! free point masses, pins held), then with the scene's effects added one at a time in the order
//! of [`Effect::ALL`], on one backend. Contact comes in one row per collider kind of the scene:
//! `Contact` with the scene's colliders of its first kind, then each other kind's colliders
//! added, in the order of [`ColliderKind::ALL`]. `cloth bench --effects` prints it; the inspector's stats
//! panel shows it for the scene on screen.
//!
//! Every row runs the same number of substeps per frame (the scene's own, `Auto` resolved for
//! the whole scene), so a row differs from the one before only by the code of one effect.
//! Absent effects are compiled out of the kernels (see `shaders/`), which is what makes the
//! bare row cheaper; the cost of an effect is the difference between its row and the one before.
//!
//! Each row is timed [`crate::timing::DEFAULT_REPEATS`] times (or as many as asked), the rows in alternating
//! order, and an effect's cost is read from the paired differences of its row and the one
//! before ([`crate::timing`]): a cost where they agree, else "inside the noise" with its range.

use std::time::Instant;

use cloth_core::colliders::ColliderKind;
use cloth_core::self_collision::CandidateListStats;
use cloth_core::{Effect, EffectSet, Scene, SimError, Substeps, stability};

use crate::Backend;
use crate::timing::{Difference, Samples};

/// What one row adds to the one before.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Added {
    /// An effect (for `Contact`: with the colliders of the scene's first kind).
    Effect(Effect),
    /// The scene's colliders of one more kind.
    Colliders(ColliderKind),
}

/// One row of the breakdown as [`steps`] lists it: what it adds, its effects and the collider
/// kinds it keeps.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// What this row adds (`None`: the bare cloth).
    pub added: Option<Added>,
    /// The effects this row simulates.
    pub effects: EffectSet,
    /// The collider kinds whose colliders this row keeps.
    pub kinds: Vec<ColliderKind>,
}

impl Step {
    /// `bare cloth`, `+ Wind`, `+ Contact (sphere)` or `+ box colliders`.
    pub fn label(&self) -> String {
        match self.added {
            None => "bare cloth".to_string(),
            Some(Added::Effect(Effect::Contact)) => match self.kinds.first() {
                Some(kind) => format!("+ Contact ({})", kind.name()),
                None => "+ Contact".to_string(),
            },
            Some(Added::Effect(e)) => format!("+ {e:?}"),
            Some(Added::Colliders(kind)) => format!("+ {} colliders", kind.name()),
        }
    }
}

/// One row of the breakdown.
#[derive(Clone, Debug, PartialEq)]
pub struct EffectCost {
    /// What this row adds, its effects and its collider kinds.
    pub step: Step,
    /// Cost of one frame, ms, once per repeat: GPU execution time where the backend has
    /// timestamps, else wall clock to the end of the work.
    pub ms_per_frame: Samples,
    /// Whether `ms_per_frame` is GPU time (timestamps) rather than wall clock.
    pub gpu_timed: bool,
    /// What this effect costs over the previous row, from the paired differences of the two
    /// rows' timings (`None` for the bare row): a cost, a saving, or inside the noise.
    pub added_cost: Option<Difference>,
    /// With `SelfCollision` on a GPU backend: how its candidate lists fared over the timed frames
    /// (`repeats` times `frames`: the checks, the rebuilds they ordered and the lists that
    /// overflowed), which is where the effect's cost comes from. `None` elsewhere.
    pub candidate_lists: Option<CandidateListStats>,
}

impl EffectCost {
    /// `bare cloth`, `+ Wind`, `+ Contact (sphere)` or `+ box colliders`.
    pub fn label(&self) -> String {
        self.step.label()
    }

    /// The added cost in words (`+1.234 ms`, `inside the noise (...)`, `saves ...`), or `—` for
    /// the bare row.
    pub fn added_text(&self) -> String {
        self.added_cost.map_or("—".to_string(), |d| d.describe("ms"))
    }
}

/// The breakdown of one scene on one backend.
#[derive(Clone, Debug, PartialEq)]
pub struct Breakdown {
    /// The adapter (or CPU) it ran on.
    pub adapter: String,
    /// Substeps per frame of every row.
    pub substeps: u32,
    /// Frames of each timing.
    pub frames: u32,
    /// Timings of each row, taken in alternating order.
    pub repeats: u32,
    /// The bare cloth, then each effect added.
    pub rows: Vec<EffectCost>,
}

impl Breakdown {
    /// `GPU timestamps` or `wall clock`: what the rows' times are.
    pub fn timer(&self) -> &'static str {
        if !self.rows.is_empty() && self.rows.iter().all(|r| r.gpu_timed) { "GPU timestamps" } else { "wall clock" }
    }

    /// Median ms per frame of the whole scene (the last row).
    pub fn whole_ms(&self) -> f64 {
        self.rows.last().map_or(0.0, |r| r.ms_per_frame.median())
    }
}

/// The fewest timings a row may have: with fewer, the middle half of the paired differences is
/// one difference and a single disturbed timing decides the verdict.
pub const MIN_REPEATS: u32 = 3;

/// The collider kinds of `scene`'s colliders, in [`ColliderKind::ALL`] order.
fn kinds_of(scene: &Scene) -> Vec<ColliderKind> {
    ColliderKind::ALL.into_iter().filter(|k| scene.colliders.iter().any(|c| c.kind() == *k)).collect()
}

/// The rows `measure` runs for `scene`: none, then each of its effects added in turn, `Contact`
/// with the colliders of its first collider kind and then one row per further kind.
pub fn steps(scene: &Scene) -> Vec<Step> {
    let all_kinds = kinds_of(scene);
    let mut effects = EffectSet::empty();
    let mut rows = vec![Step { added: None, effects, kinds: Vec::new() }];
    let mut kinds: Vec<ColliderKind> = Vec::new();
    for effect in Effect::ALL.into_iter().filter(|e| scene.effects.contains(*e)) {
        effects = effects.with(effect);
        if effect == Effect::Contact {
            kinds.extend(all_kinds.first());
        }
        rows.push(Step { added: Some(Added::Effect(effect)), effects, kinds: kinds.clone() });
        if effect == Effect::Contact {
            for kind in all_kinds.iter().skip(1) {
                kinds.push(*kind);
                rows.push(Step { added: Some(Added::Colliders(*kind)), effects, kinds: kinds.clone() });
            }
        }
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

/// The scene of one row: `scene` with the step's effects, with `Contact` only its colliders of
/// the step's kinds (without it they are not met, and all kept), and the substeps of the whole
/// scene fixed.
pub fn row_scene(scene: &Scene, step: &Step) -> Scene {
    let mut row = scene.clone();
    row.effects = step.effects;
    if step.effects.contains(Effect::Contact) {
        row.colliders.retain(|c| step.kinds.contains(&c.kind()));
    }
    row.time.substeps = Substeps::Fixed(substeps(scene));
    row
}

/// Times `frames` frames of each row of [`steps`] on `backend` (laid out as `tuning` says),
/// `repeats` times, in alternating order: forward through the rows, then backward, and so on, so
/// a slow spell of the device falls on neighbouring rows alike and cancels in their difference.
/// Every row's simulator is created (and warmed up) first and kept for all the repeats.
/// `progress(done, total)` is called after each timing.
///
/// # Errors
/// [`SimError::InvalidOption`] for `repeats` below [`MIN_REPEATS`] or `frames` of 0; else the
/// first [`SimError`] of a row: the backend unavailable, the scene refused, a device error.
pub fn measure(
    scene: &Scene,
    backend: &Backend,
    tuning: &cloth_gpu::GpuTuning,
    frames: u32,
    repeats: u32,
    mut progress: impl FnMut(usize, usize),
) -> Result<Breakdown, SimError> {
    if repeats < MIN_REPEATS {
        return Err(SimError::InvalidOption {
            option: "repeats",
            value: repeats.to_string(),
            expected: format!("at least {MIN_REPEATS} timings of each row, to tell an effect's cost from noise"),
        });
    }
    if frames == 0 {
        return Err(SimError::InvalidOption {
            option: "frames",
            value: "0".to_string(),
            expected: "at least one frame per timing".to_string(),
        });
    }
    let steps = steps(scene);
    let mut adapter_name = String::new();
    let mut sims = Vec::with_capacity(steps.len());
    for step in &steps {
        let mut sim = (backend.create)(&row_scene(scene, step), tuning)?;
        adapter_name = sim.adapter_name();
        // Warm-up: pipeline compilation and first-use allocations, then wait for it.
        sim.advance(1)?;
        let warmed = sim.diagnostics()?.candidate_lists;
        let gpu_timed = sim.set_gpu_timing(true);
        sims.push((sim, gpu_timed, warmed));
    }
    let total = steps.len() * repeats as usize;
    let mut timings = vec![Vec::with_capacity(repeats as usize); steps.len()];
    let mut done = 0;
    for r in 0..repeats as usize {
        let order: Vec<usize> = if r % 2 == 0 { (0..steps.len()).collect() } else { (0..steps.len()).rev().collect() };
        for k in order {
            let (sim, gpu_timed, _) = &mut sims[k];
            let start = Instant::now();
            sim.advance(frames)?;
            let seconds = match sim.take_gpu_seconds()? {
                Some(s) if *gpu_timed => s,
                _ => {
                    // The wall clock to the end of the work: diagnostics waits for the device.
                    sim.diagnostics()?;
                    start.elapsed().as_secs_f64()
                }
            };
            timings[k].push(seconds * 1e3 / frames as f64);
            done += 1;
            progress(done, total);
        }
    }
    let mut rows: Vec<EffectCost> = Vec::with_capacity(steps.len());
    for ((step, (sim, gpu_timed, warmed)), times) in steps.into_iter().zip(&mut sims).zip(timings) {
        let ms_per_frame = Samples::new(times);
        let added_cost = rows.last().map(|previous| Difference::of(&ms_per_frame.paired_minus(&previous.ms_per_frame)));
        // The timed frames' share of the counts: those of the warm-up frame taken off.
        let candidate_lists = match (sim.diagnostics()?.candidate_lists, *warmed) {
            (Some(now), Some(before)) => Some(CandidateListStats {
                checks: now.checks.saturating_sub(before.checks),
                rebuilds: now.rebuilds.saturating_sub(before.rebuilds),
                overflowed_lists: now.overflowed_lists.saturating_sub(before.overflowed_lists),
            }),
            (now, _) => now,
        };
        rows.push(EffectCost { step, ms_per_frame, gpu_timed: *gpu_timed, added_cost, candidate_lists });
    }
    Ok(Breakdown { adapter: adapter_name, substeps: substeps(scene), frames, repeats, rows })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_add_the_scenes_effects_one_at_a_time_and_keep_its_substeps() {
        let scene = Scene::default();
        let steps = steps(&scene);
        assert_eq!(steps[0], Step { added: None, effects: EffectSet::empty(), kinds: vec![] });
        assert_eq!(steps.len(), 1 + scene.effects.iter().count());
        assert_eq!(steps.last().unwrap().effects, scene.effects);
        let auto =
            Scene { time: cloth_core::scene::TimeSpec { substeps: Substeps::Auto, ..scene.time.clone() }, ..scene };
        let bare = row_scene(&auto, &steps[0]);
        assert_eq!(bare.time.substeps, Substeps::Fixed(stability::auto_substeps(&auto)));
    }

    #[test]
    fn contact_has_a_row_for_each_collider_kind() {
        use cloth_core::colliders::{ColliderSpec, Shape};
        let mut scene = Scene::default();
        scene.colliders.push(ColliderSpec::of(Shape::Plane { normal: [0.0, 1.0, 0.0], offset: 0.0 }));
        scene.colliders.push(ColliderSpec::of(Shape::Capsule { a: [0.0; 3], b: [1.0, 0.0, 0.0], radius: 0.1 }));
        let steps = steps(&scene);
        let labels: Vec<String> = steps.iter().map(Step::label).collect();
        let contact = labels.iter().position(|l| l == "+ Contact (sphere)").unwrap();
        assert_eq!(labels[contact + 1..contact + 3], ["+ plane colliders", "+ capsule colliders"]);
        assert_eq!(labels.last().unwrap(), "+ Friction");
        // Each row keeps the colliders of its kinds only; the last keeps them all.
        assert_eq!(row_scene(&scene, &steps[contact]).colliders.len(), 1);
        assert_eq!(row_scene(&scene, &steps[contact + 1]).colliders.len(), 2);
        assert_eq!(row_scene(&scene, steps.last().unwrap()).colliders, scene.colliders);
    }

    #[test]
    fn the_cpu_breakdown_times_every_row_repeatedly() {
        let mut scene = Scene::default();
        scene.cloth.resolution = [24, 24];
        scene.time.substeps = Substeps::Fixed(8);
        let cpu = crate::find("cpu").unwrap();
        let mut calls = Vec::new();
        let breakdown =
            measure(&scene, &cpu, &Default::default(), 2, 3, |done, total| calls.push((done, total))).unwrap();
        let rows = &breakdown.rows;
        assert_eq!((breakdown.substeps, breakdown.repeats, breakdown.timer()), (8, 3, "wall clock"));
        let timings = steps(&scene).len() * 3;
        assert_eq!(calls, (1..=timings).map(|k| (k, timings)).collect::<Vec<_>>());
        // Timings themselves are the benchmark's to print, not a test's to assert.
        assert!(rows.iter().all(|r| r.ms_per_frame.len() == 3 && r.ms_per_frame.median() > 0.0 && !r.gpu_timed));
        assert!(rows[0].added_cost.is_none() && rows[1..].iter().all(|r| r.added_cost.is_some()), "{rows:?}");
        let (first, last) = (rows[1].step.effects, rows.last().unwrap().step.effects);
        assert_eq!((first.iter().count(), last), (1, scene.effects));
    }

    #[test]
    fn too_few_repeats_or_no_frames_are_refused() {
        let cpu = crate::find("cpu").unwrap();
        for (frames, repeats) in [(2, 2), (0, 5)] {
            let e = measure(&Scene::default(), &cpu, &Default::default(), frames, repeats, |_, _| {}).unwrap_err();
            assert!(matches!(e, SimError::InvalidOption { .. }), "{e}");
        }
    }
}
