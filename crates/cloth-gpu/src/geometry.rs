//! How the kernels cover the grid: the per-substep kernels' blocks, the packed state, the tiled
//! kernel's tiles, and what a device allows.
//!
//! **Blocks.** A workgroup of the per-substep kernels (`cloth_step.wgsl` / `.comp`) updates a
//! `BLOCK_WIDTH × (workgroup size / BLOCK_WIDTH)` block of the grid, and its id is the block's
//! column and row, so it finds its vertices without an integer division ([`BlockGrid`]).
//!
//! **Packed state.** A substep's time at large grids is mostly its state's traffic. The two
//! `vec4`s the read-backs and the renderer see carry 8 bytes of flags (free or pinned, the time);
//! packed, a vertex is 24 bytes, `(x, y, z, v.x)` and `(v.y, v.z)`, the pins a bit mask and the
//! time one element after the last vertex. The first substep of a submission reads the `vec4`
//! state and writes the packed one, the last reads the packed state and writes the `vec4`s
//! (`PACKED_IN`, `PACKED_OUT`), with the same arithmetic, so the results are bit for bit those of
//! the unpacked kernel.
//!
//! **Tiles.** The tiled kernel (`cloth_step_tiled`) advances a `width × height` tile of the grid
//! `substeps` times in workgroup memory. A vertex reads neighbours up to two away (the bend
//! springs), so after substep `s` the cells at least `2s` from the tile's edge are exact; only the
//! `(width − 4·substeps) × (height − 4·substeps)` cells in the middle, the output block, are
//! written. Output blocks tile the grid; the rims they overlap by, the halo, are computed by each
//! neighbour again. One invocation per cell; a cell's position and velocity take 24 bytes of
//! workgroup memory.

use cloth_core::Integrator;

use crate::tuning::{BlockOrder, GpuTuning, Tiling};

/// What a device allows, as the plan needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceLimits {
    /// Workgroups a dispatch may have along each axis (Vulkan guarantees 65 535).
    pub max_workgroups_per_dimension: u32,
    /// Invocations a workgroup may have (the smaller of the total and `x × y`).
    pub max_invocations: u32,
    /// Bytes of workgroup memory.
    pub workgroup_memory: u32,
    /// Bytes one storage binding may span.
    pub max_storage_binding: u64,
    /// Storage buffers one kernel may bind.
    pub storage_buffers_per_stage: u32,
    /// Whether the device is a CPU implementation (lavapipe).
    pub cpu: bool,
}

/// The kinds of device, best first: without a name to look for, a backend opens the best.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum DeviceKind {
    /// A discrete GPU.
    DiscreteGpu,
    /// A GPU integrated with the CPU.
    IntegratedGpu,
    /// A virtual GPU.
    VirtualGpu,
    /// Anything else.
    Other,
    /// A CPU implementation (lavapipe).
    Cpu,
}

/// Of `devices` (each with its name and kind), the first whose name contains `wanted`
/// (case-insensitive), else the best.
///
/// # Errors
/// `none` when there is no device; the names found when none matches.
pub fn choose_device<T>(
    mut devices: Vec<(T, String, DeviceKind)>,
    wanted: Option<&str>,
    none: &str,
) -> Result<T, String> {
    devices.sort_by_key(|d| d.2);
    let names: Vec<String> = devices.iter().map(|d| d.1.clone()).collect();
    let found = match wanted {
        None => devices.into_iter().next(),
        Some(w) => devices.into_iter().find(|d| d.1.to_lowercase().contains(&w.to_lowercase())),
    };
    match (found, wanted) {
        (Some((device, _, _)), _) => Ok(device),
        (None, Some(w)) if !names.is_empty() => Err(format!("no device named like '{w}'; found: {}", names.join(", "))),
        (None, _) => Err(none.to_string()),
    }
}

/// Bytes a vertex takes in semi-implicit Euler's packed state.
pub const PACKED_VERTEX_BYTES: u64 = 24;

/// Bytes a vertex takes in the `vec4` state (position and velocity).
pub const VEC4_VERTEX_BYTES: u64 = 32;

/// Sizes of the two buffers of one packed state for `vertices` vertices: `(x, v.x)`, 16 bytes a
/// vertex; `(v.y, v.z)`, 8 bytes a vertex and one element more for the time.
pub fn packed_buffer_bytes(vertices: u64) -> [u64; 2] {
    [16 * vertices, 8 * (vertices + 1)]
}

