//! Every shader module that uses a struct shared with the host declares it with the byte layout
//! of the Rust type (`cloth_gpu::layout::struct_layouts`), and declares every pipeline constant
//! the plan sets on it: the WGSL modules by naga's reflection, the SPIR-V modules by reading
//! their decorations (naga's SPIR-V reader cannot read specialization-constant expressions).

use std::collections::HashMap;

use cloth_core::{Integrator, Scene};
use cloth_gpu::plan::{Constant, Plan, Shader};
use cloth_gpu::{DeviceLimits, GpuTuning, Tiling};

/// The view's shader, as the inspector builds it.
const RENDER_SHADER: &str = concat!(
    include_str!("../../shaders/wgsl/layout.wgsl"),
    include_str!("../../shaders/wgsl/colliders.wgsl"),
    include_str!("../../shaders/wgsl/render.wgsl")
);

/// Every WGSL module, by file name.
fn wgsl_modules() -> Vec<(&'static str, String)> {
    let tiled = cloth_wgpu::tiled_shader_source(&cloth_gpu::geometry::DEFAULT_TILES[0]);
    vec![
        ("cloth_step.wgsl", cloth_wgpu::STEP_SHADER.to_string()),
        ("cloth_step_tiled.wgsl", tiled),
        ("xpbd.wgsl", cloth_wgpu::XPBD_SHADER.to_string()),
        ("self_hash.wgsl", cloth_wgpu::SELF_HASH_SHADER.to_string()),
        ("vbd.wgsl", cloth_wgpu::VBD_SHADER.to_string()),
        ("implicit.wgsl", cloth_wgpu::IMPLICIT_SHADER.to_string()),
        ("render.wgsl", RENDER_SHADER.to_string()),
    ]
}

/// Every SPIR-V module, by file name.
const SPIRV_MODULES: [(&str, &[u8]); 6] = [
    ("cloth_step.spv", cloth_vulkano::STEP_SPIRV),
    ("cloth_step_tiled.spv", cloth_vulkano::TILED_STEP_SPIRV),
    ("xpbd.spv", cloth_vulkano::XPBD_SPIRV),
    ("self_hash.spv", cloth_vulkano::SELF_HASH_SPIRV),
    ("vbd.spv", cloth_vulkano::VBD_SPIRV),
    ("implicit.spv", cloth_vulkano::IMPLICIT_SPIRV),
];

/// The modules that read the colliders (the hash's reads the parameters only).
fn reads_colliders(file: &str) -> bool {
    !file.starts_with("self_hash")
}

#[test]
fn every_wgsl_module_declares_the_shared_structs_as_the_host_lays_them_out() {
    for (file, source) in wgsl_modules() {
        let module = naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{file}: {e}"));
        for layout in cloth_gpu::layout::struct_layouts() {
            let name = layout.shader_name;
            let found = module.types.iter().find_map(|(_, ty)| match &ty.inner {
                naga::TypeInner::Struct { members, span } if ty.name.as_deref() == Some(name) => Some((members, *span)),
                _ => None,
            });
            let Some((members, span)) = found else { panic!("{file}: no struct {name}") };
            assert_eq!(span as usize, layout.size, "{file}: {name}: WGSL size {span}, Rust size {}", layout.size);
            let members: Vec<(&str, usize)> =
                members.iter().map(|m| (m.name.as_deref().unwrap_or(""), m.offset as usize)).collect();
            assert_eq!(members, layout.fields, "{file}: {name}: WGSL members (left) against the Rust type's (right)");
        }
    }
}

/// What the SPIR-V says about its types: the decorations the checks need.
#[derive(Default)]
struct Reflection {
    /// Struct type id -> member names, and member offsets.
    member_names: HashMap<u32, Vec<(u32, String)>>,
    member_offsets: HashMap<u32, Vec<(u32, u32)>>,
    /// Struct type ids, in order of declaration.
    structs: Vec<u32>,
    /// Array type id -> element type id; type id -> ArrayStride; fixed-size array type id ->
    /// the id of its length.
    array_element: HashMap<u32, u32>,
    array_stride: HashMap<u32, u32>,
    array_length: HashMap<u32, u32>,
    /// Result id -> the first word of an OpConstant's value.
    constants: HashMap<u32, u32>,
    /// Result id -> OpName; result id -> SpecId.
    names: HashMap<u32, String>,
    spec_ids: HashMap<u32, u32>,
}

fn string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).take_while(|b| *b != 0).collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

