#version 450
#extension GL_GOOGLE_include_directive : require

// Self-collision's check, and the rebuild of its spatial hash and candidate lists
// (cloth_core::self_collision; cloth_gpu::layout::SelfHashTable lays the buffers out): the GLSL
// twin of shaders/wgsl/self_hash.wgsl.
//   2 check:      one workgroup adds the relative motion the extents of the displacements since
//                 the last check allow to the
//                 bound on the relative motion since the rebuild, and sizes the two passes below:
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

// 256 invocations, whatever the tuning's workgroup size; no effect or collider constant applies
// (the parameters only, no colliders).
layout(local_size_x = 256) in;

// The pass (see above).
layout(constant_id = 111) const uint HASH_PASS = 0u;

#define PARAMS_ONLY
#include "layout.glsl"

// The state the rebuild lists: the positions at the start of the substep it comes before.
layout(set = 0, binding = 1, std430) readonly buffer Positions { vec4 positions[]; };
// The hash's words (the heads, and each vertex's record: its position at the rebuild and its
// link), written by the insert pass and read by the candidates pass: each binds the buffer at its
// own binding and a placeholder at the other (a dispatch may not both write and read a buffer through two bindings).
layout(set = 0, binding = 2, std430) buffer SelfLinks { uint self_links[]; };
layout(set = 0, binding = 3, std430) readonly buffer SelfLinksRead { uvec4 self_links_read[]; };
layout(set = 0, binding = 4, std430) buffer SelfWords { uint self_words[]; };
layout(set = 0, binding = 5, std430) buffer SelfControlBuffer { SelfControl self_control; };
// The rebuild's passes' workgroups, which the check writes and their indirect dispatches read
// (the passes themselves bind a placeholder here: cloth_gpu::layout::REBUILD_PASSES).
layout(set = 0, binding = 6, std430) buffer SelfDispatch { uvec4 self_dispatch[2]; };

// The hash's words 4 at4 to 4 at4 + 3, as the candidates pass reads them (self_collision.glsl).
uvec4 link_words(uint at4) {
    return self_links_read[at4];
}

#include "self_collision.glsl"

// The reduction of the copies of the extents of the displacements.
shared uint extent_keys[2u * MOTION_DIRECTIONS];
// The rebuilds so far, read once a workgroup (the insert and candidates passes).
shared uint rebuilds_so_far;
// Vertices the candidates pass lists a workgroup, and invocations a vertex
// (cloth_gpu::layout::{LISTING_VERTICES, LISTING_LANES}).
const uint LISTING_VERTICES = 28u;
// The side of the square block of vertices a workgroup of the candidates pass lists
// (cloth_gpu::layout::LISTING_BLOCK).
const uint LISTING_BLOCK = 16u;
const uint LISTING_LANES = 9u;
// The candidates pass's candidates of each of its vertices, as the lanes find them, and their counts.
shared uint found[LISTING_VERTICES][LIST_CAPACITY];
shared uint found_count[LISTING_VERTICES];

