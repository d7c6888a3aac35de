//! Procedural indoor scenes: rooms, doors, corridors, loops and furniture of several heights.
//!
//! Layout and walls live on a 0.05 m cell raster (walls 2 cells = 0.1 m thick, doors 20 cells =
//! 1.0 m wide) and are extruded by the shared [`extrude_grid`]; furniture is added as closed boxes.
//! Every furniture piece is kept only if, with it, the robot can still drive the whole plan: the
//! cells with ≥ 0.45 m clearance from the robot-height footprint form one connected piece that
//! reaches every room, and every free cell lies within 0.6 m of it (checked with the exact distance
//! transform of the ground truth). Without the last rule a bed and a box 0.3 m apart cut off floor
//! that counts as explorable but that the robot can never approach. The rules are checked over the
//! whole plan once the doors are in, then, for each piece tried, only where the piece can change
//! them (`Plan::keeps_drivable`, with the same answer), so a 10,000 m² plan takes seconds rather
//! than minutes. All randomness comes from one ChaCha8 stream seeded by `seed`; nothing iterates a
//! hash map.

use super::extrude::extrude_grid;
use super::TriMesh;
use crate::error::{Error, Result};
use crate::grid::distance_transform;
use crate::Pose2;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Raster cell, metres.
const RES: f64 = 0.05;
/// Wall thickness, cells (0.1 m).
const WALL: i32 = 2;
/// Door width, cells (1.0 m: a 0.5 m robot passes with margin).
const DOOR: i32 = 20;
/// Minimum distance from a door to a wall corner, cells.
const DOOR_MARGIN: i32 = 4;
/// Gap between a wall-side piece and a room corner below which the piece moves into the corner,
/// cells (0.9 m: narrower gaps cannot hold the robot).
const SNAP_GAP: i32 = 18;
/// Wall height, metres.
const WALL_HEIGHT: f64 = 2.5;
/// Squared clearance (cells², cell centre to the nearest blocked cell centre) of a cell the robot can
/// drive: 0.45 m, i.e. passages of ~0.9 m; the planner keeps the 0.25 m disc's centre ≥ ~0.33 m from
/// obstacles, so such cells are reachable with margin.
const DRIVE_D2: f64 = (0.45 / RES) * (0.45 / RES);
/// Squared distance (cells²) within which every free floor cell must have a drivable cell: 0.6 m, so
/// the camera always gets close to it (a room corner is ~0.57 m from the nearest drivable cell).
const APPROACH_D2: f64 = (0.6 / RES) * (0.6 / RES);

/// The kind of building to generate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    Apartment,
    Office,
    Corridor,
    Warehouse,
}

impl Style {
    pub const ALL: [Style; 4] = [
        Style::Apartment,
        Style::Office,
        Style::Corridor,
        Style::Warehouse,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Style::Apartment => "apartment",
            Style::Office => "office",
            Style::Corridor => "corridor",
            Style::Warehouse => "warehouse",
        }
    }

    /// Parses a style name (as the CLI's `--style` takes it).
    pub fn parse(name: &str) -> Result<Style> {
        Style::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| {
                Error::usage(format!(
                    "unknown scene style `{name}` (expected apartment, office, corridor or warehouse)"
                ))
            })
    }
}

/// A generated scene and what it contains.
#[derive(Clone, Debug)]
pub struct GeneratedScene {
    pub mesh: TriMesh,
    /// The free spot with the largest clearance in the connected free space.
    pub spawn: Pose2,
    pub style: Style,
    pub seed: u64,
    /// Footprint area (outer walls included), m².
    pub area_m2: f64,
    /// Room rectangles `[x0, y0, x1, y1]` (inner faces of the walls), metres.
    pub rooms: Vec<[f64; 4]>,
    pub doors: usize,
    /// Doors beyond a spanning tree of the rooms: each closes one cycle.
    pub loops: usize,
    /// What the scene contains, e.g. "loop", "corridor", "tables", "wall_shelves", "cubicles".
    pub features: Vec<String>,
}

impl GeneratedScene {
    /// The header lines `write_obj` puts at the top of a shipped scene.
    pub fn header(&self) -> Vec<String> {
        vec![
            format!(
                "tensorscout generated scene: style {}, seed {}, area {:.1} m2",
                self.style.name(),
                self.seed,
                self.area_m2
            ),
            format!(
                "rooms {}, doors {}, loops {}, features: {}",
                self.rooms.len(),
                self.doors,
                self.loops,
                self.features.join(", ")
            ),
        ]
    }
}

/// Largest footprint `generate` accepts, m²: a 200 × 200 m building, whose ground-truth grid at the
/// default 0.1 m voxels (about 2,000 × 2,000 cells × 25 layers, 100 M voxels) is a quarter of the
/// ground truth's voxel bound; the scaling benchmark (`examples/scaling.rs`) goes this far.
pub const MAX_AREA_M2: f64 = 40_000.0;

/// Generates a scene of `style` with a footprint of about `area_m2` (20–40,000 m²), deterministic per
/// `seed`.
pub fn generate(style: Style, seed: u64, area_m2: f64) -> Result<GeneratedScene> {
    build(style, seed, area_m2, &mut |_, _| {}, false)
}

