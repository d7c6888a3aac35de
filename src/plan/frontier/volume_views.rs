//! Volume views: what GREEDY and THP look at before calling the map complete, once no frontier is
//! left (`additions.volume_views`; not in any paper). Views are scored by NBV-TSP's gain model
//! ([`crate::plan::view_gain::GainModel`]).

use crate::config::{CameraConfig, Config, NbvConfig};
use crate::grid::GridSpec;
use crate::map::Map;
use crate::plan::search::DistanceField;
use crate::plan::view_gain::{attenuation, FanTemplate, GainModel};
use crate::plan::Count;
use rayon::prelude::*;

/// Radius around a volume view within which no other view is taken, metres: about the robot's
/// diameter. Views are taken once each: whatever a view still shows after the robot stood there
/// and turned around is unknown it cannot see (inside furniture, behind a closed gap), and looking
/// again from beside it would only repeat the trip.
const VIEW_GIVE_UP_M: f64 = 0.5;

/// Added to a view's path cost when its gain is ranked per metre, so that a view at the robot's feet
/// does not win by its zero cost alone, metres.
const COST_OFFSET_M: f64 = 1.0;

/// Volume views: before calling the map complete, GREEDY and THP drive to the floor position with
/// the most expected unknown band volume per metre of path (gain ÷ (path cost + 1 m), NBV-TSP's gain
/// model [`GainModel`]) among those whose gain reaches `additions.volume_view_gain_cutoff_m3`, and turn once
/// there, until no such position is left. Ranked per metre rather than nearest first: on 33 real
/// plans that gave higher completeness for the same path (0.953 against 0.949, about 52 m both).
///
/// A 2D frontier is a floor cell beside unknown floor. The explored volume is 3D: with the camera
/// 0.6 m up and a 45° vertical field of view, the top of the 1.8 m band is seen only from 2.9 m
/// away or more, and space over and behind furniture only from some angles. A run that has reached
/// every 2D frontier can therefore still leave observable volume unseen; on real apartment plans
/// that was 5–8 % of it. This is not in the THP paper, nor in Yamauchi's GREEDY; it is a config
/// option (`additions.volume_views`), **on by default** for both: on the 66 plans of
/// `scenes/floorplans/` (GREEDY, scene spawn) it raised mean completeness from 0.916 to 0.956 for
/// about 26 m more path a run (+80 %). THP's rule for a mechanism the paper lacks is that it is on
/// by default only if it serves the paper's goal, a shorter path at similar completeness; the
/// benchmark measures completeness against what the camera can observe, and with both planners
/// taking the views their paths compare at the same ending.
#[derive(Clone)]
pub struct VolumeViews {
    model: GainModel,
    cutoff_m3: f64,
    /// Spacing of the candidate lattice, metres.
    spacing_m: f64,
    /// Floor cells no longer considered (near a view already taken).
    given_up: Vec<bool>,
    /// Views taken (`planner_stats.volume_views`).
    taken: Count,
    /// Per floor cell, its gain as of map frame `gains_frame` (NaN: never evaluated). A gain reads
    /// only the voxels within the camera's range, so it is reused until one of them changes: each
    /// call scores the whole lattice, and re-scoring all of it took about a second on
    /// `office_large` before the fan ([`FanTemplate`]), a few tenths since.
    gains: Vec<f64>,
    gains_frame: u32,
    /// The gain model's rays as voxel lists for the map's grid (made at the first call).
    fan: Option<FanTemplate>,
    /// Gains evaluated so far (not reported; tests read it).
    evaluated: usize,
}

/// What [`VolumeViews`] reads of the config: its switch and parameters in `[additions]`, and the
/// gain model's camera, height band and `nbv` keys.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeViewParams {
    /// `additions.volume_views`.
    pub enabled: bool,
    /// `additions.volume_view_gain_cutoff_m3`.
    pub gain_cutoff_m3: f64,
    /// `additions.volume_view_spacing_m`.
    pub spacing_m: f64,
    pub camera: CameraConfig,
    /// `map.band_min_m`, `map.band_max_m`.
    pub band_m: (f64, f64),
    pub nbv: NbvConfig,
}

