//! Separatrices and the topology graph (TENSOR §4.2 and §6).
//!
//! Separatrix directions come from the locally linear field at the point (Delmarcelle & Hesselink):
//! with `a = a₁x + a₂y`, `b = b₁x + b₂y`, a ray at angle φ is a separatrix of the major field when the
//! major eigenvector is radial there, i.e. `b₂u³ + (2a₂+b₁)u² + (2a₁−b₂)u − b₁ = 0` with `u = tan φ`,
//! taking of each root's two rays the one where the tensor is positive along the ray. The cubic is
//! solved on the circle (scan of `a sin 2φ − b cos 2φ` over φ, then bisection), which also covers
//! φ = 90°. A wedge has one or three such rays, a trisector three.
//!
//! Edges: separatrices traced with RK4 that reach another point; then, because tracing can miss
//! connections, points are paired by shortest paths (TENSOR §6): a multi-source Dijkstra over free
//! cells gives each cell its nearest point, neighbouring cells of different points give candidate
//! pairs with their path length, and the shortest candidates that join separate components are added
//! (Kruskal), so every group of mutually reachable points ends up connected.

use super::advect::{trace, StopConditions, StopReason};
use super::degenerate::{DegenerateKind, DegeneratePoint};
use super::eval::FieldGrid;
use crate::grid::{Cell, GridSpec, NEIGHBOURS_8};
use nalgebra::{Point2, Vector2};
use rayon::prelude::*;
use serde::Serialize;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A traced separatrix.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Separatrix {
    /// Index of the point it leaves from, in [`TopologyGraph::nodes`].
    pub from: usize,
    /// Leaving direction, radians.
    pub direction: f64,
    pub end: StopReason,
    pub length_m: f64,
    pub polyline: Vec<[f64; 2]>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EdgeKind {
    Separatrix,
    /// Added by shortest-path pairing where tracing missed a connection.
    ShortestPath,
}

/// An edge of the topology graph between two nodes (indices into [`TopologyGraph::nodes`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TopoEdge {
    pub a: usize,
    pub b: usize,
    pub kind: EdgeKind,
    pub length_m: f64,
    pub polyline: Vec<[f64; 2]>,
}

/// Nodes (degenerate points), separatrices and edges.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TopologyGraph {
    pub nodes: Vec<DegeneratePoint>,
    pub separatrices: Vec<Separatrix>,
    pub edges: Vec<TopoEdge>,
}

/// Options of the tracer (the step is at least half a topology cell: finer buys nothing there).
#[derive(Clone, Copy, Debug)]
pub struct TraceOptions {
    pub step_m: f64,
    pub max_length_m: f64,
    pub arrive_radius_m: f64,
    pub stop_at_unknown: bool,
}

