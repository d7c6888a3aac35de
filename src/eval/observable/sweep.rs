//! The observable set's column sweep: the rays of one pixel column swept together through the
//! floor cells they share, with triangle tests where they meet occupied voxels (see
//! [`VoxelCaster::sweep_column`]).

use super::caster::VoxelCaster;
use crate::grid::{floor_both, floor_i64, layer_span, TIE_M};
use crate::sensor::DepthCamera;
use nalgebra::{Point3, Vector3};

/// A part of a run that meets an occupied voxel in a cell is halved while it holds more rays than
/// this (see [`VoxelCaster::sweep_column`]): the halves that meet none are marked as runs, the rest
/// walked one by one.
pub(super) const MIN_SPLIT: usize = 4;

/// One ray of a pixel column during a sweep (see [`VoxelCaster::sweep_column`]).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ColumnRay {
    pub(super) dir: Vector3<f32>,
    pub(super) d: [f64; 3],
    /// `1 / d`, per axis.
    pub(super) inv: [f64; 3],
    /// Where the ray's walk ends: the band cut or the range (as [`VoxelCaster::observe`]), or the
    /// grid's top or bottom face.
    pub(super) t1: f64,
    /// `t1` is the grid's top or bottom face: the last layer is the grid's, whatever the rounding.
    pub(super) z_clamped: bool,
    /// `t1` times the ray's horizontal length: how far from the camera, on the floor, it ends.
    pub(super) h1: f64,
}

/// What a sweep has found of one ray of its column so far (see [`VoxelCaster::sweep_column`]): kept
/// apart from the [`ColumnRay`]s, which are the same for every position and so are not copied.
#[derive(Clone, Copy, Debug)]
pub(super) struct RayHits {
    /// Nearest hit found so far (infinity until the ray has entered an occupied voxel).
    pub(super) best: f64,
    /// The triangle list ([`super::caster::TriangleIndex::list`]) of the last occupied voxel the ray was tested
    /// against: a ray that meets a wall lying on a cell line finds the same list in the voxels on
    /// both sides (about a third of the lists met were such repeats on `office_large`).
    pub(super) tested: u32,
}

impl RayHits {
    pub(super) const NONE: RayHits = RayHits {
        best: f64::INFINITY,
        tested: u32::MAX,
    };
}

/// A pixel column's rays as [`VoxelCaster::sweep_column`] sees them, whatever the position (see
/// [`VoxelCaster::column_setup`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct ColumnSetup {
    /// The reference horizontal direction (the middle row's), unit length.
    pub(super) u: [f64; 2],
    /// How far along a grid line of axis `a` a ray may cross it from where the reference ray does,
    /// per metre from the camera.
    pub(super) drift: [f64; 2],
    /// The farthest any ray reaches on the floor, metres.
    pub(super) h_max: f64,
    /// The layers whose occupied voxels make a run be walked ray by ray.
    pub(super) occ_mask: u64,
}

/// One floor cell of a pixel column's path: the cell, and the grid line the path leaves it by.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct PathCell {
    pub(super) cell: usize,
    /// 0 for a line x = `exit`, 1 for y = `exit`.
    pub(super) exit_axis: usize,
    pub(super) exit: f64,
    /// Horizontal distance from the camera where the reference ray leaves the cell.
    pub(super) h_out: f64,
    /// The path leaves the grid, or reaches no ray's end, here.
    pub(super) last: bool,
}

/// Scratch space of one worker of the sweep.
#[derive(Default)]
pub(super) struct SweepScratch {
    pub(super) hits: Vec<RayHits>,
    pub(super) marks: Vec<(usize, u64)>,
    pub(super) buf: Vec<usize>,
    /// The marks of the current position in cells beyond the reachable region.
    pub(super) beyond: Vec<(usize, u64)>,
}

/// A pixel column's walk found a case it does not decide exactly: walk its rays one by one.
pub(super) struct Ambiguous;

