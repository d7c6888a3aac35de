//! The online TSP over the groups (THP §3.3, Alg. 1, Eq. 6): where each tour starts, and the path
//! costs between the groups' access cells. The volume views before `Complete` are ordered by the
//! same kind of tour (`additions.volume_view_tour`).

use super::*;

/// Path cost from the robot to a node's anchor (its position): from the robot's distance field where
/// the anchor's cell is reachable, else through its nearest member (member cost plus the straight
/// distance on to the anchor), as a frontier anchor's centroid may fall off the known floor.
pub(super) fn anchor_cost(
    grid: &GridSpec,
    df: &DistanceField,
    node: &Node,
    fronts: &[Frontier],
) -> f32 {
    grid.cell_of(node.pos)
        .and_then(|c| df.cost_to(grid.index(c)))
        .unwrap_or_else(|| {
            node.members
                .iter()
                .map(|&m| fronts[m].cost + (fronts[m].pos - node.pos).norm() as f32)
                .fold(f32::INFINITY, f32::min)
        })
}

/// Open volume views within this of a kept one do not become tour nodes of their own: from about a
/// metre apart a view turned once shows much the same volume, metres.
const VOLUME_VIEW_NODE_SPACING_M: f64 = 1.0;

/// A tour's first group whose entry is farther than the nearest group's by more than this counts
/// as not starting at the nearest group (`tour_starts_not_nearest_group`), metres: about a cell.
const TOUR_START_SLACK_M: f64 = 0.1;

/// At most this many volume views (the largest gains after thinning) make one tour.
const VOLUME_VIEW_NODES_MAX: usize = 24;

impl Thp {
    /// The next volume view to drive to, marked taken; `None` when views are off or none is open.
    ///
    /// With `additions.volume_view_tour` (not in the paper) the open views, thinned to one per
    /// [`VOLUME_VIEW_NODE_SPACING_M`], are ordered by a fixed-start open TSP from the robot over
    /// their path costs, as Alg. 1 orders anchors, and the first is taken; the tour is solved again
    /// at every view, since each view changes what the others would still show. Without it, the
    /// best gain per metre one view at a time, as GREEDY does ([`VolumeViews::next`]).
    pub(super) fn next_volume_view(
        &mut self,
        ctx: &mut PlanContext,
        costs: &plan::StepCosts,
        df: &DistanceField,
    ) -> Option<super::super::frontier::VolumeView> {
        let grid = *ctx.map.grid();
        let mut views = self.volume_views.take()?;
        let next = if self.rules.volume_view_tour {
            let open = views.thinned(
                ctx.map,
                df,
                VOLUME_VIEW_NODE_SPACING_M,
                VOLUME_VIEW_NODES_MAX,
            );
            let first = match open.len() {
                0 => None,
                1 => Some(open[0]),
                _ => {
                    let cells: Vec<usize> = open.iter().map(|v| v.cell).collect();
                    let m = self.cost_matrix(ctx, costs, &cells);
                    Some(open[self.tour_from_robot(&m, df, &cells)[0]])
                }
            };
            if let Some(v) = first {
                views.mark_taken(&grid, v.cell);
            }
            first
        } else {
            views.next(ctx.map, df)
        };
        self.volume_views = Some(views);
        next
    }

    /// The open tour over the nodes at `cells` (path costs `m` between them) with the robot's cell
    /// as its fixed start: the nodes' indices in tour order, the robot left out. The robot's row
    /// holds its distance field to each cell; no open tour comes back to its start, so its column is
    /// never used (filled symmetrically).
    fn tour_from_robot(&self, m: &CostMatrix, df: &DistanceField, cells: &[usize]) -> Vec<usize> {
        let n = m.n();
        let from_robot: Vec<f64> = cells
            .iter()
            .map(|&c| df.cost_to(c).map_or(f64::INFINITY, f64::from))
            .collect();
        let with_robot = CostMatrix::from_fn(n + 1, |i, j| match (i == n, j == n) {
            (true, true) => 0.0,
            (true, false) => from_robot[j],
            (false, true) => from_robot[i],
            (false, false) => m.get(i, j),
        });
        tsp::solve(&with_robot, n, self.cfg.exact_tsp_max_nodes).order[1..].to_vec()
    }