/// Separatrix directions (radians) at `p` from the linear model of `field` there.
pub fn separatrix_directions(field: &FieldGrid, p: Point2<f64>) -> Vec<f64> {
    let Some((c0, u, t)) = field.bilinear_cell(p) else {
        return Vec::new();
    };
    let s = &field.spec;
    let i00 = s.index(c0);
    let v = [i00, i00 + 1, i00 + 1 + s.nx, i00 + s.nx].map(|i| field.ab[i]);
    // Gradients of the bilinear interpolant at (u, t), per metre.
    let grad = |k: usize| {
        let du = (v[1][k] - v[0][k]) * (1.0 - t) + (v[2][k] - v[3][k]) * t;
        let dt = (v[3][k] - v[0][k]) * (1.0 - u) + (v[2][k] - v[1][k]) * u;
        (du / s.res, dt / s.res)
    };
    let ((a1, a2), (b1, b2)) = (grad(0), grad(1));
    let along = |phi: f64| {
        let (c, sn) = (phi.cos(), phi.sin());
        (a1 * c + a2 * sn, b1 * c + b2 * sn)
    };
    let h = |phi: f64| {
        let (a, b) = along(phi);
        a * (2.0 * phi).sin() - b * (2.0 * phi).cos()
    };
    let positive = |phi: f64| {
        let (a, b) = along(phi);
        a * (2.0 * phi).cos() + b * (2.0 * phi).sin() > 0.0
    };
    const N: usize = 720;
    let step = std::f64::consts::TAU / N as f64;
    let mut out = Vec::new();
    for k in 0..N {
        let (mut lo, mut hi) = (k as f64 * step, (k + 1) as f64 * step);
        let (hl, hh) = (h(lo), h(hi));
        if hl == 0.0 {
            if positive(lo) {
                out.push(lo);
            }
            continue;
        }
        if hl * hh >= 0.0 {
            continue;
        }
        for _ in 0..50 {
            let mid = 0.5 * (lo + hi);
            if h(lo) * h(mid) <= 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let phi = 0.5 * (lo + hi);
        if positive(phi) {
            out.push(phi);
        }
    }
    out
}

/// Traces the separatrices of `nodes` and builds the graph (with shortest-path pairing).
pub fn build(
    field: &FieldGrid,
    nodes: Vec<DegeneratePoint>,
    fine: &GridSpec,
    obstacle: &[bool],
    unknown: &[bool],
    opts: &TraceOptions,
) -> TopologyGraph {
    let positions: Vec<Point2<f64>> = nodes.iter().map(|n| n.pos()).collect();
    // Trace every node's separatrices in parallel; results are collected in node order.
    let traced: Vec<(Vec<Separatrix>, Vec<TopoEdge>)> = (0..nodes.len())
        .into_par_iter()
        .map(|i| trace_node(field, &nodes, &positions, i, fine, obstacle, unknown, opts))
        .collect();
    let mut separatrices = Vec::new();
    let mut edges = Vec::new();
    for (s, e) in traced {
        separatrices.extend(s);
        edges.extend(e);
    }
    // Keep the shortest separatrix edge per pair.
    edges.sort_by(|x, y| {
        (x.a, x.b)
            .cmp(&(y.a, y.b))
            .then(x.length_m.total_cmp(&y.length_m))
    });
    edges.dedup_by(|x, y| x.a == y.a && x.b == y.b);
    let mut graph = TopologyGraph {
        nodes,
        separatrices,
        edges,
    };
    pair_by_shortest_paths(&mut graph, field, fine, obstacle);
    graph
}

/// The separatrices of node `i` and the edges they make.
#[allow(clippy::too_many_arguments)]
fn trace_node(
    field: &FieldGrid,
    nodes: &[DegeneratePoint],
    positions: &[Point2<f64>],
    i: usize,
    fine: &GridSpec,
    obstacle: &[bool],
    unknown: &[bool],
    opts: &TraceOptions,
) -> (Vec<Separatrix>, Vec<TopoEdge>) {
    let n = &nodes[i];
    let mut separatrices = Vec::new();
    let mut edges = Vec::new();
    if n.kind == DegenerateKind::Other {
        return (separatrices, edges);
    }
    for phi in separatrix_directions(field, n.pos()) {
        let stop = StopConditions {
            grid: fine,
            obstacle: Some(obstacle),
            unknown: opts.stop_at_unknown.then_some(unknown),
            degenerate_points: positions,
            degenerate_radius_m: opts.arrive_radius_m,
            origin: Some(i),
        };
        // Start one field cell out along the ray: at the point itself the direction is undefined.
        let start = n.pos() + unit(phi) * field.spec.res;
        let (mut line, end) = trace(
            |p, _| field.sample(p).map(|s| [s.a, s.b]),
            start,
            phi,
            opts.max_length_m,
            opts.step_m.max(0.5 * field.spec.res),
            &stop,
        );
        line.insert(0, n.pos());
        let mut polyline: Vec<[f64; 2]> = line.iter().map(|p| [p.x, p.y]).collect();
        let mut length_m = polyline_length(&polyline);
        if let StopReason::NearDegenerate(j) = end {
            polyline.push([positions[j].x, positions[j].y]);
            length_m = polyline_length(&polyline);
            if j != i {
                edges.push(TopoEdge {
                    a: i.min(j),
                    b: i.max(j),
                    kind: EdgeKind::Separatrix,
                    length_m,
                    polyline: polyline.clone(),
                });
            }
        }
        separatrices.push(Separatrix {
            from: i,
            direction: phi,
            end,
            length_m,
            polyline,
        });
    }
    (separatrices, edges)
}

fn polyline_length(p: &[[f64; 2]]) -> f64 {
    p.windows(2)
        .map(|w| ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt())
        .sum()
}

fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

/// TENSOR §6 fallback: connect components by the shortest free-space paths between their points,
/// computed on the cells of `field.spec` (a cell is blocked if any fine obstacle cell lies in it).
fn pair_by_shortest_paths(
    graph: &mut TopologyGraph,
    field: &FieldGrid,
    fine: &GridSpec,
    obstacle: &[bool],
) {
    let n = graph.nodes.len();
    if n < 2 {
        return;
    }
    let s = &field.spec;
    let mut blocked = vec![false; s.cells()];
    for (i, &o) in obstacle.iter().enumerate() {
        if o {
            let p = fine.center(fine.cell(i));
            if let Some(c) = s.cell_of(p) {
                blocked[s.index(c)] = true;
            }
        }
    }
    let mut dist = vec![f64::INFINITY; s.cells()];
    let mut label = vec![usize::MAX; s.cells()];
    let mut parent = vec![usize::MAX; s.cells()];
    let mut heap = BinaryHeap::new();
    for (k, node) in graph.nodes.iter().enumerate() {
        if let Some(c) = s.cell_of(node.pos()) {
            let i = s.index(c);
            let d = (s.center(c) - node.pos()).norm();
            if !blocked[i] && d < dist[i] {
                dist[i] = d;
                label[i] = k;
                heap.push((Reverse(d.to_bits()), i));
            }
        }
    }
    while let Some((Reverse(bits), i)) = heap.pop() {
        if f64::from_bits(bits) > dist[i] {
            continue;
        }
        let c = s.cell(i);
        for (dx, dy) in NEIGHBOURS_8 {
            let Some(j) = s.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                continue;
            };
            if blocked[j] {
                continue;
            }
            let nd = dist[i] + s.res * ((dx * dx + dy * dy) as f64).sqrt();
            if nd < dist[j] {
                dist[j] = nd;
                label[j] = label[i];
                parent[j] = i;
                heap.push((Reverse(nd.to_bits()), j));
            }
        }
    }
    // Candidate pairs: the shortest crossing between two Voronoi regions.
    let mut best: Vec<(f64, usize, usize, usize, usize)> = Vec::new();
    for i in 0..s.cells() {
        if label[i] == usize::MAX {
            continue;
        }
        let c = s.cell(i);
        for (dx, dy) in NEIGHBOURS_8 {
            let Some(j) = s.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                continue;
            };
            if label[j] == usize::MAX || label[j] <= label[i] {
                continue;
            }
            let len = dist[i] + dist[j] + s.res * ((dx * dx + dy * dy) as f64).sqrt();
            best.push((len, label[i], label[j], i, j));
        }
    }
    best.sort_by(|x, y| {
        x.0.total_cmp(&y.0)
            .then((x.1, x.2, x.3, x.4).cmp(&(y.1, y.2, y.3, y.4)))
    });
    let mut uf: Vec<usize> = (0..n).collect();
    for e in &graph.edges {
        let (ra, rb) = (find(&mut uf, e.a), find(&mut uf, e.b));
        uf[ra] = rb;
    }
    let backtrack = |mut i: usize| {
        let mut pts = Vec::new();
        while i != usize::MAX {
            let p = s.center(s.cell(i));
            pts.push([p.x, p.y]);
            i = parent[i];
        }
        pts
    };
    for (len, a, b, i, j) in best {
        let (ra, rb) = (find(&mut uf, a), find(&mut uf, b));
        if ra == rb {
            continue;
        }
        uf[ra] = rb;
        let mut poly = vec![[graph.nodes[a].x, graph.nodes[a].y]];
        let mut left = backtrack(i);
        left.reverse();
        poly.extend(left);
        poly.extend(backtrack(j));
        poly.push([graph.nodes[b].x, graph.nodes[b].y]);
        graph.edges.push(TopoEdge {
            a,
            b,
            kind: EdgeKind::ShortestPath,
            length_m: len,
            polyline: poly,
        });
    }
}

