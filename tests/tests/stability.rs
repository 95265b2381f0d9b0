//! The stability suite: every hard case of `scenes/hard/` on every backend and every integrator.
//!
//! Each case asserts, frame by frame: every position and velocity finite; the total energy
//! (kinetic + elastic + gravitational + contact) never above the initial energy plus the work of
//! driven motion, within a stated tolerance; and, over the run, the deepest penetration and the
//! largest strain within the case's bounds. docs/stability.md explains each case and how the
//! method survives it. A case that broke something keeps its name after what broke.

use cloth_conformance::{Backend, create};
use cloth_core::colliders::Shape;
use cloth_core::scene::Substeps;
use cloth_core::{ClothModel, ClothState, Energy, Integrator, Scene, stability};

/// Energy may exceed its initial value by this fraction of the case's energy scale (the initial
/// energy's terms plus the weight times the cloth's diagonal, see `energy_scale`): explicit
/// integrators conserve energy only up to an oscillation of relative size O(ω Δt), and a penalty
/// contact can return slightly more than it stored within one substep.
const ENERGY_TOLERANCE: f64 = 0.05;

fn hard(name: &str) -> Scene {
    cloth_conformance::scene(&format!("hard/{name}"))
}

/// The integrators a hard case runs on `backend`: all six on the CPU backends; on the GPU backends
/// the four explicit and position-based ones, and all six with `CLOTH_FULL_SIZE`
/// (`scripts/gpu-check.sh stability`, on a real GPU). lavapipe spends about 50 µs a dispatch, and
/// the implicit integrators' 34 (backward Euler, the suites' solver) and 52 (VBD) dispatches a
/// substep in every case took the suite past CI's time; their GPU kernels are checked in CI by
/// the conformance suite's `implicit_integrators_match_the_reference` and by
/// `implicit_integrators_at_10_and_100_times_the_explicit_bound`, which run on every backend.
fn integrators(backend: &Backend) -> Vec<Integrator> {
    if short_on(backend) {
        Integrator::ALL.into_iter().filter(|i| !i.is_implicit()).collect()
    } else {
        Integrator::ALL.to_vec()
    }
}

fn with_integrator(scene: &Scene, integrator: Integrator) -> Scene {
    cloth_conformance::under(scene, integrator)
}

/// The energy a case's tolerance is a fraction of, J: the magnitude of each initial energy term
/// plus the cloth's weight times its diagonal (what a fall of its own size is worth).
fn energy_scale(model: &ClothModel, e0: &Energy) -> f64 {
    let scene = &model.scene;
    let weight =
        scene.vertex_mass() * scene.vertex_count() as f64 * scene.gravity.iter().map(|g| g * g).sum::<f64>().sqrt();
    let diagonal = scene.cloth.size[0].hypot(scene.cloth.size[1]);
    e0.kinetic + e0.elastic.iter().sum::<f64>() + e0.gravitational.abs() + e0.contact + weight * diagonal
}

/// What a run measured.
struct Outcome {
    name: String,
    model: ClothModel,
    states: Vec<ClothState>,
    energies: Vec<f64>,
    max_penetration_m: f64,
    max_strain: f64,
}

impl Outcome {
    fn last(&self) -> &ClothState {
        self.states.last().expect("at least the initial state")
    }
}

/// Runs `scene` for `frames` frames, checking finiteness and the energy bound after every frame
/// (`every` frames apart), and records the states.
fn run_checked(backend: &Backend, scene: &Scene, frames: u32, every: u32) -> Option<Outcome> {
    run_checked_with_work(backend, scene, frames, every, 0.0)
}

/// As [`run_checked`], with `driven_work` J of work that driven motion may add to the energy.
fn run_checked_with_work(
    backend: &Backend,
    scene: &Scene,
    frames: u32,
    every: u32,
    driven_work: f64,
) -> Option<Outcome> {
    let name = format!("{} {} {:?}", backend.name, scene.name, scene.integrator);
    let mut sim = create(backend, scene)?;
    let model = ClothModel::new(scene);
    let first = sim.read_state().unwrap();
    let e0 = Energy::of(&model, &first);
    let limit = e0.total() + driven_work + ENERGY_TOLERANCE * energy_scale(&model, &e0);
    let mut outcome = Outcome {
        name,
        energies: vec![e0.total()],
        max_strain: model.max_strain(&first),
        states: vec![first],
        model,
        max_penetration_m: 0.0,
    };
    let mut done = 0;
    while done < frames {
        let n = every.min(frames - done);
        sim.advance(n).unwrap();
        done += n;
        let state = sim.read_state().unwrap();
        let name = &outcome.name;
        assert_eq!(state.non_finite_count(), 0, "{name}: NaN or infinity at frame {done}");
        let e = Energy::of(&outcome.model, &state).total();
        assert!(
            e <= limit,
            "{name}: energy {e:.6e} J at frame {done} above the initial {:.6e} J plus the tolerance (limit {limit:.6e} J)",
            outcome.energies[0]
        );
        outcome.max_strain = outcome.max_strain.max(outcome.model.max_strain(&state));
        outcome.energies.push(e);
        outcome.states.push(state);
    }
    outcome.max_penetration_m = sim.diagnostics().unwrap().max_penetration_m;
    Some(outcome)
}

fn smallest_radius(scene: &Scene) -> f64 {
    scene.colliders.iter().filter_map(|c| c.sphere()).map(|s| s.radius).fold(f64::INFINITY, f64::min)
}

/// The cloth's smaller grid step, m.
fn spacing(scene: &Scene) -> f64 {
    let [du, dv] = scene.cloth.spacing();
    du.min(dv)
}

/// What a case's penetration is measured against, m, and its name: the smallest sphere's radius
/// when the scene has spheres, else the cloth's spacing.
fn penetration_scale(scene: &Scene) -> (f64, &'static str) {
    let radius = smallest_radius(scene);
    if radius.is_finite() { (radius, "the radius") } else { (spacing(scene), "the spacing") }
}

/// `scene` at an `n × n` grid for `frames` frames: the suite's size on every backend, sized for
/// lavapipe; with `CLOTH_FULL_SIZE` set (`scripts/gpu-check.sh stability` sets it) the scene as
/// its file gives it, grid and frames.
fn sized(scene: Scene, n: u32, frames: u32) -> Scene {
    if std::env::var_os("CLOTH_FULL_SIZE").is_some() {
        return scene;
    }
    let mut scene = scene;
    scene.cloth.resolution = [n, n];
    scene.time.frames = frames;
    scene
}

