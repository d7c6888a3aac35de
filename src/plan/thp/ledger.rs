//! Where the metres go: each goal's reason and the path driven for it (`path_m_*` statistics).

use super::*;

/// Why the robot is driving where it is: each goal's reason, and the metres driven for it. Written
/// to the statistics as `path_m_*`, so that a comparison with GREEDY can say where THP's extra
/// metres go (same group, next group in the tour, leaving a group with frontiers left for another,
/// coming back to such a group, or a goal outside the tour: a blind-zone look, a distant view, a
/// volume view or an escape).
#[derive(Clone, Debug, Default)]
pub(super) struct PathLedger {
    /// Node key (anchor) of the last tour goal (kept across goals outside the tour).
    pub(super) last_node: Option<usize>,
    /// Anchors the robot left while their group still had frontiers.
    pub(super) left_unfinished: BTreeSet<usize>,
    pub(super) kind: GoalKind,
    pub(super) odometer: plan::Odometer,
}

/// A look from a viewpoint chosen for a tour goal's frontier (`sighted_viewpoint`) counts under the
/// kind of the tour goal before it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum GoalKind {
    /// No goal yet (the first look).
    #[default]
    OutsideTour,
    SameGroup,
    NextGroup,
    /// A new group chosen while the previous one still had frontiers.
    LeftUnfinished,
    /// Back to a group left unfinished earlier.
    Return,
    /// A step back to see a frontier in the camera's blind zone.
    BlindZone,
    /// A look through a gap too narrow to pass.
    DistantView,
    /// A view of unknown volume no frontier shows, before `Complete`.
    VolumeView,
    /// An escape from a pocket, or the way out of a spot with no enterable cell around.
    Escape,
}

impl GoalKind {
    pub(super) const ALL: [GoalKind; 9] = [
        GoalKind::OutsideTour,
        GoalKind::SameGroup,
        GoalKind::NextGroup,
        GoalKind::LeftUnfinished,
        GoalKind::Return,
        GoalKind::BlindZone,
        GoalKind::DistantView,
        GoalKind::VolumeView,
        GoalKind::Escape,
    ];

    pub(super) fn key(self) -> &'static str {
        match self {
            GoalKind::OutsideTour => "path_m_outside_tour",
            GoalKind::SameGroup => "path_m_same_group",
            GoalKind::NextGroup => "path_m_next_group",
            GoalKind::LeftUnfinished => "path_m_left_unfinished",
            GoalKind::Return => "path_m_return",
            GoalKind::BlindZone => "path_m_blind_zone",
            GoalKind::DistantView => "path_m_distant_view",
            GoalKind::VolumeView => "path_m_volume_view",
            GoalKind::Escape => "path_m_escape",
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
        let d = self.ledger.odometer.advance(p);
        if d > 0.0 {
            self.stats.path_m[self.ledger.kind as usize].add(d);
        }
    }
}
