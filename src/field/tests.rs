//! Known-answer and invariant tests of the whole engine on synthetic layouts.

use super::synth::{self, rasterise, room, wall, Layout, Rect};
use super::*;
use crate::config::Config;
use nalgebra::{Rotation2, Vector2};

fn cfg() -> FieldConfig {
    Config::default().field
}

fn layout(rects: &[Rect], lo: (f64, f64), hi: (f64, f64)) -> Layout {
    rasterise(
        rects,
        Point2::new(lo.0, lo.1),
        Point2::new(hi.0, hi.1),
        0.1,
        0.0,
        Point2::origin(),
    )
}

fn run(l: &Layout, cfg: &FieldConfig) -> TensorField {
    full_field(&l.grid, &l.surface, &l.surface, cfg).unwrap().0
}

#[test]
fn single_wall_has_no_degenerate_point() {
    let l = layout(&[wall(1.0, 3.03, 9.0, 3.03, 0.2)], (0.0, 0.0), (10.0, 6.0));
    let f = run(&l, &cfg());
    assert!(f.surface_constraint_count() > 30);
    assert!(f.points().is_empty(), "{:?}", f.points());
    // The raw topology field has no point either (nothing was filtered away).
    assert!(degenerate::detect(f.topology_field()).is_empty());
}

#[test]
fn closed_convex_room_sums_to_index_one_on_its_medial_axis() {
    let (x0, y0, x1, y1) = (1.03, 1.07, 7.03, 5.07);
    let l = layout(&room(x0, y0, x1, y1, 0.2), (0.0, 0.0), (8.0, 6.0));
    let mut c = cfg();
    c.cancel_pairs = false;
    c.move_trisectors_from_obstacles = false;
    let f = run(&l, &c);
    let inside: Vec<&DegeneratePoint> = f
        .points()
        .iter()
        .filter(|p| p.x > x0 && p.x < x1 && p.y > y0 && p.y < y1)
        .collect();
    assert!(!inside.is_empty());
    // Windings sum to 2 (tensor indices to +1), as Poincaré–Hopf requires for a tangential boundary.
    assert_eq!(
        inside.iter().map(|p| p.winding).sum::<i32>(),
        2,
        "{inside:?}"
    );
    assert!(inside.len() <= 4, "{inside:?}");
    for p in &inside {
        let mut d = [p.x - x0, x1 - p.x, p.y - y0, y1 - p.y];
        d.sort_by(f64::total_cmp);
        assert!(
            d[1] - d[0] < 0.5,
            "{p:?} is {} m off the medial axis",
            d[1] - d[0]
        );
        assert!(d[0] > 1.0, "{p:?} is in the open near a wall");
    }
}

#[test]
fn t_and_plus_junctions_have_trisectors_at_the_junction() {
    // + : corridors 2 m and 2.2 m wide crossing at (6, 6).
    let t = 0.2;
    let plus = vec![
        wall(0.0, 5.0, 5.0, 5.0, t),
        wall(7.0, 5.0, 12.0, 5.0, t),
        wall(0.0, 7.0, 5.0, 7.0, t),
        wall(7.0, 7.0, 12.0, 7.0, t),
        wall(5.0, 0.0, 5.0, 5.0, t),
        wall(5.0, 7.0, 5.0, 12.0, t),
        wall(7.0, 0.0, 7.0, 5.0, t),
        wall(7.0, 7.0, 7.0, 12.0, t),
    ];
    let junction = [(plus, Point2::new(6.0, 6.0), -2)];
    // T: a corridor along x at y ∈ [5, 7] and a branch going up at x ∈ [5, 7].
    let tee = vec![
        wall(0.0, 5.0, 12.0, 5.0, t),
        wall(0.0, 7.0, 5.0, 7.0, t),
        wall(7.0, 7.0, 12.0, 7.0, t),
        wall(5.0, 7.0, 5.0, 12.0, t),
        wall(7.0, 7.0, 7.0, 12.0, t),
    ];
    let mut c = cfg();
    c.stop_at_unknown = false;
    for (rects, centre, total) in junction
        .into_iter()
        .chain([(tee, Point2::new(6.0, 6.0), -1)])
    {
        let l = layout(&rects, (0.03, 0.07), (12.03, 12.07));
        let f = run(&l, &c);
        let near: Vec<&DegeneratePoint> = f
            .points()
            .iter()
            .filter(|p| (p.pos() - centre).norm() < 1.2)
            .collect();
        assert!(
            near.iter().any(|p| p.kind == DegenerateKind::Trisector),
            "{:?}",
            f.points()
        );
        assert_eq!(
            near.iter().map(|p| p.winding).sum::<i32>(),
            total,
            "{near:?}"
        );
    }
}