/// Whether `backend` runs the suite's shortened cases: a GPU backend without `CLOTH_FULL_SIZE`
/// (lavapipe in CI).
fn short_on(backend: &Backend) -> bool {
    !backend.name.starts_with("cpu") && std::env::var_os("CLOTH_FULL_SIZE").is_none()
}

/// `scene` for `frames` frames on the GPU backends in CI, its own frames on the CPU backends and
/// with `CLOTH_FULL_SIZE`: for the landing cases of 30 frames, whose cloth starts 0.1 m above the
/// sphere and lands by frame 9, so that 15 frames still hold the impact and six frames of contact
/// after it. lavapipe spends about 70 µs a dispatch (an XPBD frame of these scenes is 4400), and
/// the CPU backends run the same cases in full.
fn shortened_on_gpu(backend: &Backend, scene: Scene, frames: u32) -> Scene {
    if !short_on(backend) {
        return scene;
    }
    let mut scene = scene;
    scene.time.frames = frames;
    scene
}

/// Runs a case under every integrator and checks the common bounds: penetration over the run
/// below `penetration_fraction` of [`penetration_scale`], strain below `strain`.
fn every_integrator(
    backend: &Backend,
    scene: &Scene,
    penetration_fraction: f64,
    strain: f64,
    check: impl Fn(&Outcome),
) {
    every_integrator_with(backend, scene, |_| None, penetration_fraction, strain, check);
}

/// As [`every_integrator`], with fixed substeps per frame for the integrators `substeps` names.
fn every_integrator_with(
    backend: &Backend,
    scene: &Scene,
    substeps: impl Fn(Integrator) -> Option<u32>,
    penetration_fraction: f64,
    strain: f64,
    check: impl Fn(&Outcome),
) {
    for integrator in integrators(backend) {
        let mut scene = with_integrator(scene, integrator);
        if let Some(n) = substeps(integrator) {
            scene.time.substeps = Substeps::Fixed(n);
        }
        let Some(outcome) = run_checked(backend, &scene, scene.time.frames, 1) else { return };
        let (scale, of) = penetration_scale(&scene);
        let name = &outcome.name;
        eprintln!(
            "{name}: {} substeps/frame, max penetration {:.2}% of {of}, max strain {:.3}, energy {:.3e} -> {:.3e} J",
            scene.substeps_per_frame(),
            100.0 * outcome.max_penetration_m / scale,
            outcome.max_strain,
            outcome.energies[0],
            outcome.energies.last().unwrap()
        );
        assert!(
            outcome.max_penetration_m < penetration_fraction * scale,
            "{name}: max penetration {:.4} m, bound {:.4} m ({penetration_fraction} of {of})",
            outcome.max_penetration_m,
            penetration_fraction * scale
        );
        assert!(outcome.max_strain < strain, "{name}: max strain {:.3}, bound {strain}", outcome.max_strain);
        check(&outcome);
    }
}

// ---------------------------------------------------------------------------------------------
// The cases.

fn stiff_springs_with_auto_substeps(backend: &Backend) {
    every_integrator(backend, &shortened_on_gpu(backend, hard("stiff_springs.ron"), 15), 0.05, 0.05, |_| {});
}

/// Every force-based integrator at 0.95 times its own predicted bound (the safe Gershgorin bound
/// that validation and `Auto` use), on the stiff cloth. XPBD has no bound; it is run at 10, 100
/// and 1000 times the explicit one in `crates/cloth-core/tests/stability_limits.rs`.
fn step_at_0_95_of_the_bound(backend: &Backend) {
    let base = hard("stiff_springs.ron");
    for integrator in Integrator::EXPLICIT {
        let mut scene = with_integrator(&base, integrator);
        let bound = stability::stable_substep(&scene);
        scene.time.substeps = Substeps::Fixed(1);
        scene.time.frame_dt = 0.95 * bound;
        let frames = (0.25 / scene.time.frame_dt) as u32;
        let Some(outcome) = run_checked(backend, &scene, frames, frames / 10) else { return };
        eprintln!(
            "{}: Δt = {:.3e} s, {frames} substeps, max strain {:.4}",
            outcome.name, scene.time.frame_dt, outcome.max_strain
        );
        assert!(outcome.max_strain < 0.05, "{}: max strain {}", outcome.name, outcome.max_strain);
    }
}

/// Backward Euler and VBD far beyond the explicit integrators' limit: the stiff cloth with one
/// substep a frame of 10 and of 100 times semi-implicit Euler's stability bound (the Gershgorin
/// bound `Auto` uses), for at least 0.25 s (0.1 s on lavapipe): finite, and within the suite's
/// energy bound.
fn implicit_integrators_at_10_and_100_times_the_explicit_bound(backend: &Backend) {
    let base = hard("stiff_springs.ron");
    for integrator in Integrator::IMPLICIT {
        for factor in [10.0, 100.0] {
            // The default solver: 100 times the bound, the stiff springs need more than the
            // suites' 10 CG iterations to converge (k h²/m ≈ 3000).
            let mut scene = Scene { integrator, ..base.clone() };
            let euler = Scene { integrator: Integrator::SemiImplicitEuler, ..scene.clone() };
            scene.time.substeps = Substeps::Fixed(1);
            scene.time.frame_dt = factor * stability::stable_substep(&euler);
            // 0.25 s simulated; 0.1 s on lavapipe, where 0.25 s at 10 times the bound is about
            // 940 substeps of up to 300 dispatches each (backward Euler's default solver).
            let seconds = if short_on(backend) { 0.1 } else { 0.25 };
            let frames = ((seconds / scene.time.frame_dt).ceil() as u32).max(10);
            let Some(outcome) = run_checked(backend, &scene, frames, 1) else { return };
            let peak = outcome.energies.iter().copied().fold(f64::MIN, f64::max);
            eprintln!(
                "{}: {factor} times the explicit bound ({:.3e} s), {frames} steps: max strain {:.3}, energy {:.3e} -> {:.3e} J (peak {peak:.3e} J)",
                outcome.name,
                scene.time.frame_dt,
                outcome.max_strain,
                outcome.energies[0],
                outcome.energies.last().unwrap()
            );
        }
    }
}

