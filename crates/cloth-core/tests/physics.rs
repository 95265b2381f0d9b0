//! Physics tests of the CPU reference: each checks a closed-form result or a physical outcome.

use cloth_core::scene::{ClothSpec, Corner, Mass, Orientation, Pin, SphereSpec, Substeps, TimeSpec};
use cloth_core::{ClothModel, CpuSimulator, CpuSimulatorF64, Effect, EffectSet, Energy, Scene, Simulator, stability};

fn scenes_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

fn load(name: &str) -> Scene {
    Scene::load(&scenes_dir().join(name)).unwrap()
}

/// A scene with no effect but those given, a small grid, and no sphere.
fn bare(effects: &[Effect], resolution: [u32; 2]) -> Scene {
    Scene {
        cloth: ClothSpec { resolution, size: [1.0, 1.0], center: [0.0, 2.0, 0.0], ..Default::default() },
        colliders: vec![],
        effects: effects.iter().copied().collect(),
        ..Default::default()
    }
}

#[test]
fn free_fall_matches_the_exact_discrete_solution() {
    // With only gravity, symplectic Euler gives after n substeps of h:
    //   v_n = n h g,   x_n = x_0 + h² g n(n+1)/2.
    let scene = bare(&[Effect::Gravity], [3, 3]);
    let mut sim = CpuSimulatorF64::new(&scene).unwrap();
    let frames = 30;
    sim.advance(frames).unwrap();
    let n = (frames * scene.substeps_per_frame()) as f64;
    let h = scene.substep_dt();
    let g = scene.gravity[1];
    let y0 = 2.0;
    for (p, v) in sim.positions().iter().zip(sim.velocities()) {
        assert!((v.y - n * h * g).abs() < 1e-9, "v = {}, expected {}", v.y, n * h * g);
        assert!((p.y - (y0 + h * h * g * n * (n + 1.0) / 2.0)).abs() < 1e-9);
    }
}

#[test]
fn a_mass_on_a_vertical_spring_oscillates_at_sqrt_k_over_m() {
    // A 2x2 vertical cloth pinned along its top edge: each bottom vertex hangs on one vertical
    // structural spring (the horizontal bottom spring stays unstretched by symmetry).
    let k = 50.0;
    let m = 0.01;
    let mut scene = bare(&[Effect::Gravity, Effect::StructuralSprings], [2, 2]);
    scene.cloth.orientation = Orientation::Vertical;
    scene.cloth.mass = Mass::PerVertex(m);
    scene.cloth.pins = vec![Pin::Corner(Corner::TopLeft), Pin::Corner(Corner::TopRight)];
    scene.springs.structural.stiffness = k;
    scene.time = TimeSpec { frame_dt: 1e-3, substeps: Substeps::Fixed(10), frames: 0 };
    let mut sim = CpuSimulatorF64::new(&scene).unwrap();
    // Record y of vertex 0 and find the upward zero crossings about the equilibrium.
    let equilibrium = 2.0 - 0.5 - m * 9.81 / k;
    let mut crossings = Vec::new();
    let mut previous = sim.positions()[0].y - equilibrium;
    let h = scene.substep_dt();
    for step in 1..=200_000 {
        sim.substep();
        let y = sim.positions()[0].y - equilibrium;
        if previous < 0.0 && y >= 0.0 {
            crossings.push(step as f64 * h - h * y / (y - previous));
        }
        previous = y;
        if crossings.len() == 6 {
            break;
        }
    }
    let period = (crossings[5] - crossings[0]) / 5.0;
    let expected = 2.0 * std::f64::consts::PI / (k / m).sqrt();
    assert!((period / expected - 1.0).abs() < 0.01, "period {period} s, expected {expected} s");
}

#[test]
fn pinned_vertices_never_move() {
    let scene = load("hanging.ron");
    let model = ClothModel::new(&scene);
    let mut sim = CpuSimulator::new(&scene).unwrap();
    let start = sim.read_state().unwrap();
    sim.advance(60).unwrap();
    let end = sim.read_state().unwrap();
    let pinned: Vec<usize> = (0..model.vertex_count()).filter(|&i| model.grid.pinned[i]).collect();
    assert_eq!(pinned.len(), 2);
    for i in pinned {
        assert_eq!(start.positions[i], end.positions[i]);
        assert_eq!(end.velocities[i], [0.0; 3]);
    }
    // ... while the rest of the cloth did move.
    assert!(end.centroid()[1] < start.centroid()[1] - 0.01);
}

