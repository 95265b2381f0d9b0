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
    let normals = crate::tessellation::cloth_normals(positions, nx, ny);
    let mut out = String::with_capacity(positions.len() * 80 + tris.len() * 40);
    for line in comment.lines() {
        out += &format!("# {line}\n");
    }
    for p in positions {
        out += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for n in &normals {
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
