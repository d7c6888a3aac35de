//! Two rooms joined by one door: the fixture that holds the map and the ground truth to one
//! definition of passable (see `eval::reachable`). A test sweeps the door's width across the robot's
//! inflated diameter and its jambs across every offset within a cell, for each kind of door, and
//! checks that every planner either passes a door the ground truth calls passable or ends the run
//! rightly `complete` before one it does not.

use super::TriMesh;
use crate::Pose2;
use nalgebra::Point2;

/// The shape of the opening between the two rooms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DoorKind {
    /// A gap in a 0.1 m wall.
    Thin,
    /// A gap in a 0.3 m wall: a doorway with depth.
    Thick,
    /// A 1 m long passage as wide as the door.
    Corridor,
    /// A gap in a 0.1 m wall whose jambs each carry a 0.4 m stub into the first room, so that each
    /// jamb is an L seen end-on from the first room.
    LJamb,
}

impl DoorKind {
    pub const ALL: [DoorKind; 4] = [
        DoorKind::Thin,
        DoorKind::Thick,
        DoorKind::Corridor,
        DoorKind::LJamb,
    ];

    pub fn name(self) -> &'static str {
        match self {
            DoorKind::Thin => "thin",
            DoorKind::Thick => "thick",
            DoorKind::Corridor => "corridor",
            DoorKind::LJamb => "l-jamb",
        }
    }

    /// Depth of the wall between the rooms, metres.
    fn depth(self) -> f64 {
        match self {
            DoorKind::Thin | DoorKind::LJamb => 0.1,
            DoorKind::Thick => 0.3,
            DoorKind::Corridor => 1.0,
        }
    }
}

/// A doorway scene: the mesh, a start in the first room facing the door, a point in the middle of
/// the second room, and the x where the second room begins (the far side of the wall between).
#[derive(Clone, Debug)]
pub struct Doorway {
    pub mesh: TriMesh,
    pub spawn: Pose2,
    pub far_room: Point2<f64>,
    pub far_room_x0: f64,
}

/// Inside size of each room, metres.
const ROOM: f64 = 3.0;
/// Wall thickness and height, metres.
const WALL: f64 = 0.1;
const HEIGHT: f64 = 2.5;
/// Where the door's lower jamb lies (before `offset`), metres.
const DOOR_Y: f64 = 1.2;

/// Two `ROOM`-square rooms side by side along x, joined by one door of `width` metres whose lower
/// jamb lies at y = 1.2 + `offset` (an offset within a 0.1 m cell moves the jambs across the map's
/// cells).
pub fn doorway(kind: DoorKind, width: f64, offset: f64) -> Doorway {
    let depth = kind.depth();
    let (a0, a1) = (WALL, WALL + ROOM);
    let (b0, b1) = (a1 + depth, a1 + depth + ROOM);
    let (y0, y1) = (WALL, WALL + ROOM);
    let (door0, door1) = (y0 + DOOR_Y + offset, y0 + DOOR_Y + offset + width);
    let mut mesh = TriMesh::default();
    // Floor, then the outer walls.
    mesh.push_box([0.0, 0.0, 0.0], [b1 + WALL, y1 + WALL, 0.0]);
    mesh.push_box([0.0, 0.0, 0.0], [b1 + WALL, y0, HEIGHT]);
    mesh.push_box([0.0, y1, 0.0], [b1 + WALL, y1 + WALL, HEIGHT]);
    mesh.push_box([0.0, y0, 0.0], [a0, y1, HEIGHT]);
    mesh.push_box([b1, y0, 0.0], [b1 + WALL, y1, HEIGHT]);
    // The wall between the rooms, open over [door0, door1].
    mesh.push_box([a1, y0, 0.0], [b0, door0, HEIGHT]);
    mesh.push_box([a1, door1, 0.0], [b0, y1, HEIGHT]);
    if kind == DoorKind::LJamb {
        mesh.push_box([a1 - 0.4, door0 - WALL, 0.0], [a1, door0, HEIGHT]);
        mesh.push_box([a1 - 0.4, door1, 0.0], [a1, door1 + WALL, HEIGHT]);
    }
    Doorway {
        mesh,
        spawn: Pose2::new(a0 + 1.0, y0 + 0.6, 0.6),
        far_room: Point2::new(0.5 * (b0 + b1), 0.5 * (y0 + y1)),
        far_room_x0: b0,
    }
}
