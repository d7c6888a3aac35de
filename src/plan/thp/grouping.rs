//! Anchors and frontier groups (THP §3.3–3.4, Alg. 2, Eq. 5, 7–9): degenerate points become
//! anchors, frontiers join their nearest anchor within `d_f`, groups spanning a wall are split, and
//! the k-means baseline of Fig. 8.

use crate::config::ThpConfig;
use crate::grid::GridSpec;
use crate::map::Map;
use crate::plan::frontier::Visit;
use crate::plan::Count;
use nalgebra::Point2;
use std::collections::{BTreeMap, BTreeSet};

/// Where an anchor came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum AnchorSource {
    /// A tracked degenerate point of the field (its id).
    Degenerate(u64),
    /// A frontier too far from every anchor (Alg. 2), or split off a group (Eq. 9).
    Frontier,
}

/// An anchor of §3.3: a node the tour may route over, visited once its group is empty.
#[derive(Clone, Debug)]
struct Anchor {
    pos: Point2<f64>,
    source: AnchorSource,
    visited: bool,
}

/// A frontier segment as the planner sees it in one plan.
#[derive(Clone, Debug)]
pub(super) struct Frontier {
    /// Index into the plan's segment list.
    pub(super) segment: usize,
    /// The segment's centroid: the frontier position `f` of §3.4.
    pub(super) pos: Point2<f64>,
    /// Its least-cost observable cell: the cell the robot aims at.
    pub(super) aim: usize,
    /// Path cost from the robot to `aim`.
    pub(super) cost: f32,
}

impl Frontier {
    /// The visit of this frontier's segment (`segment_cells` as returned by `Thp::frontiers`).
    pub(super) fn visit(
        &self,
        grid: &GridSpec,
        segment_cells: &[Vec<usize>],
        near_view: bool,
    ) -> Visit {
        Visit {
            target: segment_cells[self.segment]
                .iter()
                .map(|&i| grid.cell(i))
                .collect(),
            aim: self.aim,
            near_view,
        }
    }
}

/// A TSP node of one plan: an anchor with its group, a single frontier, or a k-means cluster.
#[derive(Clone, Debug)]
pub(super) struct Node {
    /// Anchor index (anchors mode) or a plan-local number.
    pub(super) key: usize,
    pub(super) pos: Point2<f64>,
    /// Indices into the plan's frontier list.
    pub(super) members: Vec<usize>,
}

impl Node {
    /// The member the robot reaches at least path cost (ties by aim cell): where the group is
    /// entered.
    pub(super) fn nearest_member<'a>(&self, fronts: &'a [Frontier]) -> &'a Frontier {
        self.members
            .iter()
            .map(|&m| &fronts[m])
            .min_by(|a, b| a.cost.total_cmp(&b.cost).then(a.aim.cmp(&b.aim)))
            .expect("nodes have members")
    }
}

/// Lloyd iterations of the k-means grouping.
pub(super) const KMEANS_ITERATIONS: usize = 20;

/// Whether `p` lies on known traversable floor (a usable anchor position).
pub(super) fn on_floor(map: &Map, grid: &GridSpec, p: Point2<f64>) -> bool {
    grid.cell_of(p)
        .is_some_and(|c| map.is_traversable(grid.index(c)))
}

/// Group splitting, THP Eq. 9 — the reading used here.
///
/// The paper defines S(F_k) = {f_k | ν ≥ d_g ∨ (μ < d_p ∧ ν < d_g)} with μ the distance from the
/// robot to the group's anchor and ν a comparison of the A* length to f_k with it, but never defines
/// ν, and read literally S keeps exactly the frontiers that are far around a wall. Its stated intent
/// (Fig. 4) is to split a group that spans two rooms when the robot is at it. So:
///
/// - μ = ‖c_r − p_k‖: the robot is at the group when μ < d_p;
/// - ν = path cost(c_r, f_k) − ‖c_r − f_k‖: the detour to f_k, large exactly when a wall stands
///   between the robot and f_k (the straight distance, not μ, is the baseline, so a frontier merely
///   far across an open room is not split off);
/// - while μ < d_p, the members with ν ≥ d_g are split off and become anchors — but only when the
///   group also has members with ν < d_g (it really spans two sides). A group wholly behind a wall is
///   left whole, so the split-off group is never split again.
///
/// Returns the members (indices into `fronts`) to split off.
pub(super) fn split_group(
    members: &[usize],
    fronts: &[Frontier],
    robot: Point2<f64>,
    anchor: Point2<f64>,
    d_g: f64,
    d_p: f64,
) -> Vec<usize> {
    let mu = (robot - anchor).norm();
    if mu >= d_p || members.len() < 2 {
        return Vec::new();
    }
    let detour = |m: usize| f64::from(fronts[m].cost) - (fronts[m].pos - robot).norm();
    let (far, near): (Vec<usize>, Vec<usize>) =
        members.iter().copied().partition(|&m| detour(m) >= d_g);
    if near.is_empty() {
        return Vec::new();
    }
    far
}

