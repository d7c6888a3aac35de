//! The state of one frontier cell in its visits, and every change of it (in [`CellState::next`]).
//!
//! ```text
//!                    SeenFromAfar                   LookFromOnTop
//!   Unvisited ─────────────────────▶ LookedFromAfar ──────────────▶ NeedsViewpoint
//!      │  MissedInBlindZone                ▲  ViewpointLook (kept)        │  LookFromOnTop,
//!      ▼                                   │                              │  ViewpointLook (given up)
//!   Blinded ───────────────────────────────┘                              ▼
//!      │         ViewpointLook (given up), NoViewpoint, GiveUp         GivenUp ──Reopen──▶ NeedsViewpoint
//!      └──────────────────────────────────────────────────────────────▶
//! ```
//!
//! A cell can lie in several frontier segments over a run, and every look at a segment updates all
//! its cells, so a cell can be seen from afar after it lay in the blind zone of an earlier look, or
//! be looked at again while given up: the states carry what those looks were (`approached`,
//! `topped`, `blinded`), and each reader asks for what it needs ([`CellState::needs_viewpoint`],
//! [`CellState::was_approached`], [`CellState::is_given_up`]).

/// Where a frontier cell stands in its visits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum CellState {
    /// Never looked at.
    #[default]
    Unvisited,
    /// Lay in the camera's blind zone during a first look, which therefore showed nothing of it: a
    /// look from a viewpoint chosen to see it is next.
    Blinded,
    /// Looked at from afar (the robot stopped short of it and turned) and still open: an approach
    /// all the way onto it is next. `blinded`: it had also lain in the blind zone of a first look.
    LookedFromAfar { blinded: bool },
    /// Looked at from on top and still open, or reopened before `Complete`: a look from a viewpoint
    /// chosen to see it is next. `approached`: it was looked at from afar (a reopened cell may not
    /// have been).
    NeedsViewpoint { approached: bool, blinded: bool },
    /// Given up: skipped from now on, unless reopened. What the looks were is kept, since the looks at
    /// its segment still update it and a reopening goes on from there.
    GivenUp {
        approached: bool,
        topped: bool,
        blinded: bool,
    },
}

/// What happened to a frontier cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum CellEvent {
    /// A first look, from afar, had the cell in view (beyond the blind zone).
    SeenFromAfar,
    /// A first look had the cell in the blind zone; a cell already seen from afar keeps its state.
    MissedInBlindZone,
    /// A first look left the cell open and the rules have no look from on top: a viewpoint look
    /// comes next.
    LeftOpenFromAfar,
    /// A look from on top of it (the cell within the blind zone of the robot standing at it); a cell
    /// looked at from on top before is given up.
    LookFromOnTop,
    /// A look from a viewpoint chosen to see it, which gave it up or not (then it counts as looked at
    /// from afar, so its next visit goes all the way onto it).
    ViewpointLook { give_up: bool },
    /// No viewpoint sees a cell that only lay in the blind zone: it gets the approaches instead
    /// (`approach`), or is given up.
    NoViewpoint { approach: bool },
    /// Given up: the robot failed to reach it, or a look left it open under rules without further
    /// looks.
    GiveUp,
    /// Reopened before `Complete` (given up here, or by the planner's own marks).
    Reopen,
}

