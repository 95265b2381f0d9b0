//! The colliders as triangle meshes, for whatever draws or exports them (the inspector's view,
//! the glTF and OBJ exports): a plane as a square around the cloth's start, a mesh collider as its
//! own triangles, and every other kind as a sphere around it whose vertices are moved onto its
//! surface along the gradient of its signed distance (`x ← x − φ(x) n(x)`, a few times: exact for
//! these convex shapes).

use crate::colliders::{Collider, ColliderKind};
use crate::real::Vec3;
use crate::scene::Scene;

/// Half the side of the square a plane is drawn as, m.
pub const PLANE_HALF_SIDE: f64 = 8.0;
/// Segments around and rings from pole to pole of the sphere the curved colliders start from.
pub const SPHERE_SEGMENTS: [u32; 2] = [48, 24];

/// A triangle mesh in world space, m: per-vertex positions and unit normals, three indices a
/// triangle, counter-clockwise seen from the side the normals point to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions, m.
    pub positions: Vec<[f32; 3]>,
    /// Unit normals, one a vertex.
    pub normals: Vec<[f32; 3]>,
    /// Three vertex indices a triangle.
    pub indices: Vec<u32>,
}

impl TriangleMesh {
    /// Appends `other`, its indices shifted past this mesh's vertices.
    pub fn append(&mut self, other: &TriangleMesh) {
        let first = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.indices.extend(other.indices.iter().map(|i| first + i));
    }
}

/// A unit sphere of `segments` around and `rings` from pole to pole: positions (which are also
/// the normals) and indices, counter-clockwise seen from outside.
pub fn unit_sphere(segments: u32, rings: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut vertices = Vec::new();
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = 2.0 * std::f32::consts::PI * s as f32 / segments as f32;
            vertices.push([theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()]);
        }
    }
    let mut indices = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = r * (segments + 1) + s;
            let b = a + segments + 1;
            indices.extend_from_slice(&[a, a + 1, b, a + 1, b + 1, b]);
        }
    }
    (vertices, indices)
}

/// Collider `index` of `scene` at simulated time `t_s` (s), where it is then (moved only with
/// `MovingColliders`). Curved surfaces are drawn `inset` (a fraction of the collider's contact
/// thickness) inside: the cloth rests on their vertices, and flat triangles between them would
/// otherwise be pierced by the curved surface.
///
/// # Panics
/// If `index` is not a collider of `scene`.
pub fn collider(scene: &Scene, index: usize, t_s: f64) -> TriangleMesh {
    let spec = &scene.colliders[index];
    let moving = scene.effects.contains(crate::Effect::MovingColliders);
    let c = Collider::<f64>::of(spec);
    let (center, _) = c.at(t_s, moving);
    let to_f32 = |v: Vec3<f64>| v.to_f64().map(|x| x as f32);
    let mut out = TriangleMesh::default();
    if c.kind == ColliderKind::Plane {
        // The square's centre: the cloth's start, dropped onto the plane.
        let n = c.axes[1];
        let cloth_center = Vec3::from_f64(scene.cloth.center);
        let middle = cloth_center - n * c.surface(center, cloth_center).distance;
        let (u, w) = (c.axes[0] * PLANE_HALF_SIDE, c.axes[2] * PLANE_HALF_SIDE);
        for corner in [middle - u - w, middle + u - w, middle + u + w, middle - u + w] {
            out.positions.push(to_f32(corner - n * 0.002));
            out.normals.push(to_f32(n));
        }
        // Counter-clockwise about n = axes[1] = axes[2] × axes[0].
        out.indices.extend([0, 2, 1, 0, 3, 2]);
        return out;
    }
    if let Some(field) = &c.field {
        // A mesh is its triangles, flat-shaded, rotated and moved.
        let world = |v: [f64; 3]| center + c.axes[0] * v[0] + c.axes[1] * v[1] + c.axes[2] * v[2];
        for t in &field.mesh.triangles {
            let [a, b, d] = t.map(|i| world(field.mesh.vertices[i as usize]));
            let n = (b - a).cross(d - a);
            let n = n * (1.0 / n.length().max(f64::MIN_POSITIVE));
            for p in [a, b, d] {
                out.indices.push(out.positions.len() as u32);
                out.positions.push(to_f32(p));
                out.normals.push(to_f32(n));
            }
        }
        return out;
    }
    let Some((low, high)) = spec.shape.bounds() else { return out };
    let reach = 0.5 * (0..3).map(|k| (high[k] - low[k]).powi(2)).sum::<f64>().sqrt();
    let inset = 0.015 * c.thickness;
    let (sphere, indices) = unit_sphere(SPHERE_SEGMENTS[0], SPHERE_SEGMENTS[1]);
    for v in &sphere {
        let mut x = center + Vec3::from_f64(v.map(f64::from)) * reach;
        for _ in 0..8 {
            let s = c.surface(center, x);
            x -= s.normal * (s.distance + inset);
        }
        out.positions.push(to_f32(x));
        out.normals.push(to_f32(c.surface(center, x).normal));
    }
    out.indices = indices;
    out
}