/// `scene` at `n × n` and one substep a frame for `frames` frames, the cloth landing on the sphere
/// at full speed: finite, within the energy bound at every frame (`run_checked`) and under 2% of
/// the radius inside the sphere. False where the backend is unavailable outside CI.
fn lands_at_one_substep_a_frame(backend: &Backend, mut scene: Scene, n: u32, frames: u32) -> bool {
    scene.cloth.resolution = [n, n];
    scene.time.substeps = Substeps::Fixed(1);
    let Some(outcome) = run_checked(backend, &scene, frames, 1) else { return false };
    let radius = smallest_radius(&scene);
    let peak = outcome.energies.iter().copied().fold(f64::MIN, f64::max);
    eprintln!(
        "{}: {n}x{n}, {frames} frames of one substep: max penetration {:.2}% of the radius, energy {:.4e} J, peak {peak:.4e} J",
        outcome.name,
        100.0 * outcome.max_penetration_m / radius,
        outcome.energies[0]
    );
    assert!(
        outcome.max_penetration_m < 0.02 * radius,
        "{}: max penetration {:.4} m, bound {:.4} m (2% of the radius)",
        outcome.name,
        outcome.max_penetration_m,
        0.02 * radius
    );
    true
}

/// Backward Euler at one substep a frame of the drape and of the stiff drape (its springs 100
/// times stiffer), the cloth landing on the sphere at full speed: finite, under 2% of the radius
/// inside it, and within the energy bound at every frame. 16 × 16 for 1 s (0.5 s on lavapipe: the
/// cloth lands at frame 15) with four Newton iterations (with one, the stiff drape went 2.2% of
/// the radius deep); with `CLOTH_FULL_SIZE`, 256 × 256 for 2 s with four Newton iterations of at
/// most 300 CG iterations (at 256², `ω h` ≈ 450 and 4500, one Newton iteration of at most 100
/// let the drape's energy reach 11.3 J; the default's two of at most 50 hold it at 9.2 J). With
/// friction undoing a held vertex's motion over the whole step, the stiff drape's energy rose to
/// 20 J from 8.8 J here.
fn backward_euler_lands_at_one_substep_a_frame(backend: &Backend) {
    let full = std::env::var_os("CLOTH_FULL_SIZE").is_some();
    let (n, frames, cg) = match (full, short_on(backend)) {
        (true, _) => (256, 120, 300),
        (false, true) => (16, 30, 100),
        (false, false) => (16, 60, 100),
    };
    for name in ["drape.ron", "stiff_drape.ron"] {
        let mut scene = cloth_conformance::scene(name);
        scene.integrator = Integrator::BackwardEuler;
        scene.solver =
            cloth_core::solver::SolverSpec { newton_iterations: 4, cg_max_iterations: cg, ..Default::default() };
        if !lands_at_one_substep_a_frame(backend, scene, n, frames) {
            return;
        }
    }
}

/// VBD at one substep a frame of the drape and of the stiff drape, the cloth landing on the
/// sphere at full speed: finite, under 2% of the radius inside it, and within the energy bound at
/// every frame. 64 × 64 for 1 s on the CPU backends (without the multigrid correction the sweeps do
/// not carry the sphere's support across the cloth: the f32 CPU peaked at 89.1 J and 1.07e4 J from
/// 8.83 J), 32 × 32 for 0.5 s on lavapipe, 256 × 256 for 2 s with `CLOTH_FULL_SIZE`. The drape
/// runs the default solver (10 sweeps, a correction before sweeps 1 and 6); the stiff drape a
/// correction before every sweep, which its springs need at 256²: the f32 CPU peaked there at
/// 16.9 J with a correction every 5 sweeps, 10.5 J every 3, 9.10 J every 2 and never rose above
/// the start with one every sweep (the bound is 9.96 J).
fn vbd_lands_at_one_substep_a_frame(backend: &Backend) {
    let full = std::env::var_os("CLOTH_FULL_SIZE").is_some();
    let (n, frames) = match (full, short_on(backend)) {
        (true, _) => (256, 120),
        (false, true) => (32, 30),
        (false, false) => (64, 60),
    };
    for name in ["drape.ron", "stiff_drape.ron"] {
        let mut scene = cloth_conformance::scene(name);
        scene.integrator = Integrator::Vbd;
        let every =
            if name == "stiff_drape.ron" { 1 } else { cloth_core::solver::SolverSpec::default().vbd_multigrid_every };
        scene.solver = cloth_core::solver::SolverSpec { vbd_multigrid_every: every, ..Default::default() };
        if !lands_at_one_substep_a_frame(backend, scene, n, frames) {
            return;
        }
    }
}

fn light_vertices_of_1e_5_kg(backend: &Backend) {
    every_integrator(backend, &shortened_on_gpu(backend, hard("light_vertices.ron"), 15), 0.05, 0.1, |_| {});
}

fn heavy_vertices_of_10_kg(backend: &Backend) {
    every_integrator(backend, &shortened_on_gpu(backend, hard("heavy_vertices.ron"), 15), 0.05, 0.1, |_| {});
}

/// At 30 m/s onto a sphere of 10 cm: no vertex ends on the far side. A vertex that went through
/// the sphere crossed its core; two checks rule that out:
/// 1. every vertex's depth inside the sphere, checked by the backends after every substep, stays
///    below a fifth of the radius over the whole run;
/// 2. between two substeps a vertex moves less than that (30 m/s × Δt < r/5), so it cannot skip
///    over the shell into the core unseen. XPBD, whose steps are longer, projects the spheres
///    along each vertex's path in the substep (swept, `constraints::project_sphere_swept`), so no
///    step can jump over a sphere.
///
/// The cloth may still slide around the sphere and off it (XPBD's nearly inextensible cloth does:
/// its edges' momentum drags the centre around the side), which is not tunnelling.
///
/// Found with the default contact stiffness (1000 N/m): the cloth, wrapped tight around the small
/// sphere by the impact, squeezed through its lower half (vertices 1 cm inside, below the
/// equator, still moving inwards, ending under the sphere). A penalty force holds a load only at
/// the depth load / k_c, so the scene sets k_c = 1e5 N/m (Auto substeps follow: 133 per frame).
///
/// XPBD's `Auto` looks at the springs only (5 substeps here): at 30 m/s a vertex then crosses two
/// cells per substep, the unconverged springs stored 6% of the energy at the impact (over the 5%
/// tolerance), so the case gives XPBD 20 substeps per frame, and backward Euler and VBD, whose
/// `Auto` looks at the springs too, the same (at 5 a vertex moves the sphere's radius a substep:
/// backward Euler's contact, linearised about the sphere's tangent plane, then stored 10 times
/// the energy of the impact).
fn impact_at_30_m_s_does_not_tunnel(backend: &Backend) {
    let mut scene = hard("impact.ron");
    scene.time.substeps = Substeps::Auto;
    let sphere = scene.colliders[0].sphere().unwrap();
    for integrator in Integrator::EXPLICIT {
        let s = with_integrator(&scene, integrator);
        let jump = 30.0 * s.substep_dt();
        assert!(jump < 0.2 * sphere.radius, "{integrator:?}: {jump} m per substep could skip the sphere's shell");
    }
    // 46 J of kinetic energy go into springs of 400 N/m as the cloth's centre stops and its edges
    // whip around: they stretch up to about twice their length (strain 1.1 seen): bound 2.
    every_integrator_with(
        backend,
        &scene,
        |i| (i == Integrator::Xpbd || i.is_implicit()).then_some(20),
        0.2,
        2.0,
        |_| {},
    );
}

