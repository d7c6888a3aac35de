//! The observable set's tests: the caster against the map, the sweep against the caster, the
//! sampling and the cache.

use super::caster::VoxelCaster;
use super::sampling::{beyond_cells, lattice_cells, refined_positions, sample_positions};
use super::*;
use crate::config::Config;
use crate::grid::{Cell, GridSpec};
use crate::map::Occupancy;
use crate::scene::Scene;
use crate::sensor::raycast::testing::{furnished_room, push_box};
use crate::util::fnv1a64;
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
        inputs: Vec::new(),
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
    let caster = VoxelCaster::new(
        &gt,
        &bvh,
        &camera,
        (
            band.start as f64 * gt.grid.res,
            band.end as f64 * gt.grid.res,
        ),
    );
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

/// The column sweep against the ray-by-ray walk over a scene's sampled poses: the same bits, and
/// the sweep decides almost every column itself. Returns the number of observed voxels.
fn sweep_equals_rays(mesh: &crate::scene::TriMesh, spawn: Option<Pose2>, spacing: f64) -> usize {
    let cfg = Config::default();
    let gt = GroundTruth::build(mesh, spawn, &cfg).unwrap();
    let bvh = MeshBvh::new(mesh).unwrap();
    let camera = DepthCamera::new(&cfg.camera);
    let band = gt.band_layers();
    let res = gt.grid.res;
    let caster = VoxelCaster::new(
        &gt,
        &bvh,
        &camera,
        (band.start as f64 * res, band.end as f64 * res),
    );
    assert!(caster.sweep_applies(&camera));
    let k = lattice_cells(&gt.grid, spacing);
    let positions = sample_positions(&gt.grid, gt.reachable_mask(), k, |_, _| true);
    let beyond = beyond_cells(&gt);
    let yaws: Vec<(f32, f32)> = (0..8)
        .map(|k| {
            let yaw = std::f64::consts::TAU * k as f64 / 8.0;
            (yaw.sin() as f32, yaw.cos() as f32)
        })
        .collect();
    let rays = caster.frames_by_rays(&positions, &yaws, &camera, &beyond, &Silent);
    assert!(!positions.is_empty());
    let columns = positions.len() * yaws.len() * camera.image_size().0;
    // Voxels outside the band are dropped from the set (the walks differ there: the sweep does
    // not mark the floor voxel of a ray's last, out-of-band step).
    let rays_set = ObservableSet::from_bits(&gt, rays.bits, positions.len());
    // On one thread and on two (the workers' shares of the positions differ).
    for threads in [1, 2] {
        let swept = crate::util::on_threads(threads, || {
            caster.frames_by_columns(&positions, &yaws, &camera, &beyond, &Silent)
        });
        // The two ways agree on which positions looked beyond the reachable region, too.
        assert_eq!(rays.looked_beyond, swept.looked_beyond);
        let by_rays = swept.by_rays;
        assert!(
            by_rays * 100 < columns,
            "{by_rays} of {columns} columns walked ray by ray"
        );
        let swept = ObservableSet::from_bits(&gt, swept.bits, positions.len());
        let differ = (0..gt.grid.voxels())
            .filter(|&v| rays_set.contains(v) != swept.contains(v))
            .count();
        assert_eq!(
            differ,
            0,
            "{threads} threads: {differ} of {} voxels differ",
            rays_set.voxels()
        );
    }
    rays_set.voxels()
}

/// The sweep against the ray-by-ray walk on every shipped scene and three plans (one of them
/// the benchmark's, with views through narrow gaps), every fourth square of positions.
#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn column_sweep_marks_what_rays_mark_on_shipped_scenes() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut paths: Vec<std::path::PathBuf> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "obj"))
        .collect();
    paths.sort();
    assert!(paths.len() >= 8, "{paths:?}");
    for plan in ["plan_7fdb16a896", "plan_052ce6767b", "plan_2eea8ff97b"] {
        paths.push(root.join("floorplans").join(format!("{plan}.obj")));
    }
    for path in paths {
        let scene = crate::scene::load(&path, &Config::default().scene).unwrap();
        let voxels = sweep_equals_rays(&scene.mesh, scene.spawn, 2.0);
        assert!(voxels > 1000, "{}: {voxels}", path.display());
    }
}

#[test]
fn column_sweep_marks_what_rays_mark() {
    assert!(sweep_equals_rays(&furnished_room(6.0), None, 0.5) > 10_000);
    let closet = room_with_closet();
    assert!(sweep_equals_rays(&closet, Some(Pose2::new(3.0, 3.0, 0.0)), 0.5) > 10_000);
    // A real plan (furniture, doors, diagonal walls): every third square of positions.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/floorplans/plan_a64cda6b6a.obj");
    let scene = crate::scene::load(&path, &Config::default().scene).unwrap();
    assert!(sweep_equals_rays(&scene.mesh, scene.spawn, 1.5) > 10_000);
}

