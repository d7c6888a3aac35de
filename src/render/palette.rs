//! The one palette of every picture and log marker: `explore --png`, `scene render`, `field --png`,
//! `replay --render` and the `SceneUpdate` colours of run logs. The same thing has the same colour
//! everywhere; [`LEGEND`] names each entry for the legends drawn on map pictures.

use image::Rgb;

// Map cells.
/// Not yet observed.
pub const UNKNOWN: Rgb<u8> = Rgb([150, 150, 150]);
/// Observed free.
pub const FREE: Rgb<u8> = Rgb([250, 250, 250]);
/// Observed obstacle (or a ground-truth obstacle column in `scene render`).
pub const OCCUPIED: Rgb<u8> = Rgb([20, 20, 20]);
/// Free, but too close to a known obstacle for the robot's centre.
pub const INFLATED: Rgb<u8> = Rgb([214, 226, 240]);
/// Frontier cells (free cells next to unknown ones).
pub const FRONTIER: Rgb<u8> = Rgb([250, 190, 0]);
/// A ground-truth wall the map has not seen.
pub const TRUTH_WALL: Rgb<u8> = Rgb([200, 120, 120]);
/// The explorable region of the ground truth.
pub const REGION: Rgb<u8> = Rgb([225, 236, 250]);
/// Ground truth: floor the robot can reach from the spawn.
pub const REACHABLE_FLOOR: Rgb<u8> = Rgb([214, 238, 210]);
/// Ground truth: observable by the camera from some reachable pose, but not reachable.
pub const OBSERVABLE_UNREACHABLE: Rgb<u8> = Rgb([250, 228, 190]);
/// Ground truth: never observable from the reachable region.
pub const NEVER_OBSERVABLE: Rgb<u8> = Rgb([222, 210, 236]);
/// The scene mesh in a run log's 3D view (drawn faint).
pub const SCENE_MESH: Rgb<u8> = Rgb([150, 150, 165]);

// Robot and paths.
/// The path the robot drove.
pub const PATH: Rgb<u8> = Rgb([30, 90, 220]);
/// The start pose.
pub const START: Rgb<u8> = Rgb([20, 170, 60]);
/// The robot (its last pose in a run picture, its footprint in a log).
pub const ROBOT: Rgb<u8> = Rgb([220, 40, 40]);
/// The camera's field of view.
pub const FOV: Rgb<u8> = Rgb([235, 110, 110]);

// Plans.
/// The path being followed (an A* path or an advected pathline).
pub const PLAN_PATH: Rgb<u8> = Rgb([150, 40, 200]);
/// The planner's tour (TSP order of its goals).
pub const TOUR: Rgb<u8> = Rgb([245, 130, 48]);
/// A distinct colour per frontier group (cycled); none is another palette entry's colour.
pub const GROUP_COLOURS: [Rgb<u8>; 8] = [
    Rgb([230, 25, 75]),
    Rgb([60, 180, 75]),
    Rgb([0, 130, 200]),
    Rgb([0, 0, 128]),
    Rgb([170, 255, 195]),
    Rgb([70, 240, 240]),
    Rgb([240, 50, 230]),
    Rgb([128, 128, 0]),
];

// The tensor field.
/// Wedge degenerate points (index +½).
pub const WEDGE: Rgb<u8> = Rgb([230, 0, 170]);
/// Trisector degenerate points (index −½).
pub const TRISECTOR: Rgb<u8> = Rgb([0, 150, 200]);
/// Degenerate points of higher order or unclassified.
pub const OTHER_DEGENERATE: Rgb<u8> = Rgb([110, 110, 110]);
/// Separatrices traced from the degenerate points.
pub const SEPARATRIX: Rgb<u8> = Rgb([70, 120, 70]);
/// Topology-graph edges (separatrix links and shortest-path pairings).
pub const TOPOLOGY_EDGE: Rgb<u8> = Rgb([170, 110, 0]);
/// Field glyphs (along the major eigenvector) where the field is coherent; they fade towards white
/// where it is nearly isotropic.
pub const GLYPH: Rgb<u8> = Rgb([60, 80, 110]);

/// `c` faded towards white by `amount` in 0..=1 (0 = `c`, 1 = white).
pub fn fade(c: Rgb<u8>, amount: f64) -> Rgb<u8> {
    let t = amount.clamp(0.0, 1.0);
    Rgb(c
        .0
        .map(|v| (f64::from(v) + (255.0 - f64::from(v)) * t).round() as u8))
}

/// How a legend entry is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Swatch {
    /// A filled square (cells).
    Cell,
    /// A short line (paths, edges, glyphs).
    Line,
    /// A disc (points, poses).
    Dot,
}

/// Every palette entry with its legend label and swatch.
pub const LEGEND: &[(&str, Rgb<u8>, Swatch)] = &[
    ("unknown", UNKNOWN, Swatch::Cell),
    ("free", FREE, Swatch::Cell),
    ("obstacle", OCCUPIED, Swatch::Cell),
    ("free, too close for the robot", INFLATED, Swatch::Cell),
    ("frontier", FRONTIER, Swatch::Cell),
    ("unseen wall (ground truth)", TRUTH_WALL, Swatch::Cell),
    ("explorable region", REGION, Swatch::Cell),
    ("reachable floor", REACHABLE_FLOOR, Swatch::Cell),
    (
        "observable but unreachable",
        OBSERVABLE_UNREACHABLE,
        Swatch::Cell,
    ),
    ("never observable", NEVER_OBSERVABLE, Swatch::Cell),
    ("driven path", PATH, Swatch::Line),
    ("start", START, Swatch::Dot),
    ("robot", ROBOT, Swatch::Dot),
    ("camera field of view", FOV, Swatch::Line),
    ("planned path", PLAN_PATH, Swatch::Line),
    ("tour", TOUR, Swatch::Line),
    (
        "frontier groups (a colour each)",
        GROUP_COLOURS[0],
        Swatch::Dot,
    ),
    ("wedge", WEDGE, Swatch::Dot),
    ("trisector", TRISECTOR, Swatch::Dot),
    ("other degenerate point", OTHER_DEGENERATE, Swatch::Dot),
    ("separatrix", SEPARATRIX, Swatch::Line),
    ("topology edge", TOPOLOGY_EDGE, Swatch::Line),
    ("field direction", GLYPH, Swatch::Line),
];

/// The legend entry of colour `c` (label and swatch).
pub fn entry(c: Rgb<u8>) -> (&'static str, Rgb<u8>, Swatch) {
    *LEGEND
        .iter()
        .find(|e| e.1 == c)
        .expect("every palette colour has a legend entry")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_entry_has_its_own_colour_and_label() {
        for (i, a) in LEGEND.iter().enumerate() {
            for b in &LEGEND[i + 1..] {
                assert_ne!(a.1, b.1, "{} and {} share a colour", a.0, b.0);
                assert_ne!(a.0, b.0);
            }
        }
        for g in &GROUP_COLOURS[1..] {
            assert!(LEGEND.iter().all(|e| e.1 != *g), "{g:?}");
        }
        // The pairs the pictures used to confuse.
        assert_ne!(START, WEDGE);
        assert_ne!(PATH, TRISECTOR);
        assert_ne!(ROBOT, WEDGE);
    }

    #[test]
    fn fade_goes_to_white() {
        assert_eq!(fade(GLYPH, 0.0), GLYPH);
        assert_eq!(fade(GLYPH, 1.0), Rgb([255, 255, 255]));
    }
}
