//! # cloth-view
//!
//! The workbench's 3D view, drawn with wgpu into an offscreen texture: the cloth with smooth
//! two-sided shading (normals computed on the GPU) and a colour mode, its pins, every collider,
//! a ground grid and, where asked, the triangles the cloth passes through. The inspector shows the
//! texture in its window (on eframe's device); `cloth run --png` and `--gif` read it back
//! ([`ViewRenderer::read_pixels`]) on a device of their own, so the headless picture is the
//! inspector's.
//!
//! The cloth is drawn from a position buffer: with the wgpu backend in the inspector it is the
//! simulation's own buffer (no read-back); other states are uploaded once per frame.

use bytemuck::{Pod, Zeroable};
use cloth_core::{ClothModel, ClothState, Scene};
use cloth_gpu::layout::GpuCollider;
use wgpu::util::DeviceExt;

pub mod camera;

pub use camera::OrbitCamera;

/// The view's WGSL: the shared structs (`layout.wgsl`), then `render.wgsl`.
pub const RENDER_SHADER: &str = concat!(
    include_str!("../../../shaders/wgsl/layout.wgsl"),
    include_str!("../../../shaders/wgsl/colliders.wgsl"),
    include_str!("../../../shaders/wgsl/render.wgsl")
);
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The view's colour format. egui shows native textures of this format and takes their values
/// as sRGB-encoded, so the shaders' colours are written as they are (and a PNG of the pixels
/// shows what the window shows).
pub const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct CameraUniform {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    light: [f32; 4],
}

/// `ClothInfo` of `render.wgsl` (checked against it by a test).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ClothInfo {
    nx: u32,
    ny: u32,
    color_mode: u32,
    strain_kind: u32,
    collider_count: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    rest_du: f32,
    rest_dv: f32,
    speed_scale: f32,
    strain_scale: f32,
}

impl ClothInfo {
    /// The cloth's grid, spacing and colliders for `color_mode`.
    fn new(scene: &Scene, color_mode: ColorMode) -> Self {
        let [nx, ny] = scene.cloth.resolution;
        let [du, dv] = scene.cloth.spacing();
        Self {
            nx,
            ny,
            color_mode: match color_mode {
                ColorMode::Plain => 0,
                ColorMode::Strain(_) => 1,
                ColorMode::Contact => 2,
                ColorMode::Speed => 3,
            },
            strain_kind: match color_mode {
                ColorMode::Strain(kind) => kind as u32,
                _ => 0,
            },
            collider_count: scene.colliders.len() as u32,
            pad0: 0,
            pad1: 0,
            pad2: 0,
            rest_du: du as f32,
            rest_dv: dv as f32,
            speed_scale: 3.0,
            strain_scale: 0.05,
        }
    }
}

/// The colliders as the view's shaders read them: every collider of the scene, where it is at
/// time `t_s` (s).
pub fn colliders_at(scene: &Scene, t_s: f64) -> Vec<GpuCollider> {
    let mut first = 0;
    (scene.colliders.iter().enumerate())
        .map(|(i, c)| {
            let g = GpuCollider::from_spec(c);
            let d = scene.collider_offset_at(i, t_s);
            let field_first = first;
            first += g.field_dims.iter().product::<u32>();
            GpuCollider { center: [0, 1, 2].map(|k| (f64::from(g.center[k]) + d[k]) as f32), field_first, ..g }
        })
        .collect()
}

/// What the view's distance-field buffer holds: each mesh collider's file, scale and cells.
type FieldSources = Vec<(String, u64, u32)>;

fn field_sources(scene: &Scene) -> FieldSources {
    (scene.colliders.iter())
        .filter_map(|c| match &c.shape {
            cloth_core::colliders::Shape::Mesh { file, scale, cells, .. } => {
                Some((file.clone(), scale.to_bits(), *cells))
            }
            _ => None,
        })
        .collect()
}

