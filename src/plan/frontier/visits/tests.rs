use super::*;
use crate::config::Config;
use crate::map::testing::{furnished_room_setup, seen_from};
use crate::Pose2;
use std::f64::consts::FRAC_PI_2;

/// One look into a furnished room leaves frontier segments; a visit to the longest one.
fn open_visit() -> (Map, Visit) {
    let cfg = Config::default();
    let (grid, bvh) = furnished_room_setup(&cfg);
    let map = seen_from(grid, &cfg, &bvh, [Pose2::new(1.0, 4.0, 0.0)]);
    let target = map
        .frontiers()
        .into_iter()
        .max_by_key(|s| s.cells.len())
        .expect("a frontier")
        .cells;
    assert!(target.len() >= 4, "{}", target.len());
    let aim = grid.index(target[0]);
    let visit = Visit {
        target,
        aim,
        near_view: false,
    };
    assert!(visit.is_open(&map));
    (map, visit)
}

/// [`open_visit`] after a first look from 5 m away, which marks every cell approached (blind
/// zone 1 m), with the planners' memory of it.
fn looked_at_from_afar() -> (Map, Visit, FrontierVisits) {
    let (map, visit) = open_visit();
    let grid = map.grid();
    let mut visits = FrontierVisits::default();
    visits.ensure(grid);
    let aim_p = grid.center(grid.cell(visit.aim));
    let afar = Point2::new(aim_p.x - 5.0, aim_p.y);
    visits.finished(&map, &visit, true, afar, 1.0, &Config::default().camera);
    assert!(visit.target.iter().all(|c| {
        let i = grid.index(*c);
        visits.was_approached(i) && !visits.needs_viewpoint(i)
    }));
    (map, visit, visits)
}

/// [`open_visit`] after a first look from on its aim with the whole segment in the blind zone,
/// which leaves every cell wanting a viewpoint, with the planners' memory of it.
fn looked_at_from_on_it() -> (Map, Visit, FrontierVisits) {
    let (map, visit) = open_visit();
    let grid = map.grid();
    let mut visits = FrontierVisits::default();
    visits.ensure(grid);
    let robot = grid.center(grid.cell(visit.aim));
    let cam = Config::default().camera;
    visits.finished(&map, &visit, true, robot, f64::INFINITY, &cam);
    assert!(visit.target.iter().all(|c| {
        let i = grid.index(*c);
        visits.needs_viewpoint(i) && !visits.was_approached(i)
    }));
    (map, visit, visits)
}

#[test]
fn looks_give_up_a_frontier_cell_only_after_a_look_that_could_show_it() {
    let (map, visit) = open_visit();
    let grid = map.grid();
    let cam = Config::default().camera;
    // Stand on the aim, with a blind zone reaching half way along the segment: the cells within
    // it get no look, and are next looked at from a viewpoint.
    let robot = grid.center(grid.cell(visit.aim));
    let blind = 0.5
        * visit
            .target
            .iter()
            .map(|c| (grid.center(*c) - robot).norm())
            .fold(0.0, f64::max);
    let far = |c: &Cell| (grid.center(*c) - robot).norm() > blind;
    assert!(visit.target.iter().any(far) && !visit.target.iter().all(far));
    let mut visits = FrontierVisits::default();
    visits.ensure(grid);
    visits.finished(&map, &visit, true, robot, blind, &cam);
    for c in &visit.target {
        let i = grid.index(*c);
        assert_eq!(visits.was_approached(i), far(c), "{c:?}");
        assert_eq!(visits.needs_viewpoint(i), !far(c), "{c:?}");
        assert!(!visits.is_unobservable(i));
    }
    // The next look, from on top of a cell that had its look from afar, gives up nothing: the
    // approached cells now want a viewpoint too. (A look from on top counts for the cells in
    // the blind zone around the robot; here that zone spans the whole segment.)
    let aim = grid.index(*visit.target.iter().find(|c| far(c)).unwrap());
    let on_top = Visit {
        aim,
        ..visit.clone()
    };
    let top = grid.center(grid.cell(aim));
    let whole = visit
        .target
        .iter()
        .map(|c| (grid.center(*c) - top).norm())
        .fold(0.0, f64::max);
    visits.finished(&map, &on_top, true, top, whole, &cam);
    for c in &visit.target {
        let i = grid.index(*c);
        assert!(
            visits.needs_viewpoint(i) && !visits.is_unobservable(i),
            "{c:?}"
        );
    }
    // Looks from a viewpoint off the map see none of it: the first gives up nothing, the
    // second gives up the cells looked at from afar and from on top. The cells the first look
    // had in its blind zone count the first viewpoint look as their look from afar and wait
    // for their approach all the way (the aim always counts).
    let view = Visit {
        near_view: true,
        ..visit.clone()
    };
    let nowhere = Point2::new(-100.0, -100.0);
    visits.finished(&map, &view, true, nowhere, blind, &cam);
    assert!(visit
        .target
        .iter()
        .all(|c| !visits.is_unobservable(grid.index(*c))));
    visits.finished(&map, &view, true, nowhere, blind, &cam);
    for c in &visit.target {
        let i = grid.index(*c);
        assert_eq!(visits.is_unobservable(i), far(c) || i == visit.aim, "{c:?}");
    }
}

