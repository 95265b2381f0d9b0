// One Vertex Block Descent substep (cloth_core::Integrator::Vbd), as a sequence of passes.
// Prepended with layout.wgsl, colliders.wgsl, common.wgsl, self_collision.wgsl and
// self_partners.wgsl. The local step mirrors crates/cloth-core/src/vbd.rs (LocalTerms) term by
// term, and the passes cloth_core::reference's vbd_substep. A substep is:
//   pass 0 (per vertex)     predict: the inertial prediction y = x + h v* (v* = v + h g, drag,
//                           wind, as XPBD predicts, plus h/m times self-collision's repulsion at
//                           the substep's start), and the initial guess (the adaptive
//                           initialisation: x + h v + h² s g, s the share of gravity the last
//                           substep showed);
//   then the solver's vbd_iterations sweeps of
//     pass 1 (per vertex of one colour, once per colour)  the vertex's Newton step on its local
//                           incremental potential (inertia, springs with damping, colliders with
//                           friction), optionally extrapolated by Chebyshev's weight of the sweep;
//   pass 2 (per vertex)     v = (x − x⁰)/h (with SelfCollision, the speed limit), deepest
//                           penetration, the velocity the next prediction compares with.
// With the solver's vbd_multigrid_every, a coarse correction (cloth_core::multigrid) comes
// before every that many sweeps, on the levels the sweep blocks describe (this level, the next
// coarser one):
//   pass 3 (per level-1 node)  assemble level 1 from the vertices' local terms and springs;
//   pass 4 (per node of the next level)  sum this level's stencil 2 × 2 into the next;
//   pass 5 (per node of colour VBD_COLOR, (i mod 2) + 2 (j mod 2))  block Gauss–Seidel;
//   pass 6 (per node of the next level)  its right-hand side, the sum of this level's residuals;
//   pass 7 (per node)     this level's partial sums of e·A e and b·e;
//   pass 8 (per node)     e += α e' of the next level, α = (b'·e') / (e'·A'e') from its partials;
//   pass 9 (per vertex)   the vertices move by α e of level 1, stopping at colliders' surfaces.
// The vertices of colour c are those with (i + 2j) mod 5 = c (cloth_core::coloring::vertex_color):
// no spring of the stencil joins two of them, so a colour's steps read only other colours'
// positions. Units: m, kg, s, N/m.

// Which pass this pipeline runs (see above).
override VBD_PASS: u32 = 0u;
// The colour pass 1 moves.
override VBD_COLOR: u32 = 0u;

@group(0) @binding(0) var<uniform> params: SimParams;
@group(0) @binding(1) var<uniform> colliders: array<Collider, MAX_COLLIDERS>;
// The state at the substep's start (w: 1 free, minus its pin group pinned; velocity w: the time).
@group(0) @binding(2) var<storage, read> positions_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> velocities_in: array<vec4<f32>>;

// The position of vertex `index` in the state read, m (for common.wgsl's grid_normal).
fn position_in(index: u32) -> vec3<f32> {
    return positions_in[index].xyz;
}
// The iterate, moved in place by the sweeps; then the new state.
@group(0) @binding(4) var<storage, read_write> positions_out: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> velocities_out: array<vec4<f32>>;
// Deepest penetration so far, m, as the bits of a non-negative f32 (see cloth_step.wgsl).
@group(0) @binding(6) var<storage, read_write> max_penetration_bits: atomic<u32>;
// Each vertex's inertial prediction y, m.
@group(0) @binding(7) var<storage, read_write> predicted: array<vec4<f32>>;
// Each vertex's velocity at the start of the previous substep, m/s (the adaptive initialisation).
@group(0) @binding(8) var<storage, read_write> last_velocities: array<vec4<f32>>;
// Chebyshev's history (a placeholder without it): each vertex's iterate one sweep back at 2 i,
// two sweeps back at 2 i + 1, m.
@group(0) @binding(9) var<storage, read_write> history: array<vec4<f32>>;
// The sweep pass 1 belongs to (selected by a dynamic offset).
@group(0) @binding(10) var<uniform> sweep: VbdSweep;
// The mesh colliders' distance fields (colliders.wgsl), m.
@group(0) @binding(11) var<storage, read> distance_fields: array<f32>;
// Self-collision's candidate lists, its hash and its control (self_hash.wgsl; placeholders
// without SelfCollision).
@group(0) @binding(12) var<storage, read> self_words: array<u32>;
@group(0) @binding(13) var<storage, read> self_links: array<vec4<u32>>;
@group(0) @binding(14) var<storage, read_write> self_control: SelfControl;

