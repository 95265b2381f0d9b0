// Self-collision (cloth_core::self_collision, operation by operation): vertex pairs closer than
// the thickness r repel. Near partners (within NEAR_REACH grid steps) come from the grid, far
// partners from each vertex's candidate list, which self_hash.comp rebuilds when the check finds
// it may be stale (or, for a vertex with more than LIST_CAPACITY candidates, from the hash of
// that rebuild): the GLSL twin of shaders/wgsl/self_collision.wgsl. Included, after layout.glsl,
// by the kernels that evaluate or build it, which declare self_words and self_control and define
// link_words(at4), which reads the hash's words 4 at4 to 4 at4 + 3 in one load
// (cloth_gpu::layout::SelfHashTable, GpuSelfControl).
// Parameters in params.self_contact, params.self_hash, params.self_table and params.self_lists
// (cloth_gpu::layout::GpuSimParams).

// The most candidates a vertex keeps (cloth_core::self_collision::LIST_CAPACITY).
#define LIST_CAPACITY 32u
// Grid steps along i and j within which a pair are near partners (cloth_core::self_collision::NEAR_REACH).
#define NEAR_REACH 2
// No vertex: the end of a search.
#define NO_VERTEX 0xffffffffu
// The most other vertices one vertex is taken to touch at once
// (cloth_core::self_collision::CONTACTS_PER_VERTEX): the layers' friction gives each pair a share
// 1 / (2 CONTACTS_PER_VERTEX) of the force that stops its sliding.
#define CONTACTS_PER_VERTEX 8u
// The copies of the extents of the displacements in self_control that the workgroups of a
// kernel spread their atomics over (cloth_gpu::layout::MOTION_COPIES).
#define MOTION_COPIES 64u
// The directions the extents are measured along, params.motion_directions
// (cloth_gpu::layout::MOTION_DIRECTIONS).
#define MOTION_DIRECTIONS 13u

// The hash cell holding x: floor(x / h) per axis (cloth_core::self_collision::cell_of).
ivec3 hash_cell(vec3 x) {
    float inverse = 1.0 / params.self_hash.x;
    return ivec3(floor(x * inverse));
}

// The bucket of cell c: the coordinates times large primes, combined by exclusive or, in
// wrapping uint arithmetic, masked to the table's power-of-two size (bucket_of).
uint hash_bucket(ivec3 c) {
    uint h = (uint(c.x) * 73856093u) ^ (uint(c.y) * 19349663u) ^ (uint(c.z) * 83492791u);
    return h & (params.self_table.x - 1u);
}

// The first word of the table of heads the last rebuild filled: the rebuilds alternate between
// two (SelfHashTable). `rebuilds`: self_control.rebuilds, read once by the caller (every
// invocation reading it from the control's read-write buffer at every cell would all meet on one
// uncached word).
uint heads_of(uint rebuilds) {
    return (rebuilds & 1u) * params.self_table.x;
}

// The hash's word at `at`.
uint link(uint at) {
    return link_words(at >> 2u)[at & 3u];
}

// Vertex j's record, one 16-byte load: where it was at the last rebuild (the bits of three
// floats, m; record_position) and the vertex listed after it in its bucket (w; NO_VERTEX: none).
// A search walks a bucket's list record after record, each read once.
uvec4 hash_record(uint j) {
    return link_words((params.self_table.y >> 2u) + j);
}

vec3 record_position(uvec4 record) {
    return uintBitsToFloat(record.xyz);
}

// The distances from x to the low faces of its cell `base`, per axis, m (the high faces are h
// minus these): how far the neighbouring cells below and above are (hash_gaps in
// cloth_core::self_collision).
vec3 hash_gaps(vec3 x, ivec3 base) {
    return x - vec3(base) * params.self_hash.x;
}

// Whether the cell at offset d from x's comes nearer x than the cell side h: every vertex within
// h of x is in such a cell (cell_in_reach).
bool hash_cell_in_reach(vec3 below, ivec3 d) {
    float h = params.self_hash.x;
    vec3 above = vec3(h) - below;
    vec3 e = mix(vec3(0.0), below, lessThan(d, ivec3(0))) + mix(vec3(0.0), above, greaterThan(d, ivec3(0)));
    return dot(e, e) < h * h;
}

