//! Time-varying fields between key frames (TENSOR §4.1, Eq. 4–5).
//!
//! Over a window of cells around the robot and K sub-steps, each of `a` and `b` minimises
//! `‖Δ_ST τ‖² + α‖τ(0) − τ(t−1)‖² + α‖τ(K) − τ(t)‖²`, where `Δ_ST τ(i;j) = ω τ(i;j) − Σ_{k∈N(i)} ω_S
//! τ(k;j) − ω_T τ(i;j−1) − ω_T τ(i;j+1)` (4-neighbours; `ω` the sum of the weights present). Cells
//! outside the window keep the point-wise linear interpolation and enter as fixed values, so the
//! window blends into the rest of the field. The normal equations `(M² + αP) τ = M f + α τ_key` (`M` is
//! symmetric) are solved by Jacobi-preconditioned conjugate gradients, warm-started from the linear
//! interpolation; the iteration cap bounds the time (the solve is matrix-free and small).

use super::eval::FieldGrid;
use crate::grid::{Cell, GridSpec};
use nalgebra::Point2;

/// Parameters of Eq. 4–5 and of the solver.
#[derive(Clone, Copy, Debug)]
pub struct SpaceTimeParams {
    pub substeps: usize,
    pub omega_s: f64,
    pub omega_t: f64,
    pub alpha: f64,
    pub max_iterations: usize,
    pub tolerance: f64,
}

/// K+1 frames of `(a, b)` on a window of a grid (frame 0 ≈ the older key frame, frame K the newer).
#[derive(Clone, Debug)]
pub struct TimeVaryingField {
    pub grid: GridSpec,
    /// Lower-left cell of the window and its size in cells.
    pub corner: Cell,
    pub width: usize,
    pub height: usize,
    /// `frames[j][local cell]`.
    pub frames: Vec<Vec<[f64; 2]>>,
    /// CG iterations used (per component, the larger).
    pub iterations: usize,
}

impl TimeVaryingField {
    fn local(&self, c: Cell) -> Option<usize> {
        let (x, y) = (c.x - self.corner.x, c.y - self.corner.y);
        (x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height)
            .then(|| y as usize * self.width + x as usize)
    }

    /// `(a, b)` at `p` and time `t ∈ [0, 1]` (0 = older key frame): bilinear in space, linear between
    /// sub-steps; `None` outside the window.
    pub fn sample(&self, p: Point2<f64>, t: f64) -> Option<[f64; 2]> {
        let s = &self.grid;
        let c0 = s.cell_at(p.x - 0.5 * s.res, p.y - 0.5 * s.res);
        let o = s.center(c0);
        let (u, v) = ((p.x - o.x) / s.res, (p.y - o.y) / s.res);
        let idx = [
            self.local(c0)?,
            self.local(Cell::new(c0.x + 1, c0.y))?,
            self.local(Cell::new(c0.x, c0.y + 1))?,
            self.local(Cell::new(c0.x + 1, c0.y + 1))?,
        ];
        let k = self.frames.len() - 1;
        let tt = t.clamp(0.0, 1.0) * k as f64;
        let j0 = (tt.floor() as usize).min(k.saturating_sub(1));
        let f = tt - j0 as f64;
        let at = |j: usize, comp: usize| {
            let fr = &self.frames[j];
            fr[idx[0]][comp] * (1.0 - u) * (1.0 - v)
                + fr[idx[1]][comp] * u * (1.0 - v)
                + fr[idx[2]][comp] * (1.0 - u) * v
                + fr[idx[3]][comp] * u * v
        };
        let j1 = (j0 + 1).min(k);
        Some([0, 1].map(|comp| at(j0, comp) * (1.0 - f) + at(j1, comp) * f))
    }
}

fn window(grid: &GridSpec, center: Point2<f64>, radius_m: f64) -> Option<(Cell, usize, usize)> {
    let lo = grid.cell_at(center.x - radius_m, center.y - radius_m);
    let hi = grid.cell_at(center.x + radius_m, center.y + radius_m);
    let lo = Cell::new(lo.x.max(0), lo.y.max(0));
    let hi = Cell::new(hi.x.min(grid.nx as i32 - 1), hi.y.min(grid.ny as i32 - 1));
    (hi.x >= lo.x && hi.y >= lo.y)
        .then(|| (lo, (hi.x - lo.x + 1) as usize, (hi.y - lo.y + 1) as usize))
}

/// Point-wise linear interpolation on the same window (the baseline of TENSOR Fig. 6c).
pub fn linear_window(
    before: &FieldGrid,
    after: &FieldGrid,
    center: Point2<f64>,
    radius_m: f64,
    substeps: usize,
) -> Option<TimeVaryingField> {
    let (corner, width, height) = window(&before.spec, center, radius_m)?;
    let s = &before.spec;
    let k = substeps.max(1);
    let frames = (0..=k)
        .map(|j| {
            let t = j as f64 / k as f64;
            (0..width * height)
                .map(|l| {
                    let c = Cell::new(corner.x + (l % width) as i32, corner.y + (l / width) as i32);
                    let i = s.index(c);
                    [0, 1].map(|m| before.ab[i][m] * (1.0 - t) + after.ab[i][m] * t)
                })
                .collect()
        })
        .collect();
    Some(TimeVaryingField {
        grid: *s,
        corner,
        width,
        height,
        frames,
        iterations: 0,
    })
}

