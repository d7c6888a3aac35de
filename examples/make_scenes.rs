//! Regenerates the shipped scenes in `scenes/`: six generated ones and two imported from the real
//! fixtures in `tests/data/`. Each OBJ carries a spawn verified by the ground truth.
//!
//! `cargo run --release --example make_scenes` (prints the rows of `scenes/README.md`'s table).

use std::path::Path;
use tensorscout::eval::{info, GroundTruth};
use tensorscout::scene::generate::{generate, shipped_generated};
use tensorscout::scene::{self, write_obj};
use tensorscout::{Config, Pose2};

fn main() -> tensorscout::Result<()> {
    let cfg = Config::default();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = root.join("scenes");
    std::fs::create_dir_all(&out).map_err(|e| tensorscout::Error::io(&out, e))?;

    for (name, style, seed, area) in shipped_generated() {
        let g = generate(style, seed, area)?;
        let path = out.join(format!("{name}.obj"));
        write_obj(&g.mesh, Some(g.spawn), &g.header(), &path)?;
        report(
            &path,
            &cfg,
            &format!("generated:{}", style.name()),
            Some(g.rooms.len()),
            &g.features.join(", "),
        )?;
    }
    for (name, source, header, rooms, features) in [
        (
            "small_house",
            "map.yaml",
            "Imported from the AWS RoboMaker Small House World occupancy map (MIT-0), aws-robotics/aws-robomaker-small-house-world maps/turtlebot3_waffle_pi",
            None,
            "occupied cells (walls and furniture) extruded to full height, unknown = solid",
        ),
        (
            "houseexpo_1451",
            "house_expo_room_1451.json",
            "Imported from HouseExpo plan 1451 (MIT), via ExistentialRobotics/erl_geometry data/",
            Some(7),
            "outline rasterised at 0.05 m and extruded; no furniture",
        ),
    ] {
        let s = scene::load(&root.join("tests/data").join(source), &cfg.scene)?;
        let gt = GroundTruth::build(&s.mesh, None, &cfg)?;
        let spawn = Pose2::new(round3(gt.spawn.x), round3(gt.spawn.y), 0.0);
        let path = out.join(format!("{name}.obj"));
        let headers = vec![header.to_string(), format!("source: {}, walls {} m", s.source, cfg.scene.wall_height_m)];
        write_obj(&s.mesh, Some(spawn), &headers, &path)?;
        report(&path, &cfg, &s.source, rooms, features)?;
    }
    Ok(())
}

fn round3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

/// Reloads a written scene, validates its spawn and prints a table row.
fn report(
    path: &Path,
    cfg: &Config,
    source: &str,
    rooms: Option<usize>,
    features: &str,
) -> tensorscout::Result<()> {
    let t0 = std::time::Instant::now();
    let s = scene::load(path, &cfg.scene)?;
    let t1 = std::time::Instant::now();
    let gt = GroundTruth::build(&s.mesh, s.spawn, cfg)?;
    eprintln!(
        "{}: load {:.1} ms, ground truth {:.1} ms ({} × {} × {} voxels)",
        s.name,
        (t1 - t0).as_secs_f64() * 1e3,
        t1.elapsed().as_secs_f64() * 1e3,
        gt.grid.nx,
        gt.grid.ny,
        gt.grid.nz
    );
    let i = info(&s, &gt);
    let c = gt
        .grid
        .index(gt.grid.cell_of(gt.spawn.position()).expect("validated"));
    let bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    println!(
        "| `{}` | {} | {:.1} × {:.1} | {:.0} | {} | {} | ({:.2}, {:.2}), clearance {:.2} m | {} | {} KB |",
        s.name,
        source,
        i.bounds_max[0] - i.bounds_min[0],
        i.bounds_max[1] - i.bounds_min[1],
        i.reachable_area_m2,
        rooms.map(|r| r.to_string()).unwrap_or_else(|| "–".into()),
        features,
        gt.spawn.x,
        gt.spawn.y,
        gt.clearance_m(c),
        i.triangles,
        bytes / 1024
    );
    Ok(())
}
