//! The ray casting of the observable set: the reference walk, one ray at a time
//! ([`VoxelCaster::observe`]), and the two drivers that run a pass of the sampling over positions
//! and headings, ray by ray or by pixel columns (see [`super::sweep`]).

use super::sampling::{beyond_voxels, min_beyond_voxels};
use super::sweep::{Ambiguous, ColumnRay, ColumnSetup, RayHits, SweepScratch};
use super::{GroundTruth, SampleProgress};
use crate::grid::GridSpec;
use crate::map::occupancy::traverse_while;
use crate::scene::VoxelTriangles;
use crate::sensor::{DepthCamera, MeshBvh};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// Casts camera rays by walking the voxel grid, testing only the triangles that overlap each
/// occupied voxel it enters (`MeshBvh::cast_among`, the BVH cast's own arithmetic): the first hit is
/// the mesh's first hit, found without the tree.
pub(super) struct VoxelCaster<'a> {
    pub(super) grid: &'a GridSpec,
    /// The triangles of every occupied voxel, dense (the lists of `GroundTruth::voxel_triangles`,
    /// indexed without a search).
    pub(super) tris: TriangleIndex,
    pub(super) bvh: &'a MeshBvh,
    /// The height band `[z_lo, z_hi)`, metres.
    pub(super) band: (f64, f64),
    /// The camera's nearest and farthest depth, metres.
    pub(super) range: (f32, f32),
    /// The band's layers, and the same one bit each (all bits when the grid has over 64 layers).
    pub(super) band_layers: std::ops::Range<usize>,
    pub(super) band_mask: u64,
}

/// [`VoxelTriangles`] indexed densely by voxel, for the caster's hot loop.
pub(super) struct TriangleIndex {
    /// `GroundTruth::occupied`, one byte per voxel (the walk's test, kept beside the lists).
    pub(super) occupied: Vec<bool>,
    /// Per floor cell, its occupied layers, one bit each (empty when the grid has over 64 layers).
    pub(super) layers: Vec<u64>,
    /// Cell-major, per voxel of floor cell `c` and layer `iz`: where its triangle list starts in
    /// `lists` (`list[c * nz + iz]`, 0 for an empty list).
    pub(super) list: Vec<u32>,
    /// The distinct lists, each its length then its triangles (ascending). Voxels with the same
    /// triangles share one list (a wall's face covers every layer of its cell, and the cells on
    /// both sides of a cell line it lies on), so a ray that has been tested against a list knows it
    /// from its start alone (see [`RayHits::tested`]).
    pub(super) lists: Vec<u32>,
    pub(super) nz: usize,
}

impl TriangleIndex {
    pub(super) fn new(gt: &GroundTruth, lists: &VoxelTriangles) -> TriangleIndex {
        let grid = &gt.grid;
        let n = grid.voxels();
        let (cells, nz) = (grid.cells(), grid.nz);
        let occupied: Vec<bool> = (0..n).map(|v| gt.occupied(v)).collect();
        let mut list = Vec::with_capacity(n);
        let mut stored = vec![0u32];
        let mut known: std::collections::HashMap<&[u32], u32> = std::collections::HashMap::new();
        known.insert(&[], 0);
        for c in 0..cells {
            for iz in 0..nz {
                let v = iz * cells + c;
                if !occupied[v] {
                    list.push(0);
                    continue;
                }
                let tris = lists.of(v);
                list.push(*known.entry(tris).or_insert_with(|| {
                    let start = stored.len() as u32;
                    stored.push(tris.len() as u32);
                    stored.extend_from_slice(tris);
                    start
                }));
            }
        }
        let mut layers = Vec::new();
        if nz <= 64 {
            layers = vec![0u64; cells];
            for (v, _) in occupied.iter().enumerate().filter(|(_, &o)| o) {
                let (c, iz) = grid.voxel_parts(v);
                layers[c] |= 1 << iz;
            }
        }
        TriangleIndex {
            occupied,
            layers,
            list,
            lists: stored,
            nz,
        }
    }

    /// The triangle list of the voxel of floor cell `c` and layer `iz`: its start in `lists`.
    #[inline]
    pub(super) fn list(&self, c: usize, iz: usize) -> u32 {
        self.list[c * self.nz + iz]
    }

    /// The triangles of the list that starts at `start`.
    #[inline]
    pub(super) fn triangles(&self, start: u32) -> &[u32] {
        let start = start as usize;
        let len = self.lists[start] as usize;
        &self.lists[start + 1..start + 1 + len]
    }
}

