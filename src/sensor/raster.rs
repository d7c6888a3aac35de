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
//! pixel's depth is the minimum over the triangles of exactly the caster's test.
//!
//! Occlusion culling skips only tests that cannot change a pixel, so frames are bit for bit those of
//! testing every triangle on its whole span (the `#[cfg(test)]` reference): each triangle gets a
//! proven lower bound on any distance its test can return, rounding included
//! ([`MeshRaster::near_bound`]); triangles are filled in order of that bound, and a tile of 8 × 8
//! pixels, or a tile's row of 8, whose largest depth is already at or below it is skipped (hidden
//! walls behind walls; the maxima are kept exact as depths fall). The test runs on a tile row's eight
//! pixels at once, branch-free, with the rays in coordinate arrays.
//!
//! Measured against [`super::MeshBvh::cast`] (`tests/raster_vs_raycast.rs`, every shipped scene and
//! four real plans): about 0.1% of pixels differ by a few ulps (the BVH's box pruning can keep a hit
//! an ulp farther than the minimum where faces overlap), and a handful of rays grazing an edge, or a
//! face seen edge-on, differ by more: silhouettes.
//!
//! A z-buffer of ray distances (not of z-depth) makes the range rule the caster's: no hit within the
//! maximum range → `f32::INFINITY`; a nearest hit nearer than the minimum range → `NaN`.

use super::raycast::validate;
use crate::error::Result;
use crate::scene::TriMesh;
use nalgebra::Vector3;
use parry3d::math::Vector as PVector;
use rayon::prelude::*;
use std::sync::{Mutex, TryLockError};

/// Edge of a bin of the triangle grid, metres.
const BIN_M: f32 = 1.0;
/// The near clipping plane's distance in front of the optical centre along the axis, metres. A
/// surface nearer than this is not rendered; the caster would report it as too near (NaN) anyway,
/// but could then differ from the rasteriser on what lies behind it.
const NEAR_M: f32 = 1e-5;
/// Pixels per rayon task when filling the z-buffer (whole tile rows, at least one): an 80 × 60
/// frame gives 8 tasks, which two threads share evenly.
const PIXELS_PER_TASK: usize = 640;
/// Edge of a z-buffer tile, pixels: the unit of occlusion culling.
const TILE: usize = 8;
/// Unit roundoff of `f32`.
const U: f64 = f32::EPSILON as f64 * 0.5;

/// The scene mesh prepared for rendering: triangles in the ray-test form and binned on the floor plane.
pub struct MeshRaster {
    /// Per triangle: its corners, for culling and projection.
    corners: Vec<[PVector; 3]>,
    /// Per triangle: first vertex and the two edges from it, computed as `MeshBvh` computes them.
    tris: Vec<[PVector; 3]>,
    /// Per triangle: what [`MeshRaster::near_bound`] needs that does not depend on the camera.
    shape: Vec<Shape>,
    /// Per triangle: the lowest bin (x, y) it overlaps.
    first_bin: Vec<[u32; 2]>,
    /// Lower-left corner of bin (0, 0), metres.
    bin_origin: [f32; 2],
    /// Bins along x and y.
    bins: [usize; 2],
    /// Compressed rows: the triangles of bin `b` are `bin_tris[bin_start[b]..bin_start[b + 1]]`.
    bin_start: Vec<u32>,
    bin_tris: Vec<u32>,
    /// The frame buffers, kept between frames: `render_ranges` takes `&self`, so they sit behind a
    /// lock (uncontended in a run; a second concurrent render allocates its own).
    scratch: Mutex<Scratch>,
}

/// The buffers of one frame, every one rewritten before it is read.
#[derive(Default)]
struct Scratch {
    /// The gathered fill setups, and their (near bound, index) keys in fill order.
    list: Vec<Setup>,
    order: Vec<(f32, u32)>,
    /// The pixel rays' coordinates and the z-buffer, in rows padded to whole tiles.
    rays: [Vec<f32>; 3],
    depth: Vec<f32>,
    /// Per tile, the largest depth of each of its pixel rows, and of the whole tile.
    row_max: Vec<[f32; TILE]>,
    tile_max: Vec<f32>,
}