/// The pin bit mask of a `vec4` position buffer (`w ≤ 0` pinned): bit `i % 32` of word `i / 32`
/// set where vertex `i` is pinned; at least one word.
pub fn pin_bits(positions: &[[f32; 4]]) -> Vec<u32> {
    let mut bits = vec![0u32; positions.len().div_ceil(32).max(1)];
    for (i, p) in positions.iter().enumerate() {
        if p[3] <= 0.0 {
            bits[i / 32] |= 1 << (i % 32);
        }
    }
    bits
}

/// Above this many bytes a substep of the packed passes moves (24 in, 24 out a vertex), the
/// blocks alternate their order under [`BlockOrder::Auto`]: half a 50 MB L2 cache. Below, the
/// state stays in the cache either way and the switch of pipeline only costs.
pub const ALTERNATE_ORDER_MIN_SUBSTEP_BYTES: u64 = 25_000_000;

/// At most this many bytes a substep moves for the blocks to alternate under
/// [`BlockOrder::Auto`]: twice a 50 MB L2 cache, beyond which the gain was about 1% and some
/// machines ran slower.
pub const ALTERNATE_ORDER_MAX_SUBSTEP_BYTES: u64 = 100_000_000;

/// Whether the packed passes on a grid of `vertices` alternate the order in which their
/// workgroups take the blocks (substep `s` of a submission backward when `s` is odd), under
/// `order`. The results do not depend on it: a vertex's update reads only the state before the
/// substep.
pub fn alternates_order(order: BlockOrder, vertices: u64) -> bool {
    let bytes = vertices * 2 * PACKED_VERTEX_BYTES;
    match order {
        BlockOrder::Auto => bytes > ALTERNATE_ORDER_MIN_SUBSTEP_BYTES && bytes <= ALTERNATE_ORDER_MAX_SUBSTEP_BYTES,
        BlockOrder::Forward => false,
        BlockOrder::Alternating => true,
    }
}

/// How the per-substep kernels cover an `nx × ny` grid: the block width they are specialised
/// with (`BLOCK_WIDTH`) and the workgroups to dispatch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockGrid {
    /// Vertices along `i` of a block, or 0: a workgroup's worth of consecutive vertices.
    pub width: u32,
    /// Workgroups along x and y: with `width > 0`, the blocks along `i` and `j`; with 0, one
    /// invocation per vertex, along x up to the device's limit and the rest along y.
    pub workgroups: [u32; 2],
}

impl BlockGrid {
    /// The blocks of an `nx × ny` grid for `tuning` on a device allowing `max_per_dimension`
    /// workgroups along an axis. A grid narrower than the block gets a block of its next power
    /// of two (at 64 × 4 a 12-wide grid would use 48 of 256 invocations; at 16 × 16 it uses
    /// 192). Where the blocks exceed the device's count along an axis (a grid more than about
    /// 262 000 vertices tall at 64 × 4), rows, which every grid that fits in memory can be.
    pub fn new(tuning: &GpuTuning, nx: u32, ny: u32, max_per_dimension: u32) -> Self {
        let threads = tuning.workgroup_size;
        let width = if tuning.block_width == 0 { 0 } else { tuning.block_width.min(nx.max(1).next_power_of_two()) };
        if width > 0 {
            let blocks = [nx.div_ceil(width), ny.div_ceil(threads / width)];
            if blocks.iter().all(|&b| b <= max_per_dimension) {
                return Self { width, workgroups: blocks };
            }
        }
        Self { width: 0, workgroups: spilled_workgroups(nx * ny, threads, max_per_dimension) }
    }
}

/// Workgroups of `threads` invocations for `items` invocations (at least one workgroup): along x
/// up to `max_per_dimension`, the rest along y. A kernel dispatched so forms its item index as
/// `id.y · groups.x · threads + id.x` and skips the indices past `items`.
pub fn spilled_workgroups(items: u32, threads: u32, max_per_dimension: u32) -> [u32; 2] {
    let groups = items.div_ceil(threads).max(1);
    let max = max_per_dimension.max(1);
    if groups <= max { [groups, 1] } else { [max, groups.div_ceil(max)] }
}

/// A tile of the tiled kernel: cells (halo included) and the substeps it fuses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileConfig {
    /// Cells along the grid's `i` axis.
    pub width: u32,
    /// Cells along the grid's `j` axis.
    pub height: u32,
    /// Substeps per dispatch.
    pub substeps: u32,
}

