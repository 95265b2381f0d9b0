// The sum of `value` over the workgroup's invocations, in every invocation, by a tree in shared
// memory (uniform control flow): the dot products of backward Euler's conjugate gradients and the
// step lengths of VBD's multigrid correction (workgroup_sum.wgsl).
shared vec2 sums[1024];

vec2 workgroup_sum(vec2 value, uint local) {
    sums[local] = value;
    barrier();
    for (uint s = gl_WorkGroupSize.x / 2u; s > 0u; s = s / 2u) {
        if (local < s) {
            sums[local] = sums[local] + sums[local + s];
        }
        barrier();
    }
    vec2 total = sums[0];
    barrier();
    return total;
}
