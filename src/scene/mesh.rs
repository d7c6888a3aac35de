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
