//! Fixed-start open-path TSP (THP Eq. 6, NBV-TSP's FSOTSP): visit every node once starting at a
//! given node, without returning; minimise `cost(start, π1) + Σ cost(πi, πi+1)`. Matrices may be
//! asymmetric and may hold `f64::INFINITY` (unreachable).
//!
//! Solvers: [`brute_force`] (reference, n ≤ 10), [`held_karp`] (exact, n ≤ 20), [`heuristic`]
//! (nearest neighbour, then 2-opt and Or-opt to a local optimum, then a fixed number of
//! segment-swap kicks, an iterated local search), [`genetic`] (NBV-TSP Alg. 5) and [`solve`].
//!
//! Non-finite entries are replaced internally by a penalty larger than any path of finite edges, so
//! a solver first minimises the number of unreachable edges and then the finite cost, never sees a
//! NaN, and reports the true cost (infinite if an unreachable edge could not be avoided).
//!
//! Measured quality (tests `heuristic_gap_vs_exact_n10_to_12` and `genetic_gap_vs_exact`, 2026-11-21,
//! 300 instances of n = 10..12 uniform random points in the unit square, Euclidean costs, against
//! Held–Karp):
//! - heuristic: mean gap 0.022 %, worst 2.07 %; the 2-opt + Or-opt descent alone (from the index
//!   order, no kicks): mean 0.56 %, worst 12.2 %.
//! - genetic (population 60, groups of 4, 2000 generations, stall 300): mean 0.14 %, worst 8.5 %.
//!
//! Speed (`cargo bench --bench tsp`): heuristic on 30 nodes 0.58 ms, Held–Karp on 12 nodes 0.52 ms,
//! genetic with the `[nbv]` defaults on 30 nodes 2.0 ms.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};

/// Dense cost matrix, row-major; cost(i, j) may be asymmetric; `f64::INFINITY` = unreachable.
#[derive(Clone, Debug, PartialEq)]
pub struct CostMatrix {
    n: usize,
    c: Vec<f64>,
}

impl CostMatrix {
    /// An `n × n` matrix of zeros.
    pub fn new(n: usize) -> Self {
        CostMatrix {
            n,
            c: vec![0.0; n * n],
        }
    }

    /// An `n × n` matrix with `cost(i, j) = f(i, j)`, filled row by row.
    pub fn from_fn(n: usize, mut f: impl FnMut(usize, usize) -> f64) -> Self {
        let mut c = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                c.push(f(i, j));
            }
        }
        CostMatrix { n, c }
    }

    pub fn n(&self) -> usize {
        self.n
    }

    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.c[i * self.n + j]
    }

    pub fn set(&mut self, i: usize, j: usize, c: f64) {
        self.c[i * self.n + j] = c;
    }

    /// A copy with every non-finite entry (infinite or NaN) replaced by a penalty exceeding the cost
    /// of any open path of finite edges, so that comparisons are total and sums never become NaN.
    fn finite(&self) -> CostMatrix {
        let max_abs = self
            .c
            .iter()
            .filter(|c| c.is_finite())
            .fold(0.0f64, |m, c| m.max(c.abs()));
        // A path has at most n − 1 edges, each in [−max_abs, max_abs]: 2 n max_abs bounds the
        // difference between any two finite paths.
        let penalty = (max_abs + 1.0) * 2.0 * (self.n as f64 + 1.0);
        CostMatrix {
            n: self.n,
            c: self
                .c
                .iter()
                .map(|&c| if c.is_finite() { c } else { penalty })
                .collect(),
        }
    }
}

/// An open path (fixed start, no return): `order[0] == start`, every node exactly once.
#[derive(Clone, Debug, PartialEq)]
pub struct Tour {
    pub order: Vec<usize>,
    pub cost: f64,
}

impl Tour {
    fn of(m: &CostMatrix, order: Vec<usize>) -> Tour {
        let cost = open_path_cost(m, &order);
        Tour { order, cost }
    }
}

/// The cost of visiting `order` in sequence, without returning (0 for fewer than two nodes).
pub fn open_path_cost(m: &CostMatrix, order: &[usize]) -> f64 {
    order.windows(2).map(|w| m.get(w[0], w[1])).sum()
}