/// The space-time bi-harmonic interpolation of Eq. 4–5 on a window of `radius_m` around `center`.
pub fn biharmonic_window(
    before: &FieldGrid,
    after: &FieldGrid,
    center: Point2<f64>,
    radius_m: f64,
    params: &SpaceTimeParams,
) -> Option<TimeVaryingField> {
    let mut tv = linear_window(before, after, center, radius_m, params.substeps)?;
    let (w, h) = (tv.width, tv.height);
    let k = tv.frames.len() - 1;
    let n_cells = w * h;
    let n = n_cells * (k + 1);
    let s = before.spec;
    let idx = |l: usize, j: usize| j * n_cells + l;
    // Neighbour structure per local cell: in-window neighbours, and fixed outside neighbours (grid index).
    let mut inside: Vec<Vec<usize>> = vec![Vec::new(); n_cells];
    let mut outside: Vec<Vec<usize>> = vec![Vec::new(); n_cells];
    for l in 0..n_cells {
        let c = Cell::new(tv.corner.x + (l % w) as i32, tv.corner.y + (l / w) as i32);
        for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
            let nc = Cell::new(c.x + dx, c.y + dy);
            if let Some(nl) = tv.local(nc) {
                inside[l].push(nl);
            } else if let Some(gi) = s.checked_index(nc) {
                outside[l].push(gi);
            }
        }
    }
    let omega = |l: usize, j: usize| {
        let temporal = (j > 0) as usize + (j < k) as usize;
        (inside[l].len() + outside[l].len()) as f64 * params.omega_s
            + temporal as f64 * params.omega_t
    };
    // M x (unknowns only).
    let apply_m = |x: &[f64], y: &mut [f64]| {
        for j in 0..=k {
            for l in 0..n_cells {
                let mut v = omega(l, j) * x[idx(l, j)];
                for &nl in &inside[l] {
                    v -= params.omega_s * x[idx(nl, j)];
                }
                if j > 0 {
                    v -= params.omega_t * x[idx(l, j - 1)];
                }
                if j < k {
                    v -= params.omega_t * x[idx(l, j + 1)];
                }
                y[idx(l, j)] = v;
            }
        }
    };
    let penalty = |j: usize| if j == 0 || j == k { params.alpha } else { 0.0 };
    // diag(M²) + αP for the Jacobi preconditioner.
    let mut diag = vec![0.0; n];
    for j in 0..=k {
        for l in 0..n_cells {
            let temporal = (j > 0) as usize + (j < k) as usize;
            diag[idx(l, j)] = omega(l, j).powi(2)
                + inside[l].len() as f64 * params.omega_s.powi(2)
                + temporal as f64 * params.omega_t.powi(2)
                + penalty(j);
        }
    }
    // The two components are independent solves: run them side by side (results do not depend on it).
    let initial = tv.frames.clone();
    let solve = |comp: usize| -> (Vec<f64>, usize) {
        // f: fixed outside values (linear interpolation), moved to the right-hand side.
        let mut f = vec![0.0; n];
        let mut key = vec![0.0; n];
        let mut x = vec![0.0; n];
        for j in 0..=k {
            let t = j as f64 / k as f64;
            for l in 0..n_cells {
                f[idx(l, j)] = outside[l]
                    .iter()
                    .map(|&gi| {
                        params.omega_s * (before.ab[gi][comp] * (1.0 - t) + after.ab[gi][comp] * t)
                    })
                    .sum();
                x[idx(l, j)] = initial[j][l][comp];
            }
        }
        for l in 0..n_cells {
            let c = Cell::new(tv.corner.x + (l % w) as i32, tv.corner.y + (l / w) as i32);
            let gi = s.index(c);
            key[idx(l, 0)] = params.alpha * before.ab[gi][comp];
            key[idx(l, k)] = params.alpha * after.ab[gi][comp];
        }
        let mut rhs = vec![0.0; n];
        apply_m(&f, &mut rhs);
        for i in 0..n {
            rhs[i] += key[i];
        }
        let mut tmp = vec![0.0; n];
        let mut ax = vec![0.0; n];
        let apply_a = |x: &[f64], tmp: &mut Vec<f64>, out: &mut Vec<f64>| {
            apply_m(x, tmp);
            apply_m(tmp, out);
            for j in [0, k] {
                for l in 0..n_cells {
                    out[idx(l, j)] += params.alpha * x[idx(l, j)];
                }
            }
        };
        apply_a(&x, &mut tmp, &mut ax);
        let mut r: Vec<f64> = (0..n).map(|i| rhs[i] - ax[i]).collect();
        let norm_b = rhs.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
        let mut z: Vec<f64> = (0..n).map(|i| r[i] / diag[i]).collect();
        let mut p = z.clone();
        let mut rz: f64 = (0..n).map(|i| r[i] * z[i]).sum();
        let mut it = 0;
        while it < params.max_iterations {
            let rn = r.iter().map(|v| v * v).sum::<f64>().sqrt();
            if rn <= params.tolerance * norm_b {
                break;
            }
            apply_a(&p, &mut tmp, &mut ax);
            let pap: f64 = (0..n).map(|i| p[i] * ax[i]).sum();
            if pap.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            let alpha = rz / pap;
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * ax[i];
                z[i] = r[i] / diag[i];
            }
            let rz_new: f64 = (0..n).map(|i| r[i] * z[i]).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
            it += 1;
        }
        (x, it)
    };
    let ((xa, ia), (xb, ib)) = rayon::join(|| solve(0), || solve(1));
    for j in 0..=k {
        for l in 0..n_cells {
            tv.frames[j][l] = [xa[idx(l, j)], xb[idx(l, j)]];
        }
    }
    tv.iterations = ia.max(ib);
    Some(tv)
}
