//! Temporal blocking of the semi-implicit Euler substep on the GPU (issue 8): one dispatch
//! advances the cloth by several substeps, each workgroup on its own tile of the grid held in
//! workgroup memory.
//!
//! A substep of vertex `(i, j)` reads its neighbours up to two vertices away (the bend springs;
//! the wind's normal reaches one). A workgroup loads a `width × height` block of the state, the
//! **tile**, and advances it `substeps` times in workgroup memory: after substep `s` the cells at
//! least `2s` from the tile's edge are exact (their whole neighbourhood was), so after all of them
//! the `(width − 4·substeps) × (height − 4·substeps)` cells in the middle, the **output block**,
//! are, and only those are written. Output blocks tile the grid; the rims they overlap by (the
//! **halo**, `2·substeps` cells on each side) are computed by each neighbour again.
//!
//! The arithmetic of each vertex is the per-substep kernel's, operation by operation, so the
//! result is the same to the bit (lavapipe checks it against the CPU reference). What changes is
//! memory traffic: a substep of the per-substep kernel streams each vertex's 64 bytes of state
//! through DRAM; a tiled dispatch reads a tile and writes its output block once for `substeps`
//! substeps, `32 (width·height + out_w·out_h) / (out_w·out_h·substeps)` bytes per
//! vertex-substep ([`TileConfig::bytes_per_vertex_substep`]), at the price of the halo's
//! recomputation ([`TileConfig::recomputation`]).
//!
//! One invocation per cell: the workgroup is the tile (at most 1024 cells, the largest workgroup
//! Vulkan promises). Workgroup memory holds the tile's positions and velocities as six `f32`
//! arrays (24 bytes a cell); each invocation keeps its cell's new state in registers between the
//! two barriers of a substep.

use crate::error::SimError;

/// Bytes of workgroup memory per tile cell: position and velocity, three `f32` each.
pub const WORKGROUP_BYTES_PER_CELL: u32 = 24;

/// At most this many cells a tile: one invocation per cell, and 1024 is the most invocations a
/// workgroup may have on every Vulkan device we know.
pub const MAX_TILE_CELLS: u32 = 1024;

/// How a tiled dispatch covers the grid: the tile's size in cells and the substeps it fuses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileConfig {
    /// Cells along the grid's `i` (u) axis, halo included.
    pub width: u32,
    /// Cells along the grid's `j` (v) axis, halo included.
    pub height: u32,
    /// Substeps per dispatch.
    pub substeps: u32,
}

/// The tiles in use unless the environment says otherwise, largest first: a device gets the
/// first whose workgroup memory and invocations it allows. 32 × 16 cells with 2 substeps per
/// dispatch (a 24 × 8 output block; 12 KiB and 512 invocations): of the ten tiles measured on the
/// H100 (docs/performance.md) within 5% of the fastest at 128² and 256², where tiling pays;
/// 16 × 16 (6 KiB, 256 invocations: WebGPU's default limits).
pub const DEFAULT_TILES: [TileConfig; 2] =
    [TileConfig { width: 32, height: 16, substeps: 2 }, TileConfig { width: 16, height: 16, substeps: 2 }];

/// The largest of [`DEFAULT_TILES`].
pub const DEFAULT_TILE: TileConfig = DEFAULT_TILES[0];

/// Grids of more vertices than this run semi-implicit Euler one substep per dispatch under
/// [`Tiling::Auto`]. On the H100 (docs/performance.md) the tiled kernel wins where the
/// per-substep launches dominate and loses where the per-substep kernel streams at a good share of
/// the memory bandwidth (the tile's halo is loaded and recomputed, and only 192 of 512
/// invocations write): at 53 substeps, 0.19 against 0.30 ms at 128², 0.30 against 0.32 ms at
/// 256², 0.83 against 0.59 ms at 512² (wgpu).
pub const MAX_TILED_VERTICES: u32 = 256 * 256;