/// The trivial answers for n ≤ 2, shared by every solver.
fn trivial(m: &CostMatrix, start: usize) -> Option<Tour> {
    assert!(
        start < m.n() || m.n() == 0,
        "start {start} out of range for {} nodes",
        m.n()
    );
    match m.n() {
        0 => Some(Tour {
            order: Vec::new(),
            cost: 0.0,
        }),
        1 => Some(Tour::of(m, vec![start])),
        2 => Some(Tour::of(m, vec![start, 1 - start])),
        _ => None,
    }
}

/// Exact by enumeration of every order (the reference for tests; n ≤ 10). Ties go to the order that
/// comes first lexicographically.
pub fn brute_force(m: &CostMatrix, start: usize) -> Tour {
    if let Some(t) = trivial(m, start) {
        return t;
    }
    assert!(m.n() <= 10, "brute_force is limited to 10 nodes");
    let w = m.finite();
    let mut rest: Vec<usize> = (0..m.n()).filter(|&i| i != start).collect();
    let mut order = vec![start];
    let mut best: (f64, Vec<usize>) = (f64::INFINITY, Vec::new());
    fn go(
        w: &CostMatrix,
        rest: &mut Vec<usize>,
        order: &mut Vec<usize>,
        cost: f64,
        best: &mut (f64, Vec<usize>),
    ) {
        if rest.is_empty() {
            if cost < best.0 {
                *best = (cost, order.clone());
            }
            return;
        }
        for k in 0..rest.len() {
            let v = rest.remove(k);
            let c = cost + w.get(*order.last().expect("start is in order"), v);
            order.push(v);
            go(w, rest, order, c, best);
            order.pop();
            rest.insert(k, v);
        }
    }
    go(&w, &mut rest, &mut order, 0.0, &mut best);
    Tour::of(m, best.1)
}

/// Exact by Held–Karp dynamic programming over subsets, O(2^n n²) time and 2^(n−1) (n−1) × 9 bytes
/// of memory (≈ 90 MB at n = 20). Callers keep n ≤ 20 (the config validates it); a larger n is a
/// programmer error and panics. Ties go to the lower node index at each step of the reconstruction.
pub fn held_karp(m: &CostMatrix, start: usize) -> Tour {
    if let Some(t) = trivial(m, start) {
        return t;
    }
    let n = m.n();
    assert!(n <= 20, "held_karp is limited to 20 nodes, got {n}");
    let w = m.finite();
    let others: Vec<usize> = (0..n).filter(|&i| i != start).collect();
    let k = others.len();
    let full = (1usize << k) - 1;
    // dp[mask * k + j]: least cost of a path from start through exactly `mask`, ending at others[j].
    let mut dp = vec![f64::INFINITY; (1 << k) * k];
    let mut parent = vec![u8::MAX; (1 << k) * k];
    for j in 0..k {
        dp[(1 << j) * k + j] = w.get(start, others[j]);
    }
    for mask in 1..=full {
        for j in 0..k {
            if mask & (1 << j) == 0 {
                continue;
            }
            let prev = mask ^ (1 << j);
            if prev == 0 {
                continue;
            }
            let (mut best, mut arg) = (f64::INFINITY, u8::MAX);
            for i in 0..k {
                if prev & (1 << i) != 0 {
                    let c = dp[prev * k + i] + w.get(others[i], others[j]);
                    if c < best {
                        (best, arg) = (c, i as u8);
                    }
                }
            }
            dp[mask * k + j] = best;
            parent[mask * k + j] = arg;
        }
    }
    let mut last = 0;
    for j in 1..k {
        if dp[full * k + j] < dp[full * k + last] {
            last = j;
        }
    }
    let mut rev = Vec::with_capacity(n);
    let mut mask = full;
    let mut j = last;
    loop {
        rev.push(others[j]);
        let p = parent[mask * k + j];
        mask ^= 1 << j;
        if mask == 0 {
            break;
        }
        j = p as usize;
    }
    rev.push(start);
    rev.reverse();
    Tour::of(m, rev)
}

/// Segment-swap kicks of the iterated local search in [`heuristic`]; the search is deterministic
/// (its RNG has a fixed seed), so the same matrix always gives the same tour.
const ILS_KICKS: usize = 40;

