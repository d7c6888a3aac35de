//! The frontier rules GREEDY and THP share (and NBV-TSP's looks at frontiers before `Complete`):
//! how a frontier is visited, looked at and given up ([`visits`]), where to look at it from
//! ([`viewpoints`]), the end-of-run sequence ([`ending`]) and the volume views ([`volume_views`]).
//! Most of them are not in any paper: each is a key of `[additions]`, and the `published` profile
//! switches them off, leaving the papers' rule (a frontier looked at once is done).
//!
//!
//! A forward camera cannot see the floor right in front of it, so a frontier is approached in two
//! tries: first the robot stops `view_m` short of it (along the path) and turns once in place to
//! look into the unknown; if the frontier survives, the next approach goes all the way. A frontier
//! cell that is still a frontier after a look from a distance and then a look from on top of it, or
//! after a look from a viewpoint chosen to see it, or that the robot failed to reach twice, is
//! marked unobservable and skipped from then on (THP §3.4: "done after the robot has looked at
//! it"). A look counts only for the cells beyond the blind zone (`search.near_unknown_radius_m`)
//! around the robot. A second approach that the motion guard stops short within the blind zone
//! (beside never-seen floor it cannot get any nearer) counts as the look from on top, not as a
//! failed attempt. With that and the wider sighted viewpoint
//! ([`FrontierVisits::sighted_viewpoint`]), runs on 33 real plans × 3 starts that ended `complete`
//! with an observable frontier left went from 20 to 14 (GREEDY) and from 24 to 11 (THP). A look from a chosen viewpoint is driven to
//! exactly (`exact_arrival`, [`super::Action::Follow`]): 0.2 m off it the aimed voxel was often out
//! of view. A viewpoint is first sought where the camera surely sees the aimed voxel (its centre,
//! through no occupied voxel), then where it may see it (a point of the voxel, past the ray hits of
//! the occupied voxels on the way: [`Sight`]); a look gives a cell up at once only if the camera
//! surely saw it. Before calling the map done, a planner reopens each given-up frontier cell it can
//! reach whose unknown floor the camera would see from a reachable cell of the final map
//! ([`FrontierVisits::reopen_seeable`]: if the camera may see it, at most `additions.reopen_max` times): a
//! look from a chosen viewpoint, away from the earlier ones where another sees it, then decides it.

mod ending;
mod state;
mod viewpoints;
mod visits;
mod volume_views;

pub use ending::{distant_view, end_of_run, follow_to, Ending};
pub use viewpoints::{blind_zone_viewpoint, line_of_sight};
pub use visits::{blind_zone_first, FrontierVisits, Visit, VisitRules};
pub use volume_views::{VolumeView, VolumeViewParams, VolumeViews};
