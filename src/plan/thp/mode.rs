//! THP's control state between plans, and every change of it.
//!
//! ```text
//!            drive(goal)                      action_ended: the goal's last segment ended,
//!   Idle ───────────────▶ Driving { goal } ───────────────▶ Idle   or the attempt failed
//!     ▲                      │   ▲   │                   ╲ the failed attempt did not move the
//!     │                      │   │   │                    ╲ robot at all
//!     │                      │   │   │                     ▶ Blocked ──unblock (look around)──▶ Idle
//!     └──────── stop ────────┘   │   └─ interrupt: the action in flight ends early for a reason that
//!                                │      is not a failed attempt (the goal was seen on the way, new
//!                                │      anchors, a newly seen obstacle on the path)
//!                                └───── action_ended after an advected segment or an interruption:
//!                                       the goal stays
//! ```
//!
//! A new plan may replace the goal (`drive` again) or keep it; which one is the planner's choice
//! (`Thp::next_action`), not the state's.

use super::*;

/// What THP is doing between two plans.
#[derive(Clone, Debug, Default)]
pub(super) enum Mode {
    /// No goal: the next plan chooses one.
    #[default]
    Idle,
    /// Driving to `goal`, in one or more actions. `interrupted`: the action in flight is ending early
    /// for a reason that is not a failed attempt.
    Driving { goal: Goal, interrupted: bool },
    /// The last attempt ended without moving the robot at all (the motion guard refused every move):
    /// the next plan turns in place to look before choosing again. Turning is always allowed, and the
    /// never-seen cells beside the robot that the guard keeps it away from get seen.
    Blocked,
}

impl Mode {
    /// The goal being driven to.
    pub(super) fn goal(&self) -> Option<&Goal> {
        match self {
            Mode::Idle | Mode::Blocked => None,
            Mode::Driving { goal, .. } => Some(goal),
        }
    }

    pub(super) fn goal_mut(&mut self) -> Option<&mut Goal> {
        match self {
            Mode::Idle | Mode::Blocked => None,
            Mode::Driving { goal, .. } => Some(goal),
        }
    }

    /// Drive to `goal` from now on.
    pub(super) fn drive(&mut self, goal: Goal) {
        *self = Mode::Driving {
            goal,
            interrupted: false,
        };
    }

    /// Drop the goal, returning it.
    pub(super) fn stop(&mut self) -> Option<Goal> {
        match std::mem::take(self) {
            Mode::Idle | Mode::Blocked => None,
            Mode::Driving { goal, .. } => Some(goal),
        }
    }

    /// The action in flight ends early, and not as a failed attempt.
    pub(super) fn interrupt(&mut self) {
        if let Mode::Driving { interrupted, .. } = self {
            *interrupted = true;
        }
    }

    /// Leaves [`Mode::Blocked`]; true if the mode was it.
    pub(super) fn unblock(&mut self) -> bool {
        let blocked = matches!(self, Mode::Blocked);
        if blocked {
            *self = Mode::Idle;
        }
        blocked
    }

    /// The action in flight ended, having `reached` its end or not, and having `moved` the robot or
    /// not; `still_open` tells whether the goal's frontier is still a frontier. Returns the goal's
    /// visit and how it ended when the attempt is over (the planner records it), `None` while the
    /// goal stays.
    pub(super) fn action_ended(
        &mut self,
        reached: bool,
        moved: bool,
        still_open: impl Fn(&Visit) -> bool,
    ) -> Option<(Visit, bool)> {
        match self {
            // An action without a goal (an escape, a volume view) that could not move the robot
            // calls for the same look as a goal's attempt.
            Mode::Idle if !reached && !moved => {
                *self = Mode::Blocked;
                None
            }
            Mode::Idle | Mode::Blocked => None,
            Mode::Driving { goal, interrupted } if *interrupted => {
                *interrupted = false;
                goal.final_segment = !still_open(&goal.visit);
                None
            }
            // An advected segment ended; the goal stays.
            Mode::Driving { goal, .. } if reached && !goal.final_segment => None,
            Mode::Driving { .. } => {
                let goal = self.stop();
                if !reached && !moved {
                    *self = Mode::Blocked;
                }
                goal.map(|goal| (goal.visit, reached))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn goal(final_segment: bool) -> Goal {
        Goal {
            visit: Visit {
                aim: 7,
                ..Visit::default()
            },
            tour_node: Some(3),
            path: Vec::new(),
            path_cells: Vec::new(),
            look_on_arrival: true,
            final_segment,
            stale: false,
            best_progress: 0,
            progress_s: 0.0,
            direct: false,
        }
    }

    #[test]
    fn transitions_follow_the_diagram() {
        // An advected segment that ends short of the goal keeps the goal.
        let mut m = Mode::default();
        m.drive(goal(false));
        assert_eq!(m.action_ended(true, true, |_| true), None);
        assert!(m.goal().is_some());
        // An interruption keeps the goal too; its last segment is over once the frontier is seen.
        m.interrupt();
        assert_eq!(m.action_ended(false, false, |_| false), None);
        assert!(m.goal().is_some_and(|g| g.final_segment));
        // The last segment reached: the attempt is over and reported.
        let ended = m.action_ended(true, true, |_| true);
        assert_eq!(ended.map(|(v, r)| (v.aim, r)), Some((7, true)));
        assert!(matches!(m, Mode::Idle));
        // A failed attempt that moved the robot: over, reported, idle.
        m.drive(goal(true));
        assert_eq!(
            m.action_ended(false, true, |_| true).map(|e| e.1),
            Some(false)
        );
        assert!(matches!(m, Mode::Idle) && !m.unblock());
        // A failed attempt that did not move it: blocked until the look.
        m.drive(goal(true));
        assert_eq!(
            m.action_ended(false, false, |_| true).map(|e| e.1),
            Some(false)
        );
        assert!(matches!(m, Mode::Blocked) && m.goal().is_none());
        assert!(m.unblock());
        assert!(matches!(m, Mode::Idle));
        // An action without a goal (an escape, a volume view) that could not move: blocked too;
        // one that moved, or ended, changes nothing.
        assert_eq!(m.action_ended(false, true, |_| true), None);
        assert!(matches!(m, Mode::Idle));
        assert_eq!(m.action_ended(true, false, |_| true), None);
        assert!(matches!(m, Mode::Idle));
        assert_eq!(m.action_ended(false, false, |_| true), None);
        assert!(matches!(m, Mode::Blocked) && m.unblock());
    }
}
