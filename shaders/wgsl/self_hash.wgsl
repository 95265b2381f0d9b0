// The spatial hash of self-collision, rebuilt by counting sort in four dispatches
// (cloth_core::self_collision::CellHash builds the same table on the CPU):
//   0 count:   every vertex adds 1 to its bucket's count (atomic);
//   1 scan:    each workgroup turns HASH_SCAN_BLOCK counts into exclusive prefix sums within its
//              block, and writes the block's total;
//   2 sums:    one workgroup turns the block totals into exclusive prefix sums;
//   3 scatter: every vertex takes a slot of its bucket (counting the count back down to 0, so the
//              counts are zero again for the next rebuild) and writes its cell and index there.
// A bucket's entries then start at words[b] + words[block_sums + b / HASH_SCAN_BLOCK]
// (cloth_gpu::layout::SelfHashTable). Prepended with layout.wgsl and self_collision.wgsl; no
// effect or collider constant applies, and the workgroup is the scan's block whatever the
// tuning's workgroup size.

// The pass: 0 count, 1 scan, 2 sums, 3 scatter.
override HASH_PASS: u32 = 0u;

@group(0) @binding(0) var<uniform> params: SimParams;
// The state the hash lists: the positions at the start of the substep that rebuilds it.
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read_write> words: array<u32>;

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

@compute @workgroup_size(HASH_SCAN_BLOCK)
fn build(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
         @builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    let buckets = params.self_table.x;
    let block_sums = params.self_table.y;
    if (HASH_PASS == 1u) {
        let b = group.x * HASH_SCAN_BLOCK + local;
        var count = 0u;
        if (b < buckets) {
            count = atomicLoad(&counts[b]);
        }
        let inclusive = workgroup_inclusive_scan(local, count);
        if (b < buckets) {
            words[b] = inclusive - count;
        }
        if (local == HASH_SCAN_BLOCK - 1u) {
            words[block_sums + group.x] = inclusive;
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
            total += words[block_sums + k];
        }
        var running = workgroup_inclusive_scan(local, total) - total;
        for (var k = first; k < last; k++) {
            let value = words[block_sums + k];
            words[block_sums + k] = running;
            running += value;
        }
        return;
    }
    // Passes 0 and 3: one invocation a vertex (more than 65535 workgroups spill into y).
    let i = id.y * groups.x * HASH_SCAN_BLOCK + id.x;
    if (i >= params.vertex_count) {
        return;
    }
    let c = hash_cell(positions[i].xyz);
    let b = hash_bucket(c);
    if (HASH_PASS == 0u) {
        atomicAdd(&counts[b], 1u);
        return;
    }
    let slot = words[b] + words[block_sums + b / HASH_SCAN_BLOCK] + atomicSub(&counts[b], 1u) - 1u;
    let at = params.self_table.z + 4u * slot;
    words[at] = bitcast<u32>(c.x);
    words[at + 1u] = bitcast<u32>(c.y);
    words[at + 2u] = bitcast<u32>(c.z);
    words[at + 3u] = i;
}
