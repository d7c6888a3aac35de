//! TENSOR's global routing (Xu et al., ACM TOG 2017, §4.2): the information gain `I(p)`, the
//! routing graph over the field's topology, Prim's tree from the root and the target edge, and
//! driving to a node.

use super::*;

/// Information gain `I(p)` from a summed-area table of observable frontier cells (see module doc).
pub struct GainMap {
    grid: GridSpec,
    /// `(nx + 1) × (ny + 1)` prefix sums.
    sat: Vec<u32>,
    half: i32,
    norm: f64,
}

impl GainMap {
    pub fn new(grid: &GridSpec, radius_m: f64, frontier: impl Fn(usize) -> bool) -> Self {
        let (nx, ny) = (grid.nx, grid.ny);
        let w = nx + 1;
        let mut sat = vec![0u32; w * (ny + 1)];
        for y in 0..ny {
            let mut row = 0u32;
            for x in 0..nx {
                row += frontier(grid.index(Cell::new(x as i32, y as i32))) as u32;
                sat[(y + 1) * w + x + 1] = sat[y * w + x + 1] + row;
            }
        }
        let half = (radius_m / grid.res).round().max(1.0) as i32;
        GainMap {
            grid: *grid,
            sat,
            half,
            norm: (2 * half + 1) as f64,
        }
    }

    /// `I(p) ∈ [0, 1]`.
    pub fn at(&self, p: Point2<f64>) -> f64 {
        let c = self.grid.cell_at(p.x, p.y);
        let (nx, ny) = (self.grid.nx as i32, self.grid.ny as i32);
        let x0 = (c.x - self.half).clamp(0, nx) as usize;
        let x1 = (c.x + self.half + 1).clamp(0, nx) as usize;
        let y0 = (c.y - self.half).clamp(0, ny) as usize;
        let y1 = (c.y + self.half + 1).clamp(0, ny) as usize;
        let w = self.grid.nx + 1;
        let n = self.sat[y1 * w + x1] + self.sat[y0 * w + x0]
            - self.sat[y0 * w + x1]
            - self.sat[y1 * w + x0];
        (n as f64 / self.norm).min(1.0)
    }

    /// `Ī = (1/ℓ) ∫ I dp` along a polyline (midpoint rule on pieces of at most one cell); `I` of
    /// the point for a single point.
    pub fn mean_along(&self, line: &[Point2<f64>]) -> f64 {
        let (mut sum, mut len) = (0.0, 0.0);
        for w in line.windows(2) {
            let d = w[1] - w[0];
            let l = d.norm();
            let n = (l / self.grid.res).ceil().max(1.0) as usize;
            for k in 0..n {
                let p = w[0] + d * ((k as f64 + 0.5) / n as f64);
                sum += l / n as f64 * self.at(p);
            }
            len += l;
        }
        if len > 0.0 {
            sum / len
        } else {
            line.first().map_or(0.0, |p| self.at(*p))
        }
    }
}

/// An edge of the routing graph: node `a` to node `b`, or an open separatrix of `a` (`b = None`).
#[derive(Clone, Debug, PartialEq)]
pub struct RouteEdge {
    pub a: usize,
    pub b: Option<usize>,
    /// Mean information gain `Ī(e)`.
    pub gain: f64,
    /// From `a` to `b` (or to the separatrix's end).
    pub polyline: Vec<Point2<f64>>,
}

impl RouteEdge {
    /// `c(e) = 1 / Ī(e)` (§4.2), with the gain floored so that the cost stays finite.
    pub fn cost(&self) -> f64 {
        1.0 / self.gain.max(GAIN_FLOOR)
    }
}

/// A tree grown from a root: per node the edge to its parent and the summed cost from the root.
#[derive(Clone, Debug, PartialEq)]
pub struct Tree {
    pub parent_edge: Vec<Option<usize>>,
    /// Tree-path cost from the root (∞ outside the root's component).
    pub dist: Vec<f64>,
}

