//! Depth by rasterisation: a CPU z-buffer renderer of the scene mesh for the pinhole camera.
//!
//! Per frame, the triangles near the camera are gathered from a coarse 2D grid of bins (1 m) over
//! the frustum's floor footprint, culled against the frustum (the four side planes, the far plane at
//! the maximum range and a near plane just in front of the optical centre), clipped to the near plane
//! and projected to find the pixels they may cover: the rows of the projection's bounding box and,
//! on each row, the projected polygon's extent within the strip of the neighbouring rows, grown by
//! one pixel (a conservative scan conversion). Each of those pixels then gets the exact two-sided
//! Möller–Trumbore test along *its own ray* (the same unit direction the ray caster uses), and the
//! z-buffer keeps the nearest hit. Coverage and depth are decided by the caster's own per-triangle
//! arithmetic (the terms that do not depend on the ray are hoisted, which changes no bit), so a
//! pixel's depth is the minimum over the triangles of exactly the caster's test. Measured against
//! [`super::MeshBvh::cast`] (`tests/raster_vs_raycast.rs`, every shipped scene and four real plans):
//! about 0.1% of pixels differ by a few ulps (the BVH's box pruning can keep a hit an ulp farther
//! than the minimum where faces overlap), and a handful of rays grazing an edge, or a face seen
//! edge-on, differ by more: silhouettes.
//!
//! A z-buffer of ray distances (not of z-depth) makes the range rule the caster's: no hit within the
//! maximum range → `f32::INFINITY`; a nearest hit nearer than the minimum range → `NaN`.

use super::raycast::validate;
use crate::error::Result;
use crate::scene::TriMesh;
use nalgebra::Vector3;
use parry3d::math::Vector as PVector;
use rayon::prelude::*;

/// Edge of a bin of the triangle grid, metres.
const BIN_M: f32 = 1.0;
/// The near clipping plane's distance in front of the optical centre along the axis, metres. A
/// surface nearer than this is not rendered; the caster would report it as too near (NaN) anyway,
/// but could then differ from the rasteriser on what lies behind it.
const NEAR_M: f32 = 1e-5;
/// Pixels per rayon task when filling the z-buffer (whole rows).
const PIXELS_PER_TASK: usize = 2048;

/// The scene mesh prepared for rendering: triangles in the ray-test form and binned on the floor plane.
pub struct MeshRaster {
    /// Per triangle: its corners, for culling and projection.
    corners: Vec<[PVector; 3]>,
    /// Per triangle: first vertex and the two edges from it, computed as `MeshBvh` computes them.
    tris: Vec<[PVector; 3]>,
    /// Per triangle: the lowest bin (x, y) it overlaps.
    first_bin: Vec<[u32; 2]>,
    /// Lower-left corner of bin (0, 0), metres.
    bin_origin: [f32; 2],
    /// Bins along x and y.
    bins: [usize; 2],
    /// Compressed rows: the triangles of bin `b` are `bin_tris[bin_start[b]..bin_start[b + 1]]`.
    bin_start: Vec<u32>,
    bin_tris: Vec<u32>,
}

/// The camera's intrinsics as the rasteriser needs them.
#[derive(Clone, Copy, Debug)]
pub struct RasterCamera {
    pub width: usize,
    pub height: usize,
    /// Tangents of the half fields of view (horizontal, vertical).
    pub tan_h: f32,
    pub tan_v: f32,
    pub max_range: f32,
}

/// One triangle ready to fill: the ray-independent terms of the ray test and its pixel rectangle.
struct Setup {
    s: PVector,
    q: PVector,
    e1: PVector,
    e2: PVector,
    /// `e2 · q`: the distance is this over the determinant.
    tq: f32,
    rows: [usize; 2],
    cols: [usize; 2],
    /// The projected polygon (the triangle clipped to the near plane), in continuous pixel
    /// coordinates `(u, v)` whose integers are pixel centres; `n` vertices. In f64: a vertex near
    /// the near plane projects far outside the image, and f32 would lose whole pixels there.
    poly: [[f64; 2]; 4],
    n: usize,
}

