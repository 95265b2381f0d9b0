// Several semi-implicit Euler substeps in one dispatch, each workgroup on a tile of the grid in
// workgroup memory, one invocation per cell (temporal blocking; cloth_gpu::geometry says how and
// why). Prepended with common.wgsl and, by the backend, the tile's constants from
// cloth_gpu::geometry::TileConfig:
//   const TILE_WIDTH: u32;          cells along i, halo included
//   const TILE_HEIGHT: u32;         cells along j
//   const FUSED_SUBSTEPS: u32;      substeps per dispatch
// Each vertex's arithmetic is cloth_step.wgsl's with STAGE = 0, operation by operation (the
// springs, normal and state read from workgroup memory instead of the state buffers), so the
// result is the same to the bit.

const TILE_CELLS: u32 = TILE_WIDTH * TILE_HEIGHT;
// Cells each side of the output block: the bend springs reach two vertices a substep.
const HALO: u32 = 2u * FUSED_SUBSTEPS;

@group(0) @binding(0) var<uniform> params: SimParams;
@group(0) @binding(1) var<uniform> colliders: array<Collider, MAX_COLLIDERS>;
@group(0) @binding(2) var<storage, read> positions_in: array<vec4<f32>>;   // w: 1 free, minus its pin group pinned
@group(0) @binding(3) var<storage, read> velocities_in: array<vec4<f32>>;  // w: the state's time, s
@group(0) @binding(4) var<storage, read_write> positions_out: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> velocities_out: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> max_penetration_bits: atomic<u32>;
// The mesh colliders' distance fields (colliders.wgsl), m.
@group(0) @binding(7) var<storage, read> distance_fields: array<f32>;

// common.wgsl's grid_normal reads positions through this (this kernel computes its normals from
// the tile instead, below).
fn position_in(index: u32) -> vec3<f32> {
    return positions_in[index].xyz;
}

// The tile's state, one array per component (24 bytes a cell): cell c = a + b · TILE_WIDTH holds
// the grid vertex (a, b) cells from the tile's corner (the output block's corner less the halo).
var<workgroup> tile_px: array<f32, TILE_CELLS>;
var<workgroup> tile_py: array<f32, TILE_CELLS>;
var<workgroup> tile_pz: array<f32, TILE_CELLS>;
var<workgroup> tile_vx: array<f32, TILE_CELLS>;
var<workgroup> tile_vy: array<f32, TILE_CELLS>;
var<workgroup> tile_vz: array<f32, TILE_CELLS>;

fn tile_position(c: u32) -> vec3<f32> {
    return vec3<f32>(tile_px[c], tile_py[c], tile_pz[c]);
}

fn tile_velocity(c: u32) -> vec3<f32> {
    return vec3<f32>(tile_vx[c], tile_vy[c], tile_vz[c]);
}

fn set_tile_state(c: u32, x: vec3<f32>, v: vec3<f32>) {
    tile_px[c] = x.x;
    tile_py[c] = x.y;
    tile_pz[c] = x.z;
    tile_vx[c] = v.x;
    tile_vy[c] = v.y;
    tile_vz[c] = v.z;
}

// cloth_step.wgsl's add_spring, the neighbour read from the tile: (i, j) is cell c's vertex.
fn add_tile_spring(force: ptr<function, vec3<f32>>, c: u32, i: i32, j: i32, di: i32, dj: i32, kind: u32,
                   rest_length: f32, x: vec3<f32>, v: vec3<f32>) {
    let ni = i + di;
    let nj = j + dj;
    if (ni < 0 || nj < 0 || ni >= i32(params.grid_nx) || nj >= i32(params.grid_ny)) {
        return;
    }
    let other = u32(i32(c) + di + dj * i32(TILE_WIDTH));
    var damping = 0.0;
    if (EFFECT_SPRING_DAMPING) {
        damping = params.damping[kind];
    }
    add_spring_force(force, x, tile_position(other), v, tile_velocity(other),
                     rest_length, params.stiffness[kind], damping);
}

// cloth_step.wgsl's add_stencil_springs (same springs, same order), from the tile.
fn add_tile_springs(force: ptr<function, vec3<f32>>, c: u32, i: i32, j: i32, x: vec3<f32>, v: vec3<f32>) {
    let rest = params.rest_lengths;
    if (EFFECT_STRUCTURAL) {
        add_tile_spring(force, c, i, j, 0, -1, 0u, rest.y, x, v);
        add_tile_spring(force, c, i, j, -1, 0, 0u, rest.x, x, v);
        add_tile_spring(force, c, i, j, 1, 0, 0u, rest.x, x, v);
        add_tile_spring(force, c, i, j, 0, 1, 0u, rest.y, x, v);
    }
    if (EFFECT_SHEAR) {
        add_tile_spring(force, c, i, j, -1, -1, 1u, rest.z, x, v);
        add_tile_spring(force, c, i, j, 1, -1, 1u, rest.z, x, v);
        add_tile_spring(force, c, i, j, 1, 1, 1u, rest.z, x, v);
        add_tile_spring(force, c, i, j, -1, 1, 1u, rest.z, x, v);
    }
    if (EFFECT_BEND) {
        add_tile_spring(force, c, i, j, 0, -2, 2u, 2.0 * rest.y, x, v);
        add_tile_spring(force, c, i, j, -2, 0, 2u, 2.0 * rest.x, x, v);
        add_tile_spring(force, c, i, j, 2, 0, 2u, 2.0 * rest.x, x, v);
        add_tile_spring(force, c, i, j, 0, 2, 2u, 2.0 * rest.y, x, v);
    }
}

