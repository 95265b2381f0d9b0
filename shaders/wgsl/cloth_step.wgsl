// One substep of the mass-spring cloth under a force-based integrator: one invocation per
// vertex. Prepended with common.wgsl (constants, structs, force model).

// Which integration stage this pipeline runs: 0 semi-implicit Euler (the model's); 1 and 2 the
// two halves of velocity Verlet: 1 = kick and drift (v½ = v + ½Δt F(x, v)/m, x' = x + Δt v½),
// 2 = the second kick (v' = v½ + ½Δt F(x', v½)/m, positions untouched); 3 to 6 the four stages
// of classical Runge–Kutta, each evaluating a_k = F(x_k, v_k)/m at the state it reads:
//   3: x_2 = x + ½Δt v,   v_2 = v + ½Δt a_1    (stores x, v, Σx = v, Σv = a_1 in rk4_scratch)
//   4: x_3 = x + ½Δt v_2, v_3 = v + ½Δt a_2    (Σx += 2 v_2, Σv += 2 a_2)
//   5: x_4 = x + Δt v_3,  v_4 = v + Δt a_3     (Σx += 2 v_3, Σv += 2 a_3)
//   6: x' = x + Δt/6 (Σx + v_4), v' = v + Δt/6 (Σv + a_4); a vertex that friction holds at
//      this last stage's state sticks (its tangential motion over the substep is undone)
override STAGE: u32 = 0u;

@group(0) @binding(0) var<uniform> params: SimParams;
@group(0) @binding(1) var<uniform> colliders: array<Collider, MAX_COLLIDERS>;
// No spring list: the springs are computed from the grid (add_stencil_springs).
@group(0) @binding(2) var<storage, read> positions_in: array<vec4<f32>>;   // w: 1 free, minus its pin group pinned
@group(0) @binding(3) var<storage, read> velocities_in: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> positions_out: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> velocities_out: array<vec4<f32>>;
// Deepest penetration so far, m, as the bits of a non-negative f32 (whose bit patterns order
// like the numbers, so atomicMax on u32 is max on f32).
@group(0) @binding(6) var<storage, read_write> max_penetration_bits: atomic<u32>;
// RK4 only (a 64-byte placeholder otherwise): per vertex, the substep's start x and v and the
// running sums Σx and Σv, four vec4s. Each invocation touches only its own vertex's.
@group(0) @binding(7) var<storage, read_write> rk4_scratch: array<vec4<f32>>;

// Semi-implicit Euler's packed state (cloth_gpu::geometry; 64-byte placeholders for
// the other integrators): 24 bytes a vertex instead of 32, for the substeps inside a submission.
// The first substep of a submission reads the vec4 state above and writes the packed one, the
// ones between read and write the packed state, the last reads it and writes the vec4 state
// (PACKED_IN, PACKED_OUT): what the renderer and the read-backs see is the vec4 state.
//   packed_xv: (x, v.x) a vertex; packed_v: (v.y, v.z) a vertex, then one more element whose x
//   is the state's time, s (written by vertex 0's invocation); pin_bits: bit i % 32 of word
//   i / 32 set where vertex i is pinned (the vec4 state keeps that in positions.w).
@group(0) @binding(8) var<storage, read> packed_xv_in: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read> packed_v_in: array<vec2<f32>>;
@group(0) @binding(10) var<storage, read_write> packed_xv_out: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> packed_v_out: array<vec2<f32>>;
@group(0) @binding(12) var<storage, read> pin_bits: array<u32>;
// The mesh colliders' distance fields (colliders.wgsl), m.
@group(0) @binding(13) var<storage, read> distance_fields: array<f32>;
// Self-collision's candidate lists, its hash and its control (self_hash.wgsl; placeholders
// without SelfCollision).
@group(0) @binding(14) var<storage, read> self_words: array<u32>;
@group(0) @binding(15) var<storage, read> self_links: array<vec4<u32>>;
@group(0) @binding(16) var<storage, read_write> self_control: SelfControl;

// The hash's words 4 at4 to 4 at4 + 3 (self_collision.wgsl).
fn link_words(at4: u32) -> vec4<u32> {
    return self_links[at4];
}
// 1: this pipeline reads (PACKED_IN) or writes (PACKED_OUT) the packed state; STAGE 0 only.
override PACKED_IN: u32 = 0u;
override PACKED_OUT: u32 = 0u;

