// The inspector's 3D view: the cloth straight from the simulation's position buffer (normals
// and colours computed here, on the GPU), the colliders and pin markers, and a ground grid.
// Prepended with layout.wgsl (the Collider the simulation uploads, checked against the Rust type)
// and colliders.wgsl (their signed distances, as the kernels evaluate them).

struct Camera {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    light: vec4<f32>,        // direction towards the light
};

struct ClothInfo {
    nx: u32,
    ny: u32,
    color_mode: u32,         // 0 plain, 1 strain, 2 contact, 3 speed
    strain_kind: u32,        // with strain: 0 structural, 1 shear, 2 bend
    collider_count: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    rest_du: f32,            // rest spacing along u, m
    rest_dv: f32,            // rest spacing along v, m
    speed_scale: f32,        // m/s shown as full colour
    strain_scale: f32,       // strain shown as full colour
};

@group(0) @binding(0) var<uniform> camera: Camera;
@group(0) @binding(1) var<uniform> cloth: ClothInfo;
@group(0) @binding(2) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> velocities: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> colliders: array<Collider>;   // at the drawn state's time
@group(0) @binding(6) var<storage, read> distance_fields: array<f32>;  // the mesh colliders' (colliders.wgsl)
// cs_vertex_colors only: each vertex's colour, what vs_cloth draws it with.
@group(0) @binding(5) var<storage, read_write> vertex_colors: array<vec4<f32>>;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec3<f32>,
    @location(2) world: vec3<f32>,
};

fn p(i: u32, j: u32) -> vec3<f32> {
    return positions[j * cloth.nx + i].xyz;
}

fn ramp(t: f32) -> vec3<f32> {
    let x = clamp(t, 0.0, 1.0);
    return mix(mix(vec3<f32>(0.15, 0.35, 0.9), vec3<f32>(0.2, 0.85, 0.3), min(x * 2.0, 1.0)),
               vec3<f32>(0.95, 0.2, 0.1), max(x * 2.0 - 1.0, 0.0));
}

// Contact state of a vertex at x moving at v: 0 free, 1 sticking (on a collider, within 0.2% of
// its size, its tolerance being 1e-6 of it; tangential speed below 1 mm/s), 2 sliding (the
// inspector's render tests check it against the same rule on the CPU).
fn contact_state(x: vec3<f32>, v: vec3<f32>) -> u32 {
    var state = 0u;
    for (var s = 0u; s < cloth.collider_count; s++) {
        let surface = collider_surface(s, colliders[s].center, x);
        if (surface.distance < colliders[s].tolerance * 2000.0) {
            let nrm = surface.normal;
            let v_t = v - nrm * dot(v, nrm);
            state = select(2u, 1u, sqrt(dot(v_t, v_t)) < 1e-3);
        }
    }
    return state;
}

// The colour of vertex `index` in the current colour mode.
fn vertex_color(index: u32) -> vec3<f32> {
    let i = index % cloth.nx;
    let j = index / cloth.nx;
    let x = p(i, j);
    let v = velocities[index].xyz;
    if (cloth.color_mode == 1u) {
        // Strain |L/L0 - 1| of one spring kind, averaged over the vertex's springs of that kind.
        var strain = 0.0;
        var n = 0.0;
        let du = cloth.rest_du;
        let dv = cloth.rest_dv;
        let nx = i32(cloth.nx);
        let ny = i32(cloth.ny);
        for (var k = 0; k < 4; k++) {
            var offset = vec2<i32>(0, 0);
            var rest = 0.0;
            if (cloth.strain_kind == 0u) {
                offset = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(-1, 0), vec2<i32>(0, 1), vec2<i32>(0, -1))[k];
                rest = select(dv, du, offset.y == 0);
            } else if (cloth.strain_kind == 1u) {
                offset = array<vec2<i32>, 4>(vec2<i32>(1, 1), vec2<i32>(-1, 1), vec2<i32>(1, -1), vec2<i32>(-1, -1))[k];
                rest = sqrt(du * du + dv * dv);
            } else {
                offset = array<vec2<i32>, 4>(vec2<i32>(2, 0), vec2<i32>(-2, 0), vec2<i32>(0, 2), vec2<i32>(0, -2))[k];
                rest = select(2.0 * dv, 2.0 * du, offset.y == 0);
            }
            let q = vec2<i32>(i32(i), i32(j)) + offset;
            if (q.x >= 0 && q.y >= 0 && q.x < nx && q.y < ny) {
                strain += abs(length(p(u32(q.x), u32(q.y)) - x) / rest - 1.0);
                n += 1.0;
            }
        }
        return ramp(strain / max(n, 1.0) / cloth.strain_scale);
    } else if (cloth.color_mode == 2u) {
        // Contact: free (grey-blue), sticking (green), sliding (red).
        return array<vec3<f32>, 3>(vec3<f32>(0.55, 0.6, 0.75), vec3<f32>(0.2, 0.8, 0.3), vec3<f32>(0.95, 0.25, 0.15))[contact_state(x, v)];
    } else if (cloth.color_mode == 3u) {
        return ramp(length(v) / cloth.speed_scale);
    }
    return vec3<f32>(0.92, 0.45, 0.2);
}

