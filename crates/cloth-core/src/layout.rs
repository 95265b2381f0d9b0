//! GPU data layout, defined once here and consumed by every backend.
//!
//! All types are `#[repr(C)]` and `bytemuck::Pod`, with the alignment rules of WGSL and of GLSL
//! `std140`/`std430` in mind (16-byte vectors first, sizes multiple of 16 for uniform blocks).
//! The shaders declare the same structs; tests in each backend check sizes and offsets.
//!
//! Buffers of one simulation:
//!
//! | buffer | element | count |
//! |---|---|---|
//! | positions (×2, ping-pong) | `[f32; 4]`: xyz m, w = 1 free / 0 pinned | vertices |
//! | velocities (×2, ping-pong) | `[f32; 4]`: xyz m/s, w = the state's time, s | vertices |
//! | spheres | [`GpuSphere`] | spheres (at least 1 slot) |
//! | parameters (uniform) | [`GpuSimParams`] | 1 |
//!
//! Velocities carry the time of their state in `w` (s, f32): every kernel reads the time of the
//! state it reads there and writes the time of the state it writes, so moving pins, moving
//! spheres and gusts know the time of each stage without a host round trip.
//!
//! Semi-implicit Euler adds its packed state ([`PackedState`]), which the substeps inside one
//! submission pass to each other: 24 bytes a vertex instead of the two `vec4`s' 32.
//!
//! | buffer | element | count |
//! |---|---|---|
//! | packed `(x, v.x)` (×2, ping-pong) | `[f32; 4]`: m, m, m, m/s | vertices |
//! | packed `(v.y, v.z)` (×2, ping-pong) | `[f32; 2]`: m/s; the last element's first is the state's time, s | vertices + 1 |
//! | pin bits | `u32`: bit `i % 32` of word `i / 32` set where vertex `i` is pinned | ⌈vertices / 32⌉ (at least 1) |
//!
//! XPBD (`Integrator::Xpbd`) adds, for its constraint projection:
//!
//! | buffer | element | count |
//! |---|---|---|
//! | constraints | [`GpuConstraint`] (each spring once, grouped by colour) | springs |
//! | colour ranges (uniform, dynamic offset) | [`GpuColorRange`] every [`COLOR_RANGE_STRIDE`] bytes | 2 × colours |
//! | Lagrange multipliers `λ` | `f32` | springs |
//! | normal corrections | `f32` (m, summed over the iterations) | vertices |
//!
//! Why per-vertex spring ranges: one GPU thread updates one vertex. It walks its own list of
//! spring ends (each spring is stored at both of its ends), sums the forces and writes only its
//! own vertex. No two threads write the same memory, so no atomics are needed and the result
//! does not depend on thread scheduling (the sum order is fixed by the list order).

use bytemuck::{Pod, Zeroable};

use crate::coloring::COLOR_COUNT;
use crate::effects::Effect;
use crate::integrator::Integrator;
use crate::model::ClothModel;
use crate::scene::Scene;
use crate::springs::SpringKind;

/// Simulation parameters, one uniform buffer. Every field can change between frames without
/// rebuilding the pipeline.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSimParams {
    /// Gravitational acceleration, m/s² (xyz; w unused).
    pub gravity: [f32; 4],
    /// Spring stiffness `k`, N/m, indexed by `SpringKind` (w unused).
    pub stiffness: [f32; 4],
    /// Spring damping `c_d`, N·s/m, indexed by `SpringKind` (w unused).
    pub damping: [f32; 4],
    /// Mass of each vertex, kg.
    pub vertex_mass: f32,
    /// Substep length `Δt`, s.
    pub substep_dt: f32,
    /// Air-drag rate `γ`, 1/s.
    pub air_drag: f32,
    /// Number of vertices.
    pub vertex_count: u32,
    /// Number of spheres in the sphere buffer.
    pub sphere_count: u32,
    /// Grid vertices along u.
    pub grid_nx: u32,
    /// Grid vertices along v.
    pub grid_ny: u32,
    /// Effect bit mask (`EffectSet::bits`), for diagnostics; the shader branches on override /
    /// specialization constants, not on this.
    pub effects: u32,
    /// Wind (`Wind` effect): mean velocity, m/s (xyz), and `w` = coefficient × area per vertex,
    /// N·s/m.
    pub wind: [f32; 4],
    /// Gusts: `x` relative amplitude, `y` angular frequency `2π / period`, rad/s (zw unused).
    pub gust: [f32; 4],
    /// Pin motion (`MovingPins`): steady velocity, m/s (xyz), and `w` angular frequency, rad/s.
    pub pin_velocity: [f32; 4],
    /// Pin motion: amplitude of the oscillation, m (xyz; w unused).
    pub pin_amplitude: [f32; 4],
    /// Spring rest lengths, m: `x` structural along u (`Δu`), `y` structural along v (`Δv`), `z`
    /// shear (`√(Δu² + Δv²)`); the bend springs' are `2Δu` and `2Δv` (exactly twice, in `f32`
    /// too). The force kernels compute the springs from the grid with these (a stencil), as
    /// `springs::rest_length` defines them.
    pub rest_lengths: [f32; 4],
}

/// One sphere collider (64 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSphere {
    /// Centre at time 0, m.
    pub center: [f32; 3],
    /// Radius, m.
    pub radius: f32,
    /// Contact stiffness `k_c`, N/m.
    pub stiffness: f32,
    /// Friction coefficient `c_f`.
    pub friction: f32,
    /// Normal contact damping, N·s/m.
    pub damping: f32,
    /// Padding to 32 bytes.
    pub _pad: f32,
    /// Motion (`MovingSpheres`): steady velocity, m/s.
    pub velocity: [f32; 3],
    /// Motion: angular frequency of the oscillation, rad/s.
    pub omega: f32,
    /// Motion: amplitude of the oscillation, m.
    pub amplitude: [f32; 3],
    /// Padding to 64 bytes.
    pub _pad2: f32,
}

