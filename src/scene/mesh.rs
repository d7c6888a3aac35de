//! The triangle mesh every stage reads: metres, z up, floor at z = 0.

use nalgebra::Point3;

/// An indexed triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<Point3<f32>>,
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Axis-aligned bounds `(min, max)` of the vertices, or `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        let first = self.vertices.first()?;
        let mut min = first.cast::<f64>();
        let mut max = min;
        for v in &self.vertices {
            let v = v.cast::<f64>();
            min = min.inf(&v);
            max = max.sup(&v);
        }
        Some((min, max))
    }
}

impl TriMesh {
    /// Adds a vertex and returns its index.
    pub fn push_vertex(&mut self, x: f64, y: f64, z: f64) -> u32 {
        self.vertices
            .push(Point3::new(x as f32, y as f32, z as f32));
        (self.vertices.len() - 1) as u32
    }

    /// Adds the quad `a b c d` (counter-clockwise seen from the side its normal points to) as two
    /// triangles.
    pub fn push_quad(&mut self, [a, b, c, d]: [u32; 4]) {
        self.triangles.push([a, b, c]);
        self.triangles.push([a, c, d]);
    }

    /// Appends another mesh, re-indexing its triangles.
    pub fn append(&mut self, other: &TriMesh) {
        let offset = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + offset)));
    }

    /// Adds a closed axis-aligned box (12 outward-facing triangles). Boxes with an underside above the
    /// floor (table tops, wall shelves) need their bottom face, so every box gets all six.
    pub fn push_box(&mut self, min: [f64; 3], max: [f64; 3]) {
        let corner = |i: usize| {
            [
                if i & 1 == 0 { min[0] } else { max[0] },
                if i & 2 == 0 { min[1] } else { max[1] },
                if i & 4 == 0 { min[2] } else { max[2] },
            ]
        };
        let base = self.vertices.len() as u32;
        for i in 0..8 {
            let [x, y, z] = corner(i);
            self.push_vertex(x, y, z);
        }
        // Corner bits: 1 = +x, 2 = +y, 4 = +z.
        for quad in [
            [0, 2, 3, 1], // bottom (-z)
            [4, 5, 7, 6], // top (+z)
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
        ] {
            self.push_quad(quad.map(|i| base + i));
        }
    }

    /// Moves every vertex by `(dx, dy, dz)`.
    pub fn translate(&mut self, dx: f64, dy: f64, dz: f64) {
        for v in &mut self.vertices {
            *v = Point3::new(
                (v.x as f64 + dx) as f32,
                (v.y as f64 + dy) as f32,
                (v.z as f64 + dz) as f32,
            );
        }
    }
}
