//! The shared GPU layer on its own, without a device: the grid's coverage by blocks and tiles,
//! the tuning's checks, the memory estimate against the plan's buffers, and the order of a
//! frame's dispatches.

use cloth_core::{Integrator, Scene, SimError, Substeps};
use cloth_gpu::geometry::{
    BlockGrid, DEFAULT_TILES, DeviceKind, DeviceLimits, MAX_TILED_VERTICES, TileConfig, alternates_order,
    choose_device, pin_bits, spilled_workgroups,
};
use cloth_gpu::memory::{MemoryEstimate, largest_square_grid};
use cloth_gpu::{BlockOrder, Dispatch, GpuTuning, Plan, Tiling};

const GPU: DeviceLimits = DeviceLimits {
    max_workgroups_per_dimension: 65_535,
    max_invocations: 1024,
    workgroup_memory: 48 * 1024,
    max_storage_binding: 1 << 31,
    storage_buffers_per_stage: 16,
    cpu: false,
};

fn tuning(workgroup_size: u32, block_width: u32) -> GpuTuning {
    GpuTuning { workgroup_size, block_width, ..GpuTuning::default() }
}

#[test]
fn block_grids_cover_the_grid_one_workgroup_a_block() {
    let default = GpuTuning::default();
    // 1024² at 64 × 4: 16 blocks across, 256 down; remainders round up.
    assert_eq!(BlockGrid::new(&default, 1024, 1024, 65_535), BlockGrid { width: 64, workgroups: [16, 256] });
    assert_eq!(BlockGrid::new(&default, 150, 41, 65_535), BlockGrid { width: 64, workgroups: [3, 11] });
    // A narrow grid gets a narrower block: 12 wide at 16 × 16.
    assert_eq!(BlockGrid::new(&default, 12, 40, 65_535), BlockGrid { width: 16, workgroups: [1, 3] });
    // Too many block rows for the device: rows of 256 vertices, spilling into y.
    assert_eq!(BlockGrid::new(&default, 300, 300_000, 65_535), BlockGrid { width: 0, workgroups: [65_535, 6] });
    assert_eq!(BlockGrid::new(&tuning(256, 0), 4, 1000, 8), BlockGrid { width: 0, workgroups: [8, 2] });
    for (nx, ny) in [(1, 1), (7, 13), (128, 2), (129, 3), (1000, 999)] {
        for t in [tuning(256, 64), tuning(64, 16), tuning(1024, 128)] {
            let grid = BlockGrid::new(&t, nx, ny, 65_535);
            let [x, y] = grid.workgroups;
            let (w, h) = (grid.width, t.workgroup_size / grid.width);
            assert!(x * w >= nx && (x - 1) * w < nx && y * h >= ny && (y - 1) * h < ny, "{nx} × {ny}: {grid:?}");
        }
    }
    assert_eq!(spilled_workgroups(1, 256, 65_535), [1, 1]);
    assert_eq!(spilled_workgroups(256 * 70_000, 256, 65_535), [65_535, 2]);
}

#[test]
fn the_tuning_refuses_what_the_kernels_cannot_run_naming_the_field() {
    let named = |t: GpuTuning| match t.check() {
        Err(SimError::InvalidOption { option, .. }) => option,
        other => panic!("{t:?} was not refused: {other:?}"),
    };
    assert!(GpuTuning::default().check().is_ok());
    assert_eq!(named(tuning(48, 16)), "GpuTuning::workgroup_size");
    assert_eq!(named(tuning(2048, 64)), "GpuTuning::workgroup_size");
    assert_eq!(named(tuning(64, 128)), "GpuTuning::block_width");
    assert_eq!(named(tuning(256, 48)), "GpuTuning::block_width");
    assert!(tuning(32, 0).check().is_ok() && tuning(1024, 1024).check().is_ok());
    let tile = |width, height, substeps| GpuTuning {
        tile: Some(TileConfig { width, height, substeps }),
        ..GpuTuning::default()
    };
    assert_eq!(named(tile(8, 16, 2)), "GpuTuning::tile");
    assert_eq!(named(tile(64, 32, 2)), "GpuTuning::tile");
    assert_eq!(named(tile(100, 100, 9)), "GpuTuning::tile");
    // A shape the kernels can run, which a small device cannot hold.
    let small = DeviceLimits { workgroup_memory: 16 * 1024, max_invocations: 256, ..GPU };
    let asked = tile(32, 16, 2);
    let refused = TileConfig::choose(
        &GpuTuning { tiling: Tiling::On, ..asked.clone() },
        Integrator::SemiImplicitEuler,
        64,
        &small,
    );
    assert!(matches!(refused, Err(SimError::InvalidOption { option: "GpuTuning::tile", .. })), "{refused:?}");
}

