//! The WGSL structs must have the byte layout of cloth-core's `#[repr(C)]` types.

use std::mem::{offset_of, size_of};

use cloth_core::layout::{GpuSimParams, GpuSphere, GpuSpringEnd, GpuSpringRange};

/// `(member name, offset)` and span of a struct in the shader, via naga's reflection.
fn wgsl_struct(name: &str) -> (Vec<(String, u32)>, u32) {
    let module = naga::front::wgsl::parse_str(cloth_wgpu::STEP_SHADER).expect("the shader parses");
    for (_, ty) in module.types.iter() {
        if ty.name.as_deref() == Some(name)
            && let naga::TypeInner::Struct { members, span } = &ty.inner
        {
            return (members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect(), *span);
        }
    }
    panic!("struct {name} not found in cloth_step.wgsl");
}

fn check(name: &str, rust_size: usize, rust_fields: &[(&str, usize)]) {
    let (members, span) = wgsl_struct(name);
    assert_eq!(span as usize, rust_size, "{name}: WGSL size {span}, Rust size {rust_size}");
    assert_eq!(members.len(), rust_fields.len(), "{name}: member count");
    for ((wgsl_name, wgsl_offset), (rust_name, rust_offset)) in members.iter().zip(rust_fields) {
        assert_eq!(
            *wgsl_offset as usize, *rust_offset,
            "{name}.{wgsl_name} is at {wgsl_offset} in WGSL but {rust_name} is at {rust_offset} in Rust"
        );
        assert_eq!(wgsl_name.trim_start_matches('_'), rust_name.trim_start_matches('_'), "{name}: member order");
    }
}

#[test]
fn sim_params_layout_matches() {
    check(
        "SimParams",
        size_of::<GpuSimParams>(),
        &[
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
        ],
    );
}

#[test]
fn sphere_layout_matches() {
    check(
        "Sphere",
        size_of::<GpuSphere>(),
        &[
            ("center", offset_of!(GpuSphere, center)),
            ("radius", offset_of!(GpuSphere, radius)),
            ("stiffness", offset_of!(GpuSphere, stiffness)),
            ("friction", offset_of!(GpuSphere, friction)),
            ("damping", offset_of!(GpuSphere, damping)),
            ("pad", offset_of!(GpuSphere, _pad)),
        ],
    );
}

#[test]
fn spring_layouts_match() {
    check(
        "SpringRange",
        size_of::<GpuSpringRange>(),
        &[("first", offset_of!(GpuSpringRange, first)), ("count", offset_of!(GpuSpringRange, count))],
    );
    check(
        "SpringEnd",
        size_of::<GpuSpringEnd>(),
        &[
            ("other", offset_of!(GpuSpringEnd, other)),
            ("kind", offset_of!(GpuSpringEnd, kind)),
            ("rest_length", offset_of!(GpuSpringEnd, rest_length)),
            ("pad", offset_of!(GpuSpringEnd, _pad)),
        ],
    );
}

#[test]
fn every_effect_has_an_override_in_the_shader() {
    let module = naga::front::wgsl::parse_str(cloth_wgpu::STEP_SHADER).unwrap();
    let overrides: Vec<String> = module.overrides.iter().filter_map(|(_, o)| o.name.clone()).collect();
    for (name, _) in cloth_core::EffectSet::brief().shader_constants() {
        assert!(overrides.iter().any(|o| o == name), "no override {name} in cloth_step.wgsl: {overrides:?}");
    }
    assert!(overrides.iter().any(|o| o == "WORKGROUP_SIZE"));
}
