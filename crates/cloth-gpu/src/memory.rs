//! Device memory a scene needs, from the closed-form spring counts, without building anything:
//! a grid too large for the device is refused before any allocation.

use cloth_core::coloring::COLOR_COUNT;
use cloth_core::{Integrator, Scene, SimError, SpringKind};

use crate::layout::COLOR_RANGE_STRIDE;

/// Bytes of the GPU buffers of a scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// Bytes of the largest single buffer (a state buffer, RK4's scratch or XPBD's constraints).
    pub largest_buffer_bytes: u64,
    /// Bytes of all GPU buffers together.
    pub device_bytes: u64,
}

impl MemoryEstimate {
    /// The buffers `plan.rs` creates for `scene`: four `vec4` state buffers (two positions, two
    /// velocities, 16 bytes a vertex each); RK4's scratch (four `vec4`s a vertex) and stage
    /// state; Verlet's half-step velocities; semi-implicit Euler's two packed states and pin
    /// bits (not with self-collision, which runs on the `vec4` state); XPBD's constraints (16
    /// bytes), multipliers (4) and normal corrections; self-collision's candidate lists, hash,
    /// control and (XPBD) corrections; colliders, the meshes' distance fields and parameters. Computed in `u128`, so a mistyped resolution gives a huge estimate, not an
    /// overflow.
    pub fn of(scene: &Scene) -> Self {
        let [nx, ny] = scene.cloth.resolution.map(u128::from);
        let vertices = nx * ny;
        let springs: u128 = SpringKind::ALL
            .iter()
            .filter(|k| scene.effects.contains(k.effect()))
            .map(|k| k.count_in_grid(nx as u64, ny as u64) as u128)
            .sum::<u128>()
            .max(1);
        let state = 16 * vertices;
        let self_collision = scene.effects.contains(cloth_core::Effect::SelfCollision);
        let (extra, largest) = match scene.integrator {
            Integrator::SemiImplicitEuler if self_collision => (0, state),
            Integrator::SemiImplicitEuler => (2 * (24 * vertices + 8) + 4 * vertices.div_ceil(32).max(1), state),
            Integrator::VelocityVerlet => (state, state),
            Integrator::RungeKutta4 => (4 * state + 2 * state, 4 * state),
            Integrator::Xpbd => {
                (20 * springs + 4 * vertices + 2 * COLOR_COUNT as u128 * COLOR_RANGE_STRIDE as u128, 16 * springs)
            }
            // The inertial predictions, the last substep's velocities, Chebyshev's history (a
            // 16-byte placeholder without it), the sweeps' and the multigrid levels' uniform
            // blocks, the multigrid levels (a 16-byte placeholder without the correction; partial
            // sums for workgroups of the default 256 invocations).
            Integrator::Vbd => {
                let history = if scene.solver.chebyshev_rho > 0.0 { 2 * state } else { 16 };
                let (levels, blocks) = if scene.solver.vbd_multigrid_every > 0 {
                    let [rx, ry] = scene.cloth.resolution;
                    let m = crate::layout::MultigridLevels::new(rx, ry, 256);
                    (16 * u128::from(m.vec4s), m.levels.len() as u128)
                } else {
                    (16, 0)
                };
                let sweeps = COLOR_RANGE_STRIDE as u128 * (u128::from(scene.solver.vbd_iterations.max(1)) + blocks);
                (2 * state + history + sweeps + levels, state.max(history).max(levels))
            }
            // CG's vectors and the five blocks a vertex, the partial sums (a vec2 a workgroup of
            // the default 256 invocations in each section), the counters, the iterations' steps
            // and uniform blocks.
            Integrator::BackwardEuler => {
                let iterations = u128::from(scene.solver.cg_max_iterations.max(1));
                let vectors = u128::from(crate::plan::CG_VECTORS) * state;
                let partials = u128::from(crate::plan::CG_PARTIAL_SECTIONS) * 8 * vertices.div_ceil(256);
                let bytes = vectors + 5 * state + partials + 32 + 8 * (iterations + 2);
                (bytes + COLOR_RANGE_STRIDE as u128 * iterations, vectors.max(5 * state))
            }
        };
        // The colliders' uniform block, and 4 bytes a distance-field sample of each mesh.
        let samples: u128 = (scene.colliders.iter())
            .filter_map(|c| c.shape.distance_field().and_then(Result::ok))
            .map(|f| f.samples.len() as u128)
            .sum();
        let colliders =
            (size_of::<crate::layout::GpuCollider>() * crate::layout::MAX_COLLIDERS) as u128 + 4 * samples.max(1);
        let xpbd = scene.integrator == Integrator::Xpbd;
        let control = size_of::<crate::layout::GpuSelfControl>() as u128;
        let (hash, hash_largest) = if self_collision {
            let table = crate::layout::SelfHashTable::of(scene);
            let (lists, links) = (4 * table.list_words as u128, 4 * table.link_words as u128);
            // The rebuild's workgroups, and three placeholders of their size.
            let dispatch = 4 * (crate::layout::REBUILD_PASSES * 16) as u128;
            let bytes = lists + links + control + dispatch + if xpbd { 16 * vertices } else { 0 };
            (bytes, lists.max(links).max(control))
        } else {
            (32 + control + if xpbd { 16 } else { 0 }, control)
        };
        let params = size_of::<crate::layout::GpuSimParams>() as u128;
        let clamp = |b: u128| u64::try_from(b).unwrap_or(u64::MAX);
        Self {
            largest_buffer_bytes: clamp(largest.max(state).max(hash_largest)),
            device_bytes: clamp(4 * state + extra + colliders + hash + params),
        }
    }
}

/// Side `n` of the largest square `n × n` grid of `scene` (its other settings kept) whose largest
/// buffer fits in `limit_bytes` (2 when not even that fits).
pub fn largest_square_grid(scene: &Scene, limit_bytes: u64) -> u32 {
    let fits = |n: u32| {
        let mut s = scene.clone();
        s.cloth.resolution = [n, n];
        MemoryEstimate::of(&s).largest_buffer_bytes <= limit_bytes
    };
    let (mut lo, mut hi) = (2u32, 1u32 << 20);
    if !fits(lo) {
        return lo;
    }
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) { lo = mid } else { hi = mid }
    }
    lo
}

/// Refuses a scene whose largest buffer exceeds `max_storage_binding` bytes, naming the grid, the
/// bytes, the limit (`resource`, in words) and the largest square grid that fits.
///
/// # Errors
/// [`SimError::TooLarge`].
pub fn check_fits(scene: &Scene, max_storage_binding: u64, resource: &str) -> Result<(), SimError> {
    let needed = MemoryEstimate::of(scene).largest_buffer_bytes;
    if needed <= max_storage_binding {
        return Ok(());
    }
    let [nx, ny] = scene.cloth.resolution;
    Err(SimError::TooLarge {
        nx,
        ny,
        resource: resource.into(),
        needed_bytes: needed,
        limit_bytes: max_storage_binding,
        largest_square: largest_square_grid(scene, max_storage_binding),
    })
}