/// One spring as an XPBD constraint between vertices `a < b` (16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuConstraint {
    /// First vertex (the lower index).
    pub a: u32,
    /// Second vertex.
    pub b: u32,
    /// `SpringKind as u32`.
    pub kind: u32,
    /// Rest length, m.
    pub rest_length: f32,
}

/// The constraints one XPBD projection dispatch handles: one colour (16 bytes, stored every
/// [`COLOR_RANGE_STRIDE`] bytes of a uniform buffer and selected by a dynamic offset).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuColorRange {
    /// Index of the colour's first constraint.
    pub first: u32,
    /// Number of constraints of the colour.
    pub count: u32,
    /// 1 in the first iteration of a substep, where the multipliers `λ` start from 0.
    pub first_iteration: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
}

/// Bytes between two [`GpuColorRange`]s in their uniform buffer: 256, the largest
/// `minUniformBufferOffsetAlignment` Vulkan allows (and wgpu's default), so dynamic offsets are
/// valid on every device.
pub const COLOR_RANGE_STRIDE: u64 = 256;

/// Bytes of the colour-range uniform buffer: `2 × COLOR_COUNT` ranges (first iteration and the
/// others).
pub const COLOR_RANGE_BUFFER_BYTES: u64 = 2 * COLOR_COUNT as u64 * COLOR_RANGE_STRIDE;

impl GpuColorRange {
    /// Byte offset of the range of colour `color` in iteration `iteration` (the dynamic offset).
    pub fn offset(color: usize, iteration: u32) -> u32 {
        let slot = if iteration == 0 { color } else { COLOR_COUNT + color };
        (slot as u64 * COLOR_RANGE_STRIDE) as u32
    }
}

impl GpuSimParams {
    /// The parameters of a scene, in `f32`.
    pub fn from_scene(scene: &Scene) -> Self {
        let s = &scene.springs;
        let [nx, ny] = scene.cloth.resolution;
        let f = |v: f64| v as f32;
        let w = &scene.wind;
        let area_per_vertex =
            scene.cloth.size[0] / (nx.max(2) - 1) as f64 * scene.cloth.size[1] / (ny.max(2) - 1) as f64;
        let pins = &scene.cloth.pin_motion;
        Self {
            gravity: [f(scene.gravity[0]), f(scene.gravity[1]), f(scene.gravity[2]), 0.0],
            stiffness: [f(s.structural.stiffness), f(s.shear.stiffness), f(s.bend.stiffness), 0.0],
            damping: [f(s.structural.damping), f(s.shear.damping), f(s.bend.damping), 0.0],
            vertex_mass: f(scene.vertex_mass()),
            substep_dt: f(scene.substep_dt()),
            air_drag: f(scene.air_drag),
            vertex_count: nx.saturating_mul(ny),
            sphere_count: if scene.effects.contains(Effect::SphereContact) { scene.spheres.len() as u32 } else { 0 },
            grid_nx: nx,
            grid_ny: ny,
            effects: scene.effects.bits(),
            wind: [f(w.velocity[0]), f(w.velocity[1]), f(w.velocity[2]), f(w.coefficient * area_per_vertex)],
            gust: [f(w.gust_amplitude), f(2.0 * std::f64::consts::PI / w.gust_period), 0.0, 0.0],
            pin_velocity: [f(pins.velocity[0]), f(pins.velocity[1]), f(pins.velocity[2]), f(pins.angular_frequency())],
            pin_amplitude: [f(pins.amplitude[0]), f(pins.amplitude[1]), f(pins.amplitude[2]), 0.0],
            rest_lengths: {
                let spacing = scene.cloth.spacing();
                let rest = |di, dj| f(crate::springs::rest_length(spacing, di, dj));
                [rest(1, 0), rest(0, 1), rest(1, 1), 0.0]
            },
        }
    }

    /// The wind coefficient times the area per vertex, N·s/m (`wind.w`), in `f64`.
    pub fn wind_coefficient_area(scene: &Scene) -> f64 {
        let [nx, ny] = scene.cloth.resolution;
        scene.wind.coefficient * scene.cloth.size[0] / (nx.max(2) - 1) as f64 * scene.cloth.size[1]
            / (ny.max(2) - 1) as f64
    }
}

/// Semi-implicit Euler's packed state: what one substep hands the next inside a submission.
///
/// A substep reads and writes each vertex's position and velocity, and at large grids the time
/// a substep takes is mostly that traffic (docs/performance.md). The two `vec4`s of the state
/// the read-backs and the renderer see carry 8 bytes of flags (`positions.w` free or pinned,
/// `velocities.w` the time); packed, a vertex is 24 bytes: `(x, y, z, v.x)` and `(v.y, v.z)`.
/// The pins move to a bit mask read once a substep, the time to one element after the last
/// vertex's `(v.y, v.z)`. The first substep of a submission reads the `vec4` state and writes
/// the packed one, the last reads the packed state and writes the `vec4`s (`PACKED_IN`,
/// `PACKED_OUT` in `cloth_step.wgsl` / `.comp`), so nothing else sees the packing. The
/// arithmetic is the same, so the results are bit for bit those of the unpacked kernel.
pub struct PackedState;

impl PackedState {
    /// Bytes a vertex takes in the packed state (against [`PackedState::VEC4_VERTEX_BYTES`]).
    pub const VERTEX_BYTES: u64 = 24;

    /// Bytes a vertex takes in the state the read-backs see: two `vec4`s.
    pub const VEC4_VERTEX_BYTES: u64 = 32;

