//! A run as one binary glTF 2.0 file (GLB).
//!
//! * The cloth is one mesh of two triangles a cell (split along `(i, j)–(i+1, j+1)`), with
//!   POSITION and NORMAL of the first kept state and TEXCOORD_0 = `(i/(nx−1), j/(ny−1))`, in a
//!   double-sided material.
//! * Every later kept state is a morph target of that mesh: its POSITION and NORMAL minus the
//!   first's. The animation drives the targets' weights on the simulated clock (s): at the time
//!   of kept state `k` the weight of target `k` is 1 and every other 0, interpolated linearly, so
//!   a viewer shows exactly the simulated positions at the kept times and blends them between.
//!   Morph targets are the encoding every glTF importer plays (Blender imports them as shape
//!   keys); the alternative, a node per frame switched by scale, would leave one mesh a frame in
//!   Blender's outliner.
//! * Each collider is a node and mesh of its own ([`cloth_core::tessellation`]), in world space
//!   at time 0; a moving collider's node is translated by its motion, animated on the same clock.
//!
//! The binary chunk is spilled to a temporary file as the run goes (the JSON, which comes first
//! in the file, depends on every frame's bounds), and the GLB is assembled in a second temporary
//! file renamed into place at the end.

use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use cloth_core::tessellation::{self, TriangleMesh};
use cloth_core::{ClothState, Effect, Scene};
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;

use cloth_core::output::{cannot_write, temporary_beside};

use crate::{ExportError, ExportPlan, ExportSummary, Temporary};

/// The largest GLB, bytes: its header and chunk lengths are 32-bit.
pub const MAX_GLB_BYTES: u64 = u32::MAX as u64;

/// The cloth's colour (linear RGBA) and the colliders'.
const CLOTH_COLOR: [f32; 4] = [0.16, 0.36, 0.72, 1.0];
const COLLIDER_COLOR: [f32; 4] = [0.55, 0.58, 0.62, 1.0];

/// Bytes of the binary glTF of `targets` morph targets (kept frames after the first) of
/// `scene`, whose colliders take `collider_bytes`, with `moving` moving colliders; the JSON
/// estimated from above.
fn glb_bytes(scene: &Scene, collider_bytes: u64, moving: u64, targets: u64) -> u64 {
    let [nx, ny] = scene.cloth.resolution.map(u64::from);
    let (v, t) = (nx * ny, 2 * nx.saturating_sub(1) * ny.saturating_sub(1));
    let kept = targets + 1;
    let fixed = 12 * t + 32 * v + collider_bytes;
    let frames = 24 * v * targets + 4 * kept + 4 * kept * targets + 12 * kept * moving;
    // The JSON: a fixed part, a few hundred bytes a collider, and two accessors, two buffer
    // views and a target entry a frame (each under 400 bytes).
    let json = 8192 + 600 * scene.colliders.len() as u64 + 800 * targets;
    12 + 8 + json + 8 + fixed + frames
}

/// The colliders' meshes and how many of them move.
fn collider_meshes(scene: &Scene) -> (Vec<TriangleMesh>, u64) {
    let meshes: Vec<TriangleMesh> = (0..scene.colliders.len()).map(|i| tessellation::collider(scene, i, 0.0)).collect();
    let moving = if scene.effects.contains(Effect::MovingColliders) { scene.colliders.len() as u64 } else { 0 };
    (meshes, moving)
}

fn mesh_bytes(mesh: &TriangleMesh) -> u64 {
    24 * mesh.positions.len() as u64 + 4 * mesh.indices.len() as u64
}

/// Refuses, before the run, a run whose GLB would pass [`MAX_GLB_BYTES`], saying how many frames
/// fit.
pub(crate) fn check_fits(path: &Path, scene: &Scene, frames: u32, every: u32) -> Result<(), ExportError> {
    let (meshes, moving) = collider_meshes(scene);
    let collider_bytes = meshes.iter().map(mesh_bytes).sum();
    let bytes = |frames: u64| glb_bytes(scene, collider_bytes, moving, frames / u64::from(every));
    let needed = bytes(u64::from(frames));
    if needed <= MAX_GLB_BYTES {
        return Ok(());
    }
    // The most frames that fit, by bisection (the size grows with the frames).
    let (mut fits, mut too_many) = (0u64, u64::from(frames));
    while too_many - fits > 1 {
        let middle = fits + (too_many - fits) / 2;
        if bytes(middle) <= MAX_GLB_BYTES { fits = middle } else { too_many = middle }
    }
    Err(ExportError::TooLarge {
        path: path.to_path_buf(),
        frames,
        vertices: scene.vertex_count(),
        every,
        bytes: needed,
        fitting: fits,
    })
}

