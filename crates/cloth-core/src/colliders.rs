//! Colliders: the shapes the cloth meets, and the signed distance from a point to each.
//!
//! Every collider kind is a shape plus the same contact parameters (`k_c`, `c_f`, normal damping)
//! and the same prescribed [`Motion`]. The force model ([`crate::forces::contact_force`]) and
//! XPBD's projection ([`crate::constraints::project_onto_surface`]) see a collider only through
//! its [`Surface`] at a point: the signed distance `φ(x)` (m, negative inside) and the outward
//! unit normal `n(x) = ∇φ`. A vertex penetrates when `φ < 0`, by the depth `d = −φ`.
//!
//! | kind | scene shape | `φ(x)` |
//! |---|---|---|
//! | sphere | `Sphere(center: c, radius: r)` | `‖x − c‖ − r` |
//! | ground plane | `Plane(normal: n, offset: o)` | `n·x − o` (the half-space below is solid) |
//! | capsule | `Capsule(a, b, radius: r)` | `‖x − p‖ − r`, `p` the point of segment `ab` nearest `x` |
//! | oriented box | `Box(center, half_extents: h, axis, angle, rounding: ρ)` | `‖max(q, 0)‖ + min(max_k q_k, 0) − ρ`, `q = |Rᵀ(x − c)| − (h − ρ)` |
//! | triangle mesh | `Mesh(file, center, scale, axis, angle, cells)` | trilinear in a sampled field of `Rᵀ(x − c)` ([`crate::mesh`]) |
//!
//! Shapes are placed once, in `f64`, into a [`Placement`] (centre, three axes, radius, extents):
//! the CPU reference converts it to its precision and the GPU backends to their `f32`
//! `GpuCollider`, so they evaluate the same numbers with the same operations
//! (`shaders/wgsl/colliders.wgsl`, `shaders/glsl/colliders.glsl`).

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::mesh::DistanceField;
use crate::real::{Real, Vec3};
use crate::scene::{Motion, SphereSpec};

/// A collider of a scene: a shape and its contact parameters.
///
/// ```ron
/// colliders: [
///     (shape: Plane(normal: (0, 1, 0), offset: 0.0), friction: 0.8),
///     (shape: Capsule(a: (-1, 0.5, 0), b: (1, 0.5, 0), radius: 0.1)),
/// ]
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ColliderSpec {
    /// The shape. Default: the default sphere.
    pub shape: Shape,
    /// Contact (penalty) stiffness `k_c`, N/m: `F_c = k_c d`. Default 1000.
    pub stiffness: f64,
    /// Friction coefficient `c_f` (dimensionless). Default 0.5.
    pub friction: f64,
    /// Damping of the normal approach velocity while in contact, N·s/m. Default 0.2.
    pub damping: f64,
    /// How the collider moves (translation only), for the `MovingColliders` effect. Default: no
    /// motion.
    pub motion: Motion,
}

impl Default for ColliderSpec {
    fn default() -> Self {
        SphereSpec::default().into()
    }
}

impl From<SphereSpec> for ColliderSpec {
    fn from(s: SphereSpec) -> Self {
        Self {
            shape: Shape::Sphere { center: s.center, radius: s.radius },
            stiffness: s.stiffness,
            friction: s.friction,
            damping: s.damping,
            motion: s.motion,
        }
    }
}

impl ColliderSpec {
    /// A collider of `shape` with the default contact parameters.
    pub fn of(shape: Shape) -> Self {
        Self { shape, ..Self::default() }
    }

    /// Its kind.
    pub fn kind(&self) -> ColliderKind {
        self.shape.kind()
    }

    /// The collider as a [`SphereSpec`], when it is a sphere.
    pub fn sphere(&self) -> Option<SphereSpec> {
        match self.shape {
            Shape::Sphere { center, radius } => Some(SphereSpec {
                center,
                radius,
                stiffness: self.stiffness,
                friction: self.friction,
                damping: self.damping,
                motion: self.motion,
            }),
            _ => None,
        }
    }
}

