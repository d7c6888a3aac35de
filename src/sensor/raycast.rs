//! Ray casting and collision queries against the scene mesh, through parry3d's triangle-mesh BVH.
//!
//! parry3d 0.31 works in glam `f32` types; this module converts at its boundary so that the rest of the
//! crate sees only nalgebra.

use crate::error::{Error, Result};
use crate::scene::geometry::triangle_meets_cylinder;
use crate::scene::TriMesh;
use nalgebra::{Point3, Vector3};
use parry3d::bounding_volume::Aabb;
use parry3d::math::Vector as PVector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh as PTriMesh;

/// The scene mesh with its bounding-volume hierarchy, built once per scene.
pub struct MeshBvh {
    mesh: PTriMesh,
    /// Per triangle: first vertex and the two edges from it, for a lean two-sided Möller–Trumbore test
    /// (parry's generic triangle ray cast does more work than a depth camera needs).
    tris: Vec<[PVector; 3]>,
}

impl MeshBvh {
    /// Builds the BVH. A mesh with no triangles, an out-of-range index or a non-finite vertex is an
    /// error (parry would panic or build a useless tree on some of these), as is anything parry rejects.
    pub fn new(mesh: &TriMesh) -> Result<MeshBvh> {
        validate(mesh)?;
        let vertices = mesh
            .vertices
            .iter()
            .map(|p| PVector::new(p.x, p.y, p.z))
            .collect();
        let mesh = PTriMesh::new(vertices, mesh.triangles.clone())
            .map_err(|e| Error::Runtime(format!("mesh rejected by the ray caster: {e}")))?;
        let tris = (0..mesh.indices().len() as u32)
            .map(|i| {
                let t = mesh.triangle(i);
                [t.a, t.b - t.a, t.c - t.a]
            })
            .collect();
        Ok(MeshBvh { mesh, tris })
    }

    /// Distance along the unit direction `dir` from `origin` to the first triangle hit (front or back
    /// face), if one lies within `max_range`.
    #[inline]
    pub fn cast(&self, origin: Point3<f32>, dir: Vector3<f32>, max_range: f32) -> Option<f32> {
        let ray = Ray::new(
            PVector::new(origin.x, origin.y, origin.z),
            PVector::new(dir.x, dir.y, dir.z),
        );
        self.mesh
            .bvh()
            .cast_ray(&ray, max_range, |i, best| {
                ray_triangle(ray.origin, ray.dir, &self.tris[i as usize], best)
            })
            .map(|(_, t)| t)
    }

    /// [`MeshBvh::cast`] restricted to the triangles `candidates` (indices into the mesh), with the
    /// same arithmetic: a caller that walks a grid and knows which triangles touch each cell gets the
    /// same distances without the tree.
    #[inline]
    pub fn cast_among(
        &self,
        origin: Point3<f32>,
        dir: Vector3<f32>,
        candidates: &[u32],
        max_range: f32,
    ) -> Option<f32> {
        let o = PVector::new(origin.x, origin.y, origin.z);
        let d = PVector::new(dir.x, dir.y, dir.z);
        let mut best = max_range;
        let mut hit = None;
        for &i in candidates {
            if let Some(t) = ray_triangle(o, d, &self.tris[i as usize], best) {
                best = t;
                hit = Some(t);
            }
        }
        hit
    }

    /// The same query through parry's own triangle ray cast: the reference for [`MeshBvh::cast`].
    pub fn cast_reference(
        &self,
        origin: Point3<f32>,
        dir: Vector3<f32>,
        max_range: f32,
    ) -> Option<f32> {
        let ray = Ray::new(
            PVector::new(origin.x, origin.y, origin.z),
            PVector::new(dir.x, dir.y, dir.z),
        );
        self.mesh.cast_local_ray(&ray, max_range, false)
    }

    /// Whether the vertical cylinder with axis through `(x, y)`, `radius` and height range
    /// `[z_min, z_max]` touches or overlaps any triangle (boundary contact counts).
    ///
    /// Exact: each candidate triangle from the BVH is clipped to the slab `z_min ≤ z ≤ z_max`; the
    /// cylinder meets the triangle iff that clipped polygon, projected onto the floor, comes within
    /// `radius` of `(x, y)` (the cylinder is a disc extruded along z, so the test separates into the
    /// vertical clip and a planar point–polygon distance). Computed in f64.
    pub fn cylinder_intersects(&self, x: f64, y: f64, radius: f64, z_min: f64, z_max: f64) -> bool {
        if !(radius >= 0.0 && z_min <= z_max) {
            return false;
        }
        // Pad the query box by a hair so that f32 rounding of its corners cannot drop a touching triangle;
        // the exact test below decides.
        let pad = 1e-4 * (1.0 + radius);
        let aabb = Aabb::new(
            PVector::new(
                (x - radius - pad) as f32,
                (y - radius - pad) as f32,
                (z_min - pad) as f32,
            ),
            PVector::new(
                (x + radius + pad) as f32,
                (y + radius + pad) as f32,
                (z_max + pad) as f32,
            ),
        );
        let hit = self.mesh.bvh().intersect_aabb(&aabb).any(|i| {
            let tri = self.mesh.triangle(i);
            let corner = |v: PVector| [v.x as f64, v.y as f64, v.z as f64];
            triangle_meets_cylinder(
                [corner(tri.a), corner(tri.b), corner(tri.c)],
                x,
                y,
                radius,
                z_min,
                z_max,
            )
        });
        hit
    }
}

