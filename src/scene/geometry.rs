//! Exact small geometry tests on triangles, shared by the ground truth and the ray caster.

/// Exact test of one triangle against a vertical cylinder (see `MeshBvh::cylinder_intersects`).
pub fn triangle_meets_cylinder(
    tri: [[f64; 3]; 3],
    x: f64,
    y: f64,
    radius: f64,
    z_min: f64,
    z_max: f64,
) -> bool {
    // Clip to z ≥ z_min, then z ≤ z_max (Sutherland–Hodgman; inclusive, so a triangle lying in a slab
    // face is kept). At most 5 vertices result.
    let mut poly: Vec<[f64; 3]> = tri.to_vec();
    poly = clip(&poly, 2, z_min, true);
    poly = clip(&poly, 2, z_max, false);
    if poly.is_empty() {
        return false;
    }
    let pts: Vec<[f64; 2]> = poly.iter().map(|p| [p[0] - x, p[1] - y]).collect();
    let r2 = radius * radius;
    // Any vertex or edge within the radius?
    for i in 0..pts.len() {
        let a = pts[i];
        let b = pts[(i + 1) % pts.len()];
        if segment_origin_dist2(a, b) <= r2 {
            return true;
        }
    }
    // Otherwise the axis must lie strictly inside the projected (convex) polygon.
    let mut sign = 0.0f64;
    for i in 0..pts.len() {
        let a = pts[i];
        let b = pts[(i + 1) % pts.len()];
        // Cross product of edge a→b with a→origin.
        let cross = (b[0] - a[0]) * (-a[1]) - (b[1] - a[1]) * (-a[0]);
        if cross == 0.0 {
            continue;
        }
        if sign == 0.0 {
            sign = cross.signum();
        } else if cross.signum() != sign {
            return false;
        }
    }
    sign != 0.0
}

/// The x and y extent of the part of a triangle inside the closed box `[lo, hi]`, or `None` if no
/// part of it lies inside: the box of the true surface in a voxel column, as the map's obstacle box
/// is the box of the ray hits there.
pub fn triangle_extent_in_box(
    tri: [[f64; 3]; 3],
    lo: [f64; 3],
    hi: [f64; 3],
) -> Option<([f64; 2], [f64; 2])> {
    let mut poly: Vec<[f64; 3]> = tri.to_vec();
    for axis in 0..3 {
        poly = clip(&poly, axis, lo[axis], true);
        poly = clip(&poly, axis, hi[axis], false);
        if poly.is_empty() {
            return None;
        }
    }
    let mut min = [f64::INFINITY; 2];
    let mut max = [f64::NEG_INFINITY; 2];
    for p in &poly {
        for a in 0..2 {
            // Clipped coordinates are kept inside the box against rounding.
            let v = p[a].clamp(lo[a], hi[a]);
            min[a] = min[a].min(v);
            max[a] = max[a].max(v);
        }
    }
    Some((min, max))
}

/// Keeps the part of a convex polygon with coordinate `axis` at least `plane` (`keep_above`) or at
/// most `plane` (Sutherland–Hodgman; inclusive, so a polygon lying in the plane is kept).
fn clip(poly: &[[f64; 3]], axis: usize, plane: f64, keep_above: bool) -> Vec<[f64; 3]> {
    let inside = |p: &[f64; 3]| {
        if keep_above {
            p[axis] >= plane
        } else {
            p[axis] <= plane
        }
    };
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        let (ia, ib) = (inside(&a), inside(&b));
        if ia {
            out.push(a);
        }
        if ia != ib {
            let t = (plane - a[axis]) / (b[axis] - a[axis]);
            let mut p = [0.0; 3];
            for k in 0..3 {
                p[k] = a[k] + t * (b[k] - a[k]);
            }
            p[axis] = plane;
            out.push(p);
        }
    }
    out
}

/// Squared distance from the origin to segment `ab` in the plane.
fn segment_origin_dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 > 0.0 {
        ((-a[0] * d[0] - a[1] * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let p = [a[0] + t * d[0], a[1] + t * d[1]];
    p[0] * p[0] + p[1] * p[1]
}