// The rest-distance filter for a grid offset (di, dj): (di Δu)² + (dj Δv)² ≥ r² (apart_at_rest,
// whose difference of coordinates is the offset).
bool offset_apart_at_rest(float di, float dj) {
    float du = di * params.self_hash.z;
    float dv = dj * params.self_hash.w;
    float r = params.self_contact.x;
    return du * du + dv * dv >= r * r;
}

// The near partner of the vertex at (vi, vj) at grid offset (di, dj): the vertex there if it is
// on the grid and apart at rest, NO_VERTEX otherwise (for_each_near_partner).
uint near_partner(uint vi, uint vj, int di, int dj) {
    // One off the grid on the low side wraps to a huge value: one comparison a coordinate.
    uint ni = uint(int(vi) + di);
    uint nj = uint(int(vj) + dj);
    if (ni >= params.grid_nx || nj >= params.grid_ny || !offset_apart_at_rest(float(di), float(dj))) {
        return NO_VERTEX;
    }
    return nj * params.grid_nx + ni;
}

// How many candidates vertex i listed at the last rebuild (more than LIST_CAPACITY: its list
// overflowed, and it reads the hash instead).
uint candidate_count(uint i) {
    return self_words[i];
}

// Vertex i's k-th candidate, in increasing index (slot-major: cloth_gpu::layout::SelfHashTable).
uint candidate(uint i, uint k) {
    return self_words[params.vertex_count * (k + 1u) + i];
}

// Where vertex j was at the last rebuild, m (the bits of three floats, the first words of j's
// record).
vec3 rebuild_position(uint j) {
    return record_position(hash_record(j));
}

// A search of the hash for the far partners of vertex i within the window r + W of x0, its
// position at the rebuild (far_partners, with the window as the hash's cell side): the 27 cells
// around x0's (far_cell), and the vertices each lists (far_candidate). A search is two loops:
//   for (uint k = 0u; k < 27u; k++) {
//       FarCell cell = far_cell(search, k);
//       uint j = cell.head;
//       while (j != NO_VERTEX) {
//           uvec4 record = hash_record(j);
//           if (far_candidate(search, cell, j, record)) { ... }
//           j = record.w;
//       }
//   }
struct FarSearch {
    // i's column and row.
    int ci;
    int cj;
    vec3 x0;
    ivec3 base;
    // The first word of the last rebuild's table of heads (heads_of).
    uint heads;
};

FarSearch far_search(uint i, vec3 x0, uint heads) {
    return FarSearch(int(i % params.grid_nx), int(i / params.grid_nx), x0, hash_cell(x0), heads);
}

// The k-th of the 27 cells around the search's (by z, y, x offset) and the first vertex its
// bucket lists: none where the cell does not come within the window of x0 (every vertex within it
// is in a cell that does).
struct FarCell {
    ivec3 cell;
    uint head;
};

FarCell far_cell(FarSearch search, uint k) {
    ivec3 offset = ivec3(int(k % 3u) - 1, int((k / 3u) % 3u) - 1, int(k / 9u) - 1);
    ivec3 cell = search.base + offset;
    if (!hash_cell_in_reach(hash_gaps(search.x0, search.base), offset)) {
        return FarCell(cell, NO_VERTEX);
    }
    return FarCell(cell, link(search.heads + hash_bucket(cell)));
}

// Whether vertex j (its record), listed in the cell's bucket, is a far partner of the search's
// vertex within the window (and in this cell: a bucket two cells share lists both). The distance
// first, the cheapest test that rejects most.
bool far_candidate(FarSearch search, FarCell cell, uint j, uvec4 record) {
    vec3 x_j = record_position(record);
    vec3 d = x_j - search.x0;
    float window = params.self_hash.x;
    if (dot(d, d) >= window * window) {
        return false;
    }
    int di = int(j % params.grid_nx) - search.ci;
    int dj = int(j / params.grid_nx) - search.cj;
    bool far = abs(di) > NEAR_REACH || abs(dj) > NEAR_REACH;
    return far && hash_cell(x_j) == cell.cell && offset_apart_at_rest(float(di), float(dj));
}

