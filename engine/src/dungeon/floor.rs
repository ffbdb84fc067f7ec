//! One generated floor: flat per-cell grids indexed `y * width + x`, plus its rooms.

use crate::geometry::Rect;

/// What a cell is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum Surface {
    /// Rock (or a not-yet-found hidden passage).
    #[default]
    Nothing,
    /// Room floor `.`.
    Floor,
    /// Passage `#`.
    Passage,
    /// Horizontal wall `-` (top and bottom rows, corners included); also a secret door.
    WallH,
    /// Vertical wall `|`; also a secret door.
    WallV,
    /// Door `+`.
    Door,
    /// Down stairs `%`.
    Stair,
}

impl Surface {
    /// Can a creature stand here?
    #[inline]
    pub fn walkable(self) -> bool {
        matches!(
            self,
            Surface::Floor | Surface::Passage | Surface::Door | Surface::Stair
        )
    }

    /// The ASCII tile.
    #[inline]
    pub fn tile(self) -> u8 {
        match self {
            Surface::Nothing => b' ',
            Surface::Floor => b'.',
            Surface::Passage => b'#',
            Surface::WallH => b'-',
            Surface::WallV => b'|',
            Surface::Door => b'+',
            Surface::Stair => b'%',
        }
    }
}

/// Per-cell flag bits.
pub mod flag {
    /// Shown now.
    pub const VISIBLE: u8 = 1;
    /// Seen before (objects on it are drawn).
    pub const DRAWN: u8 = 2;
    /// A hidden passage (surface stays `Nothing` until found).
    pub const HIDDEN: u8 = 4;
    /// A secret door (surface stays a wall until found).
    pub const LOCKED: u8 = 8;
    /// Floor of a dark room.
    pub const DARK: u8 = 16;
    /// A door position (secret or not).
    pub const DOOR: u8 = 32;
    /// Already registered by the passage digger (never re-rolled: no re-hiding).
    pub const REGISTERED: u8 = 64;
}

/// The kind of a room slot's content.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoomKind {
    /// A "gone" room: a single junction point.
    Gone,
    /// A rectangular room with walls.
    Normal,
    /// A maze filling the slot (always dark).
    Maze,
}

/// One room slot and what it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Room {
    /// Kind.
    pub kind: RoomKind,
    /// The slot (assigned area).
    pub slot: Rect,
    /// The room rectangle (walls included); the maze rectangle; a 1x1 rect at the junction.
    pub rect: Rect,
    /// Dark room (floor seen only around the player).
    pub dark: bool,
    /// Entered at least once.
    pub visited: bool,
    /// Got a gold pile.
    pub has_gold: bool,
}

impl Room {
    /// A room not yet visited and without gold.
    pub fn new(kind: RoomKind, slot: Rect, rect: Rect, dark: bool) -> Self {
        Room {
            kind,
            slot,
            rect,
            dark,
            visited: false,
            has_gold: false,
        }
    }

    /// Does a creature entering by a door light this room up?
    pub fn is_lit_normal(&self) -> bool {
        self.kind == RoomKind::Normal && !self.dark
    }
}

/// A floor: the dungeon area and what lies on it.
#[derive(Debug, Clone, Default)]
pub struct Floor {
    /// Width.
    pub w: i32,
    /// Height.
    pub h: i32,
    /// Surface per cell.
    pub surface: Vec<Surface>,
    /// Flag bits per cell ([`flag`]).
    pub flags: Vec<u8>,
    /// 1 where the player stood on this floor (history plane).
    pub visited: Vec<u8>,
    /// Gold amount per cell (0 = none).
    pub gold: Vec<u32>,
    /// The amulet's cell, if on this floor.
    pub amulet: Option<usize>,
    /// Per cell: `slot * 2 + (inside the room rect)`, or `u16::MAX` outside every slot.
    pub zone: Vec<u16>,
    /// Slot id per cell, or `u8::MAX` outside every slot.
    pub slot_of: Vec<u8>,
    /// Rooms in slot order.
    pub rooms: Vec<Room>,
    /// The stairs cell.
    pub stairs: usize,
}

impl Floor {
    /// Resets all grids to an empty `w` x `h` floor, reusing the allocations.
    pub fn clear(&mut self, w: i32, h: i32) {
        let n = (w * h) as usize;
        self.w = w;
        self.h = h;
        for v in [&mut self.flags, &mut self.visited] {
            v.clear();
            v.resize(n, 0);
        }
        self.surface.clear();
        self.surface.resize(n, Surface::Nothing);
        self.gold.clear();
        self.gold.resize(n, 0);
        self.zone.clear();
        self.zone.resize(n, u16::MAX);
        self.slot_of.clear();
        self.slot_of.resize(n, u8::MAX);
        self.rooms.clear();
        self.amulet = None;
        self.stairs = 0;
    }

    /// Index of `(x, y)`; the caller guarantees it is on the screen.
    #[inline]
    pub fn idx(&self, x: i32, y: i32) -> usize {
        (y * self.w + x) as usize
    }

    /// `(x, y)` of an index.
    #[inline]
    pub fn xy(&self, i: usize) -> (i32, i32) {
        (i as i32 % self.w, i as i32 / self.w)
    }

    /// Is `(x, y)` inside the dungeon area (rows 1..h-2)?
    #[inline]
    pub fn in_area(&self, x: i32, y: i32) -> bool {
        x >= 0 && x < self.w && y >= 1 && y < self.h - 1
    }

    /// Walkable if every hidden feature were found (for generation checks).
    #[cfg_attr(not(test), allow(dead_code))]
    pub fn walkable_unhidden(&self, i: usize) -> bool {
        self.surface[i].walkable() || self.flags[i] & (flag::HIDDEN | flag::LOCKED) != 0
    }

    /// The room whose slot holds cell `i`.
    pub fn room_at(&self, i: usize) -> Option<usize> {
        let s = self.slot_of[i];
        (s != u8::MAX).then_some(s as usize)
    }

    /// Is cell `i` free for an object: walkable, no gold, no stairs, no amulet?
    pub fn is_empty_cell(&self, i: usize) -> bool {
        matches!(self.surface[i], Surface::Floor | Surface::Passage)
            && self.gold[i] == 0
            && self.amulet != Some(i)
    }
}
