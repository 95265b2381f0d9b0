// Self-collision (cloth_core::self_collision, operation by operation): vertex pairs closer than
// the thickness r repel. Near partners (within NEAR_REACH grid steps) come from the grid, far
// partners from each vertex's candidate list, which self_hash.wgsl rebuilds when the check finds
// it may be stale (or, for a vertex with more than LIST_CAPACITY candidates, from the hash of
// that rebuild). Prepended, after layout.wgsl, to the kernels that evaluate or build it, each of
// which declares self_words and self_control and defines link_words(at4), which reads the hash's
// words 4 at4 to 4 at4 + 3 in one load (cloth_gpu::layout::SelfHashTable, GpuSelfControl).
// Parameters in params.self_contact, params.self_hash, params.self_table and params.self_lists
// (cloth_gpu::layout::GpuSimParams).

// The most candidates a vertex keeps (cloth_core::self_collision::LIST_CAPACITY).
const LIST_CAPACITY: u32 = 32u;
// Grid steps along i and j within which a pair are near partners (cloth_core::self_collision::NEAR_REACH).
const NEAR_REACH: i32 = 2;
// No vertex: the end of a search.
const NO_VERTEX: u32 = 0xffffffffu;
// The most other vertices one vertex is taken to touch at once
// (cloth_core::self_collision::CONTACTS_PER_VERTEX): the layers' friction gives each pair a share
// 1 / (2 CONTACTS_PER_VERTEX) of the force that stops its sliding.
const CONTACTS_PER_VERTEX: u32 = 8u;

// The hash cell holding x: floor(x / h) per axis (cloth_core::self_collision::cell_of).
fn hash_cell(x: vec3<f32>) -> vec3<i32> {
    let inverse = 1.0 / params.self_hash.x;
    return vec3<i32>(floor(x * inverse));
}

// The bucket of cell c: the coordinates times large primes, combined by exclusive or, in
// wrapping u32 arithmetic, masked to the table's power-of-two size (bucket_of).
fn hash_bucket(c: vec3<i32>) -> u32 {
    let h = (u32(c.x) * 73856093u) ^ (u32(c.y) * 19349663u) ^ (u32(c.z) * 83492791u);
    return h & (params.self_table.x - 1u);
}

// The first word of the table of heads the last rebuild filled: the rebuilds alternate between
// two (SelfHashTable). `rebuilds`: self_control.rebuilds, read once by the caller (every
// invocation reading it from the control's read-write buffer at every cell would all meet on one
// uncached word).
fn heads_of(rebuilds: u32) -> u32 {
    return (rebuilds & 1u) * params.self_table.x;
}

// The hash's word at `at`.
fn link(at: u32) -> u32 {
    return link_words(at >> 2u)[at & 3u];
}

// Vertex j's record, one 16-byte load: where it was at the last rebuild (the bits of three f32,
// m; record_position) and the vertex listed after it in its bucket (w; NO_VERTEX: none). A
// search walks a bucket's list record after record, each read once.
fn hash_record(j: u32) -> vec4<u32> {
    return link_words((params.self_table.y >> 2u) + j);
}

fn record_position(record: vec4<u32>) -> vec3<f32> {
    return bitcast<vec3<f32>>(record.xyz);
}

// The distances from x to the low and the high faces of its cell `base`, per axis, m: how far
// the neighbouring cells below and above are (hash_gaps in cloth_core::self_collision).
struct HashGaps {
    below: vec3<f32>,
    above: vec3<f32>,
}

fn hash_gaps(x: vec3<f32>, base: vec3<i32>) -> HashGaps {
    let h = params.self_hash.x;
    let below = x - vec3<f32>(base) * h;
    return HashGaps(below, vec3<f32>(h) - below);
}

// Whether the cell at offset d (each −1, 0 or 1) from x's comes nearer x than the cell side h:
// every vertex within h of x is in such a cell (cell_in_reach).
fn hash_cell_in_reach(gaps: HashGaps, d: vec3<i32>) -> bool {
    let low = select(vec3<f32>(0.0), gaps.below, d < vec3<i32>(0));
    let high = select(vec3<f32>(0.0), gaps.above, d > vec3<i32>(0));
    let e = low + high;
    let h = params.self_hash.x;
    return dot(e, e) < h * h;
}

// The rest-distance filter for a grid offset (di, dj): (di Δu)² + (dj Δv)² ≥ r² (apart_at_rest,
// whose difference of coordinates is the offset).
fn offset_apart_at_rest(di: f32, dj: f32) -> bool {
    let du = di * params.self_hash.z;
    let dv = dj * params.self_hash.w;
    let r = params.self_contact.x;
    return du * du + dv * dv >= r * r;
}

