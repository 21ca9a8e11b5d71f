//! A board model stricter than the hardware (as embedded-graphics' mock display is stricter than
//! a display): static memory is declared to it and checked against the RAM budget before
//! anything runs, peak use is tracked while it runs, and a tick entered while another is running
//! is refused instead of silently corrupting the state.

use core::cell::Cell;

/// What the board offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardSpec {
    pub ram_bytes: usize,
    /// RAM kept for the stack: statics may use at most `ram_bytes - stack_bytes`.
    pub stack_bytes: usize,
}

/// A Cortex-M4F of the target: 64 KiB of RAM, 8 KiB of it for the stack.
pub const TARGET_BOARD: BoardSpec = BoardSpec {
    ram_bytes: 64 * 1024,
    stack_bytes: 8 * 1024,
};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardError {
    /// The statics declared so far do not fit beside the stack.
    OverBudget {
        name: &'static str,
        statics: usize,
        available: usize,
    },
    /// A tick was entered while another was running (an interrupt handler calling into the
    /// mapper, say): the state has one owner.
    Reentered,
    /// More statics than the board's table holds.
    TooManyStatics,
}

impl core::fmt::Display for BoardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::OverBudget {
                name,
                statics,
                available,
            } => write!(
                f,
                "static {name} brings statics to {statics} bytes, over the {available} bytes left beside the stack"
            ),
            Self::Reentered => write!(f, "a tick was entered while another was running"),
            Self::TooManyStatics => write!(f, "more statics than the board model tracks"),
        }
    }
}

impl core::error::Error for BoardError {}

/// The board: declared statics, peaks, and the re-entry guard.
#[derive(Debug)]
pub struct Board {
    spec: BoardSpec,
    statics: heapless::Vec<(&'static str, usize), 8>,
    in_tick: Cell<bool>,
    ticks: Cell<u64>,
    peak_pending: Cell<usize>,
    peak_clusters: Cell<usize>,
}

impl Board {
    pub const fn new(spec: BoardSpec) -> Self {
        Self {
            spec,
            statics: heapless::Vec::new(),
            in_tick: Cell::new(false),
            ticks: Cell::new(0),
            peak_pending: Cell::new(0),
            peak_clusters: Cell::new(0),
        }
    }

    pub fn spec(&self) -> BoardSpec {
        self.spec
    }

    /// Declares a static of type `T`; refused if the statics no longer fit beside the stack.
    pub fn declare<T>(&mut self, name: &'static str) -> Result<(), BoardError> {
        let statics = self.static_bytes() + core::mem::size_of::<T>();
        let available = self.spec.ram_bytes.saturating_sub(self.spec.stack_bytes);
        if statics > available {
            return Err(BoardError::OverBudget {
                name,
                statics,
                available,
            });
        }
        self.statics
            .push((name, core::mem::size_of::<T>()))
            .map_err(|_| BoardError::TooManyStatics)
    }

    pub fn static_bytes(&self) -> usize {
        self.statics.iter().map(|&(_, b)| b).sum()
    }

    pub fn statics(&self) -> &[(&'static str, usize)] {
        &self.statics
    }

    /// Runs one tick; refused if called from inside another.
    pub fn tick<R>(&self, f: impl FnOnce() -> R) -> Result<R, BoardError> {
        if self.in_tick.replace(true) {
            return Err(BoardError::Reentered);
        }
        let r = f();
        self.in_tick.set(false);
        self.ticks.set(self.ticks.get() + 1);
        Ok(r)
    }

    /// Records what the firmware holds after a delivery or a tick.
    pub fn observe(&self, pending_bytes: usize, clusters: usize) {
        self.peak_pending
            .set(self.peak_pending.get().max(pending_bytes));
        self.peak_clusters
            .set(self.peak_clusters.get().max(clusters));
    }

    pub fn ticks(&self) -> u64 {
        self.ticks.get()
    }

    pub fn peak_pending(&self) -> usize {
        self.peak_pending.get()
    }

    pub fn peak_clusters(&self) -> usize {
        self.peak_clusters.get()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statics_over_budget_are_refused() {
        let mut board = Board::new(BoardSpec {
            ram_bytes: 4096,
            stack_bytes: 1024,
        });
        assert_eq!(board.declare::<[u8; 2000]>("a"), Ok(()));
        assert_eq!(
            board.declare::<[u8; 1500]>("b"),
            Err(BoardError::OverBudget {
                name: "b",
                statics: 3500,
                available: 3072
            })
        );
        assert_eq!(board.static_bytes(), 2000);
    }

    #[test]
    fn a_tick_inside_a_tick_is_refused() {
        let board = Board::new(TARGET_BOARD);
        let inner = board.tick(|| board.tick(|| 1));
        assert_eq!(inner, Ok(Err(BoardError::Reentered)));
        // The guard is released: the next tick runs.
        assert_eq!(board.tick(|| 2), Ok(2));
        assert_eq!(board.ticks(), 2);
    }
}
