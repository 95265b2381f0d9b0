#version 450
// The copy kernel that measures a device's memory bandwidth (cloth_gpu::bandwidth): vec4 loads
// and stores in a grid-stride loop, the access pattern of a memory-bound substep at its best.

layout(local_size_x = 256) in;
layout(set = 0, binding = 0, std430) readonly buffer Source { vec4 source[]; };
layout(set = 0, binding = 1, std430) buffer Destination { vec4 destination[]; };

void main() {
    uint stride = gl_NumWorkGroups.x * 256u;
    uint n = uint(source.length());
    for (uint i = gl_GlobalInvocationID.x; i < n; i += stride) {
        destination[i] = source[i];
    }
}
