//! What the robot could ever observe: the ceiling that completeness is measured against.
//!
//! **Observable set.** The height-band voxels that the configured depth camera marks as known (the
//! hit voxel of a valid ray, or a voxel a ray passes through) from some pose of the reachable
//! region (`GroundTruth::reachable`). It is computed under the same sensor model and voxel
//! traversal the map uses: the camera's own ray directions and range rule, `MeshBvh::cast`, and
//! `map::occupancy::traverse` (a test checks agreement with `Occupancy::integrate` frame by frame).
//!
//! **Sampling.** The reachable region is cut into squares of side `metrics.observable_spacing_m`; in
//! each square, every 8-connected patch of reachable cells gets one position, the patch cell nearest
//! its centroid (so a narrow corridor or an alcove that crosses no lattice point is still sampled).
//! At each position the camera looks along `metrics.observable_yaws` headings evenly spread over the
//! full turn (the robot turns in place, so every heading is reachable). A ray only matters while it
//! is inside the height band, so it is cast and traversed up to where it leaves the band; that gives
//! the same band voxels as a full-length ray (a ray leaves a horizontal slab once).
//!
//! **Cost and cache.** This costs seconds, so [`ObservableCache`] keeps one file per scene and the
//! config keys the set depends on, written atomically and checked on read (length, key and
//! checksum): a damaged file is recomputed and reported, never trusted.

use crate::config::Config;
use crate::grid::{Cell, GridSpec, NEIGHBOURS_8};
use crate::map::occupancy::traverse_while;
use crate::scene::{GroundTruth, Scene, VoxelTriangles};
use crate::sensor::{DepthCamera, MeshBvh};
use crate::util::fnv1a64;
use crate::{Error, Result};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The voxels the camera could observe from the reachable region.
#[derive(Clone, Debug, PartialEq)]
pub struct ObservableSet {
    /// One bit per voxel of the grid (flat voxel index); set only in the height band.
    bits: Vec<u64>,
    voxels: usize,
    /// Observable voxels that the ground truth marks occupied (observable surface), ascending.
    surface: Vec<u32>,
    /// Sampled positions (each seen from every heading).
    positions: usize,
    voxel_volume: f64,
}

/// The pose sampling, from the config (the sensor model is the `DepthCamera`'s).
#[derive(Clone, Debug, PartialEq)]
pub struct ObservableParams {
    pub spacing_m: f64,
    pub yaws: usize,
}

impl ObservableParams {
    pub fn from_config(cfg: &Config) -> Self {
        ObservableParams {
            spacing_m: cfg.metrics.observable_spacing_m,
            yaws: cfg.metrics.observable_yaws,
        }
    }
}