/// Nearest neighbour from the start (ties to the lower index), then 2-opt and Or-opt to a local
/// optimum, then [`ILS_KICKS`] rounds of: swap two random consecutive segments (a move neither
/// 2-opt nor Or-opt undoes), descend again, keep the result if it is better.
pub fn heuristic(m: &CostMatrix, start: usize) -> Tour {
    if let Some(t) = trivial(m, start) {
        return t;
    }
    let w = m.finite();
    let n = w.n();
    let mut order = Vec::with_capacity(n);
    let mut used = vec![false; n];
    order.push(start);
    used[start] = true;
    for _ in 1..n {
        let last = *order.last().expect("start is in order");
        let next = (0..n)
            .filter(|&j| !used[j])
            .min_by(|&a, &b| w.get(last, a).total_cmp(&w.get(last, b)).then(a.cmp(&b)))
            .expect("an unvisited node is left");
        used[next] = true;
        order.push(next);
    }
    let mut ls = LocalSearch::new(&w);
    ls.descend(&mut order);
    let mut best_cost = open_path_cost(&w, &order);
    if n >= 4 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x75_7370);
        let mut trial = order.clone();
        for _ in 0..ILS_KICKS {
            trial.clone_from(&order);
            // Cut points 1 ≤ a < b < c ≤ n: [0, a) + [b, c) + [a, b) + [c, n).
            let a = rng.random_range(1..n - 1);
            let b = rng.random_range(a + 1..n);
            let c = rng.random_range(b + 1..=n);
            trial[a..c].rotate_left(b - a);
            ls.descend(&mut trial);
            let cost = open_path_cost(&w, &trial);
            if cost < best_cost - ls.eps {
                best_cost = cost;
                order.clone_from(&trial);
            }
        }
    }
    Tour::of(m, order)
}

/// 2-opt and Or-opt moves on an open path with a fixed first node, first improvement, for
/// asymmetric costs: a reversed segment is re-costed in O(1) from prefix sums of its forward and
/// backward edge costs.
struct LocalSearch<'a> {
    w: &'a CostMatrix,
    /// Least improvement accepted: rounding in the prefix sums cannot make a move look better by
    /// this much, so every accepted move strictly lowers the cost and the descent terminates.
    eps: f64,
    fwd: Vec<f64>,
    bwd: Vec<f64>,
}

impl<'a> LocalSearch<'a> {
    fn new(w: &'a CostMatrix) -> Self {
        let max_abs = w.c.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        LocalSearch {
            w,
            eps: 1e-12 * (w.n() as f64) * (max_abs + 1.0),
            fwd: Vec::new(),
            bwd: Vec::new(),
        }
    }

    fn descend(&mut self, order: &mut [usize]) {
        while self.two_opt(order) || self.or_opt(order) {}
    }

    fn prefix(&mut self, o: &[usize]) {
        let w = self.w;
        self.fwd.clear();
        self.bwd.clear();
        let (mut f, mut b) = (0.0, 0.0);
        self.fwd.push(0.0);
        self.bwd.push(0.0);
        for e in o.windows(2) {
            f += w.get(e[0], e[1]);
            b += w.get(e[1], e[0]);
            self.fwd.push(f);
            self.bwd.push(b);
        }
    }

    /// Reverses `o[i..=j]` (1 ≤ i < j) at the first improving (i, j); whether one was found.
    fn two_opt(&mut self, o: &mut [usize]) -> bool {
        let n = o.len();
        self.prefix(o);
        let w = self.w;
        for i in 1..n - 1 {
            let before = o[i - 1];
            for j in i + 1..n {
                let mut delta = w.get(before, o[j]) - w.get(before, o[i])
                    + (self.bwd[j] - self.bwd[i])
                    - (self.fwd[j] - self.fwd[i]);
                if j + 1 < n {
                    delta += w.get(o[i], o[j + 1]) - w.get(o[j], o[j + 1]);
                }
                if delta < -self.eps {
                    o[i..=j].reverse();
                    return true;
                }
            }
        }
        false
    }