impl CellState {
    /// The state after `event`: the one place a cell's state changes.
    pub(super) fn next(self, event: CellEvent) -> CellState {
        use CellEvent as E;
        use CellState::*;
        let (approached, topped, blinded) = self.looks();
        match event {
            E::SeenFromAfar => match self {
                Unvisited => LookedFromAfar { blinded: false },
                Blinded => LookedFromAfar { blinded: true },
                LookedFromAfar { .. } => self,
                NeedsViewpoint { blinded, .. } => NeedsViewpoint {
                    approached: true,
                    blinded,
                },
                GivenUp {
                    topped, blinded, ..
                } => GivenUp {
                    approached: true,
                    topped,
                    blinded,
                },
            },
            E::MissedInBlindZone => match self {
                Unvisited => Blinded,
                NeedsViewpoint {
                    approached: false, ..
                } => NeedsViewpoint {
                    approached: false,
                    blinded: true,
                },
                GivenUp {
                    approached: false,
                    topped,
                    ..
                } => GivenUp {
                    approached: false,
                    topped,
                    blinded: true,
                },
                _ => self,
            },
            E::LeftOpenFromAfar => match self {
                GivenUp { blinded, .. } => GivenUp {
                    approached: true,
                    topped: true,
                    blinded,
                },
                _ => NeedsViewpoint {
                    approached: true,
                    blinded,
                },
            },
            E::LookFromOnTop => match self {
                NeedsViewpoint { .. } | GivenUp { .. } => GivenUp {
                    approached,
                    topped: true,
                    blinded,
                },
                _ => NeedsViewpoint {
                    approached,
                    blinded,
                },
            },
            E::ViewpointLook { give_up: true } => GivenUp {
                approached,
                topped,
                blinded: false,
            },
            E::ViewpointLook { give_up: false } => match self {
                GivenUp { topped, .. } => GivenUp {
                    approached: true,
                    topped,
                    blinded: false,
                },
                _ if topped => NeedsViewpoint {
                    approached: true,
                    blinded: false,
                },
                _ => LookedFromAfar { blinded: false },
            },
            E::NoViewpoint { approach } => {
                if !blinded || topped {
                    return self;
                }
                match (self, approach) {
                    (GivenUp { .. }, _) | (_, false) => GivenUp {
                        approached: approached || approach,
                        topped,
                        blinded: false,
                    },
                    (_, true) => LookedFromAfar { blinded: false },
                }
            }
            E::GiveUp => GivenUp {
                approached,
                topped,
                blinded,
            },
            E::Reopen => NeedsViewpoint {
                approached,
                blinded,
            },
        }
    }

    /// How the cell was looked at: from afar (`approached`), from on top or reopened (`topped`),
    /// from within the blind zone (`blinded`).
    fn looks(self) -> (bool, bool, bool) {
        match self {
            CellState::Unvisited => (false, false, false),
            CellState::Blinded => (false, false, true),
            CellState::LookedFromAfar { blinded } => (true, false, blinded),
            CellState::NeedsViewpoint {
                approached,
                blinded,
            } => (approached, true, blinded),
            CellState::GivenUp {
                approached,
                topped,
                blinded,
            } => (approached, topped, blinded),
        }
    }

    /// Given up (and not reopened).
    pub(super) fn is_given_up(self) -> bool {
        matches!(self, CellState::GivenUp { .. })
    }

    /// Looked at from afar: its next approach goes all the way.
    pub(super) fn was_approached(self) -> bool {
        self.looks().0
    }

    /// Looked at from on top, or reopened.
    pub(super) fn was_topped(self) -> bool {
        self.looks().1
    }

    /// Lay in the blind zone of a first look and has had no viewpoint look since.
    pub(super) fn is_blinded(self) -> bool {
        self.looks().2
    }