impl TopologyGraph {
    /// Shortest distances over the graph's edges from node `from` (∞ where unreachable).
    pub fn distances_from(&self, from: usize) -> Vec<f64> {
        let mut dist = vec![f64::INFINITY; self.nodes.len()];
        if from >= dist.len() {
            return dist;
        }
        dist[from] = 0.0;
        let mut heap = BinaryHeap::new();
        heap.push((Reverse(0f64.to_bits()), from));
        while let Some((Reverse(bits), i)) = heap.pop() {
            let d = f64::from_bits(bits);
            if d > dist[i] {
                continue;
            }
            for e in &self.edges {
                let j = if e.a == i {
                    e.b
                } else if e.b == i {
                    e.a
                } else {
                    continue;
                };
                let nd = d + e.length_m;
                if nd < dist[j] {
                    dist[j] = nd;
                    heap.push((Reverse(nd.to_bits()), j));
                }
            }
        }
        dist
    }

    /// Number of wedges and trisectors.
    pub fn counts(&self) -> (usize, usize) {
        let w = self
            .nodes
            .iter()
            .filter(|n| n.kind == DegenerateKind::Wedge)
            .count();
        let t = self
            .nodes
            .iter()
            .filter(|n| n.kind == DegenerateKind::Trisector)
            .count();
        (w, t)
    }
}

