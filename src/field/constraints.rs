//! Constraint points: incremental farthest-point sampling of the surface layer, tangents by PCA, and
//! polyline (path) constraints (THP Eq. 10).
//!
//! Incremental contract: [`SurfaceSampler::update`] takes the *whole* surface layer every key frame and
//! diffs it against the layer it saw last time. Samples never move: new samples are drawn only from
//! surface cells that no existing sample covers (within `d_s`), which after the first key frame are
//! only newly surfaced cells. A sample whose cell stops being surface is removed and the cells it
//! covered are sampled again. A sample's tangent is re-fitted when surface cells appear or vanish in
//! its PCA window, so that the field changes only near what changed.

use crate::grid::{Cell, CellRect, GridSpec};
use nalgebra::{Point2, Vector2};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// One basis field of THP Eq. 4/11: position, and the traceless tensor `ρ (cos 2θ, sin 2θ)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Constraint {
    pub pos: Point2<f64>,
    /// `ρ (cos 2θ, sin 2θ)`; exact zeros in `b` for axis-aligned tangents (see [`double_angle`]).
    pub tensor: [f64; 2],
    /// `ρ`.
    pub strength: f64,
    /// The fine-grid cell when the constraint sits exactly at that cell's centre (surface samples):
    /// lets the fast evaluator use exact integer offsets and a weight table.
    pub cell: Option<Cell>,
    /// Hard radius of influence, metres: the constraint counts only at points within it. Infinite
    /// for the map's constraints; σ for THP's path constraints (§3.5: "the global path given by A*
    /// can only modify the tensor field within its σ range").
    pub radius: f64,
}

impl Constraint {
    /// Whether the constraint has a finite radius of influence (a THP path constraint).
    pub fn is_limited(&self) -> bool {
        self.radius.is_finite()
    }

    /// Whether the constraint counts at `p` (within its radius of influence).
    pub fn counts_at(&self, p: Point2<f64>) -> bool {
        !self.is_limited() || (p - self.pos).norm_squared() <= self.radius * self.radius
    }

    /// A constraint whose major eigenvector is along `dir`, with strength `strength`.
    pub fn along(
        pos: Point2<f64>,
        dir: Vector2<f64>,
        strength: f64,
        cell: Option<Cell>,
    ) -> Option<Self> {
        let [c, s] = double_angle(dir.x, dir.y)?;
        Some(Constraint {
            pos,
            tensor: [strength * c, strength * s],
            strength,
            cell,
            radius: f64::INFINITY,
        })
    }

    /// Angle of the major eigenvector, in (-π/2, π/2].
    pub fn angle(&self) -> f64 {
        0.5 * self.tensor[1].atan2(self.tensor[0])
    }
}

/// `(cos 2θ, sin 2θ)` of the direction `(dx, dy)` computed without trigonometry, so that axis-aligned
/// directions give exactly `b = 0` (with `sin(π)` they would give 1.2e-16, which would decide the
/// sign of `b` on the degenerate curves of axis-aligned scenes).
pub fn double_angle(dx: f64, dy: f64) -> Option<[f64; 2]> {
    let n = dx * dx + dy * dy;
    (n > 0.0 && n.is_finite()).then(|| [(dx * dx - dy * dy) / n, 2.0 * dx * dy / n])
}

/// Constraints along a polyline (THP Eq. 10): points resampled every `d_s` of arc length, each with
/// the tangent `p_c - p_{c-1}` (the first uses `p_1 - p_0`) and strength `strength`, weighted by the
/// Gaussian of Eq. 11 like every other constraint and counting only within `radius` of themselves
/// (THP uses σ; `f64::INFINITY` for no limit).
pub fn path_constraints(
    path: &[Point2<f64>],
    d_s: f64,
    strength: f64,
    radius: f64,
) -> Vec<Constraint> {
    if path.len() < 2 || d_s.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Vec::new();
    }
    let mut samples = vec![path[0]];
    let mut carried = 0.0;
    for w in path.windows(2) {
        let seg = w[1] - w[0];
        let len = seg.norm();
        if len <= 0.0 {
            continue;
        }
        let mut s = d_s - carried;
        while s <= len {
            samples.push(w[0] + seg * (s / len));
            s += d_s;
        }
        carried = len - (s - d_s);
    }
    let last = *path.last().expect("non-empty");
    if (last - *samples.last().expect("non-empty")).norm() > 1e-9 {
        samples.push(last);
    }
    (0..samples.len())
        .filter_map(|c| {
            let (p, q) = if c == 0 {
                (samples[0], samples[1])
            } else {
                (samples[c - 1], samples[c])
            };
            Constraint::along(samples[c], q - p, strength, None).map(|c| Constraint { radius, ..c })
        })
        .collect()
}