/// A triangle's shape in `f64`, from its ray-test form `(v0, e1, e2)`.
#[derive(Clone, Copy)]
struct Shape {
    /// Unit normal `e1 × e2 / |e1 × e2|` (zero for a degenerate triangle).
    normal: [f64; 3],
    /// `|e1|`, `|e2|`.
    a: f64,
    b: f64,
    /// Sine of the angle between `e1` and `e2` (zero for a degenerate triangle).
    sin: f64,
    /// Bounding box of the corners.
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Shape {
    fn new(corners: &[PVector; 3], [_, e1, e2]: &[PVector; 3]) -> Shape {
        let f = |v: &PVector| [v.x as f64, v.y as f64, v.z as f64];
        let (e1, e2) = (f(e1), f(e2));
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let (len, a, b) = (norm(n), norm(e1), norm(e2));
        let ok = len > 0.0 && len.is_finite();
        let c = corners.map(|p| f(&p));
        let lo = std::array::from_fn(|k| c[0][k].min(c[1][k]).min(c[2][k]));
        let hi = std::array::from_fn(|k| c[0][k].max(c[1][k]).max(c[2][k]));
        Shape {
            normal: if ok { n.map(|x| x / len) } else { [0.0; 3] },
            a,
            b,
            sin: if ok { len / (a * b) } else { 0.0 },
            lo,
            hi,
        }
    }
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
    /// A lower bound on every distance the ray test can return for this triangle on an accepted
    /// hit, rounding included (see [`MeshRaster::near_bound`]); `-∞` where none is proven.
    near: f32,
}

impl Setup {
    /// The ray test on the pixels `lo..=hi` of one tile row (rays and depths `x`, `y`, `z`, `depth`),
    /// lowering each depth its hit beats; whether any was. The same operations as [`Setup::test`],
    /// written branch-free over the lanes so that they are computed side by side.
    #[inline(always)]
    // `!(det.abs() < 1e-12)` as the caster writes it (a NaN passes), not `>=`.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn test_lanes<const AVX: bool>(
        &self,
        [x, y, z]: [&[f32; TILE]; 3],
        depth: &mut [f32; TILE],
        lo: usize,
        hi: usize,
    ) -> bool {
        let (e1, e2, s, q) = (self.e1, self.e2, self.s, self.q);
        let mut candidate = [f32::INFINITY; TILE];
        for k in 0..TILE {
            let (dx, dy, dz) = (x[k], y[k], z[k]);
            // d × e2 and the dot products as glam's `cross` and `dot` compute them.
            let px = dy * e2.z - e2.y * dz;
            let py = dz * e2.x - e2.z * dx;
            let pz = dx * e2.y - e2.x * dy;
            let det = (e1.x * px) + (e1.y * py) + (e1.z * pz);
            let inv = 1.0 / det;
            let u = ((s.x * px) + (s.y * py) + (s.z * pz)) * inv;
            let v = ((dx * q.x) + (dy * q.y) + (dz * q.z)) * inv;
            let t = self.tq * inv;
            let accept = !(det.abs() < 1e-12)
                & (0.0..=1.0).contains(&u)
                & !((v < 0.0) | (u + v > 1.0))
                & (t >= 0.0)
                & (k >= lo)
                & (k <= hi);
            candidate[k] = if accept { t } else { f32::INFINITY };
        }
        keep_nearer::<AVX>(&candidate, depth)
    }

    /// The ray test along the unit ray `d`: its distance if it hits nearer than `z`. Möller–Trumbore
    /// as `raycast::ray_triangle`, operation for operation.
    #[cfg(test)]
    fn test(&self, d: Vector3<f32>, z: f32) -> Option<f32> {
        let d = PVector::new(d.x, d.y, d.z);
        let p = d.cross(self.e2);
        let det = self.e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let inv = 1.0 / det;
        let u = self.s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let v = d.dot(self.q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = self.tq * inv;
        (t >= 0.0 && t < z).then_some(t)
    }

    /// The columns of row `row` to test: the polygon's extent within the strip of rows
    /// `row ± 1`, grown by a pixel (the slack absorbs the projection's rounding; the ray test
    /// decides), clipped to the triangle's column range. The reference for [`Setup::row_spans`].
    #[cfg(test)]
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
        self.clip_cols(lo, hi)
    }

    /// The columns `lo ..= hi` (polygon coordinates) grown by a pixel and clipped to the triangle's.
    #[inline(always)]
    fn clip_cols(&self, lo: f64, hi: f64) -> Option<[usize; 2]> {
        let c0 = (floor(lo) - 1.0).max(self.cols[0] as f64);
        let c1 = (ceil(hi) + 1.0).min(self.cols[1] as f64);
        (c0 <= c1).then_some([c0 as usize, c1 as usize])
    }

