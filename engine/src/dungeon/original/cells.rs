//! The original's free-cell bookkeeping: each real room keeps the cells an object may take
//! and the cells a character may take (a `FenwickSet` of room-local indices there), and a
//! pick is the n-th remaining cell in row order, n drawn as a `usize`.

use crate::rng::xorshift::XorShift128;

/// A set of floor cells, kept in row order (the order of the original's room-local indices).
#[derive(Debug, Clone, Default)]
pub(super) struct CellSet(Vec<usize>);

impl CellSet {
    /// A set of `cells`, given in row order.
    pub(super) fn from_sorted(cells: Vec<usize>) -> Self {
        debug_assert!(cells.windows(2).all(|w| w[0] < w[1]));
        CellSet(cells)
    }

    /// A uniform cell of the set (one `usize` draw), or `None` without a draw when empty.
    pub(super) fn pick(&self, rng: &mut XorShift128) -> Option<usize> {
        (!self.0.is_empty()).then(|| self.0[rng.below_usize(self.0.len())])
    }

    /// Takes `cell` out of the set, if it is there.
    pub(super) fn remove(&mut self, cell: usize) {
        if let Ok(k) = self.0.binary_search(&cell) {
            self.0.remove(k);
        }
    }
}

/// Who a cell is picked for: an object (gold, stairs) or a character (the player).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Occupant {
    /// Gold, stairs, the amulet: the cell must hold no object.
    Object,
    /// The player: the cell must hold no character (objects are allowed).
    Character,
}

/// The free cells of every room slot; gone rooms have none and are never candidates.
#[derive(Debug, Clone, Default)]
pub(super) struct FreeCells {
    /// Per slot: (free of objects, free of characters); `None` for a gone room.
    rooms: Vec<Option<(CellSet, CellSet)>>,
}

impl FreeCells {
    /// Adds the next slot's room with its initial `cells` (row order), or a gone room.
    pub(super) fn push(&mut self, cells: Option<Vec<usize>>) {
        self.rooms.push(cells.map(|c| {
            let set = CellSet::from_sorted(c);
            (set.clone(), set)
        }));
    }

    fn set(&self, room: usize, who: Occupant) -> Option<&CellSet> {
        let (objects, characters) = self.rooms[room].as_ref()?;
        Some(match who {
            Occupant::Object => objects,
            Occupant::Character => characters,
        })
    }

    /// A cell of room `room` (no draw for a gone or full room).
    pub(super) fn pick_in_room(
        &self,
        room: usize,
        who: Occupant,
        rng: &mut XorShift128,
    ) -> Option<usize> {
        self.set(room, who)?.pick(rng)
    }

    /// The original's `Floor::select_cell`: a uniform real room, then a uniform free cell in
    /// it; a full room is dropped from the candidates and the pick is redrawn.
    pub(super) fn pick(&self, who: Occupant, rng: &mut XorShift128) -> Option<usize> {
        let mut candidates: Vec<usize> = (0..self.rooms.len())
            .filter(|&r| self.rooms[r].is_some())
            .collect();
        while !candidates.is_empty() {
            let k = rng.below_usize(candidates.len());
            match self.pick_in_room(candidates[k], who, rng) {
                Some(cell) => return Some(cell),
                None => {
                    candidates.remove(k);
                }
            }
        }
        None
    }

    /// Marks `cell` of room `room` as holding an object (a character also fills it for
    /// characters).
    pub(super) fn fill(&mut self, room: usize, cell: usize, who: Occupant) {
        if let Some((objects, characters)) = self.rooms[room].as_mut() {
            objects.remove(cell);
            if who == Occupant::Character {
                characters.remove(cell);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn picks_follow_row_order_and_skip_full_rooms() {
        let mut cells = FreeCells::default();
        cells.push(None);
        cells.push(Some(vec![3, 5, 9]));
        cells.push(Some(vec![]));
        let mut rng = XorShift128::from_seed(99);
        let mut replay = rng.clone();
        let cell = cells.pick_in_room(1, Occupant::Object, &mut rng).unwrap();
        assert_eq!(cell, [3, 5, 9][replay.below_usize(3)]);
        // Gone and full rooms cost no draw.
        assert_eq!(cells.pick_in_room(0, Occupant::Object, &mut rng), None);
        assert_eq!(cells.pick_in_room(2, Occupant::Object, &mut rng), None);
        assert_eq!(rng.next_u32(), replay.next_u32());
        // Objects leave the cell to characters.
        cells.fill(1, 3, Occupant::Object);
        cells.fill(1, 5, Occupant::Object);
        cells.fill(1, 9, Occupant::Object);
        assert_eq!(cells.pick(Occupant::Object, &mut rng), None);
        assert!(cells.pick(Occupant::Character, &mut rng).is_some());
    }
}