/// What one [`SurfaceSampler::update`] changed, by sample id.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SampleChanges {
    pub added: Vec<u32>,
    pub removed: Vec<u32>,
    /// Existing samples whose tangent was re-fitted (their old constraint must be replaced).
    pub refitted: Vec<u32>,
}

#[derive(Clone, Debug)]
struct Sample {
    cell: Cell,
    constraint: Option<Constraint>,
}

const NO_SAMPLE: u32 = u32::MAX;

/// Incremental farthest-point sampler of the surface layer, with PCA tangents.
#[derive(Clone, Debug)]
pub struct SurfaceSampler {
    grid: GridSpec,
    d_s: f64,
    /// PCA window radius, cells.
    pca_radius_cells: i32,
    min_anisotropy: f64,
    surface: Vec<bool>,
    /// Holds every cell ever on the surface layer.
    surface_ever: CellRect,
    sample_at: Vec<u32>,
    samples: Vec<Option<Sample>>,
}

impl SurfaceSampler {
    pub fn new(grid: GridSpec, d_s: f64, tangent_radius_m: f64, min_anisotropy: f64) -> Self {
        SurfaceSampler {
            grid,
            d_s,
            pca_radius_cells: (tangent_radius_m / grid.res).round().max(1.0) as i32,
            min_anisotropy,
            surface: vec![false; grid.cells()],
            surface_ever: CellRect::EMPTY,
            sample_at: vec![NO_SAMPLE; grid.cells()],
            samples: Vec::new(),
        }
    }

    /// The constraint of sample `id` (None if removed or without a defined tangent).
    pub fn constraint(&self, id: u32) -> Option<Constraint> {
        self.samples
            .get(id as usize)
            .and_then(|s| s.as_ref())
            .and_then(|s| s.constraint)
    }

