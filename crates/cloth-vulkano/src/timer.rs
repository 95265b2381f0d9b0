//! [`GpuTimer`]: GPU time of each advance, from timestamps written before and after its
//! dispatches, read only when asked.

use std::sync::Arc;

use vulkano::command_buffer::RecordingCommandBuffer;
use vulkano::device::Queue;
use vulkano::query::{QueryPool, QueryPoolCreateInfo, QueryResultFlags, QueryType};
use vulkano::sync::PipelineStage;

/// Timestamp pairs held in the pool before they must be read: one per advance.
const CAPACITY: u32 = 256;

/// A ring of timestamp pairs, one per advance.
pub(crate) struct GpuTimer {
    pool: Arc<QueryPool>,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
    /// Mask of the valid bits of a timestamp.
    mask: u64,
    /// Pairs written since the last read.
    pending: u32,
}

impl GpuTimer {
    /// A timer for work on `queue`, or `None` when its family has no timestamps.
    pub(crate) fn new(queue: &Arc<Queue>) -> Option<Self> {
        let device = queue.device();
        let family = &device.physical_device().queue_family_properties()[queue.queue_family_index() as usize];
        let bits = family.timestamp_valid_bits?;
        let pool = QueryPool::new(
            device.clone(),
            QueryPoolCreateInfo { query_count: 2 * CAPACITY, ..QueryPoolCreateInfo::query_type(QueryType::Timestamp) },
        )
        .ok()?;
        let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
        Some(Self { pool, period_ns: device.physical_device().properties().timestamp_period as f64, mask, pending: 0 })
    }

    /// Whether the ring is full: the pairs must be read before the next advance.
    pub(crate) fn is_full(&self) -> bool {
        self.pending >= CAPACITY
    }

    /// Records the start timestamp of the next advance (before its dispatches).
    pub(crate) fn begin(&self, recording: &mut RecordingCommandBuffer) -> Result<(), String> {
        let first = 2 * self.pending;
        // SAFETY: the two queries are reset just before, in the same command buffer, and are not
        // read until the command buffer has completed (`take` runs after a wait); the pool lives
        // as long as the simulator, which waits for the device before dropping it.
        unsafe {
            recording.reset_query_pool(&self.pool, first..first + 2).map_err(|e| format!("{e}"))?;
            recording.write_timestamp(&self.pool, first, PipelineStage::TopOfPipe).map_err(|e| format!("{e}"))?;
        }
        Ok(())
    }

    /// Records the end timestamp of the advance (after its dispatches).
    pub(crate) fn end(&mut self, recording: &mut RecordingCommandBuffer) -> Result<(), String> {
        // SAFETY: as in `begin`.
        unsafe {
            recording
                .write_timestamp(&self.pool, 2 * self.pending + 1, PipelineStage::BottomOfPipe)
                .map_err(|e| format!("{e}"))?;
        }
        self.pending += 1;
        Ok(())
    }

    /// Seconds the pending pairs span; empties the ring. Call only after waiting for the device.
    pub(crate) fn take(&mut self) -> Result<f64, String> {
        if self.pending == 0 {
            return Ok(0.0);
        }
        let mut stamps = vec![0u64; 2 * self.pending as usize];
        self.pool
            .get_results(0..2 * self.pending, &mut stamps, QueryResultFlags::WAIT)
            .map_err(|e| format!("reading the timestamps: {e}"))?;
        self.pending = 0;
        let ticks: u64 = stamps.chunks_exact(2).map(|p| (p[1].wrapping_sub(p[0])) & self.mask).sum();
        Ok(ticks as f64 * self.period_ns * 1e-9)
    }
}
