//! Where the metres go: each goal's reason and the path driven for it (`path_m_*` statistics).

use super::*;

/// Why the robot is driving where it is: each goal's reason, and the metres driven for it. Written
/// to the statistics as `path_m_*`, so that a comparison with GREEDY can say where THP's extra
/// metres go (same group, next group in the tour, leaving a group with frontiers left for another,
/// coming back to such a group, or a goal outside the tour).
#[derive(Clone, Debug, Default)]
pub(super) struct PathLedger {
    /// Node key (anchor) of the last tour goal (kept across goals outside the tour).
    pub(super) last_node: Option<usize>,
    /// Anchors the robot left while their group still had frontiers.
    pub(super) left_unfinished: BTreeSet<usize>,
    pub(super) kind: GoalKind,
    pub(super) last_pos: Option<Point2<f64>>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum GoalKind {
    /// Blind-zone views, views through gaps, escapes and the initial look: no tour node.
    #[default]
    OutsideTour,
    SameGroup,
    NextGroup,
    /// A new group chosen while the previous one still had frontiers.
    LeftUnfinished,
    /// Back to a group left unfinished earlier.
    Return,
}

impl GoalKind {
    pub(super) const ALL: [GoalKind; 5] = [
        GoalKind::OutsideTour,
        GoalKind::SameGroup,
        GoalKind::NextGroup,
        GoalKind::LeftUnfinished,
        GoalKind::Return,
    ];

    pub(super) fn key(self) -> &'static str {
        match self {
            GoalKind::OutsideTour => "path_m_outside_tour",
            GoalKind::SameGroup => "path_m_same_group",
            GoalKind::NextGroup => "path_m_next_group",
            GoalKind::LeftUnfinished => "path_m_left_unfinished",
            GoalKind::Return => "path_m_return",
        }
    }
}

impl Thp {
    /// Classifies a new tour goal at node `node`; `open` says whether a node key still has
    /// frontiers.
    pub(super) fn note_tour_goal(&mut self, node: usize, open: impl Fn(usize) -> bool) {
        let l = &mut self.ledger;
        let kind = match l.last_node {
            Some(p) if p == node => GoalKind::SameGroup,
            Some(p) if open(p) => {
                l.left_unfinished.insert(p);
                if l.left_unfinished.contains(&node) {
                    GoalKind::Return
                } else {
                    GoalKind::LeftUnfinished
                }
            }
            _ if l.left_unfinished.contains(&node) => GoalKind::Return,
            _ => GoalKind::NextGroup,
        };
        l.last_node = Some(node);
        l.kind = kind;
        match kind {
            GoalKind::LeftUnfinished => self.stats.groups_left_unfinished.add(1.0),
            GoalKind::Return => self.stats.returns_to_unfinished.add(1.0),
            _ => {}
        }
    }

    /// Adds the distance moved since the last call to the current goal's kind.
    pub(super) fn note_position(&mut self, p: Point2<f64>) {
        if let Some(q) = self.ledger.last_pos.replace(p) {
            let d = (p - q).norm();
            if d > 0.0 {
                self.stats.path_m[self.ledger.kind as usize].add(d);
            }
        }
    }
}