/// The geometry of a collider, m. Rotations are an axis and an angle in degrees.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Shape {
    /// A ball.
    Sphere {
        /// Centre, m.
        center: [f64; 3],
        /// Radius, m.
        radius: f64,
    },
    /// The solid half-space `n·x ≤ offset` (a ground when `normal` points up).
    Plane {
        /// Outward normal (normalised at load; must not be zero).
        #[serde(default = "up")]
        normal: [f64; 3],
        /// Signed distance of the plane from the origin along `normal`, m. Default 0.
        #[serde(default)]
        offset: f64,
    },
    /// The points within `radius` of the segment from `a` to `b`.
    Capsule {
        /// One end of the axis, m.
        a: [f64; 3],
        /// The other end, m (distinct from `a`).
        b: [f64; 3],
        /// Radius, m.
        radius: f64,
    },
    /// A box rotated by `angle` degrees about `axis`, its edges rounded by `rounding`.
    Box {
        /// Centre, m.
        center: [f64; 3],
        /// Half the side lengths along the box's own axes, m (each > 0).
        half_extents: [f64; 3],
        /// Axis of the rotation (normalised at load). Default `(0, 1, 0)`.
        #[serde(default = "up")]
        axis: [f64; 3],
        /// Rotation angle, degrees. Default 0.
        #[serde(default)]
        angle: f64,
        /// Radius of the rounded edges and corners, m, at most the smallest half extent.
        /// Default 0 (sharp).
        #[serde(default)]
        rounding: f64,
    },
    /// A closed triangle mesh from a Wavefront OBJ file, rotated by `angle` degrees about `axis`,
    /// scaled, and moved so that its origin is at `center`; sampled once as a signed distance
    /// field ([`crate::mesh`]).
    Mesh {
        /// The OBJ file: a path relative to the scene file's folder, or absolute.
        file: String,
        /// Where the mesh's origin goes, m. Default `(0, 0, 0)`.
        #[serde(default)]
        center: [f64; 3],
        /// Factor on the file's coordinates, m per file unit. Default 1.
        #[serde(default = "one")]
        scale: f64,
        /// Axis of the rotation (normalised at load). Default `(0, 1, 0)`.
        #[serde(default = "up")]
        axis: [f64; 3],
        /// Rotation angle, degrees. Default 0.
        #[serde(default)]
        angle: f64,
        /// Cells of the distance field along the mesh's longest side (2 to
        /// [`crate::mesh::MAX_CELLS`]). Default 32.
        #[serde(default = "default_cells")]
        cells: u32,
    },
}

fn up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

fn one() -> f64 {
    1.0
}

fn default_cells() -> u32 {
    32
}

impl Shape {
    /// Its kind.
    pub fn kind(&self) -> ColliderKind {
        match self {
            Shape::Sphere { .. } => ColliderKind::Sphere,
            Shape::Plane { .. } => ColliderKind::Plane,
            Shape::Capsule { .. } => ColliderKind::Capsule,
            Shape::Box { .. } => ColliderKind::Box,
            Shape::Mesh { .. } => ColliderKind::Mesh,
        }
    }

    /// A mesh's distance field (read and sampled the first time it is asked for; see
    /// [`crate::mesh::load`]); `None` for the other kinds.
    pub fn distance_field(&self) -> Option<Result<Arc<DistanceField>, crate::mesh::MeshError>> {
        match self {
            Shape::Mesh { file, scale, cells, .. } => {
                Some(crate::mesh::load(std::path::Path::new(file), *scale, *cells))
            }
            _ => None,
        }
    }

    /// The point the collider's [`Motion`] moves, m: the centre (a plane's point nearest the
    /// origin, a capsule's midpoint).
    pub fn anchor(&self) -> [f64; 3] {
        Placement::of(self).center
    }