/// Rejects a mesh with a non-finite vertex or an out-of-range index (an empty mesh is left to the
/// caller: parry rejects it, the rasteriser renders nothing).
pub(super) fn validate(mesh: &TriMesh) -> Result<()> {
    if let Some((i, v)) = mesh
        .vertices
        .iter()
        .enumerate()
        .find(|(_, v)| !v.iter().all(|c| c.is_finite()))
    {
        return Err(Error::Runtime(format!(
            "mesh vertex {i} is not finite: ({}, {}, {})",
            v.x, v.y, v.z
        )));
    }
    let n = mesh.vertices.len();
    if let Some((t, tri)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find(|(_, tri)| tri.iter().any(|&i| i as usize >= n))
    {
        return Err(Error::Runtime(format!(
            "mesh triangle {t} refers to a vertex out of range: {tri:?} with {n} vertices"
        )));
    }
    Ok(())
}

/// Two-sided Möller–Trumbore: distance to triangle `[v0, e1, e2]` if hit in `[0, max)`.
#[inline(always)]
fn ray_triangle(o: PVector, d: PVector, tri: &[PVector; 3], max: f32) -> Option<f32> {
    let [v0, e1, e2] = *tri;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None; // parallel to the triangle's plane
    }
    let inv = 1.0 / det;
    let s = o - v0;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t >= 0.0 && t < max).then_some(t)
}

/// Test and bench geometry: axis-aligned boxes as closed triangle meshes.
pub mod testing {
    use crate::scene::TriMesh;

    /// Appends the 12 triangles of the box `[min, max]` to `mesh` ([`TriMesh::push_box`] in `f32`).
    pub fn push_box(mesh: &mut TriMesh, min: [f32; 3], max: [f32; 3]) {
        mesh.push_box(min.map(f64::from), max.map(f64::from));
    }

    /// A furnished room: floor, four walls (the room box's inside faces), a table-like box, a shelf and a
    /// pillar. `size` is the room's edge in x and y, metres; walls 2.5 m high.
    pub fn furnished_room(size: f32) -> TriMesh {
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [0.0, 0.0, 0.0], [size, size, 2.5]);
        let s = size / 8.0;
        push_box(&mut mesh, [2.0 * s, 5.0 * s, 0.0], [3.5 * s, 6.0 * s, 0.75]);
        push_box(&mut mesh, [6.0 * s, 1.0 * s, 0.0], [7.5 * s, 1.5 * s, 1.9]);
        push_box(&mut mesh, [4.0 * s, 3.0 * s, 0.0], [4.3 * s, 3.3 * s, 2.5]);
        push_box(&mut mesh, [1.0 * s, 1.0 * s, 0.3], [2.0 * s, 2.0 * s, 0.5]);
        mesh
    }
}

#[cfg(test)]
mod tests {
    use super::testing::push_box;
    use super::*;

    fn unit_box_mesh() -> TriMesh {
        let mut m = TriMesh::default();
        push_box(&mut m, [1.0, -1.0, 0.0], [2.0, 1.0, 1.0]);
        m
    }

    #[test]
    fn ray_hits_box_face_at_known_distance() {
        let bvh = MeshBvh::new(&unit_box_mesh()).unwrap();
        let d = bvh
            .cast(Point3::new(0.0, 0.0, 0.5), Vector3::new(1.0, 0.0, 0.0), 5.0)
            .unwrap();
        assert!((d - 1.0).abs() < 1e-5, "{d}");
        // Diagonal: 45° in xy reaches x = 1 after √2.
        let dir = Vector3::new(1.0, 0.5, 0.0).normalize();
        let d = bvh.cast(Point3::new(0.0, 0.0, 0.5), dir, 5.0).unwrap();
        assert!((d - 1.25f32.sqrt()).abs() < 1e-5, "{d}");
    }

