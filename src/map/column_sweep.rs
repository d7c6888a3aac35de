//! The miss pass's fast path: the rays of one pixel column swept together through the floor cells
//! they share, instead of one voxel walk per ray (`occupancy::traverse`).
//!
//! The camera turns only about z, so the rays of a pixel column lie in one vertical plane (up to the
//! f32 rounding of their directions) and cross the same floor cells in the same order. In a cell, a
//! ray passes the layers between its heights where it enters the cell and where it leaves it or
//! ends (its range, the frame's maximum range, or the grid's box). Neighbouring rays of a column are
//! less than a voxel apart where they cross a cell line, so the layers that a *run* of neighbouring
//! rays passes in a cell form one span: from the lowest to the highest of the run's top and bottom
//! rays where they enter, of the rays that end in the cell where they end, and of the top and bottom
//! rays that go on where they leave. That is a few heights per cell and run instead of a walk per
//! ray; the union is then the same voxels as walking every ray.
//!
//! **Bit for bit the walk's voxels.** The walk decides each step by comparing floating-point
//! distances computed from the ray's own direction; rounding matters only where two of them (or a
//! ray's end and a boundary) are within about 1e-13 m. The sweep computes every distance and height
//! it relies on from each ray's own direction too, and gives the column up ([`Ambiguous`]: its rays
//! are walked one by one) wherever one lies within [`TIE_M`] of a voxel boundary:
//! - the camera's origin, frame-wide (it must also lie inside the grid);
//! - where a ray of the column crosses a grid line of one axis, its position along the other axis
//!   (bounded for all the rays at once with their extreme slopes): then all rays cross the lines in
//!   the same order, the path of cells is shared;
//! - each ray's end: against the cell lines around it and, in height, against the layer boundaries
//!   (the grid's faces end the walk, they are not steps); there only that ray is walked on its own;
//! - the top and bottom rays of each run where they cross a cell line. A ray inside a run may cross
//!   a cell line at a layer boundary, where the walk could take either voxel; its neighbours in the
//!   run cross that line more than 4·[`TIE_M`] above and below it (checked at the first line, the
//!   nearest) and less than a voxel apart, so they pass both voxels and the union is the same.
//!
//! Rays are in one run only while their heights at every line that both cross differ by less than a
//! voxel (rows ended between them, invalid readings and coarse cameras split runs). Heights must
//! rise strictly from the bottom row up along every line. A ray that ends within TIE_M of a cell
//! line or a layer boundary (a wall or a table top on a voxel boundary) is left out of the sweep and
//! walked on its own: about 0.3 % of the rays on the shipped scenes, where no whole column was given
//! up (see the test `column_sweep_equals_the_voxel_walk_on_real_scenes` in `occupancy.rs`). Grids
//! of more than 64 layers, frames whose ray count is not width × height, and origins outside the
//! grid are walked ray by ray.
//!
//! (The observable set's `VoxelCaster::sweep_column` in `eval/observable/sweep.rs` sweeps columns the
//! same way but cannot be this sweep: this one takes each ray's end from the frame, that one finds
//! the end while it sweeps, from the triangles of the occupied voxels its runs meet. Integrating a
//! cast frame here instead does not give the observable set's voxels bit for bit: see that module.)

use super::occupancy::hit_voxel_at;
use crate::grid::{floor_both, floor_i64, layer_span, GridSpec, TIE_M};
use crate::sensor::DepthFrame;
use nalgebra::Point3;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

/// A column the sweep cannot vouch for: walk its rays one by one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Ambiguous;

/// No ray (end of a linked list); no voxel.
pub(super) const NONE: u32 = u32::MAX;

/// In a frame's hit voxels ([`Sweep::column`]'s `hits`): the ray's hit lies in no voxel of the
/// grid (most often a floor hit whose point rounded under z = 0, or a wall hit above the grid's
/// top).
pub(super) const OUTSIDE: u32 = u32::MAX - 1;

/// The frame-wide part of the sweep.
pub(super) struct Sweep<'a> {
    grid: &'a GridSpec,
    frame: &'a DepthFrame,
    o: [f64; 3],
    lo: [f64; 2],
    inv_res: f64,
    /// Twice TIE_M, in cells.
    tie: f64,
    /// The grid's box, per axis, as `clip_to_grid_inv` computes its faces; and shrunk by 1e-6 m.
    faces: [(f64, f64); 3],
    inner: [(f64, f64); 3],
    dims: [i64; 2],
    cells: u32,
    /// The origin's floor cell and layer.
    cell: [i64; 2],
    layer: usize,
}