// The force on vertex i from vertex j, N: repulsion k_s (r − d) and approach damping along
// u = (x_i − x_j)/d, and the layers' friction, capped by Coulomb and by a share of the force that
// stops the sliding (repulsion_force).
vec3 repulsion_force(vec3 x_i, vec3 x_j, vec3 v_i, vec3 v_j, float mass, float dt) {
    float r = params.self_contact.x;
    vec3 delta = x_i - x_j;
    float d2 = dot(delta, delta);
    if (d2 >= r * r || d2 <= 0.0) {
        return vec3(0.0);
    }
    float d = sqrt(d2);
    vec3 u = delta * (1.0 / d);
    vec3 v_r = v_i - v_j;
    float approach = dot(v_r, u);
    float normal = params.self_contact.y * (r - d) - params.self_contact.z * min(approach, 0.0);
    vec3 force = u * normal;
    vec3 v_t = v_r - u * approach;
    float sliding = sqrt(dot(v_t, v_t));
    if (sliding > 0.0) {
        float stop = mass * sliding / (float(2u * CONTACTS_PER_VERTEX) * dt);
        force += v_t * (-(min(stop, params.self_contact.w * abs(normal)) / sliding));
    }
    return force;
}

// Whether x_i and x_j are closer than the thickness (and apart): the pairs that act.
bool in_contact(vec3 x_i, vec3 x_j) {
    float r = params.self_contact.x;
    vec3 delta = x_i - x_j;
    float d2 = dot(delta, delta);
    return d2 < r * r && d2 > 0.0;
}

// The speed limit's part on a substep's displacement from x_start: at most s_max Δt
// (limit_speed).
vec3 limit_step(vec3 x_start, vec3 x) {
    vec3 step_ = x - x_start;
    float reach = params.self_hash.y * params.substep_dt;
    float len = sqrt(dot(step_, step_));
    if (len > reach) {
        return x_start + step_ * (reach / len);
    }
    return x;
}

// The speed limit's part on a velocity: at most s_max (limit_speed).
vec3 limit_velocity(vec3 v) {
    float max_speed = params.self_hash.y;
    float speed = sqrt(dot(v, v));
    if (speed > max_speed) {
        return v * (max_speed / speed);
    }
    return v;
}

// The key of f whose unsigned order is the order of the numbers (order_key): the extents of
// the substep's displacements are kept with atomicMax on keys, and on inverted keys for the
// lowest projections.
uint order_key(float f) {
    uint bits = floatBitsToUint(f);
    return (bits & 0x80000000u) != 0u ? ~bits : bits | 0x80000000u;
}

// The number whose order_key is `key` (from_order_key).
float from_order_key(uint key) {
    return uintBitsToFloat((key & 0x80000000u) != 0u ? key & 0x7fffffffu : ~key);
}

// The workgroup's extents of displacements, as keys: the highest projection on each of the
// MOTION_DIRECTIONS, then the highest inverted ones (the lowest projections).
shared uint motion_keys[2u * MOTION_DIRECTIONS];

// Before a kernel that records the motion (uniform control flow): the workgroup's extents are
// empty.
void clear_motion(uint local_index) {
    if (local_index < 2u * MOTION_DIRECTIONS) {
        motion_keys[local_index] = 0u;
    }
    barrier();
}

// Adds a vertex's displacement over the substep (moved.xyz, m; moved.w 0 where the invocation
// has no vertex) to the workgroup's extents, and those to one of self_control's copies, chosen
// by the workgroup's index `group` (uniform control flow).
void record_motion(vec4 moved, uint local_index, uint group) {
    // (Each atomic maximum is skipped where it would change nothing: most invocations of a
    // cloth that moves as a whole.)
    if (moved.w != 0.0) {
        for (uint k = 0u; k < MOTION_DIRECTIONS; k++) {
            uint key = order_key(dot(moved.xyz, params.motion_directions[k].xyz));
            if (key > motion_keys[k]) {
                atomicMax(motion_keys[k], key);
            }
            if (~key > motion_keys[MOTION_DIRECTIONS + k]) {
                atomicMax(motion_keys[MOTION_DIRECTIONS + k], ~key);
            }
        }
    }
    barrier();
    if (local_index < 2u * MOTION_DIRECTIONS) {
        uint key = motion_keys[local_index];
        uint copy = group % MOTION_COPIES;
        if (key > self_control.motion[copy][local_index]) {
            atomicMax(self_control.motion[copy][local_index], key);
        }
    }
}