/// The key of the asset's extras under which the run is described.
pub const EXTRAS_KEY: &str = "cloth_workbench";

/// What [`crate::read`] needs to draw the run again: the scene as RON (its colliders, pins and
/// grid) and the backend that ran it, in the asset's extras.
fn embedded_run(scene: &Scene, source: &str) -> Result<Box<serde_json::value::RawValue>, ExportError> {
    let value = serde_json::json!({ EXTRAS_KEY: { "scene_ron": scene.to_ron_string(), "backend": source } });
    serde_json::value::to_raw_value(&value).map_err(|e| ExportError::Io(io::Error::other(e)))
}

/// Bounds of a list of points, per axis.
fn bounds(points: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut low = [f32::INFINITY; 3];
    let mut high = [f32::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            low[k] = low[k].min(p[k]);
            high[k] = high[k].max(p[k]);
        }
    }
    (low, high)
}

/// What an accessor holds.
#[derive(Clone, Copy)]
enum Kind {
    Vertex3,
    Vertex2,
    Indices,
    Scalar,
    Vec3Output,
}

/// A binary glTF file being written.
pub struct GlbWriter {
    path: PathBuf,
    spill: Temporary,
    bin: BufWriter<std::fs::File>,
    length: u64,
    root: json::Root,
    scene: Scene,
    cloth_mesh: json::Index<json::Mesh>,
    cloth_node: json::Index<json::Node>,
    /// The moving colliders' nodes.
    moving_nodes: Vec<(usize, json::Index<json::Node>)>,
    base_positions: Vec<[f32; 3]>,
    base_normals: Vec<[f32; 3]>,
    targets: Vec<json::mesh::MorphTarget>,
    times: Vec<f32>,
    planned: u64,
}