// The position of vertex `index` in the state read, m (common.wgsl's grid_normal reads it too).
fn position_in(index: u32) -> vec3<f32> {
    if (PACKED_IN != 0u) {
        return packed_xv_in[index].xyz;
    }
    return positions_in[index].xyz;
}

// The position (m) and velocity (m/s) of a vertex.
struct VertexState {
    x: vec3<f32>,
    v: vec3<f32>,
}

// The state of vertex `index` in the state read.
fn state_in(index: u32) -> VertexState {
    if (PACKED_IN != 0u) {
        let xv = packed_xv_in[index];
        return VertexState(xv.xyz, vec3<f32>(xv.w, packed_v_in[index]));
    }
    return VertexState(positions_in[index].xyz, velocities_in[index].xyz);
}

// Adds to `force` the spring from vertex (i, j) (buffer index `index`) to its grid neighbour
// (i + di, j + dj), if that neighbour exists: Hooke plus damping, with the kind's k and c_d and
// the given rest length. `interior`: (i, j) is two or more vertices from every edge, so every
// neighbour exists and its index is an offset from `index` (no edge checks; measured on the
// H100: docs/performance.md).
fn add_spring(force: ptr<function, vec3<f32>>, i: i32, j: i32, index: u32, interior: bool, di: i32, dj: i32,
              kind: u32, rest_length: f32, x: vec3<f32>, v: vec3<f32>) {
    var other = u32(i32(index) + dj * i32(params.grid_nx) + di);
    if (!interior) {
        // The neighbour's column and row as u32: one off the grid on the low side wraps to a
        // huge value, so one comparison a coordinate tests both sides (nx, ny < 2^31).
        let ni = u32(i + di);
        let nj = u32(j + dj);
        // (An early return, not a flag around the load below: with a flag every neighbour's
        // load sits under a condition and the NVIDIA driver's kernel was 6-8% slower on the
        // H100, docs/performance.md.)
        if ((ni >= params.grid_nx) | (nj >= params.grid_ny)) {
            return;
        }
        other = nj * params.grid_nx + ni;
    }
    var damping = 0.0;
    if (EFFECT_SPRING_DAMPING) {
        damping = params.damping[kind];
    }
    let neighbour = state_in(other);
    add_spring_force(force, x, neighbour.x, v, neighbour.v, rest_length, params.stiffness[kind], damping);
}

// The spring forces on vertex `index`, from its grid neighbours: the springs are a stencil of the
// grid (no spring list is read; rest lengths from params.rest_lengths). They are added in the
// order of the CPU reference's per-vertex spring list (cloth_core::model::Adjacency), so the sums
// round alike: kind by kind, and within a kind the springs from lower-indexed vertices first:
// structural (0,−1) (−1,0) (+1,0) (0,+1); shear (−1,−1) (+1,−1) (+1,+1) (−1,+1); bend (0,−2)
// (−2,0) (+2,0) (0,+2).
fn add_stencil_springs(force: ptr<function, vec3<f32>>, i: i32, j: i32, index: u32, x: vec3<f32>, v: vec3<f32>) {
    // (`&` and `|` rather than `&&` and `||` here, in add_spring and in substep: naga turns each
    // short-circuit operator into a branch, and from the operators without branches the NVIDIA
    // driver compiles a faster kernel: 1024² and 2048² × 64 substeps 0.9% and 1.0% faster on the
    // H100, docs/performance.md. The operands have no side effects, so the results are the same.)
    let interior = (i >= 2) & (j >= 2) & (i + 2 < i32(params.grid_nx)) & (j + 2 < i32(params.grid_ny));
    let rest = params.rest_lengths;
    if (EFFECT_STRUCTURAL) {
        add_spring(force, i, j, index, interior, 0, -1, 0u, rest.y, x, v);
        add_spring(force, i, j, index, interior, -1, 0, 0u, rest.x, x, v);
        add_spring(force, i, j, index, interior, 1, 0, 0u, rest.x, x, v);
        add_spring(force, i, j, index, interior, 0, 1, 0u, rest.y, x, v);
    }
    if (EFFECT_SHEAR) {
        add_spring(force, i, j, index, interior, -1, -1, 1u, rest.z, x, v);
        add_spring(force, i, j, index, interior, 1, -1, 1u, rest.z, x, v);
        add_spring(force, i, j, index, interior, 1, 1, 1u, rest.z, x, v);
        add_spring(force, i, j, index, interior, -1, 1, 1u, rest.z, x, v);
    }
    if (EFFECT_BEND) {
        add_spring(force, i, j, index, interior, 0, -2, 2u, 2.0 * rest.y, x, v);
        add_spring(force, i, j, index, interior, -2, 0, 2u, 2.0 * rest.x, x, v);
        add_spring(force, i, j, index, interior, 2, 0, 2u, 2.0 * rest.x, x, v);
        add_spring(force, i, j, index, interior, 0, 2, 2u, 2.0 * rest.y, x, v);
    }
}

