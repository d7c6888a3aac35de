//! What a camera at a floor position would see of the unknown: NBV-TSP's volumetric gain model
//! (Meng et al., "A two-stage optimized next-view planning framework for 3-D unknown environment
//! exploration, and structural reconstruction", RA-L 2017, Eq. 4–6), shared with the volume views
//! that GREEDY and THP take before calling the map complete (`plan::frontier::VolumeViews`).

use crate::config::{CameraConfig, NbvConfig};
use crate::grid::{Cell, GridSpec};
use crate::map::occupancy::{traverse_while, Occupancy, VoxelState};
use crate::map::Map;
use nalgebra::{Point2, Point3, Vector3};
use std::f64::consts::TAU;
use std::ops::Range;

/// Rays stop contributing once their visibility falls below this.
const MIN_VISIBILITY: f64 = 1e-3;

/// What voxel `v` does to a ray's log-visibility, as one number: NaN if Unknown; if Free,
/// ln(1 − p) = −ln(1 + e^l) for log-odds l, added per visibility length crossed (negative); if
/// Occupied, −ln(1 − p) = ln(1 + e^l), subtracted once (positive).
pub(crate) fn attenuation(occ: &Occupancy, v: usize) -> f64 {
    let ln_odds_1p = || (occ.log_odds(v) as f64).exp().ln_1p();
    match occ.state(v) {
        VoxelState::Unknown => f64::NAN,
        VoxelState::Free => -ln_odds_1p(),
        VoxelState::Occupied => ln_odds_1p(),
    }
}

/// The coarse ray fan of the gain model (all yaws at once) and its constants.
#[derive(Clone)]
pub(crate) struct GainModel {
    /// Azimuth columns over the full circle.
    pub n_az: usize,
    /// Columns in one field of view (the window whose best sum picks the yaw).
    window: usize,
    /// Per azimuth column, the (cos, sin) of its azimuth: computed once, not per ray.
    az_dirs: Vec<(f64, f64)>,
    /// Per elevation row: (sin, cos) of the elevation and the row's solid-angle weight per column.
    pub rows: Vec<(f64, f64, f64)>,
    pub mount_m: f64,
    min_range_m: f64,
    pub max_range_m: f64,
    /// Height band of the explored volume, metres.
    band_m: (f64, f64),
    /// `1 / nbv.visibility_length_m`.
    inv_l: f64,
    /// ln ½ per visibility length: what an unknown voxel (unoccupancy ½) does per metre.
    ln_half_per_m: f64,
    /// ln [`MIN_VISIBILITY`].
    ln_min_visibility: f64,
    cover_min_visibility: f64,
}

/// A ray's running state while its voxels are added up ([`GainModel::absorb`]).
#[derive(Default)]
struct RayWalk {
    /// Natural log of the visibility so far.
    ln_vis: f64,
    /// Σ p·vis·t²·dt so far.
    sum: f64,
}

/// A viewpoint's predicted observation.
pub(crate) struct Gain {
    /// Expected unknown volume seen from the best yaw, m³ (Eq. 6).
    pub volume_m3: f64,
    pub yaw: f64,
}

impl GainModel {
    /// The fan of `camera` with every `nbv.gain_ray_stride`-th ray, counting unknown voxels in the
    /// height band `band_m`.
    pub fn new(camera: &CameraConfig, band_m: (f64, f64), nbv: &NbvConfig) -> Self {
        let c = camera;
        let stride = nbv.gain_ray_stride;
        let cols = c.width.div_ceil(stride).max(1);
        let rows = c.height.div_ceil(stride).max(1);
        let hfov = c.hfov_deg.to_radians();
        let vfov = c.vfov_deg.to_radians();
        let n_az = ((TAU / (hfov / cols as f64)).round() as usize).max(1);
        let d_az = TAU / n_az as f64;
        let window = ((hfov / d_az).round() as usize).clamp(1, n_az);
        let d_el = vfov / rows as f64;
        let rows = (0..rows)
            .map(|k| {
                let el = -0.5 * vfov + (k as f64 + 0.5) * d_el;
                (el.sin(), el.cos(), d_az * d_el * el.cos())
            })
            .collect();
        let az_dirs = (0..n_az)
            .map(|a| {
                let az = (a as f64 + 0.5) * TAU / n_az as f64;
                (az.cos(), az.sin())
            })
            .collect();
        let inv_l = 1.0 / nbv.visibility_length_m;
        GainModel {
            n_az,
            window,
            az_dirs,
            rows,
            mount_m: c.mount_height_m.get(),
            min_range_m: c.min_range_m.get(),
            max_range_m: c.max_range_m.get(),
            band_m,
            inv_l,
            ln_half_per_m: 0.5f64.ln() * inv_l,
            ln_min_visibility: MIN_VISIBILITY.ln(),
            cover_min_visibility: nbv.cover_min_visibility,
        }
    }