impl ObservableSet {
    /// Samples the camera over the reachable region of `gt` (see the module doc).
    pub fn compute(
        gt: &GroundTruth,
        bvh: &MeshBvh,
        camera: &DepthCamera,
        p: &ObservableParams,
    ) -> ObservableSet {
        let grid = gt.grid;
        let lists = gt.voxel_triangles();
        let band = gt.band_layers();
        let positions = sample_positions(&grid, gt.reachable_mask(), p.spacing_m);
        let words = grid.voxels().div_ceil(64);
        // The band as a z interval: a ray is cast and walked only while inside it.
        let (z_lo, z_hi) = (band.start as f64 * grid.res, band.end as f64 * grid.res);
        let yaws: Vec<(f32, f32)> = (0..p.yaws)
            .map(|k| {
                let yaw = std::f64::consts::TAU * k as f64 / p.yaws as f64;
                (yaw.sin() as f32, yaw.cos() as f32)
            })
            .collect();
        let cam_dirs = camera.camera_dirs();
        let caster = VoxelCaster {
            grid: &grid,
            gt,
            lists,
            bvh,
            band: (z_lo, z_hi),
            range: camera.range_limits(),
        };
        let bits = positions
            .par_iter()
            .fold(
                || (vec![0u64; words], Vec::new()),
                |(mut bits, mut buf), &cell| {
                    let c = grid.center(grid.cell(cell));
                    let origin = Point3::new(c.x as f32, c.y as f32, camera.mount_height());
                    for &(sin, cos) in &yaws {
                        for d in cam_dirs {
                            let dir =
                                Vector3::new(cos * d.x - sin * d.y, sin * d.x + cos * d.y, d.z);
                            for v in caster.observe(origin, dir, &mut buf) {
                                bits[v >> 6] |= 1 << (v & 63);
                            }
                        }
                    }
                    (bits, buf)
                },
            )
            .map(|(bits, _)| bits)
            .reduce(
                || vec![0u64; words],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x |= y);
                    a
                },
            );
        ObservableSet::from_bits(gt, bits, positions.len())
    }

    /// Completes a set from its bits: keeps band voxels only, counts them, lists the surface.
    fn from_bits(gt: &GroundTruth, mut bits: Vec<u64>, positions: usize) -> ObservableSet {
        let grid = gt.grid;
        let band = gt.band_layers();
        let (lo, hi) = (band.start * grid.cells(), band.end * grid.cells());
        for v in (0..lo).chain(hi..grid.voxels()) {
            bits[v >> 6] &= !(1 << (v & 63));
        }
        let has = |v: usize| bits[v >> 6] >> (v & 63) & 1 == 1;
        let voxels = (lo..hi).filter(|&v| has(v)).count();
        let surface = (lo..hi)
            .filter(|&v| has(v) && gt.occupied(v))
            .map(|v| v as u32)
            .collect();
        ObservableSet {
            bits,
            voxels,
            surface,
            positions,
            voxel_volume: grid.voxel_volume(),
        }
    }

    /// Whether flat voxel `v` is observable.
    #[inline]
    pub fn contains(&self, v: usize) -> bool {
        self.bits
            .get(v >> 6)
            .is_some_and(|w| w >> (v & 63) & 1 == 1)
    }

    /// Number of observable voxels.
    pub fn voxels(&self) -> usize {
        self.voxels
    }

    /// Observable volume, m³.
    pub fn volume_m3(&self) -> f64 {
        self.voxels as f64 * self.voxel_volume
    }

    /// Observable voxels that are occupied in the ground truth, ascending.
    pub fn surface_voxels(&self) -> &[u32] {
        &self.surface
    }

    /// Positions the camera was sampled at.
    pub fn positions(&self) -> usize {
        self.positions
    }

    /// Whether any band voxel of `cell`'s column is observable.
    pub fn column_observable(&self, gt: &GroundTruth, cell: usize) -> bool {
        gt.band_layers()
            .any(|iz| self.contains(iz * gt.grid.cells() + cell))
    }
}

/// Casts camera rays by walking the voxel grid, testing only the triangles that overlap each
/// occupied voxel it enters (`MeshBvh::cast_among`, the BVH cast's own arithmetic): the first hit is
/// the mesh's first hit, found without the tree.
struct VoxelCaster<'a> {
    grid: &'a GridSpec,
    gt: &'a GroundTruth,
    lists: &'a VoxelTriangles,
    bvh: &'a MeshBvh,
    /// The height band `[z_lo, z_hi)`, metres.
    band: (f64, f64),
    /// The camera's nearest and farthest depth, metres.
    range: (f32, f32),
}