// The multigrid correction's levels, each at offsets its sweep block gives: the 3 × 3 stencil of
// 3 × 3 blocks of every node (27 rows), the right-hand sides b, the corrections e, the partial sums
// (a placeholder without the correction).
@group(0) @binding(15) var<storage, read_write> multigrid: array<vec4<f32>>;

// The hash's words 4 at4 to 4 at4 + 3 (self_collision.wgsl).
fn link_words(at4: u32) -> vec4<u32> {
    return self_links[at4];
}

// The self-collision term of partner j (self_partners.wgsl): its repulsion at the substep's
// start on free vertex i at c.x moving at c.a, with the friction's step c.s.
fn pair_term(j: u32, c: PairContext) -> vec4<f32> {
    let x_j = positions_in[j].xyz;
    if (!in_contact(c.x, x_j)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(repulsion_force(c.x, x_j, c.a, velocities_in[j].xyz, params.vertex_mass, c.s), 0.0);
}

// The slip speed below which friction holds a vertex like a stiff tangential spring, m/s
// (cloth_core::vbd::FRICTION_SLIP_SPEED).
const FRICTION_SLIP_SPEED: f32 = 1e-4;

// The band outside a collider's surface within which a vertex's local potential holds the
// contact's curvature, and from beyond which a step into the collider stops at its surface, m
// (cloth_core::vbd::CONTACT_BAND).
const CONTACT_BAND: f32 = 1e-4;

// A 3 × 3 matrix by rows (cloth_core::real::Mat3).
struct Mat3 {
    r0: vec3<f32>,
    r1: vec3<f32>,
    r2: vec3<f32>,
}

fn mat3_scaled(m: Mat3, s: f32) -> Mat3 {
    return Mat3(m.r0 * s, m.r1 * s, m.r2 * s);
}

fn mat3_add(a: Mat3, b: Mat3) -> Mat3 {
    return Mat3(a.r0 + b.r0, a.r1 + b.r1, a.r2 + b.r2);
}

fn mat3_identity() -> Mat3 {
    return Mat3(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
}

// a bᵀ.
fn mat3_outer(a: vec3<f32>, b: vec3<f32>) -> Mat3 {
    return Mat3(b * a.x, b * a.y, b * a.z);
}

// The vertex's local gradient g, N, and Hessian H, N/m (cloth_core::vbd::LocalTerms).
struct LocalTerms {
    g: vec3<f32>,
    h: Mat3,
}

// The spring stiffness block K = k (u uᵀ + max(0, 1 − L0/L)(I − u uᵀ))
// (cloth_core::forces::spring_stiffness_block).
fn spring_stiffness_block(x_i: vec3<f32>, x_j: vec3<f32>, rest_length: f32, stiffness: f32) -> Mat3 {
    let delta = x_j - x_i;
    let length = sqrt(dot(delta, delta));
    if (length <= 0.0) {
        return mat3_scaled(mat3_identity(), 0.0);
    }
    let u = delta * (1.0 / length);
    let axial = mat3_outer(u, u);
    let transverse = max(1.0 - rest_length / length, 0.0);
    let across = Mat3(vec3<f32>(1.0, 0.0, 0.0) - axial.r0, vec3<f32>(0.0, 1.0, 0.0) - axial.r1,
                      vec3<f32>(0.0, 0.0, 1.0) - axial.r2);
    return mat3_scaled(mat3_add(axial, mat3_scaled(across, transverse)), stiffness);
}

// The spring damping block C = c_d u uᵀ (cloth_core::forces::spring_damping_block).
fn spring_damping_block(x_i: vec3<f32>, x_j: vec3<f32>, damping: f32) -> Mat3 {
    let delta = x_j - x_i;
    let length = sqrt(dot(delta, delta));
    if (length <= 0.0) {
        return mat3_scaled(mat3_identity(), 0.0);
    }
    let u = delta * (1.0 / length);
    return mat3_scaled(mat3_outer(u, u), damping);
}

// A spring to neighbour j (LocalTerms::add_spring).
fn add_local_spring(t: ptr<function, LocalTerms>, x: vec3<f32>, x0: vec3<f32>, j: u32, kind: u32,
                    rest_length: f32) {
    let x_j = positions_out[j].xyz;
    let x0_j = positions_in[j].xyz;
    let h = params.substep_dt;
    let inv_h = 1.0 / h;
    var damping = 0.0;
    if (EFFECT_SPRING_DAMPING) {
        damping = params.damping[kind];
    }
    var force = vec3<f32>(0.0);
    add_spring_force(&force, x, x_j, (x - x0) * inv_h, (x_j - x0_j) * inv_h, rest_length, params.stiffness[kind], damping);
    (*t).g = (*t).g - force;
    (*t).h = mat3_add((*t).h, spring_stiffness_block(x, x_j, rest_length, params.stiffness[kind]));
    if (damping > 0.0) {
        (*t).h = mat3_add((*t).h, mat3_scaled(spring_damping_block(x, x_j, damping), inv_h));
    }
}

// The spring from vertex (i, j) to its grid neighbour (i + di, j + dj), if it exists.
fn add_neighbour(t: ptr<function, LocalTerms>, x: vec3<f32>, x0: vec3<f32>, i: i32, j: i32, di: i32, dj: i32,
                 kind: u32, rest_length: f32) {
    let ni = u32(i + di);
    let nj = u32(j + dj);
    if ((ni >= params.grid_nx) | (nj >= params.grid_ny)) {
        return;
    }
    add_local_spring(t, x, x0, nj * params.grid_nx + ni, kind, rest_length);
}

// Collider c whose surface seen from x is `surface`, moving at `velocity` (LocalTerms::add_contact).
fn add_local_contact(t: ptr<function, LocalTerms>, x: vec3<f32>, x0: vec3<f32>, surface: Surface,
                     velocity: vec3<f32>, c: u32) {
    let h = params.substep_dt;
    let inv_h = 1.0 / h;
    let v_rel = (x - x0) * inv_h - velocity;
    let contact = contact_force(v_rel, surface, colliders[c].stiffness, colliders[c].damping);
    let n = surface.normal;
    if (contact.hit) {
        (*t).g = (*t).g - contact.force;
    }
    // (Inside, φ < 0, and in the band outside the surface, without a force there
    // (CONTACT_BAND): the stiffness block k_c n nᵀ; the damping block c n nᵀ while approaching.)
    var blocks = mat3_scaled(mat3_outer(n, n), colliders[c].stiffness);
    if (dot(v_rel, n) < 0.0) {
        blocks = mat3_add(blocks, mat3_scaled(mat3_scaled(mat3_outer(n, n), colliders[c].damping), inv_h));
    }
    (*t).h = mat3_add((*t).h, blocks);
    if (!contact.hit) {
        return;
    }
    var friction = 0.0;
    if (EFFECT_FRICTION) {
        friction = colliders[c].friction;
    }
    let normal_force = dot(contact.force, n);
    if ((friction <= 0.0) | (normal_force <= 0.0)) {
        return;
    }
    let slip = v_rel * h;
    let u = slip - n * dot(slip, n);
    let reach = max(sqrt(dot(u, u)), FRICTION_SLIP_SPEED * h);
    let scale = friction * normal_force / reach;
    (*t).g = (*t).g + u * scale;
    let nn = mat3_outer(n, n);
    let across = Mat3(vec3<f32>(1.0, 0.0, 0.0) - nn.r0, vec3<f32>(0.0, 1.0, 0.0) - nn.r1,
                      vec3<f32>(0.0, 0.0, 1.0) - nn.r2);
    (*t).h = mat3_add((*t).h, mat3_scaled(across, scale));
}

// x − H⁻¹ g (LocalTerms::step): the inverse's columns are the cross products of the rows over
// the determinant; the vertex stays where H is singular.
fn newton_step(x: vec3<f32>, t: LocalTerms) -> vec3<f32> {
    let a = t.h.r0;
    let b = t.h.r1;
    let c = t.h.r2;
    let det = dot(a, cross(b, c));
    // (det − det is NaN for an infinite or NaN determinant.)
    if ((det == 0.0) | !(det - det == 0.0)) {
        return x;
    }
    let inv = 1.0 / det;
    let c0 = cross(b, c) * inv;
    let c1 = cross(c, a) * inv;
    let c2 = cross(a, b) * inv;
    let g = t.g;
    return x - vec3<f32>(dot(vec3<f32>(c0.x, c1.x, c2.x), g), dot(vec3<f32>(c0.y, c1.y, c2.y), g),
                         dot(vec3<f32>(c0.z, c1.z, c2.z), g));
}

// The share of gravity the adaptive initialisation adds (cloth_core::vbd::gravity_share).
fn gravity_share(acceleration: vec3<f32>, gravity: vec3<f32>) -> f32 {
    let g2 = dot(gravity, gravity);
    if (g2 <= 0.0) {
        return 0.0;
    }
    return min(max(dot(acceleration, gravity) / g2, 0.0), 1.0);
}

fn predict(i: u32) {
    let p = positions_in[i];
    let state = velocities_in[i];
    let t = state.w;
    let h = params.substep_dt;
    let m = params.vertex_mass;
    var y = p.xyz;
    var guess = p.xyz;
    if (p.w > 0.0) {
        var v = state.xyz;
        if (EFFECT_GRAVITY) {
            v += params.gravity.xyz * h;
        }
        if (EFFECT_AIR_DRAG) {
            v += air_drag_force(m, params.air_drag, v) * (h / m);
        }
        if (EFFECT_WIND) {
            v += wind_force(grid_normal(i), v, wind_velocity(t), params.wind.w) * (h / m);
        }
        y = p.xyz + v * h;
        if (EFFECT_SELF_COLLISION) {
            let nx = params.grid_nx;
            let push = sum_over_partners(i, i % nx, i / nx, PairContext(p.xyz, state.xyz, h)).xyz;
            y += push * (h * h / m);
        }
        let acceleration = (state.xyz - last_velocities[i].xyz) * (1.0 / h);
        let gravity = params.gravity.xyz;
        guess = p.xyz + state.xyz * h + gravity * (gravity_share(acceleration, gravity) * h * h);
    } else {
        y = pin_carry(pin_group(p.w), p.xyz, t, t + h);
        guess = y;
    }
    predicted[i] = vec4<f32>(y, p.w);
    positions_out[i] = vec4<f32>(guess, p.w);
    if (sweep.chebyshev != 0u) {
        history[2u * i] = vec4<f32>(guess, 0.0);
        history[2u * i + 1u] = vec4<f32>(guess, 0.0);
    }
}

// The local terms of free vertex `index` at (i, j), where the sweeps have it (positions_out):
// inertia, its springs and its colliders (cloth_core::reference's vbd_substep, local_terms).
fn vertex_terms(index: u32, i: u32, j: u32) -> LocalTerms {
    let h = params.substep_dt;
    let m = params.vertex_mass;
    let x = positions_out[index].xyz;
    let x0 = positions_in[index].xyz;
    let w = m / (h * h);
    var t = LocalTerms((x - predicted[index].xyz) * w, mat3_scaled(mat3_identity(), w));
    // The stencil in the reference's spring order (cloth_step.wgsl's add_stencil_springs).
    let ii = i32(i);
    let jj = i32(j);
    let rest = params.rest_lengths;
    if (EFFECT_STRUCTURAL) {
        add_neighbour(&t, x, x0, ii, jj, 0, -1, 0u, rest.y);
        add_neighbour(&t, x, x0, ii, jj, -1, 0, 0u, rest.x);
        add_neighbour(&t, x, x0, ii, jj, 1, 0, 0u, rest.x);
        add_neighbour(&t, x, x0, ii, jj, 0, 1, 0u, rest.y);
    }
    if (EFFECT_SHEAR) {
        add_neighbour(&t, x, x0, ii, jj, -1, -1, 1u, rest.z);
        add_neighbour(&t, x, x0, ii, jj, 1, -1, 1u, rest.z);
        add_neighbour(&t, x, x0, ii, jj, 1, 1, 1u, rest.z);
        add_neighbour(&t, x, x0, ii, jj, -1, 1, 1u, rest.z);
    }
    if (EFFECT_BEND) {
        add_neighbour(&t, x, x0, ii, jj, 0, -2, 2u, 2.0 * rest.y);
        add_neighbour(&t, x, x0, ii, jj, -2, 0, 2u, 2.0 * rest.x);
        add_neighbour(&t, x, x0, ii, jj, 2, 0, 2u, 2.0 * rest.x);
        add_neighbour(&t, x, x0, ii, jj, 0, 2, 2u, 2.0 * rest.y);
    }
    if (EFFECT_CONTACT) {
        let t_end = velocities_in[index].w + h;
        for (var c = 0u; c < params.collider_count; c++) {
            let center = collider_center(c, t_end);
            if (collider_distance(c, center, x) < CONTACT_BAND) {
                add_local_contact(&t, x, x0, collider_surface(c, center, x), collider_velocity(c, t_end), c);
            }
        }
    }
    return t;
}

// Where a move of a vertex from `x` to `moved`, at the substep's end time `t_end`, stops: at the
// surface of a collider it would enter from beyond its band (cloth_core::vbd::surface_fraction).
fn stop_at_surfaces(x: vec3<f32>, moved: vec3<f32>, t_end: f32) -> vec3<f32> {
    var fraction = 1.0;
    for (var c = 0u; c < params.collider_count; c++) {
        let center = collider_center(c, t_end);
        let start = collider_distance(c, center, x);
        let end = collider_distance(c, center, moved);
        if ((start > CONTACT_BAND) & (end < 0.0)) {
            fraction = min(fraction, start / (start - end));
        }
    }
    if (fraction < 1.0) {
        return x + (moved - x) * fraction;
    }
    return moved;
}

// Pass 1: the vertex of colour VBD_COLOR that invocation `k` moves (row j, every fifth column
// from the row's first of the colour).
fn step_color(k: u32) {
    let nx = params.grid_nx;
    let per_row = (nx + 4u) / 5u;
    let j = k / per_row;
    if (j >= params.grid_ny) {
        return;
    }
    let i = (VBD_COLOR + 5u - (2u * j) % 5u) % 5u + 5u * (k % per_row);
    if (i >= nx) {
        return;
    }
    let index = j * nx + i;
    let p = positions_out[index];
    if (p.w <= 0.0) {
        return;
    }
    let x = p.xyz;
    let t = vertex_terms(index, i, j);
    var moved = newton_step(x, t);
    if (EFFECT_CONTACT) {
        // A step from outside a collider into it stops at its surface.
        moved = stop_at_surfaces(x, moved, velocities_in[index].w + params.substep_dt);
    }
    if (sweep.chebyshev != 0u) {
        let before = history[2u * index + 1u].xyz;
        moved = before + (moved - before) * sweep.omega;
        history[2u * index + 1u] = history[2u * index];
        history[2u * index] = vec4<f32>(moved, 0.0);
    }
    positions_out[index] = vec4<f32>(moved, p.w);
}

// Pass 2; returns the vertex's displacement over the substep (w 1).
fn finish(i: u32) -> vec4<f32> {
    let p = positions_out[i];
    let start = velocities_in[i];
    let t_end = start.w + params.substep_dt;
    var x = p.xyz;
    var v = pin_velocity(pin_group(p.w), x, t_end);
    if (p.w > 0.0) {
        let x0 = positions_in[i].xyz;
        v = (x - x0) * (1.0 / params.substep_dt);
        if (EFFECT_SELF_COLLISION) {
            // The speed limit (self_collision.wgsl).
            x = limit_step(x0, x);
            v = limit_velocity(v);
            positions_out[i] = vec4<f32>(x, p.w);
        }
    }
    last_velocities[i] = vec4<f32>(start.xyz, 0.0);
    velocities_out[i] = vec4<f32>(v, t_end);
    if (EFFECT_CONTACT) {
        var deepest = 0.0;
        for (var s = 0u; s < params.collider_count; s++) {
            deepest = max(deepest, -collider_distance(s, collider_center(s, t_end), x));
        }
        if (deepest > 0.0) {
            atomicMax(&max_penetration_bits, bitcast<u32>(deepest));
        }
    }
    return vec4<f32>(x - positions_in[i].xyz, 1.0);
}

// The multigrid correction (passes 3 to 9; cloth_core::multigrid).

// M v.
fn mat3_mul(m: Mat3, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(m.r0, v), dot(m.r1, v), dot(m.r2, v));
}

// The stencil entry of the node at (di, dj) from a node (cloth_core::multigrid::slot).
fn mg_slot(di: i32, dj: i32) -> u32 {
    return u32((di + 1) + 3 * (dj + 1));
}

// Block `s` of node `node` of the stencil at `base`.
fn mg_block(base: u32, node: u32, s: u32) -> Mat3 {
    let at = base + 27u * node + 3u * s;
    return Mat3(multigrid[at].xyz, multigrid[at + 1u].xyz, multigrid[at + 2u].xyz);
}

fn mg_store_block(base: u32, node: u32, s: u32, m: Mat3) {
    let at = base + 27u * node + 3u * s;
    multigrid[at] = vec4<f32>(m.r0, 0.0);
    multigrid[at + 1u] = vec4<f32>(m.r1, 0.0);
    multigrid[at + 2u] = vec4<f32>(m.r2, 0.0);
}

fn mat3_zero() -> Mat3 {
    return Mat3(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
}

// This level's correction at node `node`.
fn mg_e(node: u32) -> vec3<f32> {
    return multigrid[sweep.vectors + sweep.nx * sweep.ny + node].xyz;
}

// (A e) at node (i, j) of this level, leaving out the node's own block when `skip_self`.
fn mg_apply(i: u32, j: u32, skip_self: bool) -> vec3<f32> {
    let node = j * sweep.nx + i;
    var sum = vec3<f32>(0.0);
    for (var dj = -1; dj <= 1; dj++) {
        for (var di = -1; di <= 1; di++) {
            if (skip_self & (di == 0) & (dj == 0)) {
                continue;
            }
            let ni = i32(i) + di;
            let nj = i32(j) + dj;
            if ((ni < 0) | (nj < 0) | (ni >= i32(sweep.nx)) | (nj >= i32(sweep.ny))) {
                continue;
            }
            sum += mat3_mul(mg_block(sweep.stencil, node, mg_slot(di, dj)), mg_e(u32(nj) * sweep.nx + u32(ni)));
        }
    }
    return sum;
}

// The coupling block −(K_s + C_s/h) of vertex (i, j)'s spring to its neighbour (i + di, j + dj), if
// both are free, added to the level-1 stencil entry of the neighbour's aggregate.
fn mg_add_coupling(blocks: ptr<function, array<Mat3, 9>>, x: vec3<f32>, i: i32, j: i32, di: i32, dj: i32,
                   kind: u32, rest_length: f32) {
    let ni = i + di;
    let nj = j + dj;
    if ((ni < 0) | (nj < 0) | (ni >= i32(params.grid_nx)) | (nj >= i32(params.grid_ny))) {
        return;
    }
    let other = positions_out[u32(nj) * params.grid_nx + u32(ni)];
    if (other.w <= 0.0) {
        return;
    }
    var k = spring_stiffness_block(x, other.xyz, rest_length, params.stiffness[kind]);
    if (EFFECT_SPRING_DAMPING) {
        let c = params.damping[kind];
        k = mat3_add(k, mat3_scaled(spring_damping_block(x, other.xyz, c), 1.0 / params.substep_dt));
    }
    let s = mg_slot(ni / 2 - i / 2, nj / 2 - j / 2);
    (*blocks)[s] = mat3_add((*blocks)[s], mat3_scaled(k, -1.0));
}

// Pass 3: level-1 node k from its 2 × 2 vertices (cloth_core::multigrid::first_level).
fn mg_assemble(k: u32) {
    let cnx = sweep.coarse_nx;
    if (k >= cnx * sweep.coarse_ny) {
        return;
    }
    let ci = k % cnx;
    let cj = k / cnx;
    var blocks: array<Mat3, 9>;
    for (var s = 0u; s < 9u; s++) {
        blocks[s] = mat3_zero();
    }
    var b = vec3<f32>(0.0);
    let rest = params.rest_lengths;
    for (var dj = 0u; dj < 2u; dj++) {
        for (var di = 0u; di < 2u; di++) {
            let i = 2u * ci + di;
            let j = 2u * cj + dj;
            if ((i >= params.grid_nx) | (j >= params.grid_ny)) {
                continue;
            }
            let index = j * params.grid_nx + i;
            let p = positions_out[index];
            if (p.w <= 0.0) {
                continue;
            }
            let t = vertex_terms(index, i, j);
            b -= t.g;
            blocks[4] = mat3_add(blocks[4], t.h);
            let ii = i32(i);
            let jj = i32(j);
            if (EFFECT_STRUCTURAL) {
                mg_add_coupling(&blocks, p.xyz, ii, jj, 0, -1, 0u, rest.y);
                mg_add_coupling(&blocks, p.xyz, ii, jj, -1, 0, 0u, rest.x);
                mg_add_coupling(&blocks, p.xyz, ii, jj, 1, 0, 0u, rest.x);
                mg_add_coupling(&blocks, p.xyz, ii, jj, 0, 1, 0u, rest.y);
            }
            if (EFFECT_SHEAR) {
                mg_add_coupling(&blocks, p.xyz, ii, jj, -1, -1, 1u, rest.z);
                mg_add_coupling(&blocks, p.xyz, ii, jj, 1, -1, 1u, rest.z);
                mg_add_coupling(&blocks, p.xyz, ii, jj, 1, 1, 1u, rest.z);
                mg_add_coupling(&blocks, p.xyz, ii, jj, -1, 1, 1u, rest.z);
            }
            if (EFFECT_BEND) {
                mg_add_coupling(&blocks, p.xyz, ii, jj, 0, -2, 2u, 2.0 * rest.y);
                mg_add_coupling(&blocks, p.xyz, ii, jj, -2, 0, 2u, 2.0 * rest.x);
                mg_add_coupling(&blocks, p.xyz, ii, jj, 2, 0, 2u, 2.0 * rest.x);
                mg_add_coupling(&blocks, p.xyz, ii, jj, 0, 2, 2u, 2.0 * rest.y);
            }
        }
    }
    for (var s = 0u; s < 9u; s++) {
        mg_store_block(sweep.coarse_stencil, k, s, blocks[s]);
    }
    let nodes = cnx * sweep.coarse_ny;
    multigrid[sweep.coarse_vectors + k] = vec4<f32>(b, 0.0);
    multigrid[sweep.coarse_vectors + nodes + k] = vec4<f32>(0.0);
}

// Pass 4: node k of the next level, this level's stencil summed 2 × 2 (Level::coarsen).
fn mg_coarsen(k: u32) {
    let cnx = sweep.coarse_nx;
    if (k >= cnx * sweep.coarse_ny) {
        return;
    }
    let ci = i32(k % cnx);
    let cj = i32(k / cnx);
    var blocks: array<Mat3, 9>;
    for (var s = 0u; s < 9u; s++) {
        blocks[s] = mat3_zero();
    }
    for (var b = 0; b < 2; b++) {
        for (var a = 0; a < 2; a++) {
            let i = 2 * ci + a;
            let j = 2 * cj + b;
            if ((i >= i32(sweep.nx)) | (j >= i32(sweep.ny))) {
                continue;
            }
            let node = u32(j) * sweep.nx + u32(i);
            for (var dj = -1; dj <= 1; dj++) {
                for (var di = -1; di <= 1; di++) {
                    let ni = i + di;
                    let nj = j + dj;
                    if ((ni < 0) | (nj < 0) | (ni >= i32(sweep.nx)) | (nj >= i32(sweep.ny))) {
                        continue;
                    }
                    let s = mg_slot(ni / 2 - ci, nj / 2 - cj);
                    blocks[s] = mat3_add(blocks[s], mg_block(sweep.stencil, node, mg_slot(di, dj)));
                }
            }
        }
    }
    for (var s = 0u; s < 9u; s++) {
        mg_store_block(sweep.coarse_stencil, k, s, blocks[s]);
    }
}

// Pass 5: block Gauss–Seidel at node k of colour VBD_COLOR (Level::smooth).
fn mg_smooth(k: u32) {
    let half = (sweep.nx + 1u) / 2u;
    let i = 2u * (k % half) + VBD_COLOR % 2u;
    let j = 2u * (k / half) + VBD_COLOR / 2u;
    if ((i >= sweep.nx) | (j >= sweep.ny)) {
        return;
    }
    let node = j * sweep.nx + i;
    let rhs = multigrid[sweep.vectors + node].xyz - mg_apply(i, j, true);
    // A⁻¹ rhs as newton_step's x − H⁻¹ g at x = 0, g = −rhs (0 where the block is singular).
    let e = newton_step(vec3<f32>(0.0), LocalTerms(-rhs, mg_block(sweep.stencil, node, 4u)));
    multigrid[sweep.vectors + sweep.nx * sweep.ny + node] = vec4<f32>(e, 0.0);
}

// Pass 6: node k of the next level: the sum of its children's residuals b − A e, and e' = 0.
fn mg_restrict(k: u32) {
    let cnx = sweep.coarse_nx;
    let nodes = cnx * sweep.coarse_ny;
    if (k >= nodes) {
        return;
    }
    let ci = k % cnx;
    let cj = k / cnx;
    var b = vec3<f32>(0.0);
    for (var dj = 0u; dj < 2u; dj++) {
        for (var di = 0u; di < 2u; di++) {
            let i = 2u * ci + di;
            let j = 2u * cj + dj;
            if ((i < sweep.nx) & (j < sweep.ny)) {
                b += multigrid[sweep.vectors + j * sweep.nx + i].xyz - mg_apply(i, j, false);
            }
        }
    }
    multigrid[sweep.coarse_vectors + k] = vec4<f32>(b, 0.0);
    multigrid[sweep.coarse_vectors + nodes + k] = vec4<f32>(0.0);
}

// (workgroup_sum: workgroup_sum.wgsl.)

// Pass 7: this level's partial sums of e·A e and b·e, one a workgroup (uniform control flow).
fn mg_model(k: u32, local: u32, group: u32) {
    var value = vec2<f32>(0.0);
    if (k < sweep.nx * sweep.ny) {
        let i = k % sweep.nx;
        let j = k / sweep.nx;
        let e = mg_e(k);
        value = vec2<f32>(dot(e, mg_apply(i, j, false)), dot(multigrid[sweep.vectors + k].xyz, e));
    }
    let total = workgroup_sum(value, local);
    if (local == 0u) {
        multigrid[sweep.partials + group] = vec4<f32>(total, 0.0, 0.0);
    }
}

// The step α = (b'·e') / (e'·A'e') along the next level's correction, from its partials
// (multigrid::step_length; 0 where the curvature is not positive), in every invocation.
fn mg_step_length(local: u32) -> f32 {
    let count = (sweep.coarse_nx * sweep.coarse_ny + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    var sum = vec2<f32>(0.0);
    for (var k = local; k < count; k += WORKGROUP_SIZE) {
        sum += multigrid[sweep.coarse_partials + k].xy;
    }
    let total = workgroup_sum(sum, local);
    // (slope − slope is NaN for an infinite or NaN slope.)
    if ((total.x > 0.0) & (total.y - total.y == 0.0)) {
        return total.y / total.x;
    }
    return 0.0;
}

// Pass 8: this level's node k moves by α times its parent's correction (uniform control flow).
fn mg_prolong(k: u32, local: u32) {
    let alpha = mg_step_length(local);
    if (k >= sweep.nx * sweep.ny) {
        return;
    }
    let parent = (k / sweep.nx / 2u) * sweep.coarse_nx + (k % sweep.nx) / 2u;
    let cnodes = sweep.coarse_nx * sweep.coarse_ny;
    let at = sweep.vectors + sweep.nx * sweep.ny + k;
    multigrid[at] = vec4<f32>(multigrid[at].xyz + multigrid[sweep.coarse_vectors + cnodes + parent].xyz * alpha, 0.0);
}

// Pass 9: free vertex k moves by α times its aggregate's level-1 correction, stopping at the
// surface of a collider it would enter (uniform control flow).
fn mg_move(k: u32, local: u32) {
    let alpha = mg_step_length(local);
    if (k >= params.vertex_count) {
        return;
    }
    let p = positions_out[k];
    if (p.w <= 0.0) {
        return;
    }
    let nx = params.grid_nx;
    let parent = (k / nx / 2u) * sweep.coarse_nx + (k % nx) / 2u;
    let cnodes = sweep.coarse_nx * sweep.coarse_ny;
    var moved = p.xyz + multigrid[sweep.coarse_vectors + cnodes + parent].xyz * alpha;
    if (EFFECT_CONTACT) {
        moved = stop_at_surfaces(p.xyz, moved, velocities_in[k].w + params.substep_dt);
    }
    positions_out[k] = vec4<f32>(moved, p.w);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn vbd(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
       @builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    if (EFFECT_SELF_COLLISION & (VBD_PASS == 2u)) {
        clear_motion(local);
    }
    if (VBD_PASS >= 3u) {
        let k = id.y * groups.x * WORKGROUP_SIZE + id.x;
        let g = group.y * groups.x + group.x;
        switch VBD_PASS {
            case 3u: { mg_assemble(k); }
            case 4u: { mg_coarsen(k); }
            case 5u: { mg_smooth(k); }
            case 6u: { mg_restrict(k); }
            case 7u: { mg_model(k, local, g); }
            case 8u: { mg_prolong(k, local); }
            default: { mg_move(k, local); }
        }
        return;
    }
    let moved = run_pass(id, groups);
    if (EFFECT_SELF_COLLISION & (VBD_PASS == 2u)) {
        // The extents of the substep's displacements along the motion directions, which the next
        // check turns into its bound.
        record_motion(moved, local, group.y * groups.x + group.x);
    }
}

// Runs the pipeline's pass for the invocation; returns the vertex's displacement over the
// substep in the finishing pass (w 1), zero otherwise.
fn run_pass(id: vec3<u32>, groups: vec3<u32>) -> vec4<f32> {
    // 2D dispatch: more than 65535 workgroups spill into y.
    let k = id.y * groups.x * WORKGROUP_SIZE + id.x;
    if (VBD_PASS == 1u) {
        step_color(k);
        return vec4<f32>(0.0);
    }
    if (k >= params.vertex_count) {
        return vec4<f32>(0.0);
    }
    if (VBD_PASS == 0u) {
        predict(k);
        return vec4<f32>(0.0);
    }
    return finish(k);
}
