//! Exact accelerated k-means++: the plain seeding's draws in far fewer distance evaluations.
//!
//! Each point sits in the list of the centre that gave it its current distance (the lowest
//! index among the nearest, since a point moves only on a strict decrease), and each list keeps
//! a radius bounding the true distance of its points. A new centre `c` can only lower the
//! distances of list `j` if `|c - c_j| < 2 r_j`; every other list is skipped whole, which the
//! triangle inequality and `margin::skip_squared` prove cannot change a single distance. The
//! draw walks exact integer block sums (`weights`), so it picks the same point as the plain
//! full scan. On return the lists are the labels of the nearest seed, which is Lloyd's first
//! assignment.

use super::margin::{skip_squared, squared, upper};
use super::weights::{BLOCK, blocks_for, draw_target};
use super::{KMEANS_STREAM, KMeansError, check_extent, check_len, seeding_scale, seeding_start};
use crate::geometry::Point3;
use crate::rng::stream_rng;

/// End of a list.
const NIL: u32 = u32::MAX;

/// One seeding list: its first point, and the squared centre distance beyond which a new
/// centre cannot touch it (from the bound on its points' true distance to the centre).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeedList {
    head: u32,
    skip: f32,
}

impl Default for SeedList {
    fn default() -> Self {
        Self::new(NIL, 0.0)
    }
}

impl SeedList {
    fn new(head: u32, max_squared: f32) -> Self {
        Self {
            head,
            skip: skip_squared(upper(max_squared)),
        }
    }
}

fn get(points: &[Point3], i: u32) -> Point3 {
    points.get(i as usize).copied().unwrap_or_default()
}