impl VoxelCaster<'_> {
    /// The voxels one camera ray makes known in the map, as `Occupancy::integrate` does: every voxel
    /// the ray passes through up to its first hit and the voxel of that hit; nothing when the hit is
    /// nearer than the minimum range (no reading); free space up to the maximum range when there is
    /// no hit. The ray is cut where it leaves the band, which changes no band voxel (a ray leaves a
    /// horizontal slab once). `buf` is scratch space; the result borrows it.
    #[inline]
    fn observe<'b>(
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
        let mut best = f32::INFINITY;
        traverse_while(self.grid, o, d, cut, |v, t_in, t_out| {
            if self.gt.occupied(v) {
                let tris = self.lists.of(v);
                if let Some(t) = self.bvh.cast_among(origin, dir, tris, max_range) {
                    best = best.min(t);
                }
            }
            // A face on this voxel's entry face can lie a hair before it in world coordinates (the
            // voxelisation is half-open): the map's ray ends there and never enters this voxel.
            if best as f64 <= t_in {
                return false;
            }
            buf.push(v);
            // A hit found in an earlier voxel's triangles may lie further on: stop only once the
            // walk has reached it.
            (best as f64) > t_out
        });
        if best.is_finite() {
            if best < min_range {
                buf.clear();
            } else if let Some(v) = self.grid.voxel_of(o + d * best as f64) {
                buf.push(v);
            }
        }
        buf
    }
}

/// One sample cell per 8-connected patch of reachable cells in each `spacing_m` square: the patch
/// cell nearest the patch centroid (ties: lowest index). Ascending.
fn sample_positions(grid: &GridSpec, reachable: &[bool], spacing_m: f64) -> Vec<usize> {
    let k = ((spacing_m / grid.res).round() as usize).max(1);
    let mut out = Vec::new();
    let mut label = vec![false; grid.cells()];
    for by in (0..grid.ny).step_by(k) {
        for bx in (0..grid.nx).step_by(k) {
            let (x1, y1) = ((bx + k).min(grid.nx), (by + k).min(grid.ny));
            let inside = |c: Cell| {
                (bx as i32..x1 as i32).contains(&c.x) && (by as i32..y1 as i32).contains(&c.y)
            };
            for y in by..y1 {
                for x in bx..x1 {
                    let start = y * grid.nx + x;
                    if !reachable[start] || label[start] {
                        continue;
                    }
                    let mut patch = vec![start];
                    label[start] = true;
                    let mut i = 0;
                    while i < patch.len() {
                        let c = grid.cell(patch[i]);
                        i += 1;
                        for (dx, dy) in NEIGHBOURS_8 {
                            let n = Cell::new(c.x + dx, c.y + dy);
                            if inside(n) {
                                let j = grid.index(n);
                                if reachable[j] && !label[j] {
                                    label[j] = true;
                                    patch.push(j);
                                }
                            }
                        }
                    }
                    let (sx, sy) = patch.iter().fold((0.0, 0.0), |(sx, sy), &j| {
                        let c = grid.cell(j);
                        (sx + c.x as f64, sy + c.y as f64)
                    });
                    let (mx, my) = (sx / patch.len() as f64, sy / patch.len() as f64);
                    let dist = |j: usize| {
                        let c = grid.cell(j);
                        (c.x as f64 - mx).powi(2) + (c.y as f64 - my).powi(2)
                    };
                    let best = patch
                        .iter()
                        .copied()
                        .min_by(|&a, &b| dist(a).total_cmp(&dist(b)).then(a.cmp(&b)))
                        .expect("a patch has its start cell");
                    out.push(best);
                }
            }
        }
    }
    out.sort_unstable();
    out
}

/// How a cached set was obtained (reported to the user).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheOutcome {
    /// Read from the cache file.
    Hit(PathBuf),
    /// Computed and written to the cache file.
    Computed(PathBuf),
    /// The cache file was damaged (the reason); the set was recomputed and the file rewritten.
    Repaired(PathBuf, String),
    /// Computed without a cache (none configured, or the folder could not be written: the reason).
    Uncached(Option<String>),
}

/// The on-disk cache of observable sets: one file per scene and relevant config, under a folder the
/// user can see and clear. The folder is `$TENSORSCOUT_CACHE_DIR`, else `$XDG_CACHE_HOME/tensorscout`,
/// else `~/.cache/tensorscout`; files live in its `observable/` subfolder.
#[derive(Clone, Debug)]
pub struct ObservableCache {
    dir: Option<PathBuf>,
}

/// File layout: magic, key, voxel count, positions, word count, words (little-endian u64), then the
/// FNV-1a checksum of everything before it.
const MAGIC: &[u8; 8] = b"TSOBS01\n";