/// [`generate`], calling `progress(rooms furnished, rooms)` before the first room and after each
/// (furnishing is most of the work).
pub fn generate_with_progress(
    style: Style,
    seed: u64,
    area_m2: f64,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<GeneratedScene> {
    build(style, seed, area_m2, progress, false)
}

/// [`generate_with_progress`]; with `verify`, every placement's drivability check is compared
/// with the whole-plan check (a panic on disagreement: for tests).
fn build(
    style: Style,
    seed: u64,
    area_m2: f64,
    progress: &mut dyn FnMut(usize, usize),
    verify: bool,
) -> Result<GeneratedScene> {
    if !(20.0..=MAX_AREA_M2).contains(&area_m2) {
        return Err(Error::usage(format!(
            "scene area {area_m2} m² is outside [20, {MAX_AREA_M2}] m²"
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut plan = layout(style, area_m2, &mut rng);
    plan.verify = verify;
    plan.add_doors(style, area_m2, &mut rng);
    let (_, drivable) = plan.drivable_spawn().ok_or_else(|| {
        Error::Runtime(format!(
            "generator: {} seed {seed} produced a room the robot cannot drive",
            style.name()
        ))
    })?;
    plan.drivable = Some(drivable);
    furnish(&mut plan, style, &mut rng, progress);
    let (spawn_cell, _) = plan
        .drivable_spawn()
        .expect("furniture is only kept while the plan stays drivable");

    let (w, h) = (plan.w as usize, plan.h as usize);
    let mut mesh = extrude_grid(&plan.solid, w, h, [0.0, 0.0], RES, WALL_HEIGHT);
    for b in &plan.boxes {
        mesh.push_box(b.0, b.1);
    }
    let (sx, sy) = (spawn_cell % w, spawn_cell / w);
    let spawn = Pose2::new((sx as f64 + 0.5) * RES, (sy as f64 + 0.5) * RES, 0.0);
    let mut features = vec!["rooms".to_string(), "doors".to_string()];
    if plan.loops > 0 {
        features.push("loop".into());
    }
    if style == Style::Corridor {
        features.push("corridor".into());
    }
    features.extend(plan.placed.iter().map(|s| s.to_string()));
    Ok(GeneratedScene {
        mesh,
        spawn,
        style,
        seed,
        area_m2: plan.w as f64 * plan.h as f64 * RES * RES,
        rooms: plan
            .rooms
            .iter()
            .map(|r| {
                [
                    r.x0 as f64 * RES,
                    r.y0 as f64 * RES,
                    r.x1 as f64 * RES,
                    r.y1 as f64 * RES,
                ]
            })
            .collect(),
        doors: plan.doors.len(),
        loops: plan.loops,
        features,
    })
}

/// A rectangle of cells `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rect {
    x0: i32,
    y0: i32,
    x1: i32,
    y1: i32,
}

impl Rect {
    fn w(&self) -> i32 {
        self.x1 - self.x0
    }
    fn h(&self) -> i32 {
        self.y1 - self.y0
    }
    fn area_m2(&self) -> f64 {
        self.w() as f64 * self.h() as f64 * RES * RES
    }
    fn grow(&self, d: i32) -> Rect {
        Rect {
            x0: self.x0 - d,
            y0: self.y0 - d,
            x1: self.x1 + d,
            y1: self.y1 + d,
        }
    }
    fn intersects(&self, o: &Rect) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }
    fn contains(&self, o: &Rect) -> bool {
        o.x0 >= self.x0 && o.x1 <= self.x1 && o.y0 >= self.y0 && o.y1 <= self.y1
    }
    /// The part of `self` inside `o` (empty: zero or negative width or height).
    fn clip(&self, o: &Rect) -> Rect {
        Rect {
            x0: self.x0.max(o.x0),
            y0: self.y0.max(o.y0),
            x1: self.x1.min(o.x1),
            y1: self.y1.min(o.y1),
        }
    }
    /// Squared distance, cells², from the centre of cell `(x, y)` to the nearest cell centre of
    /// `self` (not empty).
    fn dist2(&self, x: i32, y: i32) -> i64 {
        let dx = (self.x0 - x).max(x - (self.x1 - 1)).max(0) as i64;
        let dy = (self.y0 - y).max(y - (self.y1 - 1)).max(0) as i64;
        dx * dx + dy * dy
    }
}

/// The smallest rectangle holding every rectangle of `rects`; `None` for none.
fn bounding_box(rects: &[Rect]) -> Option<Rect> {
    rects.iter().copied().reduce(|a, b| Rect {
        x0: a.x0.min(b.x0),
        y0: a.y0.min(b.y0),
        x1: a.x1.max(b.x1),
        y1: a.y1.max(b.y1),
    })
}

/// A margin, in cells, that holds every cell whose centre lies within `sqrt(d2)` of a given cell
/// (with one cell to spare).
fn reach_cells(d2: f64) -> i32 {
    d2.sqrt().ceil() as i32 + 1
}

/// The 4-neighbours of cell `i` of a `w` × `h` raster.
fn neighbours4(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (i % w, i / w);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < w).then(|| i + 1),
        (y > 0).then(|| i - w),
        (y + 1 < h).then(|| i + w),
    ]
    .into_iter()
    .flatten()
}

/// Whether the set `cells` (of a raster `w` wide) joins every cell of `targets` (distinct, all
/// set) in one 4-connected piece. A breadth-first fill grows from every target at once, its parts
/// merging where they meet: it answers yes once all have merged, and no as soon as one part has
/// run out of cells while others remain. So the cost is that of the smallest piece when the set
/// falls apart, and of the gaps between the targets when it does not, never the whole raster's.
fn joined(targets: &[usize], w: usize, cells: &[bool], label: &mut [u32]) -> bool {
    let mut reached = Vec::with_capacity(targets.len());
    let answer = fill_parts(targets, w, cells, label, &mut reached);
    for &c in &reached {
        label[c] = 0;
    }
    answer
}

/// The fill of [`joined`]: `label` (all 0 on entry) gets, per cell reached, 1 + the target whose
/// part reached it first; `reached` lists those cells, in the order reached.
fn fill_parts(
    targets: &[usize],
    w: usize,
    cells: &[bool],
    label: &mut [u32],
    reached: &mut Vec<usize>,
) -> bool {
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let h = cells.len() / w;
    let mut parts = targets.len();
    if parts <= 1 {
        return true;
    }
    let mut parent: Vec<usize> = (0..parts).collect();
    // Per part (at its root), the cells reached and not yet expanded.
    let mut pending = vec![1usize; parts];
    for (k, &t) in targets.iter().enumerate() {
        label[t] = k as u32 + 1;
        reached.push(t);
    }
    let mut next = 0;
    while let Some(&i) = reached.get(next) {
        next += 1;
        let a = root(&mut parent, label[i] as usize - 1);
        for j in neighbours4(i, w, h) {
            if !cells[j] {
                continue;
            }
            if label[j] == 0 {
                label[j] = label[i];
                reached.push(j);
                pending[a] += 1;
            } else {
                let b = root(&mut parent, label[j] as usize - 1);
                if b != a {
                    parent[b] = a;
                    pending[a] += pending[b];
                    parts -= 1;
                    if parts == 1 {
                        return true;
                    }
                }
            }
        }
        pending[a] -= 1;
        if pending[a] == 0 {
            // This part is a whole piece of the set, and others remain.
            return false;
        }
    }
    unreachable!("the fill ends when one part runs out of cells")
}

/// The plan being built: wall raster, rooms, doors, furniture.
struct Plan {
    w: i32,
    h: i32,
    solid: Vec<bool>,
    rooms: Vec<Rect>,
    /// Index of a room every other room should open onto first (a corridor or hall), if any.
    hub: Option<usize>,
    /// Door openings (the carved wall cells).
    doors: Vec<Rect>,
    loops: usize,
    /// Footprints that block the robot (furniture reaching into [0.1, 1.2] m).
    blocking: Vec<Rect>,
    /// Footprints of all furniture, kept apart from each other.
    taken: Vec<Rect>,
    /// Mesh boxes `(min, max)` in metres.
    boxes: Vec<([f64; 3], [f64; 3])>,
    /// Furniture kinds placed, in first-placed order, without repeats.
    placed: Vec<&'static str>,
    /// The drivable cells of the plan as it stands, once it has been checked drivable.
    drivable: Option<Drivable>,
    /// Compare every placement's drivability check with the whole-plan check (tests).
    verify: bool,
}

/// The cells the robot can drive in a plan that passed [`Plan::drivable_spawn`], kept between
/// placements so that a piece is checked only where it changes them ([`Plan::keeps_drivable`]).
#[derive(Clone, Debug, PartialEq)]
struct Drivable {
    /// Walls and robot-blocking furniture.
    blocked: Vec<bool>,
    /// The cells whose clearance is at least [`DRIVE_D2`].
    cells: Vec<bool>,
    /// How many cells are drivable.
    count: usize,
    /// Scratch space of [`joined`], one per cell, all 0 between calls.
    label: Vec<u32>,
}

/// Splits the footprint into rooms according to the style.
fn layout(style: Style, area_m2: f64, rng: &mut ChaCha8Rng) -> Plan {
    let cells = |m: f64| (m / RES).round() as i32;
    let (w, h, rooms, hub) = match style {
        Style::Corridor => {
            // Side rooms of depth `d` on both sides of a 2 m corridor.
            let d = (area_m2.sqrt() / 3.0).clamp(2.6, 4.5);
            let h_m = 2.0 + 2.0 * d + 4.0 * WALL as f64 * RES;
            let w_m = area_m2 / h_m;
            let (w, h) = (cells(w_m), cells(h_m));
            let (dc, cc) = (cells(d), cells(2.0));
            let bottom = Rect {
                x0: WALL,
                y0: WALL,
                x1: w - WALL,
                y1: WALL + dc,
            };
            let corridor = Rect {
                x0: WALL,
                y0: bottom.y1 + WALL,
                x1: w - WALL,
                y1: bottom.y1 + WALL + cc,
            };
            let top = Rect {
                x0: WALL,
                y0: corridor.y1 + WALL,
                x1: w - WALL,
                y1: h - WALL,
            };
            let mut rooms = vec![corridor];
            for strip in [bottom, top] {
                rooms.extend(split_along_x(strip, cells(3.0), cells(4.5), rng));
            }
            (w, h, rooms, Some(0))
        }
        _ => {
            let aspect = rng.random_range(1.0..1.5);
            let w_m = (area_m2 * aspect).sqrt();
            let (w, h) = (cells(w_m), cells(area_m2 / w_m));
            let inner = Rect {
                x0: WALL,
                y0: WALL,
                x1: w - WALL,
                y1: h - WALL,
            };
            match style {
                Style::Apartment => (w, h, bsp(inner, 15.0, cells(2.6), rng), None),
                Style::Office => {
                    // An open-plan area on ~45 % of the floor, single offices on the rest.
                    let (open, rest) = cut(inner, 0.45, rng);
                    let mut rooms = vec![open];
                    rooms.extend(bsp(rest, 28.0, cells(3.0), rng));
                    (w, h, rooms, Some(0))
                }
                Style::Warehouse => {
                    // One hall on ~80 % of the floor, a strip of small rooms beside it.
                    let (hall, strip) = cut(inner, 0.8, rng);
                    let mut rooms = vec![hall];
                    rooms.extend(bsp(strip, 20.0, cells(2.6), rng));
                    (w, h, rooms, Some(0))
                }
                Style::Corridor => unreachable!("handled above"),
            }
        }
    };
    let mut solid = vec![true; (w * h) as usize];
    for r in &rooms {
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                solid[(y * w + x) as usize] = false;
            }
        }
    }
    Plan {
        w,
        h,
        solid,
        rooms,
        hub,
        doors: Vec::new(),
        loops: 0,
        blocking: Vec::new(),
        taken: Vec::new(),
        boxes: Vec::new(),
        placed: Vec::new(),
        drivable: None,
        verify: false,
    }
}

