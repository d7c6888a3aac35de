use super::*;
use crate::field::synth::{rasterise, wall};
use crate::field::MaskInputs;

fn edge(a: usize, b: Option<usize>, gain: f64) -> RouteEdge {
    RouteEdge {
        a,
        b,
        gain,
        polyline: vec![Point2::new(a as f64, 0.0), Point2::new(a as f64 + 1.0, 0.0)],
    }
}

/// Total cost of the cheapest spanning tree, by trying every subset of n − 1 edges.
fn brute_force_mst(n: usize, edges: &[RouteEdge]) -> f64 {
    let m = edges.len();
    let mut best = f64::INFINITY;
    for mask in 0u32..(1 << m) {
        if mask.count_ones() as usize != n - 1 {
            continue;
        }
        let mut parent: Vec<usize> = (0..n).collect();
        fn find(p: &mut [usize], x: usize) -> usize {
            if p[x] == x {
                x
            } else {
                let r = find(p, p[x]);
                p[x] = r;
                r
            }
        }
        let mut ok = true;
        let mut cost = 0.0;
        for (k, e) in edges.iter().enumerate() {
            if mask & (1 << k) == 0 {
                continue;
            }
            let (ra, rb) = (find(&mut parent, e.a), find(&mut parent, e.b.unwrap()));
            if ra == rb {
                ok = false;
                break;
            }
            parent[ra] = rb;
            cost += e.cost();
        }
        if ok {
            best = best.min(cost);
        }
    }
    best
}

#[test]
fn mst_agrees_with_brute_force_and_sums_tree_paths() {
    let gains = [
        (0, 1, 0.5),
        (1, 2, 0.1),
        (0, 2, 0.2),
        (2, 3, 0.05),
        (1, 3, 0.04),
        (3, 4, 0.25),
        (2, 4, 0.0),
        (0, 4, 0.02),
    ];
    let edges: Vec<RouteEdge> = gains.iter().map(|&(a, b, g)| edge(a, Some(b), g)).collect();
    let tree = min_spanning_tree(5, &edges, 0);
    let total: f64 = tree
        .parent_edge
        .iter()
        .flatten()
        .map(|&k| edges[k].cost())
        .sum();
    assert_eq!(tree.parent_edge.iter().flatten().count(), 4);
    assert!((total - brute_force_mst(5, &edges)).abs() < 1e-9);
    // Known answer: 0-1 (2), 0-2 (5), 2-3 (20), 3-4 (4).
    assert!((total - 31.0).abs() < 1e-9, "{total}");
    assert_eq!(tree.dist[0], 0.0);
    assert!((tree.dist[4] - (5.0 + 20.0 + 4.0)).abs() < 1e-9);
    // Unreached nodes stay at infinity.
    let tree = min_spanning_tree(6, &edges, 0);
    assert!(tree.dist[5].is_infinite() && tree.parent_edge[5].is_none());
}

#[test]
fn target_is_the_cheapest_edge_with_gain_over_the_tree() {
    // A path 0 - 1 - 2 without gain; a leaf with gain at 2 and a weaker one at 0.
    let edges = vec![
        edge(0, Some(1), 0.0),
        edge(1, Some(2), 0.0),
        edge(2, None, 0.5),
        edge(0, None, 0.02),
    ];
    let tree = min_spanning_tree(3, &edges, 0);
    // Leaf at 0 costs 50; the one at 2 costs 1000 + 1000 + 2.
    let t = select_target(&edges, &tree, 0.01).unwrap();
    assert_eq!((t.edge, t.node), (3, 0));
    assert!((t.cost - 50.0).abs() < 1e-9);
    // With the root at 2 the strong leaf is right there.
    let tree = min_spanning_tree(3, &edges, 2);
    let t = select_target(&edges, &tree, 0.01).unwrap();
    assert_eq!((t.edge, t.node), (2, 2));
}

#[test]
fn no_target_when_every_gain_is_below_the_threshold() {
    let edges = vec![
        edge(0, Some(1), 0.009),
        edge(1, None, 0.0),
        edge(0, None, 0.005),
    ];
    let tree = min_spanning_tree(2, &edges, 0);
    assert_eq!(select_target(&edges, &tree, 0.01), None);
    // An edge with gain outside the root's component is not accessible from it either.
    let edges = vec![edge(0, Some(1), 0.0), edge(2, None, 0.9)];
    let tree = min_spanning_tree(3, &edges, 0);
    assert_eq!(select_target(&edges, &tree, 0.01), None);
}

#[test]
fn gain_counts_frontier_cells_in_the_view_square() {
    let grid = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(10.0, 4.0), 2.0, 0.1);
    let f = grid.index(grid.cell_of(Point2::new(8.05, 2.05)).unwrap());
    let gains = GainMap::new(&grid, 1.0, |i| i == f);
    // One cell in a 21-cell-wide square: 1/21.
    assert!((gains.at(Point2::new(8.0, 2.0)) - 1.0 / 21.0).abs() < 1e-12);
    assert!((gains.at(Point2::new(7.05, 2.05)) - 1.0 / 21.0).abs() < 1e-12);
    assert_eq!(gains.at(Point2::new(6.5, 2.0)), 0.0);
    // A line from x = 5 to 9: the cell is in view from x ≥ 7, half of the line.
    let line = [Point2::new(5.0, 2.05), Point2::new(9.0, 2.05)];
    let mean = gains.mean_along(&line);
    assert!((mean - 0.5 / 21.0).abs() < 1e-9, "{mean}");
}