// The repulsion of vertex j on free vertex i at x moving at v, N (its velocity read only for a
// pair in contact).
fn self_repulsion(j: u32, x: vec3<f32>, v: vec3<f32>, friction_dt: f32) -> vec3<f32> {
    let x_j = position_in(j);
    if (!in_contact(x, x_j)) {
        return vec3<f32>(0.0);
    }
    return repulsion_force(x, x_j, v, state_in(j).v, params.vertex_mass, friction_dt);
}

// The self-collision term of partner j (self_partners.wgsl): its repulsion on free vertex i at
// c.x moving at c.a, with the friction's step c.s.
fn pair_term(j: u32, c: PairContext) -> vec4<f32> {
    return vec4<f32>(self_repulsion(j, c.x, c.a, c.s), 0.0);
}

// The self-collision force on free vertex i at (vi, vj), at x moving at v, N: the repulsion of
// every partner (sum_over_partners, in cloth_core::reference's self_collision_force's order).
fn self_collision_force(i: u32, vi: u32, vj: u32, x: vec3<f32>, v: vec3<f32>, friction_dt: f32) -> vec3<f32> {
    return sum_over_partners(i, vi, vj, PairContext(x, v, friction_dt)).xyz;
}

// Vertices along i of the block of the grid one workgroup updates (GpuTuning::
// block_width): a workgroup updates BLOCK_WIDTH × (WORKGROUP_SIZE / BLOCK_WIDTH) vertices, so
// the rows its springs reach are mostly its own (L1 hits). 0: WORKGROUP_SIZE vertices of a row.
override BLOCK_WIDTH: u32 = 0u;
// 1: the workgroups take the grid's blocks last first (BLOCK_WIDTH != 0 only). Semi-implicit
// Euler's packed passes alternate the order from substep to substep
// (cloth_gpu::geometry::alternates_order), so each substep starts on the blocks the one before
// wrote last, which the L2 cache still holds.
override REVERSED_ORDER: u32 = 0u;

@compute @workgroup_size(WORKGROUP_SIZE)
fn substep(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
           @builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    if (EFFECT_SELF_COLLISION) {
        clear_motion(local);
    }
    let moved = advance_vertex(id, groups, group, local);
    if (EFFECT_SELF_COLLISION) {
        // The extents of the substep's displacements along the motion directions, which the next
        // check turns into its bound.
        record_motion(moved, local, group.y * groups.x + group.x);
    }
}

