// Self-collision's check, and the rebuild of its spatial hash and candidate lists
// (cloth_core::self_collision; cloth_gpu::layout::SelfHashTable lays the buffers out):
//   2 check:      one workgroup adds the relative motion the extents of the displacements since
//                 the last check allow to the bound on the relative motion since the rebuild, and sizes the two passes below:
//                 fully when the bound plus the lookahead reaches the margin (a rebuild, which
//                 flips the table of heads the rebuild fills), else zero;
//   3 forced:     the same, always rebuilding (the first substep, a written state);
//   0 insert:     every vertex writes its record (its position and link) and pushes itself onto its bucket's list
//                 (an atomic exchange of the bucket's head), and clears its share of the other
//                 table of heads, the one the next rebuild fills;
//   1 candidates: every vertex lists its far partners within the window r + W (the cell side),
//                 in increasing index;
//   4 candidates in lanes: the same, for a small grid: several invocations a vertex, each
//                 walking some of the cells it searches.
// Prepended with layout.wgsl and self_collision.wgsl; no effect or collider constant applies, and
// the workgroup holds 256 invocations whatever the tuning's workgroup size.

// The pass (see above).
override HASH_PASS: u32 = 0u;

@group(0) @binding(0) var<uniform> params: SimParams;
// The state the rebuild lists: the positions at the start of the substep it comes before.
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
// The hash's words (the heads, and each vertex's record: its position at the rebuild and its
// link), written by the insert pass and read by the candidates pass: each binds the buffer at its
// own binding and a placeholder at the other (a dispatch may not both write and read a buffer through two bindings).
@group(0) @binding(2) var<storage, read_write> self_links: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read> self_links_read: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read_write> self_words: array<u32>;
@group(0) @binding(5) var<storage, read_write> self_control: SelfControl;
// The rebuild's passes' workgroups, which the check writes and their indirect dispatches read
// (the passes themselves bind a placeholder here: cloth_gpu::layout::REBUILD_PASSES).
@group(0) @binding(6) var<storage, read_write> self_dispatch: array<vec4<u32>, 2>;

// The hash's words 4 at4 to 4 at4 + 3, as the candidates pass reads them (self_collision.wgsl).
fn link_words(at4: u32) -> vec4<u32> {
    return self_links_read[at4];
}

// The reduction of the copies of the extents of the displacements.
var<workgroup> extent_keys: array<atomic<u32>, 26>;
// The rebuilds so far, read once a workgroup (the insert and candidates passes).
var<workgroup> rebuilds_so_far: u32;
// Vertices the candidates pass lists a workgroup, and invocations a vertex
// (cloth_gpu::layout::{LISTING_VERTICES, LISTING_LANES}).
const LISTING_VERTICES: u32 = 28u;
// The side of the square block of vertices a workgroup of the candidates pass lists
// (cloth_gpu::layout::LISTING_BLOCK).
const LISTING_BLOCK: u32 = 16u;
const LISTING_LANES: u32 = 9u;
// The candidates pass's candidates of each of its vertices, as the lanes find them, and their counts.
var<workgroup> found: array<array<u32, LIST_CAPACITY>, LISTING_VERTICES>;
var<workgroup> found_count: array<atomic<u32>, LISTING_VERTICES>;

// Passes 2 and 3, one workgroup (cloth_core::self_collision::{MotionBound, rebuild_due}): the
// first MOTION_COPIES invocations gather the copies of the extents (and clear them), the first
// invocation decides.
fn check(local: u32) {
    if (local < 2u * MOTION_DIRECTIONS) {
        atomicStore(&extent_keys[local], 0u);
    }
    workgroupBarrier();
    if (local < MOTION_COPIES) {
        for (var k = 0u; k < 2u * MOTION_DIRECTIONS; k++) {
            let slot = &self_control.motion[local][k];
            atomicMax(&extent_keys[k], atomicLoad(slot));
            atomicStore(slot, 0u);
        }
    }
    workgroupBarrier();
    if (local != 0u) {
        return;
    }
    var bound = self_control.bound;
    if (atomicLoad(&extent_keys[0]) != 0u) {
        // relative_motion_bound: the box's diagonal, or the widest extent times its factor
        // (whichever is less; a diagonal that is not a number, from a displacement that is not,
        // stays).
        var box = vec3<f32>(0.0);
        var polytope = 0.0;
        for (var k = 0u; k < MOTION_DIRECTIONS; k++) {
            let high = from_order_key(atomicLoad(&extent_keys[k]));
            let extent = high - from_order_key(~atomicLoad(&extent_keys[MOTION_DIRECTIONS + k]));
            if (k < 3u) {
                box[k] = extent;
            }
            polytope = max(polytope, extent * params.motion_directions[k].w);
        }
        let diagonal = sqrt(dot(box, box));
        bound += params.self_lists.z * select(diagonal, polytope, polytope < diagonal);
    }
    // (Written so that a bound that is not a number rebuilds.)
    let due = (HASH_PASS == 3u) | !(bound + params.self_lists.y <= params.self_lists.x);
    for (var k = 0u; k < 2u; k++) {
        self_dispatch[k] = select(vec4<u32>(0u), self_control.full[k], due);
    }
    if (due) {
        bound = 0.0;
        self_control.rebuilds += 1u;
    }
    self_control.bound = bound;
    self_control.checks += 1u;
}