/// Revision of the computation, part of every key: bump it whenever the sampling, the sensor model
/// or the traversal changes, so that no cache file of an older computation is ever read.
const REVISION: u32 = 2;

impl ObservableCache {
    /// The cache in the user's cache folder (see the type doc); `None` folder when no home is known.
    pub fn user() -> ObservableCache {
        let base = std::env::var_os("TENSORSCOUT_CACHE_DIR")
            .filter(|s| !s.is_empty())
            .map(PathBuf::from)
            .or_else(|| {
                std::env::var_os("XDG_CACHE_HOME")
                    .filter(|s| !s.is_empty())
                    .map(|d| PathBuf::from(d).join("tensorscout"))
            })
            .or_else(|| {
                std::env::var_os("HOME")
                    .filter(|s| !s.is_empty())
                    .map(|h| PathBuf::from(h).join(".cache").join("tensorscout"))
            });
        ObservableCache {
            dir: base.map(|b| b.join("observable")),
        }
    }

    /// A cache in `dir` (tests, or a user's `--cache-dir`).
    pub fn at(dir: impl Into<PathBuf>) -> ObservableCache {
        ObservableCache {
            dir: Some(dir.into()),
        }
    }

    /// No cache: always compute.
    pub fn none() -> ObservableCache {
        ObservableCache { dir: None }
    }

    /// The folder the files go to, if any.
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    /// The cache key: the scene's content, the grid, the reachable region (which holds the robot's
    /// size, the inflation and the spawn's component), the band, the camera and the sampling.
    pub fn key(scene_hash: &str, gt: &GroundTruth, cfg: &Config) -> u64 {
        let reach: Vec<u8> = gt.reachable_mask().iter().map(|&r| r as u8).collect();
        let text = format!(
            "observable r{REVISION}|{scene_hash}|{:?}|{:016x}|{:?}|{}|{}|{}",
            gt.grid,
            fnv1a64(&reach),
            gt.band_layers(),
            toml::to_string(&cfg.camera).unwrap_or_default(),
            cfg.metrics.observable_spacing_m,
            cfg.metrics.observable_yaws,
        );
        fnv1a64(text.as_bytes())
    }

