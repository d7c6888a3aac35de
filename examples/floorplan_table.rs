//! Prints the table of `scenes/floorplans/README.md`: per plan its size, floor area, rooms, openings,
//! reachable floor and observable volume (default config).
//!
//! `cargo run --release --example floorplan_table` (uses the observable-volume cache).
//!
//! Rooms and openings are read from the mesh: an opening is a door or passage with a lintel (a group of
//! horizontal faces between 1.9 and 2.45 m, the lintels' undersides, over floor that obstacles in
//! the robot's band leave open); rooms are the 4-connected
//! regions of floor of at least 1 m² that obstacles in the robot's band and the door openings
//! separate, not touching the plan's outside.

use std::path::Path;
use tensorscout::eval::info;
use tensorscout::grid::Cell;
use tensorscout::scene;
use tensorscout::sim::{ObservableCache, World};
use tensorscout::Config;

fn main() -> tensorscout::Result<()> {
    let cfg = Config::default();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/floorplans");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .map_err(|e| tensorscout::Error::io(&dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    paths.sort();
    println!(
        "| plan | size (m) | floor (m²) | rooms | openings | reachable (m²) | observable (m³) |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|");
    for path in paths {
        let s = scene::load(&path, &cfg.scene)?;
        let world = World::with_cache(&s, &cfg, None, &ObservableCache::user())?;
        let gt = &world.ground_truth;
        let i = info(&s, gt);
        let grid = gt.grid;
        // Lintel undersides: horizontal triangles between 1.9 and 2.45 m, grouped by shared vertices.
        let lintel: Vec<usize> = (0..s.mesh.triangles.len())
            .filter(|&t| {
                let z = s.mesh.triangles[t].map(|k| s.mesh.vertices[k as usize].z);
                z[0] == z[1] && z[1] == z[2] && (1.9..2.45).contains(&z[0])
            })
            .collect();
        let mut parent: Vec<usize> = (0..s.mesh.vertices.len()).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        for &t in &lintel {
            let [a, b, c] = s.mesh.triangles[t].map(|k| k as usize);
            for (x, y) in [(a, b), (b, c)] {
                let (rx, ry) = (root(&mut parent, x), root(&mut parent, y));
                parent[rx] = ry;
            }
        }
        // A door is a group over floor the robot's band leaves open (a wardrobe's top or a window's
        // lintel over its sill is not).
        let over_open_floor = |t: usize| {
            let v = s.mesh.triangles[t].map(|k| s.mesh.vertices[k as usize]);
            let cx = (v[0].x + v[1].x + v[2].x) as f64 / 3.0;
            let cy = (v[0].y + v[1].y + v[2].y) as f64 / 3.0;
            grid.cell_of(nalgebra::Point2::new(cx, cy))
                .is_some_and(|c| !gt.obstacle_column(grid.index(c)))
        };
        let mut groups: Vec<usize> = lintel
            .iter()
            .filter(|&&t| over_open_floor(t))
            .map(|&t| root(&mut parent, s.mesh.triangles[t][0] as usize))
            .collect();
        groups.sort_unstable();
        groups.dedup();
        // Cells under a lintel close their door for the room count.
        let mut closed: Vec<bool> = (0..grid.cells()).map(|c| gt.obstacle_column(c)).collect();
        for &t in &lintel {
            let v = s.mesh.triangles[t].map(|k| s.mesh.vertices[k as usize]);
            let (x0, x1) = (
                v.iter().map(|p| p.x).fold(f32::MAX, f32::min),
                v.iter().map(|p| p.x).fold(f32::MIN, f32::max),
            );
            let (y0, y1) = (
                v.iter().map(|p| p.y).fold(f32::MAX, f32::min),
                v.iter().map(|p| p.y).fold(f32::MIN, f32::max),
            );
            let (a, b) = (
                grid.cell_at(x0 as f64, y0 as f64),
                grid.cell_at(x1 as f64, y1 as f64),
            );
            for y in a.y..=b.y {
                for x in a.x..=b.x {
                    if let Some(j) = grid.checked_index(Cell::new(x, y)) {
                        closed[j] = true;
                    }
                }
            }
        }
        let (mut rooms, mut floor) = (0, 0usize);
        let mut seen = vec![false; grid.cells()];
        for start in 0..grid.cells() {
            if closed[start] || seen[start] {
                continue;
            }
            let (mut size, mut border) = (0usize, false);
            let mut stack = vec![start];
            seen[start] = true;
            while let Some(k) = stack.pop() {
                size += 1;
                let c = grid.cell(k);
                border |= c.x == 0
                    || c.y == 0
                    || c.x as usize == grid.nx - 1
                    || c.y as usize == grid.ny - 1;
                for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                    if let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                        if !closed[j] && !seen[j] {
                            seen[j] = true;
                            stack.push(j);
                        }
                    }
                }
            }
            if !border && size as f64 * grid.cell_area() >= 1.0 {
                rooms += 1;
                floor += size;
            }
        }
        println!(
            "| `{}` | {:.1} × {:.1} | {:.0} | {} | {} | {:.1} | {:.1} |",
            s.name,
            i.bounds_max[0] - i.bounds_min[0],
            i.bounds_max[1] - i.bounds_min[1],
            floor as f64 * grid.cell_area(),
            rooms,
            groups.len(),
            gt.reachable_area_m2(),
            world.observable.volume_m3()
        );
    }
    Ok(())
}