// Pass 0: vertex i's position at the rebuild, pushed onto its bucket's list in the table of
// heads of this rebuild (`rebuilds`: the rebuilds so far, this one counted); and its share of
// the other table cleared.
fn insert(i: u32, rebuilds: u32) {
    let buckets = params.self_table.x;
    let heads = heads_of(rebuilds);
    let other = heads_of(rebuilds + 1u);
    for (var b = i; b < buckets; b += params.vertex_count) {
        atomicStore(&self_links[other + b], NO_VERTEX);
    }
    let x = positions[i].xyz;
    let bits = bitcast<vec3<u32>>(x);
    let at = params.self_table.y + 4u * i;
    for (var k = 0u; k < 3u; k++) {
        atomicStore(&self_links[at + k], bits[k]);
    }
    let head = atomicExchange(&self_links[heads + hash_bucket(hash_cell(x))], i);
    atomicStore(&self_links[at + 3u], head);
}

// Pass 1: vertex i's candidates in increasing index (an insertion sort as they come); a vertex
// with more than LIST_CAPACITY keeps its first LIST_CAPACITY as found, which nothing reads (its
// count says it overflowed), and counts in self_control.overflows.
fn list_candidates(i: u32, rebuilds: u32) {
    var list: array<u32, LIST_CAPACITY>;
    var count = 0u;
    let search = far_search(i, rebuild_position(i), heads_of(rebuilds));
    for (var c = 0u; c < 27u; c++) {
        let cell = far_cell(search, c);
        var j = cell.head;
        while (j != NO_VERTEX) {
            let record = hash_record(j);
            if (far_candidate(search, cell, j, record)) {
                if (count < LIST_CAPACITY) {
                    var k = count;
                    while ((k > 0u) && (list[k - 1u] > j)) {
                        list[k] = list[k - 1u];
                        k -= 1u;
                    }
                    list[k] = j;
                }
                count += 1u;
            }
            j = record.w;
        }
    }
    let n = params.vertex_count;
    self_words[i] = count;
    for (var k = 0u; k < min(count, LIST_CAPACITY); k++) {
        self_words[n * (k + 1u) + i] = list[k];
    }
    if (count > LIST_CAPACITY) {
        atomicAdd(&self_control.overflows, 1u);
    }
}

// Pass 4: pass 1 for a small grid, whose vertices alone leave most of the GPU idle while each
// walks its lists record after record: LISTING_LANES invocations a vertex, each walking every
// LISTING_LANES-th of its 27 cells, LISTING_VERTICES vertices a workgroup. The lanes gather the
// vertex's candidates in `found` and write each at its rank, so the list is in increasing index
// (a vertex lies in one cell, so none comes twice). `group`: the workgroup's index (uniform
// control flow).
fn list_candidates_in_lanes(group: u32, local: u32, rebuilds: u32) {
    let slot = local / LISTING_LANES;
    let lane = local % LISTING_LANES;
    let i = group * LISTING_VERTICES + slot;
    let n = params.vertex_count;
    if ((lane == 0u) & (slot < LISTING_VERTICES)) {
        atomicStore(&found_count[slot], 0u);
    }
    workgroupBarrier();
    if ((i < n) & (slot < LISTING_VERTICES)) {
        let search = far_search(i, rebuild_position(i), heads_of(rebuilds));
        for (var c = lane; c < 27u; c += LISTING_LANES) {
            let cell = far_cell(search, c);
            var j = cell.head;
            while (j != NO_VERTEX) {
                let record = hash_record(j);
                if (far_candidate(search, cell, j, record)) {
                    let k = atomicAdd(&found_count[slot], 1u);
                    if (k < LIST_CAPACITY) {
                        found[slot][k] = j;
                    }
                }
                j = record.w;
            }
        }
    }
    workgroupBarrier();
    if ((i >= n) | (slot >= LISTING_VERTICES)) {
        return;
    }
    let count = atomicLoad(&found_count[slot]);
    if (lane == 0u) {
        self_words[i] = count;
        if (count > LIST_CAPACITY) {
            atomicAdd(&self_control.overflows, 1u);
        }
    }
    if (count > LIST_CAPACITY) {
        return;
    }
    for (var at = lane; at < count; at += LISTING_LANES) {
        let j = found[slot][at];
        var rank = 0u;
        for (var k = 0u; k < count; k++) {
            rank += select(0u, 1u, found[slot][k] < j);
        }
        self_words[n * (rank + 1u) + i] = j;
    }
}

@compute @workgroup_size(256)
fn build(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
         @builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    if ((HASH_PASS == 2u) | (HASH_PASS == 3u)) {
        check(local);
        return;
    }
    if (local == 0u) {
        rebuilds_so_far = self_control.rebuilds;
    }
    let rebuilds = workgroupUniformLoad(&rebuilds_so_far);
    // More than 65535 workgroups spill into y.
    if (HASH_PASS == 4u) {
        list_candidates_in_lanes(group.y * groups.x + group.x, local, rebuilds);
        return;
    }
    if (HASH_PASS == 1u) {
        // One invocation a vertex, a workgroup a block of LISTING_BLOCK × LISTING_BLOCK vertices,
        // whose searches walk overlapping cells (cloth_gpu::layout::LISTING_BLOCK).
        let g = group.y * groups.x + group.x;
        let blocks_along_i = (params.grid_nx + LISTING_BLOCK - 1u) / LISTING_BLOCK;
        let vi = (g % blocks_along_i) * LISTING_BLOCK + local % LISTING_BLOCK;
        let vj = (g / blocks_along_i) * LISTING_BLOCK + local / LISTING_BLOCK;
        if (vi >= params.grid_nx || vj >= params.grid_ny) {
            return;
        }
        list_candidates(vj * params.grid_nx + vi, rebuilds);
        return;
    }
    // One invocation a vertex.
    let i = id.y * groups.x * 256u + id.x;
    if (i >= params.vertex_count) {
        return;
    }
    insert(i, rebuilds);
}
