//! The online TSP over the groups (THP §3.3, Alg. 1, Eq. 6): when the tour is solved again, where
//! it starts, and the path costs between the groups' access cells, cached between solves.

use super::grouping::{Frontier, Node};
use crate::config::{Grouping, ThpConfig, TourCosts, TourStart};
use crate::grid::GridSpec;
use crate::map::Map;
use crate::plan::search::{DistanceField, Search};
use crate::plan::tsp::{self, CostMatrix};
use crate::plan::{Count, StepCosts};
use nalgebra::Point2;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

/// A tour's first group whose entry is farther than the nearest group's by more than this counts
/// as not starting at the nearest group (`tour_starts_not_nearest_group`), metres: about a cell.
const TOUR_START_SLACK_M: f64 = 0.1;

/// The tour of Alg. 1: the node keys in the order the robot visits them, the cached path costs it
/// is solved with, and its counters. THP asks it for the next node at every goal choice
/// ([`Tour::plan`]); the volume views before `Complete` borrow its cost cache
/// ([`Tour::cost_matrix`]).
#[derive(Clone, Default)]
pub(super) struct Tour {
    /// Node keys in tour order, and their positions (for the log).
    order: Vec<usize>,
    points: Vec<Point2<f64>>,
    /// Cached rows of path costs between access cells.
    cost_rows: CostRows,
    /// Search workspaces for computing cost rows in parallel (one per worker, made on first use).
    row_searches: Vec<Search>,
    /// Time spent solving since [`Tour::take_solve_ms`], milliseconds.
    solve_ms: Option<f64>,
    stats: TourStats,
}

/// The tour's counters (`planner_stats`).
#[derive(Clone, Copy, Debug, Default)]
struct TourStats {
    solves: Count,
    nodes_max: Count,
    nodes_total: Count,
    cost_rows: Count,
    /// Tours that start at a group the robot does not reach at least cost (its least-cost frontier
    /// farther than another group's), and the sum of those extra path costs, metres.
    starts_not_nearest_group: Count,
    start_extra_m: Count,
}

/// What one planning step gives the tour: the map, the time, the step costs and the robot's
/// distance field under them.
pub(super) struct TourInputs<'a> {
    pub(super) map: &'a Map,
    pub(super) time_s: f64,
    pub(super) costs: &'a StepCosts,
    pub(super) df: &'a DistanceField,
}

impl Tour {
    /// Alg. 1: solves the tour over `nodes` again when `P*` is not empty (`new_anchors`), when a
    /// node is not on it, or at every choice without anchor grouping; else follows it, dropping
    /// the nodes that are gone (visited anchors). `current` is the node the robot is scanning, kept
    /// as the start of a new tour under `thp.finish_group_first`. Returns the tour's first node and
    /// its least-cost frontier; `None` (and no tour) when there is no node.
    pub(super) fn plan(
        &mut self,
        at: &TourInputs,
        cfg: &ThpConfig,
        nodes: &[Node],
        fronts: &[Frontier],
        new_anchors: bool,
        current: Option<usize>,
    ) -> Option<(usize, Frontier)> {
        if nodes.is_empty() {
            self.order.clear();
            self.points.clear();
            return None;
        }
        if needs_solve(&self.order, nodes, new_anchors, cfg.grouping) {
            self.solve(at, cfg, nodes, fronts, current);
        } else {
            self.keep_nodes(nodes);
        }
        let first = self.order[0];
        let node = nodes
            .iter()
            .find(|n| n.key == first)
            .expect("tour covers the nodes");
        Some((first, node.nearest_member(fronts).clone()))
    }

    /// Follows the tour: drops the keys no node has any more, and keeps the order.
    fn keep_nodes(&mut self, nodes: &[Node]) {
        let keep: Vec<(usize, Point2<f64>)> = self
            .order
            .iter()
            .zip(&self.points)
            .filter(|(k, _)| nodes.iter().any(|n| n.key == **k))
            .map(|(k, p)| (*k, *p))
            .collect();
        self.order = keep.iter().map(|k| k.0).collect();
        self.points = keep.iter().map(|k| k.1).collect();
    }

    /// The tour's node positions in order (drawn in the log).
    pub(super) fn points(&self) -> &[Point2<f64>] {
        &self.points
    }

    /// The solve time since the last call, milliseconds; `None` if the tour was not solved.
    pub(super) fn take_solve_ms(&mut self) -> Option<f64> {
        self.solve_ms.take()
    }