impl From<&Config> for VolumeViewParams {
    fn from(cfg: &Config) -> Self {
        VolumeViewParams {
            enabled: cfg.additions.volume_views,
            gain_cutoff_m3: cfg.additions.volume_view_gain_cutoff_m3.get(),
            spacing_m: cfg.additions.volume_view_spacing_m.get(),
            camera: cfg.camera.clone(),
            band_m: (cfg.map.band_min_m, cfg.map.band_max_m),
            nbv: cfg.nbv.clone(),
        }
    }
}

/// A volume view: where to drive, and what the model expects to be seen there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeView {
    pub cell: usize,
    pub gain_m3: f64,
}

impl VolumeViews {
    /// Volume views with these parameters, or `None` when `additions.volume_views` is off.
    pub fn new(p: &VolumeViewParams) -> Option<Self> {
        p.enabled.then(|| VolumeViews {
            model: GainModel::new(&p.camera, p.band_m, &p.nbv),
            cutoff_m3: p.gain_cutoff_m3,
            spacing_m: p.spacing_m,
            given_up: Vec::new(),
            taken: Count::default(),
            gains: Vec::new(),
            gains_frame: 0,
            fan: None,
            evaluated: 0,
        })
    }

    /// The best view per metre (path cost by `df`; ties to the lower cell) among the traversable
    /// lattice cells `df` reaches, away from the views already taken, whose gain reaches the cutoff;
    /// the view is marked taken. `None` when there is none: the volume is done.
    pub fn next(&mut self, map: &Map, df: &DistanceField) -> Option<VolumeView> {
        let best = self
            .open(map, df)
            .into_iter()
            .map(|(cost, view)| (view.gain_m3 / (cost as f64 + COST_OFFSET_M), view))
            .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cell.cmp(&a.1.cell)))?
            .1;
        self.mark_taken(map.grid(), best.cell);
        Some(best)
    }

    /// The views still open, thinned for a tour: the open lattice views by decreasing gain (ties to
    /// the lower cell), each kept only if no kept one lies within `spacing_m`, at most `max` of
    /// them. Nothing is marked taken; [`VolumeViews::mark_taken`] does that for the one driven to.
    pub fn thinned(
        &mut self,
        map: &Map,
        df: &DistanceField,
        spacing_m: f64,
        max: usize,
    ) -> Vec<VolumeView> {
        let grid = *map.grid();
        let mut open: Vec<VolumeView> = self.open(map, df).into_iter().map(|v| v.1).collect();
        open.sort_by(|a, b| b.gain_m3.total_cmp(&a.gain_m3).then(a.cell.cmp(&b.cell)));
        let mut kept: Vec<VolumeView> = Vec::new();
        for v in open {
            if kept.len() == max {
                break;
            }
            let p = grid.center(grid.cell(v.cell));
            if kept
                .iter()
                .all(|k| (grid.center(grid.cell(k.cell)) - p).norm() > spacing_m)
            {
                kept.push(v);
            }
        }
        kept
    }

    /// The open views with their path costs: the traversable lattice cells `df` reaches, away from
    /// the views already taken, whose gain reaches the cutoff.
    fn open(&mut self, map: &Map, df: &DistanceField) -> Vec<(f32, VolumeView)> {
        let grid: GridSpec = *map.grid();
        self.fit_to(&grid);
        let s = ((self.spacing_m / grid.res).round() as usize).max(1);
        let candidates: Vec<(f32, usize)> = (0..grid.ny)
            .step_by(s)
            .flat_map(|y| (0..grid.nx).step_by(s).map(move |x| y * grid.nx + x))
            .filter(|&i| !self.given_up[i] && map.is_traversable(i))
            .filter_map(|i| df.cost_to(i).map(|cost| (cost, i)))
            .collect();
        self.refresh_gains(map, &candidates);
        candidates
            .into_iter()
            .filter(|&(_, cell)| self.gains[cell] >= self.cutoff_m3)
            .map(|(cost, cell)| {
                (
                    cost,
                    VolumeView {
                        cell,
                        gain_m3: self.gains[cell],
                    },
                )
            })
            .collect()
    }

    /// Brings the gains of `candidates` up to date with `map`: evaluates (in parallel) those never
    /// evaluated and those within the camera's range of a column that changed since the last call,
    /// and keeps the rest. The same gains as evaluating every candidate, whatever the thread count.
    /// A kept gain of a cell that is not a candidate this time is dropped by the same rule, so that
    /// a cell that is a candidate again later does not keep a gain from before changes it missed.
    fn refresh_gains(&mut self, map: &Map, candidates: &[(f32, usize)]) {
        let grid = *map.grid();
        let occ = map.occupancy();
        if self.gains.len() != grid.cells() || occ.frames() < self.gains_frame {
            // Another map (or a first call): nothing to keep.
            self.gains = vec![f64::NAN; grid.cells()];
        }
        // A ray reaches `max_range_m` horizontally at most; a cell more for rounding at its end.
        let reach = self.model.max_range_m / grid.res + 1.0;
        let changed = ChangedNear::new(&grid, &occ.columns_changed_after(self.gains_frame), reach);
        for (i, gain) in self.gains.iter_mut().enumerate() {
            if !gain.is_nan() && changed.any_within(&grid, i) {
                *gain = f64::NAN;
            }
        }
        let stale: Vec<usize> = candidates
            .iter()
            .map(|&(_, i)| i)
            .filter(|&i| self.gains[i].is_nan())
            .collect();
        if stale.is_empty() {
            self.gains_frame = occ.frames();
            return;
        }
        // Each voxel's attenuation once, rather than once per ray that crosses it.
        let mut table = vec![0.0; grid.voxels()];
        table
            .par_chunks_mut(grid.cells())
            .enumerate()
            .for_each(|(layer, out)| {
                let first = layer * grid.cells();
                for (j, a) in out.iter_mut().enumerate() {
                    *a = attenuation(occ, first + j);
                }
            });
        if !self.fan.as_ref().is_some_and(|f| f.fits(&grid)) {
            self.fan = FanTemplate::new(&self.model, &grid);
        }
        let (model, fan) = (&self.model, self.fan.as_ref());
        let fresh: Vec<f64> = stale
            .par_iter()
            .map(|&i| match fan {
                Some(fan) => model.evaluate_fan(&grid, fan, &table, i).volume_m3,
                None => {
                    let p = grid.center(grid.cell(i));
                    model.evaluate_with(&grid, |v| table[v], p).volume_m3
                }
            })
            .collect();
        for (&i, g) in stale.iter().zip(fresh) {
            self.gains[i] = g;
        }
        self.evaluated += stale.len();
        self.gains_frame = occ.frames();
    }

    /// The `volume_views` statistic of `views` (absent when views are off or none was taken).
    pub fn taken(views: &Option<VolumeViews>) -> Count {
        views.as_ref().map(|v| v.taken).unwrap_or_default()
    }

    /// Sizes the given-up marks to `grid` (all open) unless they already fit it.
    fn fit_to(&mut self, grid: &GridSpec) {
        if self.given_up.len() != grid.cells() {
            self.given_up = vec![false; grid.cells()];
        }
    }

    /// Marks the view at `cell` taken: counted, and the cells within [`VIEW_GIVE_UP_M`] of it no
    /// longer considered.
    pub fn mark_taken(&mut self, grid: &GridSpec, cell: usize) {
        self.fit_to(grid);
        self.taken.add(1.0);
        let c = grid.cell(cell);
        let p = grid.center(c);
        let r = (VIEW_GIVE_UP_M / grid.res).ceil() as i32;
        for dy in -r..=r {
            for dx in -r..=r {
                if let Some(j) = grid.checked_index(crate::grid::Cell::new(c.x + dx, c.y + dy)) {
                    if (grid.center(grid.cell(j)) - p).norm() <= VIEW_GIVE_UP_M {
                        self.given_up[j] = true;
                    }
                }
            }
        }
    }
}