/// A look from on top of one frontier cell is a look from on top only for the cells in the
/// blind zone around the robot. Counted for the whole segment, a look from on top of a cell
/// gave up cells 3.3–3.6 m from the robot (THP, `plan_28182f788a` start 1).
#[test]
fn a_look_from_on_top_counts_only_for_the_cells_around_the_robot() {
    let (map, visit, mut visits) = looked_at_from_afar();
    let grid = map.grid();
    let cam = Config::default().camera;
    let p0 = grid.center(grid.cell(visit.aim));
    // Twice from on top of one end of the segment.
    let end = *visit
        .target
        .iter()
        .max_by(|a, b| {
            let d = |c: &Cell| (grid.center(*c) - p0).norm();
            d(a).total_cmp(&d(b)).then(a.cmp(b))
        })
        .unwrap();
    let top = grid.center(end);
    // A blind zone around the robot reaching half way along the segment.
    let blind = 0.5
        * visit
            .target
            .iter()
            .map(|c| (grid.center(*c) - top).norm())
            .fold(0.0, f64::max);
    let near = |c: &Cell| (grid.center(*c) - top).norm() <= blind;
    assert!(visit.target.iter().any(|c| !near(c)) && near(&end));
    let on_top = Visit {
        aim: grid.index(end),
        ..visit.clone()
    };
    visits.finished(&map, &on_top, true, top, blind, &cam);
    for c in &visit.target {
        let i = grid.index(*c);
        assert_eq!(visits.needs_viewpoint(i), near(c), "{c:?}");
        assert!(visits.was_approached(i) && !visits.is_unobservable(i));
    }
    visits.finished(&map, &on_top, true, top, blind, &cam);
    for c in &visit.target {
        assert_eq!(visits.is_unobservable(grid.index(*c)), near(c), "{c:?}");
    }
}

/// A look from a viewpoint chosen to see a cell that lay in the blind zone, which showed
/// nothing, counts as its look from afar: the cell's next visit goes all the way onto it. Left
/// unapproached, it stayed a blind-zone cell, the next step back looked from the same spot, and
/// that second look gave it up, never approached (THP, `plan_28182f788a` start 1).
#[test]
fn a_look_from_a_viewpoint_that_shows_nothing_counts_as_the_look_from_afar() {
    // A first look with the whole segment in the blind zone: every cell wants a viewpoint.
    let (map, visit, mut visits) = looked_at_from_on_it();
    let grid = map.grid();
    let cam = Config::default().camera;
    // A look from a viewpoint that sees none of it.
    let view = Visit {
        near_view: true,
        ..visit.clone()
    };
    visits.finished(&map, &view, true, Point2::new(-100.0, -100.0), 1.0, &cam);
    for c in &visit.target {
        let i = grid.index(*c);
        assert!(visits.was_approached(i), "{c:?}");
        assert!(
            !visits.needs_viewpoint(i) && !visits.is_unobservable(i),
            "{c:?}"
        );
    }
}

