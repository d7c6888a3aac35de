//! Depth frames (BVH ray casting and rasterisation) and map integration: rays per second on a
//! synthetic furnished room, and depth frames of the largest shipped scene.
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use nalgebra::Point2;
use tensorscout::map::Map;
use tensorscout::sensor::raycast::testing::furnished_room;
use tensorscout::sensor::{DepthCamera, DepthFrame, MeshBvh, MeshRaster};
use tensorscout::{Config, GridSpec, Pose2};

fn rays(c: &mut Criterion) {
    let bvh = MeshBvh::new(&furnished_room(8.0)).unwrap();
    let raster = MeshRaster::new(&furnished_room(8.0)).unwrap();
    for (w, h) in [(80usize, 60usize), (640, 480)] {
        let mut cfg = Config::default();
        cfg.camera.width = w;
        cfg.camera.height = h;
        let cam = DepthCamera::new(&cfg.camera);
        let mut frame = DepthFrame::default();
        let mut g = c.benchmark_group(format!("rays_{w}x{h}"));
        g.throughput(Throughput::Elements((w * h) as u64));
        let mut k = 0u32;
        g.bench_function("cast", |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let yaw = k as f64 * 0.37;
                cam.capture_into(&bvh, Pose2::new(4.0, 4.0, yaw), &mut frame);
            })
        });
        g.bench_function("render", |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let yaw = k as f64 * 0.37;
                cam.render_into(&raster, Pose2::new(4.0, 4.0, yaw), &mut frame);
            })
        });
        let grid = GridSpec::covering(
            Point2::new(-0.5, -0.5),
            Point2::new(8.5, 8.5),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        );
        let mut map = Map::new(grid, &cfg);
        g.bench_function("cast_and_integrate", |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                // Poses on a circle around the room centre, looking all ways: some frames see new space.
                let a = k as f64 * 0.37;
                let pose = Pose2::new(4.0 + 1.5 * a.cos(), 4.0 + 1.5 * (0.7 * a).sin(), a * 1.3);
                cam.capture_into(&bvh, pose, &mut frame);
                map.integrate(&frame).touched_columns
            })
        });
        // Integration alone, of frames rendered beforehand from the same circle of poses.
        let frames: Vec<DepthFrame> = (0..32)
            .map(|i| {
                let a = i as f64 * 0.37;
                let pose = Pose2::new(4.0 + 1.5 * a.cos(), 4.0 + 1.5 * (0.7 * a).sin(), a * 1.3);
                cam.render(&raster, pose)
            })
            .collect();
        let mut map = Map::new(grid, &cfg);
        let mut i = 0usize;
        g.bench_function("integrate", |b| {
            b.iter(|| {
                i += 1;
                map.integrate(&frames[i % frames.len()]).touched_columns
            })
        });
        let mut map = Map::new(grid, &cfg);
        g.bench_function("render_and_integrate", |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let a = k as f64 * 0.37;
                let pose = Pose2::new(4.0 + 1.5 * a.cos(), 4.0 + 1.5 * (0.7 * a).sin(), a * 1.3);
                cam.render_into(&raster, pose, &mut frame);
                map.integrate(&frame).touched_columns
            })
        });
        g.finish();
    }
    // The largest shipped scene: frames from poses along a line through its middle, all headings.
    let cfg = Config::default();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/office_large.obj");
    let scene = tensorscout::scene::load(std::path::Path::new(path), &cfg.scene).unwrap();
    let bvh = MeshBvh::new(&scene.mesh).unwrap();
    let raster = MeshRaster::new(&scene.mesh).unwrap();
    let (lo, hi) = scene.mesh.bounds().unwrap();
    let poses: Vec<Pose2> = (0..64)
        .map(|i| {
            let f = (i as f64 + 0.5) / 64.0;
            Pose2::new(
                lo.x + (hi.x - lo.x) * f,
                0.5 * (lo.y + hi.y),
                i as f64 * 0.9,
            )
        })
        .collect();
    let cam = DepthCamera::new(&cfg.camera);
    let mut frame = DepthFrame::default();
    let mut g = c.benchmark_group("office_large_80x60");
    g.throughput(Throughput::Elements(cam.rays() as u64));
    let mut k = 0usize;
    g.bench_function("cast", |b| {
        b.iter(|| {
            k += 1;
            cam.capture_into(&bvh, poses[k % poses.len()], &mut frame);
        })
    });
    g.bench_function("render", |b| {
        b.iter(|| {
            k += 1;
            cam.render_into(&raster, poses[k % poses.len()], &mut frame);
        })
    });
    g.finish();
}

criterion_group!(benches, rays);
criterion_main!(benches);