impl<'a> VoxelCaster<'a> {
    pub(super) fn new(
        gt: &'a GroundTruth,
        bvh: &'a MeshBvh,
        camera: &DepthCamera,
        band: (f64, f64),
    ) -> VoxelCaster<'a> {
        let band_layers = gt.band_layers();
        let band_mask = if gt.grid.nz > 64 {
            u64::MAX
        } else {
            band_layers.clone().fold(0u64, |m, l| m | 1 << l)
        };
        VoxelCaster {
            grid: &gt.grid,
            tris: TriangleIndex::new(gt, gt.voxel_triangles()),
            bvh,
            band,
            range: camera.range_limits(),
            band_layers,
            band_mask,
        }
    }

    /// The nearest hit of the ray on the triangles of list `list` (see [`TriangleIndex::list`]), or
    /// infinity. Kept out of line so that the walk's loop stays small.
    #[inline(never)]
    pub(super) fn hit_in(&self, list: u32, origin: Point3<f32>, dir: Vector3<f32>) -> f64 {
        self.bvh
            .cast_among(origin, dir, self.tris.triangles(list), self.range.1)
            .map_or(f64::INFINITY, |t| t as f64)
    }

    /// The voxels one camera ray makes known in the map, as `Occupancy::integrate` does: every voxel
    /// the ray passes through up to its first hit and the voxel of that hit; nothing when the hit is
    /// nearer than the minimum range (no reading); free space up to the maximum range when there is
    /// no hit. The ray is cut where it leaves the band, which changes no band voxel (a ray leaves a
    /// horizontal slab once). `buf` is scratch space; the result borrows it.
    #[inline]
    pub(super) fn observe<'b>(
        &self,
        origin: Point3<f32>,
        dir: Vector3<f32>,
        buf: &'b mut Vec<usize>,
    ) -> &'b [usize] {
        buf.clear();
        let (min_range, max_range) = self.range;
        let (oz, dz) = (origin.z as f64, dir.z as f64);
        let leave = if dz > 0.0 {
            (self.band.1 - oz) / dz
        } else if dz < 0.0 {
            (self.band.0 - oz) / dz
        } else {
            f64::INFINITY
        };
        if leave < 0.0 {
            return buf;
        }
        let cut = (leave + 1e-6).max(min_range as f64).min(max_range as f64);
        let (o, d) = (origin.cast::<f64>(), dir.cast::<f64>());
        // The nearest hit so far (an f32 distance, held as f64).
        let mut best = f64::INFINITY;
        let occupied = &self.tris.occupied[..];
        traverse_while(self.grid, o, d, cut, |v, t_in, t_out| {
            if occupied[v] {
                let (c, iz) = self.grid.voxel_parts(v);
                best = best.min(self.hit_in(self.tris.list(c, iz), origin, dir));
            }
            // A face on this voxel's entry face can lie a hair before it in world coordinates (the
            // voxelisation is half-open): the map's ray ends there and never enters this voxel.
            if best <= t_in {
                return false;
            }
            buf.push(v);
            // A hit found in an earlier voxel's triangles may lie further on: stop only once the
            // walk has reached it.
            best > t_out
        });
        if best.is_finite() {
            if best < min_range as f64 {
                buf.clear();
            } else if let Some(v) = self.grid.voxel_of(o + d * best) {
                buf.push(v);
            }
        }
        buf
    }
}

/// Rotates a camera-frame ray to the world frame for heading (sin, cos), as the camera does.
#[inline]
pub(super) fn world_ray(sin: f32, cos: f32, d: &Vector3<f32>) -> Vector3<f32> {
    Vector3::new(cos * d.x - sin * d.y, sin * d.x + cos * d.y, d.z)
}

/// What one pass of the sampling gives: the observed bits, the sample positions (ascending) that
/// looked into space beyond the reachable region (see [`super::sampling::beyond_cells`]), and the
/// pixel columns walked ray by ray.
pub(super) struct Frames {
    pub(super) bits: Vec<u64>,
    pub(super) looked_beyond: Vec<usize>,
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) by_rays: usize,
}