    /// Casts one ray from `origin` at azimuth `az` and elevation row `k`; calls
    /// `visit(cell, ln_vis)` for each voxel it enters with visibility at or above the cutoff (the
    /// natural log of the visibility); returns Σ p·vis·t²·dt over the unknown voxels in the band
    /// (Eq. 4–5; times the row weight, the ray's solid angle).
    pub fn cast(
        &self,
        map: &Map,
        band: &Range<usize>,
        origin: Point3<f64>,
        az: f64,
        k: usize,
        visit: impl FnMut(usize, f64),
    ) -> f64 {
        let occ = map.occupancy();
        self.cast_with(
            occ.grid(),
            |v| attenuation(occ, v),
            band,
            origin,
            (az.cos(), az.sin()),
            k,
            visit,
        )
    }

    /// [`GainModel::cast`] at the azimuth whose cosine and sine are given, reading each voxel's
    /// [`attenuation`] through `att`, which may be a table of them (the same numbers, computed once
    /// for many casts). The walk ends where the visibility falls below [`MIN_VISIBILITY`].
    #[allow(clippy::too_many_arguments)]
    fn cast_with(
        &self,
        grid: &GridSpec,
        att: impl Fn(usize) -> f64,
        band: &Range<usize>,
        origin: Point3<f64>,
        (az_cos, az_sin): (f64, f64),
        k: usize,
        mut visit: impl FnMut(usize, f64),
    ) -> f64 {
        let layer_len = grid.cells();
        // The band as flat voxel indices (a layer is a contiguous run of them): a range test per
        // unknown voxel rather than an integer division.
        let band_v = band.start * layer_len..band.end * layer_len;
        let mut walk = RayWalk::default();
        traverse_while(
            grid,
            origin,
            self.ray_dir(az_cos, az_sin, k),
            self.max_range_m,
            |v, t_in, t_out| {
                visit(v % layer_len, walk.ln_vis);
                self.absorb(&mut walk, &band_v, v, t_in, t_out, att(v))
            },
        );
        walk.sum
    }

    /// The unit direction of the ray at the azimuth whose cosine and sine are given, in row `k`.
    fn ray_dir(&self, az_cos: f64, az_sin: f64, k: usize) -> Vector3<f64> {
        let (s_el, c_el, _) = self.rows[k];
        Vector3::new(c_el * az_cos, c_el * az_sin, s_el)
    }

    /// Adds voxel `v` (attenuation `a`, entered at ray distance `t_in` and left at `t_out`) to a
    /// ray's walk; whether the ray goes on (its visibility is still at least [`MIN_VISIBILITY`]).
    ///
    /// The visibility is carried as its logarithm: a free voxel then costs a multiply-add rather
    /// than an `exp` (nine in ten voxels a ray crosses are free), and `exp` is taken only where an
    /// unknown voxel in the band (`band_v`, flat voxel indices) adds to the sum.
    #[inline(always)]
    fn absorb(
        &self,
        walk: &mut RayWalk,
        band_v: &Range<usize>,
        v: usize,
        t_in: f64,
        t_out: f64,
        a: f64,
    ) -> bool {
        let seg = t_out - t_in;
        // Free first (most voxels); ±0 (never in the table) would leave `ln_vis` as it is in
        // either known branch.
        if a < 0.0 {
            // Free: `a` = ln(1 − p) per visibility length.
            walk.ln_vis += a * seg * self.inv_l;
        } else if a >= 0.0 {
            // Occupied: `a` = −ln(1 − p).
            walk.ln_vis -= a;
        } else {
            // Unknown (NaN).
            let t_from = t_in.max(self.min_range_m);
            if t_out > t_from && band_v.contains(&v) {
                // Midpoint rule over the part of the voxel beyond the minimum range.
                let t = 0.5 * (t_from + t_out);
                let vis_mid = (walk.ln_vis + self.ln_half_per_m * (t - t_in)).exp();
                walk.sum += 0.5 * vis_mid * t * t * (t_out - t_from);
            }
            walk.ln_vis += self.ln_half_per_m * seg;
        }
        walk.ln_vis >= self.ln_min_visibility
    }