    /// A box around the shape at time 0, `(low, high)` corners, m; `None` for a plane (unbounded).
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let around = |c: [f64; 3], r: [f64; 3]| Some(([0, 1, 2].map(|k| c[k] - r[k]), [0, 1, 2].map(|k| c[k] + r[k])));
        match *self {
            Shape::Sphere { center, radius } => around(center, [radius; 3]),
            Shape::Plane { .. } => None,
            Shape::Capsule { a, b, radius } => {
                Some(([0, 1, 2].map(|k| a[k].min(b[k]) - radius), [0, 1, 2].map(|k| a[k].max(b[k]) + radius)))
            }
            Shape::Box { center, half_extents, .. } => {
                let p = Placement::of(self);
                // The rotated box's reach along each world axis: Σ_k |axis_k · e_i| h_k.
                let reach = [0, 1, 2].map(|i| (0..3).map(|k| p.axes[k][i].abs() * half_extents[k]).sum());
                around(center, reach)
            }
            Shape::Mesh { center, .. } => {
                let p = Placement::of(self);
                let field = p.field?;
                // The sampled grid's corners, rotated and moved.
                let size = field.dims.map(|d| (d - 1) as f64 * field.cell);
                let mut low = [f64::INFINITY; 3];
                let mut high = [f64::NEG_INFINITY; 3];
                for corner in 0..8 {
                    let local = [0, 1, 2].map(|k| field.origin[k] + if corner >> k & 1 == 1 { size[k] } else { 0.0 });
                    for i in 0..3 {
                        let world = center[i] + (0..3).map(|k| p.axes[k][i] * local[k]).sum::<f64>();
                        low[i] = low[i].min(world);
                        high[i] = high[i].max(world);
                    }
                }
                Some((low, high))
            }
        }
    }

    /// Moves the shape by `d`, m.
    pub fn translate(&mut self, d: [f64; 3]) {
        let add = |p: &mut [f64; 3]| (0..3).for_each(|k| p[k] += d[k]);
        match self {
            Shape::Sphere { center, .. } | Shape::Box { center, .. } | Shape::Mesh { center, .. } => add(center),
            Shape::Capsule { a, b, .. } => {
                add(a);
                add(b);
            }
            Shape::Plane { normal, offset } => {
                let n = normalized(*normal);
                *offset += n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
            }
        }
    }
}

/// The kinds of collider. A kind no collider of the scene has is compiled out of the GPU
/// pipelines (a boolean constant per kind, [`ColliderKind::shader_constant_name`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ColliderKind {
    /// [`Shape::Sphere`].
    Sphere,
    /// [`Shape::Plane`].
    Plane,
    /// [`Shape::Capsule`].
    Capsule,
    /// [`Shape::Box`].
    Box,
    /// [`Shape::Mesh`].
    Mesh,
}

impl ColliderKind {
    /// Every kind, in the order of their codes (`kind` of the GPU struct).
    pub const ALL: [ColliderKind; 5] =
        [ColliderKind::Sphere, ColliderKind::Plane, ColliderKind::Capsule, ColliderKind::Box, ColliderKind::Mesh];

    /// The kind's code in the GPU struct.
    pub fn code(self) -> u32 {
        self as u32
    }

    /// Name of the boolean shader constant that compiles this kind in or out.
    pub fn shader_constant_name(self) -> &'static str {
        match self {
            ColliderKind::Sphere => "COLLIDER_SPHERE",
            ColliderKind::Plane => "COLLIDER_PLANE",
            ColliderKind::Capsule => "COLLIDER_CAPSULE",
            ColliderKind::Box => "COLLIDER_BOX",
            ColliderKind::Mesh => "COLLIDER_MESH",
        }
    }

    /// Lower-case name, as the tools print it.
    pub fn name(self) -> &'static str {
        match self {
            ColliderKind::Sphere => "sphere",
            ColliderKind::Plane => "plane",
            ColliderKind::Capsule => "capsule",
            ColliderKind::Box => "box",
            ColliderKind::Mesh => "mesh",
        }
    }
}

/// The most colliders a scene may have. The GPU kernels read the colliders from a uniform block
/// of this many (every thread of a kernel reads the same collider at once, which a uniform block
/// serves from the constant cache).
pub const MAX_COLLIDERS: usize = 64;

