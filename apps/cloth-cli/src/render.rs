//! The fallback picture of `--png` where no Vulkan device can draw the inspector's view: a small
//! software renderer of the cloth as flat-shaded two-sided triangles and the colliders
//! (sphere-traced from their signed distances), seen by a perspective camera. Good enough to see a
//! drape at a glance without any GPU; also the PNG encoder of the study's plots.

use cloth_core::colliders::{Collider, ColliderKind};
use cloth_core::real::Vec3;
use cloth_core::{ClothModel, ClothState};

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn norm(a: V3) -> V3 {
    let l = dot(a, a).sqrt();
    if l > 0.0 { [a[0] / l, a[1] / l, a[2] / l] } else { a }
}

struct Camera {
    eye: V3,
    right: V3,
    up: V3,
    forward: V3,
    focal: f64,
    width: usize,
    height: usize,
}

impl Camera {
    fn looking_at(target: V3, distance: f64, width: usize, height: usize) -> Self {
        let dir = norm([0.9, 0.7, 1.6]);
        let eye = [target[0] + dir[0] * distance, target[1] + dir[1] * distance, target[2] + dir[2] * distance];
        let forward = norm(sub(target, eye));
        let right = norm(cross(forward, [0.0, 1.0, 0.0]));
        let up = cross(right, forward);
        Self { eye, right, up, forward, focal: 1.2 * height as f64, width, height }
    }

    /// Pixel coordinates and depth of a point, or `None` behind the camera.
    fn project(&self, p: V3) -> Option<(f64, f64, f64)> {
        let d = sub(p, self.eye);
        let z = dot(d, self.forward);
        if z <= 1e-6 {
            return None;
        }
        let x = self.width as f64 / 2.0 + self.focal * dot(d, self.right) / z;
        let y = self.height as f64 / 2.0 - self.focal * dot(d, self.up) / z;
        Some((x, y, z))
    }

    fn ray(&self, px: f64, py: f64) -> V3 {
        let x = (px - self.width as f64 / 2.0) / self.focal;
        let y = -(py - self.height as f64 / 2.0) / self.focal;
        norm([
            self.forward[0] + x * self.right[0] + y * self.up[0],
            self.forward[1] + x * self.right[1] + y * self.up[1],
            self.forward[2] + x * self.right[2] + y * self.up[2],
        ])
    }
}

const LIGHT: V3 = [0.35, 0.85, 0.4];

/// Most sphere-tracing steps along one pixel's ray.
const RAY_STEPS: usize = 128;

fn shade(base: [f64; 3], lambert: f64) -> [f64; 3] {
    let l = 0.25 + 0.75 * lambert.clamp(0.0, 1.0);
    [base[0] * l, base[1] * l, base[2] * l]
}