impl GlbWriter {
    /// Starts the file for `plan` with the cloth's first kept state `initial`.
    pub(crate) fn start(
        path: &Path,
        plan: &ExportPlan,
        scene: &Scene,
        initial: &ClothState,
        source: &str,
    ) -> Result<Self, ExportError> {
        let [nx, ny] = scene.cloth.resolution;
        if initial.positions.len() != scene.vertex_count() {
            return Err(ExportError::WrongState { expected: scene.vertex_count(), got: initial.positions.len() });
        }
        // The binary chunk's spill file: `.NAME.PID.bin.tmp` beside the final file.
        let spill = Temporary::new(temporary_beside(path).with_extension("bin.tmp"));
        let file = std::fs::File::create(&spill.path).map_err(|e| cannot_write(path, &e, e.kind()))?;
        let mut root = json::Root {
            asset: json::Asset {
                version: "2.0".into(),
                generator: Some(format!("cloth workbench {}", env!("CARGO_PKG_VERSION"))),
                copyright: None,
                extensions: None,
                extras: Some(embedded_run(scene, source)?),
                min_version: None,
            },
            ..Default::default()
        };
        root.buffers.push(json::Buffer {
            byte_length: USize64(0),
            extensions: None,
            extras: Default::default(),
            name: None,
            uri: None,
        });
        let material = |root: &mut json::Root, name: &str, color: [f32; 4], double_sided: bool| {
            let mut m = json::Material { double_sided, name: Some(name.into()), ..Default::default() };
            m.pbr_metallic_roughness.base_color_factor = json::material::PbrBaseColorFactor(color);
            m.pbr_metallic_roughness.metallic_factor = json::material::StrengthFactor(0.0);
            m.pbr_metallic_roughness.roughness_factor = json::material::StrengthFactor(0.8);
            root.push(m)
        };
        let cloth_material = material(&mut root, "cloth", CLOTH_COLOR, true);
        let collider_material = material(&mut root, "collider", COLLIDER_COLOR, false);
        let mut writer = Self {
            path: path.to_path_buf(),
            spill,
            bin: BufWriter::with_capacity(1 << 20, file),
            length: 0,
            root,
            scene: scene.clone(),
            cloth_mesh: json::Index::new(0),
            cloth_node: json::Index::new(0),
            moving_nodes: Vec::new(),
            base_positions: initial.positions.clone(),
            base_normals: tessellation::cloth_normals(&initial.positions, nx, ny),
            targets: Vec::new(),
            times: vec![initial.time_s as f32],
            planned: plan.kept_frames(),
        };
        // The cloth.
        let indices: Vec<u32> = cloth_core::intersections::triangles(nx, ny).into_iter().flatten().collect();
        let uv: Vec<[f32; 2]> = (0..ny)
            .flat_map(|j| (0..nx).map(move |i| [i as f32 / (nx - 1).max(1) as f32, j as f32 / (ny - 1).max(1) as f32]))
            .collect();
        let base_positions = writer.base_positions.clone();
        let base_normals = writer.base_normals.clone();
        let positions = writer.accessor(bytemuck::cast_slice(&base_positions), Kind::Vertex3, Some(&base_positions))?;
        let normals = writer.accessor(bytemuck::cast_slice(&base_normals), Kind::Vertex3, None)?;
        let texcoords = writer.accessor(bytemuck::cast_slice(&uv), Kind::Vertex2, None)?;
        let index_accessor = writer.accessor(bytemuck::cast_slice(&indices), Kind::Indices, None)?;
        let attributes = [
            (json::mesh::Semantic::Positions, positions),
            (json::mesh::Semantic::Normals, normals),
            (json::mesh::Semantic::TexCoords(0), texcoords),
        ];
        writer.cloth_mesh = writer.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some("cloth".into()),
            primitives: vec![primitive(&attributes, index_accessor, cloth_material)],
            weights: None,
        });
        writer.cloth_node = writer.root.push(json::Node {
            mesh: Some(writer.cloth_mesh),
            name: Some(format!("cloth '{}' ({nx} x {ny} vertices, {source})", scene.name)),
            ..Default::default()
        });
        let mut nodes = vec![writer.cloth_node];
        // The colliders.
        let (meshes, moving) = collider_meshes(scene);
        for (i, mesh) in meshes.iter().enumerate() {
            if mesh.indices.is_empty() {
                continue;
            }
            let positions =
                writer.accessor(bytemuck::cast_slice(&mesh.positions), Kind::Vertex3, Some(&mesh.positions))?;
            let normals = writer.accessor(bytemuck::cast_slice(&mesh.normals), Kind::Vertex3, None)?;
            let indices = writer.accessor(bytemuck::cast_slice(&mesh.indices), Kind::Indices, None)?;
            let attributes = [(json::mesh::Semantic::Positions, positions), (json::mesh::Semantic::Normals, normals)];
            let name = format!("collider {i} ({})", scene.colliders[i].kind().name());
            let mesh = writer.root.push(json::Mesh {
                extensions: None,
                extras: Default::default(),
                name: Some(name.clone()),
                primitives: vec![primitive(&attributes, indices, collider_material)],
                weights: None,
            });
            let node = writer.root.push(json::Node { mesh: Some(mesh), name: Some(name), ..Default::default() });
            if moving > 0 {
                writer.moving_nodes.push((i, node));
            }
            nodes.push(node);
        }
        let scene_index = writer.root.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: Some(scene.name.clone()),
            nodes,
        });
        writer.root.scene = Some(scene_index);
        Ok(writer)
    }

    /// Appends `bytes` to the binary chunk as a buffer view, and an accessor of `kind` over it
    /// (with per-axis `bounds_of` where given: glTF requires them on POSITION).
    fn accessor(
        &mut self,
        bytes: &[u8],
        kind: Kind,
        bounds_of: Option<&[[f32; 3]]>,
    ) -> Result<json::Index<json::Accessor>, ExportError> {
        use json::accessor::{ComponentType, GenericComponentType, Type};
        let (type_, component, size, target) = match kind {
            Kind::Vertex3 => (Type::Vec3, ComponentType::F32, 12, Some(json::buffer::Target::ArrayBuffer)),
            Kind::Vertex2 => (Type::Vec2, ComponentType::F32, 8, Some(json::buffer::Target::ArrayBuffer)),
            Kind::Indices => (Type::Scalar, ComponentType::U32, 4, Some(json::buffer::Target::ElementArrayBuffer)),
            Kind::Scalar => (Type::Scalar, ComponentType::F32, 4, None),
            Kind::Vec3Output => (Type::Vec3, ComponentType::F32, 12, None),
        };
        self.bin.write_all(bytes).map_err(|e| cannot_write(&self.path, &e, e.kind()))?;
        let view = self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64(bytes.len() as u64),
            byte_offset: Some(USize64(self.length)),
            byte_stride: None,
            extensions: None,
            extras: Default::default(),
            name: None,
            target: target.map(Valid),
        });
        self.length += bytes.len() as u64;
        let (min, max) = match bounds_of {
            Some(points) => {
                let (low, high) = bounds(points);
                (Some(json::Value::from(low.to_vec())), Some(json::Value::from(high.to_vec())))
            }
            None => (None, None),
        };
        Ok(self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64((bytes.len() / size) as u64),
            component_type: Valid(GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        }))
    }

    /// Records the next kept state as a morph target.
    pub(crate) fn record(&mut self, state: &ClothState) -> Result<(), ExportError> {
        if state.positions.len() != self.base_positions.len() {
            return Err(ExportError::WrongState { expected: self.base_positions.len(), got: state.positions.len() });
        }
        if self.times.len() as u64 >= self.planned {
            return Err(ExportError::TooManyFrames { planned: self.planned });
        }
        let [nx, ny] = self.scene.cloth.resolution;
        let delta = |a: &[[f32; 3]], b: &[[f32; 3]]| -> Vec<[f32; 3]> {
            a.iter().zip(b).map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]]).collect()
        };
        let positions = delta(&state.positions, &self.base_positions);
        let normals = delta(&tessellation::cloth_normals(&state.positions, nx, ny), &self.base_normals);
        let positions = self.accessor(bytemuck::cast_slice(&positions), Kind::Vertex3, Some(&positions))?;
        let normals = self.accessor(bytemuck::cast_slice(&normals), Kind::Vertex3, None)?;
        self.targets.push(json::mesh::MorphTarget {
            positions: Some(positions),
            normals: Some(normals),
            tangents: None,
        });
        self.times.push(state.time_s as f32);
        Ok(())
    }

    /// Writes the animation and the JSON, assembles the GLB and renames it into place.
    pub(crate) fn finish(mut self) -> Result<ExportSummary, ExportError> {
        let kept = self.times.len();
        let targets = self.targets.len();
        let mut channels = Vec::new();
        let mut samplers = Vec::new();
        if kept > 1 {
            let times = self.times.clone();
            let input = self.accessor(bytemuck::cast_slice(&times), Kind::Scalar, None)?;
            // The input must state its bounds (glTF: animation sampler inputs have min and max).
            let accessor = &mut self.root.accessors[input.value()];
            accessor.min = Some(json::Value::from(vec![times[0]]));
            accessor.max = Some(json::Value::from(vec![times[kept - 1]]));
            // At kept state k (0 is the base mesh): the weight of target k − 1 is 1.
            let mut weights = vec![0.0f32; kept * targets];
            for k in 1..kept {
                weights[k * targets + (k - 1)] = 1.0;
            }
            let output = self.accessor(bytemuck::cast_slice(&weights), Kind::Scalar, None)?;
            let property = json::animation::Property::MorphTargetWeights;
            animate(&mut samplers, &mut channels, [input, output], self.cloth_node, property);
            for (collider, node) in self.moving_nodes.clone() {
                let offsets: Vec<[f32; 3]> = (times.iter())
                    .map(|&t| self.scene.collider_offset_at(collider, f64::from(t)).map(|x| x as f32))
                    .collect();
                let output = self.accessor(bytemuck::cast_slice(&offsets), Kind::Vec3Output, None)?;
                animate(&mut samplers, &mut channels, [input, output], node, json::animation::Property::Translation);
            }
            let mesh = &mut self.root.meshes[self.cloth_mesh.value()];
            mesh.primitives[0].targets = Some(std::mem::take(&mut self.targets));
            mesh.weights = Some(vec![0.0; targets]);
            self.root.push(json::Animation {
                extensions: None,
                extras: Default::default(),
                name: Some(format!("{} (simulated time, s)", self.scene.name)),
                channels,
                samplers,
            });
        }
        self.root.buffers[0].byte_length = USize64(self.length);
        self.bin.flush().map_err(|e| cannot_write(&self.path, &e, e.kind()))?;
        let mut json_bytes =
            json::serialize::to_vec(&self.root).map_err(|e| cannot_write(&self.path, &e, io::ErrorKind::Other))?;
        while json_bytes.len() % 4 != 0 {
            json_bytes.push(b' ');
        }
        let bin_padding = (4 - self.length % 4) % 4;
        let total = 12 + 8 + json_bytes.len() as u64 + 8 + self.length + bin_padding;
        if total > MAX_GLB_BYTES {
            // Planned runs fit; this is a run recorded past its plan's estimate.
            return Err(cannot_write(
                &self.path,
                format!("{total} bytes is more than a GLB can hold ({MAX_GLB_BYTES})"),
                io::ErrorKind::FileTooLarge,
            )
            .into());
        }
        let assembled = Temporary::new(temporary_beside(&self.path));
        let write = || -> io::Result<()> {
            let file = std::fs::File::create(&assembled.path)?;
            let mut out = BufWriter::with_capacity(1 << 20, file);
            out.write_all(b"glTF")?;
            out.write_all(&2u32.to_le_bytes())?;
            out.write_all(&(total as u32).to_le_bytes())?;
            out.write_all(&(json_bytes.len() as u32).to_le_bytes())?;
            out.write_all(b"JSON")?;
            out.write_all(&json_bytes)?;
            out.write_all(&((self.length + bin_padding) as u32).to_le_bytes())?;
            out.write_all(b"BIN\0")?;
            let mut spilled = std::fs::File::open(&self.spill.path)?;
            io::copy(&mut spilled, &mut out)?;
            out.write_all(&vec![0u8; bin_padding as usize])?;
            out.into_inner().map_err(io::IntoInnerError::into_error)?.sync_all()
        };
        write().map_err(|e| cannot_write(&self.path, &e, e.kind()))?;
        assembled.keep(&self.path)?;
        Ok(ExportSummary { path: self.path.clone(), frames: kept as u64, bytes: total })
    }
}

