//! HouseExpo floor-plan importer (`{verts, room_num, room_category, bbox, id}` JSON).
//!
//! `verts` is one implicitly closed outline of the free space. We rasterise it (even-odd test on cell
//! centres, [`RASTER_M`] cells) and extrude the grid with the shared [`extrude_grid`], rather than
//! extruding the outline edges as thin quads: the raster path closes the outside with solid cells (a
//! 2-cell = 0.1 m wall ring, like HouseExpo's own walls), is robust to the outline's many tiny
//! staircase steps and near-touching edges, and shares one code path with the ROS-map importer. The
//! price is that walls are snapped to a 0.05 m raster, well below the 0.1 m map voxel.
//! `room_category` boxes are room labels, not walls; only `room_num` is kept.

use super::extrude::extrude_grid;
use super::TriMesh;
use crate::config::SceneConfig;
use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::Path;

/// Raster cell edge, metres.
pub const RASTER_M: f64 = 0.05;
/// Largest raster imported: 16 M cells, a 200 × 200 m plan (found by the fuzz run, which gave a
/// plan a 915 m coordinate).
pub const MAX_RASTER_CELLS: usize = 16_000_000;
/// Solid ring around the outline, in raster cells (0.1 m, HouseExpo's wall thickness).
const RING_CELLS: usize = 2;

#[derive(Deserialize)]
struct PlanJson {
    verts: Vec<[f64; 2]>,
    #[serde(default)]
    room_num: Option<usize>,
}

/// An imported plan.
#[derive(Clone, Debug)]
pub struct ImportedPlan {
    pub mesh: TriMesh,
    /// `room_num` from the file, if present.
    pub rooms: Option<usize>,
    /// Free floor area of the raster, m².
    pub free_area_m2: f64,
}

/// Imports a HouseExpo plan from its JSON bytes; `path` names the file in errors.
pub fn import_bytes(path: &Path, bytes: &[u8], cfg: &SceneConfig) -> Result<ImportedPlan> {
    let plan: PlanJson = serde_json::from_slice(bytes)
        .map_err(|e| Error::scene(path, format!("not a HouseExpo plan: {e}")))?;
    let verts = plan.verts;
    if verts.len() < 3 {
        return Err(Error::scene(
            path,
            format!(
                "`verts` has {} points; an outline needs at least 3",
                verts.len()
            ),
        ));
    }
    if let Some(i) = verts
        .iter()
        .position(|v| !(v[0].is_finite() && v[1].is_finite()))
    {
        return Err(Error::scene(path, format!("`verts[{i}]` is not finite")));
    }
    let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for v in &verts {
        for k in 0..2 {
            min[k] = min[k].min(v[k]);
            max[k] = max[k].max(v[k]);
        }
    }
    super::check_extent(path, "plan", (max[0] - min[0]).max(max[1] - min[1]), cfg)?;
    let ring = RING_CELLS as f64 * RASTER_M;
    let origin = [min[0] - ring, min[1] - ring];
    let nx = ((max[0] - min[0]) / RASTER_M).ceil() as usize + 2 * RING_CELLS;
    let ny = ((max[1] - min[1]) / RASTER_M).ceil() as usize + 2 * RING_CELLS;
    // A house plan spans tens of metres; a plan whose raster is far larger (a damaged or mis-scaled
    // coordinate) would take minutes and gigabytes to rasterise and extrude.
    if nx.saturating_mul(ny) > MAX_RASTER_CELLS {
        return Err(Error::scene(
            path,
            format!(
                "plan of {:.1} × {:.1} m is too large to import at {RASTER_M} m ({nx} × {ny} cells, more than {MAX_RASTER_CELLS}); wrong units?",
                max[0] - min[0],
                max[1] - min[1]
            ),
        ));
    }
    let free = rasterise_polygon(&verts, origin, RASTER_M, nx, ny);
    let free_cells = free.iter().filter(|&&f| f).count();
    if free_cells == 0 {
        return Err(Error::scene(path, "outline encloses no floor"));
    }
    let solid: Vec<bool> = free.iter().map(|f| !f).collect();
    Ok(ImportedPlan {
        mesh: extrude_grid(&solid, nx, ny, origin, RASTER_M, cfg.wall_height_m.get()),
        rooms: plan.room_num,
        free_area_m2: free_cells as f64 * RASTER_M * RASTER_M,
    })
}