/// Prim's minimum spanning tree of `root`'s component over the node–node edges (leaves ignored).
/// Ties go to the lower edge index, so the tree is deterministic.
pub fn min_spanning_tree(n: usize, edges: &[RouteEdge], root: usize) -> Tree {
    let mut tree = Tree {
        parent_edge: vec![None; n],
        dist: vec![f64::INFINITY; n],
    };
    if root >= n {
        return tree;
    }
    let mut inside = vec![false; n];
    inside[root] = true;
    tree.dist[root] = 0.0;
    loop {
        let mut best: Option<(f64, usize, usize)> = None;
        for (k, e) in edges.iter().enumerate() {
            let Some(b) = e.b else { continue };
            let to = match (inside[e.a], inside[b]) {
                (true, false) => b,
                (false, true) => e.a,
                _ => continue,
            };
            let c = e.cost();
            if best.is_none_or(|(bc, bk, _)| (c, k) < (bc, bk)) {
                best = Some((c, k, to));
            }
        }
        let Some((c, k, to)) = best else { break };
        let e = &edges[k];
        let from = if e.a == to {
            e.b.expect("node edge")
        } else {
            e.a
        };
        inside[to] = true;
        tree.parent_edge[to] = Some(k);
        tree.dist[to] = tree.dist[from] + c;
    }
    tree
}

/// Where global routing sends the robot.
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    /// Index of the target edge in the routing graph.
    pub edge: usize,
    /// The node at which the robot enters the target edge (its end nearer the root in the tree).
    pub node: usize,
    /// Tree-path cost from the root to `node` plus the edge's own cost.
    pub cost: f64,
}

/// The cheapest edge with `Ī ≥ threshold` reached over the tree (§4.2), or `None` when no edge of
/// the root's component has gain: the termination condition. A non-tree edge can be chosen only
/// through a tree node; by the cut property, its tree path holds edges of at least its gain.
pub fn select_target(edges: &[RouteEdge], tree: &Tree, threshold: f64) -> Option<Target> {
    let mut best: Option<Target> = None;
    for (k, e) in edges.iter().enumerate() {
        if e.gain < threshold {
            continue;
        }
        let node = match e.b {
            None => e.a,
            Some(b) => {
                if tree.dist[b] < tree.dist[e.a] {
                    b
                } else {
                    e.a
                }
            }
        };
        if !tree.dist[node].is_finite() {
            continue;
        }
        let cost = tree.dist[node] + e.cost();
        if best.as_ref().is_none_or(|t| (cost, k) < (t.cost, t.edge)) {
            best = Some(Target {
                edge: k,
                node,
                cost,
            });
        }
    }
    best
}

/// The direction in which to leave `node` along `edge`: toward the edge's point about `reach_m`
/// along it from that node.
pub fn leaving_heading(edge: &RouteEdge, node: usize, reach_m: f64) -> Option<f64> {
    let forward = edge.a == node;
    let pts: Vec<Point2<f64>> = if forward {
        edge.polyline.clone()
    } else {
        edge.polyline.iter().rev().copied().collect()
    };
    let start = *pts.first()?;
    let mut along = 0.0;
    let mut target = *pts.last()?;
    for w in pts.windows(2) {
        along += (w[1] - w[0]).norm();
        if along >= reach_m {
            target = w[1];
            break;
        }
    }
    let d: Vector2<f64> = target - start;
    (d.norm() > 1e-9).then(|| d.y.atan2(d.x))
}

impl Tensor {
    /// Graph nodes on traversable cells (wedges and trisectors), in graph order.
    pub(super) fn usable_nodes(&self, map: &Map) -> Vec<Node> {
        let Some(field) = &self.field else {
            return Vec::new();
        };
        let grid = map.grid();
        field
            .points()
            .iter()
            .filter(|n| n.kind != DegenerateKind::Other)
            .filter(|n| {
                grid.cell_of(n.pos())
                    .is_some_and(|c| map.is_traversable(grid.index(c)))
            })
            .map(|n| Node {
                id: n.id,
                kind: n.kind,
                pos: n.pos(),
            })
            .collect()
    }