// Advances the invocation's vertex; returns its displacement over the substep where this stage
// ends one (w 1), zero otherwise (w 0: another stage, or no vertex).
fn advance_vertex(id: vec3<u32>, groups: vec3<u32>, group: vec3<u32>, local: u32) -> vec4<f32> {
    // The vertex's index and grid coordinates.
    var i: u32;
    var vi: u32;
    var vj: u32;
    if (BLOCK_WIDTH != 0u) {
        // One workgroup per block, the workgroup grid the grid's blocks (cloth_gpu::
        // geometry::BlockGrid): the workgroup id is the block's column and row, no division needed.
        // (max: no constant division by zero where the pipeline has BLOCK_WIDTH = 0.)
        let width = max(BLOCK_WIDTH, 1u);
        var block = group.xy;
        if (REVERSED_ORDER != 0u) {
            block = groups.xy - 1u - block;
        }
        vi = block.x * width + local % width;
        vj = block.y * (WORKGROUP_SIZE / width) + local / width;
        if ((vi >= params.grid_nx) | (vj >= params.grid_ny)) {
            return vec4<f32>(0.0);
        }
        i = vj * params.grid_nx + vi;
    } else {
        // 2D dispatch: more than 65535 workgroups spill into y.
        i = id.y * groups.x * WORKGROUP_SIZE + id.x;
        if (i >= params.vertex_count) {
            return vec4<f32>(0.0);
        }
        vi = i % params.grid_nx;
        vj = i / params.grid_nx;
    }
    let own = state_in(i);
    let x = own.x;
    let v = own.v;
    // Whether the vertex moves freely (positions.w, or its pin bit), and the time of the state
    // read (velocities.w, or the packed state's clock) and of the state written.
    // The packed state has no pin groups (cloth_gpu::plan keeps a scene with several on the vec4
    // state), so its pins are group 0.
    var free_vertex: bool;
    var w_in: f32;
    var t: f32;
    if (PACKED_IN != 0u) {
        free_vertex = (pin_bits[i >> 5u] & (1u << (i & 31u))) == 0u;
        w_in = select(0.0, 1.0, free_vertex);
        t = packed_v_in[params.vertex_count].x;
    } else {
        w_in = positions_in[i].w;
        free_vertex = w_in > 0.0;
        t = velocities_in[i].w;
    }
    let dt = params.substep_dt;
    let half = dt * 0.5;
    var t_out = t + dt;       // Euler, Verlet's kick and drift
    if (STAGE == 2u || STAGE == 4u || STAGE == 6u) {
        t_out = t;            // Verlet's second kick; RK4's second and fourth stages (same time)
    }
    if (STAGE == 3u) {
        t_out = t + half;     // RK4's first stage
    }
    if (STAGE == 3u) {
        // RK4's first stage keeps the substep's start time for the third (every vertex).
        rk4_scratch[4u * i] = vec4<f32>(x, t);
    }
    if (STAGE == 5u) {
        t_out = rk4_scratch[4u * i].w + dt; // RK4's third stage: the substep's end
    }
    var x_new = x;
    var v_new = vec3<f32>(0.0);
    if (free_vertex) {
        let mass = params.vertex_mass;
        // The step the friction's stopping term refers to: what this stage's velocity update spans.
        var friction_dt = dt;
        if (STAGE == 1u || STAGE == 2u) {
            friction_dt = half;
        }
        var force = vec3<f32>(0.0);
        if (EFFECT_GRAVITY) {
            force += gravity_force(mass, params.gravity.xyz);
        }
        if (ANY_SPRINGS) {
            add_stencil_springs(&force, i32(vi), i32(vj), i, x, v);
        }
        if (EFFECT_AIR_DRAG) {
            force += air_drag_force(mass, params.air_drag, v);
        }
        if (EFFECT_WIND) {
            force += wind_force(grid_normal(i), v, wind_velocity(t), params.wind.w);
        }
        if (EFFECT_SELF_COLLISION) {
            force += self_collision_force(i, vi, vj, x, v, friction_dt);
        }
        // Against a moving collider, contact and friction act on the velocity relative to it.
        let other_forces = force;
        // RK4's last stage: the normal of a contact whose friction holds the vertex (it sticks).
        var stuck = false;
        var stick_normal = vec3<f32>(0.0);
        if (EFFECT_CONTACT) {
            for (var s = 0u; s < params.collider_count; s++) {
                let center = collider_center(s, t);
                // The normal only for a vertex inside: outside, the distance alone.
                let surface = collider_contact(s, center, x);
                if (surface.distance >= 0.0) {
                    continue;
                }
                let v_rel = v - collider_velocity(s, t);
                let c = contact_force(v_rel, surface, colliders[s].stiffness, colliders[s].damping);
                if (c.hit) {
                    force += c.force;
                    if (EFFECT_FRICTION) {
                        force += friction_force(other_forces, v_rel, c.normal, mass, friction_dt, colliders[s].friction);
                        if (STAGE == 6u && !stuck
                            && friction_holds(other_forces, v_rel, c.normal, mass, friction_dt, colliders[s].friction)) {
                            stuck = true;
                            stick_normal = c.normal;
                        }
                    }
                }
            }
        }
        if (STAGE == 0u) {
            // v_c = v_p + Δt R/m, x_c = x_p + Δt v_c (semi-implicit Euler).
            v_new = v + force * (dt / mass);
            x_new = x + v_new * dt;
            if (EFFECT_SELF_COLLISION) {
                // The speed limit (self_collision.wgsl), on the substep's end.
                x_new = limit_step(x, x_new);
                v_new = limit_velocity(v_new);
            }
        } else if (STAGE <= 2u) {
            // Verlet: a half kick, then (stage 1) a full drift.
            v_new = v + force * (half / mass);
            if (STAGE == 1u) {
                x_new = x + v_new * dt;
                if (EFFECT_SELF_COLLISION) {
                    x_new = limit_step(x, x_new);
                }
            } else if (EFFECT_SELF_COLLISION) {
                v_new = limit_velocity(v_new);
            }
        } else {
            // RK4 (see STAGE above): x, v here are the stage's state x_k, v_k.
            let a = force * (1.0 / mass);
            let slot = 4u * i;
            if (STAGE == 3u) {
                rk4_scratch[slot] = vec4<f32>(x, t);
                rk4_scratch[slot + 1u] = vec4<f32>(v, 0.0);
                rk4_scratch[slot + 2u] = vec4<f32>(v, 0.0);
                rk4_scratch[slot + 3u] = vec4<f32>(a, 0.0);
                x_new = x + v * half;
                v_new = v + a * half;
            } else {
                let x_start = rk4_scratch[slot].xyz;
                let v_start = rk4_scratch[slot + 1u].xyz;
                let sum_x = rk4_scratch[slot + 2u].xyz;
                let sum_v = rk4_scratch[slot + 3u].xyz;
                if (STAGE == 6u) {
                    let sixth = dt / 6.0;
                    x_new = x_start + (sum_x + v) * sixth;
                    v_new = v_start + (sum_v + a) * sixth;
                    if (stuck) {
                        // Static friction: no tangential motion over the substep.
                        let d = x_new - x_start;
                        x_new = x_new - (d - stick_normal * dot(d, stick_normal));
                        v_new = stick_normal * dot(v_new, stick_normal);
                    }
                    if (EFFECT_SELF_COLLISION) {
                        x_new = limit_step(x_start, x_new);
                        v_new = limit_velocity(v_new);
                    }
                } else {
                    rk4_scratch[slot + 2u] = vec4<f32>(sum_x + v * 2.0, 0.0);
                    rk4_scratch[slot + 3u] = vec4<f32>(sum_v + a * 2.0, 0.0);
                    var step = half;
                    if (STAGE == 5u) {
                        step = dt;
                    }
                    x_new = x_start + v * step;
                    v_new = v_start + a * step;
                }
            }
        }
    } else {
        // A pin stays put, or follows its group's motion (MovingPins) from t to t_out.
        let group = pin_group(w_in);
        x_new = pin_carry(group, x, t, t_out);
        v_new = pin_velocity(group, x_new, t_out);
    }
    if (PACKED_OUT != 0u) {
        packed_xv_out[i] = vec4<f32>(x_new, v_new.x);
        packed_v_out[i] = v_new.yz;
        if (i == 0u) {
            packed_v_out[params.vertex_count] = vec2<f32>(t_out, 0.0);
        }
    } else {
        velocities_out[i] = vec4<f32>(v_new, t_out);
        if (STAGE == 2u) {
            return vec4<f32>(0.0); // the second kick leaves the positions of the first stage as they are
        }
        positions_out[i] = vec4<f32>(x_new, w_in);
    }
    // The deepest penetration is checked on the state that ends a substep, as on the CPU.
    // (Nested ifs: a constant condition stays one branch, which a compiler removes whole.)
    if (EFFECT_CONTACT) {
        if (STAGE == 0u || STAGE == 1u || STAGE == 6u) {
            var deepest = 0.0;
            for (var s = 0u; s < params.collider_count; s++) {
                deepest = max(deepest, -collider_distance(s, collider_center(s, t_out), x_new));
            }
            if (deepest > 0.0) {
                atomicMax(&max_penetration_bits, bitcast<u32>(deepest));
            }
        }
    }
    if (STAGE == 0u || STAGE == 1u) {
        return vec4<f32>(x_new - x, 1.0);
    }
    if (STAGE == 6u) {
        return vec4<f32>(x_new - rk4_scratch[4u * i].xyz, 1.0);
    }
    return vec4<f32>(0.0);
}