@vertex
fn vs_cloth(@builtin(vertex_index) index: u32) -> VsOut {
    let i = index % cloth.nx;
    let j = index / cloth.nx;
    let x = p(i, j);
    let du = p(min(i + 1u, cloth.nx - 1u), j) - p(max(i, 1u) - 1u, j);
    let dv = p(i, min(j + 1u, cloth.ny - 1u)) - p(i, max(j, 1u) - 1u);
    var out: VsOut;
    out.clip = camera.view_proj * vec4<f32>(x, 1.0);
    out.normal = normalize(cross(du, dv));
    out.world = x;
    out.color = vertex_color(index);
    return out;
}

// Every vertex's colour into vertex_colors: what vs_cloth draws, for checking it against the CPU.
@compute @workgroup_size(64)
fn cs_vertex_colors(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x < cloth.nx * cloth.ny) {
        vertex_colors[id.x] = vec4<f32>(vertex_color(id.x), 1.0);
    }
}

fn shade(normal: vec3<f32>, color: vec3<f32>) -> vec3<f32> {
    let l = normalize(camera.light.xyz);
    let diffuse = max(dot(normal, l), 0.0);
    return color * (0.3 + 0.7 * diffuse);
}

@fragment
fn fs_cloth(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = normalize(in.normal);
    var color = in.color;
    if (!front) {
        n = -n;
        color = color * vec3<f32>(0.55, 0.75, 1.0);
    }
    return vec4<f32>(shade(n, color), 1.0);
}

// A cloth triangle a cloth edge passes through: red on both sides.
@fragment
fn fs_crossed(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let n = select(-normalize(in.normal), normalize(in.normal), front);
    return vec4<f32>(shade(n, vec3<f32>(0.95, 0.05, 0.05)), 1.0);
}

@fragment
fn fs_wire(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(0.08, 0.08, 0.1, 1.0);
}

struct Instance {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) center_radius: vec4<f32>,
    @location(3) color: vec4<f32>,
};

@vertex
fn vs_instance(in: Instance) -> VsOut {
    let world = in.center_radius.xyz + in.position * in.center_radius.w;
    var out: VsOut;
    out.clip = camera.view_proj * vec4<f32>(world, 1.0);
    out.normal = in.normal;
    out.color = in.color.rgb;
    out.world = world;
    return out;
}

@fragment
fn fs_lit(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(normalize(in.normal), in.color), 1.0);
}

struct LineVertex {
    @location(0) position: vec3<f32>,
    @location(1) color: vec4<f32>,
};

@vertex
fn vs_line(in: LineVertex) -> VsOut {
    var out: VsOut;
    out.clip = camera.view_proj * vec4<f32>(in.position, 1.0);
    out.normal = vec3<f32>(0.0, 1.0, 0.0);
    out.color = in.color.rgb;
    out.world = in.position;
    return out;
}

@fragment
fn fs_line(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(in.color, 1.0);
}
