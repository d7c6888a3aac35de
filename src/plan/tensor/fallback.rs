//! What TENSOR does when its method has nothing to follow: the paper's termination rule, or with
//! `tensor.fallback` a GREEDY leg.

use super::*;

impl Tensor {
    /// The method has nothing to follow (no edge with gain, or nothing new for long). With
    /// `tensor.fallback`: GREEDY's nearest frontier, `Complete` when none is left. Without (the
    /// default, the paper's rule): `Complete` when no reachable, observable frontier is left, else
    /// `Stuck`.
    pub(super) fn fallback(&mut self, ctx: &mut PlanContext) -> Result<Action> {
        if !self.cfg.fallback {
            self.route_target = None;
            self.advecting = false;
            self.current = Current::None;
            // GREEDY's choice decides whether a frontier it would pursue is left; its action is not
            // taken.
            if self.greedy.next_action(ctx)? == Action::Complete {
                return Ok(Action::Complete);
            }
            self.stats.stuck_no_route += 1;
            return Ok(Action::Stuck);
        }
        self.stats.fallback_plans += 1;
        self.route_target = None;
        self.advecting = false;
        let a = self.greedy.next_action(ctx)?;
        self.current = if a == Action::Complete {
            Current::None
        } else {
            Current::Fallback
        };
        Ok(a)
    }
}