/// K-means grouping (the Fig. 8 baseline, clusters as in Kulich et al. 2019): one cluster per
/// `cluster_m` metres of frontier, farthest-point initialisation (deterministic), Lloyd iterations on
/// the segment centroids.
pub(super) fn kmeans_nodes(
    fronts: &[Frontier],
    segment_cells: &[Vec<usize>],
    res: f64,
    cluster_m: f64,
) -> Vec<Node> {
    if fronts.is_empty() {
        return Vec::new();
    }
    let length_m: f64 = fronts
        .iter()
        .map(|f| segment_cells[f.segment].len() as f64 * res)
        .sum();
    let k = ((length_m / cluster_m).ceil() as usize).clamp(1, fronts.len());
    let mut centres = vec![fronts[0].pos];
    while centres.len() < k {
        let next = fronts
            .iter()
            .map(|f| {
                centres
                    .iter()
                    .map(|c| (c - f.pos).norm_squared())
                    .fold(f64::INFINITY, f64::min)
            })
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
            .map(|(i, _)| i)
            .expect("fronts is not empty");
        centres.push(fronts[next].pos);
    }
    let mut assign = vec![0usize; fronts.len()];
    for _ in 0..KMEANS_ITERATIONS {
        let mut changed = false;
        for (i, f) in fronts.iter().enumerate() {
            let best = (0..k)
                .min_by(|&a, &b| {
                    (centres[a] - f.pos)
                        .norm_squared()
                        .total_cmp(&(centres[b] - f.pos).norm_squared())
                        .then(a.cmp(&b))
                })
                .expect("k ≥ 1");
            changed |= assign[i] != best;
            assign[i] = best;
        }
        for (c, centre) in centres.iter_mut().enumerate() {
            let members: Vec<&Frontier> = fronts
                .iter()
                .zip(&assign)
                .filter(|(_, &a)| a == c)
                .map(|(f, _)| f)
                .collect();
            if !members.is_empty() {
                let sum = members
                    .iter()
                    .fold(nalgebra::Vector2::zeros(), |s, f| s + f.pos.coords);
                *centre = Point2::from(sum / members.len() as f64);
            }
        }
        if !changed {
            break;
        }
    }
    (0..k)
        .map(|c| Node {
            key: c,
            pos: centres[c],
            members: (0..fronts.len()).filter(|&i| assign[i] == c).collect(),
        })
        .filter(|n| !n.members.is_empty())
        .collect()
}

/// The distances of Alg. 2 (`thp.d_f_m`, `thp.d_g_m`, `thp.d_p_m`), metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct GroupDistances {
    /// A frontier joins its nearest unvisited anchor within this (Eq. 7–8).
    pub(super) d_f: f64,
    /// A member whose detour from the robot is at least this is split off (Eq. 9's ν).
    pub(super) d_g: f64,
    /// Groups are split only while the robot is within this of their anchor (Eq. 9's μ).
    pub(super) d_p: f64,
}

impl From<&ThpConfig> for GroupDistances {
    fn from(cfg: &ThpConfig) -> Self {
        GroupDistances {
            d_f: cfg.d_f_m,
            d_g: cfg.d_g_m,
            d_p: cfg.d_p_m,
        }
    }
}