    /// Bytes a vertex of the state the substeps hand each other (`Simulator::substep_state_bytes`):
    /// [`Self::VERTEX_BYTES`] where the packed passes run, else [`Self::VEC4_VERTEX_BYTES`].
    pub fn substep_bytes(packed: bool) -> u32 {
        (if packed { Self::VERTEX_BYTES } else { Self::VEC4_VERTEX_BYTES }) as u32
    }

    /// Sizes in bytes of the two buffers of one packed state for `vertices` vertices:
    /// `(x, v.x)`, 16 bytes a vertex, and `(v.y, v.z)`, 8 bytes a vertex and one more element
    /// for the time.
    pub fn buffer_bytes(vertices: u64) -> [u64; 2] {
        [16 * vertices, 8 * (vertices + 1)]
    }

    /// The pin bit mask of a `vec4` position buffer (`w = 0` pinned): bit `i % 32` of word
    /// `i / 32` set where vertex `i` is pinned; at least one word.
    pub fn pin_bits(positions: &[[f32; 4]]) -> Vec<u32> {
        let mut bits = vec![0u32; positions.len().div_ceil(32).max(1)];
        for (i, p) in positions.iter().enumerate() {
            if p[3] == 0.0 {
                bits[i / 32] |= 1 << (i % 32);
            }
        }
        bits
    }

    /// Whether semi-implicit Euler's one-substep-per-dispatch kernel runs the substeps inside a
    /// submission on the packed state: yes, unless the environment variable
    /// `CLOTH_PACKED_STATE` is `0` (a knob for benchmarks, to measure what packing gains).
    ///
    /// # Errors
    /// The variable and its value when it is neither `0` nor `1`.
    pub fn enabled() -> Result<bool, String> {
        Self::enabled_from(std::env::var("CLOTH_PACKED_STATE").ok().as_deref())
    }

    fn enabled_from(explicit: Option<&str>) -> Result<bool, String> {
        match explicit.map(str::trim) {
            None | Some("") | Some("1") => Ok(true),
            Some("0") => Ok(false),
            Some(other) => Err(format!("CLOTH_PACKED_STATE={other} (0 or 1)")),
        }
    }

    /// [`PackedState::enabled`] as the error a GPU backend named `backend` returns when the knob
    /// is wrong.
    ///
    /// # Errors
    /// [`SimError::Unsupported`](crate::error::SimError::Unsupported) naming the variable, its
    /// value and the fix.
    pub fn checked_enabled(backend: &'static str) -> Result<bool, crate::error::SimError> {
        Self::enabled().map_err(|what| crate::error::SimError::Unsupported {
            backend,
            what,
            fix: "set it to 0 (the two vec4s throughout) or 1, or unset it for the default, 1".into(),
        })
    }
}

/// The contents of every GPU buffer of a simulation, ready to upload.
#[derive(Clone, Debug)]
pub struct GpuBuffers {
    /// Parameters.
    pub params: GpuSimParams,
    /// Initial positions (w = 1 free, 0 pinned).
    pub positions: Vec<[f32; 4]>,
    /// Initial velocities.
    pub velocities: Vec<[f32; 4]>,
    /// Spheres (at least one element, so the buffer is never empty; `params.sphere_count` says
    /// how many are real).
    pub spheres: Vec<GpuSphere>,
    /// XPBD only (empty otherwise): every spring once, grouped by colour (at least one element).
    pub constraints: Vec<GpuConstraint>,
    /// XPBD only (empty otherwise): the contents of the colour-range uniform buffer,
    /// [`COLOR_RANGE_BUFFER_BYTES`] bytes.
    pub color_ranges: Vec<u8>,
    /// Semi-implicit Euler only (empty otherwise): the pin bits of its packed state
    /// ([`PackedState::pin_bits`]).
    pub pin_bits: Vec<u32>,
}

impl GpuBuffers {
    /// Converts a model to GPU buffers.
    pub fn new(model: &ClothModel) -> Self {
        let scene = &model.scene;
        let v0 = scene.cloth.initial_velocity;
        let positions: Vec<[f32; 4]> = model
            .grid
            .positions
            .iter()
            .zip(&model.grid.pinned)
            .map(|(p, &pinned)| [p[0] as f32, p[1] as f32, p[2] as f32, if pinned { 0.0 } else { 1.0 }])
            .collect();
        let velocities = model
            .grid
            .pinned
            .iter()
            .map(|&pinned| if pinned { [0.0; 4] } else { [v0[0] as f32, v0[1] as f32, v0[2] as f32, 0.0] })
            .collect();
        let mut spheres: Vec<GpuSphere> = if scene.effects.contains(Effect::SphereContact) {
            scene.spheres.iter().map(GpuSphere::from_spec).collect()
        } else {
            Vec::new()
        };
        if spheres.is_empty() {
            spheres.push(GpuSphere::default());
        }
        let (constraints, color_ranges) =
            if scene.integrator == Integrator::Xpbd { xpbd_constraints(model) } else { (Vec::new(), Vec::new()) };
        let pin_bits = if scene.integrator == Integrator::SemiImplicitEuler {
            PackedState::pin_bits(&positions)
        } else {
            Vec::new()
        };
        Self {
            params: GpuSimParams::from_scene(scene),
            positions,
            velocities,
            spheres,
            constraints,
            color_ranges,
            pin_bits,
        }
    }

    /// XPBD: the range of colour `color` in iteration `iteration`, as stored in `color_ranges`.
    pub fn color_range(&self, color: usize, iteration: u32) -> GpuColorRange {
        let at = GpuColorRange::offset(color, iteration) as usize;
        self.color_ranges.get(at..at + size_of::<GpuColorRange>()).map(bytemuck::pod_read_unaligned).unwrap_or_default()
    }