#[test]
fn drape_rests_on_the_sphere_without_sinking_into_it() {
    let scene = load("drape.ron");
    let sphere = scene.colliders[0].sphere().unwrap();
    let mut sim = CpuSimulator::new(&scene).unwrap();
    sim.advance(scene.time.frames).unwrap();
    let state = sim.read_state().unwrap();
    let diagnostics = sim.diagnostics().unwrap();
    assert_eq!(state.non_finite_count(), 0);
    assert!(
        diagnostics.max_penetration_m < 0.02 * sphere.radius,
        "max penetration {} m is more than 2% of the radius",
        diagnostics.max_penetration_m
    );
    let centroid = state.centroid();
    assert!(centroid[1] > sphere.center[1], "centroid {centroid:?} should be above the sphere's centre");
    assert!(centroid[0].abs() < 0.05 && centroid[2].abs() < 0.05, "drape stays centred: {centroid:?}");
    let energy = Energy::of(&ClothModel::new(&scene), &state);
    // Near rest: the kinetic energy is a tiny fraction of the 0.5 kg x 9.81 x 0.8 m ≈ 4 J released.
    assert!(energy.kinetic < 0.01, "kinetic energy {} J", energy.kinetic);
}

/// `true` when the cloth has left the sphere: no vertex near it and the centroid below it.
fn is_off_the_sphere(state: &cloth_core::ClothState, sphere: &SphereSpec) -> bool {
    let near = state.positions.iter().any(|p| {
        let d: f64 = (0..3).map(|k| (p[k] as f64 - sphere.center[k]).powi(2)).sum::<f64>().sqrt();
        d < sphere.radius * 1.1
    });
    !near && state.centroid()[1] < sphere.center[1] - sphere.radius
}

#[test]
fn slide_leaves_the_frictionless_sphere_and_hold_stays() {
    for (name, should_leave) in [("slide.ron", true), ("hold.ron", false)] {
        let scene = load(name);
        let sphere = scene.colliders[0].sphere().unwrap();
        let mut sim = CpuSimulator::new(&scene).unwrap();
        sim.advance(scene.time.frames).unwrap();
        let state = sim.read_state().unwrap();
        assert_eq!(state.non_finite_count(), 0, "{name}");
        assert_eq!(is_off_the_sphere(&state, &sphere), should_leave, "{name}: centroid {:?}", state.centroid());
        if !should_leave {
            assert!(state.centroid()[1] > sphere.center[1], "{name}: centroid {:?}", state.centroid());
        }
    }
}

#[test]
fn the_stability_bound_separates_stable_from_unstable_steps() {
    let mut scene = bare(
        &[Effect::Gravity, Effect::StructuralSprings, Effect::ShearSprings, Effect::BendSprings, Effect::SpringDamping],
        [12, 9],
    );
    scene.cloth.pins = vec![Pin::Corner(Corner::TopLeft), Pin::Corner(Corner::TopRight)];
    scene.cloth.orientation = Orientation::Vertical;
    let bound = stability::stable_substep(&scene);
    let run = |factor: f64| {
        let mut s = scene.clone();
        s.time = TimeSpec { frame_dt: factor * bound, substeps: Substeps::Fixed(1), frames: 0 };
        let warnings = s.validate().unwrap();
        let mut sim = CpuSimulator::new(&s).unwrap();
        sim.advance(10_000).unwrap();
        let state = sim.read_state().unwrap();
        let extent = state.positions.iter().flatten().fold(0.0f32, |a, x| a.max(x.abs()));
        (warnings.len(), state.non_finite_count(), extent)
    };
    let (warnings, nan, extent) = run(0.8);
    assert_eq!((warnings, nan), (0, 0));
    assert!(extent < 10.0, "stable run stays near its start, extent {extent} m");
    let (warnings, nan, extent) = run(3.0);
    assert_eq!(warnings, 1, "validation warns at 3x the bound");
    assert!(nan > 0 || extent > 1e3, "3x the bound blows up (extent {extent} m, {nan} NaN vertices)");
}

#[test]
fn f32_and_f64_references_agree_on_a_short_horizon() {
    // 12 frames (0.2 s) ends before the cloth reaches the sphere (free fall of 0.3 m takes
    // 0.25 s): only rounding separates the two. A coordinate near 2 m has an f32 ulp of
    // 2.4e-7 m; the springs are restoring, so rounding errors do not grow without bound.
    // 1e-5 m allows about 40 ulps (seen: 2.5 ulps). After contact starts, the two runs may
    // drift apart faster (contact switches on and off at slightly different substeps), which
    // the conformance suite handles with outcome checks instead.
    let scene = load("drape.ron");
    let mut a = CpuSimulator::new(&scene).unwrap();
    let mut b = CpuSimulatorF64::new(&scene).unwrap();
    a.advance(12).unwrap();
    b.advance(12).unwrap();
    let (sa, sb) = (a.read_state().unwrap(), b.read_state().unwrap());
    let worst = sa
        .positions
        .iter()
        .zip(&sb.positions)
        .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).abs()).fold(0.0, f32::max))
        .fold(0.0, f32::max);
    assert!(worst < 1e-5, "f32 and f64 differ by {worst} m after 12 frames");
}

