// One backward-Euler substep (cloth_core::Integrator::BackwardEuler), as a sequence of passes.
// Prepended with layout.wgsl, colliders.wgsl, common.wgsl, self_collision.wgsl and
// self_partners.wgsl. The passes mirror cloth_core::reference's backward_euler_substep and
// cloth_core::implicit's conjugate_gradients; the Newton iterate (x̄, v̄) lives in the output
// state. A substep is:
//   pass 0 (per vertex)   start: x̄ = x, v̄ = v;
//   then newton_iterations times:
//     pass 1 or 2         linearise about (x̄, v̄) (1: the first iteration, at the substep's start
//       (per vertex)      time; 2: the later ones, at its end): the force f, the right-hand side
//                         b = h (f − K d_x − C d_v) − M (v̄ − v), the 3 × 3 block-Jacobi
//                         preconditioner, the contacts' blocks; Δ = 0, r = b, p = z = P r;
//                         partial sums of r·z and b·b;
//     then cg_max_iterations times (iteration k, from a dynamic uniform):
//       pass 3 or 4       3 (k = 1): sums the linearisation's partials into the solve's start
//       (per vertex)      (r·z, |b|, done when b is within the tolerance); 4 (k > 1): ends
//                         iteration k − 1 from its totals (done when |r| ≤ tol |b| or p·q ≤ 0,
//                         else β = r·z' / r·z and the new direction p = z + β p, which each
//                         vertex also forms for its neighbours from their z and old p); then
//                         q = A p; partial sums of p·q;
//       pass 5            α = r·z / p·q; Δ += α p, r −= α q, z = P r; partial sums of r·z and r·r;
//     pass 6              ends the last iteration as pass 4 does (the counts, done);
//     pass 7 (per vertex) v̄ += Δ, x̄ = x + h v̄ (the pins where their motion puts them);
//     with the solver's line search, for each of the LINE_SEARCH_SLOPES slopes r it measures
//     (cloth_core::solver; the dynamic uniform carries r):
//       pass 9            partial sums of the incremental potential's slopes along Δ, at the
//       (per vertex)      iterate before the change (−Δ·b; b kept in the w of the
//                         preconditioner's rows) and where the iterate is now (the full step for
//                         r = 1);
//       pass 10           the bracket of step lengths from their totals (regula falsi with the
//                         Illinois rule), kept in the last entries of `steps`; the iterate moved
//                         to the bracket's secant root α: v̄ += (α − α_r) Δ, x̄ = x + h v̄;
//   pass 8 (per vertex)   finish: with SelfCollision the speed limit, the state's time, the
//                         deepest penetration.
// Sums over the vertices are reduced in two levels: each workgroup sums its invocations' terms in
// workgroup memory and writes one partial sum; the pass that needs the total sums the partials
// again in every workgroup (the same order everywhere, so every workgroup gets the same number),
// and the first workgroup records what later passes read (the iteration's r·z and whether the
// solve is done, at index k of `steps`). A pass skips its vertices' work once the solve is
// done: the dispatches stay in the frame's one submission, the work stops. A CG iteration is two
// dispatches: pass 4 reads iteration k − 1's direction and p·q while it writes iteration k's, so
// the two alternate between two slots (`direction_slot`, `product_section`). Units: m, kg, s, N/m.

// Which pass this pipeline runs (see above).
override IMPLICIT_PASS: u32 = 0u;