// Passes 2 and 3, one workgroup (cloth_core::self_collision::{MotionBound, rebuild_due}): the
// first MOTION_COPIES invocations gather the copies of the extents (and clear them), the first
// invocation decides.
void check(uint local_index) {
    if (local_index < 2u * MOTION_DIRECTIONS) {
        extent_keys[local_index] = 0u;
    }
    barrier();
    if (local_index < MOTION_COPIES) {
        for (uint k = 0u; k < 2u * MOTION_DIRECTIONS; k++) {
            atomicMax(extent_keys[k], self_control.motion[local_index][k]);
            self_control.motion[local_index][k] = 0u;
        }
    }
    barrier();
    if (local_index != 0u) {
        return;
    }
    float bound = self_control.bound;
    if (extent_keys[0] != 0u) {
        // relative_motion_bound: the box's diagonal, or the widest extent times its factor
        // (whichever is less; a diagonal that is not a number, from a displacement that is not,
        // stays).
        vec3 box;
        float polytope = 0.0;
        for (uint k = 0u; k < MOTION_DIRECTIONS; k++) {
            float extent = from_order_key(extent_keys[k]) - from_order_key(~extent_keys[MOTION_DIRECTIONS + k]);
            if (k < 3u) {
                box[k] = extent;
            }
            polytope = max(polytope, extent * params.motion_directions[k].w);
        }
        float diagonal = sqrt(dot(box, box));
        bound += params.self_lists.z * (polytope < diagonal ? polytope : diagonal);
    }
    // (Written so that a bound that is not a number rebuilds.)
    bool due = HASH_PASS == 3u || !(bound + params.self_lists.y <= params.self_lists.x);
    for (uint k = 0u; k < 2u; k++) {
        self_dispatch[k] = due ? self_control.full[k] : uvec4(0u);
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
void insert(uint i, uint rebuilds) {
    uint buckets = params.self_table.x;
    uint heads = heads_of(rebuilds);
    uint other = heads_of(rebuilds + 1u);
    for (uint b = i; b < buckets; b += params.vertex_count) {
        self_links[other + b] = NO_VERTEX;
    }
    vec3 x = positions[i].xyz;
    uvec3 bits = floatBitsToUint(x);
    uint at = params.self_table.y + 4u * i;
    for (uint k = 0u; k < 3u; k++) {
        self_links[at + k] = bits[k];
    }
    uint head = atomicExchange(self_links[heads + hash_bucket(hash_cell(x))], i);
    self_links[at + 3u] = head;
}

// Pass 1: vertex i's candidates in increasing index (an insertion sort as they come); a vertex
// with more than LIST_CAPACITY keeps its first LIST_CAPACITY as found, which nothing reads (its
// count says it overflowed), and counts in self_control.overflows.
void list_candidates(uint i, uint rebuilds) {
    uint list[LIST_CAPACITY];
    uint count = 0u;
    FarSearch search = far_search(i, rebuild_position(i), heads_of(rebuilds));
    for (uint c = 0u; c < 27u; c++) {
        FarCell cell = far_cell(search, c);
        uint j = cell.head;
        while (j != NO_VERTEX) {
            uvec4 record = hash_record(j);
            if (far_candidate(search, cell, j, record)) {
                if (count < LIST_CAPACITY) {
                    uint k = count;
                    while (k > 0u && list[k - 1u] > j) {
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
    uint n = params.vertex_count;
    self_words[i] = count;
    for (uint k = 0u; k < min(count, LIST_CAPACITY); k++) {
        self_words[n * (k + 1u) + i] = list[k];
    }
    if (count > LIST_CAPACITY) {
        atomicAdd(self_control.overflows, 1u);
    }
}

// Pass 4: pass 1 for a small grid, LISTING_LANES invocations a vertex
// (self_hash.wgsl's list_candidates_in_lanes). `group`: the workgroup's index (uniform control
// flow).
void list_candidates_in_lanes(uint group, uint local_index, uint rebuilds) {
    uint slot = local_index / LISTING_LANES;
    uint lane = local_index % LISTING_LANES;
    uint i = group * LISTING_VERTICES + slot;
    uint n = params.vertex_count;
    if (lane == 0u && slot < LISTING_VERTICES) {
        found_count[slot] = 0u;
    }
    barrier();
    if (i < n && slot < LISTING_VERTICES) {
        FarSearch search = far_search(i, rebuild_position(i), heads_of(rebuilds));
        for (uint c = lane; c < 27u; c += LISTING_LANES) {
            FarCell cell = far_cell(search, c);
            uint j = cell.head;
            while (j != NO_VERTEX) {
                uvec4 record = hash_record(j);
                if (far_candidate(search, cell, j, record)) {
                    uint k = atomicAdd(found_count[slot], 1u);
                    if (k < LIST_CAPACITY) {
                        found[slot][k] = j;
                    }
                }
                j = record.w;
            }
        }
    }
    barrier();
    if (i >= n || slot >= LISTING_VERTICES) {
        return;
    }
    uint count = found_count[slot];
    if (lane == 0u) {
        self_words[i] = count;
        if (count > LIST_CAPACITY) {
            atomicAdd(self_control.overflows, 1u);
        }
    }
    if (count > LIST_CAPACITY) {
        return;
    }
    for (uint at = lane; at < count; at += LISTING_LANES) {
        uint j = found[slot][at];
        uint rank = 0u;
        for (uint k = 0u; k < count; k++) {
            rank += found[slot][k] < j ? 1u : 0u;
        }
        self_words[n * (rank + 1u) + i] = j;
    }
}

void main() {
    if (HASH_PASS == 2u || HASH_PASS == 3u) {
        check(gl_LocalInvocationIndex);
        return;
    }
    if (gl_LocalInvocationIndex == 0u) {
        rebuilds_so_far = self_control.rebuilds;
    }
    barrier();
    uint rebuilds = rebuilds_so_far;
    // More than maxComputeWorkGroupCount[0] workgroups spill into y.
    if (HASH_PASS == 4u) {
        list_candidates_in_lanes(gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x, gl_LocalInvocationIndex, rebuilds);
        return;
    }
    if (HASH_PASS == 1u) {
        // One invocation a vertex, a workgroup a block of LISTING_BLOCK × LISTING_BLOCK vertices,
        // whose searches walk overlapping cells (cloth_gpu::layout::LISTING_BLOCK).
        uint g = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
        uint local_index = gl_LocalInvocationIndex;
        uint blocks_along_i = (params.grid_nx + LISTING_BLOCK - 1u) / LISTING_BLOCK;
        uint vi = (g % blocks_along_i) * LISTING_BLOCK + local_index % LISTING_BLOCK;
        uint vj = (g / blocks_along_i) * LISTING_BLOCK + local_index / LISTING_BLOCK;
        if (vi >= params.grid_nx || vj >= params.grid_ny) {
            return;
        }
        list_candidates(vj * params.grid_nx + vi, rebuilds);
        return;
    }
    // One invocation a vertex.
    uint i = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 256u + gl_GlobalInvocationID.x;
    if (i >= params.vertex_count) {
        return;
    }
    insert(i, rebuilds);
}