    /// The observable set of `gt`: from the cache file when it is intact, else computed (and
    /// written, atomically).
    pub fn get_or_compute(
        &self,
        scene: &Scene,
        gt: &GroundTruth,
        bvh: &MeshBvh,
        cfg: &Config,
    ) -> (ObservableSet, CacheOutcome) {
        let compute = || {
            ObservableSet::compute(
                gt,
                bvh,
                &DepthCamera::new(&cfg.camera),
                &ObservableParams::from_config(cfg),
            )
        };
        let Some(dir) = &self.dir else {
            return (compute(), CacheOutcome::Uncached(None));
        };
        let key = Self::key(&scene.content_hash, gt, cfg);
        let path = dir.join(format!("{key:016x}.bin"));
        let damage = match std::fs::read(&path) {
            Ok(bytes) => match decode(&bytes, key, gt) {
                Ok(set) => return (set, CacheOutcome::Hit(path)),
                Err(why) => Some(why),
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => Some(format!("unreadable: {e}")),
        };
        let set = compute();
        let outcome = match write_atomic(dir, &path, &encode(&set, key)) {
            Ok(()) => match damage {
                Some(why) => CacheOutcome::Repaired(path, why),
                None => CacheOutcome::Computed(path),
            },
            Err(e) => CacheOutcome::Uncached(Some(e.to_string())),
        };
        (set, outcome)
    }
}

impl CacheOutcome {
    /// A line for the user when something about the cache deserves one (damage, unwritable folder).
    pub fn warning(&self) -> Option<String> {
        match self {
            CacheOutcome::Repaired(p, why) => Some(format!(
                "warning: observable-volume cache {} was damaged ({why}); recomputed and rewritten",
                p.display()
            )),
            CacheOutcome::Uncached(Some(why)) => Some(format!(
                "warning: observable-volume cache not written ({why}); set TENSORSCOUT_CACHE_DIR to a writable folder"
            )),
            _ => None,
        }
    }
}

fn encode(set: &ObservableSet, key: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(48 + 8 * set.bits.len());
    out.extend_from_slice(MAGIC);
    for v in [
        key,
        set.voxels as u64,
        set.positions as u64,
        set.bits.len() as u64,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for w in &set.bits {
        out.extend_from_slice(&w.to_le_bytes());
    }
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Reads a cache file back, or says what is wrong with it.
fn decode(bytes: &[u8], key: u64, gt: &GroundTruth) -> std::result::Result<ObservableSet, String> {
    let words = gt.grid.voxels().div_ceil(64);
    let expected = MAGIC.len() + 32 + 8 * words + 8;
    if bytes.len() != expected {
        return Err(format!("{} bytes, expected {expected}", bytes.len()));
    }
    if &bytes[..8] != MAGIC {
        return Err("not an observable-volume cache file".into());
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    let u64_at = |b: &[u8], i: usize| u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
    if u64_at(sum, 0) != fnv1a64(body) {
        return Err("checksum mismatch".into());
    }
    if u64_at(body, 8) != key || u64_at(body, 32) != words as u64 {
        return Err("written for another scene or config".into());
    }
    let voxels = u64_at(body, 16) as usize;
    let positions = u64_at(body, 24) as usize;
    let bits: Vec<u64> = (0..words).map(|k| u64_at(body, 40 + 8 * k)).collect();
    let set = ObservableSet::from_bits(gt, bits, positions);
    if set.voxels != voxels {
        return Err("voxel count does not match its bits".into());
    }
    Ok(set)
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so a reader
/// never sees a partial file.
fn write_atomic(dir: &Path, path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    // Unique per process and call: bench workers may write the same key at once.
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(
        ".{}.{}.{n}.tmp",
        path.file_name().and_then(|n| n.to_str()).unwrap_or("cache"),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).map_err(|e| Error::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::Occupancy;
    use crate::scene::Scene;
    use crate::sensor::raycast::testing::{furnished_room, push_box};
    use crate::Pose2;

    fn scene(mesh: crate::scene::TriMesh) -> Scene {
        Scene {
            name: "test".into(),
            path: "test.obj".into(),
            mesh,
            spawn: None,
            content_hash: "test".into(),
            floor_z: 0.0,
            source: "obj".into(),
            warnings: Vec::new(),
        }
    }

    /// A 6 × 6 m room (inside x, y ∈ [0.1, 6.1]) with a table, plus a 3 × 2 m closet east of it
    /// (x ∈ [6.2, 9.2], y ∈ [0.1, 2.1]) behind a 0.5 m door (y ∈ [0.8, 1.3]) in the 0.1 m wall: the
    /// door is narrower than the inflated robot, so the closet is observable through it but not
    /// reachable.
    fn room_with_closet() -> crate::scene::TriMesh {
        let (nx, ny) = (94, 63);
        let solid: Vec<bool> = (0..nx * ny)
            .map(|i| {
                let (x, y) = (i % nx, i / nx);
                let room = (1..61).contains(&x) && (1..61).contains(&y);
                let closet = (62..92).contains(&x) && (1..21).contains(&y);
                let door = x == 61 && (8..13).contains(&y);
                !(room || closet || door)
            })
            .collect();
        let mut mesh = crate::scene::extrude::extrude_grid(&solid, nx, ny, [0.0, 0.0], 0.1, 2.5);
        push_box(&mut mesh, [2.0, 4.0, 0.0], [3.0, 5.0, 0.75]);
        mesh
    }

    #[test]
    fn rays_mark_what_the_map_integrates() {
        // Every band voxel a frame makes known in the map, and no other, is what the caster marks.
        let cfg = Config::default();
        let mesh = furnished_room(6.0);
        let gt = GroundTruth::build(&mesh, None, &cfg).unwrap();
        let bvh = MeshBvh::new(&mesh).unwrap();
        let camera = DepthCamera::new(&cfg.camera);
        let band = gt.band_layers();
        let caster = VoxelCaster {
            grid: &gt.grid,
            gt: &gt,
            lists: gt.voxel_triangles(),
            bvh: &bvh,
            band: (
                band.start as f64 * gt.grid.res,
                band.end as f64 * gt.grid.res,
            ),
            range: camera.range_limits(),
        };
        let in_band = |v: usize| band.contains(&gt.grid.voxel_parts(v).1);
        let (mut total, mut differ) = (0usize, 0usize);
        let mut buf = Vec::new();
        for (k, pose) in [
            Pose2::new(3.0, 3.0, 0.3),
            Pose2::new(1.0, 4.5, -2.0),
            Pose2::new(5.2, 5.2, 3.9),
            Pose2::new(0.6, 0.7, 0.8),
        ]
        .into_iter()
        .enumerate()
        {
            let frame = camera.capture(&bvh, pose);
            let mut occ = Occupancy::new(
                gt.grid,
                crate::map::LogOdds::from_config(&cfg.map),
                band.clone(),
            );
            let mut map: Vec<u32> = occ.integrate(&frame).newly_known;
            map.retain(|&v| in_band(v as usize));
            let mut cast: Vec<u32> = Vec::new();
            for d in &frame.dirs {
                cast.extend(
                    caster
                        .observe(frame.origin, *d, &mut buf)
                        .iter()
                        .filter(|&&v| in_band(v))
                        .map(|&v| v as u32),
                );
            }
            cast.sort_unstable();
            cast.dedup();
            total += map.len();
            differ += map.len() + cast.len()
                - 2 * map.iter().filter(|v| cast.binary_search(v).is_ok()).count();
            assert!(map.len() > 1000, "pose {k}: {} voxels", map.len());
        }
        // Exact agreement but for ties of floating-point rounding at voxel faces.
        assert_eq!(differ, 0, "{differ} of {total} voxels differ");
    }

    #[test]
    fn closet_is_observable_not_reachable() {
        let cfg = Config::default();
        let mesh = room_with_closet();
        let gt = GroundTruth::build(&mesh, Some(Pose2::new(3.0, 3.0, 0.0)), &cfg).unwrap();
        let bvh = MeshBvh::new(&mesh).unwrap();
        let set = ObservableSet::compute(
            &gt,
            &bvh,
            &DepthCamera::new(&cfg.camera),
            &ObservableParams::from_config(&cfg),
        );
        let cell = |x: f64, y: f64| gt.grid.index(gt.grid.cell_at(x, y));
        // The door (0.5 m) is narrower than 2 × 0.29 m: the closet is not reachable ...
        assert!(gt.reachable(cell(3.0, 3.0)));
        assert!(!gt.reachable(cell(6.15, 1.05)) && !gt.reachable(cell(7.5, 1.0)));
        // ... but the camera sees into it through the door, and not into its corners beside the
        // door, hidden behind the wall from every reachable pose.
        assert!(set.column_observable(&gt, cell(7.5, 1.05)));
        assert!(!set.column_observable(&gt, cell(6.25, 0.15)));
        // Reachable floor: the room's inside less a band of the inflation radius along its walls
        // and around the table: (6 − 2·0.3)² − (1 + 2·0.3)² ≈ 26.6 m², to a cell.
        let area = gt.reachable_area_m2();
        assert!((area - 26.6).abs() < 1.5, "{area}");
        // Observable: at most the room's and closet's band volume plus their walls' faces.
        let v = set.volume_m3();
        assert!(
            v > 0.9 * 36.0 * 1.7 && v < (6.2 * 6.2 + 3.2 * 2.2) * 1.7,
            "{v}"
        );
    }

    #[test]
    fn cache_round_trip_and_damage() {
        let cfg = Config::default();
        let mesh = furnished_room(5.0);
        let scene = scene(mesh.clone());
        let gt = GroundTruth::build(&mesh, None, &cfg).unwrap();
        let bvh = MeshBvh::new(&mesh).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let cache = ObservableCache::at(dir.path());
        let (fresh, how) = ObservableCache::none().get_or_compute(&scene, &gt, &bvh, &cfg);
        assert_eq!(how, CacheOutcome::Uncached(None));
        let (first, how) = cache.get_or_compute(&scene, &gt, &bvh, &cfg);
        let CacheOutcome::Computed(path) = how else {
            panic!("{how:?}")
        };
        assert_eq!(first, fresh);
        let (hit, how) = cache.get_or_compute(&scene, &gt, &bvh, &cfg);
        assert_eq!(how, CacheOutcome::Hit(path.clone()));
        assert_eq!(hit, fresh);
        // A truncated file, a flipped byte and a file of another key are each found, recomputed and
        // reported; the set is the fresh one every time.
        let good = std::fs::read(&path).unwrap();
        let mut flipped = good.clone();
        flipped[good.len() / 2] ^= 0x10;
        let mut other = good.clone();
        other[8] ^= 1; // the key, with a checksum that matches
        let n = other.len();
        let sum = fnv1a64(&other[..n - 8]).to_le_bytes();
        other[n - 8..].copy_from_slice(&sum);
        for (bytes, why) in [
            (&good[..good.len() - 9], "bytes, expected"),
            (&flipped[..], "checksum mismatch"),
            (&other[..], "written for another scene or config"),
            (&b""[..], "0 bytes"),
        ] {
            std::fs::write(&path, bytes).unwrap();
            let (set, how) = cache.get_or_compute(&scene, &gt, &bvh, &cfg);
            assert_eq!(set, fresh);
            let CacheOutcome::Repaired(p, reason) = &how else {
                panic!("{how:?}")
            };
            assert_eq!(p, &path);
            assert!(reason.contains(why), "{reason}");
            assert!(how.warning().unwrap().contains("was damaged"));
            assert_eq!(std::fs::read(&path).unwrap(), good);
        }
        // Another sampling is another file.
        let mut coarse = cfg.clone();
        coarse.metrics.observable_spacing_m = 1.0;
        assert_ne!(
            ObservableCache::key("test", &gt, &cfg),
            ObservableCache::key("test", &gt, &coarse)
        );
    }

    #[test]
    fn set_does_not_depend_on_thread_count() {
        let cfg = Config::default();
        let mesh = room_with_closet();
        let gt = GroundTruth::build(&mesh, Some(Pose2::new(3.0, 3.0, 0.0)), &cfg).unwrap();
        let bvh = MeshBvh::new(&mesh).unwrap();
        let compute = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    ObservableSet::compute(
                        &gt,
                        &bvh,
                        &DepthCamera::new(&cfg.camera),
                        &ObservableParams::from_config(&cfg),
                    )
                })
        };
        assert_eq!(compute(1), compute(2));
    }

    #[test]
    fn every_reachable_patch_gets_a_position() {
        // A 1-cell-wide reachable corridor and an isolated cell: sampled although they cross no
        // lattice point.
        let grid = GridSpec::covering(
            nalgebra::Point2::new(0.0, 0.0),
            nalgebra::Point2::new(2.0, 2.0),
            1.0,
            0.1,
        );
        let mut reach = vec![false; grid.cells()];
        for x in 2..18 {
            reach[grid.index(Cell::new(x, 7))] = true;
        }
        reach[grid.index(Cell::new(13, 13))] = true;
        let pos = sample_positions(&grid, &reach, 0.5);
        // Corridor cells 2..18 fall in blocks x 0..5, 5..10, 10..15, 15..20: one each; plus the cell.
        assert_eq!(pos.len(), 5, "{pos:?}");
        assert!(pos.contains(&grid.index(Cell::new(13, 13))));
        assert!(pos.iter().all(|&c| reach[c]));
    }
}