impl VoxelCaster<'_> {
    /// Whether the column sweep applies: at most 64 layers and 64 rows (one bit each), and adjacent
    /// rows of a column closer than a voxel at the farthest range (so the voxels of a run of rays are
    /// one span per cell, see [`VoxelCaster::sweep_column`]).
    pub(super) fn sweep_applies(&self, camera: &DepthCamera) -> bool {
        let (w, h) = camera.image_size();
        if self.grid.nz > 64 || !(2..=64).contains(&h) {
            return false;
        }
        let dirs = camera.camera_dirs();
        (0..w).all(|u| {
            (1..h).all(|k| {
                let slope = |d: &Vector3<f32>| d.z as f64 / (d.x as f64).hypot(d.y as f64);
                let gap = slope(&dirs[(k - 1) * w + u]) - slope(&dirs[k * w + u]);
                gap > 0.0 && gap * self.range.1 as f64 <= 0.9 * self.grid.res
            })
        })
    }

    /// A ray's walk limits, as [`VoxelCaster::observe`] and the voxel walk's clip to the grid's
    /// top and bottom faces set them.
    pub(super) fn column_ray(&self, origin: Point3<f32>, dir: Vector3<f32>) -> ColumnRay {
        let (min_range, max_range) = self.range;
        let (oz, dz) = (origin.z as f64, dir.z as f64);
        let leave = if dz > 0.0 {
            (self.band.1 - oz) / dz
        } else if dz < 0.0 {
            (self.band.0 - oz) / dz
        } else {
            f64::INFINITY
        };
        let cut = (leave + 1e-6).max(min_range as f64).min(max_range as f64);
        let top = self.grid.nz as f64 * self.grid.res;
        let face = if dz > 0.0 {
            (top - oz) / dz
        } else if dz < 0.0 {
            -oz / dz
        } else {
            f64::INFINITY
        };
        let d = [dir.x as f64, dir.y as f64, dz];
        let t1 = cut.min(face);
        ColumnRay {
            dir,
            d,
            inv: d.map(|x| 1.0 / x),
            t1,
            z_clamped: face <= cut,
            h1: t1 * (d[0] * d[0] + d[1] * d[1]).sqrt(),
        }
    }

    /// What [`VoxelCaster::sweep_column`] needs of a pixel column's rays alone (not of the
    /// position): the same for every position, so set up once per heading and column. `None` when
    /// the column is to be walked ray by ray wherever the camera stands.
    pub(super) fn column_setup(&self, oz: f64, rays: &[ColumnRay]) -> Option<ColumnSetup> {
        let (res, nz) = (self.grid.res, self.grid.nz);
        let n = rays.len();
        let span = layer_span;
        if !(self.band.0..self.band.1).contains(&oz) || n == 0 || n > 64 {
            return None;
        }
        // The reference horizontal direction (the middle row's) and the largest angle to it.
        let r = rays[n / 2].d;
        let g = (r[0] * r[0] + r[1] * r[1]).sqrt();
        let u = [r[0] / g, r[1] / g];
        let mut spread = 0.0f64;
        let mut h_max = 0.0f64;
        for ray in rays.iter() {
            let gk = (ray.d[0] * ray.d[0] + ray.d[1] * ray.d[1]).sqrt();
            if gk == 0.0 {
                return None;
            }
            spread = spread.max(((u[0] * ray.d[1] - u[1] * ray.d[0]) / gk).abs());
            h_max = h_max.max(ray.h1);
        }
        // Rays end in order from both ends of the column toward its most horizontal row.
        let peak = (0..n)
            .max_by(|&a, &b| rays[a].h1.total_cmp(&rays[b].h1))
            .unwrap_or(0);
        if (1..=peak).any(|k| rays[k].h1 < rays[k - 1].h1)
            || (peak + 1..n).any(|k| rays[k].h1 > rays[k - 1].h1)
        {
            return None;
        }
        // How far along a grid line of axis `a` a ray may cross it from where the reference ray does,
        // per metre from the camera.
        let mut drift = [f64::INFINITY; 2];
        for (a, dr) in drift.iter_mut().enumerate() {
            let slack = u[a].abs() - spread;
            if slack > 0.0 {
                *dr = spread / slack;
            }
        }
        // Outside the band only a ray's last voxel lies (the walk is cut where it leaves the band),
        // and what it marks there is dropped; an occupied voxel there matters only through a hit
        // nearer than the minimum range, impossible when the band is left beyond it. Then runs need
        // to meet occupied voxels of the band only to be walked one by one.
        let (z_lo, z_hi) = self.band;
        let (mut rise, mut fall) = (0.0f64, 0.0f64);
        for ray in rays.iter() {
            rise = rise.max(ray.d[2]);
            fall = fall.max(-ray.d[2]);
        }
        let leaves_beyond_min_range =
            |gap: f64, speed: f64| speed <= 0.0 || gap / speed > self.range.0 as f64 + 10.0 * res;
        let in_band = span(
            floor_i64(z_lo / res + 0.5).max(0) as usize,
            (floor_i64(z_hi / res + 0.5) as usize).clamp(1, nz) - 1,
        );
        let occ_mask = if leaves_beyond_min_range(oz - z_lo, fall)
            && leaves_beyond_min_range(z_hi - oz, rise)
        {
            in_band
        } else {
            u64::MAX
        };
        Some(ColumnSetup {
            u,
            drift,
            h_max,
            occ_mask,
        })
    }

    /// Marks, as `(floor cell, layer mask)` pairs, the voxels that the rays of one pixel column
    /// (top row first) make known: the same voxels as [`VoxelCaster::observe`] gives ray by ray.
    ///
    /// The rays of a pixel column lie in one vertical plane, so they cross the same floor cells
    /// (checked: no ray passes a cell corner on the other side than the reference ray). In a cell,
    /// a ray walks the layers between its heights where it enters and leaves the cell; consecutive
    /// rows are less than a voxel apart (see [`VoxelCaster::sweep_applies`]), so a run of rays that
    /// meets no occupied voxel in the cell makes known exactly the span of layers between its top
    /// ray's highest point and its bottom ray's lowest one (and the lowest/highest point of a ray
    /// that ends in the cell). Those runs cost a few operations per cell instead of a voxel walk per
    /// ray. Where a run meets an occupied voxel, it is halved (down to [`MIN_SPLIT`] rays): a part
    /// that meets none is a run of its own (above or below a table top, say), and the rays of the
    /// rest are walked through the cell's layers one voxel at a time, with `observe`'s rule for
    /// hits; a ray that has found a hit beyond the cell goes on that way. (A part, like a run, has
    /// only the heights of its top and bottom rays and of its rays that end in the cell checked
    /// against the layer boundaries.) Every distance and height is computed from the ray's own
    /// direction; where one lies within [`TIE_M`] of a voxel boundary (so that rounding could decide
    /// which side the map's walk takes), the column is given up ([`Ambiguous`]) and walked ray by ray.
    pub(super) fn sweep_column(
        &self,
        origin: Point3<f32>,
        rays: &[ColumnRay],
        setup: &ColumnSetup,
        hits: &mut [RayHits],
        marks: &mut Vec<(usize, u64)>,
    ) -> std::result::Result<(), Ambiguous> {
        let grid = self.grid;
        let res = grid.res;
        let inv_res = 1.0 / res;
        let nz = grid.nz;
        let n = rays.len();
        let o = [origin.x as f64, origin.y as f64, origin.z as f64];
        let lo = [grid.origin_x, grid.origin_y];
        let dims = [grid.nx as i64, grid.ny as i64];
        let ColumnSetup {
            u,
            drift,
            h_max,
            occ_mask,
        } = *setup;
        // The floor cells of the path, leaving each by its nearer grid line: made one at a time as
        // the sweep reaches them, so the cells past where every ray has stopped (behind a wall) cost
        // nothing and cannot make the column ambiguous.
        let cell_of = |a: usize| floor_i64((o[a] - lo[a]) / res);
        let mut idx = [cell_of(0), cell_of(1)];
        if (0..2).any(|a| idx[a] < 0 || idx[a] >= dims[a]) {
            return Err(Ambiguous);
        }
        // The grid line of axis `a` ahead of the cell `idx[a]`, and how far along `u` it lies (kept
        // from cell to cell, and made again for the axis stepped only).
        let ahead = |a: usize, i: i64| {
            let line = if u[a] > 0.0 {
                lo[a] + (i + 1) as f64 * res
            } else if u[a] < 0.0 {
                lo[a] + i as f64 * res
            } else {
                return (0.0, f64::INFINITY);
            };
            (line, (line - o[a]) / u[a])
        };
        let (mut line, mut next) = ([0.0f64; 2], [f64::INFINITY; 2]);
        for a in 0..2 {
            (line[a], next[a]) = ahead(a, idx[a]);
        }
        let mut next_cell = || -> std::result::Result<PathCell, Ambiguous> {
            let a = if next[0] < next[1] { 0 } else { 1 };
            let h_out = next[a];
            if !h_out.is_finite() {
                return Err(Ambiguous);
            }
            // Every ray of the column crosses this line away from the other axis's grid lines.
            let b = 1 - a;
            let along = o[b] + u[b] * h_out;
            let f = (along - lo[b]) * inv_res;
            let corner = (f - floor_both(f + 0.5).1).abs() * res;
            if corner <= h_out * drift[a] + TIE_M {
                return Err(Ambiguous);
            }
            let cell = (idx[1] * dims[0] + idx[0]) as usize;
            let exit = line[a];
            idx[a] += if u[a] > 0.0 { 1 } else { -1 };
            (line[a], next[a]) = ahead(a, idx[a]);
            let leaves = idx[a] < 0 || idx[a] >= dims[a];
            let last = leaves || h_out > h_max + 1e-6;
            Ok(PathCell {
                cell,
                exit_axis: a,
                exit,
                h_out,
                last,
            })
        };
        let cross = |ray: &ColumnRay, axis: usize, line: f64| (line - o[axis]) * ray.inv[axis];
        let z_at = |ray: &ColumnRay, t: f64| o[2] + ray.d[2] * t;
        // The layer of height `z`, or Ambiguous when `z` is within TIE_M of a layer boundary.
        let layer = |z: f64, clamped: bool| -> std::result::Result<usize, Ambiguous> {
            let (l, l_f) = floor_both(z * inv_res);
            let base = l_f * res;
            if !clamped && (z - base < TIE_M || base + res - z < TIE_M) {
                return Err(Ambiguous);
            }
            Ok((l.max(0) as usize).min(nz - 1))
        };
        let span = layer_span;
        let all = if n == 64 { u64::MAX } else { (1u64 << n) - 1 };
        // Rays walked as runs, rays walked one by one (a hit found beyond the cell), rays not ended.
        let mut runs = all;
        let mut single = 0u64;
        let (mut first, mut last_ray) = (0usize, n - 1);
        let mut ended_all = false;
        let mut entry: Option<(usize, f64)> = None;
        loop {
            let step = next_cell()?;
            let occ = self.occupied_layers(step.cell);
            let t_in = |ray: &ColumnRay| entry.map_or(0.0, |(a, line)| cross(ray, a, line));
            let t_out = |ray: &ColumnRay| cross(ray, step.exit_axis, step.exit);
            // Where a ray's walk leaves this cell, and whether that is the grid's top or bottom.
            let t_end = |ray: &ColumnRay, ends: bool| {
                let t = t_out(ray);
                if ends && ray.t1 <= t {
                    (ray.t1, ray.z_clamped)
                } else {
                    (t, false)
                }
            };
            // The rays that end in this cell: from both ends of the rows not yet ended.
            let mut enders = 0u64;
            if step.last {
                enders = (runs | single) & span(first, last_ray);
            } else {
                let tol = 1e-5 * (1.0 + step.h_out);
                let check = |k: usize| -> std::result::Result<bool, Ambiguous> {
                    let ray = &rays[k];
                    if ray.h1 > step.h_out + tol {
                        return Ok(false);
                    }
                    let te = t_out(ray);
                    if ray.t1 < te - TIE_M {
                        Ok(true)
                    } else if ray.t1 > te + tol {
                        Ok(false)
                    } else {
                        Err(Ambiguous)
                    }
                };
                while first <= last_ray && !ended_all && check(first)? {
                    enders |= 1 << first;
                    if first == last_ray {
                        ended_all = true;
                    } else {
                        first += 1;
                    }
                }
                while first <= last_ray && !ended_all && check(last_ray)? {
                    enders |= 1 << last_ray;
                    if first == last_ray {
                        ended_all = true;
                    } else {
                        last_ray -= 1;
                    }
                }
            }
            // One ray through this cell's layers, voxel by voxel, with observe's rule for hits.
            // Returns whether the ray stops here.
            let walk =
                |k: usize, hits: &mut [RayHits], here: &mut u64, marks: &mut Vec<(usize, u64)>| {
                    let ray = &rays[k];
                    let ends = enders >> k & 1 == 1;
                    let t0 = t_in(ray);
                    let (t_end, clamped) = t_end(ray, ends);
                    let l0 = layer(z_at(ray, t0), false)?;
                    let l1 = layer(z_at(ray, t_end), clamped)?;
                    let up = ray.d[2] > 0.0;
                    let hit = &mut hits[k];
                    if hit.best == f64::INFINITY && span(l0, l1) & occ & occ_mask == 0 {
                        // No occupied voxel on the way through this cell: all its layers, no hit.
                        *here |= span(l0, l1);
                        return Ok(ends);
                    }
                    let mut best = hit.best;
                    let mut l = l0;
                    let mut stopped = false;
                    let mut mask = 0u64;
                    loop {
                        let tv_in = if l == l0 {
                            t0
                        } else {
                            let z = if up {
                                l as f64 * res
                            } else {
                                (l + 1) as f64 * res
                            };
                            (z - o[2]) * ray.inv[2]
                        };
                        let tv_out = if l == l1 {
                            t_end
                        } else {
                            let z = if up {
                                (l + 1) as f64 * res
                            } else {
                                l as f64 * res
                            };
                            (z - o[2]) * ray.inv[2]
                        };
                        // `occ` holds the cell's occupied layers: `tris.occupied` without a load.
                        if occ >> l & 1 == 1 {
                            let list = self.tris.list(step.cell, l);
                            // The ray's nearest hit is the least over every triangle it was tested
                            // against, in any order: a list tested again changes nothing.
                            if list != hit.tested {
                                hit.tested = list;
                                best = best.min(self.hit_in(list, origin, ray.dir));
                            }
                        }
                        if best <= tv_in {
                            stopped = true;
                            break;
                        }
                        mask |= 1 << l;
                        if best <= tv_out {
                            stopped = true;
                            break;
                        }
                        if l == l1 {
                            break;
                        }
                        l = if up { l + 1 } else { l - 1 };
                    }
                    *here |= mask;
                    hit.best = best;
                    let done = stopped || ends;
                    if done && best.is_finite() {
                        if best < self.range.0 as f64 {
                            // No reading: the map integrates nothing of this ray, not even the cells
                            // already marked. Rare (a hit within the minimum range): walk ray by ray.
                            return Err(Ambiguous);
                        }
                        let p = Point3::new(o[0], o[1], o[2]) + ray.dir.cast::<f64>() * best;
                        // `grid.voxel_of(p)`, its floors taken without a libm call (the same values).
                        let ix = floor_i64((p.x - grid.origin_x) / res);
                        let iy = floor_i64((p.y - grid.origin_y) / res);
                        let iz = floor_i64(p.z / res);
                        if (0..dims[0]).contains(&ix)
                            && (0..dims[1]).contains(&iy)
                            && (0..nz as i64).contains(&iz)
                        {
                            let c = (iy * dims[0] + ix) as usize;
                            // Usually this cell's: joined to its mark rather than a mark of its own.
                            if c == step.cell {
                                *here |= 1 << iz;
                            } else {
                                marks.push((c, 1 << iz));
                            }
                        }
                    }
                    Ok(done)
                };
            // The layers marked in this cell.
            let mut here = 0u64;
            // The rays walked one by one here: the single rays, and the runs that meet an
            // occupied voxel (gathered first, so that the walk has one call site and is inlined).
            let mut walked = single;
            // The layers of a part `a..=b` of a run: from its lowest to its highest point, which are
            // those of its top and bottom rays and of its rays that end here.
            let cover = |a: usize, b: usize| -> std::result::Result<u64, Ambiguous> {
                let (mut z_min, mut z_max) = (f64::INFINITY, f64::NEG_INFINITY);
                let (mut c_min, mut c_max) = (false, false);
                let mut ext = (enders & span(a, b)) | 1 << a | 1 << b;
                while ext != 0 {
                    let k = ext.trailing_zeros() as usize;
                    ext &= ext - 1;
                    let ray = &rays[k];
                    let ends = enders >> k & 1 == 1;
                    let (t_e, clamped_e) = t_end(ray, ends);
                    for (z, clamped) in [(z_at(ray, t_in(ray)), false), (z_at(ray, t_e), clamped_e)]
                    {
                        if z < z_min {
                            (z_min, c_min) = (z, clamped);
                        }
                        if z > z_max {
                            (z_max, c_max) = (z, clamped);
                        }
                    }
                }
                Ok(span(layer(z_min, c_min)?, layer(z_max, c_max)?))
            };
            let blocked = occ & occ_mask;
            // Parts of runs that meet an occupied voxel, still to be split.
            let mut parts = [(0usize, 0usize); 16];
            let mut m = runs;
            while m != 0 {
                let a = m.trailing_zeros() as usize;
                let len = (!(m >> a)).trailing_zeros() as usize;
                let b = a + len - 1;
                m &= !span(a, b);
                let mut todo = 0;
                let mut part = (a, b);
                loop {
                    let (a, b) = part;
                    let layers = cover(a, b)?;
                    if layers & blocked == 0 {
                        here |= layers;
                    } else if b - a < MIN_SPLIT || layers & self.band_mask & !blocked == 0 {
                        // Too few rays to split, or every ray meets an occupied voxel (each passes
                        // a band layer of the part's, all occupied): walked one by one.
                        walked |= span(a, b);
                    } else {
                        // The halves that meet no occupied voxel are runs of their own.
                        let mid = (a + b) / 2;
                        parts[todo] = (mid + 1, b);
                        part = (a, mid);
                        todo += 1;
                        continue;
                    }
                    if todo == 0 {
                        break;
                    }
                    todo -= 1;
                    part = parts[todo];
                }
            }
            let mut stopped = 0u64;
            while walked != 0 {
                let k = walked.trailing_zeros() as usize;
                walked &= walked - 1;
                if walk(k, hits, &mut here, marks)? {
                    stopped |= 1 << k;
                } else if hits[k].best.is_finite() {
                    // A hit beyond this cell: walked one by one from now on.
                    runs &= !(1 << k);
                    single |= 1 << k;
                }
            }
            if here != 0 {
                marks.push((step.cell, here));
            }
            runs &= !(enders | stopped);
            single &= !(enders | stopped);
            if runs | single == 0 {
                return Ok(());
            }
            if step.last {
                // Rays left when the path ended: a case the checks above should exclude.
                return Err(Ambiguous);
            }
            entry = Some((step.exit_axis, step.exit));
        }
    }

    /// The occupied layers of floor cell `cell`, one bit each.
    #[inline]
    pub(super) fn occupied_layers(&self, cell: usize) -> u64 {
        self.tris.layers.get(cell).copied().unwrap_or(u64::MAX)
    }
}