/// Relative distance within which XPBD's friction treats a projected vertex as on the surface
/// (of the collider's size; [`Placement::tolerance`]).
pub const ON_SURFACE: f64 = 1e-6;

/// A shape placed for evaluation, in `f64`: the fields of the GPU's `GpuCollider`.
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// The kind.
    pub kind: ColliderKind,
    /// Centre at time 0 (sphere, box), a capsule's midpoint, a plane's point nearest the origin, m.
    pub center: [f64; 3],
    /// The collider's axes, unit and orthogonal: a box's rotated axes, a capsule's `axes[0]` along
    /// `b − a`, a plane's `axes[1]` its normal.
    pub axes: [[f64; 3]; 3],
    /// Radius (sphere, capsule), rounding (box) or the distance field's cell (mesh), m.
    pub radius: f64,
    /// A capsule's half length (`extent[0]`); a box's half extents less the rounding; the
    /// origin of a mesh's distance field in its own coordinates, m.
    pub extent: [f64; 3],
    /// The thinnest the collider is, m (∞ for a plane): a path shorter than this cannot cross
    /// it, so XPBD sweeps only longer paths (see [`crate::constraints::project_swept`]).
    pub thickness: f64,
    /// Distance from the surface within which a vertex counts as on it, m
    /// ([`ON_SURFACE`] × the collider's size).
    pub tolerance: f64,
    /// A mesh's distance field (`None` for the other kinds, and for a mesh that cannot be read,
    /// which validation refuses).
    pub field: Option<Arc<DistanceField>>,
}

fn normalized(v: [f64; 3]) -> [f64; 3] {
    let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if length > 0.0 { v.map(|x| x / length) } else { [0.0, 1.0, 0.0] }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Two unit vectors completing `n` to a right-handed orthonormal basis `(t, n, b)`.
fn basis_around(n: [f64; 3]) -> [[f64; 3]; 3] {
    let helper = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 0.0, 1.0] };
    let b = normalized(cross(helper, n));
    let t = cross(n, b);
    [t, n, b]
}

/// The rotation by `angle_deg` degrees about `axis` (Rodrigues), as its three columns.
pub fn rotation_columns(axis: [f64; 3], angle_deg: f64) -> [[f64; 3]; 3] {
    let k = normalized(axis);
    let (s, c) = angle_deg.to_radians().sin_cos();
    let rotate = |v: [f64; 3]| {
        let kxv = cross(k, v);
        let kv = k[0] * v[0] + k[1] * v[1] + k[2] * v[2];
        [0, 1, 2].map(|i| v[i] * c + kxv[i] * s + k[i] * kv * (1.0 - c))
    };
    [rotate([1.0, 0.0, 0.0]), rotate([0.0, 1.0, 0.0]), rotate([0.0, 0.0, 1.0])]
}