    /// The routing graph with gains, the snapped node cells, and the distance field, for routing.
    pub(super) fn routing_graph(&self, ctx: &mut PlanContext) -> Option<RoutingGraph> {
        let field = self.field.as_ref()?;
        let grid = *ctx.map.grid();
        let robot = ctx.pose.position();
        let start = grid.index(grid.cell_of(robot)?);
        let map = ctx.map;
        let search_cfg = &ctx.cfg.search;
        let df = ctx.search.distance_field(
            &grid,
            |i| crate::plan::step_cost(map, search_cfg, robot, i),
            start,
            f32::INFINITY,
        );
        let gains = GainMap::new(&grid, self.cfg.gain_radius_m, |i| {
            map.is_frontier(i) && !self.greedy.is_given_up(i) && df.cost_to(i).is_some()
        });
        // Nodes snapped to their nearest reachable cell (graph index → routing index).
        let snap = (SNAP_M / grid.res).ceil() as i32;
        let mut nodes = Vec::new();
        let mut cells = Vec::new();
        let mut index_of = vec![usize::MAX; field.points().len()];
        for (k, n) in field.points().iter().enumerate() {
            if n.kind == DegenerateKind::Other
                || self
                    .node_failures
                    .get(&n.id)
                    .is_some_and(|&f| f >= MAX_NODE_FAILURES)
            {
                continue;
            }
            let Some(c) = grid.cell_of(n.pos()) else {
                continue;
            };
            let mut best: Option<(f64, usize)> = None;
            for dy in -snap..=snap {
                for dx in -snap..=snap {
                    let Some(i) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                        continue;
                    };
                    if df.cost_to(i).is_none() || !map.is_traversable(i) {
                        continue;
                    }
                    let d = (grid.center(grid.cell(i)) - n.pos()).norm();
                    if d <= SNAP_M && best.is_none_or(|(bd, bi)| (d, i) < (bd, bi)) {
                        best = Some((d, i));
                    }
                }
            }
            if let Some((_, i)) = best {
                index_of[k] = nodes.len();
                nodes.push(Node {
                    id: n.id,
                    kind: n.kind,
                    pos: n.pos(),
                });
                cells.push(i);
            }
        }
        let contact_ok = |line: &[Point2<f64>]| {
            let ok = line
                .iter()
                .filter(|p| {
                    grid.cell_of(**p).is_some_and(|c| {
                        let i = grid.index(c);
                        !map.is_inflated(i) && !map.is_obstacle(i)
                    })
                })
                .count();
            !line.is_empty() && ok as f64 >= ACCESSIBLE_FRACTION * line.len() as f64
        };
        let mut edges = Vec::new();
        let graph = field.graph();
        for e in &graph.edges {
            let (a, b) = (index_of[e.a], index_of[e.b]);
            if a == usize::MAX || b == usize::MAX {
                continue;
            }
            let polyline: Vec<Point2<f64>> =
                e.polyline.iter().map(|p| Point2::new(p[0], p[1])).collect();
            if !contact_ok(&polyline) {
                continue;
            }
            edges.push(RouteEdge {
                a,
                b: Some(b),
                gain: gains.mean_along(&polyline),
                polyline,
            });
        }
        for s in &graph.separatrices {
            let open = !matches!(s.end, StopReason::NearDegenerate(j) if j != s.from);
            let a = index_of[s.from];
            if !open || a == usize::MAX {
                continue;
            }
            let polyline: Vec<Point2<f64>> =
                s.polyline.iter().map(|p| Point2::new(p[0], p[1])).collect();
            if polyline.len() < 2 || !contact_ok(&polyline) {
                continue;
            }
            edges.push(RouteEdge {
                a,
                b: None,
                gain: gains.mean_along(&polyline),
                polyline,
            });
        }
        Some(RoutingGraph {
            nodes,
            cells,
            edges,
            df,
        })
    }

    /// Global routing (§4.2) from the node `root_id`, or from the nearest reachable node.
    pub(super) fn route(&mut self, ctx: &mut PlanContext, root_id: Option<u64>) -> Routed {
        let Some(RoutingGraph {
            nodes,
            cells,
            edges,
            df,
        }) = self.routing_graph(ctx)
        else {
            return Routed::Nothing;
        };
        let grid = *ctx.map.grid();
        let robot = ctx.pose.position();
        let root = match root_id.and_then(|id| nodes.iter().position(|n| n.id == id)) {
            Some(r) => r,
            None => {
                // Not on the graph: the nearest node by path cost (ties: lower index).
                let Some(r) = (0..nodes.len())
                    .filter_map(|k| df.cost_to(cells[k]).map(|c| (c, k)))
                    .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
                    .map(|(_, k)| k)
                else {
                    return Routed::Nothing;
                };
                r
            }
        };
        let tree = min_spanning_tree(nodes.len(), &edges, root);
        let Some(target) = select_target(&edges, &tree, self.cfg.min_info_gain) else {
            return Routed::Nothing;
        };
        let at_root = (nodes[root].pos - robot).norm() <= self.cfg.dock_radius_m;
        if !at_root {
            // Get onto the graph first: A* to the nearest node, routing again there.
            return self.go_to_node(&grid, &df, &nodes[root], cells[root], None);
        }
        self.stats.mst_routes += 1;
        let reach = self.field_cfg.arrive_radius_m * 2.0;
        let heading = leaving_heading(&edges[target.edge], target.node, reach);
        if target.node == root {
            self.stats.branch_choices += 1;
            return match heading {
                Some(h) => Routed::Leave {
                    heading: h,
                    node_id: nodes[root].id,
                },
                None => Routed::Nothing,
            };
        }
        let node = nodes[target.node];
        self.go_to_node(&grid, &df, &node, cells[target.node], heading)
    }

    pub(super) fn go_to_node(
        &mut self,
        grid: &GridSpec,
        df: &crate::plan::search::DistanceField,
        node: &Node,
        cell: usize,
        heading: Option<f64>,
    ) -> Routed {
        let Some(path) = df.path_to(grid, cell) else {
            return Routed::Nothing;
        };
        let pts: Vec<Point2<f64>> = path.cells.iter().map(|c| grid.center(*c)).collect();
        self.route_target = Some(node.pos);
        self.advecting = false;
        self.current = Current::Route {
            id: node.id,
            pos: node.pos,
            heading,
            cells: path.cells.iter().skip(1).map(|c| grid.index(*c)).collect(),
        };
        if pts.len() < 2 {
            // Already in the node's cell: arrive at once (after a look).
            self.current = Current::Arrived(Arrival {
                id: node.id,
                kind: ArrivalKind::Route { heading },
            });
            return Routed::Go(Action::LookAround);
        }
        Routed::Go(Action::Follow {
            path: pts,
            look_on_arrival: false,
            exact_arrival: false,
        })
    }

    /// Whether some accessible edge still has gain (ends the fallback mode).
    pub(super) fn graph_has_gain(&mut self, ctx: &mut PlanContext) -> bool {
        // Every routing node is reachable (snapped to a reachable cell), so every edge kept is
        // accessible.
        self.routing_graph(ctx)
            .is_some_and(|g| g.edges.iter().any(|e| e.gain >= self.cfg.min_info_gain))
    }

    /// Whether an edge or open separatrix at node `id` has gain.
    pub(super) fn node_has_gain(&mut self, ctx: &mut PlanContext, id: u64) -> bool {
        let Some(RoutingGraph { nodes, edges, .. }) = self.routing_graph(ctx) else {
            return false;
        };
        let Some(k) = nodes.iter().position(|n| n.id == id) else {
            return false;
        };
        edges
            .iter()
            .any(|e| (e.a == k || e.b == Some(k)) && e.gain >= self.cfg.min_info_gain)
    }
}