    /// Bytes of device memory these buffers take, counting both ping-pong copies, semi-implicit
    /// Euler's packed states and the XPBD multipliers and normal corrections (not the
    /// integrators' small scratch buffers).
    pub fn device_bytes(&self) -> u64 {
        let b = |n: usize, size: usize| (n * size) as u64;
        let xpbd = if self.constraints.is_empty() {
            0
        } else {
            b(self.constraints.len(), 16 + 4) + b(self.positions.len(), 4) + self.color_ranges.len() as u64
        };
        let packed = if self.pin_bits.is_empty() {
            0
        } else {
            let [xv, v] = PackedState::buffer_bytes(self.positions.len() as u64);
            2 * (xv + v) + b(self.pin_bits.len(), 4)
        };
        2 * b(self.positions.len(), 16)
            + 2 * b(self.velocities.len(), 16)
            + packed
            + b(self.spheres.len(), 64)
            + size_of::<GpuSimParams>() as u64
            + xpbd
    }
}

/// XPBD's constraint list (grouped by colour) and the colour-range uniform buffer's bytes.
fn xpbd_constraints(model: &ClothModel) -> (Vec<GpuConstraint>, Vec<u8>) {
    let colors = model.spring_colors();
    let mut constraints: Vec<GpuConstraint> = colors
        .order
        .iter()
        .map(|&s| {
            let s = &model.springs[s as usize];
            GpuConstraint { a: s.a, b: s.b, kind: s.kind as u32, rest_length: s.rest_length as f32 }
        })
        .collect();
    if constraints.is_empty() {
        constraints.push(GpuConstraint::default());
    }
    let mut bytes = vec![0u8; COLOR_RANGE_BUFFER_BYTES as usize];
    for iteration in [0, 1] {
        for color in 0..COLOR_COUNT {
            let range = GpuColorRange {
                first: colors.first[color],
                count: colors.first[color + 1] - colors.first[color],
                first_iteration: u32::from(iteration == 0),
                _pad: 0,
            };
            let at = GpuColorRange::offset(color, iteration) as usize;
            bytes[at..at + size_of::<GpuColorRange>()].copy_from_slice(bytemuck::bytes_of(&range));
        }
    }
    (constraints, bytes)
}

impl GpuSphere {
    /// Converts a scene sphere to `f32`.
    pub fn from_spec(s: &crate::scene::SphereSpec) -> Self {
        Self {
            center: [s.center[0] as f32, s.center[1] as f32, s.center[2] as f32],
            radius: s.radius as f32,
            stiffness: s.stiffness as f32,
            friction: s.friction as f32,
            damping: s.damping as f32,
            _pad: 0.0,
            velocity: [s.motion.velocity[0] as f32, s.motion.velocity[1] as f32, s.motion.velocity[2] as f32],
            omega: s.motion.angular_frequency() as f32,
            amplitude: [s.motion.amplitude[0] as f32, s.motion.amplitude[1] as f32, s.motion.amplitude[2] as f32],
            _pad2: 0.0,
        }
    }
}

/// The byte layout of one GPU struct, with the names the shaders give it and its fields.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StructLayout {
    /// Name of the struct in the shaders.
    pub shader_name: &'static str,
    /// Size in bytes.
    pub size: usize,
    /// `(field name in the shaders, byte offset)`, in declaration order.
    pub fields: Vec<(&'static str, usize)>,
}

/// The layouts of every struct the shaders share with the host: what each backend's layout test
/// checks its shader against (one list, here, next to the types).
pub fn struct_layouts() -> Vec<StructLayout> {
    use std::mem::offset_of;
    vec![
        StructLayout {
            shader_name: "SimParams",
            size: size_of::<GpuSimParams>(),
            fields: vec![
                ("gravity", offset_of!(GpuSimParams, gravity)),
                ("stiffness", offset_of!(GpuSimParams, stiffness)),
                ("damping", offset_of!(GpuSimParams, damping)),
                ("vertex_mass", offset_of!(GpuSimParams, vertex_mass)),
                ("substep_dt", offset_of!(GpuSimParams, substep_dt)),
                ("air_drag", offset_of!(GpuSimParams, air_drag)),
                ("vertex_count", offset_of!(GpuSimParams, vertex_count)),
                ("sphere_count", offset_of!(GpuSimParams, sphere_count)),
                ("grid_nx", offset_of!(GpuSimParams, grid_nx)),
                ("grid_ny", offset_of!(GpuSimParams, grid_ny)),
                ("effects", offset_of!(GpuSimParams, effects)),
                ("wind", offset_of!(GpuSimParams, wind)),
                ("gust", offset_of!(GpuSimParams, gust)),
                ("pin_velocity", offset_of!(GpuSimParams, pin_velocity)),
                ("pin_amplitude", offset_of!(GpuSimParams, pin_amplitude)),
                ("rest_lengths", offset_of!(GpuSimParams, rest_lengths)),
            ],
        },
        StructLayout {
            shader_name: "Sphere",
            size: size_of::<GpuSphere>(),
            fields: vec![
                ("center", offset_of!(GpuSphere, center)),
                ("radius", offset_of!(GpuSphere, radius)),
                ("stiffness", offset_of!(GpuSphere, stiffness)),
                ("friction", offset_of!(GpuSphere, friction)),
                ("damping", offset_of!(GpuSphere, damping)),
                ("pad", offset_of!(GpuSphere, _pad)),
                ("velocity", offset_of!(GpuSphere, velocity)),
                ("omega", offset_of!(GpuSphere, omega)),
                ("amplitude", offset_of!(GpuSphere, amplitude)),
                ("pad2", offset_of!(GpuSphere, _pad2)),
            ],
        },
        StructLayout {
            shader_name: "Constraint",
            size: size_of::<GpuConstraint>(),
            fields: vec![
                ("a", offset_of!(GpuConstraint, a)),
                ("b", offset_of!(GpuConstraint, b)),
                ("kind", offset_of!(GpuConstraint, kind)),
                ("rest_length", offset_of!(GpuConstraint, rest_length)),
            ],
        },
        StructLayout {
            shader_name: "ColorRange",
            size: size_of::<GpuColorRange>(),
            fields: vec![
                ("first", offset_of!(GpuColorRange, first)),
                ("count", offset_of!(GpuColorRange, count)),
                ("first_iteration", offset_of!(GpuColorRange, first_iteration)),
                ("pad", offset_of!(GpuColorRange, _pad)),
            ],
        },
    ]
}

