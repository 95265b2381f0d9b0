//! A cloth pinned at two corners, printed as it settles: no GPU, no window, just the model.
//!
//! ```text
//! cargo run -p cloth-core --example hanging
//! ```

use cloth_core::scene::{ClothSpec, Corner, Orientation, Pin};
use cloth_core::{ClothModel, CpuSimulator, Effect, Energy, Scene, Simulator, Substeps};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scene = Scene {
        name: "hanging example".into(),
        cloth: ClothSpec {
            resolution: [16, 16],
            size: [1.0, 1.0],
            center: [0.0, 1.5, 0.0],
            orientation: Orientation::Vertical,
            pins: vec![Pin::Corner(Corner::TopLeft), Pin::Corner(Corner::TopRight)],
            ..Default::default()
        },
        colliders: vec![],
        air_drag: 0.5,
        effects: [
            Effect::Gravity,
            Effect::StructuralSprings,
            Effect::ShearSprings,
            Effect::BendSprings,
            Effect::SpringDamping,
            Effect::AirDrag,
        ]
        .into_iter()
        .collect(),
        ..Default::default()
    };
    let mut scene = scene;
    scene.time.substeps = Substeps::Auto;
    let model = ClothModel::new(&scene);
    let mut sim = CpuSimulator::new(&scene)?;
    println!(
        "{} vertices, {} substeps per frame of {:.4} s",
        model.vertex_count(),
        scene.substeps_per_frame(),
        scene.time.frame_dt
    );
    println!("{:>6}  {:>10}  {:>12}  {:>12}", "t (s)", "lowest y", "kinetic (J)", "elastic (J)");
    for _ in 0..=20 {
        let state = sim.read_state()?;
        let energy = Energy::of(&model, &state);
        let lowest = state.positions.iter().map(|p| p[1]).fold(f32::INFINITY, f32::min);
        println!(
            "{:>6.2}  {:>10.4}  {:>12.3e}  {:>12.3e}",
            state.time_s,
            lowest,
            energy.kinetic,
            energy.elastic.iter().sum::<f64>()
        );
        sim.advance(15)?;
    }
    Ok(())
}
