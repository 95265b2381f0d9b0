//! The GPU tuning flags every command that runs a simulation takes: one flag per field of
//! [`GpuTuning`], with its default.

use cloth_gpu::tuning::{DEFAULT_WORKGROUP_SIZE, default_block_width};
use cloth_gpu::{BlockOrder, CandidateListing, GpuTuning, TileConfig, Tiling};

/// How the GPU backends lay their work out (see `cloth_gpu::GpuTuning`); nothing here changes a
/// result, only its speed, except `--adapter`, which picks the device.
#[derive(clap::Args, Clone, Debug)]
pub struct TuningArgs {
    /// GPU backends: use the adapter whose name contains this text (default: the best one).
    #[arg(long)]
    pub adapter: Option<String>,
    /// Invocations per workgroup of every kernel: a power of two from 32 to 1024.
    #[arg(long, default_value_t = DEFAULT_WORKGROUP_SIZE)]
    workgroup_size: u32,
    /// Vertices along i of the block a workgroup of the per-substep kernels updates: a power of
    /// two dividing the workgroup size, or 0 for rows (default 64, or the workgroup size if that
    /// is smaller).
    #[arg(long)]
    block_width: Option<u32>,
    /// Whether semi-implicit Euler fuses substeps in workgroup memory: auto (on GPUs, for grids
    /// of up to 256²), on (wherever the device fits the tile), off. Never with self-collision,
    /// which runs one substep a dispatch.
    #[arg(long, default_value = "auto", value_parser = tiling)]
    tiling: Tiling,
    /// The fused kernel's tile, WIDTHxHEIGHTxSUBSTEPS (default: the largest of 32x16x2 and
    /// 16x16x2 the device fits).
    #[arg(long, value_parser = tile)]
    tile: Option<TileConfig>,
    /// Whether semi-implicit Euler's substeps inside a submission pass each other the packed
    /// 24-byte state (on) or two vec4s (off).
    #[arg(long, default_value = "on", value_parser = on_off, action = clap::ArgAction::Set)]
    packed_state: bool,
    /// The order the packed passes take the grid's blocks in: auto (alternating where a substep
    /// moves 25 to 100 MB), forward, alternating.
    #[arg(long, default_value = "auto", value_parser = block_order)]
    block_order: BlockOrder,
    /// How self-collision's rebuild lists each vertex's candidates: auto (in lanes below 2^18
    /// vertices), lanes (several invocations a vertex), one-per-vertex.
    #[arg(long, default_value = "auto", value_parser = candidate_listing)]
    candidate_listing: CandidateListing,
    /// vulkano: print each pipeline's registers and workgroup memory as the driver reports them.
    #[arg(long)]
    pipeline_statistics: bool,
}

fn tiling(text: &str) -> Result<Tiling, String> {
    match text {
        "auto" => Ok(Tiling::Auto),
        "on" => Ok(Tiling::On),
        "off" => Ok(Tiling::Off),
        _ => Err(format!("'{text}' is not a tiling: auto, on or off")),
    }
}

fn block_order(text: &str) -> Result<BlockOrder, String> {
    match text {
        "auto" => Ok(BlockOrder::Auto),
        "forward" => Ok(BlockOrder::Forward),
        "alternating" => Ok(BlockOrder::Alternating),
        _ => Err(format!("'{text}' is not a block order: auto, forward or alternating")),
    }
}

fn candidate_listing(text: &str) -> Result<CandidateListing, String> {
    match text {
        "auto" => Ok(CandidateListing::Auto),
        "lanes" => Ok(CandidateListing::Lanes),
        "one-per-vertex" => Ok(CandidateListing::OnePerVertex),
        _ => Err(format!("'{text}' is not a candidate listing: auto, lanes or one-per-vertex")),
    }
}

/// `WIDTHxHEIGHTxSUBSTEPS`, e.g. `32x16x2`.
fn tile(text: &str) -> Result<TileConfig, String> {
    let parts: Vec<Option<u32>> = text.split(['x', 'X']).map(|p| p.trim().parse().ok()).collect();
    match parts[..] {
        [Some(width), Some(height), Some(substeps)] => Ok(TileConfig { width, height, substeps }),
        _ => Err(format!("'{text}' is not a tile WIDTHxHEIGHTxSUBSTEPS (e.g. 32x16x2)")),
    }
}

fn on_off(text: &str) -> Result<bool, String> {
    match text {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("'{text}' is neither on nor off")),
    }
}

impl TuningArgs {
    /// The tuning the flags ask for.
    pub fn tuning(&self) -> GpuTuning {
        GpuTuning {
            workgroup_size: self.workgroup_size,
            block_width: self.block_width.unwrap_or_else(|| default_block_width(self.workgroup_size)),
            tiling: self.tiling,
            tile: self.tile,
            packed_state: self.packed_state,
            block_order: self.block_order,
            candidate_listing: self.candidate_listing,
            pipeline_statistics: self.pipeline_statistics,
            adapter: self.adapter.clone(),
        }
    }
}