#[test]
fn views_through_a_narrow_door_are_sampled_again_finer() {
    let cfg = Config::default();
    let mesh = room_with_closet();
    let gt = GroundTruth::build(&mesh, Some(Pose2::new(3.0, 3.0, 0.0)), &cfg).unwrap();
    let grid = gt.grid;
    let beyond = beyond_cells(&gt);
    let cell = |x: f64, y: f64| grid.index(grid.cell_at(x, y));
    // The closet lies beyond the reachable region; nothing of the room does, not even the free
    // band along its walls and around the table that the inflation keeps the robot out of.
    assert!(beyond[cell(7.55, 1.05)] && beyond[cell(9.15, 2.05)] && beyond[cell(6.55, 0.25)]);
    for (i, &b) in beyond.iter().enumerate() {
        let p = grid.center(grid.cell(i));
        if p.x > 0.1 && p.x < 6.1 && p.y > 0.1 && p.y < 6.1 {
            assert!(!b, "{p:?}");
        }
    }
    // The first pass alone, as `compute` runs it.
    let bvh = MeshBvh::new(&mesh).unwrap();
    let camera = DepthCamera::new(&cfg.camera);
    let band = gt.band_layers();
    let res = grid.res;
    let caster = VoxelCaster::new(
        &gt,
        &bvh,
        &camera,
        (band.start as f64 * res, band.end as f64 * res),
    );
    let yaws: Vec<(f32, f32)> = (0..cfg.metrics.observable_yaws)
        .map(|k| {
            let yaw = std::f64::consts::TAU * k as f64 / cfg.metrics.observable_yaws as f64;
            (yaw.sin() as f32, yaw.cos() as f32)
        })
        .collect();
    let k = lattice_cells(&grid, cfg.metrics.observable_spacing_m);
    let coarse = sample_positions(&grid, gt.reachable_mask(), k, |_, _| true);
    let first = caster.frames_by_columns(&coarse, &yaws, &camera, &beyond, &Silent);
    // Some positions look into the closet through the door, and only those of the room's
    // eastern part (the closet is out of range of the rest).
    assert!(!first.looked_beyond.is_empty());
    assert!(first
        .looked_beyond
        .iter()
        .all(|&c| grid.center(grid.cell(c)).x > 1.0));
    let fine = refined_positions(&grid, gt.reachable_mask(), k, &first.looked_beyond, &coarse);
    assert!(fine.len() > first.looked_beyond.len());
    assert!(fine
        .iter()
        .all(|&c| gt.reachable(c) && !coarse.contains(&c)));
    // Every refined position lies in a square next to one that looked beyond.
    let square = |c: usize| {
        let c = grid.cell(c);
        (c.x / k as i32, c.y / k as i32)
    };
    assert!(fine.iter().all(|&f| first.looked_beyond.iter().any(|&l| {
        let (a, b) = (square(f), square(l));
        (a.0 - b.0).abs() <= 1 && (a.1 - b.1).abs() <= 1
    })));
    // The set holds the first pass and sees more of the closet.
    let coarse_set = ObservableSet::from_bits(&gt, first.bits, coarse.len());
    let set = ObservableSet::compute(
        &gt,
        &bvh,
        &camera,
        &ObservableParams::from_config(&cfg.metrics),
    );
    assert_eq!(set.positions(), coarse.len() + fine.len());
    assert!((0..grid.voxels()).all(|v| !coarse_set.contains(v) || set.contains(v)));
    let in_closet = |s: &ObservableSet| {
        (0..grid.voxels())
            .filter(|&v| s.contains(v) && beyond[grid.voxel_parts(v).0])
            .count()
    };
    let (before, after) = (in_closet(&coarse_set), in_closet(&set));
    assert!(after > before, "{before} → {after} closet voxels");
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
        &ObservableParams::from_config(&cfg.metrics),
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
    let (fresh, how) = ObservableCache::none().get_or_compute(
        &scene,
        &gt,
        &bvh,
        &cfg.camera,
        &ObservableParams::from_config(&cfg.metrics),
    );
    assert_eq!(how, CacheOutcome::Uncached(None));
    let (first, how) = cache.get_or_compute(
        &scene,
        &gt,
        &bvh,
        &cfg.camera,
        &ObservableParams::from_config(&cfg.metrics),
    );
    let CacheOutcome::Computed(path) = how else {
        panic!("{how:?}")
    };
    assert_eq!(first, fresh);
    let (hit, how) = cache.get_or_compute(
        &scene,
        &gt,
        &bvh,
        &cfg.camera,
        &ObservableParams::from_config(&cfg.metrics),
    );
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
        let (set, how) = cache.get_or_compute(
            &scene,
            &gt,
            &bvh,
            &cfg.camera,
            &ObservableParams::from_config(&cfg.metrics),
        );
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
        ObservableCache::key(
            "test",
            &gt,
            &cfg.camera,
            &ObservableParams::from_config(&cfg.metrics)
        ),
        ObservableCache::key(
            "test",
            &gt,
            &coarse.camera,
            &ObservableParams::from_config(&coarse.metrics)
        )
    );
}

#[test]
fn set_does_not_depend_on_thread_count() {
    let cfg = Config::default();
    let mesh = room_with_closet();
    let gt = GroundTruth::build(&mesh, Some(Pose2::new(3.0, 3.0, 0.0)), &cfg).unwrap();
    let bvh = MeshBvh::new(&mesh).unwrap();
    let compute = |threads: usize| {
        crate::util::on_threads(threads, || {
            ObservableSet::compute(
                &gt,
                &bvh,
                &DepthCamera::new(&cfg.camera),
                &ObservableParams::from_config(&cfg.metrics),
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
    let pos = sample_positions(&grid, &reach, lattice_cells(&grid, 0.5), |_, _| true);
    // Corridor cells 2..18 fall in blocks x 0..5, 5..10, 10..15, 15..20: one each; plus the cell.
    assert_eq!(pos.len(), 5, "{pos:?}");
    assert!(pos.contains(&grid.index(Cell::new(13, 13))));
    assert!(pos.iter().all(|&c| reach[c]));
}
