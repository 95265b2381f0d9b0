//! Semi-implicit Euler's packed passes give the same results, bit for bit, whichever order their
//! workgroups take the grid's blocks in: forward every substep, or forward and backward by turns
//! (`REVERSED_ORDER` in `cloth_step.wgsl` / `.comp`, `cloth_gpu::geometry::alternates_order`).
//! By default the order alternates only where a substep moves 25 to 100 MB, grids larger than
//! lavapipe runs in a test's time, so the tuning asks for each order here.

use cloth_conformance::{VULKANO, WGPU, create_tuned, scene};
use cloth_core::Scene;
use cloth_core::scene::{Mass, Substeps};
use cloth_gpu::{BlockOrder, GpuTuning, Tiling};

/// The cases: Euler on a grid with contact (the drape, 150 × 41: several block rows and columns,
/// a partial block at the edge), and on the flag (pins, wind, moving pins and spheres).
fn cases() -> Vec<(&'static str, Scene, u32)> {
    let mut drape = scene("drape.ron");
    drape.cloth.resolution = [150, 41];
    drape.cloth.mass = Mass::PerVertex(0.01);
    drape.time.substeps = Substeps::Fixed(41);
    let mut flag = scene("flag.ron");
    flag.cloth.resolution = [50, 30];
    flag.integrator = cloth_core::Integrator::SemiImplicitEuler;
    vec![("drape-150x41", drape, 18), ("flag-50x30", flag, 8)]
}

#[test]
fn alternating_and_forward_block_orders_agree() {
    let _gpu = cloth_conformance::gpu_lock();
    let mut compared = 0;
    for backend in [&WGPU, &VULKANO] {
        for (name, scene, frames) in cases() {
            let mut runs = Vec::new();
            for block_order in [BlockOrder::Forward, BlockOrder::Alternating] {
                let tuning = GpuTuning { tiling: Tiling::Off, block_order, ..GpuTuning::default() };
                let Some(mut sim) = create_tuned(backend, &scene, &tuning) else { continue };
                assert_eq!(sim.substep_state_bytes(), Some(24), "{name}: {} runs on the packed state", backend.name);
                sim.advance(frames).unwrap();
                runs.push((sim.read_state().unwrap(), sim.diagnostics().unwrap().max_penetration_m));
            }
            let [(forward, a), (alternating, b)] = &runs[..] else { continue };
            assert!(forward.non_finite_count() == 0 && forward.time_s > 0.0, "{name}");
            let same = forward.positions == alternating.positions && forward.velocities == alternating.velocities;
            assert!(same && a == b, "{name} on {}: the alternating order changed the results", backend.name);
            compared += 1;
        }
    }
    if std::env::var_os("CI").is_some() {
        assert_eq!(compared, 4, "under CI both GPU backends must run both cases");
    }
}
