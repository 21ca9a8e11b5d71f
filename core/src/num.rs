//! Standard-library operations without their panicking branches, so the release build of the
//! core links with no panic path at all (the firmware image checks it with `panic-never`), and a
//! square root the same on every target at a fraction of the software routine's cost.

/// `x.clamp(lo, hi)` as `f64::clamp` computes it, without its `assert!(lo <= hi)`: callers
/// guarantee the order, and a NaN `x` passes through unchanged as it does there.
#[inline]
pub(crate) fn clamp(x: f64, lo: f64, hi: f64) -> f64 {
    let mut x = x;
    if x < lo {
        x = lo;
    }
    if x > hi {
        x = hi;
    }
    x
}

/// A stable insertion sort for the tiny slices the core sorts (3 axes, at most 32 indices).
/// `sort_unstable_by` keeps a panic for inconsistent orderings; this keeps equal elements in
/// their order, which is what the standard sort produced on these inputs.
pub(crate) fn insertion_sort_by<T: Copy>(v: &mut [T], before: impl Fn(&T, &T) -> bool) {
    for i in 1..v.len() {
        let mut j = i;
        while j > 0 {
            let (Some(&prev), Some(&cur)) = (v.get(j - 1), v.get(j)) else {
                break;
            };
            if !before(&cur, &prev) {
                break;
            }
            if let Some(pair) = v.get_mut(j - 1..=j) {
                pair.copy_from_slice(&[cur, prev]);
            }
            j -= 1;
        }
    }
}

/// Sorts `v` by `before` (a strict total order) in O(n log n) compares, in place and without
/// recursion: the coarsening's sweep sorts a whole frozen store at every scan, where an
/// insertion sort's n^2 / 4 moves would cost a few dozen fits.
pub(crate) fn heap_sort_by<T: Copy>(v: &mut [T], before: impl Fn(&T, &T) -> bool) {
    // Moves element `at` down a max-heap of the first `end` elements.
    let sift = |v: &mut [T], mut at: usize, end: usize| {
        loop {
            let left = 2 * at + 1;
            if left >= end {
                break;
            }
            let right = left + 1;
            let child = match (v.get(left), v.get(right)) {
                (Some(l), Some(r)) if right < end && before(l, r) => right,
                _ => left,
            };
            let (Some(&parent), Some(&larger)) = (v.get(at), v.get(child)) else {
                break;
            };
            if !before(&parent, &larger) {
                break;
            }
            swap_within(v, at, child);
            at = child;
        }
    };
    let n = v.len();
    for start in (0..n / 2).rev() {
        sift(v, start, n);
    }
    for end in (1..n).rev() {
        swap_within(v, 0, end);
        sift(v, 0, end);
    }
}

/// `v.swap(i, j)` where both are in range, else nothing: the check in sight lets the compiler
/// drop `swap`'s panic.
fn swap_within<T>(v: &mut [T], i: usize, j: usize) {
    if i < v.len() && j < v.len() {
        v.swap(i, j);
    }
}

/// `v.swap_remove(i)` without its `assert!`: removes element `i`, moving the last one into its
/// place, and returns false (changing nothing) if `i` is out of range. The callers' own range
/// checks do not always reach heapless's assert at opt-level "s", which then keeps a panic.
pub(crate) fn swap_remove<T, const N: usize>(v: &mut heapless::Vec<T, N>, i: usize) -> bool {
    if i >= v.len() {
        return false;
    }
    let Some(last) = v.pop() else {
        return false;
    };
    if let Some(slot) = v.get_mut(i) {
        *slot = last;
    }
    true
}

/// `sqrt(x)` within 10^-6 of it, in a dozen instructions where the Cortex-M4F's libm takes
/// a software routine of a hundred (the core cannot reach its VSQRT without `unsafe`): three
/// Newton steps from the exponent halved, IEEE single operations only, so the same bits on
/// every target; 0 for 0, NaN for a negative or NaN `x`, infinity for infinity.
pub(crate) fn square_root(x: f32) -> f32 {
    if !(x > 0.0 && x.is_finite()) {
        return if x == 0.0 || x == f32::INFINITY {
            x
        } else {
            f32::NAN
        };
    }
    let mut y = f32::from_bits(0x1fbd_1df5 + (x.to_bits() >> 1));
    for _ in 0..3 {
        y = 0.5 * (y + x / y);
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamp_matches_the_standard_one() {
        for x in [
            -2.0,
            -0.0,
            0.0,
            0.5,
            1.0,
            3.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            assert_eq!(clamp(x, 0.0, 1.0).to_bits(), x.clamp(0.0, 1.0).to_bits());
        }
        assert!(clamp(f64::NAN, 0.0, 1.0).is_nan());
    }

    #[test]
    fn insertion_sort_is_stable_and_sorted() {
        let mut v = [(3, 'a'), (1, 'b'), (3, 'c'), (2, 'd'), (1, 'e')];
        insertion_sort_by(&mut v, |a, b| a.0 > b.0);
        assert_eq!(v, [(3, 'a'), (3, 'c'), (2, 'd'), (1, 'b'), (1, 'e')]);
        let mut w: [usize; 0] = [];
        insertion_sort_by(&mut w, |a, b| a < b);
    }

    #[test]
    fn heap_sort_sorts_as_the_insertion_sort() {
        let mut rng = crate::rng::stream_rng(7, 0);
        for n in [0usize, 1, 2, 3, 7, 64, 551] {
            let mut v = [(0u8, 0u16); 551];
            for (i, x) in v.iter_mut().enumerate().take(n) {
                // Few distinct keys, so ties are common and broken by the index.
                *x = (crate::rng::index_below(&mut rng, 7) as u8, i as u16);
            }
            let mut expected = v;
            insertion_sort_by(&mut expected[..n], |a, b| a < b);
            heap_sort_by(&mut v[..n], |a, b| a < b);
            assert_eq!(v, expected, "n = {n}");
        }
    }

    #[test]
    fn swap_remove_matches_heapless() {
        for i in 0..5 {
            let mut ours: heapless::Vec<u8, 4> = heapless::Vec::new();
            for b in 1..=4 {
                assert!(ours.push(b).is_ok());
            }
            let mut theirs = ours.clone();
            assert_eq!(swap_remove(&mut ours, i), i < 4);
            if i < 4 {
                theirs.swap_remove(i);
            }
            assert_eq!(ours, theirs);
        }
    }
}