/// Starting inside the sphere, the cloth is pushed out without exploding: the energy bound
/// holds (its initial contact energy is all it may spend), and at the end no vertex is inside.
fn starting_inside_the_sphere_is_pushed_out(backend: &Backend) {
    let scene = hard("inside_sphere.ron");
    let sphere = scene.colliders[0].sphere().unwrap();
    // The penalty force on the deepest vertices starts at k_c times half the radius, a hundred
    // times the springs' pull: the cloth stretches up to about 1.5 times its rest length while it
    // is pushed out, then recovers. Penetration starts at the full depth, so it is bounded at the
    // end instead.
    every_integrator(backend, &scene, 1.0, 2.0, |outcome| {
        let deepest = outcome
            .last()
            .positions
            .iter()
            .map(|p| sphere.radius - (0..3).map(|k| (p[k] as f64 - sphere.center[k]).powi(2)).sum::<f64>().sqrt())
            .fold(f64::MIN, f64::max);
        assert!(deepest < 0.02 * sphere.radius, "{}: still {deepest:.4} m inside at the end", outcome.name);
    });
}

fn two_overlapping_spheres(backend: &Backend) {
    every_integrator(backend, &hard("two_spheres.ron"), 0.05, 0.2, |_| {});
}

/// A sphere smaller than a cell: vertex-based contact cannot hold it, so the bounds are only
/// finiteness and energy (checked every frame) and a loose strain bound.
fn sphere_smaller_than_a_cell(backend: &Backend) {
    let scene = shortened_on_gpu(backend, hard("tiny_sphere.ron"), 15);
    every_integrator(backend, &scene, 1.0, 0.5, |outcome| {
        let c = outcome.last().centroid();
        eprintln!("{}: the cloth ends with its centroid at y = {:.3} m (sphere centre 1.0 m)", outcome.name, c[1]);
    });
}

/// A ball at 8 m/s hits a hanging cloth and drags it along (`MovingColliders`). The ball does work
/// on the cloth, so the energy bound adds what it can give: a mass hit by a wall moving at `U`
/// leaves at up to `2U`, so at most `½ M (2U)²` for the cloth's mass `M`. The cloth stretches
/// around the ball held by its pinned edge (strain bound 2); the ball never goes deeper than a
/// fifth of its radius.
fn fast_moving_sphere(backend: &Backend) {
    let scene = hard("fast_sphere.ron");
    let speed = scene.colliders[0].sphere().unwrap().motion.max_speed();
    let mass = scene.vertex_mass() * scene.vertex_count() as f64;
    let driven = 0.5 * mass * (2.0 * speed).powi(2);
    for integrator in integrators(backend) {
        let scene = with_integrator(&scene, integrator);
        let Some(outcome) = run_checked_with_work(backend, &scene, scene.time.frames, 1, driven) else { return };
        let radius = scene.colliders[0].sphere().unwrap().radius;
        eprintln!(
            "{}: {} substeps/frame, max penetration {:.2}% of the radius, max strain {:.3}, energy {:.3e} -> {:.3e} J (bound {:.3e} J)",
            outcome.name,
            scene.substeps_per_frame(),
            100.0 * outcome.max_penetration_m / radius,
            outcome.max_strain,
            outcome.energies[0],
            outcome.energies.last().unwrap(),
            outcome.energies[0] + driven
        );
        assert!(
            outcome.max_penetration_m < 0.2 * radius,
            "{}: penetration {}",
            outcome.name,
            outcome.max_penetration_m
        );
        assert!(outcome.max_strain < 2.0, "{}: strain {}", outcome.name, outcome.max_strain);
        let z = outcome.last().centroid()[2];
        assert!(z > 0.05, "{}: the ball pushed the cloth along (centroid z {z})", outcome.name);
    }
}

/// Substeps of the soak on a backend: a million on the CPU backends (1e5 for the implicit
/// integrators, whose substeps are tens of sweeps or solver iterations each); on the GPU backends
/// a million too when `CLOTH_SOAK_SUBSTEPS` says so (`scripts/gpu-check.sh stability` does), else
/// 1e4 for the force-based integrators and 1e3 for XPBD, VBD and backward Euler, since lavapipe
/// spends about 70 µs per dispatch and a substep of this cloth is 112 dispatches under XPBD, 52
/// under VBD and 66 under backward Euler with the suites' solver (the CPU backends run the same
/// code paths a million times; the GPU runs check the kernels over a long run within CI's time).
fn soak_substeps(backend: &Backend, integrator: Integrator) -> u64 {
    if let Some(n) = std::env::var("CLOTH_SOAK_SUBSTEPS").ok().and_then(|s| s.parse().ok()) {
        return n;
    }
    match (backend.name, integrator) {
        ("cpu" | "cpu-f64", i) if i.is_implicit() => 100_000,
        ("cpu" | "cpu-f64", _) => 1_000_000,
        (_, i) if i == Integrator::Xpbd || i.is_implicit() => 1_000,
        _ => 10_000,
    }
}

/// A hanging cloth without any damping, for a million substeps: no NaN, the pins exactly where
/// they started, the energy bounded (checked every 100 frames of 100 substeps).
fn soak_of_a_million_substeps(backend: &Backend) {
    let base = hard("soak.ron");
    for integrator in integrators(backend) {
        let scene = with_integrator(&base, integrator);
        let per_frame = scene.substeps_per_frame() as u64;
        let frames = (soak_substeps(backend, integrator) / per_frame) as u32;
        let Some(outcome) = run_checked(backend, &scene, frames, 100) else { return };
        let first = &outcome.states[0];
        let last = outcome.last();
        for (i, &pinned) in outcome.model.grid.pinned.iter().enumerate() {
            if pinned {
                assert_eq!(last.positions[i], first.positions[i], "{}: pin {i} moved", outcome.name);
                assert_eq!(last.velocities[i], [0.0; 3], "{}: pin {i} has a velocity", outcome.name);
            }
        }
        let (low, high) = outcome.energies.iter().fold((f64::MAX, f64::MIN), |(a, b), &e| (a.min(e), b.max(e)));
        eprintln!(
            "{}: {} substeps, energy from {:.6e} J within [{low:.6e}, {high:.6e}] J",
            outcome.name,
            frames as u64 * per_frame,
            outcome.energies[0]
        );
    }
}