fn level_with(cs: &[Constraint], grid: GridSpec) -> FieldLevel {
    let mut l = FieldLevel::new(grid, 1, Kernel::new(0.5, 1.0, 1e-12));
    for c in cs {
        l.insert(*c);
    }
    l.refresh();
    l
}

#[test]
fn translating_or_rotating_constraints_moves_points_and_field_alike() {
    // A room-like set of free constraints with a few diagonal ones, so points are isolated.
    let mut cs = path_constraints(
        &[
            Point2::new(2.0, 2.0),
            Point2::new(5.0, 2.2),
            Point2::new(5.3, 4.5),
            Point2::new(2.2, 4.9),
            Point2::new(2.0, 2.0),
        ],
        0.2,
        1.0,
        f64::INFINITY,
    );
    cs.retain(|c| c.pos.x > 0.0);
    let grid = GridSpec::covering(Point2::new(-3.0, -3.0), Point2::new(10.0, 10.0), 1.0, 0.1);
    let base = level_with(&cs, grid);
    let pts = degenerate::detect(&base.grid);
    assert!(!pts.is_empty());
    let pivot = Point2::new(3.6, 3.4);
    for (angle, shift) in [(0.0, Vector2::new(0.7, -0.3)), (0.5, Vector2::zeros())] {
        let rot = Rotation2::new(angle);
        let moved: Vec<Constraint> = cs
            .iter()
            .map(|c| {
                let dir = rot * Vector2::new(c.angle().cos(), c.angle().sin());
                Constraint::along(pivot + rot * (c.pos - pivot) + shift, dir, 1.0, None).unwrap()
            })
            .collect();
        let lvl = level_with(&moved, grid);
        let moved_pts = degenerate::detect(&lvl.grid);
        assert_eq!(moved_pts.len(), pts.len());
        for p in &pts {
            let want = pivot + rot * (p.pos - pivot) + shift;
            let got = moved_pts
                .iter()
                .filter(|q| q.winding == p.winding)
                .map(|q| (q.pos - want).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(got < 0.05, "angle {angle}: point moved by {got}");
        }
        // The field at a transformed point is the transformed field (reference evaluation).
        let k = Kernel::new(0.5, 1.0, 1e-12);
        for q in [
            Point2::new(3.0, 3.0),
            Point2::new(4.4, 2.9),
            Point2::new(7.0, 1.0),
        ] {
            let a = eval::reference_at(&cs, q, &k);
            let b = eval::reference_at(&moved, pivot + rot * (q - pivot) + shift, &k);
            assert!((a.mu() - b.mu()).abs() < 1e-9);
            assert!(crate::util::wrap_angle(2.0 * (b.theta() - a.theta() - angle)).abs() < 1e-9);
        }
    }
}

#[test]
fn office_fast_field_matches_reference_and_points_are_few_and_clear() {
    let l = synth::office(0.1);
    let (mut f, _) = full_field(&l.grid, &l.surface, &l.surface, &cfg()).unwrap();
    let cmp = max_orientation_difference_vs_reference(&mut f);
    assert!(cmp.max_orientation_difference_rad < 1e-6, "{cmp:?}");
    let n = f.points().len();
    eprintln!(
        "office: {} constraints, {} wedges, {} trisectors, {} other, {} edges",
        f.surface_constraint_count(),
        f.graph().counts().0,
        f.graph().counts().1,
        f.graph().nodes.len() - f.graph().counts().0 - f.graph().counts().1,
        f.graph().edges.len()
    );
    assert!((8..=60).contains(&n), "{n} points");
    for p in f.points() {
        assert!(p.clearance_m >= 0.25, "{p:?}");
    }
    // Every room and the junction has a point: centres of the eight rooms.
    for (cx, cy) in [
        (2.25, 4.5),
        (6.75, 4.5),
        (2.25, 15.5),
        (6.75, 15.5),
        (13.0, 15.5),
        (17.5, 15.5),
    ] {
        let c = Point2::new(cx, cy);
        let d = f
            .points()
            .iter()
            .map(|p| (p.pos() - c).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(d < 3.0, "no point within 3 m of room centre {c:?}");
    }
    assert!(f
        .graph()
        .nodes
        .iter()
        .any(|n| matches!(n.kind, DegenerateKind::Trisector | DegenerateKind::Wedge)));
}

/// Viewpoints along the synthetic office's corridor, revealed one by one.
const OFFICE_ROUTE: [Point2<f64>; 5] = [
    Point2::new(2.0, 10.0),
    Point2::new(6.0, 10.0),
    Point2::new(10.0, 10.0),
    Point2::new(10.0, 14.0),
    Point2::new(10.0, 18.0),
];

#[test]
fn points_stay_put_as_more_of_an_axis_aligned_scene_is_revealed() {
    let l = synth::office(0.1);
    let mut f = TensorField::new(l.grid, &cfg());
    let route = OFFICE_ROUTE;
    let mut previous: Vec<DegeneratePoint> = Vec::new();
    let mut seen_centres: Vec<Point2<f64>> = Vec::new();
    for (k, c) in route.iter().enumerate() {
        seen_centres.push(*c);
        let surface = synth::reveal(&l, &seen_centres, 7.0);
        let inputs = MaskInputs::new(&l.grid, &surface, &surface, None).unwrap();
        f.update(&inputs).unwrap();
        // Points well inside what was already seen two key frames ago keep their id and place.
        if k >= 2 {
            let settled = |p: &DegeneratePoint| {
                seen_centres[..k - 1]
                    .iter()
                    .any(|c| (p.pos() - c).norm() < 3.0)
            };
            for old in previous.iter().filter(|p| settled(p)) {
                let now = f.points().iter().find(|p| p.id == old.id);
                let now = now.unwrap_or_else(|| panic!("key frame {k}: point {old:?} lost"));
                assert!((now.pos() - old.pos()).norm() < 0.3, "{old:?} -> {now:?}");
            }
        }
        previous = f.points().to_vec();
        // Incremental equals a full recompute of the same constraints.
        let mut full = f.clone();
        full.recompute_all();
        assert_eq!(full.field(), f.field());
    }
}

#[test]
fn biharmonic_time_interpolation_gives_smoother_pathlines_than_linear() {
    let rects_a = vec![
        wall(0.0, 0.0, 8.0, 0.0, 0.2),
        wall(0.0, 4.0, 3.0, 4.0, 0.2),
        wall(0.0, 0.0, 0.0, 4.0, 0.2),
    ];
    let mut rects_b = rects_a.clone();
    rects_b.push(wall(4.0, 2.5, 4.0, 4.0, 0.2));
    rects_b.push(wall(5.0, 4.0, 8.0, 4.0, 0.2));
    let (la, lb) = (
        layout(&rects_a, (-0.5, -0.5), (8.5, 4.5)),
        layout(&rects_b, (-0.5, -0.5), (8.5, 4.5)),
    );
    let c = cfg();
    let (fa, fb) = (run(&la, &c), run(&lb, &c));
    let start = Point2::new(1.5, 2.0);
    let params = SpaceTimeParams {
        substeps: c.substeps,
        omega_s: c.omega_s,
        omega_t: c.omega_t,
        alpha: c.alpha,
        max_iterations: c.timevary_max_iterations,
        tolerance: 1e-10,
    };
    let bih =
        biharmonic_window(fa.field(), fb.field(), Point2::new(3.0, 2.0), 2.5, &params).unwrap();
    let lin = linear_window(
        fa.field(),
        fb.field(),
        Point2::new(3.0, 2.0),
        2.5,
        c.substeps,
    )
    .unwrap();
    // Key frames are reproduced (α is large).
    let i = bih.width * 10 + 10;
    let g = &fa.field().spec;
    let gi = g.index(Cell::new(bih.corner.x + 10, bih.corner.y + 10));
    assert!((bih.frames[0][i][0] - fa.field().ab[gi][0]).abs() < 1e-2);
    let stop = StopConditions::border_only(g);
    let length = 3.0;
    let turn = |tv: &TimeVaryingField| {
        let (line, _) = advect::trace(
            |p, s| tv.sample(p, s / length),
            start,
            0.0,
            length,
            0.05,
            &stop,
        );
        assert!(line.len() > 20);
        advect::mean_turn(&line)
    };
    let (tb, tl) = (turn(&bih), turn(&lin));
    eprintln!(
        "mean turn per step: biharmonic {tb:.5}, linear {tl:.5}, CG iterations {}",
        bih.iterations
    );
    assert!(tb < tl, "biharmonic {tb} vs linear {tl}");
}

#[test]
fn mismatched_layers_are_reported() {
    let g = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(1.0, 1.0), 1.0, 0.1);
    let e = MaskInputs::new(&g, &[false; 3], &[false; 100], None).unwrap_err();
    assert_eq!(
        e.to_string(),
        "field input layer `surface` has 3 cells, the grid has 100"
    );
}

#[test]
fn trisector_near_an_obstacle_is_moved_out() {
    // A T junction with a narrow branch: its trisector sits close to the walls.
    let t = 0.2;
    let rects = vec![
        wall(0.0, 5.0, 12.0, 5.0, t),
        wall(0.0, 6.2, 5.6, 6.2, t),
        wall(6.4, 6.2, 12.0, 6.2, t),
        wall(5.6, 6.2, 5.6, 10.0, t),
        wall(6.4, 6.2, 6.4, 10.0, t),
    ];
    let l = layout(&rects, (0.03, 0.07), (12.03, 12.07));
    let mut c = cfg();
    c.cancel_pairs = false;
    c.move_trisectors_from_obstacles = false;
    c.min_clearance_m = 0.0;
    let before = run(&l, &c);
    let close: Vec<&DegeneratePoint> = before
        .points()
        .iter()
        .filter(|p| p.kind == DegenerateKind::Trisector && p.clearance_m < c.trisector_clearance_m)
        .collect();
    assert!(!close.is_empty(), "{:?}", before.points());
    c.move_trisectors_from_obstacles = true;
    let after = run(&l, &c);
    assert!(after.control_counts().moved_trisectors >= 1);
    let still = after
        .points()
        .iter()
        .filter(|p| {
            p.kind == DegenerateKind::Trisector && p.clearance_m < c.trisector_clearance_m - 0.15
        })
        .count();
    assert!(still < close.len(), "{:?}", after.points());
}

#[test]
fn sharp_wedges_are_those_with_separatrices_under_ninety_degrees() {
    assert!(sharp(&[0.1, 1.2, 3.0]));
    assert!(sharp(&[6.2, 0.5]));
    assert!(!sharp(&[0.0, 2.1, 4.2]));
    assert!(!sharp(&[1.0]));
}

#[test]
fn path_constraints_steer_the_planning_field_not_the_topology() {
    let l = layout(&room(1.03, 1.07, 9.03, 5.07, 0.2), (0.0, 0.0), (10.0, 6.0));
    let mut f = run(&l, &cfg());
    let points: Vec<DegeneratePoint> = f.points().to_vec();
    // A diagonal path across the room: near it the major eigenvector follows it.
    let (a, b) = (Point2::new(3.0, 2.0), Point2::new(7.0, 4.0));
    assert!(f.set_path(&[a, b]) > 0);
    let mid = Point2::new(5.0, 3.0);
    let s = f.sample(mid).unwrap();
    let want = (b.y - a.y).atan2(b.x - a.x);
    assert!(
        crate::util::wrap_angle(2.0 * (s.theta() - want)).abs() < 0.05,
        "{}",
        s.theta()
    );
    let (line, _) = f.pathline(Point2::new(4.0, 2.5), want, 2.0, false);
    let end = *line.last().unwrap();
    assert!(((end.y - 2.5) - 0.5 * (end.x - 4.0)).abs() < 0.1, "{end:?}");
    f.compute_topology();
    assert_eq!(f.points(), &points[..]);
    // Clearing the path restores the field exactly.
    f.set_path(&[]);
    let again = run(&l, &cfg());
    assert_eq!(f.field(), again.field());
}

#[test]
fn lazy_planning_field_equals_the_eager_one_after_key_frames_and_paths() {
    // The office revealed key frame by key frame, with a path set between key frames (as THP does):
    // the lazy field's pathlines, whole field, points and graph equal those of the eager field.
    let l = synth::office(0.1);
    let mut eager = TensorField::new(l.grid, &cfg());
    let mut lazy = TensorField::new(l.grid, &cfg());
    lazy.set_lazy_planning_field(true);
    let route = OFFICE_ROUTE;
    let mut seen = Vec::new();
    for (k, c) in route.iter().enumerate() {
        seen.push(*c);
        let surface = synth::reveal(&l, &seen, 7.0);
        let inputs = MaskInputs::new(&l.grid, &surface, &surface, None).unwrap();
        eager.update(&inputs).unwrap();
        lazy.update(&inputs).unwrap();
        assert_eq!(lazy.points(), eager.points(), "key frame {k}");
        let path = [*c, route[(k + 1) % route.len()]];
        eager.set_path(&path);
        lazy.set_path(&path);
        for heading in [0.0, 1.0, 2.5, 4.0] {
            assert_eq!(
                lazy.pathline_computing(*c, heading, 2.0, false),
                eager.pathline(*c, heading, 2.0, false),
                "key frame {k}, heading {heading}"
            );
        }
        // The pathlines computed part of the field, not all of it.
        assert!(lazy.main.is_stale(), "key frame {k}");
        assert_eq!(lazy.field(), eager.field(), "key frame {k}");
        let mut full = eager.clone();
        full.recompute_all();
        assert_eq!(full.field(), lazy.field(), "key frame {k}");
        assert_eq!(lazy.graph(), eager.graph(), "key frame {k}");
    }
}