/// The tiles in use unless [`GpuTuning::tile`] says otherwise, largest first: a device gets the
/// first it fits. 32 × 16 cells with 2 substeps (a 24 × 8 output block; 12 KiB and 512
/// invocations) was within 5% of the fastest of ten tiles at 128² and 256²; 16 × 16 (6 KiB, 256
/// invocations) fits WebGPU's default limits.
pub const DEFAULT_TILES: [TileConfig; 2] =
    [TileConfig { width: 32, height: 16, substeps: 2 }, TileConfig { width: 16, height: 16, substeps: 2 }];

/// At most this many cells a tile: one invocation each, and 1024 invocations is what every
/// Vulkan device we know allows a workgroup.
pub const MAX_TILE_CELLS: u32 = 1024;

/// Grids of more vertices than this run semi-implicit Euler one substep per dispatch under
/// [`Tiling::Auto`]: beyond, the per-substep kernel streams at a good share of the bandwidth and
/// the tile's halo (loaded and recomputed) costs more than the launches it saves.
pub const MAX_TILED_VERTICES: u32 = 256 * 256;

impl TileConfig {
    /// Cells each side of the output block that are loaded but not written: two a substep.
    pub fn halo(&self) -> u32 {
        2 * self.substeps
    }

    /// The output block, `(width − 2·halo, height − 2·halo)` cells.
    pub fn output_block(&self) -> (u32, u32) {
        (self.width.saturating_sub(2 * self.halo()), self.height.saturating_sub(2 * self.halo()))
    }

    /// Cells of the tile.
    pub fn cells(&self) -> u32 {
        self.width * self.height
    }

    /// Workgroup memory a tile needs, bytes.
    pub fn workgroup_bytes(&self) -> u32 {
        self.cells() * 24
    }

    /// Workgroups along `i` and `j` for an `nx × ny` grid: one per output block.
    pub fn workgroups(&self, nx: u32, ny: u32) -> [u32; 2] {
        let (w, h) = self.output_block();
        [nx.div_ceil(w.max(1)), ny.div_ceil(h.max(1))]
    }

    /// Checks the tile's shape.
    ///
    /// # Errors
    /// What is wrong, in words.
    pub fn check(&self) -> Result<(), String> {
        let (w, h) = self.output_block();
        if !(1..=8).contains(&self.substeps) {
            Err(format!("{} fused substeps: give 1 to 8 (tiling off runs one a dispatch)", self.substeps))
        } else if w == 0 || h == 0 || self.width > 256 || self.height > 256 {
            Err(format!("each side must exceed 4 × substeps = {} and be at most 256", 4 * self.substeps))
        } else if self.cells() > MAX_TILE_CELLS {
            Err(format!("{} cells, one invocation each: at most {MAX_TILE_CELLS}", self.cells()))
        } else {
            Ok(())
        }
    }

    /// Whether a device with `limits` can run the tile.
    pub fn fits(&self, limits: &DeviceLimits) -> bool {
        self.workgroup_bytes() <= limits.workgroup_memory && self.cells() <= limits.max_invocations
    }

    /// The tile semi-implicit Euler uses on a grid of `vertices` with `integrator` on a device
    /// with `limits`, as `tuning` asks, or `None`: one dispatch per substep (as exact).
    ///
    /// # Errors
    /// [`cloth_core::SimError::InvalidOption`] when the tile asked for does not fit the device.
    pub fn choose(
        tuning: &GpuTuning,
        integrator: Integrator,
        vertices: u32,
        limits: &DeviceLimits,
    ) -> Result<Option<TileConfig>, cloth_core::SimError> {
        let wanted = match tuning.tiling {
            Tiling::Off => false,
            Tiling::On => true,
            Tiling::Auto => !limits.cpu && vertices <= MAX_TILED_VERTICES,
        };
        if !wanted || integrator != Integrator::SemiImplicitEuler {
            return Ok(None);
        }
        match tuning.tile {
            None => Ok(DEFAULT_TILES.iter().find(|t| t.fits(limits)).copied()),
            Some(tile) if tile.fits(limits) => Ok(Some(tile)),
            Some(tile) => Err(crate::tuning::invalid(
                "GpuTuning::tile",
                tile,
                format!(
                    "a tile the device fits: this one needs {} bytes of workgroup memory and {} invocations, the \
                     device allows {} and {}",
                    tile.workgroup_bytes(),
                    tile.cells(),
                    limits.workgroup_memory,
                    limits.max_invocations
                ),
            )),
        }
    }
}

impl std::fmt::Display for TileConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}x{}", self.width, self.height, self.substeps)
    }
}