impl Placement {
    /// Places a shape. The shape should have been validated; an invalid one places without
    /// panicking (a zero normal or axis becomes `+Y`).
    pub fn of(shape: &Shape) -> Self {
        let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        match *shape {
            Shape::Sphere { center, radius } => Self {
                kind: ColliderKind::Sphere,
                center,
                axes: identity,
                radius,
                extent: [0.0; 3],
                thickness: 2.0 * radius,
                tolerance: ON_SURFACE * radius,
                field: None,
            },
            Shape::Plane { normal, offset } => {
                let n = normalized(normal);
                Self {
                    kind: ColliderKind::Plane,
                    center: n.map(|x| x * offset),
                    axes: basis_around(n),
                    radius: 0.0,
                    extent: [0.0; 3],
                    thickness: f64::INFINITY,
                    tolerance: ON_SURFACE * offset.abs().max(1.0),
                    field: None,
                }
            }
            Shape::Capsule { a, b, radius } => {
                let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let length = (ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2]).sqrt();
                let [t, n, bn] = basis_around(normalized(ab));
                Self {
                    kind: ColliderKind::Capsule,
                    center: [0, 1, 2].map(|k| 0.5 * (a[k] + b[k])),
                    // axes[0] along the capsule.
                    axes: [n, bn, t],
                    radius,
                    extent: [0.5 * length, 0.0, 0.0],
                    thickness: 2.0 * radius,
                    tolerance: ON_SURFACE * radius,
                    field: None,
                }
            }
            Shape::Box { center, half_extents, axis, angle, rounding } => {
                let smallest = half_extents.iter().copied().fold(f64::INFINITY, f64::min);
                Self {
                    kind: ColliderKind::Box,
                    center,
                    axes: rotation_columns(axis, angle),
                    radius: rounding,
                    extent: half_extents.map(|h| h - rounding),
                    thickness: 2.0 * smallest,
                    tolerance: ON_SURFACE * half_extents.iter().copied().fold(0.0, f64::max),
                    field: None,
                }
            }
            Shape::Mesh { center, axis, angle, .. } => {
                let field = shape.distance_field().and_then(Result::ok);
                let (origin, cell, size) = field.as_ref().map_or(([0.0; 3], 0.0, 0.0), |f| {
                    (f.origin, f.cell, f.dims.iter().map(|&d| (d - 1) as f64 * f.cell).fold(0.0, f64::max))
                });
                Self {
                    kind: ColliderKind::Mesh,
                    center,
                    axes: rotation_columns(axis, angle),
                    radius: cell,
                    extent: origin,
                    // Paths longer than two cells are swept: the field resolves nothing thinner.
                    thickness: 2.0 * cell,
                    tolerance: ON_SURFACE * size,
                    field,
                }
            }
        }
    }
}

/// A collider's surface seen from a point: the signed distance `φ` (m, negative inside) and the
/// outward unit normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface<R> {
    /// Signed distance `φ(x)`, m.
    pub distance: R,
    /// Outward unit normal at the nearest surface point.
    pub normal: Vec3<R>,
}

/// A [`Placement`] in precision `R`, with its contact parameters and motion: what a solver
/// evaluates.
#[derive(Clone, Debug)]
pub struct Collider<R> {
    /// The kind.
    pub kind: ColliderKind,
    /// Centre at time 0, m.
    pub center: Vec3<R>,
    /// The axes (see [`Placement::axes`]).
    pub axes: [Vec3<R>; 3],
    /// Radius or rounding, m.
    pub radius: R,
    /// Half length or reduced half extents, m.
    pub extent: Vec3<R>,
    /// Thinnest width, m.
    pub thickness: R,
    /// On-surface tolerance, m.
    pub tolerance: R,
    /// `k_c`, N/m.
    pub stiffness: R,
    /// `c_f`.
    pub friction: R,
    /// Normal damping, N·s/m.
    pub damping: R,
    /// The motion of its centre.
    pub motion: crate::motion::MotionOf<R>,
    /// A mesh's distance field.
    pub field: Option<Arc<DistanceField>>,
}

impl<R: Real> Collider<R> {
    /// Converts a scene collider.
    pub fn of(spec: &ColliderSpec) -> Self {
        let p = Placement::of(&spec.shape);
        Self {
            kind: p.kind,
            center: Vec3::from_f64(p.center),
            axes: p.axes.map(Vec3::from_f64),
            radius: R::of(p.radius),
            extent: Vec3::from_f64(p.extent),
            thickness: R::of(p.thickness),
            tolerance: R::of(p.tolerance),
            stiffness: R::of(spec.stiffness),
            friction: R::of(spec.friction),
            damping: R::of(spec.damping),
            motion: crate::motion::MotionOf::of(&spec.motion),
            field: p.field,
        }
    }

    /// Centre (m) and velocity (m/s) at time `t`: moving only when `moving` (the
    /// `MovingColliders` effect).
    pub fn at(&self, t: R, moving: bool) -> (Vec3<R>, Vec3<R>) {
        if moving {
            (self.center + self.motion.displacement(t), self.motion.velocity_at(t))
        } else {
            (self.center, Vec3::zero())
        }
    }