/// Adds a linearly interpolated sampler of `[input, output]` (times, values) and the channel
/// that drives `property` of `node` with it.
fn animate(
    samplers: &mut Vec<json::animation::Sampler>,
    channels: &mut Vec<json::animation::Channel>,
    [input, output]: [json::Index<json::Accessor>; 2],
    node: json::Index<json::Node>,
    property: json::animation::Property,
) {
    let sampler = json::Index::new(samplers.len() as u32);
    samplers.push(json::animation::Sampler {
        extensions: None,
        extras: Default::default(),
        input,
        interpolation: Valid(json::animation::Interpolation::Linear),
        output,
    });
    channels.push(json::animation::Channel {
        sampler,
        target: json::animation::Target { extensions: None, extras: Default::default(), node, path: Valid(property) },
        extensions: None,
        extras: Default::default(),
    });
}

/// A triangle primitive of `attributes` and `indices` in `material`.
fn primitive(
    attributes: &[(json::mesh::Semantic, json::Index<json::Accessor>)],
    indices: json::Index<json::Accessor>,
    material: json::Index<json::Material>,
) -> json::mesh::Primitive {
    json::mesh::Primitive {
        attributes: attributes.iter().map(|(s, a)| (Valid(s.clone()), *a)).collect(),
        extensions: None,
        extras: Default::default(),
        indices: Some(indices),
        material: Some(material),
        mode: Valid(json::mesh::Mode::Triangles),
        targets: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_size_estimate_bounds_a_written_file_from_above() {
        let mut scene = Scene::default();
        scene.cloth.resolution = [12, 10];
        let dir = std::env::temp_dir().join(format!("cloth-glb-size-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.glb");
        let plan = ExportPlan::new(&path, &scene, 30, 1).unwrap();
        let mut sim = cloth_core::CpuSimulator::new(&scene).unwrap();
        use cloth_core::Simulator as _;
        let mut w = GlbWriter::start(&path, &plan, &scene, &sim.read_state().unwrap(), "cpu").unwrap();
        for _ in 0..30 {
            sim.advance(1).unwrap();
            w.record(&sim.read_state().unwrap()).unwrap();
        }
        let summary = w.finish().unwrap();
        let (meshes, moving) = collider_meshes(&scene);
        let estimate = glb_bytes(&scene, meshes.iter().map(mesh_bytes).sum(), moving, 30);
        assert_eq!(summary.bytes, std::fs::metadata(&path).unwrap().len());
        assert!(summary.bytes <= estimate && estimate < summary.bytes + 40_000, "{} vs {estimate}", summary.bytes);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_run_past_the_format_is_refused_with_the_frames_that_fit() {
        let mut scene = Scene::default();
        scene.cloth.resolution = [1024, 1024];
        let e = check_fits(Path::new("big.glb"), &scene, 300, 1).unwrap_err().to_string();
        // 1024² vertices take 24 MiB a kept frame and 32 MiB for the first: 168 frames fit in 4 GiB.
        assert!(e.contains("at most 168 frames fit at --every 1"), "{e}");
        check_fits(Path::new("big.glb"), &scene, 300, 2).unwrap();
    }
}