/// The springs become 100 times stiffer in the middle of a drape: `Auto` substeps follow (ten
/// times as many), and nothing blows up for 20 frames (10 on lavapipe). After the change the
/// energy is bounded by its value right after the change (the stiffer springs hold 100 times the elastic energy they did).
fn live_stiffness_change_of_100_times(backend: &Backend) {
    let base = hard("two_spheres.ron");
    for integrator in integrators(backend) {
        let scene = with_integrator(&base, integrator);
        let Some(mut sim) = create(backend, &scene) else { return };
        let name = format!("{} {integrator:?}", backend.name);
        sim.advance(20).unwrap();
        let before = scene.substeps_per_frame();
        let mut stiff = scene.clone();
        for spec in [&mut stiff.springs.structural, &mut stiff.springs.shear, &mut stiff.springs.bend] {
            spec.stiffness *= 100.0;
        }
        sim.update_parameters(&stiff).unwrap();
        let after = sim.scene().substeps_per_frame();
        assert!(after >= 5 * before, "{name}: Auto went from {before} to {after} substeps per frame");
        let model = ClothModel::new(&stiff);
        let at_change = sim.read_state().unwrap();
        let e0 = Energy::of(&model, &at_change);
        let limit = e0.total() + ENERGY_TOLERANCE * energy_scale(&model, &e0);
        // 20 frames after the change; 10 on lavapipe (each of them ten times the substeps).
        let after_frames = if short_on(backend) { 10 } else { 20 };
        for frame in 1..=after_frames {
            sim.advance(1).unwrap();
            let state = sim.read_state().unwrap();
            assert_eq!(state.non_finite_count(), 0, "{name}: NaN {frame} frames after the change");
            let e = Energy::of(&model, &state).total();
            assert!(e <= limit, "{name}: energy {e:.4e} J {frame} frames after the change, limit {limit:.4e} J");
        }
        eprintln!("{name}: {before} -> {after} substeps per frame, energy after the change {:.4e} J", e0.total());
    }
}

/// Regularised friction lets a resting cloth creep down a slope forever; the model's friction,
/// with its stopping term (and XPBD's in position form), holds it. After 10 s on a high-friction
/// sphere the cloth is still on it, and the patch of vertices in contact (within 1% of the radius
/// of its surface) drifted less than `CREEP_SPEED_M_S` on average over the last four seconds
/// (the mean of the patch: single edge vertices jiggle by a millimetre as the free flaps, still
/// swinging at centimetres per second, tug at them; that is not creep).
///
/// Found with XPBD's first friction, applied to velocities after the substep: the positions had
/// already slid `g sin θ Δt²` in every substep, and the drape slid off the sphere within a second.
const CREEP_SPEED_M_S: f64 = 2e-4;

fn resting_drape_does_not_creep(backend: &Backend) {
    let base = hard("creep.ron");
    let sphere = base.colliders[0].sphere().unwrap();
    let distance = |p: &[f32; 3]| (0..3).map(|k| (p[k] as f64 - sphere.center[k]).powi(2)).sum::<f64>().sqrt();
    for integrator in integrators(backend) {
        let scene = with_integrator(&base, integrator);
        let Some(outcome) = run_checked(backend, &scene, scene.time.frames, 30) else { return };
        let n = outcome.states.len();
        // States every 30 frames (0.5 s): the last four seconds are the last 8 intervals.
        let (early, late) = (&outcome.states[n - 9], outcome.last());
        let seconds = 8.0 * 30.0 * scene.time.frame_dt;
        let patch: Vec<usize> =
            (0..late.positions.len()).filter(|&i| distance(&late.positions[i]) < 1.01 * sphere.radius).collect();
        assert!(patch.len() >= 4, "{}: only {} vertices rest on the sphere", outcome.name, patch.len());
        let mean = |state: &ClothState| {
            let mut m = [0.0; 3];
            for &i in &patch {
                for (k, mk) in m.iter_mut().enumerate() {
                    *mk += state.positions[i][k] as f64 / patch.len() as f64;
                }
            }
            m
        };
        let (a, b) = (mean(early), mean(late));
        let speed = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt() / seconds;
        eprintln!(
            "{}: {} vertices in contact, their mean drifts at {speed:.3e} m/s over the last 4 s",
            outcome.name,
            patch.len()
        );
        assert!(speed < CREEP_SPEED_M_S, "{}: creeps at {speed:.3e} m/s", outcome.name);
    }
}

// ---------------------------------------------------------------------------------------------
// The colliders: ground, box, capsule, and the cloth on itself.

/// `scenes/floor.ron` (a cloth dropped flat from 0.6 m onto the ground, default contact
/// stiffness) at 12 × 12 for 1.5 s: the cloth lands and rests. The deepest penetration over every
/// substep stays under 5% of the spacing; at the end every vertex lies within 5% of the spacing
/// of the ground and moves at under 2 cm/s.
fn floor_landing_rests(backend: &Backend) {
    let scene = sized(cloth_conformance::scene("floor.ron"), 12, 90);
    let h = spacing(&scene);
    every_integrator(backend, &scene, 0.05, 0.1, |outcome| {
        let last = outcome.last();
        let highest = last.positions.iter().map(|p| p[1] as f64).fold(f64::MIN, f64::max);
        let lowest = last.positions.iter().map(|p| p[1] as f64).fold(f64::MAX, f64::min);
        let fastest = last.velocities.iter().map(|v| (0..3).map(|k| (v[k] as f64).powi(2)).sum::<f64>().sqrt());
        let fastest = fastest.fold(0.0, f64::max);
        eprintln!("{}: rests between y = {lowest:.2e} and {highest:.2e} m, fastest {fastest:.2e} m/s", outcome.name);
        assert!(highest < 0.05 * h && lowest > -0.05 * h, "{}: not flat on the ground", outcome.name);
        assert!(fastest < 0.02, "{}: still moving at {fastest} m/s", outcome.name);
    });
}

/// The same cloth thrown at the ground at 10 m/s from 0.3 m: no vertex tunnels. The penetration
/// stays below half the spacing over every substep (a vertex stopped that short of the far side
/// of a half-space cannot be through it), and at the end every vertex is above the ground.
fn floor_at_10_m_s_does_not_tunnel(backend: &Backend) {
    let mut scene = sized(cloth_conformance::scene("floor.ron"), 12, 30);
    scene.cloth.center[1] = 0.3;
    scene.cloth.initial_velocity = [0.0, -10.0, 0.0];
    every_integrator(backend, &scene, 0.5, 0.5, |outcome| {
        let lowest = outcome.last().positions.iter().map(|p| p[1] as f64).fold(f64::MAX, f64::min);
        assert!(lowest > -0.05 * spacing(&scene), "{}: a vertex ended at y = {lowest} m", outcome.name);
    });
}