#[test]
fn the_tiling_policy_tiles_small_grids_on_gpus_and_what_is_asked() {
    let small = DeviceLimits { workgroup_memory: 16 * 1024, max_invocations: 256, ..GPU };
    let tiny = DeviceLimits { max_invocations: 128, ..GPU };
    let lavapipe = DeviceLimits { workgroup_memory: 32 * 1024, cpu: true, ..GPU };
    let choose = |tiling, vertices, limits: &DeviceLimits| {
        TileConfig::choose(
            &GpuTuning { tiling, ..GpuTuning::default() },
            Integrator::SemiImplicitEuler,
            vertices,
            limits,
        )
        .unwrap()
    };
    let n = 128 * 128;
    assert_eq!(choose(Tiling::Auto, n, &GPU), Some(DEFAULT_TILES[0]));
    assert_eq!(choose(Tiling::Auto, n, &small), Some(DEFAULT_TILES[1]));
    assert_eq!(choose(Tiling::Auto, n, &tiny), None);
    assert_eq!(choose(Tiling::Auto, MAX_TILED_VERTICES + 1, &GPU), None);
    assert_eq!(choose(Tiling::On, MAX_TILED_VERTICES + 1, &GPU), Some(DEFAULT_TILES[0]));
    assert_eq!(choose(Tiling::Off, n, &GPU), None);
    // A CPU implementation: not by default, but when asked.
    assert_eq!(choose(Tiling::Auto, n, &lavapipe), None);
    assert_eq!(choose(Tiling::On, n, &lavapipe), Some(DEFAULT_TILES[0]));
    // Only semi-implicit Euler has a tiled kernel.
    let verlet = TileConfig::choose(
        &GpuTuning { tiling: Tiling::On, ..GpuTuning::default() },
        Integrator::VelocityVerlet,
        n,
        &GPU,
    );
    assert_eq!(verlet.unwrap(), None);
    // 32 × 16 cells: 12 KiB and 512 invocations; 16 × 16: WebGPU's default 16 KiB and 256.
    assert_eq!(DEFAULT_TILES[0].output_block(), (24, 8));
    assert_eq!(DEFAULT_TILES[0].workgroups(1024, 1024), [1024u32.div_ceil(24), 1024u32.div_ceil(8)]);
}

#[test]
fn the_order_alternates_where_the_state_outgrows_the_cache() {
    // 1024²: 50 MB a substep, alternates; 768²: 28 MB, too; 512²: 13 MB and 2048²: 201 MB do not.
    for (n, expected) in [(1024, true), (768, true), (512, false), (2048, false)] {
        assert_eq!(alternates_order(BlockOrder::Auto, n * n), expected, "{n}²");
    }
    assert!(alternates_order(BlockOrder::Alternating, 32 * 32));
    assert!(!alternates_order(BlockOrder::Forward, 1024 * 1024));
}

#[test]
fn pin_bits_mark_the_pinned_vertices() {
    let mut positions = vec![[0.0, 0.0, 0.0, 1.0]; 70];
    for i in [0, 31, 32, 69] {
        positions[i][3] = 0.0;
    }
    assert_eq!(pin_bits(&positions), vec![1 | 1 << 31, 1, 1 << 5]);
    assert_eq!(pin_bits(&[]), vec![0]);
}