/// The samples of the scene's mesh colliders' distance fields, in the order of its colliders
/// (what `colliders_at`'s `field_first` indexes); at least one value.
fn distance_fields_at(scene: &Scene) -> Vec<f32> {
    let mut samples: Vec<f32> = (scene.colliders.iter())
        .filter_map(|c| c.shape.distance_field().and_then(Result::ok))
        .flat_map(|f| f.samples.clone())
        .collect();
    if samples.is_empty() {
        samples.push(0.0);
    }
    samples
}

/// The colliders of `scene` at time `t_s` (s) as one triangle mesh in world space
/// ([`cloth_core::tessellation`]).
fn collider_mesh(scene: &Scene, t_s: f64) -> (Vec<MeshVertex>, Vec<u32>) {
    let mesh = cloth_core::tessellation::colliders(scene, t_s);
    let vertices = mesh.positions.iter().zip(&mesh.normals).map(|(&position, &normal)| MeshVertex { position, normal });
    (vertices.collect(), mesh.indices)
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct MeshVertex {
    position: [f32; 3],
    normal: [f32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct InstanceData {
    center_radius: [f32; 4],
    color: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct LineVertex {
    position: [f32; 3],
    color: [f32; 4],
}

/// How the cloth is coloured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ColorMode {
    /// One colour, two-sided.
    Plain,
    /// Stretch `|L/L0 − 1|` of the springs of one kind (blue 0, red 5%).
    Strain(cloth_core::SpringKind),
    /// Free, sticking or sliding on a collider.
    Contact,
    /// Speed.
    Speed,
}

impl ColorMode {
    /// The names the command lines take (`--color`).
    pub const NAMES: [&'static str; 6] = ["plain", "strain", "shear", "bend", "contact", "speed"];

    /// The mode of a name of [`Self::NAMES`] (`strain` is the structural springs'); `None` for
    /// any other.
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "plain" => Self::Plain,
            "strain" => Self::Strain(cloth_core::SpringKind::Structural),
            "shear" => Self::Strain(cloth_core::SpringKind::Shear),
            "bend" => Self::Strain(cloth_core::SpringKind::Bend),
            "contact" => Self::Contact,
            "speed" => Self::Speed,
            _ => return None,
        })
    }
}

/// Where the cloth's vertices come from this frame.
pub enum Source<'a> {
    /// Buffers on the view's device (the wgpu backend's own buffers, in the inspector).
    Device { positions: &'a wgpu::Buffer, velocities: &'a wgpu::Buffer },
    /// A state read back from another backend, uploaded now.
    Host(&'a ClothState),
}

/// What to draw.
pub struct ViewInputs<'a> {
    pub view_proj: glam::Mat4,
    pub eye: glam::Vec3,
    pub color_mode: ColorMode,
    pub wireframe: bool,
    pub source: Source<'a>,
    /// Simulated time of the drawn state, s: where moving colliders and pins are drawn.
    pub time_s: f64,
    /// Cloth triangles a cloth edge passes through, drawn red over the cloth.
    pub crossed_triangles: &'a [[u32; 3]],
}

struct Target {
    size: [u32; 2],
    texture: wgpu::Texture,
    render_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
}

/// GPU objects of one grid (rebuilt when the grid changes).
struct Mesh {
    nx: u32,
    ny: u32,
    triangles: wgpu::Buffer,
    triangle_count: u32,
    lines: wgpu::Buffer,
    line_count: u32,
    upload_positions: wgpu::Buffer,
    upload_velocities: wgpu::Buffer,
}