fn reflect(spirv: &[u8]) -> Reflection {
    let words: Vec<u32> = spirv.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert_eq!(words[0], 0x0723_0203, "SPIR-V magic number");
    let mut r = Reflection::default();
    let mut i = 5;
    while i < words.len() {
        let (count, opcode) = ((words[i] >> 16) as usize, words[i] & 0xffff);
        let op = &words[i + 1..i + count];
        match opcode {
            5 => drop(r.names.insert(op[0], string(&op[1..]))),
            6 => r.member_names.entry(op[0]).or_default().push((op[1], string(&op[2..]))),
            71 if op[1] == 1 => drop(r.spec_ids.insert(op[0], op[2])),
            71 if op[1] == 6 => drop(r.array_stride.insert(op[0], op[2])),
            72 if op[2] == 35 => r.member_offsets.entry(op[0]).or_default().push((op[1], op[3])),
            28 => {
                r.array_element.insert(op[0], op[1]);
                r.array_length.insert(op[0], op[2]);
            }
            29 => drop(r.array_element.insert(op[0], op[1])),
            43 => drop(r.constants.insert(op[1], op[2])),
            30 => r.structs.push(op[0]),
            _ => {}
        }
        i += count.max(1);
    }
    r
}

/// The laid-out struct whose members are named `names`: `(member, offset)` and its array stride
/// (its size) if it is the element of a runtime array. Only the buffer-layout copy of a struct
/// carries Offset decorations (a copy for function-local values has none).
/// A struct's `(member, offset)` list and its array stride, if any.
type SpirvStruct = (Vec<(String, u32)>, Option<u32>);

fn spirv_struct(r: &Reflection, names: &[&str]) -> Option<SpirvStruct> {
    r.structs.iter().find_map(|id| {
        let mut members = r.member_names.get(id).cloned().unwrap_or_default();
        members.sort();
        let mut offsets = r.member_offsets.get(id).cloned().unwrap_or_default();
        offsets.sort();
        let same = members.len() == names.len() && members.iter().zip(names).all(|((_, a), b)| a == b);
        (same && offsets.len() == names.len()).then(|| {
            let fields = members.into_iter().zip(offsets).map(|((_, n), (_, o))| (n, o)).collect();
            let stride = r.array_element.iter().find(|(_, e)| *e == id).and_then(|(a, _)| r.array_stride.get(a));
            (fields, stride.copied())
        })
    })
}

#[test]
fn every_spirv_module_lays_the_shared_structs_out_as_the_host() {
    for (file, spirv) in SPIRV_MODULES {
        let r = reflect(spirv);
        let mut found = 0;
        for layout in cloth_gpu::layout::struct_layouts() {
            let name = layout.shader_name;
            let names: Vec<&str> = layout.fields.iter().map(|f| f.0).collect();
            // A module that does not use a struct carries no trace of it.
            let Some((members, stride)) = spirv_struct(&r, &names) else { continue };
            found += 1;
            // Array elements carry their size as the array's stride; a uniform block has none (its
            // last member, a float or a vec4 in our blocks, ends where the Rust struct does).
            match stride {
                Some(stride) => assert_eq!(stride as usize, layout.size, "{file}: {name}: stride against size"),
                None => {
                    let last = layout.size - layout.fields.last().map_or(0, |f| f.1);
                    assert!(last == 4 || last == 16, "{file}: {name}: the last member ends the struct");
                }
            }
            let members: Vec<(&str, usize)> = members.iter().map(|(n, o)| (n.as_str(), *o as usize)).collect();
            assert_eq!(members, layout.fields, "{file}: {name}: SPIR-V members (left) against the Rust type's (right)");
        }
        let least = if reads_colliders(file) { 2 } else { 1 };
        assert!(found >= least, "{file}: the parameters (and the colliders) at least");
    }
}

/// The kernels' uniform block of colliders holds `cloth_core::colliders::MAX_COLLIDERS`, the
/// number the host pads it to and validation allows: in WGSL the constant `MAX_COLLIDERS`, in
/// SPIR-V the length of the array of `Collider`s.
#[test]
fn the_collider_block_holds_as_many_colliders_as_the_host_allows() {
    let max = cloth_core::colliders::MAX_COLLIDERS;
    for (file, source) in wgsl_modules() {
        let module = naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{file}: {e}"));
        let (_, constant) = (module.constants.iter())
            .find(|(_, c)| c.name.as_deref() == Some("MAX_COLLIDERS"))
            .unwrap_or_else(|| panic!("{file}: no MAX_COLLIDERS"));
        let value = match module.global_expressions[constant.init] {
            naga::Expression::Literal(naga::Literal::U32(n)) => n as usize,
            ref other => panic!("{file}: MAX_COLLIDERS is {other:?}"),
        };
        assert_eq!(value, max, "{file}: MAX_COLLIDERS");
    }
    let collider = (cloth_gpu::layout::struct_layouts().into_iter())
        .find(|l| l.shader_name == "Collider")
        .expect("the Collider layout");
    let names: Vec<&str> = collider.fields.iter().map(|f| f.0).collect();
    for (file, spirv) in SPIRV_MODULES.into_iter().filter(|(file, _)| reads_colliders(file)) {
        let r = reflect(spirv);
        let id = r.structs.iter().copied().find(|id| {
            let mut members: Vec<String> = r.member_names.get(id).into_iter().flatten().map(|m| m.1.clone()).collect();
            members.sort();
            let mut sorted = names.clone();
            sorted.sort();
            members == sorted && r.member_offsets.contains_key(id)
        });
        let id = id.unwrap_or_else(|| panic!("{file}: no laid-out Collider"));
        let (array, _) =
            (r.array_element.iter()).find(|(_, e)| **e == id).unwrap_or_else(|| panic!("{file}: no array of Collider"));
        let length = r.array_length.get(array).and_then(|l| r.constants.get(l)).copied();
        assert_eq!(length, Some(max as u32), "{file}: the array of Collider holds MAX_COLLIDERS");
    }
}