// The near partner of vertex i at (vi, vj) at grid offset (di, dj): the vertex there if it is on
// the grid and apart at rest, NO_VERTEX otherwise (for_each_near_partner).
fn near_partner(vi: u32, vj: u32, di: i32, dj: i32) -> u32 {
    // One off the grid on the low side wraps to a huge value: one comparison a coordinate.
    let ni = u32(i32(vi) + di);
    let nj = u32(i32(vj) + dj);
    if ((ni >= params.grid_nx) | (nj >= params.grid_ny) | !offset_apart_at_rest(f32(di), f32(dj))) {
        return NO_VERTEX;
    }
    return nj * params.grid_nx + ni;
}

// How many candidates vertex i listed at the last rebuild (more than LIST_CAPACITY: its list
// overflowed, and it reads the hash instead).
fn candidate_count(i: u32) -> u32 {
    return self_words[i];
}

// Vertex i's k-th candidate, in increasing index (slot-major: cloth_gpu::layout::SelfHashTable).
fn candidate(i: u32, k: u32) -> u32 {
    return self_words[params.vertex_count * (k + 1u) + i];
}

// Where vertex j was at the last rebuild, m (the bits of three f32, the first words of j's record).
fn rebuild_position(j: u32) -> vec3<f32> {
    return record_position(hash_record(j));
}

// A search of the hash for the far partners of vertex i within the window r + W of x0, its
// position at the rebuild (far_partners, with the window as the hash's cell side): the 27 cells
// around x0's (far_cell), and the vertices each lists (far_candidate). A search is two loops:
//   for (var k = 0u; k < 27u; k++) {
//       let cell = far_cell(search, k);
//       var j = cell.head;
//       while (j != NO_VERTEX) {
//           let record = hash_record(j);
//           if (far_candidate(search, cell, j, record)) { ... }
//           j = record.w;
//       }
//   }
struct FarSearch {
    // i's column and row.
    ci: i32,
    cj: i32,
    x0: vec3<f32>,
    base: vec3<i32>,
    // The first word of the last rebuild's table of heads (heads_of).
    heads: u32,
}

fn far_search(i: u32, x0: vec3<f32>, heads: u32) -> FarSearch {
    return FarSearch(i32(i % params.grid_nx), i32(i / params.grid_nx), x0, hash_cell(x0), heads);
}

// The k-th of the 27 cells around the search's (by z, y, x offset) and the first vertex its
// bucket lists: none where the cell does not come within the window of x0 (every vertex within it
// is in a cell that does).
struct FarCell {
    cell: vec3<i32>,
    head: u32,
}

fn far_cell(search: FarSearch, k: u32) -> FarCell {
    let offset = vec3<i32>(i32(k % 3u) - 1, i32((k / 3u) % 3u) - 1, i32(k / 9u) - 1);
    let cell = search.base + offset;
    if (!hash_cell_in_reach(hash_gaps(search.x0, search.base), offset)) {
        return FarCell(cell, NO_VERTEX);
    }
    return FarCell(cell, link(search.heads + hash_bucket(cell)));
}

// Whether vertex j (its record), listed in the cell's bucket, is a far partner of the search's
// vertex within the window (and in this cell: a bucket two cells share lists both). The distance
// first, the cheapest test that rejects most.
fn far_candidate(search: FarSearch, cell: FarCell, j: u32, record: vec4<u32>) -> bool {
    let x_j = record_position(record);
    let d = x_j - search.x0;
    let window = params.self_hash.x;
    if (dot(d, d) >= window * window) {
        return false;
    }
    let di = i32(j % params.grid_nx) - search.ci;
    let dj = i32(j / params.grid_nx) - search.cj;
    let far = (abs(di) > NEAR_REACH) | (abs(dj) > NEAR_REACH);
    return far & all(hash_cell(x_j) == cell.cell) & offset_apart_at_rest(f32(di), f32(dj));
}