#[test]
fn the_best_device_is_chosen_unless_one_is_named() {
    let devices = || {
        vec![("cpu", "llvmpipe".to_string(), DeviceKind::Cpu), ("gpu", "NVIDIA H200".into(), DeviceKind::DiscreteGpu)]
    };
    assert_eq!(choose_device(devices(), None, "none"), Ok("gpu"));
    assert_eq!(choose_device(devices(), Some("LLVM"), "none"), Ok("cpu"));
    let missing = choose_device(devices(), Some("radeon"), "none").unwrap_err();
    assert!(missing.contains("'radeon'") && missing.contains("NVIDIA H200, llvmpipe"), "{missing}");
    assert_eq!(
        choose_device(Vec::<((), String, DeviceKind)>::new(), None, "install a driver"),
        Err("install a driver".into())
    );
}

fn scene(integrator: Integrator, n: u32) -> Scene {
    let mut scene = Scene { integrator, ..Scene::default() };
    scene.cloth.resolution = [n, n + 3];
    scene.time.substeps = Substeps::Fixed(7);
    scene
}

/// The estimate refuses grids before anything is built: it must count what the plan creates.
#[test]
fn the_memory_estimate_is_what_the_plan_allocates() {
    for integrator in Integrator::ALL {
        for tiling in [Tiling::Off, Tiling::On] {
            for (n, self_collision) in [2, 13, 64].into_iter().flat_map(|n| [(n, false), (n, true)]) {
                let mut scene = scene(integrator, n);
                scene.effects.set(cloth_core::Effect::SelfCollision, self_collision);
                let plan = Plan::new(&scene, &GpuTuning { tiling, ..GpuTuning::default() }, &GPU, "test").unwrap();
                let estimate = MemoryEstimate::of(&scene);
                // The largest storage buffer: what the device's storage bindings limit.
                let storage = plan.buffers.iter().filter(|b| b.usage != cloth_gpu::plan::BufferUsage::Uniform);
                let largest = storage.map(|b| b.size).max().unwrap();
                let total: u64 = plan.buffers.iter().map(|b| b.size).sum();
                assert_eq!(estimate.largest_buffer_bytes, largest, "{integrator:?} {n}");
                // The 64-byte placeholders, Verlet's 16-byte sink and the 4-byte deepest
                // penetration are not estimated; the packed states are, which the tiled kernel
                // does without.
                let packed = tiling == Tiling::Off || integrator != Integrator::SemiImplicitEuler;
                assert!(
                    total <= estimate.device_bytes + 4 * 64 + 16 + 4 && (!packed || total >= estimate.device_bytes),
                    "{integrator:?} {n}: {total} against {}",
                    estimate.device_bytes
                );
            }
        }
    }
    let limit = 128 << 20;
    let n = largest_square_grid(&Scene::default(), limit);
    let at = |n: u32| {
        MemoryEstimate::of(&Scene {
            cloth: cloth_core::scene::ClothSpec { resolution: [n, n], ..Default::default() },
            ..Scene::default()
        })
    };
    assert!(at(n).largest_buffer_bytes <= limit && at(n + 1).largest_buffer_bytes > limit, "{n}");
}

/// The state buffer `k` a frame's dispatches read, by the bind groups' first input position.
fn read_state(plan: &Plan, d: &Dispatch) -> usize {
    let positions = plan.state.positions;
    let first_input = plan.bind_groups[d.bind_group].buffers[2];
    positions.iter().position(|&p| p == first_input).unwrap_or(usize::MAX)
}

#[test]
fn a_frame_is_the_substeps_in_order_and_flips_the_state_once_a_substep() {
    let plain = GpuTuning { tiling: Tiling::Off, packed_state: false, ..GpuTuning::default() };
    for (integrator, per_substep) in
        [(Integrator::SemiImplicitEuler, 1), (Integrator::VelocityVerlet, 2), (Integrator::RungeKutta4, 4)]
    {
        let plan = Plan::new(&scene(integrator, 13), &plain, &GPU, "test").unwrap();
        for (substeps, current) in [(1, 0), (5, 1), (6, 0)] {
            let mut out = Vec::new();
            let after = plan.schedule.frame(substeps, current, &mut out);
            assert_eq!(out.len() as u64, substeps * per_substep, "{integrator:?}");
            assert_eq!(after, (current + substeps as usize) % 2, "{integrator:?}: the state flips each substep");
            // Each substep's first pass reads the state the one before left.
            for (s, d) in out.iter().step_by(per_substep as usize).enumerate() {
                assert_eq!(read_state(&plan, d), (current + s) % 2, "{integrator:?} substep {s}");
            }
        }
    }
    // XPBD: predict, 10 sweeps of the non-empty colours and the spheres, finish.
    let plan = Plan::new(&scene(Integrator::Xpbd, 13), &plain, &GPU, "test").unwrap();
    let mut out = Vec::new();
    plan.schedule.frame(1, 0, &mut out);
    let colours = out.iter().filter(|d| d.pipeline == out[1].pipeline).count();
    assert_eq!(colours % 10, 0);
    assert_eq!(out.len(), 1 + colours + 10 + 1);
    assert!(out.iter().all(|d| d.dynamic_offset.is_some()), "XPBD's layout has a dynamic uniform");
}