    /// Live samples: (id, cell).
    pub fn samples(&self) -> impl Iterator<Item = (u32, Cell)> + '_ {
        self.samples
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.as_ref().map(|s| (i as u32, s.cell)))
    }

    /// Diffs `surface` (one flag per cell of the grid, false outside `within`) against the last
    /// layer and samples what changed.
    pub fn update(&mut self, within: CellRect, surface: impl Fn(usize) -> bool) -> SampleChanges {
        let mut changes = SampleChanges::default();
        let mut changed_cells = Vec::new();
        // A cell that was on the surface may have left it outside `within`; in ascending order.
        let look = within.clip(&self.grid).union(self.surface_ever);
        for (c, idx) in look.cells(&self.grid) {
            let now = within.contains(c) && surface(idx);
            if now != self.surface[idx] {
                self.surface[idx] = now;
                changed_cells.push(idx);
                if now {
                    self.surface_ever.add(c);
                }
            }
        }
        if changed_cells.is_empty() {
            return changes;
        }
        // Remove samples on vanished cells; their neighbourhoods must be covered again.
        let reach = (self.d_s / self.grid.res).ceil() as i32;
        let mut candidates: Vec<usize> = Vec::new();
        for &idx in &changed_cells {
            if self.surface[idx] {
                candidates.push(idx);
            } else if self.sample_at[idx] != NO_SAMPLE {
                let id = self.sample_at[idx];
                self.sample_at[idx] = NO_SAMPLE;
                self.samples[id as usize] = None;
                changes.removed.push(id);
                let c = self.grid.cell(idx);
                self.for_disc(c, reach, |n| {
                    if self.surface[n] {
                        candidates.push(n);
                    }
                });
            }
        }
        candidates.sort_unstable();
        candidates.dedup();
        self.farthest_point_sample(&candidates, &mut changes.added);
        // Re-fit tangents of older samples whose PCA window changed.
        let mut touched = Vec::new();
        for &idx in &changed_cells {
            self.for_disc(self.grid.cell(idx), self.pca_radius_cells, |n| {
                let id = self.sample_at[n];
                if id != NO_SAMPLE {
                    touched.push(id);
                }
            });
        }
        touched.sort_unstable();
        touched.dedup();
        for id in touched {
            if changes.added.binary_search(&id).is_ok() {
                continue;
            }
            let cell = self.samples[id as usize].as_ref().expect("live").cell;
            let fitted = self.fit(cell);
            let s = self.samples[id as usize].as_mut().expect("live");
            if s.constraint != fitted {
                s.constraint = fitted;
                changes.refitted.push(id);
            }
        }
        changes
    }

    /// Calls `f` with the index of every in-grid cell within `r` cells (Euclidean) of `c`.
    fn for_disc(&self, c: Cell, r: i32, mut f: impl FnMut(usize)) {
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy <= r * r {
                    if let Some(i) = self.grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                        f(i);
                    }
                }
            }
        }
    }

    /// Distance from cell `c` to the nearest sample, capped at `cap` (searching within `cap`).
    fn nearest_sample_distance(&self, c: Cell, cap: f64) -> f64 {
        let r = (cap / self.grid.res).ceil() as i32;
        let mut best = cap;
        for dy in -r..=r {
            for dx in -r..=r {
                if let Some(i) = self.grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                    if self.sample_at[i] != NO_SAMPLE {
                        best = best.min(((dx * dx + dy * dy) as f64).sqrt() * self.grid.res);
                    }
                }
            }
        }
        best
    }

    /// Farthest-point sampling over `candidates` until every one lies within `d_s` of a sample.
    /// Distances are capped at 2·d_s (ties broken by the lower cell index), which keeps it local.
    fn farthest_point_sample(&mut self, candidates: &[usize], added: &mut Vec<u32>) {
        let cap = 2.0 * self.d_s;
        let covered = |d: f64| d < self.d_s - 1e-9;
        let mut heap: BinaryHeap<(u64, Reverse<usize>)> = BinaryHeap::new();
        for &idx in candidates {
            let d = self.nearest_sample_distance(self.grid.cell(idx), cap);
            if !covered(d) {
                heap.push((d.to_bits(), Reverse(idx)));
            }
        }
        while let Some((bits, Reverse(idx))) = heap.pop() {
            let stored = f64::from_bits(bits);
            let c = self.grid.cell(idx);
            let d = self.nearest_sample_distance(c, cap);
            if covered(d) {
                continue;
            }
            if d < stored {
                heap.push((d.to_bits(), Reverse(idx)));
                continue;
            }
            let id = self.samples.len() as u32;
            self.samples.push(Some(Sample {
                cell: c,
                constraint: None,
            }));
            self.sample_at[idx] = id;
            added.push(id);
        }
        // Tangents after all samples exist (they depend only on surface cells, not on other samples).
        for &id in added.iter() {
            let cell = self.samples[id as usize].as_ref().expect("live").cell;
            self.samples[id as usize].as_mut().expect("live").constraint = self.fit(cell);
        }
    }

    /// PCA of the surface cells within the window around `c`, in exact integer arithmetic: corners
    /// (an L of cells) get a diagonal tangent, straight axis-aligned walls exactly 0° or 90°.
    fn fit(&self, c: Cell) -> Option<Constraint> {
        let r = self.pca_radius_cells;
        let (mut n, mut sx, mut sy, mut sxx, mut syy, mut sxy) =
            (0i64, 0i64, 0i64, 0i64, 0i64, 0i64);
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy > r * r {
                    continue;
                }
                if let Some(i) = self.grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                    if self.surface[i] {
                        let (x, y) = (dx as i64, dy as i64);
                        n += 1;
                        sx += x;
                        sy += y;
                        sxx += x * x;
                        syy += y * y;
                        sxy += x * y;
                    }
                }
            }
        }
        if n < 2 {
            return None;
        }
        // n² × covariance, exact.
        let cxx = n * sxx - sx * sx;
        let cyy = n * syy - sy * sy;
        let cxy = n * sxy - sx * sy;
        let (da, db) = ((cxx - cyy) as f64, (2 * cxy) as f64);
        let trace = (cxx + cyy) as f64;
        let norm = (da * da + db * db).sqrt();
        if trace <= 0.0 || norm / trace < self.min_anisotropy {
            return None;
        }
        Some(Constraint {
            pos: self.grid.center(c),
            tensor: [da / norm, db / norm],
            strength: 1.0,
            cell: Some(c),
            radius: f64::INFINITY,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> GridSpec {
        GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(4.0, 4.0), 1.0, 0.1)
    }

    #[test]
    fn straight_wall_gets_exact_axis_tangent_and_spacing() {
        let g = grid();
        let mut s = SurfaceSampler::new(g, 0.2, 0.4, 0.05);
        let ch = s.update(CellRect::all(&g), |i| {
            g.cell(i).y == 20 && (5..35).contains(&g.cell(i).x)
        });
        assert!(ch.removed.is_empty());
        // 30 cells at 0.1 m sampled every 0.2 m: 15 samples.
        assert_eq!(ch.added.len(), 15);
        for &id in &ch.added {
            let c = s.constraint(id).unwrap();
            assert_eq!(c.tensor, [1.0, 0.0]);
        }
        let mut xs: Vec<i32> = s.samples().map(|(_, c)| c.x).collect();
        xs.sort();
        for w in xs.windows(2) {
            assert!(w[1] - w[0] >= 2, "{xs:?}");
        }
    }

    #[test]
    fn corner_gets_diagonal_tangent() {
        let g = grid();
        let mut s = SurfaceSampler::new(g, 0.2, 0.4, 0.05);
        let on = |i: usize| {
            let c = g.cell(i);
            (c.y == 10 && (10..30).contains(&c.x)) || (c.x == 10 && (10..30).contains(&c.y))
        };
        s.update(CellRect::all(&g), on);
        let corner = s
            .samples()
            .find(|(_, c)| *c == Cell::new(10, 10))
            .map(|(id, _)| id);
        // The corner cell is the lowest index, so FPS (ties by index) samples it first.
        let c = s.constraint(corner.unwrap()).unwrap();
        assert!(c.tensor[0].abs() < 1e-12);
        // Arms along +x and +y: major axis along (1, -1), i.e. 2θ = -90°.
        assert!((c.tensor[1] + 1.0).abs() < 1e-12, "{:?}", c.tensor);
    }

    #[test]
    fn incremental_keeps_old_samples_and_adds_only_new_ones() {
        let g = grid();
        let mut s = SurfaceSampler::new(g, 0.2, 0.4, 0.05);
        s.update(CellRect::all(&g), |i| {
            g.cell(i).y == 20 && (5..20).contains(&g.cell(i).x)
        });
        let before: Vec<(u32, Cell)> = s.samples().collect();
        let ch = s.update(CellRect::all(&g), |i| {
            g.cell(i).y == 20 && (5..35).contains(&g.cell(i).x)
        });
        let after: Vec<(u32, Cell)> = s.samples().collect();
        assert!(before.iter().all(|b| after.contains(b)));
        for &id in &ch.added {
            let c = after.iter().find(|(i, _)| *i == id).unwrap().1;
            assert!(c.x >= 20, "new sample on old surface at {c:?}");
        }
        // The sample at the old end saw its window grow, so it is the only re-fit candidate.
        assert!(ch.refitted.len() <= 2, "{:?}", ch.refitted);
        // Outside `within` no cell is surface, whatever the layer says: a narrower rectangle removes
        // the samples beyond it, and an empty one removes them all.
        let left = CellRect {
            min: Cell::new(0, 0),
            max: Cell::new(19, g.ny as i32 - 1),
        };
        let ch = s.update(left, |i| {
            g.cell(i).y == 20 && (5..35).contains(&g.cell(i).x)
        });
        assert!(!ch.removed.is_empty());
        assert!(s.samples().all(|(_, c)| c.x < 20));
        s.update(CellRect::EMPTY, |_| true);
        assert_eq!(s.samples().count(), 0);
    }

    #[test]
    fn path_constraints_follow_the_tangent() {
        let path = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(1.0, 1.0),
        ];
        let cs = path_constraints(&path, 0.2, 1.0, f64::INFINITY);
        assert_eq!(cs.len(), 11);
        assert_eq!(cs[1].tensor, [1.0, 0.0]);
        assert_eq!(cs[8].tensor, [-1.0, 0.0]);
        assert!((cs[8].pos - Point2::new(1.0, 0.6)).norm() < 1e-9);
        assert!(path_constraints(&path[..1], 0.2, 1.0, f64::INFINITY).is_empty());
    }
}