// The force on vertex i from vertex j, N: repulsion k_s (r − d) and approach damping along
// u = (x_i − x_j)/d, and the layers' friction, capped by Coulomb and by a share of the force that
// stops the sliding (repulsion_force).
fn repulsion_force(x_i: vec3<f32>, x_j: vec3<f32>, v_i: vec3<f32>, v_j: vec3<f32>, mass: f32,
                   dt: f32) -> vec3<f32> {
    let r = params.self_contact.x;
    let delta = x_i - x_j;
    let d2 = dot(delta, delta);
    if ((d2 >= r * r) | (d2 <= 0.0)) {
        return vec3<f32>(0.0);
    }
    let d = sqrt(d2);
    let u = delta * (1.0 / d);
    let v_r = v_i - v_j;
    let approach = dot(v_r, u);
    let normal = params.self_contact.y * (r - d) - params.self_contact.z * min(approach, 0.0);
    var force = u * normal;
    let v_t = v_r - u * approach;
    let sliding = sqrt(dot(v_t, v_t));
    if (sliding > 0.0) {
        let stop = mass * sliding / (f32(2u * CONTACTS_PER_VERTEX) * dt);
        force += v_t * (-(min(stop, params.self_contact.w * abs(normal)) / sliding));
    }
    return force;
}

// Whether x_i and x_j are closer than the thickness (and apart): the pairs that act.
fn in_contact(x_i: vec3<f32>, x_j: vec3<f32>) -> bool {
    let r = params.self_contact.x;
    let delta = x_i - x_j;
    let d2 = dot(delta, delta);
    return (d2 < r * r) & (d2 > 0.0);
}

// The speed limit's part on a substep's displacement from x_start: at most s_max Δt
// (limit_speed).
fn limit_step(x_start: vec3<f32>, x: vec3<f32>) -> vec3<f32> {
    let step = x - x_start;
    let reach = params.self_hash.y * params.substep_dt;
    let length = sqrt(dot(step, step));
    if (length > reach) {
        return x_start + step * (reach / length);
    }
    return x;
}

// The speed limit's part on a velocity: at most s_max (limit_speed).
fn limit_velocity(v: vec3<f32>) -> vec3<f32> {
    let max_speed = params.self_hash.y;
    let speed = sqrt(dot(v, v));
    if (speed > max_speed) {
        return v * (max_speed / speed);
    }
    return v;
}

// The key of f whose unsigned order is the order of the numbers (order_key): the extents of
// the substep's displacements are kept with atomicMax on keys, and on inverted keys for the
// lowest projections.
fn order_key(f: f32) -> u32 {
    let bits = bitcast<u32>(f);
    return select(bits | 0x80000000u, ~bits, (bits & 0x80000000u) != 0u);
}

// The number whose order_key is `key` (from_order_key).
fn from_order_key(key: u32) -> f32 {
    return bitcast<f32>(select(~key, key & 0x7fffffffu, (key & 0x80000000u) != 0u));
}

// The copies of the extents of the displacements in self_control that the workgroups of a
// kernel spread their atomics over (cloth_gpu::layout::MOTION_COPIES).
const MOTION_COPIES: u32 = 64u;
// The directions the extents are measured along, params.motion_directions
// (cloth_gpu::layout::MOTION_DIRECTIONS).
const MOTION_DIRECTIONS: u32 = 13u;

// The workgroup's extents of displacements, as keys: the highest projection on each of the
// MOTION_DIRECTIONS, then the highest inverted ones (the lowest projections).
var<workgroup> motion_keys: array<atomic<u32>, 26>;

// Before a kernel that records the motion (uniform control flow): the workgroup's extents are
// empty.
fn clear_motion(local: u32) {
    if (local < 2u * MOTION_DIRECTIONS) {
        atomicStore(&motion_keys[local], 0u);
    }
    workgroupBarrier();
}

// Adds a vertex's displacement over the substep (moved.xyz, m; moved.w 0 where the invocation
// has no vertex) to the workgroup's extents, and those to one of self_control's copies, chosen
// by the workgroup's index `group` (uniform control flow).
fn record_motion(moved: vec4<f32>, local: u32, group: u32) {
    // (Each atomic maximum is skipped where it would change nothing: most invocations of a
    // cloth that moves as a whole.)
    if (moved.w != 0.0) {
        for (var k = 0u; k < MOTION_DIRECTIONS; k++) {
            let key = order_key(dot(moved.xyz, params.motion_directions[k].xyz));
            if (key > atomicLoad(&motion_keys[k])) {
                atomicMax(&motion_keys[k], key);
            }
            if (~key > atomicLoad(&motion_keys[MOTION_DIRECTIONS + k])) {
                atomicMax(&motion_keys[MOTION_DIRECTIONS + k], ~key);
            }
        }
    }
    workgroupBarrier();
    if (local < 2u * MOTION_DIRECTIONS) {
        let key = atomicLoad(&motion_keys[local]);
        let slot = &self_control.motion[group % MOTION_COPIES][local];
        if (key > atomicLoad(slot)) {
            atomicMax(slot, key);
        }
    }
}
