//! The device's copy bandwidth: the memory ceiling a memory-bound substep is compared with,
//! measured the same way on every backend.

use std::time::Instant;

use cloth_core::SimError;

use crate::plan::{BindGroupDesc, Binding, BufferDesc, BufferUsage, KernelDesc, PipelineDesc, Shader};
use crate::{Dispatch, Frame, GpuBackend, GpuTuning};

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

/// Workgroups of the copy kernel (256 invocations each; its grid-stride loop covers the rest):
/// enough to keep every SM of a large GPU busy.
const COPY_WORKGROUPS: u32 = 1024;

/// Measures the copy bandwidth of the device `tuning.adapter` names on backend `B`: `COPIES`
/// copies of 512 MiB (less where the device binds less), back and forth between two buffers, by
/// the `copy` kernel of `shaders/` in one submission, timed by its timestamps (else by the wall
/// clock from submission to completion).
///
/// # Errors
/// [`SimError::Unavailable`] without a matching adapter, [`SimError::Device`] when it fails.
pub fn copy_bandwidth<B: GpuBackend>(tuning: &GpuTuning) -> Result<CopyBandwidth, SimError> {
    let mut backend = B::open(tuning)?;
    let bytes = (512u64 << 20).min(backend.limits().max_storage_binding) / 16 * 16;
    let buffer =
        |label: &str| BufferDesc { label: label.into(), usage: BufferUsage::Storage, size: bytes, contents: None };
    let kernel = KernelDesc {
        shader: Shader::Copy,
        bindings: vec![Binding::Storage { read_only: true }, Binding::Storage { read_only: false }],
    };
    let pipeline =
        PipelineDesc { kernel: 0, name: "copy".into(), label: "bandwidth copy".into(), constants: Vec::new() };
    let group = |label: &str| BindGroupDesc { kernel: 0, label: label.into(), buffers: Vec::new() };
    let (buffers, pipelines, groups) = backend.setup(|b| {
        let buffers = [b.create_buffer(&buffer("bandwidth a"))?, b.create_buffer(&buffer("bandwidth b"))?];
        let kernel = b.create_kernel(&kernel)?;
        let pipelines = [b.create_pipeline(&kernel, &pipeline)?];
        let [x, y] = [&buffers[0], &buffers[1]];
        let groups = [
            b.create_bind_group(&kernel, &group("a -> b"), &[x, y])?,
            b.create_bind_group(&kernel, &group("b -> a"), &[y, x])?,
        ];
        Ok((buffers, pipelines, groups))
    })?;
    let dispatches: Vec<Dispatch> = (0..COPIES)
        .map(|k| Dispatch {
            pipeline: 0,
            bind_group: k as usize % 2,
            workgroups: [COPY_WORKGROUPS, 1],
            dynamic_offset: None,
            indirect: None,
        })
        .collect();
    let timed = backend.create_timer();
    let frame = |n: usize, timestamps| Frame {
        timestamps,
        dispatches: &dispatches[..n],
        pipelines: &pipelines,
        bind_groups: &groups,
        indirect: None,
    };
    backend.submit(frame(1, None))?;
    backend.read(&[(&buffers[0], 16)])?;
    let start = Instant::now();
    backend.submit(frame(dispatches.len(), timed.then_some(0)))?;
    let seconds = if timed {
        backend.read_timer(1)?
    } else {
        backend.read(&[(&buffers[0], 16)])?;
        start.elapsed().as_secs_f64()
    };
    Ok(CopyBandwidth {
        adapter: backend.adapter_name(),
        copy_bytes: bytes,
        copies: COPIES,
        bytes_per_s: 2.0 * bytes as f64 * COPIES as f64 / seconds,
    })
}
