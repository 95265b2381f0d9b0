// The sum of `value` over the workgroup's invocations, in every invocation, by a tree in workgroup
// memory (uniform control flow): the dot products of backward Euler's conjugate gradients and the
// step lengths of VBD's multigrid correction.
var<workgroup> sums: array<vec2<f32>, 1024>;

fn workgroup_sum(value: vec2<f32>, local: u32) -> vec2<f32> {
    sums[local] = value;
    workgroupBarrier();
    for (var s = WORKGROUP_SIZE / 2u; s > 0u; s = s / 2u) {
        if (local < s) {
            sums[local] = sums[local] + sums[local + s];
        }
        workgroupBarrier();
    }
    let total = sums[0];
    workgroupBarrier();
    return total;
}