/// The anchors THP routes over (§3.3, Eq. 5) and the grouping of frontiers around them (§3.4,
/// Alg. 2). It owns the anchors, which degenerate points it has taken, and `P*`: whether anchors
/// appeared since the tour was last planned.
#[derive(Clone, Debug, Default)]
pub(super) struct Anchors {
    list: Vec<Anchor>,
    /// Degenerate-point ids already turned into anchors (or deliberately ignored).
    known_ids: BTreeSet<u64>,
    /// `P*` is not empty.
    new_since_tour: bool,
    stats: AnchorStats,
}

/// The grouping's counters (`planner_stats`).
#[derive(Clone, Copy, Debug, Default)]
struct AnchorStats {
    degenerate: Count,
    frontier: Count,
    visited: Count,
    groups_split: Count,
}

impl Anchors {
    /// Whether anchors appeared since [`Anchors::tour_planned`] (`P*` is not empty; Alg. 1 then
    /// breaks its loop and re-solves the tour).
    pub(super) fn has_new(&self) -> bool {
        self.new_since_tour
    }

    /// The tour was planned over the anchors as they are: `P*` is empty again.
    pub(super) fn tour_planned(&mut self) {
        self.new_since_tour = false;
    }

    fn add(&mut self, pos: Point2<f64>, source: AnchorSource) -> usize {
        self.list.push(Anchor {
            pos,
            source,
            visited: false,
        });
        self.new_since_tour = true;
        match source {
            AnchorSource::Degenerate(_) => self.stats.degenerate.add(1.0),
            AnchorSource::Frontier => self.stats.frontier.add(1.0),
        }
        self.list.len() - 1
    }

    /// Eq. 5: turns a key frame's degenerate points (tracked id, position) into anchors, and moves
    /// each unvisited degenerate anchor with its tracked point. A point where `on_floor` is false
    /// (unknown space, outside the walls, inside furniture) is skipped until it is on the floor.
    /// Without `take_new` (the Table 3 ablation after the first key frame), new points are ignored
    /// for good.
    pub(super) fn take_points(
        &mut self,
        points: &[(u64, Point2<f64>)],
        on_floor: impl Fn(Point2<f64>) -> bool,
        take_new: bool,
    ) {
        for &(id, pos) in points {
            if let Some(a) = self
                .list
                .iter_mut()
                .find(|a| a.source == AnchorSource::Degenerate(id))
            {
                if !a.visited && on_floor(pos) {
                    a.pos = pos;
                }
                continue;
            }
            if self.known_ids.contains(&id) || !on_floor(pos) {
                continue;
            }
            self.known_ids.insert(id);
            if take_new {
                self.add(pos, AnchorSource::Degenerate(id));
            }
        }
    }

    /// Alg. 2: groups the frontiers around the unvisited anchors (Eq. 7–8), makes the ungrouped
    /// ones anchors, splits groups (Eq. 9, [`split_group`]), and marks the anchors whose group is
    /// empty visited. Returns the groups as tour nodes, keyed by anchor index.
    pub(super) fn group(
        &mut self,
        fronts: &[Frontier],
        robot: Point2<f64>,
        d: GroupDistances,
    ) -> Vec<Node> {
        let mut groups: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for (fi, f) in fronts.iter().enumerate() {
            let nearest = self
                .list
                .iter()
                .enumerate()
                .filter(|(_, a)| !a.visited)
                .map(|(k, a)| ((a.pos - f.pos).norm(), k))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let k = match nearest {
                Some((dist, k)) if dist <= d.d_f => k,
                _ => self.add(f.pos, AnchorSource::Frontier),
            };
            groups.entry(k).or_default().push(fi);
        }
        let keys: Vec<usize> = groups.keys().copied().collect();
        for k in keys {
            let members = groups.get(&k).cloned().unwrap_or_default();
            let split = split_group(&members, fronts, robot, self.list[k].pos, d.d_g, d.d_p);
            if split.is_empty() {
                continue;
            }
            self.stats.groups_split.add(1.0);
            groups.insert(
                k,
                members
                    .iter()
                    .copied()
                    .filter(|m| !split.contains(m))
                    .collect(),
            );
            for fi in split {
                let a = self.add(fronts[fi].pos, AnchorSource::Frontier);
                groups.entry(a).or_default().push(fi);
            }
        }
        for (k, a) in self.list.iter_mut().enumerate() {
            if !a.visited && groups.get(&k).is_none_or(|g| g.is_empty()) {
                a.visited = true;
                self.stats.visited.add(1.0);
            }
        }
        groups
            .into_iter()
            .filter(|(_, m)| !m.is_empty())
            .map(|(k, members)| Node {
                key: k,
                pos: self.list[k].pos,
                members,
            })
            .collect()
    }

