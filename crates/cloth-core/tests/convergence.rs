//! Each integrator's measured order of accuracy on a smooth scene without contact.
//!
//! XPBD is included: on this undamped scene, with small steps its Gauss–Seidel sweeps converge
//! (the compliance `1/(k Δt²)` dominates), so it approaches implicit Euler, a first-order method.

use cloth_core::scene::{ClothSpec, Corner, Orientation, Pin, Substeps, TimeSpec};
use cloth_core::{CpuSimulatorF64, Effect, Integrator, Scene, Simulator, stability};

/// A hanging 8 x 8 cloth with gravity and the three spring kinds, no damping and no contact:
/// smooth, conservative forces, where every integrator shows its theoretical order (XPBD, which
/// does not model spring damping, needs the undamped scene too).
fn smooth_scene(integrator: Integrator, duration: f64, substeps: u32) -> Scene {
    Scene {
        cloth: ClothSpec {
            resolution: [8, 8],
            size: [0.7, 0.7],
            center: [0.0, 1.0, 0.0],
            orientation: Orientation::Vertical,
            pins: vec![Pin::Corner(Corner::TopLeft), Pin::Corner(Corner::TopRight)],
            initial_velocity: [0.0, 0.0, 0.4],
            ..Default::default()
        },
        colliders: vec![],
        effects: [Effect::Gravity, Effect::StructuralSprings, Effect::ShearSprings, Effect::BendSprings]
            .into_iter()
            .collect(),
        time: TimeSpec { frame_dt: duration, substeps: Substeps::Fixed(substeps), frames: 1 },
        integrator,
        ..Default::default()
    }
}

fn positions_after(scene: &Scene) -> Vec<[f64; 3]> {
    let mut sim = CpuSimulatorF64::new(scene).unwrap();
    sim.advance(1).unwrap();
    sim.positions().iter().map(|p| p.to_f64()).collect()
}

fn max_error(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter().zip(b).flat_map(|(p, q)| (0..3).map(move |k| (p[k] - q[k]).abs())).fold(0.0, f64::max)
}

#[test]
fn measured_orders_match_the_theory() {
    let duration = 0.05;
    // The reference: RK4 in f64 with a step 64 times below the finest one measured.
    let probe = smooth_scene(Integrator::SemiImplicitEuler, duration, 1);
    let h_max = stability::stable_substep(&probe);
    let coarse = (duration / (0.5 * h_max)).ceil() as u32;
    let reference = positions_after(&smooth_scene(Integrator::RungeKutta4, duration, coarse * 4 * 64));
    for integrator in Integrator::ALL {
        let errors: Vec<f64> = [1, 2, 4]
            .iter()
            .map(|k| max_error(&positions_after(&smooth_scene(integrator, duration, coarse * k)), &reference))
            .collect();
        let orders: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
        eprintln!(
            "{integrator:?}: h = {:.3e} s, errors {errors:?}, measured orders {orders:.2?}",
            duration / coarse as f64
        );
        for order in &orders {
            assert!(
                (order - integrator.order() as f64).abs() <= 0.3,
                "{integrator:?}: measured order {order:.2}, theory {} (errors {errors:?})",
                integrator.order()
            );
        }
    }
}
