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

    /// Drops every triangle that repeats an earlier one: the same three corner positions in the
    /// same cyclic order (a face the other way round stays: it faces the other side). A repeated
    /// face changes nothing the camera, the collision test or the ground truth can see, but
    /// multiplies the work of every test that lists the faces in a voxel (a face copied thousands
    /// of times kept the observable set busy for minutes). Answers how many were dropped.
    pub fn drop_repeated_triangles(&mut self) -> usize {
        let TriMesh {
            vertices,
            triangles,
        } = self;
        let corner = |i: u32| vertices[i as usize].coords.map(f32::to_bits).into();
        let mut seen = std::collections::HashSet::with_capacity(triangles.len());
        let before = triangles.len();
        triangles.retain(|t| {
            let c: [[u32; 3]; 3] = t.map(corner);
            let first = (0..3).min_by_key(|&k| c[k]).unwrap_or(0);
            seen.insert([c[first], c[(first + 1) % 3], c[(first + 2) % 3]])
        });
        before - triangles.len()
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

/// Most vertices of a non-convex face: ear clipping costs up to the cube of the count.
pub const MAX_CONCAVE_FACE_VERTICES: usize = 1000;

/// Appends the triangles of the planar polygon `face` (indices into `vertices`, in order) to `out`.
/// A convex face (or a degenerate one, of no area) is fanned from its first vertex, as OBJ and PLY
/// loaders do; a non-convex one is ear-clipped, so that it does not cover its notches. Fails, with
/// the reason, for a non-convex face of more than [`MAX_CONCAVE_FACE_VERTICES`] vertices or one
/// whose edges cross.
pub fn triangulate_face(
    vertices: &[Point3<f32>],
    face: &[u32],
    out: &mut Vec<[u32; 3]>,
) -> Result<(), String> {
    let n = face.len();
    let fan = |out: &mut Vec<[u32; 3]>| {
        for k in 1..n.saturating_sub(1) {
            out.push([face[0], face[k], face[k + 1]]);
        }
    };
    if n <= 3 {
        fan(out);
        return Ok(());
    }
    let p3: Vec<[f64; 3]> = face
        .iter()
        .map(|&i| {
            let v = vertices[i as usize];
            [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
        })
        .collect();
    // Newell's normal; the polygon is projected on the plane of its two other axes.
    let mut normal = [0.0f64; 3];
    for i in 0..n {
        let (a, b) = (p3[i], p3[(i + 1) % n]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let drop = (0..3)
        .max_by(|&a, &b| normal[a].abs().total_cmp(&normal[b].abs()))
        .unwrap_or(2);
    let (u, v) = ((drop + 1) % 3, (drop + 2) % 3);
    let p: Vec<[f64; 2]> = p3.iter().map(|q| [q[u], q[v]]).collect();
    // Orientation: +1 counter-clockwise in the projection.
    let sign = if normal[drop] == 0.0 {
        0.0
    } else {
        normal[drop].signum()
    };
    let scale = p
        .iter()
        .flat_map(|q| q.iter())
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(1e-9);
    let eps = 1e-12 * scale * scale;
    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        sign * ((b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]))
    };
    let convex = sign == 0.0 || (0..n).all(|i| cross(p[i], p[(i + 1) % n], p[(i + 2) % n]) >= -eps);
    if convex {
        fan(out);
        return Ok(());
    }
    if n > MAX_CONCAVE_FACE_VERTICES {
        return Err(format!(
            "a non-convex face of {n} vertices (at most {MAX_CONCAVE_FACE_VERTICES} are triangulated)"
        ));
    }
    // Ear clipping: a convex corner whose triangle holds no other remaining vertex is cut off.
    let inside = |q: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        cross(a, b, q) >= -eps && cross(b, c, q) >= -eps && cross(c, a, q) >= -eps
    };
    let mut left: Vec<usize> = (0..n).collect();
    while left.len() > 3 {
        let m = left.len();
        let ear = (0..m).find(|&k| {
            let (a, b, c) = (left[(k + m - 1) % m], left[k], left[(k + 1) % m]);
            cross(p[a], p[b], p[c]) > eps
                && left.iter().all(|&j| {
                    j == a
                        || j == b
                        || j == c
                        || p[j] == p[a]
                        || p[j] == p[b]
                        || p[j] == p[c]
                        || !inside(p[j], p[a], p[b], p[c])
                })
        });
        let Some(k) = ear else {
            return Err(format!(
                "a non-convex face of {n} vertices whose edges cross (not a simple polygon)"
            ));
        };
        let (a, b, c) = (left[(k + m - 1) % m], left[k], left[(k + 1) % m]);
        out.push([face[a], face[b], face[c]]);
        left.remove(k);
    }
    out.push([face[left[0]], face[left[1]], face[left[2]]]);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_triangles_are_dropped_and_turned_ones_kept() {
        let mut m = TriMesh::default();
        let a = m.push_vertex(0.0, 0.0, 0.0);
        let b = m.push_vertex(1.0, 0.0, 0.0);
        let c = m.push_vertex(0.0, 1.0, 0.0);
        // The same corners again under other indices (as OBJ files often repeat vertices).
        let (a2, b2, c2) = (
            m.push_vertex(0.0, 0.0, 0.0),
            m.push_vertex(1.0, 0.0, 0.0),
            m.push_vertex(0.0, 1.0, 0.0),
        );
        m.triangles = vec![
            [a, b, c],
            [b, c, a],    // the same face, another first corner
            [a2, b2, c2], // the same positions, other vertices
            [a, c, b],    // turned round: faces the other way, kept
            [a, b, c],
            [c2, b2, a2], // turned round again: a repeat of the turned face
        ];
        assert_eq!(m.drop_repeated_triangles(), 4);
        assert_eq!(m.triangles, vec![[a, b, c], [a, c, b]]);
        assert_eq!(m.drop_repeated_triangles(), 0);
    }
}
