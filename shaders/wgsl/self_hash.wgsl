// Self-collision's check, and the rebuild of its spatial hash and candidate lists
// (cloth_core::self_collision; cloth_gpu::layout::SelfHashTable lays the buffers out):
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
// Prepended with layout.wgsl and self_collision.wgsl; no effect or collider constant applies, and
// the workgroup is the scan's block whatever the tuning's workgroup size.

// The pass (see above).
override HASH_PASS: u32 = 0u;

@group(0) @binding(0) var<uniform> params: SimParams;
// The state the rebuild lists: the positions at the start of the substep it comes before.
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read_write> self_words: array<u32>;
@group(0) @binding(4) var<storage, read_write> self_entries: array<vec4<u32>>;
@group(0) @binding(5) var<storage, read_write> self_control: SelfControl;
// The rebuild's passes' workgroups, which the check writes and their indirect dispatches read
// (the passes themselves bind a placeholder here: cloth_gpu::layout::REBUILD_PASSES).
@group(0) @binding(6) var<storage, read_write> self_dispatch: array<vec4<u32>, 5>;

var<workgroup> partial: array<u32, HASH_SCAN_BLOCK>;

// Inclusive prefix sum of `partial` across the workgroup (Hillis–Steele), returned for `local`.
fn workgroup_inclusive_scan(local: u32, value: u32) -> u32 {
    partial[local] = value;
    workgroupBarrier();
    var sum = value;
    for (var offset = 1u; offset < HASH_SCAN_BLOCK; offset = offset * 2u) {
        var before = 0u;
        if (local >= offset) {
            before = partial[local - offset];
        }
        workgroupBarrier();
        sum = sum + before;
        partial[local] = sum;
        workgroupBarrier();
    }
    return sum;
}

// Passes 5 and 6, one invocation (cloth_core::self_collision::{MotionBound, rebuild_due}).
fn check() {
    var bound = self_control.bound;
    let recorded = atomicLoad(&self_control.motion_high[0]) != 0u;
    if (recorded) {
        var extent = vec3<f32>(0.0);
        for (var k = 0u; k < 3u; k++) {
            let high = from_order_key(atomicLoad(&self_control.motion_high[k]));
            let low = from_order_key(~atomicLoad(&self_control.motion_low[k]));
            extent[k] = high - low;
        }
        bound += params.self_lists.z * sqrt(dot(extent, extent));
    }
    // (Written so that a bound that is not a number rebuilds.)
    let due = (HASH_PASS == 6u) | !(bound + params.self_lists.y <= params.self_lists.x);
    for (var k = 0u; k < 5u; k++) {
        self_dispatch[k] = select(vec4<u32>(0u), self_control.full[k], due);
    }
    if (due) {
        bound = 0.0;
        self_control.rebuilds += 1u;
    }
    self_control.bound = bound;
    self_control.checks += 1u;
    for (var k = 0u; k < 4u; k++) {
        atomicStore(&self_control.motion_high[k], 0u);
        atomicStore(&self_control.motion_low[k], 0u);
    }
}

// Pass 4: vertex i's position at the rebuild, and its candidates in increasing index (an
// insertion sort as they come); a vertex with more than LIST_CAPACITY keeps the count only, and
// counts in self_control.overflows.
fn list_candidates(i: u32) {
    let x0 = positions[i].xyz;
    self_entries[params.vertex_count + i] = vec4<u32>(bitcast<vec3<u32>>(x0), i);
    var list: array<u32, LIST_CAPACITY>;
    var count = 0u;
    let search = far_search(i, x0);
    for (var c = 0u; c < 27u; c++) {
        let cell = far_cell(search, c);
        for (var e = cell.first; e < cell.end; e++) {
            let j = far_candidate(search, cell, e);
            if (j == NO_VERTEX) {
                continue;
            }
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
    }
    let n = params.vertex_count;
    let counts_at = params.self_table.z;
    self_words[counts_at + i] = count;
    for (var k = 0u; k < min(count, LIST_CAPACITY); k++) {
        self_words[counts_at + n * (k + 1u) + i] = list[k];
    }
    if (count > LIST_CAPACITY) {
        atomicAdd(&self_control.overflows, 1u);
    }
}

@compute @workgroup_size(HASH_SCAN_BLOCK)
fn build(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
         @builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    let buckets = params.self_table.x;
    let block_sums = params.self_table.y;
    if (HASH_PASS >= 5u) {
        if (local == 0u) {
            check();
        }
        return;
    }
    if (HASH_PASS == 1u) {
        let b = group.x * HASH_SCAN_BLOCK + local;
        var count = 0u;
        if (b < buckets) {
            count = atomicLoad(&counts[b]);
        }
        let inclusive = workgroup_inclusive_scan(local, count);
        if (b < buckets) {
            self_words[b] = inclusive - count;
        }
        if (local == HASH_SCAN_BLOCK - 1u) {
            self_words[block_sums + group.x] = inclusive;
        }
        return;
    }
    if (HASH_PASS == 2u) {
        // One workgroup: each invocation sums a run of consecutive blocks, the runs are scanned,
        // and each invocation writes its run's exclusive sums.
        let blocks = params.self_table.w;
        let run = (blocks + HASH_SCAN_BLOCK - 1u) / HASH_SCAN_BLOCK;
        let first = local * run;
        let last = min(first + run, blocks);
        var total = 0u;
        for (var k = first; k < last; k++) {
            total += self_words[block_sums + k];
        }
        var running = workgroup_inclusive_scan(local, total) - total;
        for (var k = first; k < last; k++) {
            let value = self_words[block_sums + k];
            self_words[block_sums + k] = running;
            running += value;
        }
        return;
    }
    // Passes 0, 3 and 4: one invocation a vertex (more than 65535 workgroups spill into y).
    let i = id.y * groups.x * HASH_SCAN_BLOCK + id.x;
    if (i >= params.vertex_count) {
        return;
    }
    if (HASH_PASS == 4u) {
        list_candidates(i);
        return;
    }
    let x = positions[i].xyz;
    let b = hash_bucket(hash_cell(x));
    if (HASH_PASS == 0u) {
        atomicAdd(&counts[b], 1u);
        return;
    }
    let slot = bucket_start(b) + atomicSub(&counts[b], 1u) - 1u;
    self_entries[slot] = vec4<u32>(bitcast<vec3<u32>>(x), i);
}