/// Changed columns as prefix counts along each row: whether any lies within a disc around a cell,
/// in one lookup per row of the disc.
struct ChangedNear {
    /// Per row, `nx + 1` prefix counts.
    sums: Vec<u32>,
    /// Per row offset `0..=radius`, the disc's half-width in cells.
    half: Vec<i64>,
}

impl ChangedNear {
    /// The disc holds the cells whose nearest point lies within `radius` cells of the centre cell's
    /// centre.
    fn new(grid: &GridSpec, changed: &[bool], radius: f64) -> Self {
        let (nx, ny) = (grid.nx, grid.ny);
        let mut sums = vec![0u32; (nx + 1) * ny];
        for y in 0..ny {
            let row = &mut sums[y * (nx + 1)..(y + 1) * (nx + 1)];
            for x in 0..nx {
                row[x + 1] = row[x] + u32::from(changed[y * nx + x]);
            }
        }
        // From a cell centre, the nearest point of the cell `d` cells away is `d − ½` cells away.
        let gap = |d: i64| (d as f64 - 0.5).max(0.0);
        let rows = (0..).take_while(|&dy| gap(dy) <= radius);
        let half = rows
            .map(|dy| {
                let left = radius * radius - gap(dy) * gap(dy);
                (0..)
                    .take_while(|&dx| gap(dx) * gap(dx) <= left)
                    .last()
                    .unwrap_or(0)
            })
            .collect();
        ChangedNear { sums, half }
    }