    /// [`GainModel::cast_with`] for the ray `ray` of `fan` from the centre of floor cell
    /// `(cx, cy)`, reading attenuations from `table`. With `CHECKED`, the walk also ends where the
    /// ray leaves the grid sideways (needed within the fan's reach of the grid's edge).
    fn cast_fan<const CHECKED: bool>(
        &self,
        fan: &FanTemplate,
        ray: usize,
        table: &[f64],
        band_v: &Range<usize>,
        (cx, cy): (i32, i32),
    ) -> f64 {
        let base = cy as i64 * fan.nx as i64 + cx as i64;
        let mut walk = RayWalk::default();
        for s in &fan.steps[fan.rays[ray] as usize..fan.rays[ray + 1] as usize] {
            if CHECKED {
                let (x, y) = (cx + i32::from(s.dx), cy + i32::from(s.dy));
                if x < 0 || y < 0 || x >= fan.nx as i32 || y >= fan.ny as i32 {
                    break;
                }
            }
            let v = (base + i64::from(s.offset)) as usize;
            if !self.absorb(&mut walk, band_v, v, s.t_in, s.t_out, table[v]) {
                break;
            }
        }
        walk.sum
    }

    /// The best-yaw gain at `p` (Eq. 6 over one field of view, best of `n_az` yaws).
    pub fn evaluate(&self, map: &Map, p: Point2<f64>) -> Gain {
        let occ = map.occupancy();
        self.evaluate_with(occ.grid(), |v| attenuation(occ, v), p)
    }

    /// [`GainModel::evaluate`] reading the voxels' [`attenuation`] through `att`.
    pub(crate) fn evaluate_with(
        &self,
        grid: &GridSpec,
        att: impl Fn(usize) -> f64,
        p: Point2<f64>,
    ) -> Gain {
        let band = grid.layers_in(self.band_m.0, self.band_m.1);
        let origin = Point3::new(p.x, p.y, self.mount_m);
        self.best_window(|a, k| {
            self.cast_with(grid, &att, &band, origin, self.az_dirs[a], k, |_, _| {})
        })
    }

    /// The gain at the centre of floor cell `cell` of `grid` (the grid `fan` was made for),
    /// reading the voxels' attenuations from `table`: [`GainModel::evaluate`] up to rounding in
    /// the last bits of the ray distances (see [`FanTemplate`]).
    pub(crate) fn evaluate_fan(
        &self,
        grid: &GridSpec,
        fan: &FanTemplate,
        table: &[f64],
        cell: usize,
    ) -> Gain {
        let band = grid.layers_in(self.band_m.0, self.band_m.1);
        let band_v = band.start * grid.cells()..band.end * grid.cells();
        let c = grid.cell(cell);
        let inside = |v: i32, n: usize| v >= fan.reach_cells && v + fan.reach_cells < n as i32;
        let rows = self.rows.len();
        if inside(c.x, grid.nx) && inside(c.y, grid.ny) {
            self.best_window(|a, k| {
                self.cast_fan::<false>(fan, a * rows + k, table, &band_v, (c.x, c.y))
            })
        } else {
            self.best_window(|a, k| {
                self.cast_fan::<true>(fan, a * rows + k, table, &band_v, (c.x, c.y))
            })
        }
    }

    /// Eq. 6 from the rays' sums (`cast(a, k)` is the sum of the ray at azimuth column `a`, row
    /// `k`): the best circular window of `window` columns, ties to the lowest start.
    fn best_window(&self, cast: impl Fn(usize, usize) -> f64) -> Gain {
        let cols: Vec<f64> = (0..self.n_az)
            .map(|a| {
                (0..self.rows.len())
                    .map(|k| self.rows[k].2 * cast(a, k))
                    .sum()
            })
            .collect();
        let mut sum: f64 = cols[..self.window].iter().sum();
        let (mut best, mut best_start) = (sum, 0);
        for s in 1..self.n_az {
            sum += cols[(s + self.window - 1) % self.n_az] - cols[s - 1];
            if sum > best + 1e-12 {
                (best, best_start) = (sum, s);
            }
        }
        let mid = best_start as f64 + 0.5 * self.window as f64 - 0.5;
        Gain {
            volume_m3: best.max(0.0),
            yaw: (mid + 0.5) * TAU / self.n_az as f64,
        }
    }