/// One valid ray of the column being swept.
#[derive(Clone, Copy, Debug, Default)]
struct Ray {
    /// Rise per metre along x and along y (dz/dx, dz/dy).
    w: [f64; 2],
    /// |displacement| along x and y at its end.
    reach: [f64; 2],
    /// The step of the path in which it ends, and the floor cell and layer.
    end: u32,
    end_cell: u32,
    end_layer: u32,
}

/// A floor cell of the column's path and the grid line by which the rays leave it.
#[derive(Clone, Copy, Debug)]
struct Step {
    cell: usize,
    axis: usize,
    line: f64,
}

/// Neighbouring rays (indices into the column's rays, linked) that enter a cell within the layers
/// `lo..=hi`.
#[derive(Clone, Copy, Debug)]
struct Run {
    top: u32,
    bottom: u32,
    lo: usize,
    hi: usize,
}

/// Buffers reused from column to column.
#[derive(Clone, Debug, Default)]
pub(super) struct Scratch {
    rays: Vec<Ray>,
    path: Vec<Step>,
    prev: Vec<u32>,
    next: Vec<u32>,
    /// Per step, where its rays (that end in it) start in `ends`.
    start: Vec<u32>,
    ends: Vec<u32>,
    runs: Vec<Run>,
    next_runs: Vec<Run>,
    gaps: Vec<u32>,
    /// The column's result: a layer mask per floor cell, and rays (frame indices) to walk one by
    /// one.
    pub marks: Vec<(usize, u64)>,
    pub singles: Vec<usize>,
}

/// The smaller of two numbers that are not NaN, in a compare and a select (`f64::min` also
/// handles NaN).
#[inline(always)]
fn min_f64(a: f64, b: f64) -> f64 {
    if b < a {
        b
    } else {
        a
    }
}