/// `scenes/hard/tilted_table.ron`: a cloth dropped 2 cm onto a slab tilted by 20°. With friction
/// 1.0 (above tan 20° = 0.36) the cloth stays where it landed: over the last half second its
/// centroid moves less than 2 mm along the slope. With friction 0.05 it slides down, by more than
/// 0.3 m in 1 s (`½ g (sin θ − c_f cos θ) t²` = 1.4 m without the drag of the slab's edge).
fn tilted_table_holds_with_friction_and_slides_without(backend: &Backend) {
    let held = hard("tilted_table.ron");
    let mut slippery = held.clone();
    slippery.colliders[0].friction = 0.05;
    let slope = [0.93969, 0.34202, 0.0];
    let along = |c: [f64; 3]| (0..3).map(|k| c[k] * slope[k]).sum::<f64>();
    let start = along(held.cloth.center);
    every_integrator(backend, &held, 0.05, 0.1, |outcome| {
        let half = &outcome.states[outcome.states.len() / 2];
        let landing = along(half.centroid()) - start;
        let moved = along(outcome.last().centroid()) - along(half.centroid());
        eprintln!(
            "{}: friction 1.0, the centroid moved {landing:.4} m along the slope landing, then {moved:.2e} m",
            outcome.name
        );
        assert!(moved.abs() < 0.002, "{}: slid {moved} m in the last half second with friction 1.0", outcome.name);
    });
    every_integrator(backend, &slippery, 0.05, 0.2, |outcome| {
        let moved = along(outcome.last().centroid()) - start;
        eprintln!("{}: friction 0.05, the centroid moved {moved:.4} m along the slope", outcome.name);
        assert!(moved < -0.3, "{}: moved only {moved} m down the slope with friction 0.05", outcome.name);
    });
}

/// `scenes/capsule.ron` at 16 × 16 (cells smaller than the pole's radius) for 1.25 s: the cloth
/// falls across the pole and hangs over it, no deeper than 10% of the spacing inside it; at the
/// end its middle row rests on the pole and its sides hang below it.
fn cloth_falls_across_a_capsule(backend: &Backend) {
    let scene = sized(cloth_conformance::scene("capsule.ron"), 16, 75);
    let Shape::Capsule { a, radius, .. } = scene.colliders[0].shape else {
        panic!("capsule.ron starts with a capsule")
    };
    let top = a[1] + radius;
    every_integrator(backend, &scene, 0.1, 0.2, |outcome| {
        let last = outcome.last();
        let highest = last.positions.iter().map(|p| p[1] as f64).fold(f64::MIN, f64::max);
        let c = last.centroid();
        eprintln!("{}: highest vertex at {highest:.3} m (pole top {top:.3} m), centroid {c:.3?}", outcome.name);
        assert!((highest - top).abs() < 0.05, "{}: the cloth does not rest on the pole", outcome.name);
        assert!(c[1] < top - 0.1, "{}: the sides do not hang (centroid {c:?})", outcome.name);
    });
}

/// `scenes/mesh.ron` at 16 × 16 for 1.25 s: the cloth falls onto a ring, a triangle mesh sampled as
/// a distance field, no deeper than 10% of the spacing inside anything; at the end it rests on the
/// ring (its highest vertex within 5 cm of the ring's top, 0.3 m) and sags into its hole.
fn cloth_falls_onto_a_mesh(backend: &Backend) {
    let scene = sized(cloth_conformance::scene("mesh.ron"), 16, 75);
    let top = 0.3;
    every_integrator(backend, &scene, 0.1, 0.2, |outcome| {
        let last = outcome.last();
        let highest = last.positions.iter().map(|p| p[1] as f64).fold(f64::MIN, f64::max);
        let c = last.centroid();
        eprintln!("{}: highest vertex at {highest:.3} m (ring top {top} m), centroid {c:.3?}", outcome.name);
        assert!((highest - top).abs() < 0.05, "{}: the cloth does not rest on the ring", outcome.name);
        assert!(c[1] > 0.0 && c[1] < top, "{}: the cloth does not drape (centroid {c:?})", outcome.name);
    });
}

/// `scenes/heap.ron` at 32 × 32, 0.5 s, with `SelfCollision` taken out: the cloth passes through
/// itself, and the counter sees it: more than 0 edge–triangle crossings in some frame (counted
/// every 10 frames and at the end). Proof that the counter counts what it should, and that the
/// heap needs self-collision; no bound is claimed on how many.
fn heap_passes_through_itself_without_self_collision(backend: &Backend) {
    let mut scene = sized(cloth_conformance::scene("heap.ron"), 32, 30);
    scene.effects = scene.effects.without(cloth_core::Effect::SelfCollision);
    passes_through_itself(backend, &scene, 10);
}

/// The work moving pins may do on `scene`'s cloth, J, for the energy bound: they may wind every
/// spring up to three times its rest length (`Σ ½ k (2 L₀)²`, strain 2, the bound the twist cases
/// assert) and fling the cloth's mass `M` at up to twice their speed `U` (`½ M (2U)²`, as a
/// moving wall).
fn pin_work(scene: &Scene) -> f64 {
    let model = ClothModel::new(scene);
    let k = |kind: cloth_core::SpringKind| match kind {
        cloth_core::SpringKind::Structural => scene.springs.structural.stiffness,
        cloth_core::SpringKind::Shear => scene.springs.shear.stiffness,
        cloth_core::SpringKind::Bend => scene.springs.bend.stiffness,
    };
    let elastic: f64 = model.springs.iter().map(|s| 0.5 * k(s.kind) * (2.0 * s.rest_length).powi(2)).sum();
    let radius = 0.5 * scene.cloth.size[0].hypot(scene.cloth.size[1]);
    let speed = (0..=scene.cloth.pin_groups.len())
        .filter_map(|g| scene.pin_group_motion(g))
        .map(|m| m.max_speed_at(radius))
        .fold(0.0, f64::max);
    let mass = scene.vertex_mass() * scene.vertex_count() as f64;
    elastic + 0.5 * mass * (2.0 * speed).powi(2)
}

/// Every integrator on `scene` (without self-collision): more than 0 edge–triangle crossings in
/// some frame, counted every `every` frames and at the end.
fn passes_through_itself(backend: &Backend, scene: &Scene, every: u32) {
    passes_through_itself_under(backend, scene, every, &integrators(backend));
}