#[test]
fn a_second_approach_blocked_in_the_blind_zone_counts_as_the_look_from_on_top() {
    let (map, visit) = open_visit();
    let grid = map.grid();
    let cam = Config::default().camera;
    let aim_p = grid.center(grid.cell(visit.aim));
    let blind = 1.0;
    // The first look, from afar, marks the cells approached.
    let afar = Point2::new(aim_p.x - 5.0, aim_p.y);
    let approached = || {
        let mut visits = FrontierVisits::default();
        visits.ensure(grid);
        visits.finished(&map, &visit, true, afar, blind, &cam);
        assert!(visits.was_approached(visit.aim));
        visits
    };
    // Blocked 0.4 m short of the aim (inside the blind zone), twice: the cells want a
    // viewpoint after the first, and only the second gives them up, as two looks from on top.
    let mut visits = approached();
    let short = Point2::new(aim_p.x - 0.4, aim_p.y);
    visits.finished(&map, &visit, false, short, blind, &cam);
    assert!(visits.needs_viewpoint(visit.aim) && !visits.is_unobservable(visit.aim));
    visits.finished(&map, &visit, false, short, blind, &cam);
    assert!(visits.is_unobservable(visit.aim));
    // Blocked beyond the blind zone: failed attempts, the aim given up on the second.
    let mut visits = approached();
    let far = Point2::new(aim_p.x - 1.5, aim_p.y);
    visits.finished(&map, &visit, false, far, blind, &cam);
    assert!(!visits.needs_viewpoint(visit.aim) && !visits.is_unobservable(visit.aim));
    visits.finished(&map, &visit, false, far, blind, &cam);
    assert!(visits.is_unobservable(visit.aim));
}

/// Before `Complete`, a frontier cell given up after two failed attempts is reopened when the
/// camera would surely see the unknown floor beside it from a reachable cell: it next wants a
/// viewpoint, a second call before its look does not count again, and the look from the
/// viewpoint gives it up. While the voxel stays unknown and in sight that repeats, each look
/// from a viewpoint away from the earlier ones, at most `additions.reopen_max` times; then the cell
/// stays given up. Where every cell was looked from, the viewpoint is the one chosen first.
#[test]
fn a_given_up_cell_the_camera_would_see_is_reopened_a_bounded_number_of_times() {
    let cfg = Config::default();
    let cam = cfg.camera.clone();
    let (grid, bvh) = furnished_room_setup(&cfg);
    let turn = |x: f64| (0..24).map(move |k| Pose2::new(x, 4.0, k as f64 * FRAC_PI_2 / 6.0));
    let map = seen_from(grid, &cfg, &bvh, turn(1.0).chain(turn(2.5)));
    let start = grid.index(grid.cell_of(Point2::new(1.0, 4.0)).unwrap());
    let df = crate::plan::search::Search::new(&grid).distance_field(
        &grid,
        |i| map.is_traversable(i).then_some(0.1),
        start,
        f32::INFINITY,
    );
    let segments: Vec<Vec<usize>> = map
        .frontiers()
        .iter()
        .map(|s| s.cells.iter().map(|c| grid.index(*c)).collect())
        .collect();
    let (near, far) = (cam.min_range_m.get(), cam.max_range_m.get());
    let seeable = |i: usize| {
        let ring = viewpoint_ring(&map, &df, i, near, far);
        first_sighted(
            &map,
            &ring,
            &lowest_unknown_beside(&map, i),
            &cam,
            Sight::Sure,
        )
        .is_some()
    };
    let (k, aim) = segments
        .iter()
        .enumerate()
        .flat_map(|(k, s)| s.iter().map(move |&i| (k, i)))
        .find(|&(_, i)| df.cost_to(i).is_some() && seeable(i))
        .expect("a reachable frontier cell the camera would see");
    let visit = Visit {
        target: segments[k].iter().map(|&i| grid.cell(i)).collect(),
        aim,
        near_view: false,
    };
    let mut visits = FrontierVisits::default();
    visits.ensure(&grid);
    let robot = grid.center(grid.cell(start));
    for _ in 0..2 {
        visits.finished(&map, &visit, false, robot, 1.0, &cam);
    }
    assert!(visits.is_unobservable(aim));
    let look = Visit {
        near_view: true,
        ..visit.clone()
    };
    let mut looked_from: Vec<Point2<f64>> = Vec::new();
    // The map does not change here, so the voxel stays unknown and in sight after every look.
    for _ in 0..Config::default().additions.reopen_max {
        assert!(visits
            .reopen_seeable(&map, &df, &segments, &cam, |_| false)
            .contains(&aim));
        assert!(!visits.is_unobservable(aim) && visits.needs_viewpoint(aim));
        assert!(!visits
            .reopen_seeable(&map, &df, &segments, &cam, |_| false)
            .contains(&aim));
        let viewpoint = visits
            .sighted_viewpoint(&map, &df, aim, 1.2, &cam)
            .expect("a viewpoint");
        let at = grid.center(grid.cell(viewpoint));
        let away_m = Config::default().additions.viewpoint_away_m.get();
        assert!(looked_from.iter().all(|p| (p - at).norm() > away_m));
        looked_from.push(at);
        visits.finished(&map, &look, true, at, 1.0, &cam);
        assert!(visits.is_unobservable(aim));
    }
    // (Cells of the segment first given up by a look may still be reopened; the aim is not.)
    visits.reopen_seeable(&map, &df, &segments, &cam, |_| false);
    assert!(visits.is_unobservable(aim));
    // With a look recorded from every cell, the viewpoint is the one chosen with none.
    let first = FrontierVisits::default().sighted_viewpoint(&map, &df, aim, 1.2, &cam);
    assert!(first.is_some());
    visits
        .looked_from
        .extend((0..grid.cells()).map(|k| (aim, k)));
    assert_eq!(visits.sighted_viewpoint(&map, &df, aim, 1.2, &cam), first);
}

