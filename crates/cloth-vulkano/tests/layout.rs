//! The GLSL structs, as compiled to SPIR-V, must have the byte layout of cloth-core's
//! `#[repr(C)]` types; the specialization constants must be the effects, in order.

use std::collections::HashMap;
use std::mem::{offset_of, size_of};

use cloth_core::layout::{GpuSimParams, GpuSphere, GpuSpringEnd, GpuSpringRange};

/// What the SPIR-V says about its types: a minimal reflection of the decorations we check
/// (naga's SPIR-V reader cannot read specialization-constant expressions, and this is short).
#[derive(Default)]
struct Reflection {
    /// Struct type id -> member names.
    member_names: HashMap<u32, Vec<(u32, String)>>,
    /// Struct type id -> member offsets.
    member_offsets: HashMap<u32, Vec<(u32, u32)>>,
    /// Struct type ids, in order of declaration.
    structs: Vec<u32>,
    /// Runtime-array type id -> element type id.
    array_element: HashMap<u32, u32>,
    /// Type id -> ArrayStride.
    array_stride: HashMap<u32, u32>,
    /// Result id -> OpName.
    names: HashMap<u32, String>,
    /// Result id -> SpecId.
    spec_ids: HashMap<u32, u32>,
}

fn string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).take_while(|b| *b != 0).collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

fn reflect() -> Reflection {
    let words: Vec<u32> =
        cloth_vulkano::STEP_SPIRV.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert_eq!(words[0], 0x0723_0203, "SPIR-V magic number");
    let mut r = Reflection::default();
    let mut i = 5;
    while i < words.len() {
        let (count, opcode) = ((words[i] >> 16) as usize, words[i] & 0xffff);
        let op = &words[i + 1..i + count];
        match opcode {
            5 => {
                r.names.insert(op[0], string(&op[1..]));
            }
            6 => r.member_names.entry(op[0]).or_default().push((op[1], string(&op[2..]))),
            71 if op[1] == 1 => {
                r.spec_ids.insert(op[0], op[2]);
            }
            71 if op[1] == 6 => {
                r.array_stride.insert(op[0], op[2]);
            }
            72 if op[2] == 35 => r.member_offsets.entry(op[0]).or_default().push((op[1], op[3])),
            29 => {
                r.array_element.insert(op[0], op[1]);
            }
            30 => r.structs.push(op[0]),
            _ => {}
        }
        i += count.max(1);
    }
    r
}

/// `(member name, offset)` of the laid-out struct whose first member is `first_member`, and its array
/// stride (its size) if it is the element of a runtime array.
fn spirv_struct(first_member: &str, member_count: usize) -> (Vec<(String, u32)>, Option<u32>) {
    let r = reflect();
    for id in &r.structs {
        let mut names = r.member_names.get(id).cloned().unwrap_or_default();
        names.sort();
        let mut offsets = r.member_offsets.get(id).cloned().unwrap_or_default();
        // Only the buffer-layout copy of a struct carries Offset decorations (a copy used for
        // function-local values has none).
        if names.len() == member_count
            && offsets.len() == member_count
            && names.first().map(|(_, n)| n.as_str()) == Some(first_member)
        {
            offsets.sort();
            let members = names.into_iter().zip(offsets).map(|((_, n), (_, o))| (n, o)).collect();
            let stride =
                r.array_element.iter().find(|(_, e)| *e == id).and_then(|(a, _)| r.array_stride.get(a)).copied();
            return (members, stride);
        }
    }
    panic!("no struct starting with member {first_member} in cloth_step.spv");
}

fn check(name: &str, first_member: &str, rust_size: usize, rust_fields: &[(&str, usize)], check_span: bool) {
    let (members, stride) = spirv_struct(first_member, rust_fields.len());
    if check_span {
        assert_eq!(stride, Some(rust_size as u32), "{name}: SPIR-V array stride {stride:?}, Rust size {rust_size}");
    }
    for ((spv_name, spv_offset), (rust_name, rust_offset)) in members.iter().zip(rust_fields) {
        assert_eq!(spv_name.trim_start_matches('_'), rust_name.trim_start_matches('_'), "{name}: member order");
        assert_eq!(
            *spv_offset as usize, *rust_offset,
            "{name}.{spv_name}: SPIR-V offset {spv_offset}, Rust {rust_offset}"
        );
    }
}

#[test]
fn sim_params_layout_matches() {
    // A uniform block's span is not recorded in SPIR-V beyond its last member: check offsets,
    // and that the last member ends at the Rust size.
    let fields = [
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
    ];
    check("SimParams", "gravity", size_of::<GpuSimParams>(), &fields, false);
    assert_eq!(offset_of!(GpuSimParams, effects) + 4, size_of::<GpuSimParams>());
}

#[test]
fn sphere_and_spring_layouts_match() {
    check(
        "Sphere",
        "center",
        size_of::<GpuSphere>(),
        &[
            ("center", offset_of!(GpuSphere, center)),
            ("radius", offset_of!(GpuSphere, radius)),
            ("stiffness", offset_of!(GpuSphere, stiffness)),
            ("friction", offset_of!(GpuSphere, friction)),
            ("damping", offset_of!(GpuSphere, damping)),
            ("pad", offset_of!(GpuSphere, _pad)),
        ],
        true,
    );
    check(
        "SpringRange",
        "first",
        size_of::<GpuSpringRange>(),
        &[("first", offset_of!(GpuSpringRange, first)), ("count", offset_of!(GpuSpringRange, count))],
        true,
    );
    check(
        "SpringEnd",
        "other",
        size_of::<GpuSpringEnd>(),
        &[
            ("other", offset_of!(GpuSpringEnd, other)),
            ("kind", offset_of!(GpuSpringEnd, kind)),
            ("rest_length", offset_of!(GpuSpringEnd, rest_length)),
            ("pad", offset_of!(GpuSpringEnd, _pad)),
        ],
        true,
    );
}

#[test]
fn specialization_constants_are_the_effects_in_order() {
    let r = reflect();
    let by_id: HashMap<u32, String> =
        r.spec_ids.iter().map(|(target, id)| (*id, r.names.get(target).cloned().unwrap_or_default())).collect();
    for (id, (name, _)) in cloth_core::EffectSet::brief().shader_constants().into_iter().enumerate() {
        assert_eq!(by_id.get(&(id as u32)).map(String::as_str), Some(name), "constant_id {id}: {by_id:?}");
    }
    assert!(
        by_id.contains_key(&cloth_vulkano::WORKGROUP_SIZE_CONSTANT_ID),
        "workgroup size is specializable: {by_id:?}"
    );
}