/// Whether semi-implicit Euler fuses substeps with the tiled kernel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tiling {
    /// Where it pays: on a GPU, for grids of up to [`MAX_TILED_VERTICES`]. Not on a CPU
    /// implementation of Vulkan (lavapipe), where the halo's recomputation and the barriers cost
    /// real time and a dispatch little: there the tiled kernel measured 2 to 6 times slower. The
    /// environment knobs `CLOTH_FUSED_SUBSTEPS` and `CLOTH_TILE`, when set, decide instead (on
    /// any device and grid).
    #[default]
    Auto,
    /// Wherever the device can run it, on any grid (the tile's shape still follows the knobs).
    On,
    /// Never: one dispatch per substep.
    Off,
}

/// What a device allows a workgroup, for [`tile_config`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceLimits {
    /// Invocations a workgroup may have (the smaller of the total and `x × y`).
    pub invocations: u32,
    /// Bytes of workgroup memory.
    pub workgroup_memory: u32,
    /// Whether the device is a CPU implementation (e.g. lavapipe).
    pub cpu: bool,
}

impl TileConfig {
    /// Cells each side of the output block that are loaded but not written: the bend springs
    /// reach two vertices, so two per fused substep.
    pub fn halo(&self) -> u32 {
        2 * self.substeps
    }

    /// The output block's size in cells, `(width − 2·halo, height − 2·halo)`.
    pub fn output_block(&self) -> (u32, u32) {
        (self.width.saturating_sub(2 * self.halo()), self.height.saturating_sub(2 * self.halo()))
    }

    /// Cells of the tile.
    pub fn cells(&self) -> u32 {
        self.width * self.height
    }

    /// Workgroup memory a tile needs, bytes.
    pub fn workgroup_bytes(&self) -> u32 {
        self.cells() * WORKGROUP_BYTES_PER_CELL
    }

    /// Workgroups along `i` and `j` for an `nx × ny` grid: one per output block.
    pub fn workgroups(&self, nx: u32, ny: u32) -> (u32, u32) {
        let (w, h) = self.output_block();
        (nx.div_ceil(w.max(1)), ny.div_ceil(h.max(1)))
    }

    /// Bytes of DRAM traffic per vertex-substep if every tile were read and every output block
    /// written once (32 bytes of state a vertex each way), for a grid of whole blocks.
    pub fn bytes_per_vertex_substep(&self) -> f64 {
        let (w, h) = self.output_block();
        let out = (w * h) as f64;
        32.0 * (self.cells() as f64 + out) / (out * self.substeps as f64)
    }

    /// Vertex-substeps computed per vertex-substep delivered: the halo's recomputation (substep
    /// `s` computes the cells at least `2s` from the tile's edge).
    pub fn recomputation(&self) -> f64 {
        let (w, h) = self.output_block();
        let computed: u32 =
            (1..=self.substeps).map(|s| self.width.saturating_sub(4 * s) * self.height.saturating_sub(4 * s)).sum();
        computed as f64 / ((w * h) as f64 * self.substeps as f64)
    }

    /// Checks the tile's shape.
    ///
    /// # Errors
    /// What is wrong, naming the quantity.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=8).contains(&self.substeps) {
            return Err(format!("{} fused substeps (1 to 8, or 0 for none)", self.substeps));
        }
        let (w, h) = self.output_block();
        if w == 0 || h == 0 || self.width > 256 || self.height > 256 {
            return Err(format!(
                "a {}×{} tile for {} fused substeps (each side must exceed 4 × substeps = {} and be at most 256)",
                self.width,
                self.height,
                self.substeps,
                4 * self.substeps
            ));
        }
        if self.cells() > MAX_TILE_CELLS {
            return Err(format!(
                "a {}×{} tile ({} cells, one invocation each; at most {MAX_TILE_CELLS})",
                self.width,
                self.height,
                self.cells()
            ));
        }
        Ok(())
    }
}