    /// The signed distance `φ(x)` alone, m, with the collider's centre at `center`: exactly
    /// [`Self::surface`]'s distance, by the same operations, without the normal (a vertex far
    /// from the collider, the common case, needs no more: the kernels skip a division per vertex
    /// and collider).
    pub fn distance(&self, center: Vec3<R>, x: Vec3<R>) -> R {
        match self.kind {
            ColliderKind::Sphere => sphere_distance(x, center, self.radius),
            ColliderKind::Plane => (x - center).dot(self.axes[1]),
            ColliderKind::Capsule => capsule_distance(x, center, self.axes[0], self.extent.x, self.radius),
            ColliderKind::Box => box_distance(x, center, &self.axes, self.extent, self.radius),
            ColliderKind::Mesh => match &self.field {
                Some(field) => {
                    let d = x - center;
                    field.distance(Vec3::new(d.dot(self.axes[0]), d.dot(self.axes[1]), d.dot(self.axes[2])))
                }
                None => R::infinity(),
            },
        }
    }

    /// The surface seen from `x` with the collider's centre at `center`.
    pub fn surface(&self, center: Vec3<R>, x: Vec3<R>) -> Surface<R> {
        match self.kind {
            ColliderKind::Sphere => sphere_surface(x, center, self.radius),
            ColliderKind::Plane => plane_surface(x, center, self.axes[1]),
            ColliderKind::Capsule => capsule_surface(x, center, self.axes[0], self.extent.x, self.radius, self.axes[1]),
            ColliderKind::Box => box_surface(x, center, &self.axes, self.extent, self.radius),
            ColliderKind::Mesh => match &self.field {
                Some(field) => mesh_surface(x, center, &self.axes, field),
                None => Surface { distance: R::infinity(), normal: Vec3::new(R::zero(), R::one(), R::zero()) },
            },
        }
    }
}

/// `φ = ‖x − c‖ − r`, `n = (x − c)/‖x − c‖` (`+Y` at the centre).
pub fn sphere_surface<R: Real>(x: Vec3<R>, center: Vec3<R>, radius: R) -> Surface<R> {
    let offset = x - center;
    let distance = offset.dot(offset).sqrt();
    let normal =
        if distance > R::zero() { offset * (R::one() / distance) } else { Vec3::new(R::zero(), R::one(), R::zero()) };
    Surface { distance: distance - radius, normal }
}

/// [`sphere_surface`]'s distance alone.
pub fn sphere_distance<R: Real>(x: Vec3<R>, center: Vec3<R>, radius: R) -> R {
    let offset = x - center;
    offset.dot(offset).sqrt() - radius
}

/// [`capsule_surface`]'s distance alone.
pub fn capsule_distance<R: Real>(x: Vec3<R>, center: Vec3<R>, axis: Vec3<R>, half_length: R, radius: R) -> R {
    let along = (x - center).dot(axis).max(-half_length).min(half_length);
    let offset = x - (center + axis * along);
    offset.dot(offset).sqrt() - radius
}

/// [`box_surface`]'s distance alone.
pub fn box_distance<R: Real>(x: Vec3<R>, center: Vec3<R>, axes: &[Vec3<R>; 3], extent: Vec3<R>, rounding: R) -> R {
    let d = x - center;
    let q = [d.dot(axes[0]).abs() - extent.x, d.dot(axes[1]).abs() - extent.y, d.dot(axes[2]).abs() - extent.z];
    let outside = [q[0].max(R::zero()), q[1].max(R::zero()), q[2].max(R::zero())];
    let outside_length = (outside[0] * outside[0] + outside[1] * outside[1] + outside[2] * outside[2]).sqrt();
    if outside_length > R::zero() {
        return outside_length - rounding;
    }
    let largest = if q[0] >= q[1] && q[0] >= q[2] {
        q[0]
    } else if q[1] >= q[2] {
        q[1]
    } else {
        q[2]
    };
    largest - rounding
}

/// `φ = n·(x − p)`, `p` a point of the plane.
pub fn plane_surface<R: Real>(x: Vec3<R>, point: Vec3<R>, normal: Vec3<R>) -> Surface<R> {
    Surface { distance: (x - point).dot(normal), normal }
}