impl VoxelCaster<'_> {
    /// The observable bits by walking every ray through the voxels ([`VoxelCaster::observe`]),
    /// telling `progress` of each position done.
    pub(super) fn frames_by_rays(
        &self,
        positions: &[usize],
        yaws: &[(f32, f32)],
        camera: &DepthCamera,
        beyond: &[bool],
        progress: &dyn SampleProgress,
    ) -> Frames {
        let grid = self.grid;
        let words = grid.voxels().div_ceil(64);
        let min_beyond = min_beyond_voxels(grid);
        let band = self.band_layers.clone();
        let (bits, looked_beyond) = positions
            .par_iter()
            .fold(
                || (vec![0u64; words], Vec::new(), Vec::new(), Vec::new()),
                |(mut bits, mut looked, mut buf, mut seen_beyond), &cell| {
                    let c = grid.center(grid.cell(cell));
                    let origin = Point3::new(c.x as f32, c.y as f32, camera.mount_height());
                    seen_beyond.clear();
                    for &(sin, cos) in yaws {
                        for d in camera.camera_dirs() {
                            for &v in self.observe(origin, world_ray(sin, cos, d), &mut buf) {
                                bits[v >> 6] |= 1 << (v & 63);
                                let (c, iz) = grid.voxel_parts(v);
                                if beyond[c] && band.contains(&iz) {
                                    seen_beyond.push(v);
                                }
                            }
                        }
                    }
                    seen_beyond.sort_unstable();
                    seen_beyond.dedup();
                    if seen_beyond.len() >= min_beyond {
                        looked.push(cell);
                    }
                    progress.sampled();
                    (bits, looked, buf, seen_beyond)
                },
            )
            .map(|(bits, looked, _, _)| (bits, looked))
            .reduce(
                || (vec![0u64; words], Vec::new()),
                |(mut a, mut la), (b, lb)| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x |= y);
                    la.extend(lb);
                    (a, la)
                },
            );
        let mut looked_beyond = looked_beyond;
        looked_beyond.sort_unstable();
        Frames {
            bits,
            looked_beyond,
            by_rays: 0,
        }
    }

    /// The observable bits by sweeping pixel columns ([`VoxelCaster::sweep_column`]); a column the
    /// sweep cannot decide exactly is walked ray by ray. Per worker, a mask of layers per floor cell.
    /// `progress` is told of each position done.
    pub(super) fn frames_by_columns(
        &self,
        positions: &[usize],
        yaws: &[(f32, f32)],
        camera: &DepthCamera,
        beyond: &[bool],
        progress: &dyn SampleProgress,
    ) -> Frames {
        let grid = self.grid;
        let cells = grid.cells();
        let min_beyond = min_beyond_voxels(grid);
        let (w, h) = camera.image_size();
        let dirs = camera.camera_dirs();
        // Every position has the same mount height, and a column ray's setup uses no other part of
        // the origin: set up each heading's columns once, `(yaw * w + u) * h + row`.
        let at_mount = Point3::new(0.0, 0.0, camera.mount_height());
        let columns: Vec<ColumnRay> = yaws
            .iter()
            .flat_map(|&(sin, cos)| {
                (0..w).flat_map(move |u| (0..h).map(move |k| world_ray(sin, cos, &dirs[k * w + u])))
            })
            .map(|dir| self.column_ray(at_mount, dir))
            .collect();
        let setups: Vec<Option<ColumnSetup>> = columns
            .chunks_exact(h)
            .map(|rays| self.column_setup(at_mount.z as f64, rays))
            .collect();
        let (seen, looked_beyond, by_rays) = positions
            .par_iter()
            .fold(
                || {
                    (
                        vec![0u64; cells],
                        Vec::new(),
                        SweepScratch::default(),
                        0usize,
                    )
                },
                |(mut seen, mut looked, mut sc, mut by_rays), &cell| {
                    let c = grid.center(grid.cell(cell));
                    let origin = Point3::new(c.x as f32, c.y as f32, camera.mount_height());
                    sc.beyond.clear();
                    for (column, setup) in columns.chunks_exact(h).zip(&setups) {
                        sc.hits.clear();
                        sc.hits.resize(h, RayHits::NONE);
                        sc.marks.clear();
                        let swept = setup.as_ref().map_or(Err(Ambiguous), |setup| {
                            self.sweep_column(origin, column, setup, &mut sc.hits, &mut sc.marks)
                        });
                        if swept.is_ok() {
                            for &(c, m) in &sc.marks {
                                seen[c] |= m;
                                if beyond[c] {
                                    sc.beyond.push((c, m));
                                }
                            }
                        } else {
                            by_rays += 1;
                            for ray in column {
                                for &v in self.observe(origin, ray.dir, &mut sc.buf) {
                                    let (c, iz) = grid.voxel_parts(v);
                                    seen[c] |= 1 << iz;
                                    if beyond[c] {
                                        sc.beyond.push((c, 1 << iz));
                                    }
                                }
                            }
                        }
                    }
                    if beyond_voxels(&mut sc.beyond, self.band_mask) >= min_beyond {
                        looked.push(cell);
                    }
                    progress.sampled();
                    (seen, looked, sc, by_rays)
                },
            )
            .map(|(seen, looked, _, by_rays)| (seen, looked, by_rays))
            .reduce(
                || (vec![0u64; cells], Vec::new(), 0),
                |(mut a, mut la, na), (b, lb, nb)| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x |= y);
                    la.extend(lb);
                    (a, la, na + nb)
                },
            );
        let mut bits = vec![0u64; grid.voxels().div_ceil(64)];
        for (c, &m) in seen.iter().enumerate() {
            let mut m = m;
            while m != 0 {
                let v = m.trailing_zeros() as usize * cells + c;
                m &= m - 1;
                bits[v >> 6] |= 1 << (v & 63);
            }
        }
        let mut looked_beyond = looked_beyond;
        looked_beyond.sort_unstable();
        Frames {
            bits,
            looked_beyond,
            by_rays,
        }
    }
}