/// Cuts `r` across its longer side at `fraction` (± a little) into two rooms separated by a wall.
fn cut(r: Rect, fraction: f64, rng: &mut ChaCha8Rng) -> (Rect, Rect) {
    let f = fraction + rng.random_range(-0.03..0.03);
    if r.w() >= r.h() {
        let s = r.x0 + (r.w() as f64 * f) as i32;
        (Rect { x1: s, ..r }, Rect { x0: s + WALL, ..r })
    } else {
        let s = r.y0 + (r.h() as f64 * f) as i32;
        (Rect { y1: s, ..r }, Rect { y0: s + WALL, ..r })
    }
}

/// Splits a strip into rooms between `min` and `max` cells wide along x.
fn split_along_x(strip: Rect, min: i32, max: i32, rng: &mut ChaCha8Rng) -> Vec<Rect> {
    let mut rooms = Vec::new();
    let mut x = strip.x0;
    while strip.x1 - x > max + WALL + min {
        let width = rng.random_range(min..=max);
        rooms.push(Rect {
            x0: x,
            x1: x + width,
            ..strip
        });
        x += width + WALL;
    }
    rooms.push(Rect { x0: x, ..strip });
    rooms
}

/// Binary space partition into rooms of about `target_m2`, no side below `min` cells.
fn bsp(r: Rect, target_m2: f64, min: i32, rng: &mut ChaCha8Rng) -> Vec<Rect> {
    let along_x = r.w() >= r.h();
    let len = if along_x { r.w() } else { r.h() };
    if r.area_m2() <= target_m2 * 1.3 || len < 2 * min + WALL {
        return vec![r];
    }
    let s = rng.random_range(min..=len - min - WALL);
    let (a, b) = if along_x {
        (
            Rect { x1: r.x0 + s, ..r },
            Rect {
                x0: r.x0 + s + WALL,
                ..r
            },
        )
    } else {
        (
            Rect { y1: r.y0 + s, ..r },
            Rect {
                y0: r.y0 + s + WALL,
                ..r
            },
        )
    };
    let mut out = bsp(a, target_m2, min, rng);
    out.extend(bsp(b, target_m2, min, rng));
    out
}

impl Plan {
    fn cell(&self, x: i32, y: i32) -> usize {
        (y * self.w + x) as usize
    }

    /// The whole raster as a rectangle.
    fn whole(&self) -> Rect {
        Rect {
            x0: 0,
            y0: 0,
            x1: self.w,
            y1: self.h,
        }
    }

    /// A room's window: the room, its walls and their doors, within the raster.
    fn window(&self, room: &Rect) -> Rect {
        room.grow(WALL).clip(&self.whole())
    }

    /// Whether an unblocked cell of `checked` lies farther than [`APPROACH_D2`] from every
    /// drivable cell of `sites` (which holds `checked`): floor the robot cannot approach.
    fn pocket(&self, drivable: &[bool], blocked: &[bool], checked: Rect, sites: Rect) -> bool {
        let (sw, sh) = (sites.w() as usize, sites.h() as usize);
        let site: Vec<bool> = (sites.y0..sites.y1)
            .flat_map(|y| (sites.x0..sites.x1).map(move |x| (x, y)))
            .map(|(x, y)| drivable[self.cell(x, y)])
            .collect();
        let near = distance_transform(&site, sw, sh);
        (checked.y0..checked.y1)
            .flat_map(|y| (checked.x0..checked.x1).map(move |x| (x, y)))
            .any(|(x, y)| {
                let d = near[(y - sites.y0) as usize * sw + (x - sites.x0) as usize];
                !blocked[self.cell(x, y)] && d > APPROACH_D2
            })
    }