/// `φ = ‖x − p‖ − r` with `p = c + clamp((x − c)·a, −e, e) a` the nearest point of the axis
/// (`a` its direction, `e` its half length); at the axis itself the normal is `fallback`.
pub fn capsule_surface<R: Real>(
    x: Vec3<R>,
    center: Vec3<R>,
    axis: Vec3<R>,
    half_length: R,
    radius: R,
    fallback: Vec3<R>,
) -> Surface<R> {
    let along = (x - center).dot(axis).max(-half_length).min(half_length);
    let offset = x - (center + axis * along);
    let distance = offset.dot(offset).sqrt();
    let normal = if distance > R::zero() { offset * (R::one() / distance) } else { fallback };
    Surface { distance: distance - radius, normal }
}

/// A rounded box: with `p = Rᵀ(x − c)` in the box's axes and `q = |p| − e` (`e` the half extents
/// less the rounding `ρ`), `φ = ‖max(q, 0)‖ + min(max_k q_k, 0) − ρ`. Outside the core box the
/// normal points from its nearest point; inside, along the axis of the nearest face.
pub fn box_surface<R: Real>(
    x: Vec3<R>,
    center: Vec3<R>,
    axes: &[Vec3<R>; 3],
    extent: Vec3<R>,
    rounding: R,
) -> Surface<R> {
    let d = x - center;
    let p = [d.dot(axes[0]), d.dot(axes[1]), d.dot(axes[2])];
    let e = [extent.x, extent.y, extent.z];
    let q = [p[0].abs() - e[0], p[1].abs() - e[1], p[2].abs() - e[2]];
    let sign = |v: R| if v < R::zero() { -R::one() } else { R::one() };
    let outside = [q[0].max(R::zero()), q[1].max(R::zero()), q[2].max(R::zero())];
    let outside_length = (outside[0] * outside[0] + outside[1] * outside[1] + outside[2] * outside[2]).sqrt();
    if outside_length > R::zero() {
        let scale = R::one() / outside_length;
        let local = [sign(p[0]) * outside[0] * scale, sign(p[1]) * outside[1] * scale, sign(p[2]) * outside[2] * scale];
        let normal = axes[0] * local[0] + axes[1] * local[1] + axes[2] * local[2];
        return Surface { distance: outside_length - rounding, normal };
    }
    // Inside the core box: the nearest face is the axis of the largest q (ties to the first).
    let k = if q[0] >= q[1] && q[0] >= q[2] {
        0
    } else if q[1] >= q[2] {
        1
    } else {
        2
    };
    Surface { distance: q[k] - rounding, normal: axes[k] * sign(p[k]) }
}