#[test]
fn packed_and_tiled_frames_fuse_substeps_as_the_schedule_says() {
    let euler = scene(Integrator::SemiImplicitEuler, 64);
    // Packed: the vec4 state flips once a submission, whatever the number of substeps.
    let packed = Plan::new(&euler, &GpuTuning { tiling: Tiling::Off, ..GpuTuning::default() }, &GPU, "test").unwrap();
    assert_eq!(packed.schedule.state_bytes(), 24);
    for substeps in [2, 3, 8] {
        let mut out = Vec::new();
        assert_eq!(packed.schedule.frame(substeps, 1, &mut out), 0);
        assert_eq!(out.len() as u64, substeps);
    }
    // A single substep cannot use the packed passes (they start and end on the vec4 state).
    let mut one = Vec::new();
    assert_eq!(packed.schedule.frame(1, 0, &mut one), 1);
    assert_eq!(one[0].pipeline, packed.schedule.substep[0].pipeline);
    // Alternating: substep s of a submission backward when s is odd.
    let alternating = GpuTuning { tiling: Tiling::Off, block_order: BlockOrder::Alternating, ..GpuTuning::default() };
    let plan = Plan::new(&euler, &alternating, &GPU, "test").unwrap();
    let mut out = Vec::new();
    plan.schedule.frame(5, 0, &mut out);
    let p = plan.schedule.packed.as_ref().unwrap();
    let expected =
        [p.first_pipeline, p.middle_pipelines[1], p.middle_pipelines[0], p.middle_pipelines[1], p.last_pipelines[0]];
    assert_eq!(out.iter().map(|d| d.pipeline).collect::<Vec<_>>(), expected);
    assert_ne!(p.middle_pipelines[0], p.middle_pipelines[1]);
    // Tiled, 2 substeps a dispatch: 7 substeps are 3 tiled dispatches and one single substep.
    let tiled = Plan::new(&euler, &GpuTuning { tiling: Tiling::On, ..GpuTuning::default() }, &GPU, "test").unwrap();
    assert_eq!(tiled.schedule.fused_substeps(), 2);
    assert!(tiled.schedule.packed.is_none(), "the packed passes never run with the tiled kernel");
    let mut out = Vec::new();
    assert_eq!(tiled.schedule.frame(7, 0, &mut out), 0);
    let t = tiled.schedule.tiled.as_ref().unwrap().pass.pipeline;
    assert_eq!(out.iter().map(|d| d.pipeline == t).collect::<Vec<_>>(), [true, true, true, false]);
}

#[test]
fn a_device_with_too_few_storage_buffers_or_invocations_is_refused() {
    let few = DeviceLimits { storage_buffers_per_stage: 8, ..GPU };
    let refused = Plan::new(&scene(Integrator::SemiImplicitEuler, 8), &GpuTuning::default(), &few, "test");
    assert!(matches!(refused, Err(SimError::Unsupported { backend: "test", .. })), "{refused:?}");
    let narrow = DeviceLimits { max_invocations: 128, ..GPU };
    let refused = Plan::new(&scene(Integrator::Xpbd, 8), &GpuTuning::default(), &narrow, "test");
    assert!(matches!(refused, Err(SimError::InvalidOption { option: "GpuTuning::workgroup_size", .. })), "{refused:?}");
    let tight = DeviceLimits { max_storage_binding: 1 << 20, ..GPU };
    let refused = Plan::new(&scene(Integrator::RungeKutta4, 300), &GpuTuning::default(), &tight, "test");
    assert!(matches!(refused, Err(SimError::TooLarge { .. })), "{refused:?}");
}