#[test]
fn state_handover_preserves_the_state_exactly() {
    let scene = load("drape.ron");
    let mut a = CpuSimulator::new(&scene).unwrap();
    a.advance(10).unwrap();
    let state = a.read_state().unwrap();
    let mut b = CpuSimulator::new(&scene).unwrap();
    b.write_state(&state).unwrap();
    assert_eq!(b.read_state().unwrap(), state);
    a.advance(5).unwrap();
    b.advance(5).unwrap();
    assert_eq!(a.read_state().unwrap().positions, b.read_state().unwrap().positions);
}

#[test]
fn live_parameter_updates_apply_and_structural_changes_are_refused() {
    let scene = load("drape.ron");
    let mut sim = CpuSimulator::new(&scene).unwrap();
    let mut changed = scene.clone();
    changed.gravity = [0.0, 0.0, 0.0];
    changed.effects = EffectSet::mass_spring();
    sim.update_parameters(&changed).unwrap();
    sim.advance(5).unwrap();
    assert_eq!(sim.read_state().unwrap().centroid()[1] as f32, 1.8f32, "no gravity: the flat cloth stays");
    let mut regrid = scene.clone();
    regrid.cloth.resolution = [8, 8];
    let err = sim.update_parameters(&regrid).unwrap_err();
    assert!(err.to_string().contains("grid resolution"), "{err}");
}

#[test]
fn every_integrator_drapes_without_nan_or_deep_penetration() {
    for integrator in cloth_core::Integrator::ALL {
        let mut scene = load("drape.ron");
        scene.cloth.resolution = [16, 16];
        scene.integrator = integrator;
        let mut sim = CpuSimulator::new(&scene).unwrap();
        sim.advance(120).unwrap();
        let state = sim.read_state().unwrap();
        assert_eq!(state.non_finite_count(), 0, "{integrator:?}");
        let depth = sim.diagnostics().unwrap().max_penetration_m;
        assert!(depth < 0.02 * scene.colliders[0].sphere().unwrap().radius, "{integrator:?}: penetration {depth} m");
        assert!(
            state.centroid()[1] > scene.colliders[0].sphere().unwrap().center[1],
            "{integrator:?}: rests on the sphere"
        );
    }
}

#[test]
fn xpbd_stays_stable_far_beyond_the_explicit_bound() {
    let mut scene = load("drape.ron");
    scene.integrator = cloth_core::Integrator::Xpbd;
    scene.time.substeps = Substeps::Fixed(2);
    let explicit =
        stability::stable_substep(&Scene { integrator: cloth_core::Integrator::SemiImplicitEuler, ..scene.clone() });
    assert!(scene.substep_dt() > 10.0 * explicit, "the step is over 10x the explicit bound");
    assert_eq!(scene.validate().unwrap(), vec![], "XPBD has no stability warning");
    let mut sim = CpuSimulator::new(&scene).unwrap();
    sim.advance(scene.time.frames).unwrap();
    let state = sim.read_state().unwrap();
    assert_eq!(state.non_finite_count(), 0);
    let sphere = &scene.colliders[0].sphere().unwrap();
    assert!(sim.diagnostics().unwrap().max_penetration_m < 0.02 * sphere.radius);
    // It rests on the sphere: its highest point on the sphere's top, its centroid over the
    // sphere. (With 2 substeps of 10 iterations the cloth is softer than its springs' k, a known
    // property of XPBD, so it hangs lower than the explicit runs: no tighter check on the centroid.)
    let top = state.positions.iter().map(|p| p[1] as f64).fold(f64::MIN, f64::max);
    assert!((top - (sphere.center[1] + sphere.radius)).abs() < 0.02, "top {top} m");
    let c = state.centroid();
    assert!(c[0].abs() < 0.15 && c[2].abs() < 0.15, "drapes over the sphere: {c:?}");
    let speed =
        state.velocities.iter().map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()).fold(0.0f32, f32::max);
    assert!(speed < 0.5, "comes nearly to rest (fastest vertex {speed} m/s)");
}
