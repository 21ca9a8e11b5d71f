//! Marks on the frozen slots, kept beside the frozen entities they describe: each slot's count
//! of scans in a row that saw through its entity ([`super::carve`]), whether the slot holds
//! another entity than the one a downlink last sent from it, and whether it changed since the
//! coarsening's last scan ([`super::coarsen`]).
//!
//! Why in the mapper and not in the carver: a slot's entity changes wherever the frozen store
//! changes (a carving removes one, [`super::coarsen`] merges two), and a mark must move with
//! its entity every time, or a downlink sends a stale entity and a count carves the wrong one.

/// A slot's byte: its count in the low bits, and this bit once the slot holds another entity
/// than the one the downlink last sent from it.
const CHANGED: u8 = 0x80;

/// This bit once the slot's entity changed since the coarsening's last scan, whose listed pairs
/// name slots as they were then (a bit a slot, where a list of changed slots would bound the
/// merges a scan can give).
const TOUCHED: u8 = 0x40;

/// The count's bits: [`super::carve::SEEN_THROUGH`] is far below them.
const COUNT: u8 = !(CHANGED | TOUCHED);

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
        self.marks.get(i).map_or(0, |m| m & COUNT)
    }

    /// Sets slot `i`'s count, keeping its other marks.
    pub(super) fn set_count(&mut self, i: usize, count: u8) {
        if let Some(m) = self.marks.get_mut(i) {
            *m = (*m & !COUNT) | (count & COUNT);
        }
    }

    /// Slot `i` changed since the coarsening's last scan.
    pub(super) fn touch(&mut self, i: usize) {
        if let Some(m) = self.marks.get_mut(i) {
            *m |= TOUCHED;
        }
    }

    /// Whether slot `i` changed since the coarsening's last scan.
    pub(super) fn touched(&self, i: usize) -> bool {
        self.marks.get(i).is_some_and(|m| m & TOUCHED != 0)
    }

    /// A new scan: no slot has changed since.
    pub(super) fn untouch_all(&mut self) {
        for m in self.marks.iter_mut() {
            *m &= !TOUCHED;
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
