//! Triangle meshes as colliders: a Wavefront OBJ is read (its vertices and faces), checked to be
//! closed, and turned once into a signed distance field `φ` sampled on a regular grid, which the
//! solvers evaluate by trilinear interpolation ([`DistanceField::surface`], the same operations
//! as `mesh_surface` in `shaders/wgsl/colliders.wgsl` and `shaders/glsl/colliders.glsl`).
//!
//! Each sample is exact: the distance to the nearest triangle (Ericson's closest point on a
//! triangle), negative inside, where inside is decided by the generalised winding number (the sum
//! of the solid angles the triangles subtend, over 4π: 1 inside a closed mesh, 0 outside). Between
//! samples `φ` is trilinear, so it is exact to within the distance field's curvature over a cell:
//! a collider's surface is rounded at the scale of one cell.
//!
//! Loading the same file with the same scale and resolution again returns the field already
//! computed (keyed by the file's path, length and modification time).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use crate::colliders::Surface;
use crate::real::{Real, Vec3};

/// Largest OBJ file read, bytes (64 MiB).
pub const MAX_OBJ_BYTES: u64 = 64 << 20;
/// Most cells along the longest side of a distance field.
pub const MAX_CELLS: u32 = 256;
/// Most point–triangle evaluations one distance field may take to compute (samples × triangles ×
/// 2, the distance and the winding number): about ten seconds of one core.
pub const MAX_WORK: u64 = 2_000_000_000;
/// Cells of padding around the mesh's bounding box, so that the field and its gradient are
/// meaningful around the surface.
pub const PADDING_CELLS: u32 = 2;

/// What went wrong reading or sampling a mesh. Each names the file; a parse error also its line.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The file cannot be read.
    #[error("{file}: cannot read it: {message}")]
    Unreadable {
        /// The file.
        file: String,
        /// Why.
        message: String,
    },
    /// A line that is not valid OBJ (or refers to a vertex that does not exist).
    #[error("{file}:{line}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// Its 1-based line.
        line: usize,
        /// What is wrong, and what is expected.
        message: String,
    },
    /// The mesh has a boundary or a non-manifold edge: it encloses no volume to be inside of.
    #[error(
        "{file}:{line}: the mesh is not closed: the edge between vertices {a} and {b} belongs to {uses} face(s), \
         not 2 (a collider mesh must enclose a volume: close its holes)"
    )]
    NotClosed {
        /// The file.
        file: String,
        /// Line of a face with the edge.
        line: usize,
        /// The edge's vertices (1-based, as in the file).
        a: u32,
        /// The other one.
        b: u32,
        /// How many faces have it.
        uses: usize,
    },
    /// No face at all.
    #[error("{file}: no faces: a collider mesh needs closed triangles (f lines)")]
    Empty {
        /// The file.
        file: String,
    },
    /// The distance field asked for is too much work for this mesh.
    #[error(
        "{file}: {triangles} triangles sampled on {samples} grid points is {work:e} point-triangle tests, more than \
         the {limit:e} allowed: lower `cells` (to about {fitting}) or simplify the mesh"
    )]
    TooLarge {
        /// The file.
        file: String,
        /// Its triangles.
        triangles: usize,
        /// Grid points asked for.
        samples: u64,
        /// Tests that would take.
        work: f64,
        /// The limit, [`MAX_WORK`].
        limit: f64,
        /// Cells along the longest side that would fit.
        fitting: u32,
    },
}

/// A closed triangle mesh read from an OBJ file.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions as the file gives them (scaled by the collider's `scale`), m.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, as indices into `vertices` (polygons split into fans).
    pub triangles: Vec<[u32; 3]>,
}