/// The tile the GPU backends use for semi-implicit Euler on a grid of `vertices` on a device with
/// `limits`, as `tiling` asks: the first of [`DEFAULT_TILES`] the device fits, or `None` (one
/// dispatch per substep) where tiling is off, does not pay ([`Tiling::Auto`]) or no tile fits.
/// The environment variables `CLOTH_FUSED_SUBSTEPS` (substeps per dispatch; `0` turns tiling off)
/// and `CLOTH_TILE` (`WIDTHxHEIGHT`, e.g. `32x16`) set the tile's shape, and under
/// [`Tiling::Auto`] turn tiling on for any device and grid: tuning knobs for benchmarks.
///
/// # Errors
/// The variable and its value when it does not parse or the tile it makes is not usable with
/// the device's workgroup memory or invocations.
pub fn tile_config(tiling: Tiling, vertices: u32, limits: DeviceLimits) -> Result<Option<TileConfig>, String> {
    let fits = |t: &TileConfig| t.workgroup_bytes() <= limits.workgroup_memory && t.cells() <= limits.invocations;
    let fitting = DEFAULT_TILES.iter().find(|t| fits(t) && t.check().is_ok());
    let explicit = ["CLOTH_FUSED_SUBSTEPS", "CLOTH_TILE"]
        .iter()
        .any(|name| std::env::var(name).is_ok_and(|text| !text.trim().is_empty()));
    let pays = !limits.cpu && vertices <= MAX_TILED_VERTICES;
    let wanted = match tiling {
        Tiling::Off => false,
        Tiling::On => true,
        Tiling::Auto => explicit || pays,
    };
    if !wanted {
        return Ok(None);
    }
    let Some(mut tile) = fitting.copied().or(explicit.then_some(DEFAULT_TILE)) else {
        return Ok(None);
    };
    if let Ok(text) = std::env::var("CLOTH_FUSED_SUBSTEPS")
        && !text.trim().is_empty()
    {
        tile.substeps =
            text.trim().parse().map_err(|_| format!("the fused substeps CLOTH_FUSED_SUBSTEPS={text} (a number)"))?;
        if tile.substeps == 0 {
            return Ok(None);
        }
    }
    if let Ok(text) = std::env::var("CLOTH_TILE")
        && !text.trim().is_empty()
    {
        let parsed = text.trim().split_once(['x', 'X']).and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)));
        let Some((width, height)) = parsed else {
            return Err(format!("the tile CLOTH_TILE={text} (WIDTHxHEIGHT, e.g. 32x16)"));
        };
        tile.width = width;
        tile.height = height;
    }
    tile.check().map_err(|what| format!("{what} (CLOTH_FUSED_SUBSTEPS / CLOTH_TILE)"))?;
    if !fits(&tile) {
        return Err(format!(
            "a {}×{} tile (CLOTH_TILE): {} bytes of workgroup memory and {} invocations, and the device allows \
             {} and {}",
            tile.width,
            tile.height,
            tile.workgroup_bytes(),
            tile.cells(),
            limits.workgroup_memory,
            limits.invocations
        ));
    }
    Ok(Some(tile))
}

