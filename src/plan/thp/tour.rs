//! The online TSP over the groups (THP §3.3, Alg. 1, Eq. 6): where each tour starts, and the path
//! costs between the groups' access cells. The volume views before `Complete` are ordered by the
//! same kind of tour (`thp.volume_view_tour`).

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
    /// With `thp.volume_view_tour` (not in the paper) the open views, thinned to one per
    /// [`VOLUME_VIEW_NODE_SPACING_M`], are ordered by a fixed-start open TSP from the robot over
    /// their path costs, as Alg. 1 orders anchors, and the first is taken; the tour is solved again
    /// at every view, since each view changes what the others would still show. Without it, the
    /// best gain per metre one view at a time, as GREEDY does ([`VolumeViews::next`]).
    pub(super) fn next_volume_view(
        &mut self,
        ctx: &mut PlanContext,
        costs: &plan::StepCosts,
        df: &DistanceField,
    ) -> Option<super::super::view_gain::VolumeView> {
        let grid = *ctx.map.grid();
        let mut views = self.volume_views.take()?;
        let next = if self.cfg.volume_view_tour {
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

    /// Solves the fixed-start open TSP over `nodes` (Eq. 6); each node is entered at its least-cost
    /// member. Sets the tour (node keys in order). The start, by `thp.tour_start` (and
    /// `thp.finish_group_first`):
    /// - `robot`: the robot's cell is an extra node, the fixed start, with the robot's
    ///   path costs to each access cell; the first group is the one the cheapest whole tour begins
    ///   with.
    /// - `nearest_anchor` (default): the node whose anchor is nearest the robot by path cost (Alg. 1, "start at
    ///   the anchor nearest the robot"), even when it lies behind the robot and the rest ahead.
    pub(super) fn solve_tour(
        &mut self,
        ctx: &mut PlanContext,
        costs: &plan::StepCosts,
        df: &DistanceField,
        nodes: &[Node],
        fronts: &[Frontier],
    ) {
        let t = Instant::now();
        let access: Vec<usize> = nodes
            .iter()
            .map(|n| {
                n.members
                    .iter()
                    .map(|&m| &fronts[m])
                    .min_by(|a, b| a.cost.total_cmp(&b.cost).then(a.aim.cmp(&b.aim)))
                    .expect("nodes have members")
                    .aim
            })
            .collect();
        let grid = *ctx.map.grid();
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
        let entry = |k: usize| df.cost_to(access[k]).map_or(f64::INFINITY, f64::from);
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
    /// ([`Search::costs_to_targets`]). A row is reused while its source cell is unchanged and younger
    /// than `thp.cost_refresh_s` (the map mostly grows, so costs change slowly); of the rows past
    /// that age, the `thp.cost_refresh_rows_max` oldest are recomputed and the others serve until
    /// their turn, so that rows computed at one solve do not all come due at one later solve. A pair
    /// missing from an old row is read from the other node's row (path costs are symmetric up to
    /// the proximity surcharge of the end cells).
    pub(super) fn cost_matrix(
        &mut self,
        ctx: &mut PlanContext,
        costs: &plan::StepCosts,
        access: &[usize],
    ) -> CostMatrix {
        let grid = *ctx.map.grid();
        let now = ctx.time_s;
        let refresh = self.cfg.cost_refresh_s;
        self.cost_rows.retain(|source, _| access.contains(source));
        let computed_at = self.cost_rows.iter().map(|(&source, row)| (source, row.0));
        for source in rows_due(computed_at, now, refresh, self.cfg.cost_refresh_rows_max) {
            self.cost_rows.remove(&source);
        }
        let mut m = CostMatrix::new(access.len());
        if access.len() < 2 {
            return m;
        }
        let mut missing: Vec<usize> = Vec::new();
        for &source in access {
            if !self.cost_rows.contains_key(&source) && !missing.contains(&source) {
                missing.push(source);
            }
        }
        // The missing rows are independent Dijkstras: spread over the thread pool, each worker with
        // its own search workspace (the result does not depend on the thread count).
        let workers = missing.len().min(rayon::current_num_threads()).max(1);
        while self.row_searches.len() < workers {
            self.row_searches.push(Search::new(&grid));
        }
        let rows: Vec<(usize, Vec<Option<f32>>)> = self.row_searches[..workers]
            .par_iter_mut()
            .enumerate()
            .flat_map_iter(|(w, search)| {
                missing
                    .iter()
                    .skip(w)
                    .step_by(workers)
                    .map(|&source| {
                        let row = search.costs_to_targets(
                            &grid,
                            |c| costs.get(c),
                            source,
                            access,
                            f32::INFINITY,
                        );
                        (source, row)
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        for (source, row_costs) in rows {
            let row = access
                .iter()
                .zip(row_costs)
                .map(|(&t, c)| (t, c.map_or(f64::INFINITY, f64::from)))
                .collect();
            self.cost_rows.insert(source, (now, row));
            self.stats.cost_rows.add(1.0);
        }
        for (i, a) in access.iter().enumerate() {
            for (j, b) in access.iter().enumerate() {
                let c = self.cost_rows[a]
                    .1
                    .get(b)
                    .or_else(|| self.cost_rows[b].1.get(a))
                    .copied()
                    .expect("the newer of two rows holds the pair");
                m.set(i, j, c);
            }
        }
        m
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