    #[test]
    fn cast_agrees_with_parrys_triangle_cast() {
        use rand::{Rng, SeedableRng};
        let bvh = MeshBvh::new(&super::testing::furnished_room(8.0)).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let (mut hits, mut disagree) = (0, 0);
        for _ in 0..20000 {
            let o = Point3::new(
                rng.random_range(0.1..7.9),
                rng.random_range(0.1..7.9),
                rng.random_range(0.1..2.4),
            );
            let d = Vector3::new(
                rng.random_range(-1.0f32..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            match (bvh.cast(o, d, 5.0), bvh.cast_reference(o, d, 5.0)) {
                (Some(a), Some(b)) => {
                    hits += 1;
                    assert!((a - b).abs() < 1e-4, "{a} vs {b} from {o:?} along {d:?}");
                }
                (None, None) => {}
                // Rays grazing an edge may fall either side of it.
                _ => disagree += 1,
            }
        }
        assert!(hits > 10000, "{hits}");
        assert!(disagree <= 2, "{disagree}");
    }

    #[test]
    fn back_faces_are_hit_from_inside() {
        let bvh = MeshBvh::new(&unit_box_mesh()).unwrap();
        let d = bvh
            .cast(Point3::new(1.5, 0.0, 0.5), Vector3::new(1.0, 0.0, 0.0), 5.0)
            .unwrap();
        assert!((d - 0.5).abs() < 1e-5, "{d}");
    }

    #[test]
    fn beyond_max_range_and_away_is_none() {
        let bvh = MeshBvh::new(&unit_box_mesh()).unwrap();
        let o = Point3::new(0.0, 0.0, 0.5);
        assert_eq!(bvh.cast(o, Vector3::new(1.0, 0.0, 0.0), 0.9), None);
        assert_eq!(bvh.cast(o, Vector3::new(-1.0, 0.0, 0.0), 100.0), None);
    }

    #[test]
    fn bad_meshes_are_errors() {
        let e = MeshBvh::new(&TriMesh::default()).err().unwrap();
        assert_eq!(
            e.to_string(),
            "mesh rejected by the ray caster: A triangle mesh must contain at least one triangle."
        );
        let mut m = unit_box_mesh();
        m.triangles.push([0, 1, 99]);
        let e = MeshBvh::new(&m).err().unwrap();
        assert_eq!(
            e.to_string(),
            "mesh triangle 12 refers to a vertex out of range: [0, 1, 99] with 8 vertices"
        );
        let mut m = unit_box_mesh();
        m.vertices[3].y = f32::NAN;
        let e = MeshBvh::new(&m).err().unwrap();
        assert_eq!(e.to_string(), "mesh vertex 3 is not finite: (2, NaN, 0)");
    }

    #[test]
    fn cylinder_touching_vs_one_centimetre_away() {
        // Wall face at x = 1 (box spans x 1..2, y -1..1, z 0..1).
        let bvh = MeshBvh::new(&unit_box_mesh()).unwrap();
        assert!(bvh.cylinder_intersects(0.75, 0.0, 0.25, 0.1, 1.2));
        assert!(!bvh.cylinder_intersects(0.74, 0.0, 0.25, 0.1, 1.2));
        // Past the box's y end: corner (1, 1) at distance √(0.25²·2) ≈ 0.354 from (0.75, 1.25).
        assert!(!bvh.cylinder_intersects(0.75, 1.25, 0.35, 0.1, 1.2));
        assert!(bvh.cylinder_intersects(0.75, 1.25, 0.36, 0.1, 1.2));
        // Inside the box, away from its side faces: the slab 0.2..0.8 clips the top and bottom faces away.
        assert!(!bvh.cylinder_intersects(1.5, 0.0, 0.1, 0.2, 0.8));
        // A slab that includes the top face (z = 1) sees it under the axis.
        assert!(bvh.cylinder_intersects(1.5, 0.0, 0.1, 0.2, 1.0));
    }

    #[test]
    fn cylinder_below_an_overhang_is_clear() {
        // A shelf slab from z 1.3 to 1.4 above the robot (height 1.2) does not collide; at 1.3 it touches.
        let mut m = TriMesh::default();
        push_box(&mut m, [-1.0, -1.0, 1.3], [1.0, 1.0, 1.4]);
        let bvh = MeshBvh::new(&m).unwrap();
        assert!(!bvh.cylinder_intersects(0.0, 0.0, 0.25, 0.1, 1.2));
        assert!(bvh.cylinder_intersects(0.0, 0.0, 0.25, 0.1, 1.3));
    }

    #[test]
    fn triangle_test_handles_a_vertical_triangle_seen_edge_on() {
        // A vertical triangle in the plane y = 0.3 projects to a segment.
        let tri = [[-1.0, 0.3, 0.0], [1.0, 0.3, 0.0], [0.0, 0.3, 2.0]];
        assert!(triangle_meets_cylinder(tri, 0.0, 0.0, 0.3, 0.5, 1.0));
        assert!(!triangle_meets_cylinder(tri, 0.0, 0.0, 0.29, 0.5, 1.0));
        // Above the apex region: at z ∈ [1.9, 2.0] the triangle spans x in [-0.05, 0.05] only.
        assert!(!triangle_meets_cylinder(tri, 0.5, 0.3, 0.4, 1.9, 2.0));
        assert!(triangle_meets_cylinder(tri, 0.5, 0.3, 0.46, 1.9, 2.0));
    }
}