/// A mesh: its distance field at `p = Rᵀ(x − c)` ([`DistanceField::surface`]), the normal
/// rotated back, `R n`.
pub fn mesh_surface<R: Real>(x: Vec3<R>, center: Vec3<R>, axes: &[Vec3<R>; 3], field: &DistanceField) -> Surface<R> {
    let d = x - center;
    let local = field.surface(Vec3::new(d.dot(axes[0]), d.dot(axes[1]), d.dot(axes[2])));
    let n = local.normal;
    Surface { distance: local.distance, normal: axes[0] * n.x + axes[1] * n.y + axes[2] * n.z }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vec3<f64> {
        Vec3::new(x, y, z)
    }

    fn collider(shape: Shape) -> Collider<f64> {
        Collider::of(&ColliderSpec::of(shape))
    }

    fn phi(c: &Collider<f64>, x: Vec3<f64>) -> f64 {
        c.surface(c.center, x).distance
    }

    /// The normal is the gradient of φ, checked by central differences.
    fn assert_normal_is_gradient(c: &Collider<f64>, x: Vec3<f64>) {
        let h = 1e-6;
        let g = v(
            (phi(c, x + v(h, 0., 0.)) - phi(c, x - v(h, 0., 0.))) / (2. * h),
            (phi(c, x + v(0., h, 0.)) - phi(c, x - v(0., h, 0.))) / (2. * h),
            (phi(c, x + v(0., 0., h)) - phi(c, x - v(0., 0., h))) / (2. * h),
        );
        let n = c.surface(c.center, x).normal;
        assert!((g - n).length() < 1e-6, "gradient {g:?} vs normal {n:?} at {x:?}");
    }

    #[test]
    fn a_plane_is_the_distance_along_its_normal() {
        let c = collider(Shape::Plane { normal: [0., 2., 0.], offset: 0.5 });
        assert!((phi(&c, v(3., 1.5, -2.)) - 1.0).abs() < 1e-12);
        assert!((phi(&c, v(0., 0.25, 0.)) + 0.25).abs() < 1e-12);
        assert_normal_is_gradient(&c, v(0.3, 0.7, 0.1));
    }

    #[test]
    fn a_capsule_is_the_distance_to_its_axis_less_the_radius() {
        let c = collider(Shape::Capsule { a: [-1., 1., 0.], b: [1., 1., 0.], radius: 0.2 });
        assert!((phi(&c, v(0.5, 1.5, 0.)) - 0.3).abs() < 1e-12, "beside the axis");
        assert!((phi(&c, v(2., 1., 0.)) - 0.8).abs() < 1e-12, "beyond an end");
        assert!((phi(&c, v(0., 1.1, 0.)) + 0.1).abs() < 1e-12, "inside");
        for x in [v(0.5, 1.5, 0.3), v(1.5, 0.7, 0.2), v(-0.3, 1.05, 0.)] {
            assert_normal_is_gradient(&c, x);
        }
    }

    #[test]
    fn a_box_is_exact_outside_inside_and_on_rounded_edges() {
        let c = collider(Shape::Box {
            center: [0., 1., 0.],
            half_extents: [1., 0.5, 2.],
            axis: [0., 1., 0.],
            angle: 0.0,
            rounding: 0.0,
        });
        assert!((phi(&c, v(0., 2., 0.)) - 0.5).abs() < 1e-12, "above the top face");
        assert!((phi(&c, v(2., 2.5, 0.)) - (1f64 + 1.0).sqrt()).abs() < 1e-12, "off an edge");
        assert!((phi(&c, v(0.2, 1.3, 0.)) + 0.2).abs() < 1e-12, "inside, nearest the top");
        let rounded = collider(Shape::Box {
            center: [0., 0., 0.],
            half_extents: [1., 1., 1.],
            axis: [0., 0., 1.],
            angle: 30.0,
            rounding: 0.25,
        });
        // A rounded box's corner is a sphere of radius ρ around the core box's corner.
        let corner = rotation_columns([0., 0., 1.], 30.0);
        let dir =
            (Vec3::from_f64(corner[0]) + Vec3::from_f64(corner[1]) + Vec3::from_f64(corner[2])) * (1.0 / 3f64.sqrt());
        assert!((phi(&rounded, dir * (0.75 * 3f64.sqrt() + 0.25)) - 0.0).abs() < 1e-12);
        for x in [v(1.3, 0.2, 0.1), v(0.9, 1.2, -1.1), v(0.1, 0.2, 0.3), v(-0.2, -1.3, 0.4)] {
            assert_normal_is_gradient(&rounded, x);
        }
    }

    #[test]
    fn a_sphere_spec_becomes_a_sphere_collider_with_its_parameters() {
        let s = SphereSpec { radius: 0.3, friction: 0.9, ..Default::default() };
        let c: ColliderSpec = s.clone().into();
        assert_eq!(c.shape, Shape::Sphere { center: s.center, radius: 0.3 });
        assert_eq!((c.friction, c.stiffness, c.damping), (0.9, s.stiffness, s.damping));
    }

    #[test]
    fn translating_a_plane_moves_its_offset_along_the_normal() {
        let mut s = Shape::Plane { normal: [0., 1., 0.], offset: 0.0 };
        s.translate([5., 0.25, 1.]);
        assert_eq!(s, Shape::Plane { normal: [0., 1., 0.], offset: 0.25 });
    }
}