/// Renders to RGB8 pixels.
pub fn render(model: &ClothModel, state: &ClothState, width: usize, height: usize) -> Vec<u8> {
    let scene = &model.scene;
    let positions: Vec<V3> = state.positions.iter().map(|p| p.map(f64::from)).collect();
    let (lo, hi) = crate::picture::scene_bounds(model);
    let solid = scene.colliders.iter().any(|c| c.shape.bounds().is_some());
    let drop = if solid { 0.2 * (hi[1] - lo[1]) } else { 0.0 };
    let target = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0 - drop, (lo[2] + hi[2]) / 2.0];
    let extent = dot(sub(hi, lo), sub(hi, lo)).sqrt().max(0.5);
    let cam = Camera::looking_at(target, 1.35 * extent, width, height);

    let mut depth = vec![f64::INFINITY; width * height];
    let mut color = vec![[0.0f64; 3]; width * height];
    for py in 0..height {
        let t = py as f64 / height as f64;
        for px in 0..width {
            color[py * width + px] = [0.93 - 0.25 * t, 0.95 - 0.2 * t, 0.98 - 0.1 * t];
        }
    }
    let light = norm(LIGHT);
    // Every collider kind is drawn the same way: sphere tracing its signed distance, where each
    // collider is at the state's time.
    let moving = scene.effects.contains(cloth_core::Effect::MovingColliders);
    let colliders: Vec<(Collider<f64>, Vec3<f64>)> = (scene.colliders.iter())
        .map(|spec| {
            let c = Collider::<f64>::of(spec);
            let (center, _) = c.at(state.time_s, moving);
            (c, center)
        })
        .collect();
    // Drawn slightly inside: the cloth rests on its vertices, and flat triangles between them
    // would otherwise be pierced by a curved surface.
    let inset = |c: &Collider<f64>| 0.01 * c.thickness.min(1.0);
    let far = 20.0 * extent;
    for py in 0..height {
        for px in 0..width {
            let d = cam.ray(px as f64 + 0.5, py as f64 + 0.5);
            let mut t = 0.0;
            for _ in 0..RAY_STEPS {
                let at = Vec3::new(cam.eye[0] + t * d[0], cam.eye[1] + t * d[1], cam.eye[2] + t * d[2]);
                let (k, surface) = (colliders.iter().enumerate())
                    .map(|(k, (c, center))| {
                        let s = c.surface(*center, at);
                        (k, cloth_core::colliders::Surface { distance: s.distance + inset(c), ..s })
                    })
                    .min_by(|a, b| a.1.distance.total_cmp(&b.1.distance))
                    .map_or((0, None), |(k, s)| (k, Some(s)));
                let Some(surface) = surface else { break };
                if surface.distance < 1e-4 * extent {
                    let i = py * width + px;
                    let z = t * dot(d, cam.forward);
                    if z < depth[i] {
                        depth[i] = z;
                        let n = surface.normal.to_f64();
                        let base = if colliders[k].0.kind == ColliderKind::Plane {
                            // A checkerboard of 0.5 m squares, so a ground reads as one.
                            let parity = ((at.x * 2.0).floor() + (at.z * 2.0).floor()) as i64 & 1;
                            if parity == 0 { [0.62, 0.64, 0.6] } else { [0.5, 0.52, 0.49] }
                        } else {
                            [0.55, 0.6, 0.68]
                        };
                        color[i] = shade(base, dot(n, light));
                    }
                    break;
                }
                t += surface.distance;
                if t > far {
                    break;
                }
            }
        }
    }
    let tris = model.grid.triangle_indices();
    for tri in tris.chunks_exact(3) {
        let p = [positions[tri[0] as usize], positions[tri[1] as usize], positions[tri[2] as usize]];
        if !p.iter().all(|q| q.iter().all(|x| x.is_finite())) {
            continue;
        }
        let n = norm(cross(sub(p[1], p[0]), sub(p[2], p[0])));
        let facing = dot(n, sub(cam.eye, p[0])) > 0.0;
        let (base, n) = if facing { ([0.92, 0.45, 0.2], n) } else { ([0.25, 0.5, 0.85], [-n[0], -n[1], -n[2]]) };
        let c = shade(base, dot(n, light).abs() * 0.8 + 0.2 * dot(n, light).max(0.0));
        let Some(a) = cam.project(p[0]) else { continue };
        let Some(b) = cam.project(p[1]) else { continue };
        let Some(d) = cam.project(p[2]) else { continue };
        fill_triangle([a, b, d], c, width, height, &mut depth, &mut color);
    }
    color.iter().flat_map(|c| c.map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8)).collect()
}

fn fill_triangle(
    v: [(f64, f64, f64); 3],
    c: [f64; 3],
    width: usize,
    height: usize,
    depth: &mut [f64],
    color: &mut [[f64; 3]],
) {
    let min_x = v.iter().map(|p| p.0).fold(f64::INFINITY, f64::min).floor().max(0.0) as usize;
    let max_x = v.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max).ceil().min(width as f64 - 1.0);
    let min_y = v.iter().map(|p| p.1).fold(f64::INFINITY, f64::min).floor().max(0.0) as usize;
    let max_y = v.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max).ceil().min(height as f64 - 1.0);
    if max_x < 0.0 || max_y < 0.0 {
        return;
    }
    let area = (v[1].0 - v[0].0) * (v[2].1 - v[0].1) - (v[2].0 - v[0].0) * (v[1].1 - v[0].1);
    if area.abs() < 1e-12 {
        return;
    }
    for py in min_y..=max_y as usize {
        for px in min_x..=max_x as usize {
            let (x, y) = (px as f64 + 0.5, py as f64 + 0.5);
            let w0 = ((v[1].0 - x) * (v[2].1 - y) - (v[2].0 - x) * (v[1].1 - y)) / area;
            let w1 = ((v[2].0 - x) * (v[0].1 - y) - (v[0].0 - x) * (v[2].1 - y)) / area;
            let w2 = 1.0 - w0 - w1;
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            // Perspective-correct depth: interpolate 1/z.
            let inv_z = w0 / v[0].2 + w1 / v[1].2 + w2 / v[2].2;
            let z = 1.0 / inv_z;
            let i = py * width + px;
            if z < depth[i] - 1e-4 {
                depth[i] = z;
                color[i] = c;
            }
        }
    }
}