/// Branch choice on a synthetic map: a trisector at the origin with three open separatrices,
/// and frontier cells only at the end of the one going north-east.
#[test]
fn branch_with_frontier_cells_is_chosen() {
    let grid = GridSpec::covering(Point2::new(-6.0, -6.0), Point2::new(6.0, 6.0), 2.0, 0.1);
    let frontier: Vec<bool> = (0..grid.cells())
        .map(|i| {
            let p = grid.center(grid.cell(i));
            (p.x - 3.5).abs() < 0.3 && (p.y - 3.5).abs() < 0.3
        })
        .collect();
    let gains = GainMap::new(&grid, 2.0, |i| frontier[i]);
    let branch = |angle: f64| {
        let polyline: Vec<Point2<f64>> = (0..=40)
            .map(|k| Point2::new(0.1 * k as f64 * angle.cos(), 0.1 * k as f64 * angle.sin()))
            .collect();
        RouteEdge {
            a: 0,
            b: None,
            gain: gains.mean_along(&polyline),
            polyline,
        }
    };
    let dirs = [std::f64::consts::FRAC_PI_4, 2.6, -1.9];
    let edges: Vec<RouteEdge> = dirs.iter().map(|&d| branch(d)).collect();
    assert!(edges[0].gain >= 0.01);
    assert!(edges[1].gain < 0.01 && edges[2].gain < 0.01);
    let tree = min_spanning_tree(1, &edges, 0);
    let t = select_target(&edges, &tree, 0.01).unwrap();
    assert_eq!((t.edge, t.node), (0, 0));
    let h = leaving_heading(&edges[t.edge], 0, 0.6).unwrap();
    assert!((h - std::f64::consts::FRAC_PI_4).abs() < 1e-9);
    // Without the frontier there is nothing to choose: termination.
    let none = GainMap::new(&grid, 2.0, |_| false);
    assert_eq!(none.mean_along(&edges[0].polyline), 0.0);
}

/// The line field has no sign: the pathline leaves in the direction nearest the heading.
#[test]
fn pathline_is_oriented_by_the_heading() {
    let layout = rasterise(
        &[wall(0.0, 0.0, 8.0, 0.0, 0.2)],
        Point2::new(-1.0, -1.0),
        Point2::new(9.0, 3.0),
        0.1,
        0.0,
        Point2::origin(),
    );
    let cfg = Config::default();
    let mut planner = Tensor::new(&TensorParams::from(&cfg));
    let mut field = TensorField::new(layout.grid, &planner.field_cfg);
    let inputs = MaskInputs::new(&layout.grid, &layout.surface, &layout.surface, None).unwrap();
    field.update(&inputs).unwrap();
    planner.field = Some(field);
    let stop = StopConditions::border_only(&layout.grid);
    let start = Point2::new(4.0, 0.6);
    for (heading, sign) in [(0.3, 1.0), (2.9, -1.0), (-0.5, 1.0), (-2.0, -1.0)] {
        let (line, reason) = planner.trace_pathline(start, heading, 0.0, 1.2, 1.0, &stop);
        assert_eq!(reason, StopReason::MaxLength);
        let d = line.last().unwrap() - start;
        // Along the wall (the major eigenvector is its tangent), in the heading's sense.
        assert!(d.x * sign > 1.1, "heading {heading}: {d:?}");
        assert!(d.y.abs() < 0.1, "heading {heading}: {d:?}");
    }
}

/// The mode table: a stall during `UntilGain` queues one GREEDY leg, after which GREEDY goes
/// on until the graph has gain; without the hand-over stalls change nothing; every mode is
/// left again by the events that end it.
#[test]
fn mode_transitions() {
    use Event::*;
    let run = |events: &[Event], hand_over: bool| {
        events
            .iter()
            .fold(Mode::Field, |m, &e| m.next(e, hand_over))
    };
    assert_eq!(run(&[NoRoute], true), Mode::UntilGain);
    assert_eq!(run(&[NoRoute, Stalled], true), Mode::LegThenUntilGain);
    assert_eq!(run(&[NoRoute, Stalled, LegReached], true), Mode::UntilGain);
    assert_eq!(
        run(&[NoRoute, Stalled, LegReached, GainAgain], true),
        Mode::Field
    );
    assert_eq!(run(&[Stalled, NoRoute, Arrived], true), Mode::Leg);
    assert_eq!(run(&[Stalled, Stalled, LegReached], true), Mode::Field);
    assert_eq!(run(&[Stalled], false), Mode::Field);
    assert_eq!(run(&[NoRoute, Stalled], false), Mode::UntilGain);
    for m in [
        Mode::Field,
        Mode::UntilGain,
        Mode::Leg,
        Mode::LegThenUntilGain,
    ] {
        // From every mode: a leg ends on reaching its goal and gain ends `UntilGain`.
        assert!(!matches!(
            m.next(LegReached, true).next(GainAgain, true),
            Mode::Leg | Mode::LegThenUntilGain | Mode::UntilGain
        ));
    }
}

/// Between key frames the field moves from the middle frame toward the new key frame.
#[test]
fn field_time_runs_from_the_middle_frame_to_the_key_frame() {
    let cfg = Config::default();
    let mut planner = Tensor::new(&TensorParams::from(&cfg));
    planner.key_time_s = 8.0;
    assert!((planner.tau(8.0) - 0.5).abs() < 1e-12);
    assert!((planner.tau(10.0) - 0.75).abs() < 1e-12);
    assert!((planner.tau(12.0) - 1.0).abs() < 1e-12);
    assert!((planner.tau(20.0) - 1.0).abs() < 1e-12);
    assert!((planner.substep_s() - 0.4).abs() < 1e-12);
    assert!((planner.pathline_length(1.0) - 1.2).abs() < 1e-12);
}
