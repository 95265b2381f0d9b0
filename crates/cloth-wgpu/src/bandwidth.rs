//! The device's measured copy bandwidth: the memory-bandwidth ceiling a memory-bound substep is
//! compared with.

use std::time::Instant;

use cloth_core::SimError;

use crate::BACKEND_NAME;
use crate::context::GpuContext;

/// What a copy-bandwidth measurement found.
#[derive(Clone, Debug, PartialEq)]
pub struct CopyBandwidth {
    /// The adapter, in words.
    pub adapter: String,
    /// Bytes of each copy.
    pub copy_bytes: u64,
    /// Copies timed.
    pub copies: u32,
    /// The ceiling the substep kernels are compared with, bytes per second: the faster of the two
    /// measurements below.
    pub bytes_per_s: f64,
    /// Bytes moved per second by a compute kernel copying `vec4<f32>`s, read plus written (a copy
    /// of `b` bytes moves `2 b`).
    pub kernel_bytes_per_s: f64,
    /// The same for `copy_buffer_to_buffer` (the driver's copy command).
    pub copy_command_bytes_per_s: f64,
}

/// Copies timed after one warm-up copy.
const COPIES: u32 = 40;

/// Workgroups of the copy kernel (of 256 invocations each; a grid-stride loop covers the rest):
/// 1024 × 256 invocations keep every SM of a large GPU busy.
const COPY_WORKGROUPS: u32 = 1024;

const COPY_SHADER: &str = r#"
@group(0) @binding(0) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<f32>>;

@compute @workgroup_size(256)
fn copy(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let stride = groups.x * 256u;
    let n = arrayLength(&src);
    for (var i = id.x; i < n; i += stride) {
        dst[i] = src[i];
    }
}
"#;

/// Measures the device's copy bandwidth: `COPIES` copies of up to 512 MiB (less where the device
/// allows less) by a compute kernel (`vec4<f32>` loads and stores, a grid-stride loop) in one
/// compute pass, timed by timestamp queries where the device has them (else by the wall clock
/// from submission to completion); and the same number of `copy_buffer_to_buffer` commands in one
/// submission, by the wall clock. Each copied byte counts twice (read and written). On the
/// adapter whose name contains `adapter`, else the best.
///
/// # Errors
/// [`SimError::Unavailable`] when no adapter matches; [`SimError::Device`] when the device fails.
pub fn copy_bandwidth(adapter: Option<&str>) -> Result<CopyBandwidth, SimError> {
    let context = GpuContext::new(adapter)?;
    let (device, queue) = (&context.device, &context.queue);
    let limits = device.limits();
    let bytes = (512u64 << 20).min(limits.max_storage_buffer_binding_size).min(limits.max_buffer_size) / 16 * 16;
    let device_error = |reason: String| SimError::Device { backend: BACKEND_NAME, reason };
    let make = |label: &str| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let (a, b) = (make("bandwidth a"), make("bandwidth b"));
    let wait = || device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| device_error(format!("waiting: {e}")));

    // The driver's copy command.
    let copy_commands = |copies: u32| {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("copies") });
        for k in 0..copies {
            let (from, to) = if k % 2 == 0 { (&a, &b) } else { (&b, &a) };
            encoder.copy_buffer_to_buffer(from, 0, to, 0, bytes);
        }
        queue.submit([encoder.finish()]);
    };
    copy_commands(1);
    wait()?;
    let start = Instant::now();
    copy_commands(COPIES);
    wait()?;
    let copy_command_bytes_per_s = 2.0 * bytes as f64 * COPIES as f64 / start.elapsed().as_secs_f64();

    // The copy kernel, a → b and b → a alternately.
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("bandwidth copy"),
        source: wgpu::ShaderSource::Wgsl(COPY_SHADER.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("bandwidth copy"),
        layout: None,
        module: &module,
        entry_point: Some("copy"),
        compilation_options: Default::default(),
        cache: None,
    });
    let layout = pipeline.get_bind_group_layout(0);
    let bind = |from: &wgpu::Buffer, to: &wgpu::Buffer| {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bandwidth copy"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: from.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: to.as_entire_binding() },
            ],
        })
    };
    let groups = [bind(&a, &b), bind(&b, &a)];
    let timed = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let queries = timed.then(|| {
        device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("bandwidth"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        })
    });
    let resolved = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bandwidth timestamps"),
        size: 16,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bandwidth timestamps read-back"),
        size: 16,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let kernels = |copies: u32, with_timestamps: bool| {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("copy kernel") });
        {
            let timestamp_writes = match (&queries, with_timestamps) {
                (Some(q), true) => Some(wgpu::ComputePassTimestampWrites {
                    query_set: q,
                    beginning_of_pass_write_index: Some(0),
                    end_of_pass_write_index: Some(1),
                }),
                _ => None,
            };
            let mut pass = encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("copy kernel"), timestamp_writes });
            pass.set_pipeline(&pipeline);
            for k in 0..copies {
                pass.set_bind_group(0, &groups[k as usize % 2], &[]);
                pass.dispatch_workgroups(COPY_WORKGROUPS, 1, 1);
            }
        }
        if let (Some(q), true) = (&queries, with_timestamps) {
            encoder.resolve_query_set(q, 0..2, &resolved, 0);
            encoder.copy_buffer_to_buffer(&resolved, 0, &readback, 0, 16);
        }
        queue.submit([encoder.finish()]);
    };
    kernels(1, false);
    wait()?;
    let start = Instant::now();
    kernels(COPIES, true);
    wait()?;
    let mut seconds = start.elapsed().as_secs_f64();
    if timed {
        let (tx, rx) = std::sync::mpsc::channel();
        readback.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        wait()?;
        rx.recv()
            .map_err(|_| device_error("the timestamp read-back never completed".into()))?
            .map_err(|e| device_error(format!("mapping the timestamps: {e}")))?;
        let view = readback.get_mapped_range(..).map_err(|e| device_error(format!("reading the timestamps: {e:?}")))?;
        let pair: [u64; 2] = bytemuck::pod_read_unaligned(&view[..16]);
        let ticks = pair[1].saturating_sub(pair[0]);
        if ticks > 0 {
            seconds = ticks as f64 * queue.get_timestamp_period() as f64 * 1e-9;
        }
    }
    let kernel_bytes_per_s = 2.0 * bytes as f64 * COPIES as f64 / seconds;
    Ok(CopyBandwidth {
        adapter: context.adapter_description.clone(),
        copy_bytes: bytes,
        copies: COPIES,
        bytes_per_s: kernel_bytes_per_s.max(copy_command_bytes_per_s),
        kernel_bytes_per_s,
        copy_command_bytes_per_s,
    })
}