    /// A look from a viewpoint chosen to see it comes next.
    pub(super) fn needs_viewpoint(self) -> bool {
        let (_, topped, blinded) = self.looks();
        topped || blinded
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference: the four independent marks a cell had before it had a state, and what each
    /// event did to them (`[given up, approached, topped, blinded]`).
    fn reference(m: [bool; 4], e: CellEvent) -> [bool; 4] {
        let [mut u, mut a, mut t, mut b] = m;
        match e {
            CellEvent::SeenFromAfar => a = true,
            CellEvent::MissedInBlindZone => b |= !a,
            CellEvent::LeftOpenFromAfar => (a, t) = (true, true),
            CellEvent::LookFromOnTop => {
                u |= t;
                t = true;
            }
            CellEvent::ViewpointLook { give_up } => {
                b = false;
                if give_up {
                    u = true;
                } else {
                    a = true;
                }
            }
            CellEvent::NoViewpoint { approach } => {
                if b && !t {
                    b = false;
                    if approach {
                        a = true;
                    } else {
                        u = true;
                    }
                }
            }
            CellEvent::GiveUp => u = true,
            CellEvent::Reopen => (u, t) = (false, true),
        }
        [u, a, t, b]
    }

    fn marks(s: CellState) -> [bool; 4] {
        let (a, t, b) = s.looks();
        [s.is_given_up(), a, t, b]
    }

    const EVENTS: [CellEvent; 10] = [
        CellEvent::SeenFromAfar,
        CellEvent::MissedInBlindZone,
        CellEvent::LeftOpenFromAfar,
        CellEvent::LookFromOnTop,
        CellEvent::ViewpointLook { give_up: true },
        CellEvent::ViewpointLook { give_up: false },
        CellEvent::NoViewpoint { approach: true },
        CellEvent::NoViewpoint { approach: false },
        CellEvent::GiveUp,
        CellEvent::Reopen,
    ];

    /// Every state the events reach from `Unvisited`.
    fn reachable() -> Vec<CellState> {
        let mut seen = vec![CellState::Unvisited];
        let mut i = 0;
        while i < seen.len() {
            for e in EVENTS {
                let n = seen[i].next(e);
                if !seen.contains(&n) {
                    seen.push(n);
                }
            }
            i += 1;
        }
        seen
    }

    /// From every state, every event does to the marks what the reference does, and distinct states
    /// have distinct marks: the state machine is the four marks, named.
    #[test]
    fn transitions_agree_with_the_four_marks() {
        let states = reachable();
        // Every combination of the three looks, open and given up.
        assert_eq!(states.len(), 16, "{states:?}");
        for s in &states {
            for e in EVENTS {
                assert_eq!(marks(s.next(e)), reference(marks(*s), e), "{s:?} {e:?}");
            }
        }
        for (i, a) in states.iter().enumerate() {
            for b in &states[i + 1..] {
                assert_ne!(marks(*a), marks(*b), "{a:?} {b:?}");
            }
        }
    }

    /// The named paths of a cell's visits, as the module doc draws them.
    #[test]
    fn the_visits_of_a_cell_in_order() {
        use CellEvent as E;
        use CellState as S;
        let path = |events: &[CellEvent]| events.iter().fold(S::Unvisited, |s, &e| s.next(e));
        assert_eq!(
            path(&[E::SeenFromAfar]),
            S::LookedFromAfar { blinded: false }
        );
        let on_top = path(&[E::SeenFromAfar, E::LookFromOnTop]);
        assert!(on_top.needs_viewpoint() && on_top.was_approached() && !on_top.is_given_up());
        // A second look from on top gives it up; so does a viewpoint look that could see it.
        assert!(on_top.next(E::LookFromOnTop).is_given_up());
        assert!(on_top
            .next(E::ViewpointLook { give_up: true })
            .is_given_up());
        // A viewpoint look that showed nothing counts as the look from afar.
        let blinded = path(&[E::MissedInBlindZone]);
        assert_eq!(blinded, S::Blinded);
        assert_eq!(
            blinded.next(E::ViewpointLook { give_up: false }),
            S::LookedFromAfar { blinded: false }
        );
        // Reopened, a given-up cell waits for a viewpoint look again.
        let reopened = on_top.next(E::LookFromOnTop).next(E::Reopen);
        assert!(reopened.needs_viewpoint() && !reopened.is_given_up());
        // Without viewpoint looks, a blinded cell with no viewpoint is given up.
        assert!(blinded
            .next(E::NoViewpoint { approach: false })
            .is_given_up());
        assert_eq!(
            blinded.next(E::NoViewpoint { approach: true }),
            S::LookedFromAfar { blinded: false }
        );
    }
}