/// The same centres and distances as `seed_plus_plus`; `labels` (used for the list links)
/// ends holding each point's nearest centre, `blocks` needs `blocks_for(n)` entries and `lists`
/// one per centre.
pub fn seed_plus_plus_fast(
    points: &[Point3],
    centres: &mut [Point3],
    distances: &mut [f32],
    labels: &mut [u32],
    blocks: &mut [u128],
    lists: &mut [SeedList],
    seed: u64,
) -> Result<(), KMeansError> {
    let mut rng = stream_rng(seed, KMEANS_STREAM);
    let first = seeding_start(points, centres, distances, &mut rng)?;
    let n = points.len();
    let k = centres.len();
    check_len("labels", n, labels.len())?;
    check_len("block sums", blocks_for(n), blocks.len())?;
    check_len("seed lists", k, lists.len())?;
    if n >= NIL as usize {
        return Err(KMeansError::SliceLength {
            what: "points (at most 2^32 - 2)",
            expected: NIL as usize - 1,
            got: n,
        });
    }
    let chosen = get(points, first as u32);
    let mut max = 0.0f32;
    for (i, ((d, p), link)) in distances
        .iter_mut()
        .zip(points.iter())
        .zip(labels.iter_mut())
        .enumerate()
    {
        *d = squared(*p, chosen);
        max = max.max(*d);
        *link = if i + 1 < n { i as u32 + 1 } else { NIL };
    }
    for l in lists.iter_mut() {
        *l = SeedList::default();
    }
    if let (Some(c), Some(l)) = (centres.first_mut(), lists.first_mut()) {
        *c = chosen;
        *l = SeedList::new(0, max);
    }
    if k == 1 {
        check_extent(distances)?;
    } else {
        let scale = seeding_scale(distances, k)?;
        let mut total = 0u128;
        for (b, chunk) in blocks.iter_mut().zip(distances.chunks(BLOCK)) {
            *b = chunk.iter().map(|&d| scale.weight(d)).sum();
            total += *b;
        }
        for m in 1..k {
            if total == 0 {
                return Err(KMeansError::TooFewDistinctPoints { k, distinct: m });
            }
            let target = draw_target(&mut rng, total);
            let mut cumulative = 0u128;
            let mut block = 0;
            for (b, &w) in blocks.iter().enumerate() {
                if cumulative + w > target {
                    block = b;
                    break;
                }
                cumulative += w;
            }
            let start = block * BLOCK;
            let mut pick = start;
            for (i, &d) in distances.iter().enumerate().skip(start) {
                cumulative += scale.weight(d);
                if cumulative > target {
                    pick = i;
                    break;
                }
            }
            let c = get(points, pick as u32);
            if let Some(slot) = centres.get_mut(m) {
                *slot = c;
            }
            // Moved points are appended, so every list stays in increasing point order and its
            // walk runs forward through memory.
            let mut new_head = NIL;
            let mut new_tail = NIL;
            let mut new_max = 0.0f32;
            for (list, &cj) in lists.iter_mut().zip(centres.iter()).take(m) {
                // Points of list j are within r_j of c_j, so at least |c - c_j| - r_j from c.
                if squared(cj, c) >= list.skip {
                    continue;
                }
                let mut prev = NIL;
                let mut p = list.head;
                let mut kept_max = 0.0f32;
                while let (Some(&next), Some(&point), Some(&d)) = (
                    labels.get(p as usize),
                    points.get(p as usize),
                    distances.get(p as usize),
                ) {
                    let dp = squared(point, c);
                    if dp < d {
                        let drop = scale.weight(d) - scale.weight(dp);
                        if let Some(b) = blocks.get_mut(p as usize / BLOCK) {
                            *b -= drop;
                        }
                        total -= drop;
                        if let Some(slot) = distances.get_mut(p as usize) {
                            *slot = dp;
                        }
                        new_max = new_max.max(dp);
                        match labels.get_mut(prev as usize) {
                            Some(l) => *l = next,
                            None => list.head = next,
                        }
                        if let Some(l) = labels.get_mut(p as usize) {
                            *l = NIL;
                        }
                        match labels.get_mut(new_tail as usize) {
                            Some(l) => *l = p,
                            None => new_head = p,
                        }
                        new_tail = p;
                    } else {
                        kept_max = kept_max.max(d);
                        prev = p;
                    }
                    p = next;
                }
                *list = SeedList::new(list.head, kept_max);
            }
            if let Some(l) = lists.get_mut(m) {
                *l = SeedList::new(new_head, new_max);
            }
        }
    }
    for (j, list) in lists.iter().enumerate() {
        let mut p = list.head;
        while let Some(l) = labels.get_mut(p as usize) {
            p = *l;
            *l = j as u32;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kmeans::{nearest, seed_plus_plus};
    use crate::test_support::{OrFail, TestResult};

    #[test]
    fn same_draws_as_the_plain_seeding() -> TestResult {
        // Clumps, duplicates and a grid: ties in fl(D^2) and points sitting on centres.
        const N: usize = 3000;
        let mut pts = [Point3::default(); N];
        let mut s = 99u64;
        for (i, p) in pts.iter_mut().enumerate() {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let r = (s >> 40) as f32 / (1u64 << 24) as f32;
            *p = match i % 4 {
                0 => Point3::new((i % 13) as f32, (i % 7) as f32, 0.0),
                1 => Point3::new(50.0 + r, r * r, 3.0),
                2 => Point3::new(r * 100.0, 20.0, r),
                _ => Point3::new(1.0, 2.0, 3.0),
            };
        }
        for (k, seed) in [(1usize, 0u64), (2, 1), (40, 2), (150, 3), (150, 4)] {
            let mut plain_c = [Point3::default(); 150];
            let mut plain_d = [0f32; N];
            seed_plus_plus(&pts, &mut plain_c[..k], &mut plain_d, seed).or_fail("plain")?;
            let mut fast_c = [Point3::default(); 150];
            let mut fast_d = [0f32; N];
            let mut labels = [0u32; N];
            let mut blocks = [0u128; blocks_for(N)];
            let mut lists = [SeedList::default(); 150];
            seed_plus_plus_fast(
                &pts,
                &mut fast_c[..k],
                &mut fast_d,
                &mut labels,
                &mut blocks,
                &mut lists[..k],
                seed,
            )
            .or_fail("fast")?;
            for (a, b) in plain_c[..k].iter().zip(fast_c[..k].iter()) {
                assert_eq!(
                    a.to_array().map(f32::to_bits),
                    b.to_array().map(f32::to_bits)
                );
            }
            for (a, b) in plain_d.iter().zip(fast_d.iter()) {
                assert_eq!(a.to_bits(), b.to_bits());
            }
            for (p, &l) in pts.iter().zip(labels.iter()) {
                assert_eq!(l as usize, nearest(*p, &fast_c[..k]).0, "k {k}");
            }
        }
        Ok(())
    }

    #[test]
    fn too_few_distinct_points_is_reported_alike() {
        let pts = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
        ];
        let mut c = [Point3::default(); 3];
        let mut d = [0f32; 3];
        let plain = seed_plus_plus(&pts, &mut c, &mut d, 0);
        let mut labels = [0u32; 3];
        let mut blocks = [0u128; 1];
        let mut lists = [SeedList::default(); 3];
        let fast = seed_plus_plus_fast(
            &pts,
            &mut c,
            &mut d,
            &mut labels,
            &mut blocks,
            &mut lists,
            0,
        );
        assert_eq!(plain, fast);
        assert_eq!(
            fast,
            Err(KMeansError::TooFewDistinctPoints { k: 3, distinct: 2 })
        );
    }
}