/// The plan of each integrator on a device that allows everything, tiled or not.
fn plans() -> Vec<Plan> {
    let limits = DeviceLimits {
        max_workgroups_per_dimension: 65_535,
        max_invocations: 1024,
        workgroup_memory: 48 * 1024,
        max_storage_binding: 1 << 30,
        storage_buffers_per_stage: 16,
        cpu: false,
    };
    let mut plans = Vec::new();
    for integrator in Integrator::ALL {
        for tiling in [Tiling::On, Tiling::Off] {
            let scene = Scene { integrator, ..Scene::default() };
            let tuning = GpuTuning { tiling, ..GpuTuning::default() };
            plans.push(Plan::new(&scene, &tuning, &limits, "test").unwrap());
        }
        let mut self_collision = Scene { integrator, ..Scene::default() };
        self_collision.effects = self_collision.effects.with(cloth_core::Effect::SelfCollision);
        plans.push(Plan::new(&self_collision, &GpuTuning::default(), &limits, "test").unwrap());
    }
    plans
}

#[test]
fn every_constant_the_plan_sets_is_declared_by_its_module() {
    let kinds = [("step", 0), ("tiled", 1), ("xpbd", 2), ("self_hash", 3), ("vbd", 4), ("implicit", 5)];
    let wgsl: HashMap<&str, naga::Module> = kinds
        .into_iter()
        .map(|(kind, k)| (kind, naga::front::wgsl::parse_str(&wgsl_modules()[k].1).unwrap()))
        .collect();
    let spirv: HashMap<&str, Reflection> =
        kinds.into_iter().map(|(kind, k)| (kind, reflect(SPIRV_MODULES[k].1))).collect();
    let mut checked = 0;
    for plan in plans() {
        for pipeline in &plan.pipelines {
            let kind = match plan.kernels[pipeline.kernel].shader {
                Shader::Step => "step",
                Shader::Tiled(_) => "tiled",
                Shader::Xpbd => "xpbd",
                Shader::SelfHash => "self_hash",
                Shader::Vbd => "vbd",
                Shader::Implicit => "implicit",
                Shader::Copy => unreachable!("a simulation's plan has no copy kernel"),
            };
            for (constant, _) in &pipeline.constants {
                let name = constant.name();
                if !constant.is_wgsl_module_constant() {
                    let overrides = &wgsl[kind].overrides;
                    let declared = overrides.iter().any(|(_, o)| o.name.as_deref() == Some(name));
                    assert!(declared, "{kind} WGSL: no override {name} for {}", pipeline.label);
                }
                let r = &spirv[kind];
                let by_id: HashMap<u32, &str> = r
                    .spec_ids
                    .iter()
                    .map(|(target, id)| (*id, r.names.get(target).map_or("", String::as_str)))
                    .collect();
                // glslc names a constant that sizes the workgroup after the gl_WorkGroupSize it
                // builds, not after itself.
                let sizes_workgroup =
                    matches!(constant, Constant::WorkgroupSize | Constant::TileWidth | Constant::TileHeight);
                let ok = by_id.get(&constant.spec_id()).is_some_and(|n| *n == name || sizes_workgroup);
                assert!(ok, "{kind} SPIR-V: constant_id {} is not {name}: {by_id:?}", constant.spec_id());
                checked += 1;
            }
        }
    }
    assert!(checked > 100, "{checked}");
}