@group(0) @binding(0) var<uniform> params: SimParams;
@group(0) @binding(1) var<uniform> colliders: array<Collider, MAX_COLLIDERS>;
// The state at the substep's start (w: 1 free, minus its pin group pinned; velocity w: the time).
@group(0) @binding(2) var<storage, read> positions_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> velocities_in: array<vec4<f32>>;
// The Newton iterate (x̄, v̄); then the new state.
@group(0) @binding(4) var<storage, read_write> positions_out: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> velocities_out: array<vec4<f32>>;
// Deepest penetration so far, m, as the bits of a non-negative f32 (see cloth_step.wgsl).
@group(0) @binding(6) var<storage, read_write> max_penetration_bits: atomic<u32>;
// Conjugate gradients' vectors, CG_SLOTS a vertex: Δ (m/s) at slot 0, r (N·s) at 1, q = A p
// (N·s) at 3, z = P r (m/s) at 4, and the direction p (m/s) of odd iterations at 2, of even ones
// at 5.
@group(0) @binding(7) var<storage, read_write> cg: array<vec4<f32>>;
// Five a vertex: the rows of the inverse of its diagonal block of A (1/kg) at 5 i to 5 i + 2, with
// the right-hand side b (N·s) in their w; its
// contacts' block h C_c + h² K_c (kg) at 5 i + 3 (xx, yy, zz, xy) and 5 i + 4 (xz, yz).
@group(0) @binding(8) var<storage, read_write> blocks: array<vec4<f32>>;
// The workgroups' partial sums: four sections of partial_count() each (the linearisation's
// and pass 5's r·z and b·b or r·r at 0 and 2, pass 3-4's p·q at 1 for odd iterations and 3 for
// even ones).
@group(0) @binding(9) var<storage, read_write> partials: array<vec2<f32>>;
@group(0) @binding(10) var<storage, read_write> counters: CgCounters;
// Per CG iteration k: r·z at its start (the bits of an f32) and 1 once the solve is done.
@group(0) @binding(11) var<storage, read_write> steps: array<vec2<u32>>;
// The CG iteration passes 3 to 6 belong to (selected by a dynamic offset).
@group(0) @binding(12) var<uniform> step: CgStep;
// The mesh colliders' distance fields (colliders.wgsl), m.
@group(0) @binding(13) var<storage, read> distance_fields: array<f32>;
// Self-collision's candidate lists, its hash and its control (self_hash.wgsl; placeholders
// without SelfCollision).
@group(0) @binding(14) var<storage, read> self_words: array<u32>;
@group(0) @binding(15) var<storage, read> self_links: array<vec4<u32>>;
@group(0) @binding(16) var<storage, read_write> self_control: SelfControl;

const CG_SLOTS: u32 = 6u;

// The slot of iteration k's search direction p.
fn direction_slot(k: u32) -> u32 {
    return select(5u, 2u, (k & 1u) == 1u);
}

// The partials' section of iteration k's p·q.
fn product_section(k: u32) -> u32 {
    return select(3u, 1u, (k & 1u) == 1u);
}

// The hash's words 4 at4 to 4 at4 + 3 (self_collision.wgsl).
fn link_words(at4: u32) -> vec4<u32> {
    return self_links[at4];
}

// The position of vertex `index` in the Newton iterate, m (common.wgsl's grid_normal: the wind
// sees the iterate's normal).
fn position_in(index: u32) -> vec3<f32> {
    return positions_out[index].xyz;
}