    /// Candidate doors between rooms separated by one wall: `(room a, room b, opening)`.
    fn door_candidates(&self, rng: &mut ChaCha8Rng) -> Vec<(usize, usize, Rect)> {
        let mut out = Vec::new();
        for (i, a) in self.rooms.iter().enumerate() {
            for (j, b) in self.rooms.iter().enumerate().skip(i + 1) {
                let span = |lo0: i32, hi0: i32, lo1: i32, hi1: i32| (lo0.max(lo1), hi0.min(hi1));
                let opening = if a.x1 + WALL == b.x0 || b.x1 + WALL == a.x0 {
                    let x0 = if a.x1 + WALL == b.x0 { a.x1 } else { b.x1 };
                    let (lo, hi) = span(a.y0, a.y1, b.y0, b.y1);
                    (hi - lo >= DOOR + 2 * DOOR_MARGIN).then(|| {
                        let y = rng.random_range(lo + DOOR_MARGIN..=hi - DOOR_MARGIN - DOOR);
                        Rect {
                            x0,
                            y0: y,
                            x1: x0 + WALL,
                            y1: y + DOOR,
                        }
                    })
                } else if a.y1 + WALL == b.y0 || b.y1 + WALL == a.y0 {
                    let y0 = if a.y1 + WALL == b.y0 { a.y1 } else { b.y1 };
                    let (lo, hi) = span(a.x0, a.x1, b.x0, b.x1);
                    (hi - lo >= DOOR + 2 * DOOR_MARGIN).then(|| {
                        let x = rng.random_range(lo + DOOR_MARGIN..=hi - DOOR_MARGIN - DOOR);
                        Rect {
                            x0: x,
                            y0,
                            x1: x + DOOR,
                            y1: y0 + WALL,
                        }
                    })
                } else {
                    None
                };
                if let Some(o) = opening {
                    out.push((i, j, o));
                }
            }
        }
        out
    }

    /// Doors along a random spanning tree of the rooms (hub edges first), plus loop doors.
    fn add_doors(&mut self, style: Style, area_m2: f64, rng: &mut ChaCha8Rng) {
        let mut edges = self.door_candidates(rng);
        edges.shuffle(rng);
        let hub = self.hub;
        edges.sort_by_key(|&(a, b, _)| !(Some(a) == hub || Some(b) == hub));
        let mut parent: Vec<usize> = (0..self.rooms.len()).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        let mut spare = Vec::new();
        for (a, b, o) in edges {
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            if ra != rb {
                parent[ra] = rb;
                self.doors.push(o);
            } else {
                spare.push(o);
            }
        }
        let wanted = match style {
            Style::Apartment if area_m2 < 90.0 => 0,
            Style::Apartment => 2,
            Style::Office => 3,
            Style::Corridor => 2,
            Style::Warehouse => 1,
        };
        for o in spare.into_iter().take(wanted) {
            self.doors.push(o);
            self.loops += 1;
        }
        for d in self.doors.clone() {
            for y in d.y0..d.y1 {
                for x in d.x0..d.x1 {
                    let c = self.cell(x, y);
                    self.solid[c] = false;
                }
            }
        }
    }

    /// The raster with walls and robot-blocking furniture set.
    fn blocked(&self) -> Vec<bool> {
        let mut blocked = self.solid.clone();
        for r in &self.blocking {
            for y in r.y0..r.y1 {
                for x in r.x0..r.x1 {
                    blocked[self.cell(x, y)] = true;
                }
            }
        }
        blocked
    }