/// [`tile_config`] as the error a GPU backend named `backend` returns when a knob is wrong.
///
/// # Errors
/// [`SimError::Unsupported`] naming the variables, their values and the fix.
pub fn checked_tile_config(
    backend: &'static str,
    tiling: Tiling,
    vertices: u32,
    limits: DeviceLimits,
) -> Result<Option<TileConfig>, SimError> {
    tile_config(tiling, vertices, limits).map_err(|what| SimError::Unsupported {
        backend,
        what,
        fix: "unset CLOTH_FUSED_SUBSTEPS and CLOTH_TILE for the default tile (the largest that fits the device), \
              give a smaller CLOTH_TILE, or set CLOTH_FUSED_SUBSTEPS=0 for one dispatch a substep"
            .into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_tiles_fit_their_devices() {
        // 32 × 16: 12 KiB and 512 invocations; 16 × 16: WebGPU's default 16 KiB and 256.
        for (tile, (memory, invocations)) in DEFAULT_TILES.iter().zip([(48 * 1024, 1024), (16 * 1024, 256)]) {
            assert!(tile.workgroup_bytes() <= memory && tile.cells() <= invocations, "{tile:?}");
            tile.check().unwrap();
        }
        assert_eq!(DEFAULT_TILE.halo(), 4);
        assert_eq!(DEFAULT_TILE.output_block(), (24, 8));
    }

    #[test]
    fn traffic_and_recomputation_follow_the_tile() {
        // One substep per dispatch on a huge tile approaches the per-substep kernel's 64 bytes.
        let one = TileConfig { width: 1024, height: 1024, substeps: 1 };
        assert!((one.bytes_per_vertex_substep() - 64.0).abs() < 1.0);
        // 32 × 16 cells, 2 substeps: 32 (512 + 192) / (192 · 2) bytes.
        assert!((DEFAULT_TILE.bytes_per_vertex_substep() - 32.0 * 704.0 / 384.0).abs() < 1e-9);
        let r = DEFAULT_TILE.recomputation();
        // 28·12 + 24·8 cells computed for 2 · 24·8 delivered.
        assert!((r - (336.0 + 192.0) / 384.0).abs() < 1e-12, "{r}");
    }

    #[test]
    fn bad_tiles_are_refused_with_the_reason() {
        let thin = TileConfig { width: 8, height: 16, substeps: 2 };
        assert!(thin.check().unwrap_err().contains("must exceed"));
        let big = TileConfig { width: 64, height: 32, substeps: 2 };
        assert!(big.check().unwrap_err().contains("one invocation each"));
        let many = TileConfig { width: 100, height: 100, substeps: 9 };
        assert!(many.check().unwrap_err().contains("fused substeps"));
    }

    #[test]
    fn the_policy_tiles_small_grids_on_gpus_and_what_is_asked() {
        // (The environment knobs are not set in the tests.)
        if std::env::var_os("CLOTH_FUSED_SUBSTEPS").is_some() || std::env::var_os("CLOTH_TILE").is_some() {
            return;
        }
        let gpu = DeviceLimits { invocations: 1024, workgroup_memory: 48 * 1024, cpu: false };
        let small = DeviceLimits { invocations: 256, workgroup_memory: 16 * 1024, cpu: false };
        let tiny = DeviceLimits { invocations: 128, workgroup_memory: 48 * 1024, cpu: false };
        let lavapipe = DeviceLimits { invocations: 1024, workgroup_memory: 32 * 1024, cpu: true };
        let n = 128 * 128;
        assert_eq!(tile_config(Tiling::Auto, n, gpu), Ok(Some(DEFAULT_TILE)));
        assert_eq!(tile_config(Tiling::Auto, n, small), Ok(Some(DEFAULT_TILES[1])));
        assert_eq!(tile_config(Tiling::Auto, n, tiny), Ok(None));
        assert_eq!(tile_config(Tiling::Auto, MAX_TILED_VERTICES + 1, gpu), Ok(None));
        assert_eq!(tile_config(Tiling::On, MAX_TILED_VERTICES + 1, gpu), Ok(Some(DEFAULT_TILE)));
        assert_eq!(tile_config(Tiling::Off, n, gpu), Ok(None));
        // A CPU implementation: not by default, but when asked.
        assert_eq!(tile_config(Tiling::Auto, n, lavapipe), Ok(None));
        assert_eq!(tile_config(Tiling::On, n, lavapipe), Ok(Some(DEFAULT_TILE)));
    }

    #[test]
    fn workgroups_cover_the_grid() {
        assert_eq!(DEFAULT_TILE.workgroups(1024, 1024), (1024u32.div_ceil(24), 1024u32.div_ceil(8)));
        assert_eq!(DEFAULT_TILE.workgroups(1, 1), (1, 1));
    }
}