/// Unit vector at angle `phi`.
pub fn unit(phi: f64) -> Vector2<f64> {
    Vector2::new(phi.cos(), phi.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn linear(f: impl Fn(f64, f64) -> [f64; 2]) -> FieldGrid {
        crate::field::synth::field_from_fn(1.0, f)
    }

    #[test]
    fn trisector_has_three_separatrices_wedge_one_or_three() {
        // (a, b) = (x, -y): the standard trisector; separatrices at 0°, 120°, 240°.
        let g = linear(|x, y| [x, -y]);
        let d = separatrix_directions(&g, Point2::new(0.0, 0.0));
        assert_eq!(d.len(), 3, "{d:?}");
        for (k, phi) in d.iter().enumerate() {
            let want = k as f64 * std::f64::consts::TAU / 3.0;
            assert!(crate::util::wrap_angle(phi - want).abs() < 1e-6, "{d:?}");
        }
        // (a, b) = (x, y): the standard wedge; one separatrix along +x.
        let g = linear(|x, y| [x, y]);
        let d = separatrix_directions(&g, Point2::new(0.0, 0.0));
        assert_eq!(d.len(), 1, "{d:?}");
        assert!(d[0].abs() < 1e-6 || (d[0] - std::f64::consts::TAU).abs() < 1e-6);
    }

    #[test]
    fn shortest_path_pairing_connects_everything_reachable() {
        let g = linear(|_, _| [1.0, 0.0]);
        let fine = g.spec;
        let obstacle = vec![false; fine.cells()];
        let node = |id, x, y| DegeneratePoint {
            id,
            x,
            y,
            kind: DegenerateKind::Wedge,
            winding: 1,
            clearance_m: 1.0,
        };
        let nodes = vec![node(0, -0.5, -0.5), node(1, 0.5, -0.5), node(2, 0.0, 0.6)];
        let opts = TraceOptions {
            step_m: 0.05,
            max_length_m: 0.0,
            arrive_radius_m: 0.1,
            stop_at_unknown: false,
        };
        let graph = build(&g, nodes, &fine, &obstacle, &obstacle, &opts);
        assert_eq!(graph.edges.len(), 2);
        let d = graph.distances_from(0);
        assert!(d.iter().all(|x| x.is_finite()));
        assert!((d[1] - 1.0).abs() < 0.15, "{d:?}");
    }
}
