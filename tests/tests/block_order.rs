//! Semi-implicit Euler's packed passes give the same results, bit for bit, whichever order their
//! workgroups take the grid's blocks in: forward every substep, or forward and backward by turns
//! (`REVERSED_ORDER` in `cloth_step.wgsl` / `.comp`, `cloth_core::layout::alternates_order`).
//!
//! By default the order alternates only where a substep moves 25 to 100 MB, grids larger than
//! lavapipe runs in a test's time, so the comparison sets `CLOTH_ALTERNATE_ORDER` (read when a
//! simulator is created) to 0 and to 1. The variable is given to a child process (this binary,
//! running only [`run_cases_for_the_parent`]), never set inside a running test: each run writes
//! its final states to files, and the parent compares them.

use std::path::{Path, PathBuf};
use std::process::Command;

use cloth_conformance::{Backend, VULKANO, WGPU, create, scene};
use cloth_core::Scene;
use cloth_core::scene::{Mass, Substeps};
use cloth_core::tiling::Tiling;

/// The variable that makes [`run_cases_for_the_parent`] run: the folder its files go to.
const CHILD_OUTPUT: &str = "CLOTH_BLOCK_ORDER_OUTPUT";

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

/// The file one backend's run of one case writes: positions, velocities (f32, native order),
/// then the deepest penetration (f64).
fn case_file(dir: &Path, backend: &Backend, case: &str) -> PathBuf {
    dir.join(format!("{}-{case}.bin", backend.name))
}

/// Runs every case on both GPU backends, untiled (so on the packed passes), and writes the final
/// states under `CLOTH_BLOCK_ORDER_OUTPUT`. It does nothing without that variable: it is the
/// child process of [`alternating_and_forward_block_orders_agree`].
#[test]
fn run_cases_for_the_parent() {
    let Some(dir) = std::env::var_os(CHILD_OUTPUT).map(PathBuf::from) else { return };
    for backend in [&WGPU, &VULKANO] {
        for (name, scene, frames) in cases() {
            let Some(mut sim) = create(backend, &scene) else { continue };
            assert_eq!(sim.set_tiling(Tiling::Off).unwrap(), 1, "{name}: the tiled kernel is off");
            assert_eq!(sim.substep_state_bytes(), Some(24), "{name}: {} runs on the packed state", backend.name);
            sim.advance(frames).unwrap();
            let state = sim.read_state().unwrap();
            let mut bytes: Vec<u8> = ne_bytes(&state.positions);
            bytes.extend(ne_bytes(&state.velocities));
            bytes.extend(sim.diagnostics().unwrap().max_penetration_m.to_ne_bytes());
            std::fs::write(case_file(&dir, backend, name), bytes).unwrap();
        }
    }
}

fn ne_bytes(values: &[[f32; 3]]) -> Vec<u8> {
    values.iter().flatten().flat_map(|v| v.to_ne_bytes()).collect()
}

/// Runs [`run_cases_for_the_parent`] in a child process with `CLOTH_ALTERNATE_ORDER=order`,
/// writing to `dir`.
fn run_child(order: &str, dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    let output = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "run_cases_for_the_parent", "--nocapture", "--test-threads", "1"])
        .env(CHILD_OUTPUT, dir)
        .env("CLOTH_ALTERNATE_ORDER", order)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "the child run with CLOTH_ALTERNATE_ORDER={order} failed:\n{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The largest difference between two runs' files, read as f32 (the state part), m or m/s.
fn max_difference(a: &[u8], b: &[u8]) -> f32 {
    let floats = |bytes: &[u8]| -> Vec<f32> {
        bytes.chunks_exact(4).map(|c| f32::from_ne_bytes([c[0], c[1], c[2], c[3]])).collect()
    };
    let (a, b) = (floats(&a[..a.len() - 8]), floats(&b[..b.len() - 8]));
    a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

#[test]
fn alternating_and_forward_block_orders_agree() {
    let dir = std::env::temp_dir().join(format!("cloth-block-order-{}", std::process::id()));
    let (forward, alternating) = (dir.join("forward"), dir.join("alternating"));
    run_child("0", &forward);
    run_child("1", &alternating);
    let mut compared = 0;
    for backend in [&WGPU, &VULKANO] {
        for (name, _, _) in cases() {
            let (Ok(a), Ok(b)) = (
                std::fs::read(case_file(&forward, backend, name)),
                std::fs::read(case_file(&alternating, backend, name)),
            ) else {
                // No adapter (the child said so, and would have failed under CI).
                continue;
            };
            assert_eq!(a.len(), b.len(), "{name} on {}: the two runs wrote different sizes", backend.name);
            assert!(
                a == b,
                "{name} on {}: the alternating order changed the results (max difference {})",
                backend.name,
                max_difference(&a, &b)
            );
            compared += 1;
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    if std::env::var_os("CI").is_some() {
        assert_eq!(compared, 4, "under CI both GPU backends must run both cases");
    }
}
