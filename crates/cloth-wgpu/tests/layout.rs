//! The WGSL structs must have the byte layout of cloth-core's `#[repr(C)]` types.

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

#[test]
fn every_shared_struct_has_the_core_layout() {
    for layout in cloth_core::layout::struct_layouts() {
        let name = layout.shader_name;
        let (members, span) = wgsl_struct(name);
        assert_eq!(span as usize, layout.size, "{name}: WGSL size {span}, Rust size {}", layout.size);
        let members: Vec<(&str, usize)> = members.iter().map(|(n, o)| (n.as_str(), *o as usize)).collect();
        assert_eq!(members, layout.fields, "{name}: WGSL members (left) against cloth-core's (right)");
    }
}

#[test]
fn every_effect_has_an_override_in_every_kernel() {
    for (file, source, stage) in
        [("cloth_step.wgsl", cloth_wgpu::STEP_SHADER, "STAGE"), ("xpbd.wgsl", cloth_wgpu::XPBD_SHADER, "XPBD_PASS")]
    {
        let module = naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{file}: {e}"));
        let overrides: Vec<String> = module.overrides.iter().filter_map(|(_, o)| o.name.clone()).collect();
        for (name, _) in cloth_core::EffectSet::brief().shader_constants() {
            assert!(overrides.iter().any(|o| o == name), "no override {name} in {file}: {overrides:?}");
        }
        assert!(overrides.iter().any(|o| o == "WORKGROUP_SIZE"), "{file}");
        assert!(overrides.iter().any(|o| o == stage), "{file}: no {stage}");
    }
}
