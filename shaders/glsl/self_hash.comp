#version 450
#extension GL_GOOGLE_include_directive : require

// Self-collision's check, and the rebuild of its spatial hash and candidate lists
// (cloth_core::self_collision; cloth_gpu::layout::SelfHashTable lays the buffers out): the GLSL
// twin of shaders/wgsl/self_hash.wgsl.
//   5 check:      one invocation adds the box of the displacements since the last check to the
//                 bound on the relative motion since the rebuild, and sizes the five passes
//                 below: fully when the bound plus the lookahead reaches the margin, else zero;
//   6 forced:     the same, always rebuilding (the first substep, a written state);
//   0 count:      every vertex adds 1 to its bucket's count (atomic);
//   1 scan:       each workgroup turns HASH_SCAN_BLOCK counts into exclusive prefix sums within
//                 its block, and writes the block's total;
//   2 sums:       one workgroup turns the block totals into exclusive prefix sums;
//   3 scatter:    every vertex takes a slot of its bucket (counting the count back down to 0, so
//                 the counts are zero again for the next rebuild) and writes its position and
//                 index there;
//   4 candidates: every vertex writes its position and lists its far partners within the window
//                 r + W (the cell side), in increasing index.

// The workgroup is the scan's block, whatever the tuning's workgroup size; no effect or collider
// constant applies (the parameters only, no colliders).
layout(local_size_x = 256) in;

// The pass (see above).
layout(constant_id = 111) const uint HASH_PASS = 0u;

#define PARAMS_ONLY
#define SELF_COLLISION_BINDING 3
#define SELF_COLLISION_ACCESS
#include "layout.glsl"
#include "self_collision.glsl"

// The state the rebuild lists: the positions at the start of the substep it comes before.
layout(set = 0, binding = 1, std430) readonly buffer Positions { vec4 positions[]; };
layout(set = 0, binding = 2, std430) buffer Counts { uint counts[]; };
// The rebuild's passes' workgroups, which the check writes and their indirect dispatches read
// (the passes themselves bind a placeholder here: cloth_gpu::layout::REBUILD_PASSES).
layout(set = 0, binding = 6, std430) buffer SelfDispatch { uvec4 self_dispatch[5]; };

shared uint partial[HASH_SCAN_BLOCK];

// Inclusive prefix sum across the workgroup (Hillis–Steele), returned for `local`.
uint workgroup_inclusive_scan(uint local, uint value) {
    partial[local] = value;
    barrier();
    uint sum = value;
    for (uint offset = 1u; offset < HASH_SCAN_BLOCK; offset *= 2u) {
        uint before = local >= offset ? partial[local - offset] : 0u;
        barrier();
        sum += before;
        partial[local] = sum;
        barrier();
    }
    return sum;
}

// Passes 5 and 6, one invocation (cloth_core::self_collision::{MotionBound, rebuild_due}).
void check() {
    float bound = self_control.bound;
    if (self_control.motion_high[0] != 0u) {
        vec3 extent;
        for (uint k = 0u; k < 3u; k++) {
            extent[k] = from_order_key(self_control.motion_high[k]) - from_order_key(~self_control.motion_low[k]);
        }
        bound += params.self_lists.z * sqrt(dot(extent, extent));
    }
    // (Written so that a bound that is not a number rebuilds.)
    bool due = HASH_PASS == 6u || !(bound + params.self_lists.y <= params.self_lists.x);
    for (uint k = 0u; k < 5u; k++) {
        self_dispatch[k] = due ? self_control.full[k] : uvec4(0u);
    }
    if (due) {
        bound = 0.0;
        self_control.rebuilds += 1u;
    }
    self_control.bound = bound;
    self_control.checks += 1u;
    for (uint k = 0u; k < 4u; k++) {
        self_control.motion_high[k] = 0u;
        self_control.motion_low[k] = 0u;
    }
}

// Pass 4: vertex i's position at the rebuild, and its candidates in increasing index (an
// insertion sort as they come); a vertex with more than LIST_CAPACITY keeps the count only, and
// counts in self_control.overflows.
void list_candidates(uint i) {
    vec3 x0 = positions[i].xyz;
    self_entries[params.vertex_count + i] = uvec4(floatBitsToUint(x0), i);
    uint list[LIST_CAPACITY];
    uint count = 0u;
    FarSearch search = far_search(i, x0);
    for (uint c = 0u; c < 27u; c++) {
        FarCell cell = far_cell(search, c);
        for (uint e = cell.first; e < cell.end; e++) {
            uint j = far_candidate(search, cell, e);
            if (j == NO_VERTEX) {
                continue;
            }
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
    }
    uint n = params.vertex_count;
    uint counts_at = params.self_table.z;
    self_words[counts_at + i] = count;
    for (uint k = 0u; k < min(count, LIST_CAPACITY); k++) {
        self_words[counts_at + n * (k + 1u) + i] = list[k];
    }
    if (count > LIST_CAPACITY) {
        atomicAdd(self_control.overflows, 1u);
    }
}

void main() {
    uint local = gl_LocalInvocationIndex;
    uint buckets = params.self_table.x;
    uint block_sums = params.self_table.y;
    if (HASH_PASS >= 5u) {
        if (local == 0u) {
            check();
        }
        return;
    }
    if (HASH_PASS == 1u) {
        uint b = gl_WorkGroupID.x * HASH_SCAN_BLOCK + local;
        uint count = b < buckets ? atomicAdd(counts[b], 0u) : 0u;
        uint inclusive = workgroup_inclusive_scan(local, count);
        if (b < buckets) {
            self_words[b] = inclusive - count;
        }
        if (local == HASH_SCAN_BLOCK - 1u) {
            self_words[block_sums + gl_WorkGroupID.x] = inclusive;
        }
        return;
    }
    if (HASH_PASS == 2u) {
        // One workgroup: each invocation sums a run of consecutive blocks, the runs are scanned,
        // and each invocation writes its run's exclusive sums.
        uint blocks = params.self_table.w;
        uint run = (blocks + HASH_SCAN_BLOCK - 1u) / HASH_SCAN_BLOCK;
        uint first = local * run;
        uint last = min(first + run, blocks);
        uint total = 0u;
        for (uint k = first; k < last; k++) {
            total += self_words[block_sums + k];
        }
        uint running = workgroup_inclusive_scan(local, total) - total;
        for (uint k = first; k < last; k++) {
            uint value = self_words[block_sums + k];
            self_words[block_sums + k] = running;
            running += value;
        }
        return;
    }
    // Passes 0, 3 and 4: one invocation a vertex (more than 65535 workgroups spill into y).
    uint i = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * HASH_SCAN_BLOCK + gl_GlobalInvocationID.x;
    if (i >= params.vertex_count) {
        return;
    }
    if (HASH_PASS == 4u) {
        list_candidates(i);
        return;
    }
    vec3 x = positions[i].xyz;
    uint b = hash_bucket(hash_cell(x));
    if (HASH_PASS == 0u) {
        atomicAdd(counts[b], 1u);
        return;
    }
    uint slot = bucket_start(b) + atomicAdd(counts[b], 0xffffffffu) - 1u;
    self_entries[slot] = uvec4(floatBitsToUint(x), i);
}