impl<'a> Sweep<'a> {
    /// The sweep of `frame`'s columns, or `None` where it does not apply to the frame (see the
    /// module's docs).
    pub fn new(
        grid: &'a GridSpec,
        frame: &'a DepthFrame,
        origin: Point3<f64>,
    ) -> Option<Sweep<'a>> {
        let n = frame.width.checked_mul(frame.height)?;
        if !(1..=64).contains(&grid.nz)
            || grid.voxels() >= OUTSIDE as usize
            || n != frame.dirs.len()
            || n != frame.range.len()
        {
            return None;
        }
        let res = grid.res;
        // The cell (layer) of coordinate `x` of a grid of `len` starting at `lo`, TIE_M clear of its
        // faces.
        let inside = |x: f64, lo: f64, len: usize| -> Option<i64> {
            let i = floor_i64((x - lo) / res);
            let base = lo + i as f64 * res;
            ((0..len as i64).contains(&i) && x - base >= TIE_M && base + res - x >= TIE_M)
                .then_some(i)
        };
        let ix = inside(origin.x, grid.origin_x, grid.nx)?;
        let iy = inside(origin.y, grid.origin_y, grid.ny)?;
        let iz = inside(origin.z, 0.0, grid.nz)?;
        let faces = [
            (grid.origin_x, grid.nx),
            (grid.origin_y, grid.ny),
            (0.0, grid.nz),
        ]
        .map(|(lo, n)| (lo, lo + n as f64 * res));
        Some(Sweep {
            grid,
            frame,
            o: [origin.x, origin.y, origin.z],
            lo: [grid.origin_x, grid.origin_y],
            inv_res: 1.0 / res,
            tie: 2.0 * TIE_M / res,
            faces,
            inner: faces.map(|(lo, hi)| (lo + 1e-6, hi - 1e-6)),
            dims: [grid.nx as i64, grid.ny as i64],
            // (Voxel indices are u32 throughout: `OccupancyUpdate::newly_known`.)
            cells: grid.cells() as u32,
            cell: [ix, iy],
            layer: iz as usize,
        })
    }

    /// The cell (along one axis: x, y or z) of coordinate `x` on a ray's way, of a grid of `len`
    /// cells from `lo`; `Ambiguous` within TIE_M of a line between two cells (the grid's faces end
    /// the walk: no tie there, and a point a rounding beyond one is in the cell inside).
    #[inline(always)]
    fn cell_along(&self, x: f64, lo: f64, len: usize) -> Result<i64, Ambiguous> {
        let len = len as i64;
        // In cells. Its rounding (under 1e-11 cells on any grid that fits in memory) is far
        // below the tie width.
        let u = (x - lo) * self.inv_res;
        let (l, lf) = floor_both(u);
        let frac = u - lf;
        // The common case first: clear of both lines, inside (false for NaN too).
        if frac >= self.tie && frac <= 1.0 - self.tie && (0..len).contains(&l) {
            return Ok(l);
        }
        if (frac < self.tie && l >= 1 && l < len)
            || (frac > 1.0 - self.tie && l >= 0 && l + 1 < len)
        {
            return Err(Ambiguous);
        }
        Ok(l.clamp(0, len - 1))
    }

    /// The layer of height `z` on a ray's way (see [`Sweep::cell_along`]).
    #[inline(always)]
    fn layer(&self, z: f64) -> Result<usize, Ambiguous> {
        self.cell_along(z, 0.0, self.grid.nz).map(|l| l as usize)
    }

    /// Sweeps pixel column `col`: on `Ok`, `s.marks` holds the voxels that its rays pass, save the
    /// rays listed in `s.singles` (to be walked one by one), the same as `traverse` gives ray by
    /// ray (rays with an invalid range skipped, no-hit rays to the maximum range). Either way,
    /// each of the column's rays has its entry in `hits` (indexed by ray) written: the voxel where
    /// it hit, [`OUTSIDE`], or [`NONE`] for no hit, as `super::occupancy::hit_voxel` gives it.
    pub fn column(&self, col: usize, s: &mut Scratch, hits: &[AtomicU32]) -> Result<(), Ambiguous> {
        s.marks.clear();
        s.singles.clear();
        let (grid, f, o) = (self.grid, self.frame, self.o);
        let res = grid.res;
        // The rays, with where they end. A ray that ends within TIE_M of a cell line or a layer
        // boundary, as rays that hit a wall or a table top on a voxel boundary do, is walked on its
        // own instead. Per axis: the common sign of the rays' directions (0: none crosses its lines)
        // and the extreme slopes of the other coordinate.
        s.rays.clear();
        let mut sgn = [2i64; 2];
        let mut slope = [(f64::INFINITY, f64::NEG_INFINITY); 2];
        let mut steps = 0usize;
        for row in 0..f.height {
            let i = row * f.width + col;
            hits[i].store(NONE, Relaxed);
            let range = f.range[i];
            let Some(t_end) = f.free_length(i) else {
                continue;
            };
            let dir = f.dirs[i].cast::<f64>();
            let d = [dir.x, dir.y, dir.z];
            let (t_end, mut t1) = (t_end as f64, t_end as f64);
            let mut end = [
                o[0] + d[0] * t_end,
                o[1] + d[1] * t_end,
                o[2] + d[2] * t_end,
            ];
            // The hit's voxel where the sweep does not tell it below: the lookup `hit_voxel`
            // makes, of the same point (its `origin + dir * range`).
            let (is_hit, hit_point) = (range.is_finite(), Point3::from(end));
            let look_up = || hit_voxel_at(grid, self.inv_res, hit_point);
            // The clip (`clip_to_grid_inv`), with the origin inside the grid: it starts the ray at
            // 0, and only an axis along which the end is not well inside the box can cut it (the
            // quotients are off by ulps, the margin is 1e-6 m), so only such axes take a division.
            // The same minimum of the same quotients, so the same end.
            let mut inside = true;
            for a in 0..3 {
                if !(end[a] > self.inner[a].0 && end[a] < self.inner[a].1) {
                    inside = false;
                    if d[a] != 0.0 {
                        let inv = 1.0 / d[a];
                        let (lo, hi) = self.faces[a];
                        let (ta, tb) = ((lo - o[a]) * inv, (hi - o[a]) * inv);
                        t1 = t1.min(ta.max(tb));
                    }
                }
            }
            // (Also NaN.)
            if t1 <= 0.0 || t1.is_nan() {
                if is_hit {
                    hits[i].store(look_up(), Relaxed);
                }
                continue; // the walk visits nothing
            }
            if !inside {
                end = [o[0] + d[0] * t1, o[1] + d[1] * t1, o[2] + d[2] * t1];
            }
            if d[0] == 0.0 && d[1] == 0.0 {
                return Err(Ambiguous);
            }
            // (Only the axes the rays cross are read: there the direction is not zero.)
            let inv = [1.0 / d[0], 1.0 / d[1]];
            for a in 0..2 {
                let sign = (d[a] > 0.0) as i64 - (d[a] < 0.0) as i64;
                if sgn[a] != sign {
                    if sgn[a] != 2 {
                        return Err(Ambiguous);
                    }
                    sgn[a] = sign;
                }
                if sign != 0 {
                    // d_b / d_a
                    let sl = d[1 - a] * inv[a];
                    // (Finite: d_a is an f32's value, not zero.)
                    if sl < slope[a].0 {
                        slope[a].0 = sl;
                    }
                    if sl > slope[a].1 {
                        slope[a].1 = sl;
                    }
                }
            }
            let (Ok(ix), Ok(iy), Ok(iz)) = (
                self.cell_along(end[0], self.lo[0], grid.nx),
                self.cell_along(end[1], self.lo[1], grid.ny),
                self.layer(end[2]),
            ) else {
                if is_hit {
                    hits[i].store(look_up(), Relaxed);
                }
                s.singles.push(i);
                continue;
            };
            let end_cell = (iy * self.dims[0] + ix) as u32;
            // Where the ray hit, the voxel of its end: the clip kept the whole ray, and the end is
            // clear of the voxel's faces by more than the rounding of `voxel_of`'s divisions, or
            // (a floor hit) in the bottom layer, not below it.
            let kept = inside
                || (t1 == t_end
                    && (0..2).all(|a| end[a] > self.inner[a].0 && end[a] < self.inner[a].1)
                    && end[2] >= 0.0
                    && end[2] < self.inner[2].1);
            if is_hit {
                let v = match kept {
                    true => iz as u32 * self.cells + end_cell,
                    false => look_up(),
                };
                hits[i].store(v, Relaxed);
            }
            // One line crossed per step of the path.
            let j = (ix - self.cell[0]).unsigned_abs() + (iy - self.cell[1]).unsigned_abs();
            steps = steps.max(j as usize + 1);
            s.rays.push(Ray {
                w: [d[2] * inv[0], d[2] * inv[1]],
                reach: [(t1 * d[0]).abs(), (t1 * d[1]).abs()],
                end: j as u32,
                end_layer: iz as u32,
                end_cell,
            });
        }
        let rays = &s.rays;
        let m = rays.len();
        if m == 0 {
            return Ok(());
        }
        // The path of floor cells, each left by the line that every ray crosses first, up to the
        // last cell a ray ends in.
        s.path.clear();
        let mut idx = self.cell;
        // Per axis, the distance to the first line crossed.
        let mut first = [f64::INFINITY; 2];
        while s.path.len() < steps {
            let mut line = [0.0f64; 2];
            let mut dist = [0.0f64; 2];
            for a in 0..2 {
                if sgn[a] != 0 {
                    line[a] = self.lo[a] + (idx[a] + (sgn[a] > 0) as i64) as f64 * res;
                    dist[a] = line[a] - o[a];
                }
            }
            let a = if sgn[0] == 0 {
                1
            } else if sgn[1] == 0 {
                0
            } else {
                // Where along y the rays cross the next x line, past the next y line.
                let (s0, s1) = (slope[0].0 * dist[0], slope[0].1 * dist[0]);
                let (y_lo, y_hi) = (o[1] + s0.min(s1), o[1] + s0.max(s1));
                let (past_lo, past_hi) = if sgn[1] > 0 {
                    (y_lo - line[1], y_hi - line[1])
                } else {
                    (line[1] - y_hi, line[1] - y_lo)
                };
                if past_hi < -TIE_M {
                    0
                } else if past_lo > TIE_M {
                    1
                } else {
                    return Err(Ambiguous);
                }
            };
            // (Finite.)
            if dist[a].abs() < first[a] {
                first[a] = dist[a].abs();
            }
            s.path.push(Step {
                cell: (idx[1] * self.dims[0] + idx[0]) as usize,
                axis: a,
                line: line[a],
            });
            idx[a] += sgn[a];
        }
        let path = &s.path;
        // Every ray ends in a cell of the path (else its own path is another).
        if rays
            .iter()
            .any(|r| path[r.end as usize].cell != r.end_cell as usize)
        {
            return Err(Ambiguous);
        }
        // Heights along a line rise strictly from each ray to the one above it, and neighbours are
        // far enough apart where they cross a line (nearest at the first line).
        for a in 0..2 {
            if sgn[a] == 0 {
                continue;
            }
            let mut min_dw = f64::INFINITY;
            for k in 1..m {
                let dw = (rays[k - 1].w[a] - rays[k].w[a]) * sgn[a] as f64;
                // (Also NaN.)
                if dw <= 0.0 || dw.is_nan() {
                    return Err(Ambiguous);
                }
                if dw < min_dw {
                    min_dw = dw;
                }
            }
            if m > 1 && min_dw * first[a] <= 4.0 * TIE_M {
                return Err(Ambiguous);
            }
        }
        s.start.clear();
        s.start.resize(steps + 1, 0);
        for r in rays.iter() {
            s.start[r.end as usize + 1] += 1;
        }
        for j in 0..steps {
            s.start[j + 1] += s.start[j];
        }
        // Rays by end step, ascending within each (`next` serves as the cursor for a moment).
        s.ends.clear();
        s.ends.resize(m, 0);
        s.next.clear();
        s.next.extend_from_slice(&s.start[..steps]);
        for (k, r) in rays.iter().enumerate() {
            let c = &mut s.next[r.end as usize];
            s.ends[*c as usize] = k as u32;
            *c += 1;
        }
        let rays = &s.rays;
        // Neighbours `i` above `j` are less than a voxel apart at every line they both cross.
        let joined = |i: u32, j: u32| {
            let (ri, rj) = (&rays[i as usize], &rays[j as usize]);
            (0..2).all(|a| {
                sgn[a] == 0
                    || (ri.w[a] - rj.w[a]).abs() * min_f64(ri.reach[a], rj.reach[a]) < res - TIE_M
            })
        };
        s.prev.clear();
        s.prev.extend((0..m as u32).map(|k| k.wrapping_sub(1)));
        s.next.clear();
        s.next
            .extend((1..=m as u32).map(|k| if k as usize == m { NONE } else { k }));
        s.runs.clear();
        let mut top = 0u32;
        for k in 1..m as u32 {
            if !joined(k - 1, k) {
                s.runs.push(Run {
                    top,
                    bottom: k - 1,
                    lo: self.layer,
                    hi: self.layer,
                });
                top = k;
            }
        }
        s.runs.push(Run {
            top,
            bottom: m as u32 - 1,
            lo: self.layer,
            hi: self.layer,
        });
        for (j, step) in path.iter().enumerate() {
            let enders = &s.ends[s.start[j] as usize..s.start[j + 1] as usize];
            let mut e = 0;
            let mut here = 0u64;
            s.next_runs.clear();
            let (axis, dist) = (step.axis, step.line - o[step.axis]);
            for run in &s.runs {
                let (mut lo, mut hi) = (run.lo, run.hi);
                let (mut top, mut bottom) = (run.top, run.bottom);
                let mut empty = false;
                s.gaps.clear();
                while e < enders.len() && enders[e] <= bottom {
                    let k = enders[e];
                    e += 1;
                    let l = rays[k as usize].end_layer as usize;
                    (lo, hi) = (lo.min(l), hi.max(l));
                    let (p, q) = (s.prev[k as usize], s.next[k as usize]);
                    if p != NONE {
                        s.next[p as usize] = q;
                    }
                    if q != NONE {
                        s.prev[q as usize] = p;
                    }
                    if k == top && k == bottom {
                        empty = true;
                    } else if k == top {
                        top = q;
                    } else if k == bottom {
                        bottom = p;
                    } else {
                        s.gaps.push(p);
                    }
                }
                if !empty {
                    // What goes on: the run, split where rows ended between rays too far apart.
                    let z_out = |k: u32| o[2] + rays[k as usize].w[axis] * dist;
                    let mut t = top;
                    let mut g = 0;
                    loop {
                        // (A gap is listed again when the row below it ended too: skip those.)
                        while g < s.gaps.len()
                            && (s.gaps[g] < t
                                || s.gaps[g] >= bottom
                                || joined(s.gaps[g], s.next[s.gaps[g] as usize]))
                        {
                            g += 1;
                        }
                        let b = if g < s.gaps.len() { s.gaps[g] } else { bottom };
                        // Every ray ends by the path's last step.
                        if j + 1 == steps {
                            return Err(Ambiguous);
                        }
                        let lt = self.layer(z_out(t))?;
                        let lb = if b == t { lt } else { self.layer(z_out(b))? };
                        let (l0, l1) = (lt.min(lb), lt.max(lb));
                        (lo, hi) = (lo.min(l0), hi.max(l1));
                        s.next_runs.push(Run {
                            top: t,
                            bottom: b,
                            lo: l0,
                            hi: l1,
                        });
                        if b == bottom {
                            break;
                        }
                        t = s.next[b as usize];
                        g += 1;
                    }
                }
                here |= layer_span(lo, hi);
            }
            debug_assert_eq!(e, enders.len());
            s.marks.push((step.cell, here));
            std::mem::swap(&mut s.runs, &mut s.next_runs);
            if s.runs.is_empty() {
                return Ok(());
            }
        }
        Err(Ambiguous)
    }
}
