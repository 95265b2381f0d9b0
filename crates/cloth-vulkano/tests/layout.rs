//! The GLSL structs, as compiled to SPIR-V, must have the byte layout of cloth-core's
//! `#[repr(C)]` types; the specialization constants must be the effects, in order.

use std::collections::HashMap;

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

/// The kernels' SPIR-V modules, by file name.
const MODULES: [(&str, &[u8]); 2] =
    [("cloth_step.spv", cloth_vulkano::STEP_SPIRV), ("xpbd.spv", cloth_vulkano::XPBD_SPIRV)];

fn reflect(spirv: &[u8]) -> Reflection {
    let words: Vec<u32> = spirv.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
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
/// stride (its size) if it is the element of a runtime array, from the first module that has it.
fn spirv_struct(first_member: &str, member_count: usize) -> StructLayout {
    MODULES
        .iter()
        .find_map(|(_, spirv)| spirv_struct_in(&reflect(spirv), first_member, member_count))
        .unwrap_or_else(|| panic!("no struct starting with member {first_member} in any kernel"))
}

/// A struct's `(member name, offset)` list and its array stride, if any.
type StructLayout = (Vec<(String, u32)>, Option<u32>);

fn spirv_struct_in(r: &Reflection, first_member: &str, member_count: usize) -> Option<StructLayout> {
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
            return Some((members, stride));
        }
    }
    None
}

#[test]
fn every_shared_struct_has_the_core_layout() {
    for layout in cloth_core::layout::struct_layouts() {
        let name = layout.shader_name;
        let (members, stride) = spirv_struct(layout.fields[0].0, layout.fields.len());
        // Array elements carry their size as the array's stride; a uniform block has none (its
        // last member, a float or a vec4 in our blocks, must end where the Rust struct does).
        match stride {
            Some(stride) => assert_eq!(
                stride as usize, layout.size,
                "{name}: SPIR-V array stride {stride}, Rust size {}",
                layout.size
            ),
            None => {
                let last = layout.size - layout.fields.last().map(|f| f.1).unwrap_or(0);
                assert!(last == 4 || last == 16, "{name}: the last member ends the struct ({last} bytes after it)");
            }
        }
        let members: Vec<(&str, usize)> = members.iter().map(|(n, o)| (n.as_str(), *o as usize)).collect();
        assert_eq!(members, layout.fields, "{name}: SPIR-V members (left) against cloth-core's (right)");
    }
}

#[test]
fn specialization_constants_are_the_effects_in_order() {
    for (file, spirv) in MODULES {
        let r = reflect(spirv);
        let by_id: HashMap<u32, String> =
            r.spec_ids.iter().map(|(target, id)| (*id, r.names.get(target).cloned().unwrap_or_default())).collect();
        for (id, (name, _)) in cloth_core::EffectSet::brief().shader_constants().into_iter().enumerate() {
            assert_eq!(by_id.get(&(id as u32)).map(String::as_str), Some(name), "{file}: constant_id {id}: {by_id:?}");
        }
        assert!(
            by_id.contains_key(&cloth_vulkano::WORKGROUP_SIZE_CONSTANT_ID),
            "{file}: workgroup size is specializable: {by_id:?}"
        );
        assert!(by_id.contains_key(&cloth_vulkano::STAGE_CONSTANT_ID), "{file}: the pass is specializable: {by_id:?}");
    }
}