    /// Moves a segment of 1–3 nodes (optionally reversed) elsewhere, at the first improving move.
    fn or_opt(&mut self, o: &mut [usize]) -> bool {
        let n = o.len();
        let w = self.w;
        for len in 1..=3usize.min(n - 1) {
            for i in 1..=n - len {
                let j = i + len - 1;
                let (first, last) = (o[i], o[j]);
                let prev = o[i - 1];
                let next = (j + 1 < n).then(|| o[j + 1]);
                let removed = match next {
                    Some(nx) => w.get(prev, nx) - w.get(prev, first) - w.get(last, nx),
                    None => -w.get(prev, first),
                };
                let inner_fwd: f64 = (i..j).map(|t| w.get(o[t], o[t + 1])).sum();
                let inner_bwd: f64 = (i..j).map(|t| w.get(o[t + 1], o[t])).sum();
                // Insert between o[p] and o[p + 1] (or after the last node), outside the segment.
                for p in 0..n {
                    if p + 1 >= i && p <= j {
                        continue;
                    }
                    let a = o[p];
                    let b = (p + 1 < n).then(|| o[p + 1]);
                    for reversed in [false, true] {
                        if reversed && len == 1 {
                            continue;
                        }
                        let (s, e, inner) = if reversed {
                            (last, first, inner_bwd - inner_fwd)
                        } else {
                            (first, last, 0.0)
                        };
                        let mut delta = removed + inner + w.get(a, s);
                        if let Some(b) = b {
                            delta += w.get(e, b) - w.get(a, b);
                        }
                        if delta < -self.eps {
                            move_segment(o, i, j, p, reversed);
                            return true;
                        }
                    }
                }
            }
        }
        false
    }
}

/// Moves `o[i..=j]` to just after the node now at position `p` (outside the segment).
fn move_segment(o: &mut [usize], i: usize, j: usize, p: usize, reversed: bool) {
    if reversed {
        o[i..=j].reverse();
    }
    if p > j {
        // [i..=j][j+1..=p] → [j+1..=p][i..=j]
        o[i..=p].rotate_left(j - i + 1);
    } else {
        // p < i − 1: [p+1..i][i..=j] → [i..=j][p+1..i]
        o[p + 1..=j].rotate_right(j - i + 1);
    }
}

/// Exact (Held–Karp) up to `exact_max_nodes` nodes, [`heuristic`] above.
pub fn solve(m: &CostMatrix, start: usize, exact_max_nodes: usize) -> Tour {
    if m.n() <= exact_max_nodes.min(20) {
        held_karp(m, start)
    } else {
        heuristic(m, start)
    }
}

/// Parameters of [`genetic`].
#[derive(Clone, Debug, PartialEq)]
pub struct GaParams {
    /// Routes per generation (rounded down to a multiple of `group_size`, at least one group).
    pub population: usize,
    /// Routes per sub-group: its best survives and breeds `group_size − 1` mutants.
    pub group_size: usize,
    /// Generations at most.
    pub generations: usize,
    /// Stop after this many generations without a lower best cost.
    pub stall_generations: usize,
}

