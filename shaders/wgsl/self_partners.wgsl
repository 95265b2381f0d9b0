// The sum over a vertex's self-collision partners, written once for the force kernels
// (cloth_step.wgsl, implicit.wgsl, vbd.wgsl: the repulsions) and XPBD (xpbd.wgsl: the contact
// corrections), each of which defines the term of one pair:
//   fn pair_term(j: u32, c: PairContext) -> vec4<f32>
// Prepended after self_collision.wgsl.

// What a pair's term needs besides its partner j: vertex i's position x, m, and a vector and a
// number of the kernel's (cloth_step, implicit, vbd: i's velocity, m/s, and the friction's step,
// s; xpbd: i's position at the substep's start, m, and its inverse mass, 1/kg).
struct PairContext {
    x: vec3<f32>,
    a: vec3<f32>,
    s: f32,
}

// The sum of pair_term over vertex i's (at grid coordinates vi, vj) partners, in the reference's
// order: its near partners row by row, then its far partners, from its candidate list in
// increasing index, or from the hash where the list overflowed.
fn sum_over_partners(i: u32, vi: u32, vj: u32, c: PairContext) -> vec4<f32> {
    var sum = vec4<f32>(0.0);
    for (var dj = -NEAR_REACH; dj <= NEAR_REACH; dj++) {
        for (var di = -NEAR_REACH; di <= NEAR_REACH; di++) {
            let j = near_partner(vi, vj, di, dj);
            if (j != NO_VERTEX) {
                sum += pair_term(j, c);
            }
        }
    }
    let count = candidate_count(i);
    if (count <= LIST_CAPACITY) {
        for (var k = 0u; k < count; k++) {
            sum += pair_term(candidate(i, k), c);
        }
    } else {
        let search = far_search(i, rebuild_position(i), heads_of(self_control.rebuilds));
        for (var k = 0u; k < 27u; k++) {
            let cell = far_cell(search, k);
            var j = cell.head;
            while (j != NO_VERTEX) {
                let record = hash_record(j);
                if (far_candidate(search, cell, j, record)) {
                    sum += pair_term(j, c);
                }
                j = record.w;
            }
        }
    }
    return sum;
}