/// Renders the scene for the inspector's 3D view.
pub struct ViewRenderer {
    layout: wgpu::BindGroupLayout,
    cloth: wgpu::RenderPipeline,
    wire: wgpu::RenderPipeline,
    crossed: wgpu::RenderPipeline,
    instances: wgpu::RenderPipeline,
    lines: wgpu::RenderPipeline,
    camera: wgpu::Buffer,
    cloth_info: wgpu::Buffer,
    /// The colliders, grown to hold every collider of the scene.
    colliders: wgpu::Buffer,
    /// The mesh colliders' distance fields, and what they were built from.
    distance_fields: (wgpu::Buffer, FieldSources),
    sphere_mesh: (wgpu::Buffer, wgpu::Buffer, u32),
    ground: (wgpu::Buffer, u32),
    mesh: Option<Mesh>,
    target: Option<Target>,
}

fn uv_sphere(segments: u32, rings: u32) -> (Vec<MeshVertex>, Vec<u32>) {
    let (positions, indices) = cloth_core::tessellation::unit_sphere(segments, rings);
    (positions.into_iter().map(|n| MeshVertex { position: n, normal: n }).collect(), indices)
}

fn ground_grid() -> Vec<LineVertex> {
    let mut v = Vec::new();
    let half = 5;
    for k in -half..=half {
        let c = if k == 0 { [0.35, 0.35, 0.4, 1.0] } else { [0.62, 0.64, 0.68, 1.0] };
        let k = k as f32 * 0.5;
        let e = half as f32 * 0.5;
        v.push(LineVertex { position: [k, 0.0, -e], color: c });
        v.push(LineVertex { position: [k, 0.0, e], color: c });
        v.push(LineVertex { position: [-e, 0.0, k], color: c });
        v.push(LineVertex { position: [e, 0.0, k], color: c });
    }
    v
}

