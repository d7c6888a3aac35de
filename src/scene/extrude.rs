//! Extrusion of a 2D solid/free cell grid into a 2.5D mesh with merged faces.
//!
//! Shared by the ROS-map and HouseExpo importers and by the generator. A box per solid cell would cost
//! 12 triangles per pixel (millions for a real map); instead the floor under free cells and the cap on
//! top of solid cells are greedy-merged rectangles, and walls are vertical quads only on the boundary
//! between solid and free cells, each collinear run merged into one quad.

use super::TriMesh;
use std::collections::HashMap;

/// Extrudes `solid` (`nx × ny`, row-major, row `iy` at `origin.y + iy·res`) to `height`.
///
/// Cells outside the grid count as solid, so a free cell on the border gets a wall there and the
/// result is closed. Normals point into the free space (walls) and up (floor, cap).
pub fn extrude_grid(
    solid: &[bool],
    nx: usize,
    ny: usize,
    origin: [f64; 2],
    res: f64,
    height: f64,
) -> TriMesh {
    assert_eq!(solid.len(), nx * ny, "solid grid has nx·ny cells");
    let mut builder = Builder {
        mesh: TriMesh::default(),
        index: HashMap::new(),
        origin,
        res,
        height,
    };
    let is_solid = |x: i64, y: i64| -> bool {
        x < 0 || y < 0 || x >= nx as i64 || y >= ny as i64 || solid[y as usize * nx + x as usize]
    };

    let free: Vec<bool> = solid.iter().map(|s| !s).collect();
    for r in greedy_rects(&free, nx, ny) {
        builder.rect(r, 0);
    }
    for r in greedy_rects(solid, nx, ny) {
        builder.rect(r, 1);
    }

    // Horizontal boundaries (constant y = j), merged along x.
    for j in 0..=ny as i64 {
        let mut run: Option<(usize, bool)> = None; // (start x, free side is +y)
        for i in 0..=nx as i64 {
            let state = if i < nx as i64 {
                let below = is_solid(i, j - 1);
                let above = is_solid(i, j);
                (below != above).then_some(!above)
            } else {
                None
            };
            if run.map(|(_, s)| Some(s)) != Some(state) {
                if let Some((start, up)) = run.take() {
                    builder.wall_y(j as usize, start, i as usize, up);
                }
                run = state.map(|s| (i as usize, s));
            }
        }
    }
    // Vertical boundaries (constant x = i), merged along y.
    for i in 0..=nx as i64 {
        let mut run: Option<(usize, bool)> = None; // (start y, free side is +x)
        for j in 0..=ny as i64 {
            let state = if j < ny as i64 {
                let left = is_solid(i - 1, j);
                let right = is_solid(i, j);
                (left != right).then_some(!right)
            } else {
                None
            };
            if run.map(|(_, s)| Some(s)) != Some(state) {
                if let Some((start, right)) = run.take() {
                    builder.wall_x(i as usize, start, j as usize, right);
                }
                run = state.map(|s| (j as usize, s));
            }
        }
    }
    builder.mesh
}

/// Covers the `true` cells of `mask` with disjoint rectangles `(x0, y0, x1, y1)` (exclusive ends),
/// greedily: grow along x, then along y while the whole row span matches.
pub fn greedy_rects(mask: &[bool], nx: usize, ny: usize) -> Vec<(usize, usize, usize, usize)> {
    let mut used = vec![false; nx * ny];
    let mut rects = Vec::new();
    for y0 in 0..ny {
        let mut x0 = 0;
        while x0 < nx {
            let i = y0 * nx + x0;
            if !mask[i] || used[i] {
                x0 += 1;
                continue;
            }
            let mut x1 = x0 + 1;
            while x1 < nx && mask[y0 * nx + x1] && !used[y0 * nx + x1] {
                x1 += 1;
            }
            let mut y1 = y0 + 1;
            while y1 < ny && (x0..x1).all(|x| mask[y1 * nx + x] && !used[y1 * nx + x]) {
                y1 += 1;
            }
            for y in y0..y1 {
                used[y * nx + x0..y * nx + x1].fill(true);
            }
            rects.push((x0, y0, x1, y1));
            x0 = x1;
        }
    }
    rects
}

/// Emits quads on grid-corner vertices, shared between faces (level 0 = floor, 1 = top).
struct Builder {
    mesh: TriMesh,
    index: HashMap<(usize, usize, u8), u32>,
    origin: [f64; 2],
    res: f64,
    height: f64,
}

