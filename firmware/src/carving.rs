//! What a device carves with (issue 29): nothing (`()`: the 64 KiB image has no room for a
//! scan's range image), or the core's [`Carver`] in memory of its own (the STM32F405 board's
//! 64 KiB of core-coupled RAM). The firmware drives it as the host's `replay` drives its
//! carver, so the map is the same bytes; only the judgement of an ended scan is spread over
//! ticks ([`JUDGED_PER_TICK`]).

use mema_core::Point3;
use mema_core::stream::{Carver, StreamMapper};

/// Working clusters an ended scan's judgement takes in one tick: a judgement (moments to
/// covariance, its eigenvectors, five pixels) is about a refit's hundredth, so a tick stays
/// shorter than one that fits.
pub const JUDGED_PER_TICK: usize = 8;

/// A device's carving: [`Carver`]'s steps as the firmware's tick takes them.
pub trait Carving {
    /// Before a frame's points, seen from `sensor`: true once they may be mapped; false while
    /// the scan that ended is judged (the tick ends; the next one steps again).
    fn step<const K: usize, const G: usize, const F: usize>(
        &mut self,
        sensor: Point3,
        mapper: &mut StreamMapper<K, G, F>,
    ) -> bool;

    /// A return of the current scan, as the mapper took it.
    fn add_return(&mut self, p: Point3);

    /// The stream ended: the last scan is judged (all of it, in the finishing tick).
    fn end<const K: usize, const G: usize, const F: usize>(
        &mut self,
        mapper: &mut StreamMapper<K, G, F>,
    );

    /// The map started again, or RAM was lost: the scan under way is forgotten uncarved.
    fn restart(&mut self);
}

/// No carving.
impl Carving for () {
    fn step<const K: usize, const G: usize, const F: usize>(
        &mut self,
        _: Point3,
        _: &mut StreamMapper<K, G, F>,
    ) -> bool {
        true
    }

    fn add_return(&mut self, _: Point3) {}

    fn end<const K: usize, const G: usize, const F: usize>(
        &mut self,
        _: &mut StreamMapper<K, G, F>,
    ) {
    }

    fn restart(&mut self) {}
}

impl<const N: usize> Carving for Carver<N> {
    fn step<const K: usize, const G: usize, const F: usize>(
        &mut self,
        sensor: Point3,
        mapper: &mut StreamMapper<K, G, F>,
    ) -> bool {
        Carver::step(self, sensor, JUDGED_PER_TICK, mapper, &mut ())
    }

    fn add_return(&mut self, p: Point3) {
        Carver::add_return(self, p);
    }

    fn end<const K: usize, const G: usize, const F: usize>(
        &mut self,
        mapper: &mut StreamMapper<K, G, F>,
    ) {
        self.end_scan(mapper, &mut ());
    }

    fn restart(&mut self) {
        Carver::restart(self);
    }
}

/// A carver in a static of its own (a board's).
impl<T: Carving> Carving for &mut T {
    fn step<const K: usize, const G: usize, const F: usize>(
        &mut self,
        sensor: Point3,
        mapper: &mut StreamMapper<K, G, F>,
    ) -> bool {
        (**self).step(sensor, mapper)
    }

    fn add_return(&mut self, p: Point3) {
        (**self).add_return(p);
    }

    fn end<const K: usize, const G: usize, const F: usize>(
        &mut self,
        mapper: &mut StreamMapper<K, G, F>,
    ) {
        (**self).end(mapper);
    }

    fn restart(&mut self) {
        (**self).restart();
    }
}