impl ViewRenderer {
    /// Creates the pipelines on `device`.
    pub fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("render.wgsl"),
            source: wgpu::ShaderSource::Wgsl(RENDER_SHADER.into()),
        });
        let uniform = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("view bind group layout"),
            entries: &[uniform(0), uniform(1), storage(2), storage(3), storage(4), storage(6)],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("view pipeline layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |label: &str,
                        vs: &str,
                        fs: &str,
                        buffers: &[Option<wgpu::VertexBufferLayout>],
                        topology: wgpu::PrimitiveTopology,
                        bias: i32,
                        through_everything: bool| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vs),
                    buffers,
                    compilation_options: Default::default(),
                },
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fs),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: COLOR,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                    compilation_options: Default::default(),
                }),
                primitive: wgpu::PrimitiveState { topology, cull_mode: None, ..Default::default() },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH,
                    depth_write_enabled: Some(!through_everything),
                    depth_compare: Some(if through_everything {
                        wgpu::CompareFunction::Always
                    } else {
                        wgpu::CompareFunction::LessEqual
                    }),
                    stencil: Default::default(),
                    bias: wgpu::DepthBiasState { constant: bias, slope_scale: 0.0, clamp: 0.0 },
                }),
                multisample: Default::default(),
                multiview_mask: None,
                cache: None,
            })
        };
        let mesh_layout = [
            Some(wgpu::VertexBufferLayout {
                array_stride: size_of::<MeshVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
            }),
            Some(wgpu::VertexBufferLayout {
                array_stride: size_of::<InstanceData>() as u64,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &wgpu::vertex_attr_array![2 => Float32x4, 3 => Float32x4],
            }),
        ];
        let line_layout = [Some(wgpu::VertexBufferLayout {
            array_stride: size_of::<LineVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4],
        })];
        // The cloth's triangles are pushed back slightly so the wireframe drawn over them wins the
        // depth test (line topologies cannot carry a depth bias).
        let cloth =
            pipeline("cloth pipeline", "vs_cloth", "fs_cloth", &[], wgpu::PrimitiveTopology::TriangleList, 2, false);
        // The crossed triangles lie where one sheet of the cloth passes through another, mostly
        // hidden inside the fold: they are drawn through everything, so the view shows where.
        let crossed = pipeline(
            "crossed triangles pipeline",
            "vs_cloth",
            "fs_crossed",
            &[],
            wgpu::PrimitiveTopology::TriangleList,
            0,
            true,
        );
        let wire = pipeline(
            "cloth wireframe pipeline",
            "vs_cloth",
            "fs_wire",
            &[],
            wgpu::PrimitiveTopology::LineList,
            0,
            false,
        );
        let instances = pipeline(
            "sphere pipeline",
            "vs_instance",
            "fs_lit",
            &mesh_layout,
            wgpu::PrimitiveTopology::TriangleList,
            0,
            false,
        );
        let lines = pipeline(
            "ground pipeline",
            "vs_line",
            "fs_line",
            &line_layout,
            wgpu::PrimitiveTopology::LineList,
            0,
            false,
        );
        let buffer = |label: &str, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false })
        };
        let copy_uniform = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST;
        let (sphere_vertices, sphere_indices) = uv_sphere(48, 24);
        let sphere_mesh = (
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("sphere mesh vertices"),
                contents: bytemuck::cast_slice(&sphere_vertices),
                usage: wgpu::BufferUsages::VERTEX,
            }),
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("sphere mesh indices"),
                contents: bytemuck::cast_slice(&sphere_indices),
                usage: wgpu::BufferUsages::INDEX,
            }),
            sphere_indices.len() as u32,
        );
        let grid = ground_grid();
        let ground = (
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("ground grid"),
                contents: bytemuck::cast_slice(&grid),
                usage: wgpu::BufferUsages::VERTEX,
            }),
            grid.len() as u32,
        );
        Self {
            layout,
            cloth,
            wire,
            crossed,
            instances,
            lines,
            camera: buffer("view camera", size_of::<CameraUniform>() as u64, copy_uniform),
            cloth_info: buffer("view cloth info", size_of::<ClothInfo>() as u64, copy_uniform),
            colliders: buffer(
                "view colliders",
                size_of::<GpuCollider>() as u64,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ),
            distance_fields: (buffer("view distance fields", 4, wgpu::BufferUsages::STORAGE), Vec::new()),
            sphere_mesh,
            ground,
            mesh: None,
            target: None,
        }
    }

    fn mesh_for(&mut self, device: &wgpu::Device, model: &ClothModel) -> &Mesh {
        let (nx, ny) = (model.grid.nx, model.grid.ny);
        if self.mesh.as_ref().is_none_or(|m| m.nx != nx || m.ny != ny) {
            let triangles = model.grid.triangle_indices();
            let mut lines = Vec::new();
            for j in 0..ny {
                for i in 0..nx {
                    let a = j * nx + i;
                    if i + 1 < nx {
                        lines.extend_from_slice(&[a, a + 1]);
                    }
                    if j + 1 < ny {
                        lines.extend_from_slice(&[a, a + nx]);
                    }
                }
            }
            let state_bytes = (nx as u64 * ny as u64 * 16).max(16);
            let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
            self.mesh = Some(Mesh {
                nx,
                ny,
                triangle_count: triangles.len() as u32,
                triangles: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("cloth triangles"),
                    contents: bytemuck::cast_slice(&triangles),
                    usage: wgpu::BufferUsages::INDEX,
                }),
                line_count: lines.len() as u32,
                lines: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("cloth wireframe"),
                    contents: bytemuck::cast_slice(&lines),
                    usage: wgpu::BufferUsages::INDEX,
                }),
                upload_positions: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("cloth positions (uploaded)"),
                    size: state_bytes,
                    usage: storage,
                    mapped_at_creation: false,
                }),
                upload_velocities: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("cloth velocities (uploaded)"),
                    size: state_bytes,
                    usage: storage,
                    mapped_at_creation: false,
                }),
            });
        }
        self.mesh.as_ref().expect("just built")
    }

    /// Makes the target `size` pixels; returns whether it is new (a view of it shown elsewhere
    /// must then be made again).
    fn ensure_target(&mut self, device: &wgpu::Device, size: [u32; 2]) -> bool {
        if self.target.as_ref().is_some_and(|t| t.size == size) {
            return false;
        }
        let extent = wgpu::Extent3d { width: size[0], height: size[1], depth_or_array_layers: 1 };
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("view colour"),
            size: extent,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: COLOR,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let render_view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let depth = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("view depth"),
            size: extent,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let depth_view = depth.create_view(&Default::default());
        self.target = Some(Target { size, texture, render_view, depth_view });
        true
    }

    /// The texture the last [`Self::render`] drew into.
    pub fn texture(&self) -> Option<&wgpu::Texture> {
        self.target.as_ref().map(|t| &t.texture)
    }

    /// The last picture drawn, read back: `width × height` RGBA pixels, row by row from the top
    /// (sRGB-encoded, as the window shows them). Waits for the device.
    ///
    /// # Errors
    /// When nothing was drawn yet, or the read-back fails.
    pub fn read_pixels(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Vec<u8>, String> {
        let target = self.target.as_ref().ok_or("nothing drawn yet")?;
        let [width, height] = target.size;
        // Rows of a texture-to-buffer copy are padded to 256 bytes.
        let row = 4 * width;
        let padded = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("view read-back"),
            size: u64::from(padded) * u64::from(height),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("view read-back") });
        encoder.copy_texture_to_buffer(
            target.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded), rows_per_image: None },
            },
            wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        );
        queue.submit([encoder.finish()]);
        let (sender, receiver) = std::sync::mpsc::channel();
        staging.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            let _ = sender.send(r);
        });
        device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| format!("the device did not finish: {e}"))?;
        receiver.recv().map_err(|e| e.to_string())?.map_err(|e| format!("cannot read the picture back: {e}"))?;
        let mapped = staging.slice(..).get_mapped_range().map_err(|e| format!("cannot read the picture back: {e}"))?;
        let mut pixels = Vec::with_capacity((row * height) as usize);
        for y in 0..height as usize {
            pixels.extend_from_slice(&mapped[y * padded as usize..y * padded as usize + row as usize]);
        }
        drop(mapped);
        staging.unmap();
        Ok(pixels)
    }

    /// Draws the scene into a `size`-pixel texture (at most 8192 a side); returns whether the
    /// texture is new ([`Self::texture`]).
    pub fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size: [u32; 2],
        model: &ClothModel,
        inputs: &ViewInputs<'_>,
    ) -> bool {
        let size = [size[0].clamp(1, 8192), size[1].clamp(1, 8192)];
        let scene = &model.scene;
        let camera = CameraUniform {
            view_proj: inputs.view_proj.to_cols_array_2d(),
            eye: inputs.eye.extend(1.0).into(),
            light: [0.35, 0.85, 0.4, 0.0],
        };
        queue.write_buffer(&self.camera, 0, bytemuck::bytes_of(&camera));
        let info = ClothInfo::new(scene, inputs.color_mode);
        queue.write_buffer(&self.cloth_info, 0, bytemuck::bytes_of(&info));
        // Moving colliders and pins are drawn where they are at the state's time.
        let colliders = colliders_at(scene, inputs.time_s);
        let bytes = std::mem::size_of_val(colliders.as_slice()) as u64;
        if bytes > self.colliders.size() {
            self.colliders = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("view colliders"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
        }
        if !colliders.is_empty() {
            queue.write_buffer(&self.colliders, 0, bytemuck::cast_slice(&colliders));
        }
        let sources = field_sources(scene);
        if sources != self.distance_fields.1 {
            let samples = distance_fields_at(scene);
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("view distance fields"),
                contents: bytemuck::cast_slice(&samples),
                usage: wgpu::BufferUsages::STORAGE,
            });
            self.distance_fields = (buffer, sources);
        }
        let (collider_vertices, collider_indices) = collider_mesh(scene, inputs.time_s);
        let collider_buffers = (!collider_indices.is_empty()).then(|| {
            let init = |label: &str, contents: &[u8], usage| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
            };
            (
                init("view collider vertices", bytemuck::cast_slice(&collider_vertices), wgpu::BufferUsages::VERTEX),
                init("view collider indices", bytemuck::cast_slice(&collider_indices), wgpu::BufferUsages::INDEX),
            )
        });
        // The colliders' mesh is in world space: one instance at the origin, of scale 1.
        let mut instances = vec![InstanceData { center_radius: [0.0, 0.0, 0.0, 1.0], color: [0.55, 0.6, 0.68, 1.0] }];
        let marker = 0.25 * (info.rest_du.min(info.rest_dv)).max(0.004);
        for (i, _) in model.grid.pinned.iter().enumerate().filter(|(_, p)| **p) {
            let p = scene.pin_position_at(model.grid.pin_group[i] as usize, model.grid.positions[i], inputs.time_s);
            instances.push(InstanceData {
                center_radius: [p[0] as f32, p[1] as f32, p[2] as f32, marker],
                color: [0.9, 0.1, 0.1, 1.0],
            });
        }
        let instance_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("view instances"),
            contents: bytemuck::cast_slice(&instances),
            usage: wgpu::BufferUsages::VERTEX,
        });
        self.mesh_for(device, model);
        let mesh = self.mesh.as_ref().expect("built");
        let (positions, velocities) = match &inputs.source {
            Source::Device { positions, velocities } => (*positions, *velocities),
            Source::Host(state) => {
                let p: Vec<[f32; 4]> = state.positions.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect();
                let v: Vec<[f32; 4]> = state.velocities.iter().map(|v| [v[0], v[1], v[2], 0.0]).collect();
                queue.write_buffer(&mesh.upload_positions, 0, bytemuck::cast_slice(&p));
                queue.write_buffer(&mesh.upload_velocities, 0, bytemuck::cast_slice(&v));
                (&mesh.upload_positions, &mesh.upload_velocities)
            }
        };
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("view bind group"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: self.camera.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: self.cloth_info.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: positions.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: velocities.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: self.colliders.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: self.distance_fields.0.as_entire_binding() },
            ],
        });
        let crossed = (!inputs.crossed_triangles.is_empty()).then(|| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("view crossed triangles"),
                contents: bytemuck::cast_slice(inputs.crossed_triangles),
                usage: wgpu::BufferUsages::INDEX,
            })
        });
        let (triangle_count, line_count) = (mesh.triangle_count, mesh.line_count);
        let (triangles, lines) = (mesh.triangles.clone(), mesh.lines.clone());
        let new_target = self.ensure_target(device, size);
        let target = self.target.as_ref().expect("just built");
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("view") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("view pass"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.render_view,
                    resolve_target: None,
                    depth_slice: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r: 0.78, g: 0.82, b: 0.88, a: 1.0 }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &bind_group, &[]);
            pass.set_pipeline(&self.lines);
            pass.set_vertex_buffer(0, self.ground.0.slice(..));
            pass.draw(0..self.ground.1, 0..1);
            pass.set_pipeline(&self.instances);
            pass.set_vertex_buffer(1, instance_buffer.slice(..));
            if let Some((vertices, indices)) = &collider_buffers {
                pass.set_vertex_buffer(0, vertices.slice(..));
                pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..collider_indices.len() as u32, 0, 0..1);
            }
            if instances.len() > 1 {
                pass.set_vertex_buffer(0, self.sphere_mesh.0.slice(..));
                pass.set_index_buffer(self.sphere_mesh.1.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..self.sphere_mesh.2, 0, 1..instances.len() as u32);
            }
            pass.set_pipeline(&self.cloth);
            pass.set_index_buffer(triangles.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..triangle_count, 0, 0..1);
            if let Some(crossed) = &crossed {
                pass.set_pipeline(&self.crossed);
                pass.set_index_buffer(crossed.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..3 * inputs.crossed_triangles.len() as u32, 0, 0..1);
            }
            if inputs.wireframe {
                pass.set_pipeline(&self.wire);
                pass.set_index_buffer(lines.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..line_count, 0, 0..1);
            }
        }
        queue.submit([encoder.finish()]);
        new_target
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cloth_core::colliders::Collider;
    use cloth_core::real::Vec3;
    use cloth_core::{CpuSimulator, Simulator};

    /// How a vertex touches the colliders, as the contact colouring shows it.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    enum ContactState {
        /// On no collider.
        Free,
        /// On a collider (within 0.2% of its size), moving along it at under 1 mm/s.
        Sticking,
        /// On a collider, moving along it faster.
        Sliding,
    }

    /// The contact state of every vertex of `state`, in `f32` with `render.wgsl`'s operations (the
    /// last collider a vertex touches decides, as there).
    fn contact_states(scene: &Scene, state: &ClothState) -> Vec<ContactState> {
        let moving = scene.effects.contains(cloth_core::Effect::MovingColliders);
        (state.positions.iter().zip(&state.velocities))
            .map(|(x, v)| {
                let mut contact = ContactState::Free;
                for spec in &scene.colliders {
                    let c = Collider::<f32>::of(spec);
                    let (center, _) = c.at(state.time_s as f32, moving);
                    let s = c.surface(center, Vec3::from_f32(*x));
                    if s.distance < c.tolerance * 2000.0 {
                        let v = Vec3::from_f32(*v);
                        let v_t = v - s.normal * v.dot(s.normal);
                        let sticking = v_t.length() < 1e-3;
                        contact = if sticking { ContactState::Sticking } else { ContactState::Sliding };
                    }
                }
                contact
            })
            .collect()
    }

    /// `(member name, offset)` and size of a struct of the view's WGSL, by naga's reflection.
    fn wgsl_struct(name: &str) -> (Vec<(String, usize)>, usize) {
        let module = naga::front::wgsl::parse_str(RENDER_SHADER).expect("render.wgsl parses");
        for (_, ty) in module.types.iter() {
            if ty.name.as_deref() == Some(name)
                && let naga::TypeInner::Struct { members, span } = &ty.inner
            {
                let fields = members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize)).collect();
                return (fields, *span as usize);
            }
        }
        panic!("no struct {name} in render.wgsl");
    }

    #[test]
    fn the_view_shader_reads_the_structs_the_host_writes() {
        let (fields, size) = wgsl_struct("ClothInfo");
        assert_eq!(size, size_of::<ClothInfo>(), "ClothInfo");
        let names = ["nx", "ny", "color_mode", "strain_kind", "collider_count", "pad0", "pad1", "pad2"];
        let names = names.iter().chain(&["rest_du", "rest_dv", "speed_scale", "strain_scale"]);
        let expected: Vec<(String, usize)> = names.enumerate().map(|(k, n)| (n.to_string(), 4 * k)).collect();
        assert_eq!(fields, expected, "ClothInfo: WGSL (left) against the Rust type's order of u32/f32 fields");
        let (_, size) = wgsl_struct("Camera");
        assert_eq!(size, size_of::<CameraUniform>(), "Camera");
        let collider = GpuCollider::layout();
        let (fields, size) = wgsl_struct(collider.shader_name);
        assert_eq!(size, collider.size, "Collider");
        let fields: Vec<(&str, usize)> = fields.iter().map(|(n, o)| (n.as_str(), *o)).collect();
        assert_eq!(fields, collider.fields, "Collider: WGSL (left) against cloth_gpu::layout::GpuCollider (right)");
    }

    /// The contact colouring on the GPU (`render.wgsl`'s `vertex_color`, which `vs_cloth` draws)
    /// agrees with the CPU's contact state on a cloth lying over two spheres: both spheres are
    /// read where the simulation put them, whatever their number.
    #[test]
    fn contact_colours_on_two_spheres_agree_with_the_cpu() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/hard/two_spheres.ron");
        let scene = Scene::load(std::path::Path::new(path)).unwrap();
        let mut sim = CpuSimulator::new(&scene).unwrap();
        sim.advance(scene.time.frames).unwrap();
        let state = sim.read_state().unwrap();
        let colliders = colliders_at(&scene, state.time_s);
        let cpu = contact_states(&scene, &state);
        for k in 0..scene.colliders.len() {
            let alone = Scene { colliders: vec![scene.colliders[k].clone()], ..scene.clone() };
            let on = contact_states(&alone, &state);
            assert!(on.iter().any(|c| *c != ContactState::Free), "collider {k}: the test needs cloth resting on it");
        }
        // No adapter fails the test (the README's test command installs lavapipe): it never
        // passes without having compared the colours.
        let context = cloth_wgpu::GpuContext::new(None).unwrap_or_else(|e| panic!("no wgpu adapter: {e}"));
        let gpu = gpu_vertex_colors(&context, &scene, &state, &colliders);
        let palette = [(ContactState::Free, [0.55, 0.6, 0.75]), (ContactState::Sticking, [0.2, 0.8, 0.3])];
        let palette = [palette[0], palette[1], (ContactState::Sliding, [0.95, 0.25, 0.15])];
        let mismatches: Vec<(usize, ContactState, [f32; 4])> = (gpu.iter().zip(&cpu).enumerate())
            .filter(|(_, (c, s))| {
                let expected = palette.iter().find(|(p, _)| p == *s).map(|(_, rgb)| *rgb).unwrap();
                (0..3).any(|k| (c[k] - expected[k]).abs() > 1e-6)
            })
            .map(|(i, (c, s))| (i, *s, *c))
            .collect();
        assert!(mismatches.is_empty(), "{} vertices coloured unlike the CPU's state: {mismatches:?}", mismatches.len());
    }

    /// Runs `cs_vertex_colors` of the view's shader on `state` in contact mode.
    fn gpu_vertex_colors(
        context: &cloth_wgpu::GpuContext,
        scene: &Scene,
        state: &ClothState,
        colliders: &[GpuCollider],
    ) -> Vec<[f32; 4]> {
        let device = &context.device;
        let init = |label: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let info = ClothInfo::new(scene, ColorMode::Contact);
        let p: Vec<[f32; 4]> = state.positions.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect();
        let v: Vec<[f32; 4]> = state.velocities.iter().map(|v| [v[0], v[1], v[2], 0.0]).collect();
        let n = p.len() as u64;
        let colors = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("colours"),
            size: 16 * n,
            usage: storage | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("colours read-back"),
            size: 16 * n,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("render.wgsl"),
            source: wgpu::ShaderSource::Wgsl(RENDER_SHADER.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("vertex colours"),
            layout: None,
            module: &module,
            entry_point: Some("cs_vertex_colors"),
            compilation_options: Default::default(),
            cache: None,
        });
        let buffers = [
            (1, init("info", bytemuck::bytes_of(&info), wgpu::BufferUsages::UNIFORM)),
            (2, init("positions", bytemuck::cast_slice(&p), storage)),
            (3, init("velocities", bytemuck::cast_slice(&v), storage)),
            (4, init("colliders", bytemuck::cast_slice(colliders), storage)),
            (6, init("distance fields", bytemuck::cast_slice(&distance_fields_at(scene)), storage)),
        ];
        let mut entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|(b, buffer)| wgpu::BindGroupEntry { binding: *b, resource: buffer.as_entire_binding() })
            .collect();
        entries.push(wgpu::BindGroupEntry { binding: 5, resource: colors.as_entire_binding() });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vertex colours"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups((n as u32).div_ceil(64), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&colors, 0, &staging, 0, 16 * n);
        context.queue.submit([encoder.finish()]);
        staging.map_async(wgpu::MapMode::Read, .., |r| r.unwrap());
        device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
        let view = staging.get_mapped_range(..).unwrap();
        bytemuck::cast_slice::<u8, [f32; 4]>(&view).to_vec()
    }
}