impl Builder {
    fn vertex(&mut self, ix: usize, iy: usize, level: u8) -> u32 {
        let (origin, res, height) = (self.origin, self.res, self.height);
        let mesh = &mut self.mesh;
        *self.index.entry((ix, iy, level)).or_insert_with(|| {
            mesh.push_vertex(
                origin[0] + ix as f64 * res,
                origin[1] + iy as f64 * res,
                if level == 0 { 0.0 } else { height },
            )
        })
    }

    /// A horizontal rectangle facing up at `level`.
    fn rect(&mut self, (x0, y0, x1, y1): (usize, usize, usize, usize), level: u8) {
        let q = [
            self.vertex(x0, y0, level),
            self.vertex(x1, y0, level),
            self.vertex(x1, y1, level),
            self.vertex(x0, y1, level),
        ];
        self.mesh.push_quad(q);
    }

    /// A wall along y = `j` from x = `x0` to `x1`, facing +y if `faces_up` else -y.
    fn wall_y(&mut self, j: usize, x0: usize, x1: usize, faces_up: bool) {
        let (a, b) = if faces_up { (x1, x0) } else { (x0, x1) };
        let q = [
            self.vertex(a, j, 0),
            self.vertex(b, j, 0),
            self.vertex(b, j, 1),
            self.vertex(a, j, 1),
        ];
        self.mesh.push_quad(q);
    }

    /// A wall along x = `i` from y = `y0` to `y1`, facing +x if `faces_right` else -x.
    fn wall_x(&mut self, i: usize, y0: usize, y1: usize, faces_right: bool) {
        let (a, b) = if faces_right { (y0, y1) } else { (y1, y0) };
        let q = [
            self.vertex(i, a, 0),
            self.vertex(i, b, 0),
            self.vertex(i, b, 1),
            self.vertex(i, a, 1),
        ];
        self.mesh.push_quad(q);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn normal(m: &TriMesh, t: [u32; 3]) -> [f32; 3] {
        let [a, b, c] = t.map(|i| m.vertices[i as usize]);
        let n = (b - a).cross(&(c - a));
        [n.x, n.y, n.z]
    }

    #[test]
    fn single_free_cell_is_a_closed_box_interior() {
        // One free cell: floor (2 tris) + 4 walls (8 tris), no cap.
        let m = extrude_grid(&[false], 1, 1, [1.0, 2.0], 0.5, 2.5);
        assert_eq!(m.triangles.len(), 10);
        let (min, max) = m.bounds().unwrap();
        assert_eq!((min.x, min.y, min.z), (1.0, 2.0, 0.0));
        assert_eq!((max.x, max.y, max.z), (1.5, 2.5, 2.5));
        // Every wall normal points towards the cell centre (1.25, 2.25).
        for &t in &m.triangles {
            let n = normal(&m, t);
            let a = m.vertices[t[0] as usize];
            let to_centre = [1.25 - a.x, 2.25 - a.y];
            assert!(n[0] * to_centre[0] + n[1] * to_centre[1] >= 0.0);
            assert!(n[2] >= 0.0);
        }
    }

    #[test]
    fn faces_are_merged_not_per_cell() {
        // A 20 × 10 free room with a 1-cell solid ring: 1 floor rect, 4 cap rects at most, 4 walls.
        let (nx, ny) = (22, 12);
        let solid: Vec<bool> = (0..nx * ny)
            .map(|i| {
                let (x, y) = (i % nx, i / nx);
                x == 0 || y == 0 || x == nx - 1 || y == ny - 1
            })
            .collect();
        let m = extrude_grid(&solid, nx, ny, [0.0, 0.0], 0.1, 2.5);
        let rects_cap = greedy_rects(&solid, nx, ny).len();
        assert_eq!(rects_cap, 4);
        assert_eq!(m.triangles.len(), 2 * (1 + rects_cap + 4));
        let (min, max) = m.bounds().unwrap();
        assert!((max.x - min.x - 2.2).abs() < 1e-6 && (max.y - min.y - 1.2).abs() < 1e-6);
    }

    #[test]
    fn greedy_rects_cover_exactly_the_mask() {
        let (nx, ny) = (7, 5);
        let mask: Vec<bool> = (0..nx * ny).map(|i| (i * 7919) % 3 != 0).collect();
        let mut covered = vec![0u8; nx * ny];
        for (x0, y0, x1, y1) in greedy_rects(&mask, nx, ny) {
            for y in y0..y1 {
                for x in x0..x1 {
                    covered[y * nx + x] += 1;
                }
            }
        }
        let expected: Vec<u8> = mask.iter().map(|&m| m as u8).collect();
        assert_eq!(covered, expected);
    }
}