    /// Solves the fixed-start open TSP over `nodes` (Eq. 6) with path costs between the nodes'
    /// access cells (`thp.tour_costs`: their anchors, or their least-cost members). Sets the tour
    /// (node keys in order). The start, by `thp.tour_start` (and `thp.finish_group_first`):
    /// - `robot`: the robot's cell is an extra node, the fixed start, with the robot's path costs
    ///   to each access cell; the first group is the one the cheapest whole tour begins with.
    /// - `nearest_anchor` (default): the node whose anchor is nearest the robot by path cost
    ///   (Alg. 1, "start at the anchor nearest the robot"), even when it lies behind the robot and
    ///   the rest ahead.
    pub(super) fn solve_tour(
        &mut self,
        ctx: &mut PlanContext,
        costs: &plan::StepCosts,
        df: &DistanceField,
        nodes: &[Node],
        fronts: &[Frontier],
    ) {
        let t = Instant::now();
        // Where each node's row of path costs starts (`thp.tour_costs`): Eq. 6 takes dist between
        // anchors; an anchor that is a frontier's centroid or a k-means centre may lie off the
        // known floor, and then its least-cost frontier stands in, as it does for every node with
        // `frontiers`.
        let grid = *ctx.map.grid();
        let access: Vec<usize> = nodes
            .iter()
            .map(|n| match self.cfg.tour_costs {
                TourCosts::Anchors => grid
                    .cell_of(n.pos)
                    .map(|c| grid.index(c))
                    .filter(|&c| ctx.map.is_traversable(c) && df.cost_to(c).is_some())
                    .unwrap_or_else(|| n.nearest_member(fronts).aim),
                TourCosts::Frontiers => n.nearest_member(fronts).aim,
            })
            .collect();
        // The tour's start (room the paper leaves): Alg. 1 starts at the anchor nearest the robot,
        // while Alg. 2 scans a group until it is empty. Read together, a re-solve that new anchors
        // trigger in the middle of a group may keep that group as the start
        // (`thp.finish_group_first`), so the robot does not leave a half-scanned group for a nearer
        // anchor and come back to it. Off by default: on real plans it removed those returns but
        // lengthened the whole path (the nearest anchor's group is usually the cheaper detour).
        let current = self
            .mode
            .goal()
            .filter(|_| self.cfg.finish_group_first)
            .and_then(|g| g.tour_node)
            .and_then(|k| nodes.iter().position(|n| n.key == k));
        let m = self.cost_matrix(ctx, costs, &access);
        let order: Vec<usize> = match (current, self.cfg.tour_start) {
            (Some(start), _) => tsp::solve(&m, start, self.cfg.exact_tsp_max_nodes).order,
            (None, TourStart::Robot) => self.tour_from_robot(&m, df, &access),
            (None, TourStart::NearestAnchor) => {
                let start = (0..nodes.len())
                    .min_by(|&a, &b| {
                        let (fa, fb) = (
                            anchor_cost(&grid, df, &nodes[a], fronts),
                            anchor_cost(&grid, df, &nodes[b], fronts),
                        );
                        fa.total_cmp(&fb).then(a.cmp(&b))
                    })
                    .expect("at least one node");
                tsp::solve(&m, start, self.cfg.exact_tsp_max_nodes).order
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
                self.stats.tour_starts_not_nearest_group.add(1.0);
                self.stats.tour_start_extra_m.add(extra);
            }
        }
        self.tour = order.iter().map(|&i| nodes[i].key).collect();
        self.tour_points = order.iter().map(|&i| nodes[i].pos).collect();
        self.new_anchors = false;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        self.tsp_ms = Some(self.tsp_ms.unwrap_or(0.0) + ms);
        self.stats.tsp_solves.add(1.0);
        let n = nodes.len() as f64;
        self.stats.tsp_nodes_max.raise_to(n);
        self.stats.tsp_nodes_total.add(n);
    }

    /// Path costs between the nodes' access cells (Eq. 6's dist): one Dijkstra per node
    /// ([`Search::costs_to_targets`]), cached in [`CostRows`] (which says when a row is searched
    /// again and which pairs it then searches for).
    pub(super) fn cost_matrix(
        &mut self,
        ctx: &mut PlanContext,
        costs: &plan::StepCosts,
        access: &[usize],
    ) -> CostMatrix {
        let grid = *ctx.map.grid();
        let now = ctx.time_s;
        self.cost_rows.keep_sources(access);
        if access.len() < 2 {
            return CostMatrix::new(access.len());
        }
        let jobs = self.cost_rows.searches(
            access,
            now,
            self.cfg.cost_refresh_s,
            self.cfg.cost_refresh_rows_max,
        );
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