/// With self-collision every integrator's frame checks the candidate lists every `C` substeps,
/// counted from the simulation's first, before the substep: the check, then the two rebuild
/// passes as indirect dispatches reading their sizes from the check's buffer; the first substep
/// after a written state always rebuilds (the forced check).
#[test]
fn self_collision_checks_come_every_check_interval_with_indirect_rebuilds() {
    for integrator in Integrator::ALL {
        let mut scene = scene(integrator, 24);
        scene.effects = scene.effects.with(cloth_core::Effect::SelfCollision);
        scene.time.substeps = Substeps::Fixed(40);
        let interval = cloth_core::self_collision::SelfCollisionQuantities::of(&scene).check_interval as u64;
        assert!(interval > 1, "{integrator:?}: a check interval of {interval} tests nothing here");
        let plan = Plan::new(&scene, &GpuTuning::default(), &GPU, "test").unwrap();
        assert!(plan.state.indirect.is_some() && plan.state.self_control.is_some());
        let checks = plan.schedule.self_collision.as_ref().expect("self-collision's checks");
        assert_eq!(checks.interval as u64, interval);
        let (check, forced) = (checks.check.pipeline, checks.forced.pipeline);
        let per_substep = plan.schedule.substep.len();
        // A fresh simulation's first frame builds the lists before its first substep.
        let mut first = Vec::new();
        plan.schedule.frame(1, 0, &mut first);
        assert_eq!(first[0].pipeline, forced, "{integrator:?}: a fresh simulation's first substep");
        // From substep 3 on, with the lists stale: a forced check first, then every C-th.
        let mut frame = Vec::new();
        let substeps = 3 * interval;
        plan.schedule.frame_from(3, true, substeps, 0, &mut frame);
        let mut at = 0;
        for s in 3..3 + substeps {
            let expected = if s == 3 { Some(forced) } else { s.is_multiple_of(interval).then_some(check) };
            if let Some(pipeline) = expected {
                assert_eq!(frame[at].pipeline, pipeline, "{integrator:?}: substep {s}");
                assert_eq!(frame[at].indirect, None);
                let offsets: Vec<Option<u64>> = frame[at + 1..at + 3].iter().map(|d| d.indirect).collect();
                assert_eq!(offsets, [Some(0), Some(16)], "{integrator:?}: substep {s}: the rebuild's two passes");
                at += 3;
            }
            assert!(frame[at..at + per_substep].iter().all(|d| d.indirect.is_none()));
            at += per_substep;
        }
        assert_eq!(at, frame.len(), "{integrator:?}: nothing else in the frame");
    }
}

/// VBD's substep: predict, the sweeps' five colour passes, finish; with the multigrid correction
/// (the default, before every fifth sweep), the correction's passes before sweeps 1 and 6, 145 of
/// them at 256² (docs/model.md).
#[test]
fn vbd_corrections_come_before_every_nth_sweep() {
    let count = |n: u32, every: u32| {
        let mut scene = scene(Integrator::Vbd, n);
        scene.cloth.resolution = [n, n];
        scene.solver.vbd_multigrid_every = every;
        let plan = Plan::new(&scene, &GpuTuning::default(), &GPU, "test").unwrap();
        let mut out = Vec::new();
        plan.schedule.frame(1, 0, &mut out);
        out.len()
    };
    assert_eq!(count(13, 0), 1 + 10 * 5 + 1);
    for n in [13, 256] {
        let correction = (count(n, 5) - count(n, 0)) / 2;
        assert_eq!(count(n, 5), count(n, 0) + 2 * correction);
        assert_eq!(count(n, 3), count(n, 0) + 4 * correction, "before sweeps 1, 4, 7 and 10");
        assert_eq!(count(n, 10), count(n, 0) + correction, "before sweep 1 only");
        if n == 256 {
            assert_eq!(correction, 145);
        }
    }
}