/// A look at a cell from a viewpoint rules out the viewpoints within `additions.viewpoint_away_m` of it for
/// that cell only.
#[test]
fn viewpoints_near_where_a_cell_was_looked_at_from_are_not_chosen_for_it_again() {
    let grid = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(3.0, 1.0), 1.8, 0.1);
    let at = |x: f64| grid.index(grid.cell_at(x, 0.55));
    let mut visits = FrontierVisits::default();
    visits.ensure(&grid);
    visits.looked_from.push((at(0.05), at(1.05)));
    let ring: Vec<(f32, usize)> = [0.65, 0.85, 1.05, 1.25, 1.45]
        .iter()
        .map(|&x| (x as f32, at(x)))
        .collect();
    let away = |cell: usize| away_from(&grid, &visits.looked_from_at(&grid, cell), &ring, 0.3);
    let kept: Vec<usize> = away(at(0.05)).iter().map(|r| r.1).collect();
    assert_eq!(kept, vec![at(0.65), at(1.45)]);
    assert_eq!(away(at(0.15)), ring);
}

#[test]
fn looks_from_a_viewpoint_give_up_the_aimed_cell_even_if_it_waits_for_its_approach() {
    // A look from afar: every cell is approached and waits for its look from on top.
    let (map, visit, mut visits) = looked_at_from_afar();
    let grid = map.grid();
    let cam = Config::default().camera;
    // Then two looks from a viewpoint that sees none of it (a distant view of a cell the robot
    // cannot reach): the aim is given up on the second, the other cells still wait.
    let view = Visit {
        near_view: true,
        ..visit.clone()
    };
    let nowhere = Point2::new(-100.0, -100.0);
    visits.finished(&map, &view, true, nowhere, 1.0, &cam);
    assert!(!visits.is_unobservable(visit.aim));
    visits.finished(&map, &view, true, nowhere, 1.0, &cam);
    assert!(visits.is_unobservable(visit.aim));
    assert!(visit
        .target
        .iter()
        .filter(|c| grid.index(**c) != visit.aim)
        .all(|c| !visits.is_unobservable(grid.index(*c))));
}

/// The voxel of layer `iz` above the centre of the cell holding `(x, y)`.

#[test]
fn a_cell_no_viewpoint_sees_gets_the_two_approaches_instead() {
    // A blind zone that holds the whole segment: every cell wants a viewpoint.
    let (map, visit, mut visits) = looked_at_from_on_it();
    let grid = map.grid();
    visits.no_viewpoint(grid, &visit);
    for c in &visit.target {
        let i = grid.index(*c);
        assert!(
            !visits.needs_viewpoint(i) && visits.was_approached(i),
            "{c:?}"
        );
    }
}
