//! TENSOR's field following: advection along the time-varying field (§4.2), wedge stops and
//! trisector docking (§6), and planning after an arrival at a node.

use super::*;

impl Tensor {
    /// One advection sub-step (§4.2) with the wedge, trisector and unknown-space rules.
    pub(super) fn advect(&mut self, ctx: &mut PlanContext, depth: u32) -> Result<Action> {
        let grid = *ctx.map.grid();
        let robot = ctx.pose.position();
        if !self.advecting {
            // The watchdog times advection only.
            self.last_progress_s = self.last_progress_s.max(ctx.time_s);
        }
        self.advecting = false;
        if let Some((_, pos)) = self.ignore {
            if (pos - robot).norm() > 2.0 * self.cfg.dock_radius_m {
                self.ignore = None;
            }
        }
        let ignore_id = self.ignore.map(|(id, _)| id);
        let nodes: Vec<Node> = self
            .usable_nodes(ctx.map)
            .into_iter()
            .filter(|n| Some(n.id) != ignore_id)
            .collect();
        let pts: Vec<Point2<f64>> = nodes.iter().map(|n| n.pos).collect();
        let heading = self.heading_override.take().unwrap_or(ctx.pose.yaw);
        let v = ctx.cfg.robot.max_speed_mps;
        let len = self.pathline_length(v);
        let stop = StopConditions {
            grid: &grid,
            obstacle: None,
            unknown: None,
            degenerate_points: &pts,
            degenerate_radius_m: self.field_cfg.arrive_radius_m,
            origin: None,
        };
        let (mut line, reason) = self.trace_pathline(robot, heading, ctx.time_s, len, v, &stop);
        self.stats.retraces += 1;
        // At a node already: handle the arrival there.
        if let (StopReason::NearDegenerate(k), true) = (reason, line.len() <= 1) {
            if depth < 2 {
                let n = nodes[k];
                let arrival = Arrival {
                    id: n.id,
                    kind: if n.kind == DegenerateKind::Trisector {
                        self.stats.trisector_dockings += 1;
                        ArrivalKind::Dock
                    } else {
                        ArrivalKind::Wedge
                    },
                };
                return self.plan_at(ctx, arrival, depth + 1);
            }
        }
        let cut = line
            .iter()
            .skip(1)
            .position(|p| {
                grid.cell_of(*p)
                    .is_none_or(|c| !ctx.passable(grid.index(c)))
            })
            .map(|k| k + 1)
            .unwrap_or(line.len());
        let whole = cut == line.len();
        line.truncate(cut);
        // Docking: the line approaches a trisector within the radius and leaves it again (or
        // ends at it); cut at the closest approach and end at the trisector.
        let mut dock: Option<(usize, usize)> = None;
        for (k, n) in nodes.iter().enumerate() {
            if n.kind != DegenerateKind::Trisector {
                continue;
            }
            let Some((j, d)) = line
                .iter()
                .enumerate()
                .map(|(j, p)| (j, (p - n.pos).norm()))
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            else {
                continue;
            };
            let ends_here = whole && reason == StopReason::NearDegenerate(k);
            if d < self.cfg.dock_radius_m
                && (j + 1 < line.len() || ends_here)
                && dock.is_none_or(|(_, bj)| j < bj)
            {
                dock = Some((k, j));
            }
        }
        if let Some((k, j)) = dock {
            let n = nodes[k];
            let mut path: Vec<Point2<f64>> = line[..=j].to_vec();
            if grid
                .cell_of(n.pos)
                .is_some_and(|c| ctx.passable(grid.index(c)))
            {
                path.push(n.pos);
            }
            self.stats.trisector_dockings += 1;
            if path.len() < 2 || path_length(&path) < ctx.cfg.motion.goal_tolerance_m {
                if depth < 2 {
                    let arrival = Arrival {
                        id: n.id,
                        kind: ArrivalKind::Dock,
                    };
                    return self.plan_at(ctx, arrival, depth + 1);
                }
            } else {
                self.advecting = true;
                self.current = Current::Dock {
                    id: n.id,
                    pos: n.pos,
                    cells: path_cells(&grid, &path),
                };
                return Ok(Action::Follow {
                    path,
                    look_on_arrival: false,
                    exact_arrival: false,
                });
            }
        }
        if path_length(&line) < MIN_ADVANCE_M.max(ctx.cfg.motion.goal_tolerance_m + 0.1) {
            // Advection is blocked here: route globally (or hand over).
            if depth < 2 {
                return match self.route(ctx, None) {
                    Routed::Leave { heading, node_id } => {
                        self.heading_override = Some(heading);
                        self.ignore = Some((node_id, robot));
                        self.advect(ctx, depth + 1)
                    }
                    Routed::Go(a) => Ok(a),
                    Routed::Nothing => {
                        self.transition(Event::NoRoute);
                        self.fallback(ctx)
                    }
                };
            }
            return self.fallback(ctx);
        }
        // A path into unknown space: look first (once per spot).
        let into_unknown = line.iter().skip(1).any(|p| {
            grid.cell_of(*p)
                .is_some_and(|c| ctx.map.is_unknown(grid.index(c)))
        });
        if into_unknown
            && !self
                .looks_at
                .iter()
                .any(|q| (q - robot).norm() < self.cfg.look_spacing_m)
        {
            self.looks_at.push(robot);
            self.stats.looks += 1;
            self.advecting = true;
            self.current = Current::Look;
            return Ok(Action::LookAround);
        }
        let wedge = match reason {
            StopReason::NearDegenerate(k) if whole && nodes[k].kind == DegenerateKind::Wedge => {
                Some((nodes[k].id, nodes[k].pos))
            }
            _ => None,
        };
        self.advecting = true;
        self.current = Current::Advect {
            started_s: ctx.time_s,
            cells: path_cells(&grid, &line),
            wedge,
        };
        self.route_target = None;
        Ok(Action::Follow {
            path: line,
            look_on_arrival: false,
            exact_arrival: false,
        })
    }

    /// Plans after an arrival at a node, then advects.
    pub(super) fn plan_at(
        &mut self,
        ctx: &mut PlanContext,
        arr: Arrival,
        depth: u32,
    ) -> Result<Action> {
        let pos = self
            .field
            .as_ref()
            .and_then(|f| f.points().iter().find(|n| n.id == arr.id))
            .map_or(ctx.pose.position(), |n| n.pos());
        self.ignore = Some((arr.id, pos));
        let branch = match arr.kind {
            ArrivalKind::Route { heading: Some(h) } => {
                self.heading_override = Some(h);
                false
            }
            ArrivalKind::Route { heading: None } | ArrivalKind::Dock => true,
            ArrivalKind::Wedge => {
                self.stats.wedge_stops += 1;
                // Stop and re-plan; route away when the wedge's branches offer nothing.
                !self.node_has_gain(ctx, arr.id)
            }
        };
        if branch {
            match self.route(ctx, Some(arr.id)) {
                Routed::Leave { heading, .. } => self.heading_override = Some(heading),
                Routed::Go(a) => return Ok(a),
                Routed::Nothing => {
                    if arr.kind != ArrivalKind::Wedge {
                        self.transition(Event::NoRoute);
                        return self.fallback(ctx);
                    }
                }
            }
        }
        self.advect(ctx, depth)
    }
}