/// The WGSL modules that evaluate or build self-collision declare its constants as the host
/// sizes and lays out their buffers: the lists' capacity, the near partners' reach, the copies
/// of the extents of the displacements, the directions they are measured along, and the contacts
/// a vertex is taken to share the layers' friction among.
#[test]
fn self_collision_constants_are_the_hosts() {
    let expected = [
        ("LIST_CAPACITY", cloth_gpu::layout::LIST_CAPACITY as i64),
        ("NEAR_REACH", cloth_core::self_collision::NEAR_REACH as i64),
        ("MOTION_COPIES", cloth_gpu::layout::MOTION_COPIES as i64),
        ("MOTION_DIRECTIONS", cloth_gpu::layout::MOTION_DIRECTIONS as i64),
        ("CONTACTS_PER_VERTEX", cloth_core::self_collision::CONTACTS_PER_VERTEX as i64),
    ];
    let mut checked = 0;
    for (file, source) in wgsl_modules().into_iter().filter(|(f, _)| !f.starts_with("render") && !f.contains("tiled")) {
        let module = naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{file}: {e}"));
        for (name, value) in expected {
            let (_, constant) = (module.constants.iter())
                .find(|(_, c)| c.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("{file}: no {name}"));
            let declared = match module.global_expressions[constant.init] {
                naga::Expression::Literal(naga::Literal::U32(n)) => n as i64,
                naga::Expression::Literal(naga::Literal::I32(n)) => n as i64,
                ref other => panic!("{file}: {name} is {other:?}"),
            };
            assert_eq!(declared, value, "{file}: {name}");
            checked += 1;
        }
    }
    assert_eq!(checked, 25, "five modules (step, XPBD, the hash, VBD, backward Euler), five constants");
}

/// The implicit integrators' constants are the host's, in both shading languages: VBD's friction
/// holds a vertex below the slip speed the CPU reference uses (`cloth_core::vbd::FRICTION_SLIP_SPEED`)
/// and holds the contact within the same band outside the surface (`cloth_core::vbd::CONTACT_BAND`),
/// backward Euler's linearisation floors the springs' transverse stiffness as the reference's does
/// (`cloth_core::implicit::TRANSVERSE_STIFFNESS_FLOOR`).
#[test]
fn implicit_constants_are_the_hosts() {
    let shaders = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders");
    for (wgsl, glsl_file, name, expected) in [
        (cloth_wgpu::VBD_SHADER, "vbd.comp", "FRICTION_SLIP_SPEED", cloth_core::vbd::FRICTION_SLIP_SPEED),
        (cloth_wgpu::VBD_SHADER, "vbd.comp", "CONTACT_BAND", cloth_core::vbd::CONTACT_BAND),
        (
            cloth_wgpu::IMPLICIT_SHADER,
            "implicit.comp",
            "TRANSVERSE_STIFFNESS_FLOOR",
            cloth_core::implicit::TRANSVERSE_STIFFNESS_FLOOR,
        ),
    ] {
        let expected = expected as f32;
        let module = naga::front::wgsl::parse_str(wgsl).unwrap();
        let (_, constant) = (module.constants.iter())
            .find(|(_, c)| c.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("the WGSL of {glsl_file} declares {name}"));
        match module.global_expressions[constant.init] {
            naga::Expression::Literal(naga::Literal::F32(v)) => assert_eq!(v, expected, "WGSL {name}"),
            ref other => panic!("WGSL: {name} is {other:?}"),
        }
        let glsl = std::fs::read_to_string(shaders.join("glsl").join(glsl_file)).expect(glsl_file);
        let line = (glsl.lines())
            .find(|l| l.contains(&format!("const float {name}")))
            .unwrap_or_else(|| panic!("{glsl_file} declares {name}"));
        let value: f32 =
            line.split('=').nth(1).and_then(|v| v.trim().trim_end_matches(';').parse().ok()).expect("a number");
        assert_eq!(value, expected, "{glsl_file}: {line}");
    }
}

/// The candidates pass of `self_hash` (both shading languages) shares its workgroup among the
/// vertices as the plan sizes its dispatch.
#[test]
fn candidate_listing_constants_are_the_hosts() {
    let expected = [
        ("LISTING_VERTICES", cloth_gpu::layout::LISTING_VERTICES),
        ("LISTING_LANES", cloth_gpu::layout::LISTING_LANES),
        ("LISTING_BLOCK", cloth_gpu::layout::LISTING_BLOCK),
    ];
    let module = naga::front::wgsl::parse_str(cloth_wgpu::SELF_HASH_SHADER).expect("self_hash.wgsl parses");
    let glsl = include_str!("../../shaders/glsl/self_hash.comp");
    for (name, value) in expected {
        let (_, constant) = (module.constants.iter())
            .find(|(_, c)| c.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("self_hash.wgsl: no {name}"));
        let declared = match module.global_expressions[constant.init] {
            naga::Expression::Literal(naga::Literal::U32(n)) => n,
            ref other => panic!("self_hash.wgsl: {name} is {other:?}"),
        };
        assert_eq!(declared, value, "self_hash.wgsl: {name}");
        let line = format!("const uint {name} = {value}u;");
        assert!(glsl.contains(&line), "self_hash.comp declares no `{line}`");
    }
}