// common.wgsl's grid_normal, from the tile: one-sided at the grid's edges.
fn tile_normal(c: u32, i: i32, j: i32) -> vec3<f32> {
    let w = i32(TILE_WIDTH);
    var left = 0;
    if (i > 0) { left = -1; }
    var right = 0;
    if (i + 1 < i32(params.grid_nx)) { right = 1; }
    var down = 0;
    if (j > 0) { down = -w; }
    var up = 0;
    if (j + 1 < i32(params.grid_ny)) { up = w; }
    let along_u = tile_position(u32(i32(c) + right)) - tile_position(u32(i32(c) + left));
    let along_v = tile_position(u32(i32(c) + up)) - tile_position(u32(i32(c) + down));
    let n = cross(along_u, along_v);
    let length = sqrt(dot(n, n));
    if (length > 0.0) {
        return n * (1.0 / length);
    }
    return vec3<f32>(0.0);
}

@compute @workgroup_size(TILE_WIDTH, TILE_HEIGHT)
fn substeps(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_id) cell: vec3<u32>) {
    let nx = i32(params.grid_nx);
    let ny = i32(params.grid_ny);
    // This invocation's cell (a, b) of the tile, c in the tile's arrays, and its grid vertex
    // (i, j): the output block's corner less the halo (outside the grid at the grid's low edges;
    // such cells are never read, since the grid-edge checks come first).
    let a = cell.x;
    let b = cell.y;
    let c = a + b * TILE_WIDTH;
    let i = i32(group.x * (TILE_WIDTH - 2u * HALO) + a) - i32(HALO);
    let j = i32(group.y * (TILE_HEIGHT - 2u * HALO) + b) - i32(HALO);
    let in_grid = i >= 0 && j >= 0 && i < nx && j < ny;
    var index = 0u;
    var free_w = 0.0;   // 1 free, minus the pin group pinned
    var t = 0.0;      // the state's time, s
    if (in_grid) {
        index = u32(j) * params.grid_nx + u32(i);
        let p = positions_in[index];
        let state = velocities_in[index];
        set_tile_state(c, p.xyz, state.xyz);
        free_w = p.w;
        t = state.w;
    }
    workgroupBarrier();
    let dt = params.substep_dt;
    let mass = params.vertex_mass;
    // The output block: the cells at least HALO from the tile's edge (each vertex is in exactly
    // one output block).
    let is_output = in_grid && a >= HALO && b >= HALO && a < TILE_WIDTH - HALO && b < TILE_HEIGHT - HALO;
    var deepest = 0.0;
    for (var s = 1u; s <= FUSED_SUBSTEPS; s++) {
        // Exact after this substep: the cells at least 2s from the tile's edge.
        let lo = 2u * s;
        let is_active = in_grid && a >= lo && b >= lo && a < TILE_WIDTH - lo && b < TILE_HEIGHT - lo;
        var x_new = vec3<f32>(0.0);
        var v_new = vec3<f32>(0.0);
        if (is_active) {
            let x = tile_position(c);
            let v = tile_velocity(c);
            let t_out = t + dt;
            if (free_w > 0.0) {
                var force = vec3<f32>(0.0);
                if (EFFECT_GRAVITY) {
                    force += gravity_force(mass, params.gravity.xyz);
                }
                if (ANY_SPRINGS) {
                    add_tile_springs(&force, c, i, j, x, v);
                }
                if (EFFECT_AIR_DRAG) {
                    force += air_drag_force(mass, params.air_drag, v);
                }
                if (EFFECT_WIND) {
                    force += wind_force(tile_normal(c, i, j), v, wind_velocity(t), params.wind.w);
                }
                let other_forces = force;
                if (EFFECT_CONTACT) {
                    for (var n = 0u; n < params.collider_count; n++) {
                        let center = collider_center(n, t);
                        // The normal only for a vertex inside: outside, the distance alone.
                        let surface = collider_contact(n, center, x);
                        if (surface.distance >= 0.0) {
                            continue;
                        }
                        let v_rel = v - collider_velocity(n, t);
                        let contact = contact_force(v_rel, surface, colliders[n].stiffness, colliders[n].damping);
                        if (contact.hit) {
                            force += contact.force;
                            if (EFFECT_FRICTION) {
                                force += friction_force(other_forces, v_rel, contact.normal, mass, dt, colliders[n].friction);
                            }
                        }
                    }
                }
                // v_c = v_p + Δt R/m, x_c = x_p + Δt v_c (semi-implicit Euler).
                v_new = v + force * (dt / mass);
                x_new = x + v_new * dt;
            } else {
                // A pin stays put, or follows its group's motion (MovingPins) from t to t_out.
                let group = pin_group(free_w);
                x_new = pin_carry(group, x, t, t_out);
                v_new = pin_velocity(group, x_new, t_out);
            }
            t = t_out;
            // The deepest penetration at the end of each substep, over the output block.
            if (EFFECT_CONTACT) {
                if (is_output) {
                    for (var n = 0u; n < params.collider_count; n++) {
                        deepest = max(deepest, -collider_distance(n, collider_center(n, t_out), x_new));
                    }
                }
            }
        }
        workgroupBarrier();
        if (is_active) {
            set_tile_state(c, x_new, v_new);
        }
        workgroupBarrier();
    }
    if (is_output) {
        positions_out[index] = vec4<f32>(tile_position(c), free_w);
        velocities_out[index] = vec4<f32>(tile_velocity(c), t);
    }
    if (EFFECT_CONTACT) {
        if (deepest > 0.0) {
            atomicMax(&max_penetration_bits, bitcast<u32>(deepest));
        }
    }
}