/// [`passes_through_itself`] under the given integrators.
fn passes_through_itself_under(backend: &Backend, scene: &Scene, every: u32, integrators: &[Integrator]) {
    let work = if scene.effects.contains(cloth_core::Effect::MovingPins) { pin_work(scene) } else { 0.0 };
    for &integrator in integrators {
        let scene = with_integrator(scene, integrator);
        let Some(outcome) = run_checked_with_work(backend, &scene, scene.time.frames, every, work) else { return };
        let [nx, ny] = scene.cloth.resolution;
        let counts: Vec<usize> = (outcome.states.iter())
            .map(|s| cloth_core::intersections::count(&s.positions, nx, ny).expect("the cloth is not torn"))
            .collect();
        let most = counts.iter().copied().max().unwrap_or(0);
        eprintln!("{}: self-intersections every {every} frames {counts:?}", outcome.name);
        assert!(most > 0, "{}: no self-intersection counted without self-collision", outcome.name);
    }
}

/// Every integrator on `scene` (with self-collision): not one edge–triangle crossing at any
/// frame. Returns each integrator's final centroid, m.
fn never_passes_through_itself(backend: &Backend, scene: &Scene) -> Vec<[f64; 3]> {
    never_passes_through_itself_under(backend, scene, &integrators(backend))
}

/// [`never_passes_through_itself`] under the given integrators.
fn never_passes_through_itself_under(backend: &Backend, scene: &Scene, integrators: &[Integrator]) -> Vec<[f64; 3]> {
    assert!(scene.effects.contains(cloth_core::Effect::SelfCollision), "{} lists SelfCollision", scene.name);
    let mut centroids = Vec::new();
    let work = if scene.effects.contains(cloth_core::Effect::MovingPins) { pin_work(scene) } else { 0.0 };
    for &integrator in integrators {
        let scene = with_integrator(scene, integrator);
        let Some(outcome) = run_checked_with_work(backend, &scene, scene.time.frames, 1, work) else {
            return centroids;
        };
        let [nx, ny] = scene.cloth.resolution;
        for (frame, state) in outcome.states.iter().enumerate() {
            let crossings = cloth_core::intersections::count(&state.positions, nx, ny).expect("the cloth is not torn");
            assert_eq!(crossings, 0, "{}: {crossings} self-intersections at frame {frame}", outcome.name);
        }
        let c = outcome.last().centroid();
        eprintln!(
            "{}: no self-intersection in {} frames, centroid {c:.3?}, largest strain {:.3}",
            outcome.name,
            outcome.states.len() - 1,
            outcome.max_strain
        );
        if work > 0.0 {
            assert!(outcome.max_strain < 2.0, "{}: a spring more than tripled its length", outcome.name);
        }
        centroids.push(c);
    }
    centroids
}

/// `scenes/heap.ron` (with `SelfCollision`) at 16 × 16, 1/4 s, every integrator: the fall of the
/// case above, and not one edge–triangle crossing at any frame. (Without self-collision this fall
/// already crosses itself 426 times within these 15 frames, on the CPU.)
fn heap_with_self_collision_never_passes_through_itself(backend: &Backend) {
    let scene = sized(cloth_conformance::scene("heap.ron"), 16, 15);
    for c in never_passes_through_itself(backend, &scene) {
        assert!(c[1] < 0.5, "{}: the heap did not fall (centroid {c:?})", backend.name);
    }
}

/// The folding drape of `scenes/drape_folds.ron` at a size lavapipe runs: 48 × 48, dropped from
/// 5 cm above the sphere instead of 30 cm, so that its free corners fold onto the cloth within
/// 36 frames. With self-collision not one edge–triangle crossing at any frame; with it taken out,
/// more than 0 in some frame (counted at every frame: the corners pass through the cloth from
/// frame 30 to 34 on, by integrator and backend; at 40 × 40 they do not fold). At this size the
/// case takes minutes on lavapipe and the CPU under all four integrators, so it runs semi-implicit
/// Euler and XPBD, one force-based integrator and the position-based one, and the run without the
/// effect, which shows what the scene needs rather than what a backend does, on the f32 reference
/// alone; with `CLOTH_FULL_SIZE` (`scripts/gpu-check.sh stability`) it runs the scene as its file
/// gives it, 128 × 128 for 240 frames, under every integrator, both halves on every backend.
fn folded_drape_never_passes_through_itself(backend: &Backend) {
    let file = cloth_conformance::scene("drape_folds.ron");
    let full_size = std::env::var_os("CLOTH_FULL_SIZE").is_some();
    let (scene, integrators) = if full_size {
        (file, integrators(backend))
    } else {
        let mut scene = sized(file, 48, 36);
        scene.cloth.center[1] = 1.55;
        (scene, vec![Integrator::SemiImplicitEuler, Integrator::Xpbd])
    };
    for c in never_passes_through_itself_under(backend, &scene, &integrators) {
        assert!(c[1] < 1.55, "{}: the drape did not fall (centroid {c:?})", backend.name);
    }
    if full_size || backend.name == cloth_conformance::CPU.name {
        let mut without = scene.clone();
        without.effects = without.effects.without(cloth_core::Effect::SelfCollision);
        passes_through_itself_under(backend, &without, 1, &integrators);
    }
}

/// The cloth of `scenes/slide_off_box.ron` lands on a tilted, slippery box, slides off it and
/// piles onto the ground. At a size lavapipe runs, 16 × 16 for 2 s, under semi-implicit Euler and
/// XPBD (one force-based integrator and the position-based one): not one edge–triangle crossing
/// at any frame, and the cloth ends on the ground past the box's lower edge. Without
/// self-collision the XPBD cloth passes through itself within these 2 s (35 crossings on the f32
/// reference; the force-based integrators' cloth at 16 × 16 is too stiff in bending to fold onto
/// itself), checked on the f32 reference alone, as for the folded drape. With `CLOTH_FULL_SIZE`
/// (`scripts/gpu-check.sh stability`) the scene as its file gives it, 48 × 48 for 180 frames,
/// under every integrator, both halves on every backend.
fn cloth_sliding_off_a_box_never_passes_through_itself(backend: &Backend) {
    let file = cloth_conformance::scene("slide_off_box.ron");
    let full_size = std::env::var_os("CLOTH_FULL_SIZE").is_some();
    let (scene, integrators) = if full_size {
        (file, integrators(backend))
    } else {
        (sized(file, 16, 120), vec![Integrator::SemiImplicitEuler, Integrator::Xpbd])
    };
    for c in never_passes_through_itself_under(backend, &scene, &integrators) {
        // The box's upper side ends near x = 0.5 m and 0.7 m above the ground.
        assert!(c[0] > 0.7 && c[1] < 0.2, "{}: the cloth did not slide off the box (centroid {c:?})", backend.name);
    }
    let mut without = scene.clone();
    without.effects = without.effects.without(cloth_core::Effect::SelfCollision);
    if full_size {
        passes_through_itself_under(backend, &without, 1, &integrators);
    } else if backend.name == cloth_conformance::CPU.name {
        passes_through_itself_under(backend, &without, 1, &[Integrator::Xpbd]);
    }
}