    /// [`Setup::row_cols`] of the rows `rows` (at most [`TILE`]) into `spans`, each line's crossings
    /// computed once for the two rows whose strips it bounds (row `r` uses the lines `r - 1` and
    /// `r + 1`, the same `f64` values). The crossings are the same operations on the same operands,
    /// and a minimum or maximum of non-NaN values does not depend on their order (the sign of a zero
    /// is lost to the ±1 that follows), so every span is `row_cols`'s bit for bit.
    #[inline(always)]
    fn row_spans(&self, rows: std::ops::Range<usize>, spans: &mut [Option<[usize; 2]>; TILE]) {
        let poly = &self.poly[..self.n];
        let nr = rows.len();
        // The polygon's edges, each from a vertex to the next (the last back to the first).
        let edges: [([f64; 2], [f64; 2]); 4] =
            std::array::from_fn(|i| (self.poly[i], self.poly[(i + 1) % self.n]));
        let edges = &edges[..self.n];
        // Line `j` is `rows.start + j - 1`.
        let mut cross = [[f64::INFINITY, f64::NEG_INFINITY]; TILE + 2];
        for (j, c) in cross[..nr + 2].iter_mut().enumerate() {
            let line = (rows.start + j) as f64 - 1.0;
            for &(p, q) in edges {
                if (p[1] < line) != (q[1] < line) {
                    let u = p[0] + (line - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
                    *c = [c[0].min(u), c[1].max(u)];
                }
            }
        }
        for (j, (row, span)) in rows.zip(spans.iter_mut()).enumerate() {
            let (a, b) = (row as f64 - 1.0, row as f64 + 1.0);
            let [mut lo, mut hi] = cross[j];
            (lo, hi) = (lo.min(cross[j + 2][0]), hi.max(cross[j + 2][1]));
            for p in poly {
                if p[1] >= a && p[1] <= b {
                    (lo, hi) = (lo.min(p[0]), hi.max(p[0]));
                }
            }
            *span = self.clip_cols(lo, hi);
        }
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
        let tris: Vec<[PVector; 3]> = corners.iter().map(|&[a, b, c]| [a, b - a, c - a]).collect();
        let shape = corners
            .iter()
            .zip(&tris)
            .map(|(c, t)| Shape::new(c, t))
            .collect();
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
            shape,
            first_bin: Vec::new(),
            bin_origin: lo,
            bins,
            bin_start: vec![0; bins[0] * bins[1] + 1],
            bin_tris: Vec::new(),
            scratch: Mutex::default(),
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
    /// (the caller applies the range rule). Triangles are filled nearest bound first, and each
    /// z-buffer row band by one task; a pixel's value is the minimum over the same tests whatever the
    /// order and the culling (which skips only tests that cannot lower it), so the frame depends on
    /// neither.
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
        let mut own = Scratch::default();
        let mut lock = self.scratch.try_lock();
        let sc: &mut Scratch = match &mut lock {
            Ok(guard) => guard,
            // Every buffer is rewritten before it is read: a panic mid-frame leaves nothing stale.
            Err(TryLockError::Poisoned(p)) => p.get_mut(),
            Err(TryLockError::WouldBlock) => &mut own,
        };
        self.gather(cam, origin, (cos, sin), &mut sc.list);
        // Front to back: near surfaces fill the z-buffer before the ones behind them are tested.
        // Ties in gather order: a hit at ±0 comes only from an unbounded triangle (bound -∞), and
        // the first of those in gather order must keep the sign of its zero, as in the reference.
        sc.order.clear();
        (sc.order).extend(sc.list.iter().enumerate().map(|(i, s)| (s.near, i as u32)));
        (sc.order).sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // Rays and z-buffer in rows padded to whole tiles, the rays' coordinates in separate arrays:
        // the ray test then runs on a tile row's pixels at once. Padding rays are zero (no hit) and
        // padding depths zero (they never raise a tile's maximum).
        let stride = w.div_ceil(TILE) * TILE;
        let (across, down) = (stride / TILE, h.div_ceil(TILE));
        for v in sc.rays.iter_mut().chain([&mut sc.depth]) {
            v.resize(h * stride, 0.0);
        }
        sc.row_max.resize(down * across, [0.0; TILE]);
        sc.tile_max.resize(down * across, 0.0);
        let (list, order) = (&sc.list, &sc.order);
        let tile_rows = (PIXELS_PER_TASK / (stride * TILE)).max(1);
        // Per band: z-buffer pixels, tiles, and image pixels (`w` a row).
        let (pixels, tiles, image) = (
            tile_rows * TILE * stride,
            tile_rows * across,
            tile_rows * TILE * w,
        );
        let [xs, ys, zs] = &mut sc.rays;
        let jobs: Vec<BandJob> = (xs.chunks_mut(pixels).zip(ys.chunks_mut(pixels)))
            .zip(zs.chunks_mut(pixels))
            .zip(sc.depth.chunks_mut(pixels))
            .zip((sc.row_max.chunks_mut(tiles)).zip(sc.tile_max.chunks_mut(tiles)))
            .zip(dirs.chunks(image).zip(range.chunks_mut(image)))
            .enumerate()
            .map(
                |(task, (((((x, y), z), depth), (row_max, max)), (dirs, range)))| BandJob {
                    r0: task * tile_rows * TILE,
                    rays: [x, y, z],
                    depth,
                    row_max,
                    max,
                    dirs,
                    range,
                },
            )
            .collect();
        // Each task copies its band's rays in and its depths out, so that those run in parallel too.
        let fill = |mut job: BandJob| {
            let rows = job.dirs.len() / w;
            let [x, y, z] = &mut job.rays;
            for (((x, y), z), src) in (x.chunks_exact_mut(stride).zip(y.chunks_exact_mut(stride)))
                .zip(z.chunks_exact_mut(stride))
                .zip(job.dirs.chunks_exact(w))
            {
                for (((d, x), y), z) in src.iter().zip(&mut *x).zip(&mut *y).zip(&mut *z) {
                    (*x, *y, *z) = (d.x, d.y, d.z);
                }
                for v in [x, y, z] {
                    v[w..].fill(0.0);
                }
            }
            for row in job.depth.chunks_exact_mut(stride) {
                row[..w].fill(cam.max_range);
                row[w..].fill(0.0);
            }
            // Rows below the image in the last tile row count as padding.
            for (k, m) in job.row_max.iter_mut().enumerate() {
                let left = rows - k / across * TILE;
                *m = std::array::from_fn(|r| if r < left { cam.max_range } else { 0.0 });
            }
            job.max.fill(cam.max_range);
            fill_band(list, order, stride, &mut job);
            for (out, z) in job
                .range
                .chunks_exact_mut(w)
                .zip(job.depth.chunks_exact(stride))
            {
                out.copy_from_slice(&z[..w]);
            }
        };
        // On one thread, in this one: handing a frame to a pool's worker and waiting costs wakeups.
        if rayon::current_num_threads() > 1 {
            jobs.into_par_iter().for_each(fill);
        } else {
            jobs.into_iter().for_each(fill);
        }
    }

    /// The fill setups of the triangles in the frustum, in bin order.
    fn gather(
        &self,
        cam: &RasterCamera,
        origin: PVector,
        (cos, sin): (f32, f32),
        list: &mut Vec<Setup>,
    ) {
        list.clear();
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
    }

    /// [`MeshRaster::gather`] into a new list.
    #[cfg(test)]
    fn gathered(&self, cam: &RasterCamera, origin: PVector, axis: (f32, f32)) -> Vec<Setup> {
        let mut list = Vec::new();
        self.gather(cam, origin, axis, &mut list);
        list
    }

    /// The renderer without occlusion culling, as it was before culling: every gathered triangle
    /// tested on every pixel of its spans. The reference the culled renderer must equal bit for bit.
    #[cfg(test)]
    fn render_ranges_reference(
        &self,
        cam: &RasterCamera,
        origin: PVector,
        (cos, sin): (f32, f32),
        dirs: &[Vector3<f32>],
        range: &mut [f32],
    ) {
        let w = cam.width;
        range.fill(cam.max_range);
        for s in &self.gathered(cam, origin, (cos, sin)) {
            for row in s.rows[0]..=s.rows[1] {
                let Some([c0, c1]) = s.row_cols(row) else {
                    continue;
                };
                for col in c0..=c1 {
                    let i = row * w + col;
                    if let Some(t) = s.test(dirs[i], range[i]) {
                        range[i] = t;
                    }
                }
            }
        }
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
            let a = (floor(lo) - 1.0).max(0.0);
            let b = (ceil(hi) + 1.0).min(n as f64 - 1.0);
            (a <= b).then_some([a as usize, b as usize])
        };
        let cols = span(u0, u1, cam.width)?;
        let rows = span(v0, v1, cam.height)?;
        let [v0, e1, e2] = self.tris[t];
        let s = o - v0;
        let q = s.cross(e1);
        Some(Setup {
            near: self.near_bound(t, o, cam.max_range),
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

    /// A lower bound on the distance the ray test of triangle `t` returns on any hit from `o` that
    /// could be nearer than `range`, rounding included; `-∞` where none is proven.
    ///
    /// Exactly, a hit lies in the triangle, so at least as far as its bounding box. The test's `f32`
    /// products err by a few roundoffs of `|e1||e2|` (and `|s|` times that), against a determinant
    /// of `|e1 × e2| h / t` for a hit at `t`, `h` the distance from `o` to the triangle's plane: so
    /// the returned distance is off by a relative `ρ` and the accepted point may lie outside the
    /// triangle by `η`, both below. The constants are eight times the worst case; a triangle seen
    /// edge-on from near its plane, or a sliver, gets no bound (it is always tested).
    fn near_bound(&self, t: usize, o: PVector, range: f32) -> f32 {
        let sh = &self.shape[t];
        let v0 = self.tris[t][0];
        let o = [o.x as f64, o.y as f64, o.z as f64];
        let s = [o[0] - v0.x as f64, o[1] - v0.y as f64, o[2] - v0.z as f64];
        let sigma = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        let h = (sh.normal[0] * s[0] + sh.normal[1] * s[1] + sh.normal[2] * s[2]).abs();
        let (a, b, r) = (sh.a, sh.b, range as f64);
        // `s` is rounded to f32 in the test: the plane distance it sees is within 2uσ of `h`.
        let hs = (h - 2.0 * U * sigma) * sh.sin;
        let rho = 64.0 * U * (sigma + 2.0 * r) / hs + 8.0 * U;
        // Error of the barycentrics (u and v together) of a hit within 2 × range.
        let bary = 128.0 * U * r * (sigma / a + sigma / b + 4.0) / hs + 8.0 * U;
        if !(hs > 0.0 && rho < 0.1 && bary < 0.1) {
            return f32::NEG_INFINITY;
        }
        // The edges and `s` are rounded to f32 too: a few more roundoffs of their lengths.
        let eta = bary * (a + b) + 2.0 * U * (a + b) + 4.0 * U * sigma;
        let mut d2 = 0.0;
        for ((lo, hi), o) in sh.lo.iter().zip(&sh.hi).zip(o) {
            let e = (lo - o).max(o - hi).max(0.0);
            d2 += e * e;
        }
        let x = (d2.sqrt() - eta) * (1.0 - rho);
        // Shrunk by more than the cast's rounding, so the f32 stays below `x`.
        if x > 0.0 {
            (x * (1.0 - 1e-6)) as f32
        } else {
            f32::NEG_INFINITY
        }
    }
}

/// `x.floor()` without a libm call (the default x86-64 target has no rounding instruction, and the
/// call showed in profiles): the same value, the sign of a zero included.
#[inline]
fn floor(x: f64) -> f64 {
    // NaN, ±∞ and from 2^52 on, `x` is its own floor; below, truncation to an integer is exact.
    if x.is_nan() || x.abs() >= 4503599627370496.0 {
        return x;
    }
    let t = x as i64 as f64;
    (if t > x { t - 1.0 } else { t }).copysign(x)
}

/// `x.ceil()` without a libm call, as [`floor`].
#[inline]
fn ceil(x: f64) -> f64 {
    if x.is_nan() || x.abs() >= 4503599627370496.0 {
        return x;
    }
    let t = x as i64 as f64;
    (if t < x { t + 1.0 } else { t }).copysign(x)
}

/// The largest of a tile row's depths (never NaN).
#[inline(always)]
fn lanes_max(v: &[f32; TILE]) -> f32 {
    let m: [f32; 4] = std::array::from_fn(|k| v[k].max(v[k + 4]));
    m[0].max(m[2]).max(m[1].max(m[3]))
}

/// Lowers each of a tile row's `depth`s that its `candidate` is strictly nearer than; whether any
/// was. Each lane is `c < d ? c : d`, which is exactly x86's `minps(c, d)`. Written as a select of
/// the old depth, the compiler makes a masked store of it, which on AMD CPUs cost about a fifth of
/// a frame; with AVX the minimum is therefore the instruction itself and
/// a plain store. Depths are never NaN, so both versions give the same bits.
#[inline(always)]
fn keep_nearer<const AVX: bool>(candidate: &[f32; TILE], depth: &mut [f32; TILE]) -> bool {
    #[cfg(target_arch = "x86_64")]
    if AVX {
        use std::arch::x86_64::{
            _mm256_cmp_ps, _mm256_loadu_ps, _mm256_min_ps, _mm256_movemask_ps,
        };
        use std::arch::x86_64::{_mm256_storeu_ps, _CMP_LT_OQ};
        // SAFETY: `AVX` is true only in `fill_band_avx`, called where the CPU has AVX; the
        // pointers are to arrays of eight f32, read and written unaligned.
        return unsafe {
            let (c, d) = (
                _mm256_loadu_ps(candidate.as_ptr()),
                _mm256_loadu_ps(depth.as_ptr()),
            );
            _mm256_storeu_ps(depth.as_mut_ptr(), _mm256_min_ps(c, d));
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(c, d)) != 0
        };
    }
    let mut changed = false;
    for (c, d) in candidate.iter().zip(depth) {
        let hit = c < d;
        *d = if hit { *c } else { *d };
        changed |= hit;
    }
    changed
}

/// One task's share of a frame (see `MeshRaster::render_ranges`): whole tile rows from image row
/// `r0` (a multiple of [`TILE`]).
struct BandJob<'a> {
    r0: usize,
    /// The rays' coordinates in the band's rows (rows of `stride`).
    rays: [&'a mut [f32]; 3],
    /// The z-buffer's rows.
    depth: &'a mut [f32],
    /// Per tile of the band, the largest depth of each pixel row, and of the tile: kept exact as
    /// the depths change (one tile row's maximum costs a few lane-wise operations).
    row_max: &'a mut [[f32; TILE]],
    max: &'a mut [f32],
    /// The image's pixel rays and ranges in the band's rows (rows of the image's width).
    dirs: &'a [Vector3<f32>],
    range: &'a mut [f32],
}

/// Fills `band` of the z-buffer (`stride` pixels a row, a multiple of [`TILE`]) with the triangles
/// `list[order[..].1]`, in that order, for the band's pixel rays. A triangle whose near bound is at
/// least every depth in a tile cannot win a pixel there (its test returns no less than the bound,
/// and a pixel keeps only a strictly nearer hit), so that tile is skipped, and a tile row whose
/// tiles are all skipped costs no spans. Within a triangle each pixel is tested once, so the order
/// of its tiles does not matter.
///
/// On a CPU with AVX a tile row's eight ray tests are one 256-bit register ([`fill_band_avx`]):
/// the same operations on the same lanes, and no fused multiply-add, so the same bits.
fn fill_band(list: &[Setup], order: &[(f32, u32)], stride: usize, band: &mut BandJob) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked just above.
        return unsafe { fill_band_avx(list, order, stride, band) };
    }
    fill_band_lanes::<false>(list, order, stride, band);
}