/// NBV-TSP Alg. 5 (Meng et al., RA-L 2017, §IV-A.4), in the style of its reference [19]: a population of random
/// routes (start fixed), shuffled each generation into sub-groups; each sub-group's best route
/// survives and its other slots are refilled by mutants of it, without crossover. The paper names
/// swapping and sliding; the flip (reversal of a piece) of the same family of GA-for-TSP codes is
/// used as well, in turn with them. Elitist: the best-so-far route is always in the population.
pub fn genetic(m: &CostMatrix, start: usize, p: &GaParams, rng: &mut impl Rng) -> Tour {
    if let Some(t) = trivial(m, start) {
        return t;
    }
    let w = m.finite();
    let n = w.n();
    let g = p.group_size.max(1);
    let groups = (p.population / g).max(1);
    let pop_size = groups * g;
    let rest: Vec<usize> = (0..n).filter(|&i| i != start).collect();
    let mut pop: Vec<Vec<usize>> = (0..pop_size)
        .map(|_| {
            let mut r = rest.clone();
            r.shuffle(rng);
            r.insert(0, start);
            r
        })
        .collect();
    let mut costs: Vec<f64> = pop.iter().map(|r| open_path_cost(&w, r)).collect();
    let best_of = |costs: &[f64]| {
        (0..costs.len())
            .min_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)))
            .expect("population is not empty")
    };
    let b = best_of(&costs);
    let (mut best, mut best_cost) = (pop[b].clone(), costs[b]);
    let mut stall = 0;
    let mut idx: Vec<usize> = (0..pop_size).collect();
    let mut next: Vec<Vec<usize>> = pop.clone();
    for _ in 0..p.generations {
        idx.shuffle(rng);
        for (gi, group) in idx.chunks(g).enumerate() {
            let champion = *group
                .iter()
                .min_by(|&&a, &&b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)))
                .expect("groups are not empty");
            let parent = &pop[champion];
            for k in 0..g {
                let child = &mut next[gi * g + k];
                child.clone_from(parent);
                if k == 0 {
                    continue;
                }
                // Mutate positions 1..n: two random cut points i < j.
                let i = rng.random_range(1..n - 1);
                let j = rng.random_range(i + 1..n);
                match (k - 1) % 3 {
                    0 => child[i..=j].reverse(),
                    1 => child.swap(i, j),
                    _ => child[i..=j].rotate_left(1),
                }
            }
        }
        std::mem::swap(&mut pop, &mut next);
        for (c, r) in costs.iter_mut().zip(&pop) {
            *c = open_path_cost(&w, r);
        }
        let b = best_of(&costs);
        if costs[b] < best_cost {
            best_cost = costs[b];
            best.clone_from(&pop[b]);
            stall = 0;
        } else {
            stall += 1;
            if stall >= p.stall_generations {
                break;
            }
        }
    }
    Tour::of(m, best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::ChaCha8Rng;

    fn euclidean(n: usize, rng: &mut ChaCha8Rng) -> CostMatrix {
        let pts: Vec<(f64, f64)> = (0..n)
            .map(|_| (rng.random::<f64>(), rng.random::<f64>()))
            .collect();
        CostMatrix::from_fn(n, |i, j| {
            ((pts[i].0 - pts[j].0).powi(2) + (pts[i].1 - pts[j].1).powi(2)).sqrt()
        })
    }

    /// Instance number `inst` of a mixed series: Euclidean for even `inst`, asymmetric for odd.
    fn mixed(n: usize, inst: usize, rng: &mut ChaCha8Rng) -> CostMatrix {
        if inst.is_multiple_of(2) {
            euclidean(n, rng)
        } else {
            asymmetric(n, rng)
        }
    }

    fn asymmetric(n: usize, rng: &mut ChaCha8Rng) -> CostMatrix {
        CostMatrix::from_fn(n, |i, j| {
            if i == j {
                0.0
            } else {
                rng.random_range(1.0..10.0)
            }
        })
    }

    fn assert_valid(t: &Tour, m: &CostMatrix, start: usize) {
        let n = m.n();
        assert_eq!(t.order.len(), n);
        if n > 0 {
            assert_eq!(t.order[0], start);
        }
        let mut seen = vec![false; n];
        for &v in &t.order {
            assert!(!seen[v], "node {v} twice in {:?}", t.order);
            seen[v] = true;
        }
        let c = open_path_cost(m, &t.order);
        assert!(
            c == t.cost || (c - t.cost).abs() <= 1e-9,
            "{c} vs {}",
            t.cost
        );
    }

    fn same_cost(a: f64, b: f64) -> bool {
        a == b || (a - b).abs() <= 1e-9
    }

    fn ga_params() -> GaParams {
        GaParams {
            population: 60,
            group_size: 4,
            generations: 2000,
            stall_generations: 300,
        }
    }

    #[test]
    fn matrix_accessors() {
        let mut m = CostMatrix::new(3);
        assert_eq!(m.n(), 3);
        assert_eq!(m.get(2, 1), 0.0);
        m.set(2, 1, 4.5);
        assert_eq!(m.get(2, 1), 4.5);
        assert_eq!(m.get(1, 2), 0.0);
        let f = CostMatrix::from_fn(2, |i, j| (10 * i + j) as f64);
        assert_eq!((f.get(0, 1), f.get(1, 0), f.get(1, 1)), (1.0, 10.0, 11.0));
        assert_eq!(open_path_cost(&f, &[1, 0]), 10.0);
        assert_eq!(open_path_cost(&f, &[1]), 0.0);
    }

    #[test]
    fn trivial_sizes() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for n in 0..=2 {
            let m = asymmetric(n, &mut rng);
            for start in 0..n.max(1) {
                for t in [
                    brute_force(&m, start),
                    held_karp(&m, start),
                    heuristic(&m, start),
                    solve(&m, start, 12),
                    genetic(&m, start, &ga_params(), &mut rng),
                ] {
                    assert_valid(&t, &m, start);
                }
            }
        }
        let m = CostMatrix::from_fn(2, |i, j| if i == j { 0.0 } else { 3.0 + i as f64 });
        assert_eq!(
            held_karp(&m, 1),
            Tour {
                order: vec![1, 0],
                cost: 4.0
            }
        );
    }

    /// A known answer: points on a line, starting at one end, are visited in order.
    #[test]
    fn points_on_a_line() {
        let xs: [f64; 6] = [0.0, 5.0, 1.0, 4.0, 2.0, 3.0];
        let m = CostMatrix::from_fn(6, |i, j| (xs[i] - xs[j]).abs());
        let want = vec![0, 2, 4, 5, 3, 1];
        assert_eq!(held_karp(&m, 0).order, want);
        assert_eq!(brute_force(&m, 0).order, want);
        assert_eq!(heuristic(&m, 0).order, want);
        assert_eq!(held_karp(&m, 0).cost, 5.0);
        // From the middle (x = 2) the best open path goes to the nearer end first: 2 → 0 → 5 = 7.
        assert_eq!(held_karp(&m, 4).cost, 7.0);
    }

    #[test]
    fn held_karp_equals_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for n in 1..=9 {
            for inst in 0..30 {
                let m = mixed(n, inst, &mut rng);
                let start = inst % n;
                let bf = brute_force(&m, start);
                let hk = held_karp(&m, start);
                assert_valid(&bf, &m, start);
                assert_valid(&hk, &m, start);
                assert!(
                    (bf.cost - hk.cost).abs() <= 1e-9,
                    "n={n}: {} vs {}",
                    bf.cost,
                    hk.cost
                );
            }
        }
    }

    #[test]
    fn heuristic_and_genetic_are_valid_and_not_below_exact() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for n in 1..=9 {
            for inst in 0..30 {
                let m = mixed(n, inst, &mut rng);
                let start = (3 * inst) % n;
                let exact = held_karp(&m, start).cost;
                let h = heuristic(&m, start);
                assert_valid(&h, &m, start);
                assert!(h.cost >= exact - 1e-9);
                let g = genetic(&m, start, &ga_params(), &mut rng);
                assert_valid(&g, &m, start);
                assert!(g.cost >= exact - 1e-9);
                // Small instances: mutation-only search can stall in a local optimum (worst seen
                // 5.6 %, asymmetric n = 8), but not far from the optimum.
                assert!(
                    g.cost <= exact * 1.10 + 1e-9,
                    "n={n}: GA {} vs {exact}",
                    g.cost
                );
                assert_eq!(solve(&m, start, 12).cost, held_karp(&m, start).cost);
            }
        }
    }

    #[test]
    fn infinite_entries_are_avoided_and_reported() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for n in 3..=8 {
            for inst in 0..20 {
                let mut m = asymmetric(n, &mut rng);
                // Cut a fifth of the edges; the rest may or may not still admit a finite path.
                for i in 0..n {
                    for j in 0..n {
                        if i != j && rng.random_range(0..5) == 0 {
                            m.set(i, j, f64::INFINITY);
                        }
                    }
                }
                let start = inst % n;
                let bf = brute_force(&m, start);
                let hk = held_karp(&m, start);
                let h = heuristic(&m, start);
                let g = genetic(&m, start, &ga_params(), &mut rng);
                for t in [&bf, &hk, &h, &g] {
                    assert_valid(t, &m, start);
                    assert!(!t.cost.is_nan());
                }
                assert!(same_cost(bf.cost, hk.cost), "{} vs {}", bf.cost, hk.cost);
                if hk.cost.is_finite() {
                    assert!(h.cost >= hk.cost - 1e-9);
                }
            }
        }
        // A start with every outgoing edge infinite: the cost is infinite, never NaN.
        let mut m = CostMatrix::from_fn(4, |i, j| (i + j) as f64);
        for j in 0..4 {
            m.set(0, j, f64::INFINITY);
        }
        m.set(1, 2, f64::NAN);
        for t in [brute_force(&m, 0), held_karp(&m, 0), heuristic(&m, 0)] {
            assert_valid(&t, &m, 0);
            assert_eq!(t.cost, f64::INFINITY);
        }
    }

    #[test]
    fn deterministic() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let m = euclidean(25, &mut rng);
        assert_eq!(heuristic(&m, 3), heuristic(&m, 3));
        let run = || genetic(&m, 3, &ga_params(), &mut ChaCha8Rng::seed_from_u64(9));
        assert_eq!(run(), run());
        // Ties: every order costs the same, the first (lowest-index) one wins.
        let flat = CostMatrix::from_fn(6, |i, j| if i == j { 0.0 } else { 1.0 });
        assert_eq!(held_karp(&flat, 2), held_karp(&flat, 2));
        assert_eq!(brute_force(&flat, 2).order, vec![2, 0, 1, 3, 4, 5]);
        assert_eq!(heuristic(&flat, 2).order, vec![2, 0, 1, 3, 4, 5]);
    }

    /// Gap statistics `(mean, worst)` in per cent of `solver` against Held–Karp on `count` random
    /// Euclidean instances of n = 10..=12 nodes.
    fn gap_vs_exact(
        count: usize,
        mut solver: impl FnMut(&CostMatrix, usize) -> Tour,
    ) -> (f64, f64) {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let (mut sum, mut worst) = (0.0, 0.0f64);
        for inst in 0..count {
            let n = 10 + inst % 3;
            let m = euclidean(n, &mut rng);
            let start = inst % n;
            let exact = held_karp(&m, start).cost;
            let t = solver(&m, start);
            assert_valid(&t, &m, start);
            let gap = 100.0 * (t.cost - exact) / exact;
            assert!(gap >= -1e-9);
            sum += gap;
            worst = worst.max(gap);
        }
        (sum / count as f64, worst)
    }

    /// The measured figures are in the module doc. Bounds: a 2-opt + Or-opt local optimum is
    /// typically within a few per cent of optimal on small Euclidean instances and the kicks only
    /// improve on it; worst ≤ 10 % and mean ≤ 1 % leave room above what was measured (0 %, 0 %).
    #[test]
    fn heuristic_gap_vs_exact_n10_to_12() {
        let (mean, worst) = gap_vs_exact(300, heuristic);
        eprintln!(
            "heuristic vs exact, n=10..12, 300 instances: mean {mean:.3} %, worst {worst:.2} %"
        );
        assert!(
            mean <= 1.0 && worst <= 10.0,
            "mean {mean} %, worst {worst} %"
        );
        // The local search alone, for the record (the kicks' contribution).
        let (mean, worst) = gap_vs_exact(300, |m, s| {
            let w = m.finite();
            let mut o: Vec<usize> = std::iter::once(s)
                .chain((0..m.n()).filter(|&i| i != s))
                .collect();
            LocalSearch::new(&w).descend(&mut o);
            Tour::of(m, o)
        });
        eprintln!("2-opt + Or-opt from the index order: mean {mean:.3} %, worst {worst:.2} %");
        assert!(mean <= 5.0 && worst <= 40.0);
    }

    /// Bounds: mean ≤ 1 %, worst ≤ 15 %, above the measured figures in the module doc (a GA without
    /// crossover occasionally stalls in a 2-opt-like local optimum).
    #[test]
    fn genetic_gap_vs_exact() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (mean, worst) = gap_vs_exact(300, |m, s| genetic(m, s, &ga_params(), &mut rng));
        eprintln!(
            "genetic vs exact, n=10..12, 300 instances: mean {mean:.3} %, worst {worst:.2} %"
        );
        assert!(
            mean <= 1.0 && worst <= 15.0,
            "mean {mean} %, worst {worst} %"
        );
    }
}
