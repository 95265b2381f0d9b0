#version 450
#extension GL_GOOGLE_include_directive : require

// The spatial hash of self-collision, rebuilt by counting sort in four dispatches
// (cloth_core::self_collision::CellHash builds the same table on the CPU):
//   0 count:   every vertex adds 1 to its bucket's count (atomic);
//   1 scan:    each workgroup turns HASH_SCAN_BLOCK counts into exclusive prefix sums within its
//              block, and writes the block's total;
//   2 sums:    one workgroup turns the block totals into exclusive prefix sums;
//   3 scatter: every vertex takes a slot of its bucket (counting the count back down to 0, so the
//              counts are zero again for the next rebuild) and writes its cell and index there.
// A bucket's entries then start at words[b] + words[block_sums + b / HASH_SCAN_BLOCK]
// (cloth_gpu::layout::SelfHashTable).

// The workgroup is the scan's block, whatever the tuning's workgroup size; no effect or collider
// constant applies (the parameters only, no colliders).
layout(local_size_x = 256) in;

// The pass: 0 count, 1 scan, 2 sums, 3 scatter.
layout(constant_id = 111) const uint HASH_PASS = 0u;

#define PARAMS_ONLY
#include "layout.glsl"
#include "self_collision.glsl"

// The state the hash lists: the positions at the start of the substep that rebuilds it.
layout(set = 0, binding = 1, std430) readonly buffer Positions { vec4 positions[]; };
layout(set = 0, binding = 2, std430) buffer Counts { uint counts[]; };
layout(set = 0, binding = 3, std430) buffer Words { uint words[]; };

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

void main() {
    uint local = gl_LocalInvocationIndex;
    uint buckets = params.self_table.x;
    uint block_sums = params.self_table.y;
    if (HASH_PASS == 1u) {
        uint b = gl_WorkGroupID.x * HASH_SCAN_BLOCK + local;
        uint count = b < buckets ? atomicAdd(counts[b], 0u) : 0u;
        uint inclusive = workgroup_inclusive_scan(local, count);
        if (b < buckets) {
            words[b] = inclusive - count;
        }
        if (local == HASH_SCAN_BLOCK - 1u) {
            words[block_sums + gl_WorkGroupID.x] = inclusive;
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
            total += words[block_sums + k];
        }
        uint running = workgroup_inclusive_scan(local, total) - total;
        for (uint k = first; k < last; k++) {
            uint value = words[block_sums + k];
            words[block_sums + k] = running;
            running += value;
        }
        return;
    }
    // Passes 0 and 3: one invocation a vertex (more than 65535 workgroups spill into y).
    uint i = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * HASH_SCAN_BLOCK + gl_GlobalInvocationID.x;
    if (i >= params.vertex_count) {
        return;
    }
    ivec3 c = hash_cell(positions[i].xyz);
    uint b = hash_bucket(c);
    if (HASH_PASS == 0u) {
        atomicAdd(counts[b], 1u);
        return;
    }
    uint slot = words[b] + words[block_sums + b / HASH_SCAN_BLOCK] + atomicAdd(counts[b], 0xffffffffu) - 1u;
    uint at = params.self_table.z + 4u * slot;
    words[at] = uint(c.x);
    words[at + 1u] = uint(c.y);
    words[at + 2u] = uint(c.z);
    words[at + 3u] = i;
}
