// The copy kernel that measures a device's memory bandwidth (cloth_gpu::bandwidth): vec4 loads
// and stores in a grid-stride loop, the access pattern of a memory-bound substep at its best.

@group(0) @binding(0) var<storage, read> source: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> destination: array<vec4<f32>>;

@compute @workgroup_size(256)
fn copy(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let stride = groups.x * 256u;
    let n = arrayLength(&source);
    for (var i = id.x; i < n; i += stride) {
        destination[i] = source[i];
    }
}
