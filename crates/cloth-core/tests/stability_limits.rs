//! Each integrator's measured stability limit against the predicted one.

use cloth_core::scene::{ClothSpec, Substeps, TimeSpec};
use cloth_core::{ClothModel, CpuSimulatorF64, Effect, Integrator, Scene, Simulator, stability};

/// A free 10 x 8 cloth with the three spring kinds and nothing else: linear at rest, so the
/// stability limit of each integrator is exactly `limit / ω_max`.
fn scene(integrator: Integrator) -> Scene {
    Scene {
        cloth: ClothSpec { resolution: [10, 8], size: [0.9, 0.7], ..Default::default() },
        colliders: vec![],
        effects: [Effect::StructuralSprings, Effect::ShearSprings, Effect::BendSprings].into_iter().collect(),
        integrator,
        ..Default::default()
    }
}

/// Stays bounded for 3000 substeps of `h` from a small pseudo-random perturbation of the rest
/// shape.
fn is_stable(base: &Scene, h: f64) -> bool {
    let mut s = base.clone();
    s.time = TimeSpec { frame_dt: h, substeps: Substeps::Fixed(1), frames: 0 };
    let mut sim = CpuSimulatorF64::new(&s).unwrap();
    let mut state = sim.read_state().unwrap();
    for (i, p) in state.positions.iter_mut().enumerate() {
        for (k, c) in p.iter_mut().enumerate() {
            *c += 1e-4 * (((i * 3 + k) as f32 * 0.618_034).fract() - 0.5);
        }
    }
    sim.write_state(&state).unwrap();
    sim.advance(3000).unwrap();
    sim.positions().iter().all(|p| p.is_finite() && p.length() < 10.0)
}

#[test]
fn measured_stability_limits_are_within_20_percent_of_the_spectral_prediction() {
    for integrator in Integrator::EXPLICIT {
        let base = scene(integrator);
        let predicted = stability::spectral_stable_substep(&ClothModel::new(&base));
        let safe = stability::stable_substep(&base);
        assert!(
            safe <= predicted * 1.0001,
            "{integrator:?}: the Gershgorin bound {safe} must not exceed the estimate {predicted}"
        );
        let (mut lo, mut hi) = (0.5 * predicted, 2.0 * predicted);
        assert!(is_stable(&base, lo) && !is_stable(&base, hi), "{integrator:?}: bracket");
        for _ in 0..12 {
            let mid = 0.5 * (lo + hi);
            if is_stable(&base, mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let ratio = lo / predicted;
        eprintln!(
            "{integrator:?}: predicted {predicted:.4e} s, measured {lo:.4e} s, ratio {ratio:.3}, Gershgorin {safe:.4e} s"
        );
        assert!((0.8..=1.2).contains(&ratio), "{integrator:?}: measured/predicted = {ratio}");
    }
}

/// XPBD has no stability limit to predict (`spectral_stable_substep` is infinite for it): what
/// can be measured is that it stays bounded at 10, 100 and 1000 times the explicit limit.
#[test]
fn xpbd_stays_bounded_far_beyond_the_explicit_limit() {
    let explicit = stability::spectral_stable_substep(&ClothModel::new(&scene(Integrator::SemiImplicitEuler)));
    let base = scene(Integrator::Xpbd);
    assert!(stability::spectral_stable_substep(&ClothModel::new(&base)).is_infinite());
    for factor in [10.0, 100.0, 1000.0] {
        assert!(is_stable(&base, factor * explicit), "XPBD diverged at {factor} times the explicit limit");
    }
}