    /// Whether a changed column lies within the disc around cell `i` (of `grid`, the one the
    /// table was built for).
    fn any_within(&self, grid: &GridSpec, i: usize) -> bool {
        let c = grid.cell(i);
        let (nx, ny) = (grid.nx as i64, grid.ny as i64);
        let (cx, cy) = (c.x as i64, c.y as i64);
        self.half.iter().zip(0i64..).any(|(&hw, dy)| {
            let x0 = (cx - hw).clamp(0, nx) as usize;
            let x1 = (cx + hw + 1).clamp(0, nx) as usize;
            let rows: &[i64] = if dy == 0 { &[cy] } else { &[cy - dy, cy + dy] };
            rows.iter().filter(|y| (0..ny).contains(*y)).any(|&y| {
                let row = &self.sums[y as usize * (grid.nx + 1)..];
                row[x1] > row[x0]
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testing::seen_from;
    use crate::plan::search::Search;
    use crate::plan::view_gain::testing::{floor_grid, half_scanned_room};
    use crate::scene::TriMesh;
    use crate::sensor::raycast::testing::push_box;
    use crate::sensor::raycast::MeshBvh;
    use crate::Pose2;
    use nalgebra::Point2;
    use rand::{Rng, SeedableRng};
    use std::f64::consts::TAU;

    /// Volume views on a 0.5 m lattice (fewer candidates than the default, for a quick test).
    fn views_with_cutoff(cutoff_m3: f64) -> Option<VolumeViews> {
        let mut cfg = Config::default();
        cfg.additions.volume_views = true;
        cfg.additions.volume_view_gain_cutoff_m3 = cutoff_m3.try_into().unwrap();
        cfg.additions.volume_view_spacing_m = 0.5.try_into().unwrap();
        VolumeViews::new(&VolumeViewParams::from(&cfg))
    }

    /// Views come out until none is left: each reaches the cutoff, lies on known floor the robot
    /// reaches, and is at least 0.5 m from every earlier one; the sequence ends (each view takes
    /// candidates away). The same sequence comes out with one thread and with two.
    #[test]
    fn views_reach_the_cutoff_stay_apart_and_run_out() {
        let cfg = Config::default();
        let (map, df) = half_scanned_room(&cfg);
        let grid = *map.grid();
        let run = |threads: usize| {
            crate::util::on_threads(threads, || {
                let mut views =
                    views_with_cutoff(cfg.additions.volume_view_gain_cutoff_m3.get()).unwrap();
                std::iter::from_fn(|| views.next(&map, &df))
                    .take(10_000)
                    .collect::<Vec<_>>()
            })
        };
        let one = run(1);
        assert!(!one.is_empty(), "the band's top near the walls is unknown");
        assert!(one.len() < 10_000, "views ran out");
        for (k, v) in one.iter().enumerate() {
            assert!(v.gain_m3 >= cfg.additions.volume_view_gain_cutoff_m3.get());
            assert!(map.is_traversable(v.cell) && df.cost_to(v.cell).is_some());
            let p = grid.center(grid.cell(v.cell));
            for w in &one[..k] {
                let q = grid.center(grid.cell(w.cell));
                assert!((p - q).norm() > VIEW_GIVE_UP_M, "{p} too near {q}");
            }
        }
        assert_eq!(one, run(2));
    }

    /// The thinned views are the open views (those `next` would rank) taken greedily by gain: in
    /// decreasing gain, pairwise farther apart than the spacing, every open view within the spacing
    /// of a kept one of at least its gain, capped in number; nothing is marked taken until
    /// `mark_taken`, which removes the views around that cell from the next call.
    #[test]
    fn thinned_views_are_the_open_ones_by_gain_and_apart() {
        let cfg = Config::default();
        let (map, df) = half_scanned_room(&cfg);
        let grid = *map.grid();
        let mut views = views_with_cutoff(cfg.additions.volume_view_gain_cutoff_m3.get()).unwrap();
        let at = |v: &VolumeView| grid.center(grid.cell(v.cell));
        let open: Vec<VolumeView> = views.open(&map, &df).into_iter().map(|v| v.1).collect();
        let kept = views.thinned(&map, &df, 1.0, usize::MAX);
        assert!(
            kept.len() >= 2 && kept.len() < open.len(),
            "{} of {}",
            kept.len(),
            open.len()
        );
        for (k, v) in kept.iter().enumerate() {
            assert!(open.contains(v));
            for w in &kept[..k] {
                assert!(w.gain_m3 >= v.gain_m3);
                assert!((at(v) - at(w)).norm() > 1.0);
            }
        }
        for v in &open {
            assert!(
                kept.iter()
                    .any(|w| w.gain_m3 >= v.gain_m3 && (at(v) - at(w)).norm() <= 1.0 + 1e-9),
                "{v:?} neither kept nor covered"
            );
        }
        assert_eq!(views.thinned(&map, &df, 1.0, 1), kept[..1]);
        assert_eq!(
            views.thinned(&map, &df, 1.0, usize::MAX),
            kept,
            "nothing taken yet"
        );
        views.mark_taken(&grid, kept[0].cell);
        let after = views.thinned(&map, &df, 1.0, usize::MAX);
        assert!(after
            .iter()
            .all(|v| (at(v) - at(&kept[0])).norm() > VIEW_GIVE_UP_M));
        assert_eq!(views.taken.get(), Some(1.0));
    }

    /// A 14 m × 4 m corridor seen from x = −5 and x = 0 (turning once at each), its distance field
    /// from the west end, and the scene to take more frames of.
    fn corridor_seen_from_the_west(cfg: &Config) -> (GridSpec, MeshBvh, Map, DistanceField) {
        let grid = floor_grid(cfg, 8.0);
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [-9.0, -9.0, -0.1], [9.0, 9.0, 0.0]);
        push_box(&mut mesh, [-7.1, -2.1, 0.0], [7.1, -2.0, 2.0]);
        push_box(&mut mesh, [-7.1, 2.0, 0.0], [7.1, 2.1, 2.0]);
        push_box(&mut mesh, [-7.1, -2.1, 0.0], [-7.0, 2.1, 2.0]);
        push_box(&mut mesh, [7.0, -2.1, 0.0], [7.1, 2.1, 2.0]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let around = |x: f64| (0..32).map(move |i| Pose2::new(x, 0.0, i as f64 * TAU / 32.0));
        let map = seen_from(grid, cfg, &bvh, around(-5.0).chain(around(0.0)));
        let df = corridor_field(&grid, &map, |_| true);
        (grid, bvh, map, df)
    }

    /// The distance field from the corridor's west end over the traversable cells `keep` accepts.
    fn corridor_field(grid: &GridSpec, map: &Map, keep: impl Fn(usize) -> bool) -> DistanceField {
        let start = grid.index(grid.cell_of(Point2::new(-5.0, 1.0)).unwrap());
        assert!(map.is_traversable(start));
        Search::new(grid).distance_field(
            grid,
            |i| (map.is_traversable(i) && keep(i)).then_some(0.1),
            start,
            f32::INFINITY,
        )
    }

    /// Eight frames at the corridor's east end, turning once: they change the map there only.
    fn look_around_the_east_end(cfg: &Config, bvh: &MeshBvh, map: &mut Map) {
        let cam = crate::sensor::DepthCamera::new(&cfg.camera);
        for i in 0..8 {
            map.integrate(&cam.capture(bvh, Pose2::new(5.0, 0.0, i as f64 * TAU / 8.0)));
        }
    }

    /// Gains kept from an earlier call are the gains a fresh evaluation gives: in a 14 m long room,
    /// after new frames at the east end, a second view comes out the same as from views that
    /// evaluate every candidate again, every candidate's gain is the same to the bit, and those out
    /// of the camera's range of every changed column were not evaluated again.
    #[test]
    fn gains_kept_between_calls_equal_fresh_ones() {
        let cfg = Config::default();
        let (grid, bvh, mut map, df) = corridor_seen_from_the_west(&cfg);
        let mut kept = views_with_cutoff(0.01).unwrap();
        assert!(kept.next(&map, &df).is_some());
        let first = kept.evaluated;
        look_around_the_east_end(&cfg, &bvh, &mut map);
        let mut fresh = kept.clone();
        fresh.gains.clear();
        let (a, b) = (kept.next(&map, &df), fresh.next(&map, &df));
        assert!(a.is_some());
        assert_eq!(a, b);
        for i in (0..grid.cells()).filter(|&i| !fresh.gains[i].is_nan()) {
            assert_eq!(
                kept.gains[i].to_bits(),
                fresh.gains[i].to_bits(),
                "cell {i}"
            );
        }
        let (again, all) = (kept.evaluated - first, fresh.evaluated - first);
        assert!(
            again < all,
            "nothing was kept: {again} of {all} evaluated again"
        );
    }

    /// A cell whose gain was kept, and that was out of the candidates (out of the distance field's
    /// reach) when the map changed near it, gets the gain of the changed map once it is a candidate
    /// again, not the one from before.
    #[test]
    fn a_gain_out_of_reach_when_the_map_changed_is_evaluated_again() {
        let cfg = Config::default();
        let (grid, bvh, mut map, df) = corridor_seen_from_the_west(&cfg);
        let mut kept = views_with_cutoff(0.01).unwrap();
        let east = |i: usize| grid.center(grid.cell(i)).x > 3.0;
        let before: Vec<(usize, f64)> = kept
            .open(&map, &df)
            .iter()
            .map(|(_, v)| (v.cell, v.gain_m3))
            .filter(|&(i, _)| east(i))
            .collect();
        assert!(!before.is_empty());
        look_around_the_east_end(&cfg, &bvh, &mut map);
        let west_only = corridor_field(&grid, &map, |i| !east(i));
        assert!(kept
            .open(&map, &west_only)
            .iter()
            .all(|(_, v)| !east(v.cell)));
        let df = corridor_field(&grid, &map, |_| true);
        kept.open(&map, &df);
        let mut fresh = kept.clone();
        fresh.gains.clear();
        fresh.open(&map, &df);
        let mut moved = 0;
        for &(i, old) in &before {
            assert_eq!(
                kept.gains[i].to_bits(),
                fresh.gains[i].to_bits(),
                "cell {i}"
            );
            moved += usize::from(fresh.gains[i] != old);
        }
        assert!(moved > 0, "the frames changed no gain east");
    }

    /// The disc of changed columns finds exactly the cells with a changed column whose nearest
    /// point lies within the radius of the cell's centre (brute force over every pair), near the
    /// grid's edges too.
    #[test]
    fn changed_columns_are_found_within_the_disc() {
        let grid = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(2.4, 1.9), 2.0, 0.1);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let changed: Vec<bool> = (0..grid.cells()).map(|_| rng.random_bool(0.01)).collect();
        for radius in [0.0, 1.0, 3.7, 6.0, 51.0] {
            let near = ChangedNear::new(&grid, &changed, radius);
            for i in 0..grid.cells() {
                let p = grid.center(grid.cell(i));
                let want = (0..grid.cells()).filter(|&j| changed[j]).any(|j| {
                    // The nearest point of cell j's square to p.
                    let q = grid.center(grid.cell(j));
                    let h = 0.5 * grid.res;
                    let d =
                        Point2::new(p.x.clamp(q.x - h, q.x + h), p.y.clamp(q.y - h, q.y + h)) - p;
                    d.norm() <= radius * grid.res + 1e-9
                });
                assert_eq!(near.any_within(&grid, i), want, "cell {i}, radius {radius}");
            }
        }
    }

    /// A cutoff no view reaches ends the volume views at once; switched off, there are none (on by
    /// default).
    #[test]
    fn a_cutoff_out_of_reach_or_switching_off_gives_no_view() {
        let mut cfg = Config::default();
        let (map, df) = half_scanned_room(&cfg);
        assert_eq!(views_with_cutoff(1e6).unwrap().next(&map, &df), None);
        assert!(VolumeViews::new(&VolumeViewParams::from(&cfg)).is_some());
        cfg.additions.volume_views = false;
        assert!(VolumeViews::new(&VolumeViewParams::from(&cfg)).is_none());
    }
}