    /// The grouping's counters, under their `planner_stats` names.
    pub(super) fn stats(&self) -> [(&'static str, Count); 4] {
        let s = &self.stats;
        [
            ("anchors_degenerate", s.degenerate),
            ("anchors_frontier", s.frontier),
            ("anchors_visited", s.visited),
            ("groups_split", s.groups_split),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn front(pos: (f64, f64), cost: f32) -> Frontier {
        Frontier {
            segment: 0,
            pos: Point2::new(pos.0, pos.1),
            aim: 0,
            cost,
        }
    }

    const D: GroupDistances = GroupDistances {
        d_f: 2.0,
        d_g: 2.0,
        d_p: 3.0,
    };

    fn at(x: f64, y: f64) -> Point2<f64> {
        Point2::new(x, y)
    }

    fn anchors_at(points: &[(u64, Point2<f64>)]) -> Anchors {
        let mut anchors = Anchors::default();
        anchors.take_points(points, |_| true, true);
        anchors
    }

    #[test]
    fn frontiers_join_their_nearest_unvisited_anchor_within_d_f() {
        let mut anchors = anchors_at(&[(1, at(0.0, 0.0)), (2, at(3.0, 0.0))]);
        anchors.tour_planned();
        // Straight paths from a robot far away (μ ≥ d_p for both anchors: no split).
        let robot = at(20.0, 20.0);
        let f = |x: f64, y: f64| front((x, y), ((at(x, y) - robot).norm()) as f32);
        let fronts = [f(1.0, 0.0), f(1.6, 0.0), f(2.9, 0.5), f(9.0, 0.0)];
        let nodes = anchors.group(&fronts, robot, D);
        let members: Vec<(usize, Vec<usize>)> =
            nodes.iter().map(|n| (n.key, n.members.clone())).collect();
        // f1 is within d_f of both anchors and joins the nearer, anchor 1 (1.4 m against 1.6 m);
        // f3, beyond d_f of both, becomes anchor 2 with itself as its group (Alg. 2).
        assert_eq!(members, vec![(0, vec![0]), (1, vec![1, 2]), (2, vec![3])]);
        assert_eq!(nodes[2].pos, at(9.0, 0.0));
        assert!(
            anchors.has_new(),
            "a frontier anchor is new: P* is not empty"
        );
    }

    #[test]
    fn frontier_beyond_d_f_of_every_anchor_joins_none() {
        let mut anchors = anchors_at(&[(1, at(0.0, 0.0))]);
        let robot = at(20.0, 20.0);
        let fronts = [front((2.5, 0.0), 30.0)];
        let nodes = anchors.group(&fronts, robot, D);
        // Anchor 0 kept nothing and is visited; the frontier is its own anchor.
        assert_eq!(nodes.len(), 1);
        assert_eq!((nodes[0].key, nodes[0].members.clone()), (1, vec![0]));
        assert_eq!(anchors.stats.visited.get(), Some(1.0));
    }

    #[test]
    fn a_visited_anchor_takes_no_frontier_again() {
        let mut anchors = anchors_at(&[(1, at(0.0, 0.0))]);
        let robot = at(20.0, 20.0);
        // No frontier near anchor 0: it is visited.
        assert!(anchors.group(&[], robot, D).is_empty());
        // A frontier beside it later makes a new anchor rather than reviving the visited one.
        let nodes = anchors.group(&[front((0.5, 0.0), 30.0)], robot, D);
        assert_eq!(nodes.len(), 1);
        assert_eq!(nodes[0].key, 1);
        // Its tracked point does not move a visited anchor either.
        anchors.take_points(&[(1, at(3.0, 3.0))], |_| true, true);
        assert_eq!(anchors.list[0].pos, at(0.0, 0.0));
    }

    #[test]
    fn a_split_makes_the_far_members_anchors_of_their_own() {
        let mut anchors = anchors_at(&[(1, at(1.0, 0.0))]);
        let robot = at(0.0, 0.0);
        // As in the split test above: f1 is 1.5 m away through a wall, 6 m by path.
        let fronts = [front((2.0, 0.0), 2.1), front((0.0, 1.5), 6.0)];
        let nodes = anchors.group(&fronts, robot, D);
        let members: Vec<(usize, Vec<usize>)> =
            nodes.iter().map(|n| (n.key, n.members.clone())).collect();
        assert_eq!(members, vec![(0, vec![0]), (1, vec![1])]);
        assert_eq!(anchors.list[1].source, AnchorSource::Frontier);
        assert_eq!(anchors.stats.groups_split.get(), Some(1.0));
    }

    #[test]
    fn degenerate_points_become_anchors_once_on_the_floor() {
        let mut anchors = Anchors::default();
        let floor = |p: Point2<f64>| p.x >= 0.0;
        // Point 7 is off the floor: skipped, and not forgotten.
        anchors.take_points(&[(7, at(-1.0, 0.0)), (8, at(1.0, 0.0))], floor, true);
        assert_eq!(anchors.list.len(), 1);
        anchors.tour_planned();
        anchors.take_points(&[(7, at(2.0, 0.0)), (8, at(1.5, 0.0))], floor, true);
        assert_eq!(anchors.list.len(), 2);
        assert!(anchors.has_new());
        // Anchor of point 8 moved with its point; off the floor it stays where it was.
        assert_eq!(anchors.list[0].pos, at(1.5, 0.0));
        anchors.take_points(&[(8, at(-3.0, 0.0))], floor, true);
        assert_eq!(anchors.list[0].pos, at(1.5, 0.0));
        // Without `take_new` (Table 3's ablation) a new point is ignored, for good.
        anchors.take_points(&[(9, at(3.0, 0.0))], floor, false);
        anchors.take_points(&[(9, at(3.0, 0.0))], floor, true);
        assert_eq!(anchors.list.len(), 2);
        assert_eq!(anchors.stats.degenerate.get(), Some(2.0));
    }

    #[test]
    fn a_group_across_a_wall_is_split_when_the_robot_is_at_it() {
        let robot = Point2::new(0.0, 0.0);
        let anchor = Point2::new(1.0, 0.0);
        // f0 in the robot's room (path ≈ straight), f1 1.5 m away through the wall but 6 m by path.
        let fronts = [front((2.0, 0.0), 2.1), front((0.0, 1.5), 6.0)];
        assert_eq!(
            split_group(&[0, 1], &fronts, robot, anchor, 2.0, 3.0),
            vec![1]
        );
        // The robot far from the group (μ ≥ d_p): no split.
        let far = Point2::new(-5.0, 0.0);
        assert!(split_group(&[0, 1], &fronts, far, anchor, 2.0, 3.0).is_empty());
        // A group wholly behind the wall is not split again.
        let behind = [front((0.0, 1.5), 6.0), front((0.5, 1.5), 6.4)];
        assert!(split_group(&[0, 1], &behind, robot, anchor, 2.0, 3.0).is_empty());
        // A frontier far across an open room is not a detour.
        let open = [front((2.0, 0.0), 2.1), front((2.9, 0.0), 3.0)];
        assert!(split_group(&[0, 1], &open, robot, anchor, 2.0, 3.0).is_empty());
    }

    #[test]
    fn kmeans_separates_two_distant_clusters() {
        let mut fronts = Vec::new();
        for i in 0..4 {
            fronts.push(front((i as f64 * 0.3, 0.0), 1.0));
            fronts.push(front((20.0 + i as f64 * 0.3, 5.0), 1.0));
        }
        for (i, f) in fronts.iter_mut().enumerate() {
            f.segment = i;
        }
        // 8 segments of 10 cells at 0.1 m = 8 m of frontier, 4 m per cluster: k = 2.
        let cells = vec![vec![0usize; 10]; 8];
        let nodes = kmeans_nodes(&fronts, &cells, 0.1, 4.0);
        assert_eq!(nodes.len(), 2);
        for n in &nodes {
            let xs: Vec<f64> = n.members.iter().map(|&m| fronts[m].pos.x).collect();
            assert!(
                xs.iter().all(|&x| x < 1.0) || xs.iter().all(|&x| x > 19.0),
                "{xs:?}"
            );
            assert_eq!(n.members.len(), 4);
        }
    }
}