    /// The floor cells the rays of yaw `yaw` reach with visibility ≥ `cover_min_visibility`.
    pub fn covered(&self, map: &Map, p: Point2<f64>, yaw: f64) -> Vec<u32> {
        let band = map.grid().layers_in(self.band_m.0, self.band_m.1);
        let origin = Point3::new(p.x, p.y, self.mount_m);
        let d_az = TAU / self.n_az as f64;
        let ln_cover = self.cover_min_visibility.ln();
        let mut out = Vec::new();
        for w in 0..self.window {
            let az = yaw + (w as f64 - 0.5 * (self.window as f64 - 1.0)) * d_az;
            for k in 0..self.rows.len() {
                self.cast(map, &band, origin, az, k, |cell, ln_vis| {
                    if ln_vis >= ln_cover {
                        out.push(cell as u32);
                    }
                });
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// The voxels each ray of a [`GainModel`]'s fan passes from the centre of a floor cell, relative
/// to that cell, made once per grid shape. A view's gain then reads its rays' voxels from these
/// lists rather than stepping through the grid ray by ray: the volume views score every lattice
/// cell of the map at each view, tens of millions of voxel steps, and the stepping's branches cost
/// more than the sums.
///
/// The lists come from the same traversal ([`traverse_while`]) from the centre of a cell of a grid
/// of the same resolution and height, wide enough that no ray leaves it sideways. From a cell of
/// the real grid the voxels are the same, and the ray distances the same up to their last bits:
/// the traversal works in world coordinates, where the cells' centres round differently. (A ray
/// passing within that rounding of a voxel's edge could pass another voxel there; on the shipped
/// scenes and the 66 floor plans no run's result moved.)
#[derive(Clone)]
pub(crate) struct FanTemplate {
    /// The grid shape the offsets are for: resolution, `nx`, `ny`, `nz`.
    res: f64,
    nx: usize,
    ny: usize,
    nz: usize,
    /// Per ray (azimuth column `a`, row `k` at `a · rows + k`), its steps: `steps[rays[r]..rays[r + 1]]`.
    rays: Vec<u32>,
    steps: Vec<FanStep>,
    /// The largest sideways offset of any step, cells: from a cell at least this far inside the
    /// grid's edges no ray leaves the grid sideways.
    reach_cells: i32,
}

/// One voxel of a ray in a [`FanTemplate`].
#[derive(Clone, Copy)]
struct FanStep {
    /// Flat voxel index relative to the start cell's (layer 0): `layer · cells + dy · nx + dx`.
    offset: i32,
    dx: i16,
    dy: i16,
    /// Ray distances at which the ray enters and leaves the voxel, metres.
    t_in: f64,
    t_out: f64,
}

impl FanTemplate {
    /// The fan of `model` for grids shaped like `grid`, or `None` when the grid is too large for
    /// 32-bit offsets (about 2·10⁹ voxels; the gains are then cast ray by ray).
    pub(crate) fn new(model: &GainModel, grid: &GridSpec) -> Option<Self> {
        let half = (model.max_range_m / grid.res).ceil() as usize + 2;
        let wide = GridSpec {
            origin_x: -((half as f64) * grid.res),
            origin_y: -((half as f64) * grid.res),
            res: grid.res,
            nx: 2 * half + 1,
            ny: 2 * half + 1,
            nz: grid.nz,
        };
        let centre = wide.center(Cell::new(half as i32, half as i32));
        let origin = Point3::new(centre.x, centre.y, model.mount_m);
        let (nx, cells) = (
            i64::try_from(grid.nx).ok()?,
            i64::try_from(grid.cells()).ok()?,
        );
        let mut rays = vec![0u32];
        let mut steps = Vec::new();
        let mut reach_cells = 0;
        for &(c, s) in &model.az_dirs {
            for k in 0..model.rows.len() {
                let mut bad = false;
                traverse_while(
                    &wide,
                    origin,
                    model.ray_dir(c, s, k),
                    model.max_range_m,
                    |v, t_in, t_out| {
                        let (cell, layer) = wide.voxel_parts(v);
                        let at = wide.cell(cell);
                        let (dx, dy) = (at.x - half as i32, at.y - half as i32);
                        reach_cells = reach_cells.max(dx.abs()).max(dy.abs());
                        let offset = layer as i64 * cells + i64::from(dy) * nx + i64::from(dx);
                        match (i32::try_from(offset), i16::try_from(dx), i16::try_from(dy)) {
                            (Ok(offset), Ok(dx), Ok(dy)) => steps.push(FanStep {
                                offset,
                                dx,
                                dy,
                                t_in,
                                t_out,
                            }),
                            _ => bad = true,
                        }
                        !bad
                    },
                );
                if bad {
                    return None;
                }
                rays.push(u32::try_from(steps.len()).ok()?);
            }
        }
        Some(FanTemplate {
            res: grid.res,
            nx: grid.nx,
            ny: grid.ny,
            nz: grid.nz,
            rays,
            steps,
            reach_cells,
        })
    }

    /// Whether this fan was made for grids shaped like `grid`.
    pub(crate) fn fits(&self, grid: &GridSpec) -> bool {
        (self.res, self.nx, self.ny, self.nz) == (grid.res, grid.nx, grid.ny, grid.nz)
    }
}

#[cfg(test)]
mod tests {
    use super::testing::{floor_grid, half_scanned_room, scanned_room};
    use super::*;
    use crate::config::Config;
    use crate::map::testing::seen_from;
    use crate::scene::TriMesh;
    use crate::sensor::raycast::testing::push_box;
    use crate::sensor::raycast::MeshBvh;
    use crate::util::wrap_angle;
    use crate::Pose2;

    /// One horizontal-most ray through an all-unknown map: the voxel sum equals the closed form
    /// of Eq. 4–5 along the ray, ∫ p · e^(−a t) · t² dt from the camera's minimum range, with
    /// p = 0.5 and a = ln 2 / visibility_length_m (an unknown voxel has unoccupancy 0.5).
    #[test]
    fn ray_gain_in_unknown_space_matches_the_closed_form() {
        let cfg = Config::default();
        let map = Map::new(floor_grid(&cfg, 8.0), &cfg);
        let model = GainModel::new(
            &cfg.camera,
            (cfg.map.band_min_m, cfg.map.band_max_m),
            &cfg.nbv,
        );
        let band = map.grid().layers_in(cfg.map.band_min_m, cfg.map.band_max_m);
        let k = model.rows.len() / 2;
        let origin = Point3::new(0.03, 0.07, model.mount_m);
        let got = model.cast(&map, &band, origin, 0.3, k, |_, _| {});
        let a = 2f64.ln() / cfg.nbv.visibility_length_m;
        // ∫ t² e^(−a t) dt = −e^(−a t) (t²/a + 2t/a² + 2/a³).
        let anti = |t: f64| -(-a * t).exp() * (t * t / a + 2.0 * t / (a * a) + 2.0 / (a * a * a));
        let (t0, t1) = (cfg.camera.min_range_m.get(), cfg.camera.max_range_m.get());
        let want = 0.5 * (anti(t1) - anti(t0));
        assert!(
            (got - want).abs() <= 0.03 * want,
            "voxel sum {got} vs closed form {want}"
        );
    }

    /// Without any known voxel the gain exceeds the cutoff; in a walled room scanned all around it
    /// falls to under a tenth of that.
    #[test]
    fn unknown_map_gain_is_positive_and_known_free_space_has_none() {
        let cfg = Config::default();
        let grid = floor_grid(&cfg, 8.0);
        let map = Map::new(grid, &cfg);
        let model = GainModel::new(
            &cfg.camera,
            (cfg.map.band_min_m, cfg.map.band_max_m),
            &cfg.nbv,
        );
        let g = model.evaluate(&map, Point2::new(0.0, 0.0));
        assert!(g.volume_m3 > cfg.nbv.gain_cutoff_m3, "{}", g.volume_m3);
        // An empty 4 × 4 m room scanned all around from the centre: nothing unknown is left nearby.
        let map = scanned_room(&cfg, grid, 2.0, 2.0);
        let closed = model.evaluate(&map, Point2::new(0.0, 0.0));
        assert!(
            closed.volume_m3 < 0.1 * g.volume_m3,
            "{} vs {}",
            closed.volume_m3,
            g.volume_m3
        );
    }

    /// Facing a scanned wall, the best yaw looks elsewhere (the wall hides what lies behind it), and
    /// the covered cells of a yaw lie in front of the viewpoint, within the camera's range.
    #[test]
    fn best_yaw_avoids_a_wall_and_coverage_lies_in_view() {
        let cfg = Config::default();
        let grid = floor_grid(&cfg, 8.0);
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [-9.0, -9.0, -0.1], [9.0, 9.0, 0.0]);
        push_box(&mut mesh, [1.5, -4.0, 0.0], [1.6, 4.0, 2.5]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let map = seen_from(grid, &cfg, &bvh, [Pose2::new(0.0, 0.0, 0.0); 3]);
        let model = GainModel::new(
            &cfg.camera,
            (cfg.map.band_min_m, cfg.map.band_max_m),
            &cfg.nbv,
        );
        let g = model.evaluate(&map, Point2::new(0.0, 0.0));
        let half_fov = 0.5 * cfg.camera.hfov_deg.to_radians();
        assert!(
            wrap_angle(g.yaw).abs() >= half_fov,
            "best yaw {} should not face the wall at +x",
            g.yaw
        );
        let cov = model.covered(&map, Point2::new(0.0, 0.0), 0.0);
        assert!(!cov.is_empty());
        for &c in &cov {
            let p = grid.center(grid.cell(c as usize));
            let d = p.coords.norm();
            assert!(d <= cfg.camera.max_range_m.get() + grid.res, "{p}");
            if d > 0.3 {
                assert!(
                    p.y.atan2(p.x).abs() <= half_fov + 0.15,
                    "cell {p} outside the field of view"
                );
            }
        }
    }

    /// A grid whose origin is not a multiple of its resolution, as a scene's is.
    fn offset_grid(cfg: &Config) -> GridSpec {
        GridSpec::covering(
            Point2::new(-4.37, -2.93),
            Point2::new(7.21, 5.66),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        )
    }

    /// From cells in the middle and at every edge and corner of a grid, each ray of the fan lists
    /// the voxels the ray-by-ray traversal passes, in order and up to where it leaves the grid,
    /// with the same entry and exit distances up to rounding.
    #[test]
    fn fan_rays_pass_the_voxels_of_the_ray_by_ray_walk() {
        let cfg = Config::default();
        let grid = offset_grid(&cfg);
        let model = GainModel::new(
            &cfg.camera,
            (cfg.map.band_min_m, cfg.map.band_max_m),
            &cfg.nbv,
        );
        let fan = FanTemplate::new(&model, &grid).unwrap();
        assert!(fan.fits(&grid));
        let (nx, ny) = (grid.nx as i32, grid.ny as i32);
        let starts = [
            (nx / 2, ny / 2),
            (0, 0),
            (nx - 1, ny - 1),
            (0, ny / 3),
            (nx / 4, ny - 1),
            (nx - 2, 1),
        ];
        let rows = model.rows.len();
        for (cx, cy) in starts {
            let p = grid.center(Cell::new(cx, cy));
            let origin = Point3::new(p.x, p.y, model.mount_m);
            let base = (cy * nx + cx) as i64;
            for (a, &(c, s)) in model.az_dirs.iter().enumerate() {
                for k in 0..rows {
                    let mut walked = Vec::new();
                    traverse_while(
                        &grid,
                        origin,
                        model.ray_dir(c, s, k),
                        model.max_range_m,
                        |v, t_in, t_out| {
                            walked.push((v, t_in, t_out));
                            true
                        },
                    );
                    let r = a * rows + k;
                    let listed: Vec<(usize, f64, f64)> = fan.steps
                        [fan.rays[r] as usize..fan.rays[r + 1] as usize]
                        .iter()
                        .take_while(|st| {
                            let (x, y) = (cx + i32::from(st.dx), cy + i32::from(st.dy));
                            (0..nx).contains(&x) && (0..ny).contains(&y)
                        })
                        .map(|st| ((base + i64::from(st.offset)) as usize, st.t_in, st.t_out))
                        .collect();
                    assert_eq!(walked.len(), listed.len(), "cell ({cx}, {cy}), ray {r}");
                    for (w, l) in walked.iter().zip(&listed) {
                        assert_eq!(w.0, l.0, "cell ({cx}, {cy}), ray {r}");
                        assert!(
                            (w.1 - l.1).abs() < 1e-9 && (w.2 - l.2).abs() < 1e-9,
                            "{w:?} {l:?}"
                        );
                    }
                }
            }
        }
    }

    /// A gain read from the fan's voxel lists is the ray-by-ray gain up to rounding, from every
    /// cell of a half-scanned room's grid (the edges' cells too).
    #[test]
    fn fan_gains_are_the_ray_by_ray_gains() {
        let cfg = Config::default();
        let (map, _) = half_scanned_room(&cfg);
        let grid = *map.grid();
        let occ = map.occupancy();
        let model = GainModel::new(
            &cfg.camera,
            (cfg.map.band_min_m, cfg.map.band_max_m),
            &cfg.nbv,
        );
        let fan = FanTemplate::new(&model, &grid).unwrap();
        let table: Vec<f64> = (0..grid.voxels()).map(|v| attenuation(occ, v)).collect();
        let mut positive = 0;
        for i in (0..grid.cells()).step_by(7) {
            let want = model.evaluate(&map, grid.center(grid.cell(i)));
            let got = model.evaluate_fan(&grid, &fan, &table, i);
            assert!(
                (got.volume_m3 - want.volume_m3).abs() <= 1e-9 * want.volume_m3.max(1.0),
                "cell {i}"
            );
            assert_eq!(got.yaw, want.yaw, "cell {i}");
            positive += usize::from(want.volume_m3 > 0.01);
        }
        assert!(positive > 10, "only {positive} cells see unknown volume");
    }
}

/// Rooms and maps the gain model's and the volume views' tests share.
#[cfg(test)]
pub(crate) mod testing {
    use super::*;
    use crate::config::Config;
    use crate::map::testing::seen_from;
    use crate::plan::search::DistanceField;
    use crate::plan::search::Search;
    use crate::scene::TriMesh;
    use crate::sensor::raycast::testing::push_box;
    use crate::sensor::raycast::MeshBvh;
    use crate::Pose2;

    /// A square grid of half side `half` about the origin, at the map's resolution.
    pub(crate) fn floor_grid(cfg: &Config, half: f64) -> GridSpec {
        GridSpec::covering(
            Point2::new(-half, -half),
            Point2::new(half, half),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        )
    }

    /// A walled room of half extents `hx` × `hy` (2 m tall walls, 0.1 m thick) on a wide floor,
    /// scanned all around from its centre and from a 1 m circle about it.
    pub(crate) fn scanned_room(cfg: &Config, grid: GridSpec, hx: f32, hy: f32) -> Map {
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [-9.0, -9.0, -0.1], [9.0, 9.0, 0.0]);
        for (lo, hi) in [
            ([-hx, -hy - 0.1, 0.0], [hx, -hy, 2.0]),
            ([-hx, hy, 0.0], [hx, hy + 0.1, 2.0]),
            ([-hx - 0.1, -hy - 0.1, 0.0], [-hx, hy + 0.1, 2.0]),
            ([hx, -hy - 0.1, 0.0], [hx + 0.1, hy + 0.1, 2.0]),
        ] {
            push_box(&mut mesh, lo, hi);
        }
        let bvh = MeshBvh::new(&mesh).unwrap();
        seen_from(
            grid,
            cfg,
            &bvh,
            (0..64).map(|i| {
                let yaw = i as f64 * TAU / 32.0;
                let r = if i < 32 { 0.0 } else { 1.0 };
                Pose2::new(r * yaw.cos(), r * yaw.sin(), yaw)
            }),
        )
    }

    /// A 6 × 4 m room scanned from near its centre ([`scanned_room`]): the top of the band near the
    /// far walls stays unknown (seen only from 2.9 m away). With the robot's distance field over the
    /// known floor.
    pub(crate) fn half_scanned_room(cfg: &Config) -> (Map, DistanceField) {
        let grid = floor_grid(cfg, 5.0);
        let map = scanned_room(cfg, grid, 3.0, 2.0);
        // The known floor cell nearest the centre (the camera never saw the floor underfoot).
        let start = (0..grid.cells())
            .filter(|&i| map.is_traversable(i))
            .min_by(|&a, &b| {
                let d = |i: usize| grid.center(grid.cell(i)).coords.norm();
                d(a).total_cmp(&d(b)).then(a.cmp(&b))
            })
            .unwrap();
        let df = Search::new(&grid).distance_field(
            &grid,
            |i| map.is_traversable(i).then_some(0.1),
            start,
            f32::INFINITY,
        );
        (map, df)
    }
}