/// Reads an OBJ file: `v x y z` vertices and `f` faces (`i`, `i/t`, `i//n` or `i/t/n`, negative
/// indices counting back from the last vertex; polygons split into fans); every other statement
/// (normals, texture coordinates, groups, materials) is ignored. Checks that the mesh is closed.
pub fn read_obj(path: &Path) -> Result<TriangleMesh, MeshError> {
    let file = path.display().to_string();
    let unreadable = |message: String| MeshError::Unreadable { file: file.clone(), message };
    let meta = std::fs::metadata(path).map_err(|e| unreadable(e.to_string()))?;
    if !meta.is_file() {
        return Err(unreadable("not a regular file".into()));
    }
    if meta.len() > MAX_OBJ_BYTES {
        return Err(unreadable(format!("{} bytes, more than the {MAX_OBJ_BYTES} read", meta.len())));
    }
    let text = std::fs::read_to_string(path).map_err(|e| unreadable(e.to_string()))?;
    parse_obj(&text, &file)
}

/// [`read_obj`] on text; `file` names it in errors.
pub fn parse_obj(text: &str, file: &str) -> Result<TriangleMesh, MeshError> {
    let parse = |line: usize, message: String| MeshError::Parse { file: file.to_string(), line, message };
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut face_lines: Vec<usize> = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut words = content.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut p = [0.0; 3];
                for (i, x) in p.iter_mut().enumerate() {
                    let word = words.next().ok_or_else(|| parse(line, "a vertex needs x, y and z".into()))?;
                    *x = word.parse::<f64>().map_err(|_| parse(line, format!("'{word}' is not a number")))?;
                    if !x.is_finite() {
                        return Err(parse(line, format!("coordinate {i} is {x}, not finite")));
                    }
                }
                vertices.push(p);
            }
            Some("f") => {
                let mut corners = Vec::new();
                for word in words {
                    let index = word.split('/').next().unwrap_or("");
                    let i: i64 = index
                        .parse()
                        .map_err(|_| parse(line, format!("'{word}' is not a vertex index (i, i/t, i//n or i/t/n)")))?;
                    let n = vertices.len() as i64;
                    let resolved = if i > 0 { i - 1 } else { n + i };
                    if i == 0 || !(0..n).contains(&resolved) {
                        return Err(parse(line, format!("vertex {i} does not exist ({n} vertices so far)")));
                    }
                    corners.push(resolved as u32);
                }
                if corners.len() < 3 {
                    return Err(parse(
                        line,
                        format!("a face needs at least 3 vertices, this one has {}", corners.len()),
                    ));
                }
                for k in 1..corners.len() - 1 {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                    face_lines.push(line);
                }
            }
            _ => {}
        }
    }
    if triangles.is_empty() {
        return Err(MeshError::Empty { file: file.to_string() });
    }
    // Closed: every edge is shared by exactly two triangles.
    let mut edges: HashMap<(u32, u32), (usize, usize)> = HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let entry = edges.entry((a.min(b), a.max(b))).or_insert((0, t));
            entry.0 += 1;
        }
    }
    if let Some((&(a, b), &(uses, t))) =
        edges.iter().filter(|(_, (uses, _))| *uses != 2).min_by_key(|(_, (_, t))| face_lines[*t])
    {
        return Err(MeshError::NotClosed { file: file.to_string(), line: face_lines[t], a: a + 1, b: b + 1, uses });
    }
    Ok(TriangleMesh { vertices, triangles })
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Distance from `p` to the triangle `abc`, m: to its closest point (Ericson, *Real-Time Collision
/// Detection*, 5.1.5: the Voronoi regions of the vertices, edges and face).
pub fn point_triangle_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return norm(ap);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return norm(bp);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return norm(sub(ap, ab.map(|x| x * v)));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return norm(cp);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return norm(sub(ap, ac.map(|x| x * w)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return norm(sub(bp, sub(c, b).map(|x| x * w)));
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    norm(sub(ap, [0, 1, 2].map(|k| ab[k] * v + ac[k] * w)))
}

/// The generalised winding number of the mesh around `p`: `Σ Ω_t / 4π` over the solid angles the
/// triangles subtend (Van Oosterom & Strackee's formula), 1 inside a closed, outward-oriented
/// mesh, 0 outside (−1 inside one oriented inwards).
pub fn winding_number(mesh: &TriangleMesh, p: [f64; 3]) -> f64 {
    let mut total = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| sub(mesh.vertices[i as usize], p));
        let (la, lb, lc) = (norm(a), norm(b), norm(c));
        let numerator = dot(a, cross(b, c));
        let denominator = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// A signed distance field sampled on an `dims[0] × dims[1] × dims[2]` grid of points `cell` apart
/// starting at `origin`, in the mesh's own (scaled) coordinates, m.
#[derive(Clone, Debug, PartialEq)]
pub struct DistanceField {
    /// The grid's first point (its lowest corner), m.
    pub origin: [f64; 3],
    /// The distance between grid points, m.
    pub cell: f64,
    /// Points along x, y and z (each at least 2).
    pub dims: [u32; 3],
    /// `φ` at point `(i, j, k)`: `samples[i + dims[0] (j + dims[1] k)]`, m.
    pub samples: Vec<f32>,
    /// The mesh it samples.
    pub mesh: TriangleMesh,
}

/// The grid `of` would sample: its origin, cell and dims for a mesh's bounding box.
fn grid_for(mesh: &TriangleMesh, cells: u32) -> ([f64; 3], f64, [u32; 3]) {
    let mut low = [f64::INFINITY; 3];
    let mut high = [f64::NEG_INFINITY; 3];
    for v in &mesh.vertices {
        for k in 0..3 {
            low[k] = low[k].min(v[k]);
            high[k] = high[k].max(v[k]);
        }
    }
    let longest = (0..3).map(|k| high[k] - low[k]).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    let cell = longest / cells.max(1) as f64;
    let pad = PADDING_CELLS as f64 * cell;
    let origin = low.map(|x| x - pad);
    let dims = [0, 1, 2].map(|k| ((high[k] - low[k] + 2.0 * pad) / cell).ceil() as u32 + 1);
    (origin, cell, dims)
}

impl DistanceField {
    /// Samples `mesh` with `cells` cells along its bounding box's longest side, padded by
    /// [`PADDING_CELLS`] on every side. `file` names it in errors.
    pub fn of(mesh: TriangleMesh, cells: u32, file: &str) -> Result<Self, MeshError> {
        let (origin, cell, dims) = grid_for(&mesh, cells);
        let work_at = |cells: u32| {
            let (_, _, dims) = grid_for(&mesh, cells);
            dims.iter().map(|&d| d as f64).product::<f64>() * mesh.triangles.len() as f64 * 2.0
        };
        let samples = dims.iter().map(|&d| d as u64).product::<u64>();
        let work = work_at(cells);
        if work > MAX_WORK as f64 {
            // The estimate from the cube root, then down until it fits (the padding counts too).
            let mut fitting = ((cells as f64 * (MAX_WORK as f64 / work).cbrt()).floor() as u32).clamp(1, MAX_CELLS);
            while fitting > 1 && work_at(fitting) > MAX_WORK as f64 {
                fitting -= 1;
            }
            return Err(MeshError::TooLarge {
                file: file.to_string(),
                triangles: mesh.triangles.len(),
                samples,
                work,
                limit: MAX_WORK as f64,
                fitting,
            });
        }
        use rayon::prelude::*;
        let [nx, ny, _] = dims.map(|d| d as usize);
        let samples: Vec<f32> = (0..samples as usize)
            .into_par_iter()
            .map(|s| {
                let (i, j, k) = (s % nx, (s / nx) % ny, s / (nx * ny));
                let p = [origin[0] + i as f64 * cell, origin[1] + j as f64 * cell, origin[2] + k as f64 * cell];
                let distance = (mesh.triangles.iter())
                    .map(|t| {
                        let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
                        point_triangle_distance(p, a, b, c)
                    })
                    .fold(f64::INFINITY, f64::min);
                let inside = winding_number(&mesh, p).abs() > 0.5;
                (if inside { -distance } else { distance }) as f32
            })
            .collect();
        Ok(Self { origin, cell, dims, samples, mesh })
    }

    /// The cell of the grid around `p`, a point in the mesh's coordinates: its eight samples, the
    /// fractions of the way across it, and, for a point outside the grid, the way (m) from the
    /// nearest grid point (zero inside).
    fn cell<R: Real>(&self, p: Vec3<R>) -> FieldCell<R> {
        let cell = R::of(self.cell);
        let origin = Vec3::from_f64(self.origin);
        let g = (p - origin) * (R::one() / cell);
        let high = self.dims.map(|d| R::of((d - 1) as f64));
        let clamp = |x: R, hi: R| x.max(R::zero()).min(hi);
        let q = [clamp(g.x, high[0]), clamp(g.y, high[1]), clamp(g.z, high[2])];
        // The cell's lowest corner: at most the last but one point, so the cell exists.
        let corner = |x: R, d: u32| x.floor().to_f64_lossy().min((d - 2) as f64) as u32;
        let (i, j, k) = (corner(q[0], self.dims[0]), corner(q[1], self.dims[1]), corner(q[2], self.dims[2]));
        let [nx, ny, _] = self.dims;
        let at = |di: u32, dj: u32, dk: u32| {
            R::of(self.samples[((i + di) + nx * ((j + dj) + ny * (k + dk))) as usize] as f64)
        };
        FieldCell {
            low: [at(0, 0, 0), at(1, 0, 0), at(0, 1, 0), at(1, 1, 0)],
            high: [at(0, 0, 1), at(1, 0, 1), at(0, 1, 1), at(1, 1, 1)],
            fraction: [q[0] - R::of(i as f64), q[1] - R::of(j as f64), q[2] - R::of(k as f64)],
            outside: Vec3::new(g.x - q[0], g.y - q[1], g.z - q[2]) * cell,
        }
    }

    /// [`Self::surface`]'s distance alone, by the same operations.
    pub fn distance<R: Real>(&self, p: Vec3<R>) -> R {
        let f = self.cell(p);
        let value = f.value(f.edges());
        let outside_length = f.outside.dot(f.outside).sqrt();
        if outside_length > R::zero() { value + outside_length } else { value }
    }

    /// The surface seen from `p`, a point in the mesh's coordinates: `φ` trilinear between the
    /// eight samples around it, the normal the normalised gradient of that trilinear function (`+Y`
    /// where it vanishes). Outside the grid, `φ` at the nearest grid point plus the distance to it,
    /// the normal pointing from it.
    pub fn surface<R: Real>(&self, p: Vec3<R>) -> Surface<R> {
        let f = self.cell(p);
        let edges = f.edges();
        let value = f.value(edges);
        let one = R::one();
        let outside_length = f.outside.dot(f.outside).sqrt();
        if outside_length > R::zero() {
            return Surface { distance: value + outside_length, normal: f.outside * (one / outside_length) };
        }
        let [c000, c100, c010, c110] = f.low;
        let [c001, c101, c011, c111] = f.high;
        let [c00, c10, c01, c11] = edges;
        let [fx, fy, fz] = f.fraction;
        let (gx, gy, gz) = (one - fx, one - fy, one - fz);
        // The trilinear function's gradient in the cell (per grid unit; the direction is all the
        // normal needs).
        let dx = ((c100 - c000) * gy + (c110 - c010) * fy) * gz + ((c101 - c001) * gy + (c111 - c011) * fy) * fz;
        let dy = ((c010 - c000) * gx + (c110 - c100) * fx) * gz + ((c011 - c001) * gx + (c111 - c101) * fx) * fz;
        let dz = (c01 - c00) * gy + (c11 - c10) * fy;
        let gradient = Vec3::new(dx, dy, dz);
        let len = gradient.dot(gradient).sqrt();
        let normal = if len > R::zero() { gradient * (one / len) } else { Vec3::new(R::zero(), one, R::zero()) };
        Surface { distance: value, normal }
    }
}

/// The cell of a distance field around a point (`DistanceField::cell`): the samples at its
/// corners `[c000, c100, c010, c110]` and, one layer up in z, `high` the same; the fractions of the
/// way across it along x, y, z; and `outside`, the way (m) from the nearest grid point to a point
/// outside the grid (zero inside). The shaders' `FieldCell` is the same.
struct FieldCell<R> {
    low: [R; 4],
    high: [R; 4],
    fraction: [R; 3],
    outside: Vec3<R>,
}

impl<R: Real> FieldCell<R> {
    /// Trilinear interpolation's first pass, along x: the four edges `[c00, c10, c01, c11]`.
    fn edges(&self) -> [R; 4] {
        let fx = self.fraction[0];
        let gx = R::one() - fx;
        [
            self.low[0] * gx + self.low[1] * fx,
            self.low[2] * gx + self.low[3] * fx,
            self.high[0] * gx + self.high[1] * fx,
            self.high[2] * gx + self.high[3] * fx,
        ]
    }

    /// The rest of it, along y, then z.
    fn value(&self, [c00, c10, c01, c11]: [R; 4]) -> R {
        let [_, fy, fz] = self.fraction;
        let gy = R::one() - fy;
        let c0 = c00 * gy + c10 * fy;
        let c1 = c01 * gy + c11 * fy;
        c0 * (R::one() - fz) + c1 * fz
    }
}

/// The key of a computed field: the file (its path, length and modification time), its scale
/// and its resolution.
type FieldKey = (PathBuf, u64, Option<std::time::SystemTime>, u64, u32);

fn fields() -> &'static Mutex<HashMap<FieldKey, Arc<DistanceField>>> {
    static FIELDS: std::sync::OnceLock<Mutex<HashMap<FieldKey, Arc<DistanceField>>>> = std::sync::OnceLock::new();
    FIELDS.get_or_init(|| Mutex::new(HashMap::new()))
}

/// The distance field of the OBJ at `path`, its coordinates times `scale`, sampled with `cells`
/// cells along its longest side: read and computed the first time, then returned from memory
/// while the file is unchanged.
pub fn load(path: &Path, scale: f64, cells: u32) -> Result<Arc<DistanceField>, MeshError> {
    let file = path.display().to_string();
    let meta =
        std::fs::metadata(path).map_err(|e| MeshError::Unreadable { file: file.clone(), message: e.to_string() })?;
    let key = (path.to_path_buf(), meta.len(), meta.modified().ok(), scale.to_bits(), cells);
    if let Some(field) = fields().lock().ok().and_then(|f| f.get(&key).cloned()) {
        return Ok(field);
    }
    let mut mesh = read_obj(path)?;
    for v in &mut mesh.vertices {
        *v = v.map(|x| x * scale);
    }
    let field = Arc::new(DistanceField::of(mesh, cells, &file)?);
    if let Ok(mut f) = fields().lock() {
        f.insert(key, field.clone());
    }
    Ok(field)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed unit cube from (0, 0, 0) to (1, 1, 1), faces outward, as quads.
    const CUBE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                        f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n";

    /// The exact signed distance to the unit cube.
    fn cube_distance(p: [f64; 3]) -> f64 {
        let q = p.map(|x| (x - 0.5).abs() - 0.5);
        let outside = norm(q.map(|x| x.max(0.0)));
        outside + q[0].max(q[1]).max(q[2]).min(0.0)
    }

    #[test]
    fn point_triangle_distance_matches_each_voronoi_region() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert!((point_triangle_distance([0.2, 0.2, 0.5], a, b, c) - 0.5).abs() < 1e-12, "face");
        assert!((point_triangle_distance([-1.0, -1.0, 0.0], a, b, c) - 2f64.sqrt()).abs() < 1e-12, "vertex a");
        assert!((point_triangle_distance([0.5, -2.0, 0.0], a, b, c) - 2.0).abs() < 1e-12, "edge ab");
        assert!((point_triangle_distance([1.0, 1.0, 0.0], a, b, c) - 0.5f64.sqrt()).abs() < 1e-12, "edge bc");
        assert!((point_triangle_distance([3.0, 0.0, 0.0], a, b, c) - 2.0).abs() < 1e-12, "vertex b");
    }

    #[test]
    fn the_winding_number_is_one_inside_and_zero_outside() {
        let cube = parse_obj(CUBE, "cube.obj").unwrap();
        assert!((winding_number(&cube, [0.5, 0.5, 0.5]) - 1.0).abs() < 1e-9);
        assert!((winding_number(&cube, [0.9, 0.1, 0.3]) - 1.0).abs() < 1e-9);
        assert!(winding_number(&cube, [1.5, 0.5, 0.5]).abs() < 1e-9);
    }

    #[test]
    fn the_sampled_field_matches_the_exact_distance_at_its_points_and_near_them_between() {
        let field = DistanceField::of(parse_obj(CUBE, "cube.obj").unwrap(), 8, "cube.obj").unwrap();
        let [nx, ny, nz] = field.dims;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let p = [i, j, k].map(|n| n as f64 * field.cell);
                    let p = [0, 1, 2].map(|a| field.origin[a] + p[a]);
                    let s = field.samples[(i + nx * (j + ny * k)) as usize] as f64;
                    assert!((s - cube_distance(p)).abs() < 1e-6, "at {p:?}: {s} vs {}", cube_distance(p));
                }
            }
        }
        // Between the points: within a tenth of a cell of the exact distance, on the faces' side
        // where the distance is planar (exact there), and the normal along the face's.
        let s = field.surface(Vec3::<f64>::new(0.5, 1.03, 0.41));
        assert!((s.distance - 0.03).abs() < 1e-6, "{s:?}");
        assert!((s.normal - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6, "{s:?}");
        for p in [[0.3, 0.4, 0.45], [1.2, 0.7, 0.1], [-0.1, -0.1, 0.5]] {
            let s = field.surface(Vec3::<f64>::from_f64(p));
            assert!((s.distance - cube_distance(p)).abs() < 0.1 * field.cell, "{p:?}: {s:?} vs {}", cube_distance(p));
        }
        // Far outside the grid: the nearest grid point's φ plus the way there.
        let far = field.surface(Vec3::<f64>::new(5.0, 0.5, 0.5));
        assert!((far.distance - 4.0).abs() < 1e-6 && far.normal.x > 0.99, "{far:?}");
    }

    #[test]
    fn bad_files_are_refused_naming_file_and_line() {
        let open = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 2 3 4\n";
        let cases = [
            ("v 0 0\n", "m.obj:1: a vertex needs x, y and z"),
            ("v 0 x 0\n", "m.obj:1: 'x' is not a number"),
            ("v 0 0 0\nv 1 0 0\nf 1 2 3\n", "m.obj:3: vertex 3 does not exist (2 vertices so far)"),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "m.obj:4: a face needs at least 3 vertices"),
            ("v 0 0 0\n", "m.obj: no faces"),
            (open, "m.obj:5: the mesh is not closed"),
        ];
        for (text, expected) in cases {
            let e = parse_obj(text, "m.obj").unwrap_err().to_string();
            assert!(e.starts_with(expected), "{text:?}\n  gave: {e}\n  expected: {expected}");
        }
        assert!(parse_obj(CUBE, "cube.obj").is_ok());
        let e = load(Path::new("/nonexistent/mesh.obj"), 1.0, 16).unwrap_err().to_string();
        assert!(e.starts_with("/nonexistent/mesh.obj: cannot read it"), "{e}");
    }

    #[test]
    fn too_fine_a_field_for_the_mesh_is_refused_with_a_resolution_that_fits() {
        let cube = parse_obj(CUBE, "cube.obj").unwrap();
        let e = DistanceField::of(cube, MAX_CELLS * 40, "cube.obj").unwrap_err();
        let MeshError::TooLarge { fitting, .. } = e else { panic!("{e}") };
        let cube = parse_obj(CUBE, "cube.obj").unwrap();
        let (_, _, dims) = grid_for(&cube, fitting);
        let work = dims.iter().map(|&d| d as f64).product::<f64>() * 12.0 * 2.0;
        assert!(work <= MAX_WORK as f64, "the suggested {fitting} cells fit");
    }
}