    /// Solves the fixed-start open TSP over `nodes` (Eq. 6) with path costs between the nodes'
    /// access cells ([`access_cells`]), from the start [`Tour::plan`] and `thp.tour_start` say:
    /// - `current`, if given;
    /// - `robot`: the robot's cell is an extra node, the fixed start, with the robot's path costs
    ///   to each access cell; the first group is the one the cheapest whole tour begins with;
    /// - `nearest_anchor` (default): the node whose anchor is nearest the robot by path cost
    ///   (Alg. 1, "start at the anchor nearest the robot", [`nearest_anchor_node`]), even when it
    ///   lies behind the robot and the rest ahead.
    fn solve(
        &mut self,
        at: &TourInputs,
        cfg: &ThpConfig,
        nodes: &[Node],
        fronts: &[Frontier],
        current: Option<usize>,
    ) {
        let t = Instant::now();
        let grid = *at.map.grid();
        let access = access_cells(at.map, at.df, nodes, fronts, cfg.tour_costs);
        let start = current.and_then(|k| nodes.iter().position(|n| n.key == k));
        let m = self.cost_matrix(at, cfg, &access);
        let order: Vec<usize> = match (start, cfg.tour_start) {
            (Some(start), _) => tsp::solve(&m, start, cfg.exact_tsp_max_nodes).order,
            (None, TourStart::Robot) => {
                open_tour_from(&m, &costs_from(at.df, &access), cfg.exact_tsp_max_nodes)
            }
            (None, TourStart::NearestAnchor) => {
                let start = nearest_anchor_node(&grid, at.df, nodes, fronts);
                tsp::solve(&m, start, cfg.exact_tsp_max_nodes).order
            }
        };
        // How much nearer another group's entry was than the first group's (a cause of THP's
        // longer legs traced on real plans: an anchor near the robot whose frontiers are not).
        // A group's entry is its least-cost frontier, whichever cell its costs start from.
        let entry = |k: usize| f64::from(nodes[k].nearest_member(fronts).cost);
        let nearest = (0..nodes.len()).map(entry).fold(f64::INFINITY, f64::min);
        if let Some(&first) = order.first() {
            let extra = entry(first) - nearest;
            if extra.is_finite() && extra > TOUR_START_SLACK_M {
                self.stats.starts_not_nearest_group.add(1.0);
                self.stats.start_extra_m.add(extra);
            }
        }
        self.order = order.iter().map(|&i| nodes[i].key).collect();
        self.points = order.iter().map(|&i| nodes[i].pos).collect();
        let ms = t.elapsed().as_secs_f64() * 1e3;
        self.solve_ms = Some(self.solve_ms.unwrap_or(0.0) + ms);
        self.stats.solves.add(1.0);
        let n = nodes.len() as f64;
        self.stats.nodes_max.raise_to(n);
        self.stats.nodes_total.add(n);
    }