    /// Checks that the robot can drive the whole plan and returns the spawn cell: the drivable cell
    /// with the largest clearance (ties → lowest index). `None` unless
    /// - every room holds a drivable cell (clearance ≥ [`DRIVE_D2`]),
    /// - all drivable cells form one 4-connected component (the robot can go everywhere it fits),
    /// - every unblocked cell lies within [`APPROACH_D2`] of a drivable cell of its own room (or of a
    ///   door of that room), so no floor hides in a pocket the robot cannot approach. The distance
    ///   is taken per room window (room + its walls and doors) so a drivable cell behind a wall
    ///   never counts.
    fn drivable_spawn(&self) -> Option<(usize, Drivable)> {
        let (w, h) = (self.w as usize, self.h as usize);
        let blocked = self.blocked();
        let d2 = distance_transform(&blocked, w, h);
        let drivable: Vec<bool> = d2.iter().map(|&d| d >= DRIVE_D2).collect();

        // (b) one connected drivable component.
        let start = drivable.iter().position(|&d| d)?;
        let mut seen = vec![false; w * h];
        seen[start] = true;
        let mut stack = vec![start];
        let mut best = start;
        let mut reached = 0usize;
        while let Some(i) = stack.pop() {
            reached += 1;
            if d2[i] > d2[best] || (d2[i] == d2[best] && i < best) {
                best = i;
            }
            let (x, y) = (i % w, i / w);
            let neighbours = [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ];
            for j in neighbours.into_iter().flatten() {
                if !seen[j] && drivable[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        if reached != drivable.iter().filter(|&&d| d).count() {
            return None;
        }

        for room in &self.rooms {
            let has_drivable =
                (room.y0..room.y1).any(|y| (room.x0..room.x1).any(|x| drivable[self.cell(x, y)]));
            if !has_drivable {
                return None;
            }
            // (a) every free cell of the room window is near the drivable space.
            let win = self.window(room);
            if self.pocket(&drivable, &blocked, win, win) {
                return None;
            }
        }
        let count = reached;
        Some((
            best,
            Drivable {
                label: vec![0; blocked.len()],
                blocked,
                cells: drivable,
                count,
            },
        ))
    }

    /// Whether the plan stays drivable ([`Plan::drivable_spawn`]'s three rules) when the cells of
    /// `new` are blocked too, given `state`, the drivable cells of the plan as it stands (which
    /// passed the rules). Blocking cells only lowers clearances, so the rules are checked only
    /// where they can change, with the same arithmetic as the whole-plan check:
    /// - a cell stops being drivable only within [`DRIVE_D2`] of a new blocked cell;
    /// - a room can lose its last drivable cell only if it lost one;
    /// - the remaining drivable cells stay connected if the ones next to the lost cells are still
    ///   connected to each other (any path through the lost cells enters and leaves by them), which
    ///   [`joined`] decides;
    /// - only cells within [`APPROACH_D2`] of a lost cell can lose the drivable cell near them;
    ///   their distances are taken on the part of their room window that holds every drivable
    ///   cell within that distance.
    ///
    /// On `true`, `state` is updated to the plan with `new` blocked; on `false` it is left as it was.
    fn keeps_drivable(&self, state: &mut Drivable, new: &[Rect]) -> bool {
        let (w, h) = (self.w as usize, self.h as usize);
        let Some(new_box) = bounding_box(new) else {
            return true;
        };
        // The drivable cells the new blocked cells take away.
        let zone = new_box.grow(reach_cells(DRIVE_D2)).clip(&self.whole());
        let mut lost = Vec::new();
        for y in zone.y0..zone.y1 {
            for x in zone.x0..zone.x1 {
                let c = self.cell(x, y);
                if state.cells[c] && new.iter().any(|r| (r.dist2(x, y) as f64) < DRIVE_D2) {
                    lost.push(c);
                }
            }
        }
        let newly_blocked: Vec<usize> = new
            .iter()
            .flat_map(|r| (r.y0..r.y1).flat_map(move |y| (r.x0..r.x1).map(move |x| (x, y))))
            .map(|(x, y)| self.cell(x, y))
            .filter(|&c| !state.blocked[c])
            .collect();
        let apply = |state: &mut Drivable, on: bool| {
            for &c in &newly_blocked {
                state.blocked[c] = on;
            }
            for &c in &lost {
                state.cells[c] = !on;
            }
        };
        apply(state, true);
        let ok = lost.is_empty() || self.still_drivable(state, &lost, w, h);
        if ok {
            state.count -= lost.len();
        } else {
            apply(state, false);
        }
        ok
    }

    /// The rules of [`Plan::keeps_drivable`] after `lost` (not empty) stopped being drivable;
    /// `state` already holds the new blocked and drivable cells.
    fn still_drivable(&self, state: &mut Drivable, lost: &[usize], w: usize, h: usize) -> bool {
        if lost.len() == state.count {
            return false;
        }
        let cells = &state.cells;
        let at = |c: usize| ((c % w) as i32, (c / w) as i32);
        let lost_box = bounding_box(
            &lost
                .iter()
                .map(|&c| {
                    let (x, y) = at(c);
                    Rect {
                        x0: x,
                        y0: y,
                        x1: x + 1,
                        y1: y + 1,
                    }
                })
                .collect::<Vec<_>>(),
        )
        .expect("lost is not empty");
        // Every room keeps a drivable cell.
        for room in self.rooms.iter().filter(|r| r.intersects(&lost_box)) {
            if !(room.y0..room.y1).any(|y| (room.x0..room.x1).any(|x| cells[self.cell(x, y)])) {
                return false;
            }
        }
        // The drivable cells stay one 4-connected piece.
        let mut border: Vec<usize> = lost
            .iter()
            .flat_map(|&c| neighbours4(c, w, h))
            .filter(|&j| cells[j])
            .collect();
        border.sort_unstable();
        border.dedup();
        if !joined(&border, w, cells, &mut state.label) {
            return false;
        }
        // No pocket: every unblocked cell near the lost ones keeps a drivable cell of its room
        // window within reach.
        let reach = reach_cells(APPROACH_D2);
        let checked = lost_box.grow(reach);
        for room in &self.rooms {
            let win = self.window(room);
            let q = checked.clip(&win);
            if q.w() <= 0 || q.h() <= 0 {
                continue;
            }
            if self.pocket(&state.cells, &state.blocked, q, q.grow(reach).clip(&win)) {
                return false;
            }
        }
        true
    }

    /// Keep-out zones in front of doors (1 m on both sides), where no furniture may stand.
    fn door_zones(&self) -> Vec<Rect> {
        self.doors
            .iter()
            .map(|d| {
                if d.w() == WALL {
                    Rect {
                        x0: d.x0 - 20,
                        x1: d.x1 + 20,
                        y0: d.y0 - 2,
                        y1: d.y1 + 2,
                    }
                } else {
                    Rect {
                        x0: d.x0 - 2,
                        x1: d.x1 + 2,
                        y0: d.y0 - 20,
                        y1: d.y1 + 20,
                    }
                }
            })
            .collect()
    }

    /// Panics unless [`Plan::keeps_drivable`] answered `keeps` for `piece` as the whole-plan check
    /// does, and left the same drivable cells (of the plan with the piece if kept, else without).
    fn verify_against_whole_plan(&mut self, state: &Drivable, piece: &Piece, keeps: bool) {
        let n = self.blocking.len();
        self.blocking.extend(piece.blocking.iter().copied());
        let with_piece = self.drivable_spawn().map(|(_, d)| d);
        self.blocking.truncate(n);
        assert_eq!(
            with_piece.is_some(),
            keeps,
            "drivability of {:?} misjudged",
            piece.footprint
        );
        let expected = if keeps {
            with_piece
        } else {
            self.drivable_spawn().map(|(_, d)| d)
        };
        assert!(
            expected.as_ref() == Some(state),
            "drivable cells after {:?} differ",
            piece.footprint
        );
    }

    /// Tries to add one piece; keeps it only if it fits in `room`, clears doors and other pieces by
    /// 0.1 m, and leaves the plan drivable ([`Plan::drivable_spawn`], checked where the piece
    /// changes it: [`Plan::keeps_drivable`]).
    fn try_place(&mut self, room: Rect, piece: &Piece) -> bool {
        let fp = piece.footprint;
        if !room.contains(&fp)
            || self.taken.iter().any(|t| t.grow(2).intersects(&fp))
            || self.door_zones().iter().any(|z| z.intersects(&fp))
        {
            return false;
        }
        let mut state = self
            .drivable
            .take()
            .expect("the plan is checked drivable before it is furnished");
        let keeps = self.keeps_drivable(&mut state, &piece.blocking);
        if self.verify {
            self.verify_against_whole_plan(&state, piece, keeps);
        }
        self.drivable = Some(state);
        if !keeps {
            return false;
        }
        self.blocking.extend(piece.blocking.iter().copied());
        self.taken.push(fp);
        self.boxes.extend(piece.boxes.iter().copied());
        if !self.placed.contains(&piece.kind) {
            self.placed.push(piece.kind);
        }
        true
    }
}

/// One furniture item (or a cubicle cluster) ready to place.
struct Piece {
    kind: &'static str,
    footprint: Rect,
    blocking: Vec<Rect>,
    boxes: Vec<([f64; 3], [f64; 3])>,
}

fn m(c: i32) -> f64 {
    c as f64 * RES
}

fn slab(r: Rect, z0: f64, z1: f64) -> ([f64; 3], [f64; 3]) {
    ([m(r.x0), m(r.y0), z0], [m(r.x1), m(r.y1), z1])
}

/// A solid box from the floor (beds, sofas, pallets, full-height shelves).
fn block(kind: &'static str, r: Rect, height: f64) -> Piece {
    Piece {
        kind,
        footprint: r,
        blocking: vec![r],
        boxes: vec![slab(r, 0.0, height)],
    }
}

/// A table: a top slab at `top` m on four 0.05 m legs (an overhang above the floor).
fn table(r: Rect, top: f64) -> Piece {
    let mut boxes = vec![slab(r, top, top + 0.04)];
    for (lx, ly) in [
        (r.x0 + 1, r.y0 + 1),
        (r.x1 - 2, r.y0 + 1),
        (r.x0 + 1, r.y1 - 2),
        (r.x1 - 2, r.y1 - 2),
    ] {
        boxes.push(slab(
            Rect {
                x0: lx,
                y0: ly,
                x1: lx + 1,
                y1: ly + 1,
            },
            0.0,
            top,
        ));
    }
    Piece {
        kind: "tables",
        footprint: r,
        blocking: vec![r],
        boxes,
    }
}

/// A shelf fixed to the wall between 1.4 and 1.75 m: the robot (1.2 m) passes under it.
fn wall_shelf(r: Rect) -> Piece {
    Piece {
        kind: "wall_shelves",
        footprint: r,
        blocking: vec![],
        boxes: vec![slab(r, 1.4, 1.75)],
    }
}

/// A row of cubicles: a spine partition with side partitions every 2 m on both sides, a desk in
/// every bay; partitions 1.2–1.5 m high, 0.05 m thick.
fn cubicles(x0: i32, y0: i32, bays: i32, height: f64) -> Piece {
    let (bay, depth) = (40, 30); // 2.0 m × 1.5 m
    let spine = Rect {
        x0,
        y0: y0 + depth,
        x1: x0 + bays * bay + 1,
        y1: y0 + depth + 1,
    };
    let mut parts = vec![spine];
    let mut boxes = Vec::new();
    for k in 0..=bays {
        let x = x0 + k * bay;
        parts.push(Rect {
            x0: x,
            y0,
            x1: x + 1,
            y1: y0 + depth,
        });
        parts.push(Rect {
            x0: x,
            y0: y0 + depth + 1,
            x1: x + 1,
            y1: y0 + 2 * depth + 1,
        });
    }
    for &p in &parts {
        boxes.push(slab(p, 0.0, height));
    }
    let mut blocking = parts;
    // Desks span the bay from partition to partition: narrower desks leave 0.25 m slots beside them
    // that the robot can neither enter nor approach.
    for k in 0..bays {
        let x = x0 + k * bay + 1;
        for desk in [
            Rect {
                x0: x,
                y0: y0 + depth - 14,
                x1: x + bay - 1,
                y1: y0 + depth,
            },
            Rect {
                x0: x,
                y0: y0 + depth + 1,
                x1: x + bay - 1,
                y1: y0 + depth + 15,
            },
        ] {
            boxes.extend(table(desk, 0.74).boxes);
            blocking.push(desk);
        }
    }
    let footprint = Rect {
        x0,
        y0,
        x1: x0 + bays * bay + 1,
        y1: y0 + 2 * depth + 1,
    };
    Piece {
        kind: "cubicles",
        footprint,
        blocking,
        boxes,
    }
}

/// A `len × depth` rectangle against a random wall of `room` at a random position along it.
fn against_wall(room: Rect, len: i32, depth: i32, rng: &mut ChaCha8Rng) -> Option<Rect> {
    let side = rng.random_range(0..4);
    let span = if side < 2 { room.w() } else { room.h() };
    if span < len {
        return None;
    }
    let mut off = rng.random_range(0..=span - len);
    // A gap narrower than a drivable passage between the piece and a corner would be a pocket the
    // robot cannot approach: push the piece into the corner instead.
    if off < SNAP_GAP {
        off = 0;
    } else if span - len - off < SNAP_GAP {
        off = span - len;
    }
    Some(match side {
        0 => Rect {
            x0: room.x0 + off,
            y0: room.y0,
            x1: room.x0 + off + len,
            y1: room.y0 + depth,
        },
        1 => Rect {
            x0: room.x0 + off,
            y0: room.y1 - depth,
            x1: room.x0 + off + len,
            y1: room.y1,
        },
        2 => Rect {
            x0: room.x0,
            y0: room.y0 + off,
            x1: room.x0 + depth,
            y1: room.y0 + off + len,
        },
        _ => Rect {
            x0: room.x1 - depth,
            y0: room.y0 + off,
            x1: room.x1,
            y1: room.y0 + off + len,
        },
    })
}

/// A `w × h` rectangle anywhere in `room` at least `gap` cells from its walls.
fn free_standing(room: Rect, w: i32, h: i32, gap: i32, rng: &mut ChaCha8Rng) -> Option<Rect> {
    let inner = room.grow(-gap);
    if inner.w() < w || inner.h() < h {
        return None;
    }
    let x = rng.random_range(inner.x0..=inner.x1 - w);
    let y = rng.random_range(inner.y0..=inner.y1 - h);
    Some(Rect {
        x0: x,
        y0: y,
        x1: x + w,
        y1: y + h,
    })
}

/// The kinds of piece a room may get.
#[derive(Clone, Copy)]
enum Kind {
    Bed,
    Sofa,
    LowBox,
    Table,
    Shelf,
    WallShelf,
}

fn make(kind: Kind, room: Rect, rng: &mut ChaCha8Rng) -> Option<Piece> {
    let c = |m: f64| (m / RES).round() as i32;
    let mut along = |len: f64, depth: f64| against_wall(room, c(len), c(depth), rng);
    Some(match kind {
        Kind::Bed => block("low_boxes", along(2.0, 1.5)?, 0.5),
        Kind::Sofa => block("low_boxes", along(1.9, 0.85)?, 0.8),
        Kind::LowBox => {
            let len = rng.random_range(0.6..1.2);
            let h = rng.random_range(0.4..0.8);
            block("low_boxes", against_wall(room, c(len), c(0.6), rng)?, h)
        }
        Kind::Table => {
            let (w, h) = (rng.random_range(1.2..1.7), rng.random_range(0.75..0.95));
            let top = rng.random_range(0.72..0.76);
            table(free_standing(room, c(w), c(h), c(0.9), rng)?, top)
        }
        Kind::Shelf => {
            let len = rng.random_range(0.8..2.0);
            let h = rng.random_range(1.9..2.2);
            block("full_shelves", against_wall(room, c(len), c(0.4), rng)?, h)
        }
        Kind::WallShelf => wall_shelf(against_wall(
            room,
            c(rng.random_range(1.0..2.0)),
            c(0.3),
            rng,
        )?),
    })
}

/// Furnishes every room according to the style.
fn furnish(
    plan: &mut Plan,
    style: Style,
    rng: &mut ChaCha8Rng,
    progress: &mut dyn FnMut(usize, usize),
) {
    let rooms = plan.rooms.clone();
    progress(0, rooms.len());
    for (i, &room) in rooms.iter().enumerate() {
        let is_hub = plan.hub == Some(i);
        let kinds: Vec<Kind> = match (style, is_hub) {
            (Style::Apartment, _) => {
                let mut k = vec![Kind::WallShelf, Kind::Shelf, Kind::LowBox];
                if room.area_m2() > 14.0 {
                    k.extend([Kind::Sofa, Kind::Table, Kind::LowBox]);
                } else {
                    k.push(Kind::Bed);
                }
                k
            }
            (Style::Office, true) => {
                place_cubicles(plan, room, rng);
                vec![Kind::Shelf, Kind::Shelf, Kind::WallShelf, Kind::LowBox]
            }
            (Style::Office, false) => vec![Kind::Table, Kind::Shelf, Kind::WallShelf, Kind::LowBox],
            (Style::Corridor, true) => vec![Kind::WallShelf, Kind::WallShelf, Kind::LowBox],
            (Style::Corridor, false) => {
                vec![Kind::Table, Kind::Shelf, Kind::WallShelf, Kind::LowBox]
            }
            (Style::Warehouse, true) => {
                place_shelf_rows(plan, room, rng);
                vec![Kind::LowBox, Kind::LowBox, Kind::LowBox, Kind::WallShelf]
            }
            (Style::Warehouse, false) => vec![Kind::Table, Kind::Shelf, Kind::LowBox],
        };
        for kind in kinds {
            for _attempt in 0..12 {
                if let Some(piece) = make(kind, room, rng) {
                    if plan.try_place(room, &piece) {
                        break;
                    }
                }
            }
        }
        progress(i + 1, rooms.len());
    }
}

/// Cubicle rows across the open-plan room, with 1.5 m aisles around them.
fn place_cubicles(plan: &mut Plan, room: Rect, rng: &mut ChaCha8Rng) {
    let aisle = 30;
    let unit_h = 61;
    let mut y = room.y0 + aisle;
    while y + unit_h + aisle <= room.y1 {
        let max_bays = (room.w() - 2 * aisle) / 40;
        if max_bays >= 2 {
            let bays = rng.random_range(2..=max_bays.min(4));
            let height = rng.random_range(1.2..1.5);
            let x = rng.random_range(room.x0 + aisle..=room.x1 - aisle - bays * 40 - 1);
            let piece = cubicles(x, y, bays, height);
            plan.try_place(room, &piece);
        }
        y += unit_h + aisle;
    }
}

/// Rows of back-to-back full-height racks (1 m deep) along the hall's longer side, 3 m aisles (counterbalance forklifts need 3–3.5 m),
/// 2.5 m cross-aisles at both ends.
fn place_shelf_rows(plan: &mut Plan, room: Rect, rng: &mut ChaCha8Rng) {
    let (depth, aisle, end) = (20, 60, 50);
    let along_x = room.w() >= room.h();
    let (len, across) = if along_x {
        (room.w(), room.h())
    } else {
        (room.h(), room.w())
    };
    let row_len = len - 2 * end;
    if row_len < 40 {
        return;
    }
    let mut pos = aisle;
    while pos + depth + aisle <= across {
        let height = rng.random_range(2.0..2.3);
        let r = if along_x {
            Rect {
                x0: room.x0 + end,
                y0: room.y0 + pos,
                x1: room.x1 - end,
                y1: room.y0 + pos + depth,
            }
        } else {
            Rect {
                x0: room.x0 + pos,
                y0: room.y0 + end,
                x1: room.x0 + pos + depth,
                y1: room.y1 - end,
            }
        };
        // Racks are open shelving in reality; a closed block is the conservative obstacle.
        plan.try_place(room, &block("shelf_rows", r, height));
        pos += depth + aisle;
    }
}

/// The generated scenes shipped in `scenes/`: `(name, style, seed, area m²)`.
pub fn shipped_generated() -> Vec<(&'static str, Style, u64, f64)> {
    vec![
        // Seed 3 (shipped before the drivability check) reached only 0.944 completeness with GREEDY
        // once its pocket was gone: its small rooms hide much of the 1.3–1.8 m band from the 0.6 m camera.
        ("apartment_small", Style::Apartment, 17, 60.0),
        ("apartment_loop", Style::Apartment, 11, 120.0),
        ("office_large", Style::Office, 5, 380.0),
        ("corridor_rooms", Style::Corridor, 2, 150.0),
        ("warehouse", Style::Warehouse, 4, 250.0),
        ("office_small", Style::Office, 8, 110.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::scene::ground_truth::SceneTruth;

    #[test]
    fn same_seed_same_mesh_different_seed_differs() {
        for style in Style::ALL {
            let a = generate(style, 1, 80.0).unwrap();
            let b = generate(style, 1, 80.0).unwrap();
            let c = generate(style, 2, 80.0).unwrap();
            assert_eq!(a.mesh, b.mesh, "{style:?}");
            assert_eq!(a.spawn, b.spawn);
            assert_ne!(a.mesh, c.mesh, "{style:?}");
        }
    }

    /// The drivability check made only where a piece changes the plan answers as the whole-plan
    /// check does at every placement, kept or refused, and leaves the same drivable cells; for
    /// every style at several sizes.
    #[test]
    fn piece_by_piece_drivability_agrees_with_the_whole_plan() {
        for style in Style::ALL {
            for (seed, area) in [(3, 60.0), (4, 200.0), (5, 700.0)] {
                build(style, seed, area, &mut |_, _| {}, true).unwrap();
            }
        }
    }

    /// The same on a large office, where the pieces are many and the open-plan room is wide.
    #[test]
    #[ignore = "heavy tier: cargo test -- --ignored"]
    fn piece_by_piece_drivability_agrees_on_a_large_office() {
        build(Style::Office, 1, 2500.0, &mut |_, _| {}, true).unwrap();
    }

    #[test]
    fn office_has_every_furniture_height() {
        let g = generate(Style::Office, 5, 380.0).unwrap();
        for f in [
            "cubicles",
            "tables",
            "wall_shelves",
            "low_boxes",
            "full_shelves",
            "loop",
        ] {
            assert!(
                g.features.iter().any(|x| x == f),
                "missing {f}: {:?}",
                g.features
            );
        }
        // Heights of horizontal faces: table tops, wall-shelf undersides, partition tops.
        let flat_z: Vec<f32> = g
            .mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| g.mesh.vertices[i as usize].z))
            .filter(|z| z[0] == z[1] && z[1] == z[2])
            .map(|z| z[0])
            .collect();
        let has = |lo: f32, hi: f32| flat_z.iter().any(|&z| z >= lo && z <= hi);
        assert!(has(0.72, 0.76), "table undersides");
        assert!(has(1.4, 1.4), "wall shelf undersides above 1.3 m");
        assert!(has(1.2, 1.5), "cubicle partitions");
        assert!(has(2.5, 2.5) && has(0.0, 0.0), "walls and floor");
    }

    #[test]
    fn area_is_respected_and_checked() {
        for style in Style::ALL {
            for area in [25.0, 150.0, 600.0] {
                let g = generate(style, 9, area).unwrap();
                let (min, max) = g.mesh.bounds().unwrap();
                let footprint = (max.x - min.x) * (max.y - min.y);
                assert!(
                    (footprint / area - 1.0).abs() < 0.15,
                    "{style:?} {area}: {footprint}"
                );
            }
        }
        assert_eq!(
            generate(Style::Office, 1, 10.0).unwrap_err().to_string(),
            "scene area 10 m² is outside [20, 40000] m²"
        );
        assert_eq!(
            generate(Style::Office, 1, 40_001.0)
                .unwrap_err()
                .to_string(),
            "scene area 40001 m² is outside [20, 40000] m²"
        );
        assert_eq!(
            Style::parse("castle").unwrap_err().to_string(),
            "unknown scene style `castle` (expected apartment, office, corridor or warehouse)"
        );
    }

    #[test]
    fn every_room_is_in_the_explorable_region() {
        let cfg = Config::default();
        for (i, style) in Style::ALL.into_iter().enumerate() {
            let g = generate(style, 20 + i as u64, 140.0).unwrap();
            let gt = SceneTruth::build(&g.mesh, Some(g.spawn), &cfg).unwrap();
            assert!(g.rooms.len() >= 2, "{style:?}");
            assert!(g.doors >= g.rooms.len() - 1);
            assert!(
                g.loops >= 1 && g.features.contains(&"loop".to_string()),
                "{style:?}"
            );
            for r in &g.rooms {
                let centre_row = (r[1] + r[3]) / 2.0;
                let reached = (0..100).any(|k| {
                    let x = r[0] + (r[2] - r[0]) * (k as f64 + 0.5) / 100.0;
                    let c = gt
                        .grid
                        .cell_of(nalgebra::Point2::new(x, centre_row))
                        .unwrap();
                    gt.in_region(gt.grid.index(c))
                });
                assert!(reached, "{style:?} room {r:?}");
            }
            let c = gt.grid.index(gt.grid.cell_of(g.spawn.position()).unwrap());
            assert!(gt.clearance_m(c) >= 0.5, "{style:?}");
        }
    }

    /// Independent check of the generator's drivability guarantee on the ground truth (0.1 m cells,
    /// voxelised mesh): `(drivable components, largest geodesic distance in metres from a free region
    /// cell to the nearest drivable cell)`. Drivable: free with clearance ≥ `drive_m`. The distance
    /// runs through free cells only (8-connected chamfer 10/14, no corner cutting), so a cell behind
    /// a wall is never "near".
    fn drivability(gt: &SceneTruth, drive_m: f32) -> (usize, f64) {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        let g = gt.grid;
        let n = g.cells();
        let free_cells: Vec<bool> = (0..n)
            .map(|c| gt.in_region(c) && !gt.obstacle_column(c))
            .collect();
        let free = &free_cells;
        let drivable: Vec<bool> = (0..n)
            .map(|c| free[c] && gt.clearance_m(c) >= drive_m)
            .collect();
        let neighbours = |i: usize| {
            let c = g.cell(i);
            crate::grid::NEIGHBOURS_8
                .iter()
                .filter_map(move |&(dx, dy)| {
                    let j = g.checked_index(crate::grid::Cell::new(c.x + dx, c.y + dy))?;
                    let corner_ok = dx == 0
                        || dy == 0
                        || [(dx, 0), (0, dy)].iter().all(|&(ex, ey)| {
                            g.checked_index(crate::grid::Cell::new(c.x + ex, c.y + ey))
                                .is_some_and(|k| free[k])
                        });
                    corner_ok.then_some((j, if dx == 0 || dy == 0 { 10u64 } else { 14 }))
                })
        };
        let mut label = vec![false; n];
        let mut components = 0;
        for s in 0..n {
            if !drivable[s] || label[s] {
                continue;
            }
            components += 1;
            label[s] = true;
            let mut stack = vec![s];
            while let Some(i) = stack.pop() {
                for (j, step) in neighbours(i) {
                    if step == 10 && drivable[j] && !label[j] {
                        label[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        let mut dist = vec![u64::MAX; n];
        let mut heap: BinaryHeap<Reverse<(u64, usize)>> = (0..n)
            .filter(|&i| drivable[i])
            .map(|i| Reverse((0, i)))
            .collect();
        for i in (0..n).filter(|&i| drivable[i]) {
            dist[i] = 0;
        }
        while let Some(Reverse((d, i))) = heap.pop() {
            if d > dist[i] {
                continue;
            }
            for (j, step) in neighbours(i) {
                if free[j] && d + step < dist[j] {
                    dist[j] = d + step;
                    heap.push(Reverse((d + step, j)));
                }
            }
        }
        let worst = (0..n)
            .filter(|&i| free[i])
            .map(|i| dist[i])
            .max()
            .unwrap_or(0);
        (components, worst as f64 / 10.0 * g.res)
    }

    /// Property (a)/(b) of the generator, re-measured on the voxelised mesh: on every shipped
    /// generated scene and on a batch of seeds per style, the space where the robot fits with
    /// 0.4 m clearance (the 0.05 m raster guarantees 0.45 m; 0.1 m voxels can eat one half cell) is
    /// one piece, and every free floor cell of the explorable region is within 0.7 m of it (the
    /// raster guarantees 0.6 m).
    #[test]
    fn generated_scenes_are_drivable_everywhere() {
        let cfg = Config::default();
        let mut cases: Vec<(String, Style, u64, f64)> = shipped_generated()
            .into_iter()
            .map(|(name, style, seed, area)| (name.to_string(), style, seed, area))
            .collect();
        for style in Style::ALL {
            for (k, area) in [40.0, 90.0, 160.0, 300.0].into_iter().enumerate() {
                let seed = 100 + k as u64;
                cases.push((format!("{} seed {seed}", style.name()), style, seed, area));
            }
        }
        for (name, style, seed, area) in cases {
            let g = generate(style, seed, area).unwrap();
            let gt = SceneTruth::build(&g.mesh, Some(g.spawn), &cfg).unwrap();
            let (components, worst) = drivability(&gt, 0.4);
            eprintln!(
                "{name}: {components} drivable component(s), farthest free cell {worst:.2} m"
            );
            assert_eq!(components, 1, "{name}");
            assert!(
                worst <= 0.7,
                "{name}: a free cell {worst:.2} m from the drivable space"
            );
        }
    }

    /// The check above does catch a pocket: a bed and a box 0.3 m apart against one wall.
    #[test]
    fn drivability_check_finds_a_pocket() {
        let cfg = Config::default();
        let mut mesh = TriMesh::default();
        for (min, max) in [
            ([0.0, 0.0, 0.0], [5.0, 0.1, 2.5]),
            ([0.0, 3.9, 0.0], [5.0, 4.0, 2.5]),
            ([0.0, 0.0, 0.0], [0.1, 4.0, 2.5]),
            ([4.9, 0.0, 0.0], [5.0, 4.0, 2.5]),
            ([1.0, 0.1, 0.0], [3.0, 1.6, 0.5]),
            ([3.3, 0.1, 0.0], [4.0, 0.7, 0.6]),
        ] {
            mesh.push_box(min, max);
        }
        let gt = SceneTruth::build(&mesh, Some(Pose2::new(2.5, 2.8, 0.0)), &cfg).unwrap();
        let (components, worst) = drivability(&gt, 0.4);
        assert_eq!(components, 1);
        assert!(worst > 0.7, "{worst}");
    }
}