/// [`fill_band`] compiled for AVX.
///
/// # Safety
/// The CPU must support AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn fill_band_avx(list: &[Setup], order: &[(f32, u32)], stride: usize, band: &mut BandJob) {
    fill_band_lanes::<true>(list, order, stride, band);
}

/// The body of [`fill_band`], inlined into each target's version (`AVX`: compiled for AVX).
#[inline(always)]
fn fill_band_lanes<const AVX: bool>(
    list: &[Setup],
    order: &[(f32, u32)],
    stride: usize,
    band: &mut BandJob,
) {
    let BandJob {
        r0,
        rays,
        depth,
        row_max,
        max,
        ..
    } = band;
    // Plain slices, so that the hot loop does not reload them through the job.
    let (r0, rays, depth): (usize, [&[f32]; 3], &mut [f32]) =
        (*r0, rays.each_ref().map(|r| &**r), depth);
    let (row_max, max): (&mut [[f32; TILE]], &mut [f32]) = (row_max, max);
    let across = stride / TILE;
    let r1 = r0 + depth.len() / stride; // exclusive
    for &(_, i) in order {
        let s = &list[i as usize];
        let (a, b) = (s.rows[0].max(r0), (s.rows[1] + 1).min(r1));
        if a >= b {
            continue;
        }
        let culls = s.near > f32::NEG_INFINITY;
        let (tx0, tx1) = (s.cols[0] / TILE, s.cols[1] / TILE);
        for ty in (a - r0) / TILE..=(b - 1 - r0) / TILE {
            let first = ty * across;
            if culls && max[first + tx0..=first + tx1].iter().all(|&m| m <= s.near) {
                continue;
            }
            // This tile row's rows of the triangle, their spans and the columns they cover.
            let (ra, rb) = (a.max(r0 + ty * TILE), b.min(r0 + ty * TILE + TILE));
            let mut spans = [None; TILE];
            s.row_spans(ra..rb, &mut spans);
            let (mut lo, mut hi) = (usize::MAX, 0);
            for [c0, c1] in spans.iter().flatten() {
                (lo, hi) = (lo.min(*c0), hi.max(*c1));
            }
            if lo > hi {
                continue;
            }
            for tx in lo / TILE..=hi / TILE {
                let k = first + tx;
                if culls && max[k] <= s.near {
                    continue;
                }
                let at = tx * TILE;
                let mut changed = false;
                for (row, span) in (ra..rb).zip(&spans) {
                    let Some([c0, c1]) = *span else {
                        continue;
                    };
                    if c1 < at || c0 >= at + TILE || culls && row_max[k][row % TILE] <= s.near {
                        continue;
                    }
                    let i = (row - r0) * stride + at;
                    let lanes =
                        |k: usize| -> &[f32; TILE] { rays[k][i..i + TILE].try_into().unwrap() };
                    let ray = [lanes(0), lanes(1), lanes(2)];
                    let d: &mut [f32; TILE] = (&mut depth[(row - r0) * stride + at..][..TILE])
                        .try_into()
                        .unwrap();
                    let (l, h) = (c0.max(at) - at, c1.min(at + TILE - 1) - at);
                    if s.test_lanes::<AVX>(ray, &mut *d, l, h) {
                        row_max[k][row % TILE] = lanes_max(d);
                        changed = true;
                    }
                }
                if changed {
                    max[k] = lanes_max(&row_max[k]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::sensor::DepthCamera;
    use crate::Pose2;
    use rand::{Rng, SeedableRng};
    use std::path::Path;

    /// Frames of `path` from `n` poses anywhere in its bounds (inside walls too), every third one
    /// snapped to a 5 cm grid and a right-angle heading (rays in faces' planes, origins on them).
    fn compare_scene(path: &Path, n: usize, sizes: &[(usize, usize)], seed: u64) -> usize {
        let cfg = Config::default();
        let scene = crate::scene::load(path, &cfg.scene).unwrap();
        let raster = MeshRaster::new(&scene.mesh).unwrap();
        let (lo, hi) = scene.mesh.bounds().unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut pixels = 0;
        for &(w, h) in sizes {
            let mut cc = cfg.camera.clone();
            (cc.width, cc.height) = (w, h);
            let camera = DepthCamera::new(&cc);
            let cam = RasterCamera {
                width: w,
                height: h,
                tan_h: (cc.hfov_deg.to_radians() / 2.0).tan() as f32,
                tan_v: (cc.vfov_deg.to_radians() / 2.0).tan() as f32,
                max_range: cc.max_range_m.get() as f32,
            };
            let (mut got, mut want) = (vec![0.0; w * h], vec![0.0; w * h]);
            for i in 0..n {
                let (mut x, mut y) = (rng.random_range(lo.x..hi.x), rng.random_range(lo.y..hi.y));
                let mut yaw = rng.random_range(-3.2..3.2);
                if i % 3 == 0 {
                    (x, y) = ((x * 20.0).round() / 20.0, (y * 20.0).round() / 20.0);
                    yaw = rng.random_range(-2..=2) as f64 * std::f64::consts::FRAC_PI_2;
                }
                let frame = camera.render(&raster, Pose2::new(x, y, yaw));
                let o = frame.origin;
                let o = PVector::new(o.x, o.y, o.z);
                let axis = (frame.axis.x, frame.axis.y);
                raster.render_ranges(&cam, o, axis, &frame.dirs, &mut got);
                raster.render_ranges_reference(&cam, o, axis, &frame.dirs, &mut want);
                for (k, (a, b)) in got.iter().zip(&want).enumerate() {
                    assert!(
                        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                        "{}: pixel {k} of {w}x{h} at ({x}, {y}, {yaw}): {a} vs {b}",
                        scene.name
                    );
                }
                pixels += w * h;
            }
        }
        pixels
    }

    #[test]
    #[ignore = "heavy tier: cargo test -- --ignored"]
    fn culled_frames_equal_the_unculled_reference_bit_for_bit() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut scenes: Vec<_> = std::fs::read_dir(root.join("scenes"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "obj"))
            .collect();
        scenes.sort();
        assert!(scenes.len() >= 8);
        for plan in ["052ce6767b", "807c123f55", "82a81996b5"] {
            scenes.push(root.join(format!("scenes/floorplans/plan_{plan}.obj")));
        }
        // Both thread counts: the bands are filled by different tasks, the frame must not change.
        for threads in [1, 2] {
            crate::util::on_threads(threads, || {
                for (k, path) in scenes.iter().enumerate() {
                    let pixels = compare_scene(path, 120, &[(80, 60), (173, 41)], k as u64);
                    assert!(pixels > 0);
                }
            });
        }
        let office = root.join("scenes/office_large.obj");
        compare_scene(&office, 4, &[(640, 480)], 99);
    }

    #[test]
    fn row_spans_equal_row_cols() {
        let cfg = Config::default();
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut rows = 0;
        for name in [
            "office_large",
            "apartment_small",
            "floorplans/plan_052ce6767b",
        ] {
            let scene = crate::scene::load(&root.join(format!("scenes/{name}.obj")), &cfg.scene);
            let scene = scene.unwrap();
            let raster = MeshRaster::new(&scene.mesh).unwrap();
            let (lo, hi) = scene.mesh.bounds().unwrap();
            for (w, h) in [(80, 60), (640, 480)] {
                let cam = RasterCamera {
                    width: w,
                    height: h,
                    tan_h: 0.55,
                    tan_v: 0.41,
                    max_range: 5.0,
                };
                for _ in 0..10 {
                    let (x, y) = (rng.random_range(lo.x..hi.x), rng.random_range(lo.y..hi.y));
                    let yaw: f32 = rng.random_range(-3.2..3.2);
                    let o = PVector::new(x as f32, y as f32, rng.random_range(0.0..1.5));
                    for s in raster.gathered(&cam, o, (yaw.cos(), yaw.sin())) {
                        // Windows of up to a tile's rows, at every offset.
                        let start = s.rows[0] + rng.random_range(0..TILE);
                        for a in (s.rows[0]..=s.rows[1]).step_by(TILE).chain([start]) {
                            let b = (a + TILE).min(s.rows[1] + 1);
                            let mut spans = [None; TILE];
                            s.row_spans(a..b, &mut spans);
                            for row in a..b {
                                assert_eq!(spans[row - a], s.row_cols(row), "{name} row {row}");
                                rows += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(rows > 10000, "{rows}");
    }

    #[test]
    fn keep_nearer_versions_agree_bit_for_bit() {
        #[cfg(target_arch = "x86_64")]
        if !std::arch::is_x86_feature_detected!("avx") {
            return;
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        // Ties, zeros of both signs, the rejected lanes' +∞ and the padding's zero depths.
        let values = [0.0, -0.0, 0.3, 1.0, 2.5, 5.0, f32::INFINITY];
        let mut any = [0; 2];
        for _ in 0..20_000 {
            let pick = |rng: &mut rand_chacha::ChaCha8Rng| -> [f32; TILE] {
                std::array::from_fn(|_| match rng.random_range(0..3) {
                    0 => values[rng.random_range(0..values.len())],
                    _ => rng.random_range(0.0f32..6.0),
                })
            };
            let candidate = pick(&mut rng);
            let mut depth = pick(&mut rng).map(|d| if d.is_finite() { d } else { 5.0 });
            let (mut plain, before) = (depth, depth);
            let changed = keep_nearer::<true>(&candidate, &mut depth);
            let expected = keep_nearer::<false>(&candidate, &mut plain);
            assert_eq!(changed, expected);
            assert_eq!(depth.map(f32::to_bits), plain.map(f32::to_bits));
            // The plain version's rule itself: a lane drops exactly where the candidate is nearer.
            for ((c, b), p) in candidate.iter().zip(&before).zip(&plain) {
                assert_eq!(p.to_bits(), if c < b { c } else { b }.to_bits());
            }
            assert_eq!(changed, candidate.iter().zip(&before).any(|(c, b)| c < b));
            any[changed as usize] += 1;
        }
        assert!(any[0] > 0 && any[1] > 0, "both outcomes exercised: {any:?}");
    }

    #[test]
    fn floor_and_ceil_are_libms_bit_for_bit() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut xs = vec![0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 2.5, -2.5, 1e-300, -1e-300];
        xs.extend([
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN,
            9.1e15,
            -9.1e15,
        ]);
        for e in [52, 53, 62, 63, 64] {
            let p = 2f64.powi(e);
            xs.extend([p, -p, p - 0.5, 0.5 - p, p + 1.0, -p - 1.0]);
        }
        for _ in 0..100_000 {
            let scale = 10f64.powi(rng.random_range(-3..8));
            xs.push(rng.random_range(-1.0..1.0) * scale);
            xs.push(rng.random_range(-40i32..40) as f64 + [0.0, 0.5, 1e-9][rng.random_range(0..3)]);
        }
        for x in xs {
            assert_eq!(floor(x).to_bits(), x.floor().to_bits(), "floor({x})");
            assert_eq!(ceil(x).to_bits(), x.ceil().to_bits(), "ceil({x})");
        }
        assert!(floor(f64::NAN).is_nan() && ceil(f64::NAN).is_nan());
    }

    #[test]
    fn near_bounds_hold_for_every_pixel_and_are_tight_on_walls() {
        // Two walls one behind the other: the faces are bounded at their true distances, less a
        // hair of slack, so the far wall is culled behind the near one.
        let mut mesh = TriMesh::default();
        super::super::raycast::testing::push_box(&mut mesh, [2.0, -5.0, 0.0], [2.1, 5.0, 3.0]);
        super::super::raycast::testing::push_box(&mut mesh, [4.0, -5.0, 0.0], [4.1, 5.0, 3.0]);
        let cam = RasterCamera {
            width: 80,
            height: 60,
            tan_h: 0.55,
            tan_v: 0.41,
            max_range: 5.0,
        };
        let raster = MeshRaster::new(&mesh).unwrap();
        let near: Vec<f32> = (raster.gathered(&cam, PVector::new(0.0, 0.0, 0.6), (1.0, 0.0)))
            .iter()
            .map(|s| s.near)
            .collect();
        assert!(near.iter().any(|&b| (1.99..2.0).contains(&b)), "{near:?}");
        assert!(near.iter().any(|&b| (3.99..4.0).contains(&b)), "{near:?}");
        // On real scenes, every pixel ray (not only those of the triangle's spans) that the test
        // accepts returns at least the bound.
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let cfg = Config::default();
        let camera = DepthCamera::new(&cfg.camera);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut bounded, mut hits) = (0, 0);
        for name in ["office_large", "small_house", "floorplans/plan_807c123f55"] {
            let scene = crate::scene::load(&root.join(format!("scenes/{name}.obj")), &cfg.scene);
            let scene = scene.unwrap();
            let raster = MeshRaster::new(&scene.mesh).unwrap();
            let (lo, hi) = scene.mesh.bounds().unwrap();
            for _ in 0..20 {
                let (x, y) = (rng.random_range(lo.x..hi.x), rng.random_range(lo.y..hi.y));
                let frame = camera.render(&raster, Pose2::new(x, y, rng.random_range(-3.2..3.2)));
                let o = PVector::new(frame.origin.x, frame.origin.y, frame.origin.z);
                for s in raster.gathered(&cam, o, (frame.axis.x, frame.axis.y)) {
                    bounded += usize::from(s.near > 0.0);
                    for &d in &frame.dirs {
                        if let Some(t) = s.test(d, f32::INFINITY) {
                            hits += 1;
                            assert!(t >= s.near, "{name}: hit at {t} below the bound {}", s.near);
                        }
                    }
                }
            }
        }
        assert!(
            bounded > 1000 && hits > 10000,
            "{bounded} bounded, {hits} hits"
        );
    }
}
