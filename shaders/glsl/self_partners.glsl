// The sum over a vertex's self-collision partners, written once for the force kernels
// (cloth_step.comp, implicit.comp, vbd.comp: the repulsions) and XPBD (xpbd.comp: the contact
// corrections), each of which defines the term of one pair, after including this file:
//   vec4 pair_term(uint j, PairContext c)
// The GLSL twin of shaders/wgsl/self_partners.wgsl. Included after self_collision.glsl.

// What a pair's term needs besides its partner j: vertex i's position x, m, and a vector and a
// number of the kernel's (cloth_step, implicit, vbd: i's velocity, m/s, and the friction's step,
// s; xpbd: i's position at the substep's start, m, and its inverse mass, 1/kg).
struct PairContext {
    vec3 x;
    vec3 a;
    float s;
};

vec4 pair_term(uint j, PairContext c);

// The sum of pair_term over vertex i's (at grid coordinates vi, vj) partners, in the reference's
// order: its near partners row by row, then its far partners, from its candidate list in
// increasing index, or from the hash where the list overflowed.
vec4 sum_over_partners(uint i, uint vi, uint vj, PairContext c) {
    vec4 sum = vec4(0.0);
    for (int dj = -NEAR_REACH; dj <= NEAR_REACH; dj++) {
        for (int di = -NEAR_REACH; di <= NEAR_REACH; di++) {
            uint j = near_partner(vi, vj, di, dj);
            if (j != NO_VERTEX) {
                sum += pair_term(j, c);
            }
        }
    }
    uint count = candidate_count(i);
    if (count <= LIST_CAPACITY) {
        for (uint k = 0u; k < count; k++) {
            sum += pair_term(candidate(i, k), c);
        }
    } else {
        FarSearch search = far_search(i, rebuild_position(i), heads_of(self_control.rebuilds));
        for (uint k = 0u; k < 27u; k++) {
            FarCell cell = far_cell(search, k);
            uint j = cell.head;
            while (j != NO_VERTEX) {
                uvec4 record = hash_record(j);
                if (far_candidate(search, cell, j, record)) {
                    sum += pair_term(j, c);
                }
                j = record.w;
            }
        }
    }
    return sum;
}