// The self-collision term of partner j (self_partners.wgsl): its repulsion on free vertex i at
// c.x moving at c.a in the iterate, with the friction's step c.s.
fn pair_term(j: u32, c: PairContext) -> vec4<f32> {
    let x_j = positions_out[j].xyz;
    if (!in_contact(c.x, x_j)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(repulsion_force(c.x, x_j, c.a, velocities_out[j].xyz, params.vertex_mass, c.s), 0.0);
}

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

fn mat3_zero() -> Mat3 {
    return Mat3(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
}

fn mat3_identity() -> Mat3 {
    return Mat3(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
}

// a bᵀ.
fn mat3_outer(a: vec3<f32>, b: vec3<f32>) -> Mat3 {
    return Mat3(b * a.x, b * a.y, b * a.z);
}

fn mat3_mul(m: Mat3, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(m.r0, v), dot(m.r1, v), dot(m.r2, v));
}

// The inverse (Mat3::inverse: the columns are the cross products of the rows over the
// determinant), or the identity where the determinant is zero or not finite.
fn mat3_inverse_or_identity(m: Mat3) -> Mat3 {
    let a = m.r0;
    let b = m.r1;
    let c = m.r2;
    let det = dot(a, cross(b, c));
    // (det − det is NaN for an infinite or NaN determinant.)
    if ((det == 0.0) | !(det - det == 0.0)) {
        return mat3_identity();
    }
    let inv = 1.0 / det;
    let c0 = cross(b, c);
    let c1 = cross(c, a);
    let c2 = cross(a, b);
    return Mat3(vec3<f32>(c0.x, c1.x, c2.x) * inv, vec3<f32>(c0.y, c1.y, c2.y) * inv,
                vec3<f32>(c0.z, c1.z, c2.z) * inv);
}

// The least transverse stiffness of a spring in the linearisation, a fraction of k
// (cloth_core::implicit::TRANSVERSE_STIFFNESS_FLOOR, which says why).
const TRANSVERSE_STIFFNESS_FLOOR: f32 = 0.05;

// The spring stiffness block K = k (u uᵀ + max(floor, 1 − L0/L)(I − u uᵀ))
// (cloth_core::forces::spring_stiffness_block_floored).
fn spring_stiffness_block(x_i: vec3<f32>, x_j: vec3<f32>, rest_length: f32, stiffness: f32) -> Mat3 {
    let delta = x_j - x_i;
    let length = sqrt(dot(delta, delta));
    if (length <= 0.0) {
        return mat3_zero();
    }
    let u = delta * (1.0 / length);
    let axial = mat3_outer(u, u);
    let transverse = max(1.0 - rest_length / length, TRANSVERSE_STIFFNESS_FLOOR);
    let across = Mat3(vec3<f32>(1.0, 0.0, 0.0) - axial.r0, vec3<f32>(0.0, 1.0, 0.0) - axial.r1,
                      vec3<f32>(0.0, 0.0, 1.0) - axial.r2);
    return mat3_scaled(mat3_add(axial, mat3_scaled(across, transverse)), stiffness);
}

// h C_s + h² K_s of the spring from x_i to x_j (its block of A), and K_s and C_s themselves.
struct SpringBlocks {
    stiffness: Mat3,
    damping: Mat3,
    system: Mat3,
}

fn spring_blocks(x_i: vec3<f32>, x_j: vec3<f32>, kind: u32, rest_length: f32) -> SpringBlocks {
    let h = params.substep_dt;
    let k = spring_stiffness_block(x_i, x_j, rest_length, params.stiffness[kind]);
    var c = mat3_zero();
    if (EFFECT_SPRING_DAMPING) {
        // C_s = c_d u uᵀ (cloth_core::forces::spring_damping_block).
        let delta = x_j - x_i;
        let length = sqrt(dot(delta, delta));
        if (length > 0.0) {
            let u = delta * (1.0 / length);
            c = mat3_scaled(mat3_outer(u, u), params.damping[kind]);
        }
    }
    return SpringBlocks(k, c, mat3_add(mat3_scaled(c, h), mat3_scaled(k, h * h)));
}

// The stencil neighbour (i + di, j + dj) of vertex (i, j), or NO_VERTEX off the grid.
fn neighbour(i: u32, j: u32, di: i32, dj: i32) -> u32 {
    let ni = u32(i32(i) + di);
    let nj = u32(i32(j) + dj);
    if ((ni >= params.grid_nx) | (nj >= params.grid_ny)) {
        return NO_VERTEX;
    }
    return nj * params.grid_nx + ni;
}

// The stencil's twelve springs in the reference's order (cloth_step.wgsl's add_stencil_springs):
// offset, kind, rest length.
struct StencilSpring {
    di: i32,
    dj: i32,
    kind: u32,
    rest_length: f32,
}

fn stencil_spring(s: u32) -> StencilSpring {
    let rest = params.rest_lengths;
    switch s {
        case 0u: { return StencilSpring(0, -1, 0u, rest.y); }
        case 1u: { return StencilSpring(-1, 0, 0u, rest.x); }
        case 2u: { return StencilSpring(1, 0, 0u, rest.x); }
        case 3u: { return StencilSpring(0, 1, 0u, rest.y); }
        case 4u: { return StencilSpring(-1, -1, 1u, rest.z); }
        case 5u: { return StencilSpring(1, -1, 1u, rest.z); }
        case 6u: { return StencilSpring(1, 1, 1u, rest.z); }
        case 7u: { return StencilSpring(-1, 1, 1u, rest.z); }
        case 8u: { return StencilSpring(0, -2, 2u, 2.0 * rest.y); }
        case 9u: { return StencilSpring(-2, 0, 2u, 2.0 * rest.x); }
        case 10u: { return StencilSpring(2, 0, 2u, 2.0 * rest.x); }
        default: { return StencilSpring(0, 2, 2u, 2.0 * rest.y); }
    }
}

// The model's force (N) and the normal of a contact whose friction holds the vertex, if any.
struct ForceAndStick {
    force: vec3<f32>,
    stuck: bool,
    normal: vec3<f32>,
}

// The model's force on free vertex i at (vi, vj) in the iterate state (x, v) at time t
// (cloth_core::reference's variant_force_and_stick, as cloth_step.wgsl evaluates it), with the
// friction's step h.
fn iterate_force(i: u32, vi: u32, vj: u32, x: vec3<f32>, v: vec3<f32>, t: f32) -> ForceAndStick {
    let mass = params.vertex_mass;
    let h = params.substep_dt;
    var force = vec3<f32>(0.0);
    if (EFFECT_GRAVITY) {
        force += gravity_force(mass, params.gravity.xyz);
    }
    if (ANY_SPRINGS) {
        for (var s = 0u; s < 12u; s++) {
            let spring = stencil_spring(s);
            if (!kind_enabled(spring.kind)) {
                continue;
            }
            let j = neighbour(vi, vj, spring.di, spring.dj);
            if (j == NO_VERTEX) {
                continue;
            }
            var damping = 0.0;
            if (EFFECT_SPRING_DAMPING) {
                damping = params.damping[spring.kind];
            }
            add_spring_force(&force, x, positions_out[j].xyz, v, velocities_out[j].xyz, spring.rest_length,
                             params.stiffness[spring.kind], damping);
        }
    }
    if (EFFECT_AIR_DRAG) {
        force += air_drag_force(mass, params.air_drag, v);
    }
    if (EFFECT_WIND) {
        force += wind_force(grid_normal(i), v, wind_velocity(t), params.wind.w);
    }
    if (EFFECT_SELF_COLLISION) {
        force += sum_over_partners(i, vi, vj, PairContext(x, v, h)).xyz;
    }
    let other_forces = force;
    var stuck = false;
    var stick_normal = vec3<f32>(0.0);
    if (EFFECT_CONTACT) {
        for (var c = 0u; c < params.collider_count; c++) {
            let center = collider_center(c, t);
            let surface = collider_contact(c, center, x);
            if (surface.distance >= 0.0) {
                continue;
            }
            let v_rel = v - collider_velocity(c, t);
            let contact = contact_force(v_rel, surface, colliders[c].stiffness, colliders[c].damping);
            if (contact.hit) {
                force += contact.force;
                if (EFFECT_FRICTION) {
                    let mu = colliders[c].friction;
                    force += friction_force(other_forces, v_rel, contact.normal, mass, h, mu);
                    if (!stuck && friction_holds(other_forces, v_rel, contact.normal, mass, h, mu)) {
                        stuck = true;
                        stick_normal = contact.normal;
                    }
                }
            }
        }
    }
    return ForceAndStick(force, stuck, stick_normal);
}

// Where pinned vertex j's motion puts it at the substep's end (positions), and its velocity there.
struct PinEnd {
    x: vec3<f32>,
    v: vec3<f32>,
}

fn pin_end(j: u32) -> PinEnd {
    let p = positions_in[j];
    let t = velocities_in[j].w;
    let t_end = t + params.substep_dt;
    let x = pin_carry(pin_group(p.w), p.xyz, t, t_end);
    return PinEnd(x, pin_velocity(pin_group(p.w), x, t_end));
}

// The change d_x (m) and d_v (m/s) the right-hand side linearises over, of vertex j: for a free
// vertex x + h v̄ − x̄ and 0, for a pinned one its prescribed end state less the iterate.
struct Change {
    dx: vec3<f32>,
    dv: vec3<f32>,
}

fn change_of(j: u32) -> Change {
    let x_bar = positions_out[j];
    let v_bar = velocities_out[j].xyz;
    if (x_bar.w > 0.0) {
        return Change(positions_in[j].xyz + v_bar * params.substep_dt - x_bar.xyz, vec3<f32>(0.0));
    }
    let end = pin_end(j);
    return Change(end.x - x_bar.xyz, end.v - v_bar);
}

// Pass 0.
fn start(i: u32) {
    positions_out[i] = positions_in[i];
    velocities_out[i] = velocities_in[i];
}

// Passes 1 and 2: returns (r·z, b·b) of the vertex.
fn linearise(i: u32, first: bool) -> vec2<f32> {
    let p_bar = positions_out[i];
    if (p_bar.w <= 0.0) {
        cg[CG_SLOTS * i] = vec4<f32>(0.0);
        cg[CG_SLOTS * i + 1u] = vec4<f32>(0.0);
        cg[CG_SLOTS * i + direction_slot(1u)] = vec4<f32>(0.0);
        blocks[5u * i] = vec4<f32>(1.0, 0.0, 0.0, 0.0);
        blocks[5u * i + 1u] = vec4<f32>(0.0, 1.0, 0.0, 0.0);
        blocks[5u * i + 2u] = vec4<f32>(0.0, 0.0, 1.0, 0.0);
        blocks[5u * i + 3u] = vec4<f32>(0.0);
        blocks[5u * i + 4u] = vec4<f32>(0.0);
        return vec2<f32>(0.0);
    }
    let h = params.substep_dt;
    let m = params.vertex_mass;
    let nx = params.grid_nx;
    let vi = i % nx;
    let vj = i / nx;
    let x = p_bar.xyz;
    let v = velocities_out[i].xyz;
    let x0 = positions_in[i].xyz;
    let v0 = velocities_in[i].xyz;
    var t = velocities_in[i].w;
    if (!first) {
        t = t + h;
    }
    let f = iterate_force(i, vi, vj, x, v, t).force;
    let own = change_of(i);
    var drop = vec3<f32>(0.0);
    var diagonal = mat3_scaled(mat3_identity(), m);
    if (ANY_SPRINGS) {
        for (var s = 0u; s < 12u; s++) {
            let spring = stencil_spring(s);
            if (!kind_enabled(spring.kind)) {
                continue;
            }
            let j = neighbour(vi, vj, spring.di, spring.dj);
            if (j == NO_VERTEX) {
                continue;
            }
            let other = change_of(j);
            let b = spring_blocks(x, positions_out[j].xyz, spring.kind, spring.rest_length);
            drop += mat3_mul(b.stiffness, own.dx - other.dx) + mat3_mul(b.damping, own.dv - other.dv);
            diagonal = mat3_add(diagonal, b.system);
        }
    }
    var contact = mat3_zero();
    var pull = vec3<f32>(0.0);
    if (EFFECT_CONTACT) {
        // The end position the iterate's velocity gives (x̄ itself after the first iteration).
        let y = x0 + v * h;
        for (var c = 0u; c < params.collider_count; c++) {
            let center = collider_center(c, t);
            let stiffness = colliders[c].stiffness;
            // In the linearisation where the vertex is inside at x̄ or at y; linearised about y
            // where y is inside, the penalty's force there entering as `pull` (the reference's
            // linearised_system says why).
            let at_iterate = collider_surface(c, center, x);
            let at_end = collider_surface(c, center, y);
            let ends_inside = at_end.distance < 0.0;
            if (ends_inside | (at_iterate.distance < 0.0)) {
                var at = x;
                var surface = at_iterate;
                if (ends_inside) {
                    at = y;
                    surface = at_end;
                }
                let n = surface.normal;
                let k_c = mat3_scaled(mat3_outer(n, n), stiffness);
                var c_c = mat3_zero();
                if (dot(v - collider_velocity(c, t), n) < 0.0) {
                    c_c = mat3_scaled(mat3_outer(n, n), colliders[c].damping);
                }
                drop += mat3_mul(k_c, own.dx) + mat3_mul(c_c, own.dv);
                pull += n * (-stiffness * min(surface.distance, 0.0))
                    - at_iterate.normal * (-stiffness * min(at_iterate.distance, 0.0)) + mat3_mul(k_c, at - x);
                contact = mat3_add(contact, mat3_add(mat3_scaled(c_c, h), mat3_scaled(k_c, h * h)));
            }
        }
    }
    diagonal = mat3_add(diagonal, contact);
    let b = (f + pull - drop) * h - (v - v0) * m;
    let pre = mat3_inverse_or_identity(diagonal);
    let z = mat3_mul(pre, b);
    cg[CG_SLOTS * i] = vec4<f32>(0.0);
    cg[CG_SLOTS * i + 1u] = vec4<f32>(b, 0.0);
    cg[CG_SLOTS * i + direction_slot(1u)] = vec4<f32>(z, 0.0);
    blocks[5u * i] = vec4<f32>(pre.r0, b.x);
    blocks[5u * i + 1u] = vec4<f32>(pre.r1, b.y);
    blocks[5u * i + 2u] = vec4<f32>(pre.r2, b.z);
    blocks[5u * i + 3u] = vec4<f32>(contact.r0.x, contact.r1.y, contact.r2.z, contact.r0.y);
    blocks[5u * i + 4u] = vec4<f32>(contact.r0.z, contact.r1.z, 0.0, 0.0);
    return vec2<f32>(dot(b, z), dot(b, b));
}

// The preconditioner's z = P r of vertex i.
fn preconditioned(i: u32, r: vec3<f32>) -> vec3<f32> {
    let p = Mat3(blocks[5u * i].xyz, blocks[5u * i + 1u].xyz, blocks[5u * i + 2u].xyz);
    return mat3_mul(p, r);
}

// Iteration k's direction p at vertex j: for k = 1 the linearisation's; for k > 1 formed from
// iteration k − 1's as z + β p (pass 6 of the reference's conjugate_gradients).
fn direction(j: u32, k: u32, beta: f32) -> vec3<f32> {
    if (k == 1u) {
        return cg[CG_SLOTS * j + direction_slot(1u)].xyz;
    }
    return cg[CG_SLOTS * j + 4u].xyz + cg[CG_SLOTS * j + direction_slot(k - 1u)].xyz * beta;
}

// Passes 3 and 4: q = A p at vertex i (zero at a pinned one, whose p is read as zero) for
// iteration k's direction, which pass 4 forms at the vertex (and writes to its slot) and at each
// neighbour (`direction`); returns p·q.
fn apply(i: u32, k: u32, beta: f32) -> f32 {
    let p_bar = positions_out[i];
    let p_i = direction(i, k, beta);
    if (k > 1u) {
        cg[CG_SLOTS * i + direction_slot(k)] = vec4<f32>(p_i, 0.0);
    }
    if (p_bar.w <= 0.0) {
        cg[CG_SLOTS * i + 3u] = vec4<f32>(0.0);
        return 0.0;
    }
    var q = p_i * params.vertex_mass;
    let nx = params.grid_nx;
    let vi = i % nx;
    let vj = i / nx;
    if (ANY_SPRINGS) {
        for (var s = 0u; s < 12u; s++) {
            let spring = stencil_spring(s);
            if (!kind_enabled(spring.kind)) {
                continue;
            }
            let j = neighbour(vi, vj, spring.di, spring.dj);
            if (j == NO_VERTEX) {
                continue;
            }
            let x_j = positions_out[j];
            var p_j = vec3<f32>(0.0);
            if (x_j.w > 0.0) {
                p_j = direction(j, k, beta);
            }
            let b = spring_blocks(p_bar.xyz, x_j.xyz, spring.kind, spring.rest_length);
            q += mat3_mul(b.system, p_i - p_j);
        }
    }
    if (EFFECT_CONTACT) {
        let d = blocks[5u * i + 3u];
        let e = blocks[5u * i + 4u];
        q += vec3<f32>(d.x * p_i.x + d.w * p_i.y + e.x * p_i.z, d.w * p_i.x + d.y * p_i.y + e.y * p_i.z,
                       e.x * p_i.x + e.y * p_i.y + d.z * p_i.z);
    }
    cg[CG_SLOTS * i + 3u] = vec4<f32>(q, 0.0);
    return dot(p_i, q);
}

// The two-level sums (see the top of the file) start with workgroup_sum (workgroup_sum.wgsl).

// Workgroups of a per-vertex pass that hold vertices: one partial sum each.
fn partial_count() -> u32 {
    return (params.vertex_count + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
}

// Writes the workgroup's sum of `value` as its partial of `section` (uniform control flow).
fn write_partial(value: vec2<f32>, section: u32, local: u32, group: u32) {
    let total = workgroup_sum(value, local);
    let count = partial_count();
    if ((local == 0u) & (group < count)) {
        partials[section * count + group] = total;
    }
}

// The total of `section`'s partials, in every invocation (uniform control flow).
fn total_of(section: u32, local: u32) -> vec2<f32> {
    let count = partial_count();
    var sum = vec2<f32>(0.0);
    for (var k = local; k < count; k += WORKGROUP_SIZE) {
        sum += partials[section * count + k];
    }
    return workgroup_sum(sum, local);
}

// How CG iteration k ended: whether the solve is done, else the β of the next direction.
struct IterationEnd {
    done: bool,
    beta: f32,
}

// Ends CG iteration k from its totals, p·q and pass 5's r·z and r·r (uniform control flow): done
// when it stopped (done before, or p·q ≤ 0) or converged (|r| ≤ tol |b|); else β = r·z' / r·z.
// The first workgroup counts the iteration and records at k + 1 of `steps` the next r·z and
// whether the solve is done.
fn end_iteration(k: u32, local: u32, group: u32) -> IterationEnd {
    let pq = total_of(product_section(k), local).x;
    let next = total_of(2u, local);
    let rz = bitcast<f32>(steps[k].x);
    let was_done = steps[k].y != 0u;
    let stopped = was_done | (pq <= 0.0);
    let converged = !stopped & (sqrt(next.y) <= counters.tolerance * counters.b_norm);
    if ((group == 0u) & (local == 0u)) {
        if (!stopped) {
            counters.solve_iterations += 1u;
            counters.cg += 1u;
        }
        if (stopped | converged) {
            steps[k + 1u] = vec2<u32>(steps[k].x, 1u);
        } else {
            steps[k + 1u] = vec2<u32>(bitcast<u32>(next.x), 0u);
        }
    }
    return IterationEnd(stopped | converged, next.x / rz);
}

// Pass 7: the Newton update of vertex i.
fn newton_update(i: u32) {
    let p = positions_in[i];
    let t = velocities_in[i].w;
    if (p.w > 0.0) {
        let v = velocities_out[i].xyz + cg[CG_SLOTS * i].xyz;
        positions_out[i] = vec4<f32>(p.xyz + v * params.substep_dt, p.w);
        velocities_out[i] = vec4<f32>(v, t);
    } else {
        let end = pin_end(i);
        positions_out[i] = vec4<f32>(end.x, p.w);
        velocities_out[i] = vec4<f32>(end.v, t);
    }
}

// Pass 9: the slopes of the incremental potential along the Newton iteration's change Δ of
// vertex i, at the iterate before the change (−Δ·b) and where the iterate is now
// (Δ·(M (v̄ + α Δ − v) − h f)): the full step pass 7 has taken, or a secant root of pass 10
// (cloth_core::reference's line_search_step).
fn line_search_slopes(i: u32) -> vec2<f32> {
    let p_bar = positions_out[i];
    if (p_bar.w <= 0.0) {
        return vec2<f32>(0.0);
    }
    let h = params.substep_dt;
    let nx = params.grid_nx;
    let v = velocities_out[i].xyz;
    let change = cg[CG_SLOTS * i].xyz;
    let b = vec3<f32>(blocks[5u * i].w, blocks[5u * i + 1u].w, blocks[5u * i + 2u].w);
    let f = iterate_force(i, i % nx, i / nx, p_bar.xyz, v, velocities_in[i].w + h).force;
    return vec2<f32>(-dot(change, b), dot(change, (v - velocities_in[i].xyz) * params.vertex_mass - f * h));
}

// Backward Euler's line search by regula falsi with the Illinois rule (cloth_core::solver's
// LineSearchBracket): step lengths lo < hi with slopes g(lo) < 0 ≤ g(hi), whether the search is on
// (the full step overshot), and which end the last cut replaced (0 none, 1 lo, 2 hi).
struct Bracket {
    lo: vec2<f32>,
    hi: vec2<f32>,
    open: bool,
    last: u32,
}

// The bracket after slope measurement r (from 1) lives in `steps`' last entries, three a
// measurement counted from the end, so that each pass reads its predecessor's while it writes its
// own.
fn bracket_at(r: u32) -> u32 {
    return arrayLength(&steps) - 3u * r;
}

fn read_bracket(r: u32) -> Bracket {
    let at = bracket_at(r);
    let lo = bitcast<vec2<f32>>(steps[at]);
    let hi = bitcast<vec2<f32>>(steps[at + 1u]);
    return Bracket(lo, hi, steps[at + 2u].x != 0u, steps[at + 2u].y);
}

fn write_bracket(r: u32, b: Bracket) {
    let at = bracket_at(r);
    steps[at] = bitcast<vec2<u32>>(b.lo);
    steps[at + 1u] = bitcast<vec2<u32>>(b.hi);
    steps[at + 2u] = vec2<u32>(select(0u, 1u, b.open), b.last);
}

// The root of the secant through the bracket's ends.
fn secant(b: Bracket) -> f32 {
    return b.lo.x + (b.hi.x - b.lo.x) * b.lo.y / (b.lo.y - b.hi.y);
}

// Pass 10 of slope measurement r, from the slopes' totals (−Δ·b, g at the iterate): the bracket
// [0, 1] where the full step overshoots (r = 1: g(0) < 0 < g(1)), else cut at its secant's root,
// where pass 9 measured (the end kept through two cuts in a row has its slope halved); the free vertex i's iterate moved from where it was measured to the new
// secant root, v̄ + α Δ. Without an overshoot the full step stays.
fn line_search_step(i: u32, r: u32, slopes: vec2<f32>, records: bool) {
    var trial = 1.0;
    var b: Bracket;
    if (r == 1u) {
        b = Bracket(vec2<f32>(0.0, slopes.x), vec2<f32>(1.0, slopes.y), (slopes.x < 0.0) & (slopes.y > 0.0), 0u);
    } else {
        b = read_bracket(r - 1u);
        if (b.open) {
            trial = secant(b);
            if (slopes.y < 0.0) {
                b.lo = vec2<f32>(trial, slopes.y);
                if (b.last == 1u) {
                    b.hi.y = b.hi.y * 0.5;
                }
                b.last = 1u;
            } else {
                b.hi = vec2<f32>(trial, slopes.y);
                if (b.last == 2u) {
                    b.lo.y = b.lo.y * 0.5;
                }
                b.last = 2u;
            }
        }
    }
    if (records) {
        write_bracket(r, b);
    }
    if (i >= params.vertex_count) {
        return;
    }
    let p = positions_in[i];
    if ((p.w <= 0.0) | !b.open) {
        return;
    }
    let v = velocities_out[i].xyz + cg[CG_SLOTS * i].xyz * (secant(b) - trial);
    positions_out[i] = vec4<f32>(p.xyz + v * params.substep_dt, p.w);
    velocities_out[i] = vec4<f32>(v, velocities_out[i].w);
}

// Pass 8; returns the vertex's displacement over the substep (w 1).
fn finish(i: u32) -> vec4<f32> {
    let p = positions_out[i];
    let t_end = velocities_in[i].w + params.substep_dt;
    var x = p.xyz;
    var v = velocities_out[i].xyz;
    if (EFFECT_FRICTION) {
        if (p.w > 0.0) {
            // Static friction at the substep's end: a vertex friction holds keeps its solved
            // position and loses its tangential velocity (the reference's backward_euler_substep
            // says why not its position too).
            let nx = params.grid_nx;
            let held = iterate_force(i, i % nx, i / nx, x, v, t_end);
            if (held.stuck) {
                let n = held.normal;
                v = n * dot(v, n);
            }
        }
    }
    if (EFFECT_SELF_COLLISION) {
        if (p.w > 0.0) {
            // The speed limit (self_collision.wgsl).
            let x0 = positions_in[i].xyz;
            x = limit_step(x0, x);
            v = limit_velocity(v);
            positions_out[i] = vec4<f32>(x, p.w);
        }
    }
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

@compute @workgroup_size(WORKGROUP_SIZE)
fn implicit(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
            @builtin(workgroup_id) group_id: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    // 2D dispatch: more than 65535 workgroups spill into y.
    let i = id.y * groups.x * WORKGROUP_SIZE + id.x;
    let group = group_id.y * groups.x + group_id.x;
    let vertex = i < params.vertex_count;
    let k = step.iteration;
    switch IMPLICIT_PASS {
        case 0u: {
            if (vertex) {
                start(i);
            }
            if (i == 0u) {
                counters.largest_b_norm = 0.0;
            }
        }
        case 1u, 2u: {
            var terms = vec2<f32>(0.0);
            if (vertex) {
                terms = linearise(i, IMPLICIT_PASS == 1u);
            }
            write_partial(terms, 0u, local, group);
        }
        case 3u, 4u: {
            var done = false;
            var beta = 0.0;
            if (IMPLICIT_PASS == 3u) {
                // The solve's start: r·z and |b| of the linearisation. The residual is measured
                // against |b| or the substep's largest earlier |b| (implicit.rs's
                // `conjugate_gradients`): done at once when b is within the tolerance of it.
                // Workgroup 0 raises `largest_b_norm` while others may read it; either value
                // gives the same maximum with this |b|.
                let initial = total_of(0u, local);
                let b_norm = sqrt(initial.y);
                let reference = max(b_norm, counters.largest_b_norm);
                done = b_norm <= counters.tolerance * reference;
                if ((group == 0u) & (local == 0u)) {
                    counters.newton += 1u;
                    counters.solve_iterations = 0u;
                    counters.b_norm = reference;
                    counters.largest_b_norm = reference;
                    steps[1] = vec2<u32>(bitcast<u32>(initial.x), select(0u, 1u, done));
                }
            } else {
                let end = end_iteration(k - 1u, local, group);
                done = end.done;
                beta = end.beta;
            }
            var pq = 0.0;
            if (vertex & !done) {
                pq = apply(i, k, beta);
            }
            write_partial(vec2<f32>(pq, 0.0), product_section(k), local, group);
        }
        case 5u: {
            let pq = total_of(product_section(k), local).x;
            let stop = (steps[k].y != 0u) | (pq <= 0.0);
            var terms = vec2<f32>(0.0);
            if (vertex & !stop) {
                let alpha = bitcast<f32>(steps[k].x) / pq;
                if (positions_out[i].w > 0.0) {
                    let p = cg[CG_SLOTS * i + direction_slot(k)].xyz;
                    cg[CG_SLOTS * i] = vec4<f32>(cg[CG_SLOTS * i].xyz + p * alpha, 0.0);
                }
                let r = cg[CG_SLOTS * i + 1u].xyz - cg[CG_SLOTS * i + 3u].xyz * alpha;
                cg[CG_SLOTS * i + 1u] = vec4<f32>(r, 0.0);
                let z = preconditioned(i, r);
                cg[CG_SLOTS * i + 4u] = vec4<f32>(z, 0.0);
                terms = vec2<f32>(dot(r, z), dot(r, r));
            }
            write_partial(terms, 2u, local, group);
        }
        case 6u: {
            end_iteration(k, local, group);
        }
        case 7u: {
            if ((group == 0u) & (local == 0u)) {
                counters.cg_most = max(counters.cg_most, counters.solve_iterations);
            }
            if (vertex) {
                newton_update(i);
            }
        }
        case 9u: {
            var terms = vec2<f32>(0.0);
            if (vertex) {
                terms = line_search_slopes(i);
            }
            write_partial(terms, 0u, local, group);
        }
        case 10u: {
            let slopes = total_of(0u, local);
            line_search_step(i, k, slopes, (group == 0u) & (local == 0u));
        }
        default: {
            if (EFFECT_SELF_COLLISION) {
                clear_motion(local);
            }
            var moved = vec4<f32>(0.0);
            if (vertex) {
                moved = finish(i);
            }
            if (EFFECT_SELF_COLLISION) {
                // The extents of the substep's displacements along the motion directions, which
                // the next check turns into its bound.
                record_motion(moved, local, group);
            }
        }
    }
}