/// Marks the cells whose centres lie inside the closed polygon (even-odd rule), by scanlines.
pub fn rasterise_polygon(
    verts: &[[f64; 2]],
    origin: [f64; 2],
    res: f64,
    nx: usize,
    ny: usize,
) -> Vec<bool> {
    let mut inside = vec![false; nx * ny];
    let mut crossings = Vec::new();
    for iy in 0..ny {
        let y = origin[1] + (iy as f64 + 0.5) * res;
        crossings.clear();
        for (i, a) in verts.iter().enumerate() {
            let b = verts[(i + 1) % verts.len()];
            // Half-open rule: an edge counts if y lies in [min y, max y), so shared vertices count once.
            if (a[1] <= y) != (b[1] <= y) {
                crossings.push(a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]));
            }
        }
        crossings.sort_by(f64::total_cmp);
        for pair in crossings.chunks_exact(2) {
            // Cells whose centre x lies in [pair[0], pair[1]).
            let first = ((pair[0] - origin[0]) / res - 0.5).ceil().max(0.0) as usize;
            let end = (((pair[1] - origin[0]) / res - 0.5).ceil().max(0.0) as usize).min(nx);
            for ix in first..end {
                inside[iy * nx + ix] = true;
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::scene::tests::data;

    fn cfg() -> SceneConfig {
        Config::default().scene
    }

    #[test]
    fn raster_matches_brute_force_point_in_polygon() {
        // An L-shaped polygon.
        let verts = [
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [0.0, 2.0],
        ];
        let (nx, ny, res, origin) = (26, 26, 0.1, [-0.3, -0.3]);
        let fast = rasterise_polygon(&verts, origin, res, nx, ny);
        for iy in 0..ny {
            for ix in 0..nx {
                let (x, y) = (
                    origin[0] + (ix as f64 + 0.5) * res,
                    origin[1] + (iy as f64 + 0.5) * res,
                );
                let brute =
                    (0.0..2.0).contains(&x) && (0.0..2.0).contains(&y) && !(x >= 1.0 && y >= 1.0);
                assert_eq!(fast[iy * nx + ix], brute, "cell {ix},{iy}");
            }
        }
    }

    #[test]
    fn plan_0000_area_and_rooms() {
        let s = crate::scene::load(&data("house_expo_room_0000.json"), &cfg()).unwrap();
        assert_eq!(s.source, "houseexpo");
        let bytes = std::fs::read(data("house_expo_room_0000.json")).unwrap();
        let plan = import_bytes(Path::new("p.json"), &bytes, &cfg()).unwrap();
        assert_eq!(plan.rooms, Some(4));
        // The data set says 57 m² for this plan (outline interior).
        assert!(
            (plan.free_area_m2 - 57.0).abs() < 4.0,
            "{}",
            plan.free_area_m2
        );
    }

    #[test]
    fn json_1451_agrees_with_the_ply_extrusion() {
        let json = crate::scene::load(&data("house_expo_room_1451.json"), &cfg()).unwrap();
        let ply = crate::scene::load(&data("house_expo_room_1451.ply"), &cfg()).unwrap();
        let (a0, a1) = json.mesh.bounds().unwrap();
        let (b0, b1) = ply.mesh.bounds().unwrap();
        for (a, b) in [(a0.x, b0.x), (a0.y, b0.y), (a1.x, b1.x), (a1.y, b1.y)] {
            assert!((a - b).abs() < 0.15, "json {a} vs ply {b}");
        }
    }

    #[test]
    fn plan_1451_explorable_area_is_plausible() {
        let path = data("house_expo_room_1451.json");
        let text = std::fs::read_to_string(&path).unwrap();
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        let verts: Vec<[f64; 2]> = serde_json::from_value(json["verts"].clone()).unwrap();
        let outline_area = 0.5
            * (0..verts.len())
                .map(|i| {
                    let (a, b) = (verts[i], verts[(i + 1) % verts.len()]);
                    a[0] * b[1] - b[0] * a[1]
                })
                .sum::<f64>()
                .abs();
        // Union of the room boxes (they overlap), rasterised at 0.05 m.
        let boxes: Vec<[f64; 4]> = json["room_category"]
            .as_object()
            .unwrap()
            .values()
            .flat_map(|v| serde_json::from_value::<Vec<[f64; 4]>>(v.clone()).unwrap())
            .collect();
        let union_cells = (0..400 * 400)
            .filter(|i| {
                let (x, y) = (
                    -1.0 + (i % 400) as f64 * 0.05,
                    -1.0 + (i / 400) as f64 * 0.05,
                );
                boxes
                    .iter()
                    .any(|b| x >= b[0] && x < b[2] && y >= b[1] && y < b[3])
            })
            .count();
        let union_area = union_cells as f64 * 0.0025;
        let cfg = Config::default();
        let s = crate::scene::load(&path, &cfg.scene).unwrap();
        let gt = crate::scene::ground_truth::SceneTruth::build(&s.mesh, None, &cfg).unwrap();
        let area = gt.region_cells() as f64 * gt.grid.cell_area();
        assert!((outline_area - 116.6).abs() < 0.1, "{outline_area}");
        // The region is the outline's interior plus a one-cell ring on the walls.
        assert!(
            area > 0.95 * outline_area && area < 1.1 * outline_area,
            "{area} vs {outline_area}"
        );
        assert!(area < union_area, "{area} vs room boxes {union_area}");
    }

    #[test]
    fn huge_plan_is_refused_quickly() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.json");
        let e = import_bytes(
            &p,
            br#"{"verts": [[0.1, 0.1], [915, 0.1], [915, 517], [0.1, 517]]}"#,
            &cfg(),
        )
        .err()
        .unwrap()
        .to_string();
        assert_eq!(
            e,
            format!(
                "{}: plan of 914.9 × 516.9 m is too large to import at 0.05 m (18302 × 10342 cells, more than 16000000); wrong units?",
                p.display()
            )
        );
    }

    #[test]
    fn bad_plans_name_the_file() {
        let e = |text: &str| {
            import_bytes(Path::new("plan.json"), text.as_bytes(), &cfg())
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            e(r#"{"verts": [[0,0],[1,0]]}"#),
            "plan.json: `verts` has 2 points; an outline needs at least 3"
        );
        assert!(e(r#"{"vertz": []}"#)
            .starts_with("plan.json: not a HouseExpo plan: missing field `verts`"));
        assert!(e("garbage").starts_with("plan.json: not a HouseExpo plan: expected value"));
        assert_eq!(
            e(r#"{"verts": [[0,0],[0.01,0],[0,0.01]]}"#),
            "plan.json: outline encloses no floor"
        );
    }
}
