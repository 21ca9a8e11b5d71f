//! Marks on the frozen slots, kept beside the frozen entities they describe: each slot's count
//! of scans in a row that saw through its entity ([`super::carve`]), and whether the slot holds
//! another entity than the one a downlink last sent from it.
//!
//! Why in the mapper and not in the carver: a slot's entity changes wherever the frozen store
//! changes (a carving removes one, [`super::coarsen`] merges two), and a mark must move with
//! its entity every time, or a downlink sends a stale entity and a count carves the wrong one.

/// A slot's byte: its count in the low bits, and this bit once the slot holds another entity
/// than the one the downlink last sent from it.
const CHANGED: u8 = 0x80;

/// The marks of `F` frozen slots.
#[derive(Clone, Debug)]
pub(super) struct SlotMarks<const F: usize> {
    marks: [u8; F],
    /// Whether any slot may be marked changed: a downlink's look costs nothing until one is.
    changed: bool,
}

impl<const F: usize> SlotMarks<F> {
    pub(super) const fn new() -> Self {
        Self {
            marks: [0; F],
            changed: false,
        }
    }

    pub(super) fn clear(&mut self) {
        *self = Self::new();
    }

    /// Slot `i`'s count of scans that saw through its entity (0 past the store).
    pub(super) fn count(&self, i: usize) -> u8 {
        self.marks.get(i).map_or(0, |m| m & !CHANGED)
    }

    /// Sets slot `i`'s count, keeping its changed mark.
    pub(super) fn set_count(&mut self, i: usize, count: u8) {
        if let Some(m) = self.marks.get_mut(i) {
            *m = (*m & CHANGED) | (count & !CHANGED);
        }
    }

    /// Slot `i` holds a new entity: no count, and changed.
    pub(super) fn replaced(&mut self, i: usize) {
        if let Some(m) = self.marks.get_mut(i) {
            *m = CHANGED;
            self.changed = true;
        }
    }

    /// The store's swap-remove of slot `index`, whose last slot was `last`: the last entity's
    /// count moves into `index`, marked changed, and the vacated last slot is marked too (an
    /// entity that freezes into it before the downlink looks again is new to a host that holds
    /// the slot's old one).
    pub(super) fn swap_removed(&mut self, index: usize, last: usize) {
        let moved = self.marks.get(last).copied().unwrap_or(0);
        if let Some(vacated) = self.marks.get_mut(last) {
            *vacated = CHANGED;
        }
        if index < last
            && let Some(slot) = self.marks.get_mut(index)
        {
            *slot = moved | CHANGED;
        }
        self.changed = true;
    }

    /// The lowest slot below `below` marked changed, its mark taken.
    pub(super) fn take_changed(&mut self, below: usize) -> Option<usize> {
        if !self.changed {
            return None;
        }
        let end = below.min(F);
        let found = self.marks.get(..end)?.iter().position(|s| s & CHANGED != 0);
        match found {
            Some(i) => {
                if let Some(slot) = self.marks.get_mut(i) {
                    *slot &= !CHANGED;
                }
                Some(i)
            }
            None => {
                // Marks at or past `below` are slots the downlink has not sent: sent whole
                // when it does, so their marks go.
                for slot in self.marks.iter_mut() {
                    *slot &= !CHANGED;
                }
                self.changed = false;
                None
            }
        }
    }
}