impl Setup {
    /// The columns of row `row` to test: the polygon's extent within the strip of rows
    /// `row ± 1`, grown by a pixel (the slack absorbs the projection's rounding; the ray test
    /// decides), clipped to the triangle's column range.
    #[inline]
    fn row_cols(&self, row: usize) -> Option<[usize; 2]> {
        let (a, b) = (row as f64 - 1.0, row as f64 + 1.0);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let poly = &self.poly[..self.n];
        for i in 0..poly.len() {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            if p[1] >= a && p[1] <= b {
                lo = lo.min(p[0]);
                hi = hi.max(p[0]);
            }
            for line in [a, b] {
                if (p[1] < line) != (q[1] < line) {
                    let u = p[0] + (line - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
                    lo = lo.min(u);
                    hi = hi.max(u);
                }
            }
        }
        let c0 = (lo.floor() - 1.0).max(self.cols[0] as f64);
        let c1 = (hi.ceil() + 1.0).min(self.cols[1] as f64);
        (c0 <= c1).then_some([c0 as usize, c1 as usize])
    }
}

impl MeshRaster {
    /// Prepares `mesh` (rejecting a non-finite vertex or an out-of-range index, as `MeshBvh` does).
    pub fn new(mesh: &TriMesh) -> Result<MeshRaster> {
        validate(mesh)?;
        let v = |i: u32| {
            let p = mesh.vertices[i as usize];
            PVector::new(p.x, p.y, p.z)
        };
        let corners: Vec<[PVector; 3]> = mesh
            .triangles
            .iter()
            .map(|t| [v(t[0]), v(t[1]), v(t[2])])
            .collect();
        let tris = corners.iter().map(|&[a, b, c]| [a, b - a, c - a]).collect();
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for p in corners.iter().flatten() {
            lo = [lo[0].min(p.x), lo[1].min(p.y)];
            hi = [hi[0].max(p.x), hi[1].max(p.y)];
        }
        if corners.is_empty() {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        let bins = [
            ((hi[0] - lo[0]) / BIN_M) as usize + 1,
            ((hi[1] - lo[1]) / BIN_M) as usize + 1,
        ];
        let mut raster = MeshRaster {
            corners,
            tris,
            first_bin: Vec::new(),
            bin_origin: lo,
            bins,
            bin_start: vec![0; bins[0] * bins[1] + 1],
            bin_tris: Vec::new(),
        };
        // Counting sort of (bin, triangle) pairs into compressed rows, triangles ascending per bin.
        let ranges: Vec<[[usize; 2]; 2]> = raster
            .corners
            .iter()
            .map(|c| {
                let (x0, x1) = (
                    c[0].x.min(c[1].x).min(c[2].x),
                    c[0].x.max(c[1].x).max(c[2].x),
                );
                let (y0, y1) = (
                    c[0].y.min(c[1].y).min(c[2].y),
                    c[0].y.max(c[1].y).max(c[2].y),
                );
                let a = raster.bin_of(x0, y0);
                let b = raster.bin_of(x1, y1);
                [[a[0], b[0]], [a[1], b[1]]]
            })
            .collect();
        raster.first_bin = ranges
            .iter()
            .map(|r| [r[0][0] as u32, r[1][0] as u32])
            .collect();
        for r in &ranges {
            for by in r[1][0]..=r[1][1] {
                for bx in r[0][0]..=r[0][1] {
                    raster.bin_start[by * bins[0] + bx + 1] += 1;
                }
            }
        }
        for b in 0..bins[0] * bins[1] {
            raster.bin_start[b + 1] += raster.bin_start[b];
        }
        let mut fill = raster.bin_start.clone();
        raster.bin_tris = vec![0; *raster.bin_start.last().unwrap() as usize];
        for (t, r) in ranges.iter().enumerate() {
            for by in r[1][0]..=r[1][1] {
                for bx in r[0][0]..=r[0][1] {
                    let slot = &mut fill[by * bins[0] + bx];
                    raster.bin_tris[*slot as usize] = t as u32;
                    *slot += 1;
                }
            }
        }
        Ok(raster)
    }

    /// Number of triangles.
    pub fn triangles(&self) -> usize {
        self.tris.len()
    }

    /// The bin holding `(x, y)`, clamped to the grid.
    fn bin_of(&self, x: f32, y: f32) -> [usize; 2] {
        let f = |v: f32, o: f32, n: usize| (((v - o) / BIN_M).max(0.0) as usize).min(n - 1);
        [
            f(x, self.bin_origin[0], self.bins[0]),
            f(y, self.bin_origin[1], self.bins[1]),
        ]
    }

    /// Renders ray distances into `range` (row-major, `cam.width × cam.height`) for the pixel rays
    /// `dirs` (unit, world frame) from `origin`, looking along the horizontal unit axis `(cos, sin)`.
    /// Writes the nearest hit distance below `cam.max_range`, or `cam.max_range` where there is none
    /// (the caller applies the range rule). Triangles are set up in order and each z-buffer row band
    /// is filled by one task; the minimum does not depend on the order, so neither does the frame.
    pub fn render_ranges(
        &self,
        cam: &RasterCamera,
        origin: PVector,
        (cos, sin): (f32, f32),
        dirs: &[Vector3<f32>],
        range: &mut [f32],
    ) {
        let (w, h) = (cam.width, cam.height);
        debug_assert_eq!(dirs.len(), w * h);
        range.fill(cam.max_range);
        let mut list = Vec::with_capacity(256);
        let [qx, qy] = self.query_bins(origin, (cos, sin), cam);
        for by in qy[0]..=qy[1] {
            for bx in qx[0]..=qx[1] {
                let b = by * self.bins[0] + bx;
                let tris =
                    &self.bin_tris[self.bin_start[b] as usize..self.bin_start[b + 1] as usize];
                for &t in tris {
                    // A triangle spanning several bins is taken in the first of them in the query.
                    let [fx, fy] = self.first_bin[t as usize];
                    if bx != (fx as usize).max(qx[0]) || by != (fy as usize).max(qy[0]) {
                        continue;
                    }
                    if let Some(s) = self.setup(t as usize, cam, origin, (cos, sin)) {
                        list.push(s);
                    }
                }
            }
        }
        let list: &[Setup] = &list;
        let rows_per_task = (PIXELS_PER_TASK / w).max(1);
        range
            .par_chunks_mut(rows_per_task * w)
            .enumerate()
            .for_each(|(task, band)| {
                let r0 = task * rows_per_task;
                let r1 = r0 + band.len() / w; // exclusive
                for s in list {
                    let (a, b) = (s.rows[0].max(r0), (s.rows[1] + 1).min(r1));
                    for row in a..b {
                        let base = row * w;
                        let Some([c0, c1]) = s.row_cols(row) else {
                            continue;
                        };
                        for col in c0..=c1 {
                            let d = dirs[base + col];
                            let d = PVector::new(d.x, d.y, d.z);
                            let z = &mut band[base - r0 * w + col];
                            // Möller–Trumbore as `raycast::ray_triangle`, operation for operation.
                            let p = d.cross(s.e2);
                            let det = s.e1.dot(p);
                            if det.abs() < 1e-12 {
                                continue;
                            }
                            let inv = 1.0 / det;
                            let u = s.s.dot(p) * inv;
                            if !(0.0..=1.0).contains(&u) {
                                continue;
                            }
                            let v = d.dot(s.q) * inv;
                            if v < 0.0 || u + v > 1.0 {
                                continue;
                            }
                            let t = s.tq * inv;
                            if t >= 0.0 && t < *z {
                                *z = t;
                            }
                        }
                    }
                }
            });
    }

    /// The bins (x range, y range, inclusive) that the frustum's floor footprint overlaps: the
    /// bounding box of the circular sector of radius `max_range` and the horizontal field of view
    /// (every pixel ray's horizontal direction lies within it, and its horizontal reach is at most
    /// its length).
    fn query_bins(
        &self,
        o: PVector,
        (cos, sin): (f32, f32),
        cam: &RasterCamera,
    ) -> [[usize; 2]; 2] {
        let r = cam.max_range as f64;
        let yaw = (sin as f64).atan2(cos as f64);
        let half = (cam.tan_h as f64).atan();
        let (mut lo, mut hi) = ([o.x as f64, o.y as f64], [o.x as f64, o.y as f64]);
        let mut add = |a: f64| {
            let p = [o.x as f64 + r * a.cos(), o.y as f64 + r * a.sin()];
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
        };
        add(yaw - half);
        add(yaw + half);
        // The arc's extreme points along the axes, where they fall inside the sector.
        for k in -4..=4 {
            let a = k as f64 * std::f64::consts::FRAC_PI_2;
            if (a - yaw).abs() <= half {
                add(a);
            }
        }
        let pad = 1e-3;
        let a = self.bin_of((lo[0] - pad) as f32, (lo[1] - pad) as f32);
        let b = self.bin_of((hi[0] + pad) as f32, (hi[1] + pad) as f32);
        [[a[0], b[0]], [a[1], b[1]]]
    }

    /// Culls triangle `t` against the frustum, or returns its fill setup.
    fn setup(
        &self,
        t: usize,
        cam: &RasterCamera,
        o: PVector,
        (cos, sin): (f32, f32),
    ) -> Option<Setup> {
        // Camera frame: x forward, y left, z up.
        let cam_pt = |p: PVector| {
            let r = p - o;
            [r.x * cos + r.y * sin, r.y * cos - r.x * sin, r.z]
        };
        let c = self.corners[t].map(cam_pt);
        let all = |f: &dyn Fn(&[f32; 3]) -> bool| c.iter().all(f);
        // A hit at distance t along a unit ray has forward coordinate ≤ t: beyond the far plane no
        // hit lies within range. The side planes pass through the image's edges, outside every
        // pixel centre, so a triangle wholly outside one meets no pixel ray.
        if all(&|p| p[0] >= cam.max_range) || all(&|p| p[0] < NEAR_M) {
            return None;
        }
        let (th, tv) = (cam.tan_h, cam.tan_v);
        if all(&|p| p[1] > p[0] * th)
            || all(&|p| -p[1] > p[0] * th)
            || all(&|p| p[2] > p[0] * tv)
            || all(&|p| -p[2] > p[0] * tv)
        {
            return None;
        }
        // Clip to the near plane (a triangle gives at most a quadrilateral), project, and take the
        // pixel-centre bounding box.
        let mut poly = [[0.0f32; 3]; 4];
        let mut n = 0;
        for i in 0..3 {
            let (a, b) = (c[i], c[(i + 1) % 3]);
            let (ia, ib) = (a[0] >= NEAR_M, b[0] >= NEAR_M);
            if ia {
                poly[n] = a;
                n += 1;
            }
            if ia != ib {
                let k = (NEAR_M - a[0]) / (b[0] - a[0]);
                poly[n] = [NEAR_M, a[1] + k * (b[1] - a[1]), a[2] + k * (b[2] - a[2])];
                n += 1;
            }
        }
        let (w, h) = (cam.width as f64, cam.height as f64);
        let (th, tv) = (th as f64, tv as f64);
        let mut proj = [[0.0f64; 2]; 4];
        let (mut u0, mut u1, mut v0, mut v1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for (p, pr) in poly[..n].iter().zip(&mut proj) {
            let x = p[0].max(NEAR_M) as f64;
            // Continuous pixel coordinates whose integers are the pixel centres.
            let u = (-p[1] as f64 / x / th + 1.0) * 0.5 * w - 0.5;
            let v = (-p[2] as f64 / x / tv + 1.0) * 0.5 * h - 0.5;
            *pr = [u, v];
            u0 = u0.min(u);
            u1 = u1.max(u);
            v0 = v0.min(v);
            v1 = v1.max(v);
        }
        // One pixel of slack absorbs the rounding of the projection; the ray test decides.
        let span = |lo: f64, hi: f64, n: usize| -> Option<[usize; 2]> {
            let a = (lo.floor() - 1.0).max(0.0);
            let b = (hi.ceil() + 1.0).min(n as f64 - 1.0);
            (a <= b).then_some([a as usize, b as usize])
        };
        let cols = span(u0, u1, cam.width)?;
        let rows = span(v0, v1, cam.height)?;
        let [v0, e1, e2] = self.tris[t];
        let s = o - v0;
        let q = s.cross(e1);
        Some(Setup {
            s,
            q,
            e1,
            e2,
            tq: e2.dot(q),
            rows,
            cols,
            poly: proj,
            n,
        })
    }
}
