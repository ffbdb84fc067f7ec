//! Directions and rectangles on the screen grid (x = column, y = row, Up = y-1).

/// The 8 directions in the original's order (which fixes search and chase order).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[allow(missing_docs)]
pub enum Dir {
    Up,
    Down,
    Left,
    Right,
    LeftUp,
    RightUp,
    LeftDown,
    RightDown,
}

impl Dir {
    /// All 8, in order.
    pub const ALL: [Dir; 8] = [
        Dir::Up,
        Dir::Down,
        Dir::Left,
        Dir::Right,
        Dir::LeftUp,
        Dir::RightUp,
        Dir::LeftDown,
        Dir::RightDown,
    ];

    /// `(dx, dy)`.
    pub fn delta(self) -> (i32, i32) {
        match self {
            Dir::Up => (0, -1),
            Dir::Down => (0, 1),
            Dir::Left => (-1, 0),
            Dir::Right => (1, 0),
            Dir::LeftUp => (-1, -1),
            Dir::RightUp => (1, -1),
            Dir::LeftDown => (-1, 1),
            Dir::RightDown => (1, 1),
        }
    }

    /// True for the 4 diagonal directions.
    pub fn is_diagonal(self) -> bool {
        let (dx, dy) = self.delta();
        dx != 0 && dy != 0
    }
}

/// A half-open rectangle `[x0, x1) x [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Rect {
    /// Left column.
    pub x0: i32,
    /// Top row.
    pub y0: i32,
    /// One past the right column.
    pub x1: i32,
    /// One past the bottom row.
    pub y1: i32,
}

impl Rect {
    /// Does it contain `(x, y)`?
    pub fn contains(&self, x: i32, y: i32) -> bool {
        x >= self.x0 && x < self.x1 && y >= self.y0 && y < self.y1
    }

    /// Is `(x, y)` on its border?
    pub fn on_edge(&self, x: i32, y: i32) -> bool {
        self.contains(x, y)
            && (x == self.x0 || x == self.x1 - 1 || y == self.y0 || y == self.y1 - 1)
    }

    /// Width.
    pub fn w(&self) -> i32 {
        self.x1 - self.x0
    }

    /// Height.
    pub fn h(&self) -> i32 {
        self.y1 - self.y0
    }
}
