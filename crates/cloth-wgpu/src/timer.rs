//! [`GpuTimer`]: GPU time of each advance, from timestamp queries at the start and end of its
//! compute pass, read back only when asked.

/// Timestamp pairs held on the device before they must be read: one per advance.
const CAPACITY: u32 = 256;

/// A ring of timestamp pairs, one per advance, resolved into a buffer on the device.
pub(crate) struct GpuTimer {
    queries: wgpu::QuerySet,
    /// Resolved pairs, one every `QUERY_RESOLVE_BUFFER_ALIGNMENT` (256) bytes.
    pub(crate) resolved: wgpu::Buffer,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
    /// Pairs written since the last read.
    pending: u32,
}

impl GpuTimer {
    /// A timer on `device`, or `None` when the device has no timestamp queries.
    pub(crate) fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Option<Self> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let queries = device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("cloth advance timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 2 * CAPACITY,
        });
        let resolved = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cloth resolved timestamps"),
            size: CAPACITY as u64 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Some(Self { queries, resolved, period_ns: queue.get_timestamp_period() as f64, pending: 0 })
    }

    /// Whether the ring is full: the pairs must be read before the next advance.
    pub(crate) fn is_full(&self) -> bool {
        self.pending >= CAPACITY
    }

    /// The timestamp writes of the next advance's compute pass.
    pub(crate) fn pass_writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: Some(2 * self.pending),
            end_of_pass_write_index: Some(2 * self.pending + 1),
        }
    }

    /// Resolves the pair the pass just wrote (recorded after the pass, in the same encoder).
    pub(crate) fn resolve(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let slot = self.pending;
        encoder.resolve_query_set(
            &self.queries,
            2 * slot..2 * slot + 2,
            &self.resolved,
            slot as u64 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT,
        );
        self.pending += 1;
    }

    /// Bytes of `resolved` that hold pairs not yet read.
    pub(crate) fn pending_bytes(&self) -> u64 {
        self.pending as u64 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT
    }

    /// Seconds the pending pairs span, from their read-back bytes; empties the ring.
    pub(crate) fn take(&mut self, bytes: &[u8]) -> f64 {
        let stride = wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT as usize;
        let mut ticks = 0u64;
        for slot in 0..self.pending as usize {
            let pair: [u64; 2] = bytemuck::pod_read_unaligned(&bytes[slot * stride..slot * stride + 16]);
            ticks += pair[1].saturating_sub(pair[0]);
        }
        self.pending = 0;
        ticks as f64 * self.period_ns * 1e-9
    }
}
