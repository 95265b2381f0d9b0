//! The cloth as files other tools open: a Wavefront OBJ of the mesh at one instant.

use crate::intersections::triangles;

/// The cloth `positions` (an `nx × ny` grid, row by row, m) as a Wavefront OBJ: one `v` line per
/// vertex in grid order, one `vn` line per vertex (the area-weighted mean of its triangles'
/// normals), and one `f` line per triangle, each cell split along its diagonal `(i, j)–(i+1, j+1)`
/// as the self-intersection count splits it ([`crate::intersections`]), counter-clockwise seen
/// from the side the normals point to. `comment` opens the file as `#` lines.
///
/// # Panics
/// If `positions` does not hold `nx · ny` vertices.
pub fn wavefront_obj(positions: &[[f32; 3]], nx: u32, ny: u32, comment: &str) -> String {
    assert_eq!(positions.len(), nx as usize * ny as usize, "positions of an {nx} x {ny} grid");
    let tris = triangles(nx, ny);
    // Each triangle adds its cross product (twice its area times its unit normal) to its
    // vertices: the area-weighted mean direction.
    let mut normals = vec![[0.0f64; 3]; positions.len()];
    let at = |k: u32| positions[k as usize].map(f64::from);
    for t in &tris {
        let (a, b, c) = (at(t[0]), at(t[1]), at(t[2]));
        let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
        let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        for &k in t {
            for (s, x) in normals[k as usize].iter_mut().zip(n) {
                *s += x;
            }
        }
    }
    let mut out = String::with_capacity(positions.len() * 80 + tris.len() * 40);
    for line in comment.lines() {
        out += &format!("# {line}\n");
    }
    for p in positions {
        out += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for n in &normals {
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let n = if length > 0.0 && length.is_finite() { n.map(|x| x / length) } else { [0.0, 0.0, 1.0] };
        out += &format!("vn {:.6} {:.6} {:.6}\n", n[0], n[1], n[2]);
    }
    for t in &tris {
        // OBJ counts from 1.
        let [a, b, c] = t.map(|k| k + 1);
        out += &format!("f {a}//{a} {b}//{b} {c}//{c}\n");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flat_cloth_has_a_vertex_a_normal_and_two_faces_a_cell() {
        let positions: Vec<[f32; 3]> =
            (0..3).flat_map(|j| (0..4).map(move |i| [i as f32 * 0.5, j as f32 * 0.25, 1.0])).collect();
        let obj = wavefront_obj(&positions, 4, 3, "a test\ncloth");
        let lines: Vec<&str> = obj.lines().collect();
        assert_eq!(&lines[..2], ["# a test", "# cloth"]);
        let count = |prefix: &str| lines.iter().filter(|l| l.starts_with(prefix)).count();
        assert_eq!((count("v "), count("vn "), count("f ")), (12, 12, 2 * 3 * 2));
        assert!(lines.contains(&"v 1.5 0.5 1"), "{obj}");
        // The cloth lies in z = 1 with u along x and v along y: every normal is +z.
        assert!(lines.iter().filter(|l| l.starts_with("vn ")).all(|l| *l == "vn 0.000000 0.000000 1.000000"));
        assert_eq!(lines.iter().find(|l| l.starts_with("f ")), Some(&"f 1//1 2//2 6//6"));
        assert_eq!(lines.last(), Some(&"f 7//7 12//12 11//11"));
    }
}
