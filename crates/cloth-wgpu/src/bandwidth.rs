//! The device's measured copy bandwidth: the memory-bandwidth ceiling a memory-bound substep is
//! compared with.

use std::time::Instant;

use cloth_core::SimError;

use crate::BACKEND_NAME;
use crate::context::{AdapterChoice, GpuContext};

/// What a copy-bandwidth measurement found.
#[derive(Clone, Debug, PartialEq)]
pub struct CopyBandwidth {
    /// The adapter, in words.
    pub adapter: String,
    /// Bytes of each copy.
    pub copy_bytes: u64,
    /// Copies timed.
    pub copies: u32,
    /// Bytes moved per second, read plus written (a copy of `b` bytes moves `2 b`).
    pub bytes_per_s: f64,
}

/// Copies timed after one warm-up copy.
const COPIES: u32 = 40;

/// Measures the device's copy bandwidth: `COPIES` buffer-to-buffer copies of up to 512 MiB (less
/// where the device allows less) in one submission, timed by the wall clock from submission to
/// completion, counting each copied byte twice (read and written). One submission of work this
/// long (tens of milliseconds on a 3 TB/s device) makes the submission's own latency negligible.
///
/// # Errors
/// [`SimError::Unavailable`] when no adapter matches; [`SimError::Device`] when the device fails.
pub fn copy_bandwidth(choice: &AdapterChoice) -> Result<CopyBandwidth, SimError> {
    let context = GpuContext::new(choice)?;
    let device = &context.device;
    let limits = device.limits();
    let bytes = (512u64 << 20).min(limits.max_buffer_size / 4 * 4);
    let make = |label: &str| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes,
            usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let (a, b) = (make("bandwidth source"), make("bandwidth destination"));
    let wait = || {
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| SimError::Device { backend: BACKEND_NAME, reason: format!("waiting for the copies: {e}") })
    };
    let submit = |copies: u32| {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bandwidth") });
        for k in 0..copies {
            let (from, to) = if k % 2 == 0 { (&a, &b) } else { (&b, &a) };
            encoder.copy_buffer_to_buffer(from, 0, to, 0, bytes);
        }
        context.queue.submit([encoder.finish()]);
    };
    // Warm-up: first-use allocation of the buffers' memory.
    submit(1);
    wait()?;
    let start = Instant::now();
    submit(COPIES);
    wait()?;
    let seconds = start.elapsed().as_secs_f64();
    Ok(CopyBandwidth {
        adapter: context.adapter_description.clone(),
        copy_bytes: bytes,
        copies: COPIES,
        bytes_per_s: 2.0 * bytes as f64 * COPIES as f64 / seconds,
    })
}