/// Every collider of `scene` at time `t_s` (s) as one mesh.
pub fn colliders(scene: &Scene, t_s: f64) -> TriangleMesh {
    let mut out = TriangleMesh::default();
    for index in 0..scene.colliders.len() {
        out.append(&collider(scene, index, t_s));
    }
    out
}

/// The unit normals of the cloth `positions` (an `nx × ny` grid, row by row): at each vertex, the
/// area-weighted mean of its triangles' normals (each cell split along `(i, j)–(i+1, j+1)`, as
/// [`crate::intersections::triangles`] splits it); `+z` where the mean vanishes or is not finite.
///
/// # Panics
/// If `positions` does not hold `nx · ny` vertices.
pub fn cloth_normals(positions: &[[f32; 3]], nx: u32, ny: u32) -> Vec<[f32; 3]> {
    assert_eq!(positions.len(), nx as usize * ny as usize, "positions of an {nx} x {ny} grid");
    // Each triangle adds its cross product (twice its area times its unit normal) to its
    // vertices: the area-weighted mean direction.
    let mut sums = vec![[0.0f64; 3]; positions.len()];
    let at = |k: u32| positions[k as usize].map(f64::from);
    for t in crate::intersections::triangles(nx, ny) {
        let (a, b, c) = (at(t[0]), at(t[1]), at(t[2]));
        let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
        let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        for k in t {
            for (s, x) in sums[k as usize].iter_mut().zip(n) {
                *s += x;
            }
        }
    }
    sums.iter()
        .map(|n| {
            let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if length > 0.0 && length.is_finite() { n.map(|x| (x / length) as f32) } else { [0.0, 0.0, 1.0] }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curved_colliders_lie_on_their_surface_with_outward_normals() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/colliders.ron");
        let mut scene = Scene::load(std::path::Path::new(path)).unwrap();
        scene.effects.set(crate::Effect::MovingColliders, false);
        assert!(scene.colliders.len() >= 3, "the scene has several kinds of collider");
        for (index, spec) in scene.colliders.iter().enumerate() {
            let mesh = collider(&scene, index, 0.0);
            assert!(!mesh.indices.is_empty() && mesh.indices.len().is_multiple_of(3), "{:?}", spec.kind());
            assert_eq!(mesh.positions.len(), mesh.normals.len());
            let c = Collider::<f64>::of(spec);
            for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
                let s = c.surface(c.center, Vec3::<f64>::from_f64(p.map(f64::from)));
                // On the surface within the inset (a plane is drawn 2 mm under it).
                assert!(s.distance.abs() <= 0.02 * c.thickness + 2.5e-3, "{:?}: φ = {}", spec.kind(), s.distance);
                let length = n.iter().map(|x| x * x).sum::<f32>().sqrt();
                assert!((length - 1.0).abs() < 1e-4, "{:?}: |n| = {length}", spec.kind());
            }
            // The triangles turn counter-clockwise about the outward normals.
            let at = |i: u32| Vec3::<f64>::from_f64(mesh.positions[i as usize].map(f64::from));
            let outward = (mesh.indices.chunks(3))
                .filter(|t| {
                    let n = (at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0]));
                    let normal = Vec3::<f64>::from_f64(mesh.normals[t[0] as usize].map(f64::from));
                    n.dot(normal) > 0.0
                })
                .count();
            let nondegenerate = (mesh.indices.chunks(3))
                .filter(|t| (at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0])).length() > 1e-6)
                .count();
            assert_eq!(outward, nondegenerate, "{:?}", spec.kind());
        }
    }

    #[test]
    fn a_flat_cloth_faces_plus_z() {
        let positions: Vec<[f32; 3]> =
            (0..3).flat_map(|j| (0..4).map(move |i| [i as f32 * 0.5, j as f32 * 0.25, 1.0])).collect();
        assert!(cloth_normals(&positions, 4, 3).iter().all(|n| *n == [0.0, 0.0, 1.0]));
    }
}
