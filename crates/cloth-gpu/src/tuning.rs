//! [`GpuTuning`]: every knob of the GPU backends, as one typed value passed when a simulator is
//! created. The defaults are the fastest settings measured (docs/performance.md); nothing here
//! changes a result, only how the work is laid out on the device (the conformance suite checks
//! that), except `adapter`, which picks the device.

use cloth_core::SimError;

use crate::geometry::TileConfig;

/// Invocations per workgroup of every kernel by default: against 64, 256 is 20-30% faster on a
/// large GPU, and 512 is within a few percent either way (docs/performance.md).
pub const DEFAULT_WORKGROUP_SIZE: u32 = 256;

/// Vertices along `i` of the block a workgroup of the per-substep kernels updates by default:
/// 64 × 4 blocks at 256 invocations, so the neighbours two rows up and down that a vertex's bend
/// springs read are mostly the workgroup's own and come from the L1 cache.
pub const DEFAULT_BLOCK_WIDTH: u32 = 64;

/// The block width a workgroup of `workgroup_size` invocations gets unless one is given:
/// [`DEFAULT_BLOCK_WIDTH`], or the whole workgroup's width where it has fewer invocations.
pub fn default_block_width(workgroup_size: u32) -> u32 {
    DEFAULT_BLOCK_WIDTH.min(workgroup_size)
}

/// How the GPU backends lay the work out. Construct it as a struct literal over `Default`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GpuTuning {
    /// Invocations per workgroup of every kernel: a power of two from 32 to 1024 that the device
    /// allows. Default [`DEFAULT_WORKGROUP_SIZE`].
    pub workgroup_size: u32,
    /// Vertices along `i` of the block of the grid a workgroup of the per-substep kernels
    /// updates (a `block_width × workgroup_size / block_width` block): a power of two that divides
    /// the workgroup size, or 0 for rows of `workgroup_size` consecutive vertices. A grid
    /// narrower than the block gets a block of its next power of two. Default
    /// [`DEFAULT_BLOCK_WIDTH`] ([`default_block_width`] for another workgroup size).
    pub block_width: u32,
    /// Whether semi-implicit Euler fuses substeps in workgroup memory (never with
    /// `SelfCollision`, which runs on the `vec4` state). Default [`Tiling::Auto`].
    pub tiling: Tiling,
    /// The tile of the fused kernel (cells and substeps per dispatch); `None`: the largest of
    /// [`crate::geometry::DEFAULT_TILES`] the device fits. Default `None`.
    pub tile: Option<TileConfig>,
    /// Whether semi-implicit Euler's substeps inside a submission hand each other a packed
    /// 24-byte state instead of two `vec4`s (32 bytes). Default `true`.
    pub packed_state: bool,
    /// The order in which the packed passes' workgroups take the grid's blocks. Default
    /// [`BlockOrder::Auto`].
    pub block_order: BlockOrder,
    /// How self-collision's rebuild lists each vertex's candidates. Default
    /// [`CandidateListing::Auto`].
    pub candidate_listing: CandidateListing,
    /// Print the driver compiler's statistics of each pipeline (registers, shared memory) to
    /// standard error as it is built: vulkano only, where the device offers
    /// `VK_KHR_pipeline_executable_properties`. Default `false`.
    pub pipeline_statistics: bool,
    /// Use the first adapter whose name contains this text (case-insensitive); `None`: the best,
    /// a discrete GPU first and a CPU implementation last. Default `None`.
    pub adapter: Option<String>,
}

impl Default for GpuTuning {
    fn default() -> Self {
        Self {
            workgroup_size: DEFAULT_WORKGROUP_SIZE,
            block_width: default_block_width(DEFAULT_WORKGROUP_SIZE),
            tiling: Tiling::Auto,
            tile: None,
            packed_state: true,
            block_order: BlockOrder::Auto,
            candidate_listing: CandidateListing::Auto,
            pipeline_statistics: false,
            adapter: None,
        }
    }
}

/// Whether semi-implicit Euler fuses substeps with the tiled kernel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tiling {
    /// Where it pays: on a GPU, for grids of up to [`crate::geometry::MAX_TILED_VERTICES`]; not
    /// on a CPU implementation of Vulkan, where the halo's recomputation costs real time and a
    /// dispatch little.
    #[default]
    Auto,
    /// Wherever the device fits the tile, on any grid (semi-implicit Euler without
    /// `SelfCollision`).
    On,
    /// Never: one dispatch per substep.
    Off,
}

/// The order in which semi-implicit Euler's packed passes take the grid's blocks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BlockOrder {
    /// Alternate where a substep moves 25 to 100 MB
    /// ([`crate::geometry::alternates_order`]), else forward.
    #[default]
    Auto,
    /// Every substep forward.
    Forward,
    /// Forward and backward by turns, so each substep starts on the blocks the one before wrote
    /// last, which the L2 cache still holds.
    Alternating,
}

/// How self-collision's rebuild lists each vertex's candidates (the same lists either way).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CandidateListing {
    /// In lanes on grids of fewer than [`crate::layout::LISTING_IN_LANES_BELOW`] vertices, one
    /// invocation a vertex on larger ones.
    #[default]
    Auto,
    /// [`crate::layout::LISTING_LANES`] invocations a vertex, each walking some of its cells.
    Lanes,
    /// One invocation a vertex, walking all of its cells.
    OnePerVertex,
}

/// The error for a tuning field `option` holding `value`, which must be `expected`.
pub(crate) fn invalid(option: &'static str, value: impl std::fmt::Display, expected: impl Into<String>) -> SimError {
    SimError::InvalidOption { option, value: value.to_string(), expected: expected.into() }
}

impl GpuTuning {
    /// Checks every field that can be checked without a device.
    ///
    /// # Errors
    /// [`SimError::InvalidOption`] naming the field, its value and what it must be.
    pub fn check(&self) -> Result<(), SimError> {
        let w = self.workgroup_size;
        if !w.is_power_of_two() || !(32..=1024).contains(&w) {
            return Err(invalid("GpuTuning::workgroup_size", w, "a power of two from 32 to 1024 (default 256)"));
        }
        let b = self.block_width;
        if b != 0 && (!b.is_power_of_two() || !w.is_multiple_of(b)) {
            return Err(invalid(
                "GpuTuning::block_width",
                b,
                format!("0 (rows), or a power of two that divides the workgroup size {w} (default 64)"),
            ));
        }
        if let Some(tile) = &self.tile {
            tile.check().map_err(|why| invalid("GpuTuning::tile", tile, why))?;
        }
        Ok(())
    }
}