/// Memory a scene will need, computed from the closed-form spring counts without building
/// anything (so that a huge grid can be refused before allocation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// Bytes of the largest single buffer (positions, RK4's scratch or XPBD's constraints).
    pub largest_buffer_bytes: u64,
    /// Bytes of all GPU buffers together.
    pub device_bytes: u64,
    /// Bytes the CPU needs to build the model (positions, springs, lists) before upload.
    pub host_bytes: u64,
}

impl MemoryEstimate {
    /// Estimates the memory of a scene.
    pub fn of(scene: &Scene) -> Self {
        // u128 arithmetic: a resolution typed by mistake (say 4e9 x 4e9) must give a huge
        // estimate that validation refuses, not an overflow.
        let [nx, ny] = scene.cloth.resolution;
        let (nx, ny) = (nx as u128, ny as u128);
        let vertices = nx * ny;
        let springs: u128 = SpringKind::ALL
            .iter()
            .filter(|k| scene.effects.contains(k.effect()))
            .map(|k| k.count_in_grid(nx as u64, ny as u64) as u128)
            .sum();
        let ends = (2 * springs).max(1);
        // The force kernels compute the springs from the grid (no spring list on the device);
        // RK4 keeps four vec4s per vertex of scratch; XPBD a constraint (16 B) and a multiplier
        // (4 B) per spring, a normal correction per vertex and the colour ranges.
        let rk4 = if scene.integrator == Integrator::RungeKutta4 { 64 * vertices } else { 0 };
        let (xpbd, constraints) = if scene.integrator == Integrator::Xpbd {
            (20 * springs.max(1) + 4 * vertices + COLOR_RANGE_BUFFER_BYTES as u128, 16 * springs.max(1))
        } else {
            (0, 0)
        };
        // Semi-implicit Euler: two packed states (24 B a vertex and 8 B for the time each) and
        // the pin bits.
        let packed = if scene.integrator == Integrator::SemiImplicitEuler {
            2 * (24 * vertices + 8) + 4 * vertices.div_ceil(32).max(1)
        } else {
            0
        };
        let device_bytes = 4 * 16 * vertices + rk4 + packed + 64 * scene.spheres.len().max(1) as u128 + 160 + xpbd;
        // Host: f64 positions + pins, the spring list (32 B each) and f64 lists (24 B each).
        let host_bytes = vertices * (24 + 1 + 4) + springs * 32 + ends * 24 + device_bytes;
        let clamp = |b: u128| u64::try_from(b).unwrap_or(u64::MAX);
        Self {
            largest_buffer_bytes: clamp((16 * vertices).max(rk4).max(constraints)),
            device_bytes: clamp(device_bytes),
            host_bytes: clamp(host_bytes),
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

/// Invocations per workgroup of every GPU kernel, unless `CLOTH_WORKGROUP_SIZE` says otherwise.
/// Tuned on the H100 (docs/performance.md): against 64, 256 cut 128² × 53 substeps from 0.326 to
/// 0.270 ms, 1024² × 64 from 2.90 to 2.66 ms and 2048² × 64 from 12.7 to 9.6 ms (wgpu); 512 was
/// 1-4% faster on the large grids and 4% slower on 128².
pub const DEFAULT_WORKGROUP_SIZE: u32 = 256;

/// Invocations per workgroup of every GPU kernel: [`DEFAULT_WORKGROUP_SIZE`], or the value of the
/// environment variable `CLOTH_WORKGROUP_SIZE` (a tuning knob for benchmarks: both backends pass
/// it to their kernels as a pipeline constant).
///
/// # Errors
/// The variable and its value when it is not a power of two from 32 to 1024.
pub fn workgroup_size() -> Result<u32, String> {
    match std::env::var("CLOTH_WORKGROUP_SIZE") {
        Ok(text) if !text.trim().is_empty() => text
            .trim()
            .parse::<u32>()
            .ok()
            .filter(|n| n.is_power_of_two() && (32..=1024).contains(n))
            .ok_or_else(|| format!("the workgroup size CLOTH_WORKGROUP_SIZE={text}")),
        _ => Ok(DEFAULT_WORKGROUP_SIZE),
    }
}

/// Vertices along `i` of the 2D block of the grid one workgroup of the per-substep kernels
/// updates (`cloth_step.wgsl` / `.comp`), unless `CLOTH_BLOCK_WIDTH` says otherwise: a workgroup
/// of `w` invocations updates a `BLOCK_WIDTH × (w / BLOCK_WIDTH)` block, so the neighbours two
/// rows up and down that its springs read are mostly its own and come from the SM's L1 cache
/// rather than L2. `0`: a workgroup updates `w` consecutive vertices of a row (the layout before).
/// Tuned on the H100 (docs/performance.md): against rows, 64 (blocks of 64 × 4 at 256
/// invocations) cut 1024² × 64 substeps from 2.66 to 2.35 ms and 2048² × 64 from 9.57 to
/// 8.26 ms (wgpu); 16 and 32 gained a little less. Once the spring loop was leaner (one inverse
/// square root, no edge checks inside the grid, 2026-11-27), 128 (128 × 2 blocks) was 2-4% faster
/// than 64 at 2048² and the same at 1024². Since the workgroups find their block without a
/// division ([`BlockGrid`], stop 17), 64 is again the fastest of 16 to 128, at every size from
/// 768² to 2048² on both backends (1024² × 64: 1.5% faster than 128; 2048²: 0.8%) and the same
/// at 512². Workgroups of fewer invocations get rows of theirs.
pub const DEFAULT_BLOCK_WIDTH: u32 = 64;

/// [`DEFAULT_BLOCK_WIDTH`] (at most the workgroup size `threads`), or the value of
/// `CLOTH_BLOCK_WIDTH` (a tuning knob for benchmarks), checked against `threads`.
///
/// # Errors
/// The variable and its value when it is not 0 or a power of two that divides `threads`.
pub fn block_width(threads: u32) -> Result<u32, String> {
    block_width_from(std::env::var("CLOTH_BLOCK_WIDTH").ok().as_deref(), threads)
}

/// The block width the per-substep kernels use on a grid `nx` vertices wide: [`block_width`]
/// (0 if the knob is wrong, which `checked_workgroup_size` reports first), but no wider than the
/// grid's next power of two, so a narrow grid does not leave most of each workgroup idle (at
/// 64 × 4 a 12-wide grid would use 48 of 256 invocations; at 16 × 16 it uses 192).
pub fn grid_block_width(threads: u32, nx: u32) -> u32 {
    let width = block_width(threads).unwrap_or(0);
    if width == 0 { 0 } else { width.min(nx.max(1).next_power_of_two()) }
}

/// [`block_width`] with the variable's value given (`None`: unset).
fn block_width_from(explicit: Option<&str>, threads: u32) -> Result<u32, String> {
    let Some(text) = explicit.filter(|t| !t.trim().is_empty()) else {
        return Ok(DEFAULT_BLOCK_WIDTH.min(threads));
    };
    let width =
        text.trim().parse::<u32>().map_err(|_| format!("the block width CLOTH_BLOCK_WIDTH={text} (a number)"))?;
    if width != 0 && (!width.is_power_of_two() || !threads.is_multiple_of(width)) {
        return Err(format!(
            "the block width CLOTH_BLOCK_WIDTH={width} (0, or a power of two that divides the workgroup size {threads})"
        ));
    }
    Ok(width)
}

/// How the per-substep kernels (`cloth_step.wgsl` / `.comp`) cover an `nx × ny` grid at `threads`
/// invocations a workgroup: the block width they are specialized with (`BLOCK_WIDTH`) and the
/// workgroups to dispatch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockGrid {
    /// [`grid_block_width`], or 0 (a workgroup's worth of consecutive vertices) where the blocks
    /// would not fit the device's workgroup counts.
    pub width: u32,
    /// Workgroups along x and y. With `width` > 0, one workgroup per block, `[blocks along i,
    /// blocks along j]`: a workgroup's id is its block's column and row, so the kernel finds its
    /// vertices without an integer division (measured on the H100: docs/performance.md). With
    /// `width` = 0, one invocation per vertex, along x up to the device's limit, the rest along y.
    pub workgroups: [u32; 2],
}

impl BlockGrid {
    /// The blocks of an `nx × ny` grid at `threads` invocations a workgroup, on a device that
    /// allows `max_per_dimension` workgroups along each axis (Vulkan guarantees 65 535).
    /// `width` is [`grid_block_width`] unless its blocks exceed that count along an axis (a grid
    /// more than about 262 000 vertices tall at the default 64 × 4 blocks), where the kernels
    /// fall back to rows, which every grid that fits in memory can be dispatched as.
    pub fn new(threads: u32, nx: u32, ny: u32, max_per_dimension: u32) -> Self {
        let width = grid_block_width(threads, nx);
        if width > 0 {
            let blocks = [nx.div_ceil(width), ny.div_ceil(threads / width)];
            if blocks.iter().all(|&b| b <= max_per_dimension) {
                return Self { width, workgroups: blocks };
            }
        }
        Self { width: 0, workgroups: spilled_workgroups(nx * ny, threads, max_per_dimension) }
    }
}

/// Workgroups of `threads` invocations for `items` invocations in all (at least one workgroup):
/// along x up to `max_per_dimension`, the rest along y. Each kernel dispatched this way forms its
/// item index as `id.y · groups.x · threads + id.x` and skips the indices past `items`.
pub fn spilled_workgroups(items: u32, threads: u32, max_per_dimension: u32) -> [u32; 2] {
    let groups = items.div_ceil(threads).max(1);
    let max = max_per_dimension.max(1);
    if groups <= max { [groups, 1] } else { [max, groups.div_ceil(max)] }
}

/// The bytes a substep of semi-implicit Euler's packed passes moves (its packed state in and out,
/// 2 × [`PackedState::VERTEX_BYTES`] a vertex) above which, up to
/// [`ALTERNATE_ORDER_MAX_SUBSTEP_BYTES`], the passes alternate the order in which their
/// workgroups take the grid's blocks by default ([`alternates_order`]): half the H100's 50 MB of
/// L2 cache. Taking the blocks forward, then backward, and so on, each substep starts on the
/// blocks the one before wrote last: the block written at fraction `f` from the end of a substep
/// is read again after `2 f` of a substep's traffic instead of after all of it, so more of the
/// reads come from the L2 cache once the state stops fitting in it. Below this the state stays in
/// the cache in either order and the switch of pipeline between substeps only costs: measured on
/// the H100 (docs/performance.md), 512² × 64 (13 MB) +0.3% and the flag at 512×341 × 4247
/// substeps (8 MB) +1% to +1.5%.
pub const ALTERNATE_ORDER_MIN_SUBSTEP_BYTES: u64 = 25_000_000;

/// The most bytes a substep may move for the packed passes to alternate the order of the blocks
/// by default (see [`ALTERNATE_ORDER_MIN_SUBSTEP_BYTES`]): twice the H100's L2 cache. Measured on
/// the H100: 1024² × 64 substeps (50 MB a substep) −4.9% (vulkano) and −6.4% (wgpu); 2048²
/// (201 MB) −1%, but vulkano's 2048² rows ran up to 2.5 times slower with it on three of five
/// machines, for a reason not found.
pub const ALTERNATE_ORDER_MAX_SUBSTEP_BYTES: u64 = 100_000_000;

/// Whether semi-implicit Euler's packed passes on a grid of `vertices` alternate the order in
/// which their workgroups take the grid's blocks (substep `s` of a submission backward when `s` is
/// odd; `REVERSED_ORDER` in `cloth_step.wgsl` / `.comp`): where a substep moves more than
/// [`ALTERNATE_ORDER_MIN_SUBSTEP_BYTES`] and at most [`ALTERNATE_ORDER_MAX_SUBSTEP_BYTES`], unless
/// `CLOTH_ALTERNATE_ORDER` says otherwise (a tuning knob for benchmarks and tests: 1 always, 0
/// never). Only where the workgroups update blocks
/// ([`grid_block_width`] > 0). The results do not depend on it: each vertex's update reads only
/// the state before the substep.
///
/// # Errors
/// The variable and its value when it is neither 0 nor 1.
pub fn alternates_order(vertices: u64) -> Result<bool, String> {
    alternates_order_from(std::env::var("CLOTH_ALTERNATE_ORDER").ok().as_deref(), vertices)
}

/// [`alternates_order`] with the variable's value given (`None`: unset).
fn alternates_order_from(explicit: Option<&str>, vertices: u64) -> Result<bool, String> {
    match explicit.map(str::trim).filter(|t| !t.is_empty()) {
        None => {
            let bytes = vertices * 2 * PackedState::VERTEX_BYTES;
            Ok(bytes > ALTERNATE_ORDER_MIN_SUBSTEP_BYTES && bytes <= ALTERNATE_ORDER_MAX_SUBSTEP_BYTES)
        }
        Some("0") => Ok(false),
        Some("1") => Ok(true),
        Some(other) => Err(format!("CLOTH_ALTERNATE_ORDER={other} (0 or 1)")),
    }
}

/// [`workgroup_size`] as the error a GPU backend named `backend` returns when the knob (or
/// `CLOTH_BLOCK_WIDTH`, [`block_width`]) is wrong.
///
/// # Errors
/// [`SimError::Unsupported`](crate::error::SimError::Unsupported) naming the variable, its value
/// and the fix.
pub fn checked_workgroup_size(backend: &'static str) -> Result<u32, crate::error::SimError> {
    let size = workgroup_size().map_err(|what| crate::error::SimError::Unsupported {
        backend,
        what,
        fix: format!("give it a power of two from 32 to 1024, or unset it for the default, {DEFAULT_WORKGROUP_SIZE}"),
    })?;
    block_width(size).map_err(|what| crate::error::SimError::Unsupported {
        backend,
        what,
        fix: format!("unset it for the default, {DEFAULT_BLOCK_WIDTH}"),
    })?;
    alternates_order(0).map_err(|what| crate::error::SimError::Unsupported {
        backend,
        what,
        fix: "unset it for the default (alternate where a substep moves 25 to 100 MB)".to_string(),
    })?;
    Ok(size)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_width_defaults_within_the_workgroup_and_checks_what_is_asked() {
        assert_eq!(block_width_from(None, 256), Ok(DEFAULT_BLOCK_WIDTH));
        // Every workgroup size the knob allows has a default block (rows below 128 invocations).
        for threads in [32, 64, 128, 1024] {
            assert_eq!(block_width_from(None, threads), Ok(DEFAULT_BLOCK_WIDTH.min(threads)), "{threads}");
        }
        assert_eq!(block_width_from(Some(" "), 64), Ok(64));
        assert_eq!(block_width_from(Some("0"), 256), Ok(0));
        assert_eq!(block_width_from(Some("32"), 256), Ok(32));
        assert!(block_width_from(Some("128"), 64).unwrap_err().contains("divides the workgroup size 64"));
        assert!(block_width_from(Some("48"), 256).unwrap_err().contains("CLOTH_BLOCK_WIDTH=48"));
        assert!(block_width_from(Some("wide"), 256).unwrap_err().contains("a number"));
    }

    #[test]
    fn a_narrow_grid_gets_a_narrower_block() {
        if std::env::var_os("CLOTH_BLOCK_WIDTH").is_some() {
            return; // (the knob is not set in the tests)
        }
        assert_eq!(grid_block_width(256, 2048), DEFAULT_BLOCK_WIDTH);
        assert_eq!(grid_block_width(256, 150), DEFAULT_BLOCK_WIDTH);
        assert_eq!(grid_block_width(256, 32), 32);
        assert_eq!(grid_block_width(256, 12), 16);
        assert_eq!(grid_block_width(256, 1), 1);
        assert_eq!(grid_block_width(64, 2048), 64);
        for nx in 1..300 {
            let w = grid_block_width(256, nx);
            assert!(w.is_power_of_two() && 256u32.is_multiple_of(w), "{nx}: {w}");
        }
    }

    #[test]
    fn block_grids_cover_the_grid_one_workgroup_a_block() {
        if std::env::var_os("CLOTH_BLOCK_WIDTH").is_some() {
            return; // (the knob is not set in the tests)
        }
        // 1024² at 64 × 4: 16 blocks across, 256 down.
        assert_eq!(BlockGrid::new(256, 1024, 1024, 65_535), BlockGrid { width: 64, workgroups: [16, 256] });
        // Remainders round up: 150 × 41 at 64 × 4 is 3 × 11 blocks.
        assert_eq!(BlockGrid::new(256, 150, 41, 65_535), BlockGrid { width: 64, workgroups: [3, 11] });
        // Narrow: 12 wide at 16 × 16.
        assert_eq!(BlockGrid::new(256, 12, 40, 65_535), BlockGrid { width: 16, workgroups: [1, 3] });
        // Too many block rows for the device: rows of 256 vertices, spilling into y.
        assert_eq!(BlockGrid::new(256, 300, 300_000, 65_535), BlockGrid { width: 0, workgroups: [65_535, 6] });
        assert_eq!(BlockGrid::new(256, 4, 1000, 8), BlockGrid { width: 0, workgroups: [8, 2] });
        for (nx, ny) in [(1, 1), (7, 13), (128, 2), (129, 3), (1000, 999)] {
            let grid = BlockGrid::new(256, nx, ny, 65_535);
            let [x, y] = grid.workgroups;
            let (w, h) = (grid.width, 256 / grid.width);
            assert!(x * w >= nx && (x - 1) * w < nx && y * h >= ny && (y - 1) * h < ny, "{nx} × {ny}: {grid:?}");
        }
    }

    #[test]
    fn layouts_have_the_sizes_the_shaders_expect() {
        assert_eq!(size_of::<GpuSimParams>(), 160);
        assert_eq!(size_of::<GpuSimParams>() % 16, 0, "uniform blocks are multiples of 16 bytes");
        assert_eq!(size_of::<GpuSphere>(), 64);
        assert_eq!(size_of::<GpuConstraint>(), 16);
        assert_eq!(size_of::<GpuColorRange>(), 16);
    }

    #[test]
    fn estimate_matches_the_built_buffers() {
        for integrator in [Integrator::SemiImplicitEuler, Integrator::Xpbd] {
            for res in [[2, 2], [7, 13], [32, 32]] {
                let scene = Scene {
                    cloth: crate::scene::ClothSpec { resolution: res, ..Default::default() },
                    integrator,
                    ..Default::default()
                };
                let buffers = GpuBuffers::new(&ClothModel::new(&scene));
                assert_eq!(MemoryEstimate::of(&scene).device_bytes, buffers.device_bytes(), "{res:?} {integrator:?}");
            }
        }
    }

    #[test]
    fn pin_bits_mark_the_pinned_vertices() {
        let mut positions = vec![[0.0, 0.0, 0.0, 1.0]; 70];
        for i in [0, 31, 32, 69] {
            positions[i][3] = 0.0;
        }
        assert_eq!(PackedState::pin_bits(&positions), vec![1 | 1 << 31, 1, 1 << 5]);
        assert_eq!(PackedState::pin_bits(&[]), vec![0]);
        assert_eq!(PackedState::buffer_bytes(10), [160, 88]);
    }

    #[test]
    fn the_packed_state_knob_takes_0_or_1() {
        assert_eq!(PackedState::enabled_from(None), Ok(true));
        assert_eq!(PackedState::enabled_from(Some("0")), Ok(false));
        assert_eq!(PackedState::enabled_from(Some(" 1 ")), Ok(true));
        let wrong = PackedState::enabled_from(Some("yes")).unwrap_err();
        assert!(wrong.contains("CLOTH_PACKED_STATE=yes"), "{wrong}");
    }

    #[test]
    fn the_order_alternates_where_the_state_outgrows_the_cache() {
        // 1024²: 50 MB a substep, alternates; 768²: 28 MB, too; 512²: 13 MB and 2048²: 201 MB,
        // do not.
        assert_eq!(alternates_order_from(None, 1024 * 1024), Ok(true));
        assert_eq!(alternates_order_from(None, 768 * 768), Ok(true));
        assert_eq!(alternates_order_from(None, 512 * 512), Ok(false));
        assert_eq!(alternates_order_from(None, 2048 * 2048), Ok(false));
        assert_eq!(alternates_order_from(Some(""), 32 * 32), Ok(false));
        assert_eq!(alternates_order_from(Some("1"), 32 * 32), Ok(true));
        assert_eq!(alternates_order_from(Some("1"), 2048 * 2048), Ok(true));
        assert_eq!(alternates_order_from(Some(" 0 "), 1024 * 1024), Ok(false));
        let wrong = alternates_order_from(Some("yes"), 1).unwrap_err();
        assert!(wrong.contains("CLOTH_ALTERNATE_ORDER=yes"), "{wrong}");
    }

    #[test]
    fn the_largest_square_grid_fits_and_the_next_does_not() {
        let scene = Scene::default();
        let limit = 128 << 20;
        let n = largest_square_grid(&scene, limit);
        let at = |n: u32| {
            let mut s = scene.clone();
            s.cloth.resolution = [n, n];
            MemoryEstimate::of(&s).largest_buffer_bytes
        };
        assert!(at(n) <= limit && at(n + 1) > limit, "{n}");
    }

    #[test]
    fn colour_ranges_cover_the_constraints_once() {
        let scene = Scene { integrator: Integrator::Xpbd, ..Default::default() };
        let buffers = GpuBuffers::new(&ClothModel::new(&scene));
        for iteration in [0, 5] {
            let mut next = 0;
            for color in 0..COLOR_COUNT {
                let range = buffers.color_range(color, iteration);
                assert_eq!(range.first, next);
                assert_eq!(range.first_iteration, u32::from(iteration == 0));
                next += range.count;
            }
            assert_eq!(next as usize, buffers.constraints.len());
        }
    }
}