/// `scenes/twist.ron` at 16 × 16 for 1 s, every integrator: its top and bottom edges turn a
/// quarter turn each against each other while closing in, and the wrung cloth lies on itself
/// without one edge–triangle crossing at any frame. (Without self-collision the same second
/// ends with 104 crossings on the CPU; the next case.)
fn twist_with_self_collision_never_passes_through_itself(backend: &Backend) {
    let scene = sized(cloth_conformance::scene("twist.ron"), 16, 60);
    assert!(scene.cloth.pin_groups.len() == 1 && scene.cloth.pin_motion.turns(), "twist.ron turns two pin groups");
    for c in never_passes_through_itself(backend, &scene) {
        // The edges' pivots stay on the y axis: so does the wrung cloth.
        assert!(c[0].abs() < 0.05 && c[2].abs() < 0.05, "{}: the twist drifted off its axis ({c:?})", backend.name);
    }
}

/// `scenes/twist.ron` at 16 × 16 for 1 s with `SelfCollision` taken out: the wrung layers pass
/// through each other, and the counter sees it.
fn twist_passes_through_itself_without_self_collision(backend: &Backend) {
    let mut scene = sized(cloth_conformance::scene("twist.ron"), 16, 60);
    scene.effects = scene.effects.without(cloth_core::Effect::SelfCollision);
    passes_through_itself(backend, &scene, 10);
}

cloth_conformance::for_every_backend! {
    stiff_springs_with_auto_substeps,
    step_at_0_95_of_the_bound,
    implicit_integrators_at_10_and_100_times_the_explicit_bound,
    backward_euler_lands_at_one_substep_a_frame,
    vbd_lands_at_one_substep_a_frame,
    light_vertices_of_1e_5_kg,
    heavy_vertices_of_10_kg,
    impact_at_30_m_s_does_not_tunnel,
    starting_inside_the_sphere_is_pushed_out,
    two_overlapping_spheres,
    sphere_smaller_than_a_cell,
    fast_moving_sphere,
    soak_of_a_million_substeps,
    live_stiffness_change_of_100_times,
    resting_drape_does_not_creep,
    floor_landing_rests,
    floor_at_10_m_s_does_not_tunnel,
    tilted_table_holds_with_friction_and_slides_without,
    cloth_falls_across_a_capsule,
    cloth_falls_onto_a_mesh,
    heap_passes_through_itself_without_self_collision,
    heap_with_self_collision_never_passes_through_itself,
    twist_passes_through_itself_without_self_collision,
    twist_with_self_collision_never_passes_through_itself,
    folded_drape_never_passes_through_itself,
    cloth_sliding_off_a_box_never_passes_through_itself,
}

/// Grids at the device's limits: the largest square grid each GPU backend accepts runs a
/// substep, and the next size up is refused with an error that names the grid, the bytes, the
/// limit and the largest grid that fits. The drape under RK4, whose largest buffer is its
/// scratch of four vec4s per vertex (the force kernels read no spring list). (On lavapipe the
/// limit is `maxStorageBufferRange`, 128 MiB, and the largest RK4 drape is 1448 × 1448.)
#[test]
fn the_largest_grid_runs_and_the_next_is_refused() {
    let _gpu = cloth_conformance::gpu_lock();
    use cloth_core::SimError;
    use cloth_gpu::GpuBackend;
    use cloth_gpu::memory::largest_square_grid;
    let tuning = cloth_gpu::GpuTuning::default();
    let limits: [(&Backend, Option<u64>); 2] = [
        (&cloth_conformance::WGPU, cloth_wgpu::WgpuBackend::open(&tuning).ok().map(|b| b.limits().max_storage_binding)),
        (
            &cloth_conformance::VULKANO,
            cloth_vulkano::VulkanoBackend::open(&tuning).ok().map(|b| b.limits().max_storage_binding),
        ),
    ];
    for (backend, limit) in limits {
        let Some(limit) = limit else {
            assert!(std::env::var_os("CI").is_none(), "{}: no device under CI", backend.name);
            eprintln!("SKIPPED on {}: no device", backend.name);
            continue;
        };
        let mut scene = Scene { integrator: Integrator::RungeKutta4, ..Scene::default() };
        scene.time.substeps = Substeps::Fixed(1);
        let n = largest_square_grid(&scene, limit);
        scene.cloth.resolution = [n, n];
        let Some(mut sim) = create(backend, &scene) else { continue };
        sim.advance(1).unwrap();
        let state = sim.read_state().unwrap();
        assert_eq!(state.positions.len(), (n * n) as usize);
        assert_eq!(state.non_finite_count(), 0, "{}: {n}x{n}", backend.name);
        drop(sim);
        scene.cloth.resolution = [n + 1, n + 1];
        match backend.create(&scene) {
            Err(e @ SimError::TooLarge { .. }) => {
                let message = e.to_string();
                eprintln!("{}: {n}x{n} ran; {}x{} refused: {message}", backend.name, n + 1, n + 1);
                for part in [format!("grid {}x{}", n + 1, n + 1), format!("largest square one that fits is {n}x{n}")] {
                    assert!(message.contains(&part), "{}: the refusal should say '{part}': {message}", backend.name);
                }
            }
            Err(e) => panic!("{}: {}x{} refused with the wrong error: {e}", backend.name, n + 1, n + 1),
            Ok(_) => panic!("{}: {}x{} was accepted beyond the limit of {limit} bytes", backend.name, n + 1, n + 1),
        }
    }
    // The CPU backends are limited by host memory (validation refuses a grid whose build would
    // need more than 8 GiB); the refusal is checked, the 8 GiB run is not (a CI machine has 24).
    let fits = |n: u32| {
        let mut s = Scene::default();
        s.cloth.resolution = [n, n];
        s.validate().is_ok()
    };
    let (mut lo, mut hi) = (2u32, 1 << 16);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) { lo = mid } else { hi = mid }
    }
    let mut scene = Scene::default();
    scene.cloth.resolution = [hi, hi];
    let message = scene.validate().unwrap_err().to_string();
    eprintln!("cpu: {lo}x{lo} is the largest grid validation accepts; {hi}x{hi}: {message}");
    assert!(message.contains("cloth.resolution") && message.contains("use a smaller grid"), "{message}");
}