    /// Path costs between `access` cells (Eq. 6's dist): one Dijkstra per cell
    /// ([`Search::costs_to_targets`]), cached in [`CostRows`] (which says when a row is searched
    /// again and which pairs it then searches for).
    pub(super) fn cost_matrix(
        &mut self,
        at: &TourInputs,
        cfg: &ThpConfig,
        access: &[usize],
    ) -> CostMatrix {
        let grid = *at.map.grid();
        let (now, costs) = (at.time_s, at.costs);
        self.cost_rows.keep_sources(access);
        if access.len() < 2 {
            return CostMatrix::new(access.len());
        }
        let jobs =
            self.cost_rows
                .searches(access, now, cfg.cost_refresh_s, cfg.cost_refresh_rows_max);
        // The searches are independent Dijkstras: spread over the thread pool, each worker with its
        // own search workspace (the result does not depend on the thread count).
        let workers = jobs.len().min(rayon::current_num_threads()).max(1);
        while self.row_searches.len() < workers {
            self.row_searches.push(Search::new(&grid));
        }
        let rows: Vec<(usize, BTreeMap<usize, f64>)> = self.row_searches[..workers]
            .par_iter_mut()
            .enumerate()
            .flat_map_iter(|(w, search)| {
                jobs.iter()
                    .skip(w)
                    .step_by(workers)
                    .map(|(source, targets)| {
                        let found = search.costs_to_targets(
                            &grid,
                            |c| costs.get(c),
                            *source,
                            targets,
                            f32::INFINITY,
                        );
                        let row = targets
                            .iter()
                            .zip(found)
                            .map(|(&t, c)| (t, c.map_or(f64::INFINITY, f64::from)))
                            .collect();
                        (*source, row)
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        for (source, row) in rows {
            if !row.is_empty() {
                self.stats.cost_rows.add(1.0);
            }
            self.cost_rows.insert(source, now, row);
        }
        self.cost_rows.matrix(access)
    }

    /// The tour's counters, under their `planner_stats` names.
    pub(super) fn stats(&self) -> [(&'static str, Count); 6] {
        let s = &self.stats;
        [
            ("tsp_solves", s.solves),
            ("tsp_nodes_max", s.nodes_max),
            ("tsp_nodes_total", s.nodes_total),
            ("cost_rows", s.cost_rows),
            ("tour_starts_not_nearest_group", s.starts_not_nearest_group),
            ("tour_start_extra_m", s.start_extra_m),
        ]
    }
}

/// Whether Alg. 1 breaks its loop: new anchors (`P*` not empty) or a node the tour does not hold.
/// Without anchor grouping the nodes are made anew at every choice, so the tour is always solved.
fn needs_solve(order: &[usize], nodes: &[Node], new_anchors: bool, grouping: Grouping) -> bool {
    match grouping {
        Grouping::Anchors => new_anchors || !nodes.iter().all(|n| order.contains(&n.key)),
        Grouping::None | Grouping::Kmeans => true,
    }
}

/// Where each node's row of path costs starts (`thp.tour_costs`). Eq. 6 takes dist between
/// anchors; an anchor that is a frontier's centroid or a k-means centre may lie off the known
/// floor (or out of the robot's reach), and then its least-cost frontier stands in, as it does for
/// every node with `frontiers`.
pub(super) fn access_cells(
    map: &Map,
    df: &DistanceField,
    nodes: &[Node],
    fronts: &[Frontier],
    tour_costs: TourCosts,
) -> Vec<usize> {
    let grid = map.grid();
    nodes
        .iter()
        .map(|n| match tour_costs {
            TourCosts::Anchors => grid
                .cell_of(n.pos)
                .map(|c| grid.index(c))
                .filter(|&c| map.is_traversable(c) && df.cost_to(c).is_some())
                .unwrap_or_else(|| n.nearest_member(fronts).aim),
            TourCosts::Frontiers => n.nearest_member(fronts).aim,
        })
        .collect()
}

/// Path cost from the robot to a node's anchor (its position): from the robot's distance field where
/// the anchor's cell is reachable, else through its nearest member (member cost plus the straight
/// distance on to the anchor), as a frontier anchor's centroid may fall off the known floor.
fn anchor_cost(grid: &GridSpec, df: &DistanceField, node: &Node, fronts: &[Frontier]) -> f32 {
    grid.cell_of(node.pos)
        .and_then(|c| df.cost_to(grid.index(c)))
        .unwrap_or_else(|| {
            node.members
                .iter()
                .map(|&m| fronts[m].cost + (fronts[m].pos - node.pos).norm() as f32)
                .fold(f32::INFINITY, f32::min)
        })
}

/// Alg. 1's start: the node whose anchor the robot reaches at least cost ([`anchor_cost`]; ties by
/// index). `nodes` must not be empty.
fn nearest_anchor_node(
    grid: &GridSpec,
    df: &DistanceField,
    nodes: &[Node],
    fronts: &[Frontier],
) -> usize {
    (0..nodes.len())
        .min_by(|&a, &b| {
            let (fa, fb) = (
                anchor_cost(grid, df, &nodes[a], fronts),
                anchor_cost(grid, df, &nodes[b], fronts),
            );
            fa.total_cmp(&fb).then(a.cmp(&b))
        })
        .expect("at least one node")
}

/// The robot's path costs to `cells` in its distance field (infinite where unreachable).
pub(super) fn costs_from(df: &DistanceField, cells: &[usize]) -> Vec<f64> {
    cells
        .iter()
        .map(|&c| df.cost_to(c).map_or(f64::INFINITY, f64::from))
        .collect()
}

/// The open tour over `m`'s nodes from an extra start outside them, with `from_start[j]` the cost
/// from that start to node `j`: the nodes' indices in tour order, the start left out. No open tour
/// comes back to its start, so the start's column is never used (it is filled symmetrically).
pub(super) fn open_tour_from(
    m: &CostMatrix,
    from_start: &[f64],
    exact_max_nodes: usize,
) -> Vec<usize> {
    let n = m.n();
    let with_start = CostMatrix::from_fn(n + 1, |i, j| match (i == n, j == n) {
        (true, true) => 0.0,
        (true, false) => from_start[j],
        (false, true) => from_start[i],
        (false, false) => m.get(i, j),
    });
    tsp::solve(&with_start, n, exact_max_nodes).order[1..].to_vec()
}

/// Cached rows of TSP path costs: per source cell, when its Dijkstra ran and what it found.
///
/// A row is reused while its source cell stays an access cell and is younger than
/// `thp.cost_refresh_s` (the map mostly grows, so costs change slowly). Of the rows past that age,
/// the `thp.cost_refresh_rows_max` oldest are searched again and the others serve until their turn,
/// so that rows computed at one solve do not all come due at one later solve. A pair is read from
/// the newer of its two rows (path costs are symmetric up to the proximity surcharge of the end
/// cells), so a row searched again for its age looks only for the cells whose pair no younger row
/// holds: usually a few, where a whole row would flood to the farthest node.
#[derive(Clone, Debug, Default)]
pub(super) struct CostRows {
    /// Source cell → (time computed, target cell → path cost).
    rows: BTreeMap<usize, (f64, BTreeMap<usize, f64>)>,
}

impl CostRows {
    /// Drops the rows whose source is no longer one of `access`.
    pub(super) fn keep_sources(&mut self, access: &[usize]) {
        self.rows.retain(|source, _| access.contains(source));
    }

    /// The searches a matrix over `access` needs at `now`, as (source, targets): every cell
    /// without a row searches for all of `access`; a row due for its age ([`rows_due`]) searches
    /// for the cells whose pair with it only aged rows hold and no earlier search here covers.
    pub(super) fn searches(
        &self,
        access: &[usize],
        now: f64,
        refresh_s: f64,
        rows_max: usize,
    ) -> Vec<(usize, Vec<usize>)> {
        let mut jobs: Vec<(usize, Vec<usize>)> = Vec::new();
        for &source in access {
            if !self.rows.contains_key(&source) && jobs.iter().all(|j| j.0 != source) {
                jobs.push((source, access.to_vec()));
            }
        }
        let computed_at = self.rows.iter().map(|(&source, row)| (source, row.0));
        for source in rows_due(computed_at, now, refresh_s, rows_max) {
            // The pair with `t` is stale unless `t`'s row is young and holds it (or `t` is searched
            // in full now).
            let stale = |t: usize| {
                self.rows
                    .get(&t)
                    .is_some_and(|(at, row)| now - at >= refresh_s || !row.contains_key(&source))
            };
            let targets = access
                .iter()
                .copied()
                .filter(|&t| t != source && jobs.iter().all(|j| j.0 != t) && stale(t))
                .collect();
            jobs.push((source, targets));
        }
        jobs
    }

    /// Stores what a search from `source` found at `now`, replacing its row.
    pub(super) fn insert(&mut self, source: usize, now: f64, found: BTreeMap<usize, f64>) {
        self.rows.insert(source, (now, found));
    }

    /// The path costs between the cells of `access`, each pair from the newer row that holds it
    /// (the row of the first cell when both are as new). Every cell must have a row, and the rows
    /// must come from [`CostRows::searches`] over the same cells, which covers every pair.
    pub(super) fn matrix(&self, access: &[usize]) -> CostMatrix {
        CostMatrix::from_fn(access.len(), |i, j| {
            let (a, b) = (access[i], access[j]);
            if a == b {
                return 0.0;
            }
            let (row_a, row_b) = (&self.rows[&a], &self.rows[&b]);
            match (row_a.1.get(&b), row_b.1.get(&a)) {
                (Some(&c), Some(&d)) => {
                    if row_b.0 > row_a.0 {
                        d
                    } else {
                        c
                    }
                }
                (Some(&c), None) | (None, Some(&c)) => c,
                (None, None) => unreachable!("the searches cover every pair"),
            }
        })
    }
}

/// The cost rows to recompute for their age: of the rows (source cell, time computed) at least
/// `refresh_s` old at `now`, the `max` oldest (ties by source cell, so the choice is reproducible).
fn rows_due(
    computed_at: impl Iterator<Item = (usize, f64)>,
    now: f64,
    refresh_s: f64,
    max: usize,
) -> Vec<usize> {
    let mut aged: Vec<(f64, usize)> = computed_at
        .filter(|&(_, t)| now - t >= refresh_s)
        .map(|(source, t)| (t, source))
        .collect();
    aged.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    aged.into_iter()
        .take(max)
        .map(|(_, source)| source)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn node(key: usize) -> Node {
        Node {
            key,
            pos: Point2::new(key as f64, 0.0),
            members: vec![0],
        }
    }

    #[test]
    fn the_tour_is_solved_again_only_when_alg_1_breaks_its_loop() {
        let nodes = [node(3), node(7)];
        // Every node on the tour and no new anchor: follow it.
        assert!(!needs_solve(&[7, 3, 9], &nodes, false, Grouping::Anchors));
        // New anchors (P* not empty), or a node the tour lacks: solve.
        assert!(needs_solve(&[7, 3, 9], &nodes, true, Grouping::Anchors));
        assert!(needs_solve(&[7], &nodes, false, Grouping::Anchors));
        // Nodes made anew at every choice: always solve.
        assert!(needs_solve(&[7, 3], &nodes, false, Grouping::None));
        assert!(needs_solve(&[7, 3], &nodes, false, Grouping::Kmeans));
    }

    #[test]
    fn following_the_tour_drops_visited_nodes_and_keeps_the_order() {
        let mut tour = Tour {
            order: vec![9, 3, 5, 7],
            points: [9.0, 3.0, 5.0, 7.0].map(|x| Point2::new(x, 0.0)).to_vec(),
            ..Tour::default()
        };
        tour.keep_nodes(&[node(7), node(3)]);
        assert_eq!(tour.order, vec![3, 7]);
        assert_eq!(
            tour.points,
            vec![Point2::new(3.0, 0.0), Point2::new(7.0, 0.0)]
        );
    }

    /// The least cost of an open tour from an outside start, by trying every order.
    fn brute_force_from(m: &CostMatrix, from_start: &[f64]) -> f64 {
        fn go(m: &CostMatrix, at: usize, left: &mut Vec<usize>, so_far: f64, best: &mut f64) {
            if left.is_empty() {
                *best = best.min(so_far);
            }
            for k in 0..left.len() {
                let next = left.remove(k);
                go(m, next, left, so_far + m.get(at, next), best);
                left.insert(k, next);
            }
        }
        let mut best = f64::INFINITY;
        for (first, &to_first) in from_start.iter().enumerate() {
            let mut left: Vec<usize> = (0..m.n()).filter(|&j| j != first).collect();
            go(m, first, &mut left, to_first, &mut best);
        }
        best
    }

    #[test]
    fn the_tour_from_the_robot_is_the_cheapest_open_path_from_it() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for n in 1..=6 {
            for _ in 0..20 {
                let pts: Vec<Point2<f64>> = (0..=n)
                    .map(|_| Point2::new(rng.random_range(0.0..10.0), rng.random_range(0.0..10.0)))
                    .collect();
                let m = CostMatrix::from_fn(n, |i, j| (pts[i] - pts[j]).norm());
                let from: Vec<f64> = (0..n).map(|j| (pts[n] - pts[j]).norm()).collect();
                let order = open_tour_from(&m, &from, 10);
                let mut sorted = order.clone();
                sorted.sort_unstable();
                assert_eq!(
                    sorted,
                    (0..n).collect::<Vec<_>>(),
                    "each node once, start left out"
                );
                let cost = from[order[0]] + tsp::open_path_cost(&m, &order);
                let best = brute_force_from(&m, &from);
                assert!((cost - best).abs() < 1e-9, "n = {n}: {cost} > {best}");
            }
        }
    }

    fn row(pairs: &[(usize, f64)]) -> BTreeMap<usize, f64> {
        pairs.iter().copied().collect()
    }

    #[test]
    fn each_pair_comes_from_the_newer_row_that_holds_it() {
        let mut rows = CostRows::default();
        rows.insert(1, 0.0, row(&[(1, 0.0), (2, 5.0), (3, 7.0)]));
        rows.insert(2, 5.0, row(&[(1, 4.0), (3, 6.0)]));
        rows.insert(3, 5.0, row(&[(1, 7.5), (2, 6.5)]));
        let m = rows.matrix(&[1, 2, 3]);
        // 1–2 and 1–3: rows 2 and 3 are newer than row 1, both ways.
        assert_eq!((m.get(0, 1), m.get(1, 0)), (4.0, 4.0));
        assert_eq!((m.get(0, 2), m.get(2, 0)), (7.5, 7.5));
        // 2–3: rows as new as each other; each way reads its own first cell's row.
        assert_eq!((m.get(1, 2), m.get(2, 1)), (6.0, 6.5));
        assert_eq!((m.get(0, 0), m.get(1, 1)), (0.0, 0.0));
    }

    #[test]
    fn an_aged_row_searches_only_for_the_pairs_no_young_row_holds() {
        let mut rows = CostRows::default();
        rows.insert(10, 0.0, row(&[(10, 0.0), (11, 1.0), (12, 2.0)]));
        rows.insert(11, 8.0, row(&[(10, 1.0), (11, 0.0), (12, 1.0)]));
        rows.insert(12, 1.0, row(&[(10, 2.0), (11, 1.0), (12, 0.0)]));
        // At 12 s (10 s refresh) rows 10 and 12 are aged and 10 is the oldest. Its pair with 11 is
        // held by 11's young row and its pair with 13 by 13's new row; only 12 is searched for.
        let jobs = rows.searches(&[10, 11, 12, 13], 12.0, 10.0, 1);
        assert_eq!(jobs, vec![(13, vec![10, 11, 12, 13]), (10, vec![12])]);
        // With room for both aged rows, the pair is searched once, by the older.
        let jobs = rows.searches(&[10, 11, 12], 12.0, 10.0, 2);
        assert_eq!(jobs, vec![(10, vec![12]), (12, vec![])]);
        // A young row that lacks the pair (made before the other cell had a row) does not cover it.
        rows.insert(11, 8.0, row(&[(11, 0.0), (12, 1.0)]));
        let jobs = rows.searches(&[10, 11, 12], 12.0, 10.0, 1);
        assert_eq!(jobs, vec![(10, vec![11, 12])]);
    }

    #[test]
    fn cached_rows_give_every_pair_as_a_full_search_would() {
        // Access sets come and go over 200 solves; with costs that do not change, the matrix read
        // from the cache must equal the costs themselves, whatever mix of new, young, aged and
        // partly searched rows serves it.
        let cost = |a: usize, b: usize| {
            if a == b {
                0.0
            } else {
                (a.abs_diff(b) * 3 + (a + b) % 7) as f64
            }
        };
        for rows_max in [1, 2, 100] {
            let mut rng = ChaCha8Rng::seed_from_u64(rows_max as u64);
            let mut rows = CostRows::default();
            let mut now = 0.0;
            for _ in 0..200 {
                now += rng.random_range(0.0..4.0);
                let n = rng.random_range(2..9);
                let mut access: Vec<usize> = (0..n).map(|_| rng.random_range(0..20)).collect();
                access.dedup();
                rows.keep_sources(&access);
                for (source, targets) in rows.searches(&access, now, 10.0, rows_max) {
                    let found = targets.iter().map(|&t| (t, cost(source, t))).collect();
                    rows.insert(source, now, found);
                }
                let m = rows.matrix(&access);
                for (i, &a) in access.iter().enumerate() {
                    for (j, &b) in access.iter().enumerate() {
                        assert_eq!(m.get(i, j), cost(a, b), "{a} to {b} at {now} s");
                    }
                }
            }
        }
    }

    #[test]
    fn rows_due_are_the_oldest_aged_rows_up_to_the_limit() {
        // Sources 10, 11, 12, 13, 14 and 9 computed at 0, 3, 3, 8, 12 and 1 s; at 15 s with a 10 s
        // refresh the rows of 0, 1, 3 and 3 s are aged (the 3 s pair tied, by source), the 8 and
        // 12 s ones are not.
        let rows = [
            (10, 0.0),
            (11, 3.0),
            (12, 3.0),
            (13, 8.0),
            (14, 12.0),
            (9, 1.0),
        ];
        assert_eq!(rows_due(rows.into_iter(), 15.0, 10.0, 2), vec![10, 9]);
        assert_eq!(rows_due(rows.into_iter(), 15.0, 10.0, 3), vec![10, 9, 11]);
        assert_eq!(
            rows_due(rows.into_iter(), 15.0, 10.0, 100),
            vec![10, 9, 11, 12]
        );
        // Exactly the refresh age is due; nothing is due before.
        assert_eq!(
            rows_due(rows.into_iter(), 18.0, 10.0, 100),
            vec![10, 9, 11, 12, 13]
        );
        assert!(rows_due(rows.into_iter(), 9.9, 10.0, 100).is_empty());
    }
}
