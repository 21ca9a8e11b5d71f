//! Issue 11: oriented shells in the streaming mapper, on real clouds.
//!
//! - Every entity of a shells stream map is the shell of its cluster's points, computed here
//!   independently: the points each cluster received (followed through the mapper's `Observer`),
//!   a two-pass f64 covariance, and nalgebra's eigen-decomposition. Frozen entities included,
//!   except those a coarsening merged: each stands for its two shells' patches weighed by
//!   their areas, not for their points, and is held to the box and the extent of its points
//!   (a lone point's shell, or a line's, has next to no area, a line's its floor of width:
//!   merged, it weighs next to nothing, and its points are counted apart for the extent but
//!   not for the box). A frozen shell that thawed comes back holding its patch's six points
//!   (`mema_core::stream::thaw`), which stand for its points from then on.
//! - `mema replay --model shells` writes the same bytes for every chunking, equal to the mapper
//!   fed directly, and the file reads back as the map in memory.
//! - Shells beat the paper's fits in the stream, scored both ways.

use mema::io::load_cloud;
use mema::link::frames::{dequantise, quantise};
use mema::link::stream::map_sent_directly_with;
use mema::link::stream::{Capacity, new_mapper_with, stream_params};
use mema_core::Point3;
use mema_core::stream::{Observer, StreamModel};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::util::{Dir, MemaCommand, shared};

/// The model `--model shells` maps with (the default sphere tolerance).
fn shells() -> StreamModel {
    StreamModel::shells(0.01)
}

/// Each working cluster's and each frozen entity's points, kept as the mapper reports its moves.
#[derive(Default)]
struct Members {
    point: [f64; 3],
    working: Vec<Vec<[f64; 3]>>,
    frozen: Vec<Vec<[f64; 3]>>,
    /// Whether each frozen entity came of a coarsening.
    coarsened: Vec<bool>,
    /// Each frozen entity's points with those of the shells with no area it merged: a line's
    /// shell keeps a floor of width, so it weighs a little, and the merged centre is within
    /// the box of them all.
    spanned: Vec<Vec<[f64; 3]>>,
    /// Points the pacing shed.
    shed: usize,
    /// Points of shells with no area a coarsening merged (they weigh nothing in the merge).
    weightless: usize,
    /// Points held by frozen shells that thawed: each came back as its patch's six points.
    thawed: usize,
    /// The thawed shells' patch points, held in their points' place.
    patches: usize,
}

impl Observer for Members {
    fn joined(&mut self, index: usize) {
        self.working[index].push(self.point);
    }

    fn opened(&mut self, index: usize) {
        assert_eq!(index, self.working.len(), "a new cluster opens at the end");
        self.working.push(vec![self.point]);
    }

    fn shed(&mut self) {
        self.shed += 1;
    }

    fn merged(&mut self, into: usize, from: usize) {
        let moved = std::mem::take(&mut self.working[from]);
        self.working[into].extend(moved);
    }

    fn frozen(&mut self, index: usize) {
        let points = std::mem::take(&mut self.working[index]);
        self.spanned.push(points.clone());
        self.frozen.push(points);
        self.coarsened.push(false);
    }

    fn coarsened(&mut self, into: usize, from: usize) {
        let mut moved = self.frozen.swap_remove(from);
        self.coarsened.swap_remove(from);
        let mut spanned = self.spanned.swap_remove(from);
        self.spanned[into].append(&mut spanned);
        let kept = &mut self.frozen[into];
        // A shell with no area (a lone point, or points on a line) beside a patch: the merged
        // shell is the patch's.
        if weightless(&moved) && !weightless(kept) {
            self.weightless += moved.len();
        } else {
            if weightless(kept) && !weightless(&moved) {
                self.weightless += kept.len();
                kept.clear();
            }
            kept.append(&mut moved);
        }
        self.coarsened[into] = true;
    }

    fn thawed(&mut self, from: usize, index: usize, patch: &[Point3]) {
        assert_eq!(
            index,
            self.working.len(),
            "a thawed shell comes back at the end"
        );
        self.thawed += self.frozen.swap_remove(from).len();
        self.patches += patch.len();
        self.coarsened.swap_remove(from);
        self.spanned.swap_remove(from);
        self.working
            .push(patch.iter().map(|q| q.to_array().map(f64::from)).collect());
    }

    fn removed(&mut self, index: usize) {
        assert!(
            self.working[index].is_empty(),
            "only emptied clusters leave"
        );
        self.working.swap_remove(index);
    }
}

/// Whether `points` make a shell with no area to weigh in a coarsening (its area is the product
/// of its two longest semi-axes): one point, or points on a line (the shells' floor, 1e-3 of
/// the longest, is all the width they have).
fn weightless(points: &[[f64; 3]]) -> bool {
    let (_, r, _) = direct_shell(points);
    points.len() < 2 || r[1] <= 1e-2 * r[0]
}

/// `R diag(r^2) R^T`: the shell's shape, the same whichever way its axes are ordered or signed.
fn shape_matrix(axes: &[Vector3<f64>; 3], semi_axes: [f64; 3]) -> Matrix3<f64> {
    (0..3).fold(Matrix3::zeros(), |s, j| {
        s + axes[j] * axes[j].transpose() * (semi_axes[j] * semi_axes[j])
    })
}

/// The shell of `points` computed here: two-pass mean and covariance in f64, nalgebra's
/// eigenvectors, semi-axes 2.0, 2.0 and 0.7 standard deviations (largest first), none shorter
/// than 1e-3 of the longest. Returns the mean, the semi-axes (descending) and the shape.
fn direct_shell(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3], Matrix3<f64>) {
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold(Vector3::zeros(), |m, p| m + Vector3::from(*p) / n);
    let covariance = points.iter().fold(Matrix3::zeros(), |c, p| {
        let d = Vector3::from(*p) - mean;
        c + d * d.transpose() / n
    });
    let eigen = SymmetricEigen::new(covariance);
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let scales = [2.0, 2.0, 0.7];
    let mut r = [0.0; 3];
    for (j, &i) in order.iter().enumerate() {
        r[j] = scales[j] * eigen.eigenvalues[i].max(0.0).sqrt();
    }
    let floor = (r[0] * 1e-3).max(f64::MIN_POSITIVE);
    let r = r.map(|v| v.max(floor));
    let axes = order.map(|i| eigen.eigenvectors.column(i).into_owned());
    let mut sorted = r;
    sorted.sort_by(|a, b| b.total_cmp(a));
    ([mean.x, mean.y, mean.z], sorted, shape_matrix(&axes, r))
}

/// The points the stream receives: the cloud through the wire's millimetre grid.
fn wire_points(cloud: &str) -> Vec<Point3> {
    let cloud = load_cloud(&shared(cloud)).expect("cloud reads");
    cloud
        .points
        .iter()
        .map(|p| dequantise(quantise(*p).expect("fits the wire")))
        .collect()
}

/// Maps `cloud` with shells, following every cluster, and checks each entity against its
/// direct shell. Returns (entities, frozen, coarsened) for the caller's own assertions.
fn check_against_direct(cloud: &str, capacity: Capacity) -> (usize, usize, usize) {
    let points = wire_points(cloud);
    let mut mapper = new_mapper_with(stream_params(
        capacity,
        0,
        Default::default(),
        0.0,
        shells(),
    ));
    let mut members = Members::default();
    for p in &points {
        members.point = p.to_f64();
        mapper.add_observed(*p, &mut members);
    }
    mapper.finish_observed(&mut members);
    let clusters: Vec<&Vec<[f64; 3]>> = members.frozen.iter().chain(&members.working).collect();
    let entities: Vec<_> = mapper.entities().collect();
    assert_eq!(
        entities.len(),
        clusters.len(),
        "{cloud}: one entity per cluster"
    );
    assert_eq!(members.frozen.len(), mapper.frozen().len());
    let held: usize = clusters.iter().map(|c| c.len()).sum();
    assert_eq!(
        held + members.shed + members.weightless + members.thawed,
        points.len() + members.patches,
        "{cloud}: every point in exactly one cluster, or shed, or a lone point coarsened, or \
         in a shell that thawed (its patch's points held in its points' place)"
    );
    assert_eq!(members.patches as u64, 6 * mapper.stats().thawed, "{cloud}");
    assert_eq!(members.shed as u64, mapper.stats().paced_shed, "{cloud}");
    // The smallest-three code keeps a frozen entity's rotation within a quarter of a degree, and
    // a working cluster's once the stream is finished; a rotation by theta moves the shape by at
    // most 2 sin(theta) r_max^2.
    let code_bound = 2.0 * 0.25f64.to_radians().sin();
    let mut worst = [0.0f64; 3];
    let mut coarsened = 0;
    let mut extent_ratio = [f64::INFINITY, 0.0f64];
    for (i, (e, points)) in entities.iter().zip(&clusters).enumerate() {
        let (mean, r_direct, shape_direct) = direct_shell(points);
        let c = e.entity.center.to_f64();
        if members.coarsened.get(i) == Some(&true) {
            // Inside the box of its points and of the shells with no area it merged (a weighted
            // mean of its patches' centres, each the mean of its points), and as long as their
            // own shell within a factor of three or four: the merge weighs each patch by its
            // area, its points' shell by their count, and a long shell of few points (nearly a
            // line, not weightless) spreads its points' shell beyond the merged one (car6's
            // worst at the image's layout, 0.31, once thawing moved which clusters froze).
            coarsened += 1;
            let spanned = &members.spanned[i];
            for j in 0..3 {
                let (lo, hi) = spanned.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
                    (lo.min(p[j]), hi.max(p[j]))
                });
                let slack = 1e-6 * (hi - lo).max(c[j].abs() * f32::EPSILON as f64);
                assert!(
                    c[j] >= lo - slack && c[j] <= hi + slack,
                    "{cloud} entity {i}: coarsened centre {c:?} outside its points' box"
                );
            }
            let r = e.entity.semi_axes_f64().into_iter().fold(0.0, f64::max);
            let ratio = r / r_direct[0];
            assert!(
                (1.0 / 4.0..=3.0).contains(&ratio),
                "{cloud} entity {i}: coarsened, longest semi-axis {ratio} of its points' shell's"
            );
            extent_ratio = [extent_ratio[0].min(ratio), extent_ratio[1].max(ratio)];
            continue;
        }
        for j in 0..3 {
            // The stored centre is the mean in f32: within one f32 rounding of it, plus what
            // the moments' grid moves it by: at most half a pitch, and the pitch is at most
            // 2^-23 of the largest offset from the cluster's first point (twice its extent).
            let extent = points
                .iter()
                .map(|p| (p[j] - mean[j]).abs())
                .fold(0.0, f64::max);
            let d = (c[j] - mean[j]).abs();
            assert!(
                d <= f32::EPSILON as f64 * mean[j].abs() + extent / (1u64 << 23) as f64 + 1e-12,
                "{cloud} entity {i}: centre {c:?} vs mean {mean:?}"
            );
        }
        let mut r = e.entity.semi_axes_f64();
        r.sort_by(|a, b| b.total_cmp(a));
        if r_direct[0] == f64::MIN_POSITIVE {
            // One point (or coincident ones): a shell of no extent, kept as the largest weight.
            assert!(
                e.entity.weights == [f32::MAX; 3],
                "{cloud} entity {i}: a point"
            );
            continue;
        }
        // The moments' grid moves each coordinate by at most 2^-23 of the cluster's extent on
        // that axis: an absolute error on every semi-axis, which a thin rotated cluster's
        // smallest one (car6 has 0.45 mm across 0.38 m) feels as 1e-5 relative.
        let grid = (0..3)
            .map(|j| {
                points
                    .iter()
                    .map(|p| (p[j] - mean[j]).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max)
            * 4.0
            / (1u64 << 23) as f64;
        for j in 0..3 {
            let rel = ((r[j] - r_direct[j]).abs() - grid).max(0.0) / r_direct[j];
            worst[0] = worst[0].max(rel);
            assert!(
                rel < 1e-6,
                "{cloud} entity {i} ({} points): semi-axes {r:?} vs {r_direct:?}",
                points.len()
            );
        }
        let m = e.entity.rotation.matrix();
        let axes = [0, 1, 2].map(|j| Vector3::new(m[0][j], m[1][j], m[2][j]));
        let shape = shape_matrix(&axes, e.entity.semi_axes_f64());
        let scale = r_direct[0] * r_direct[0];
        let off = (shape - shape_direct).abs().max() / scale;
        let frozen = i < members.frozen.len();
        let bound = code_bound + 1e-6;
        worst[1 + usize::from(frozen)] = worst[1 + usize::from(frozen)].max(off);
        assert!(
            off < bound,
            "{cloud} entity {i} (frozen {frozen}, {} points): shape differs by {off:e} of r_max^2",
            points.len()
        );
    }
    eprintln!(
        "{cloud} {capacity:?}: {} entities ({} frozen, {coarsened} coarsened: longest semi-axis {:.2}-{:.2} of their points' shell's, {} points weightless); worst semi-axis {:.1e}, shape {:.1e} working / {:.1e} frozen",
        entities.len(),
        members.frozen.len(),
        extent_ratio[0],
        extent_ratio[1],
        members.weightless,
        worst[0],
        worst[1],
        worst[2]
    );
    (entities.len(), members.frozen.len(), coarsened)
}

#[test]
fn stream_shells_are_the_shells_of_their_clusters_points() {
    let (n, frozen, _) = check_against_direct("car6.pcd", Capacity::all_working(150));
    assert!(n > 120 && frozen == 0, "{n} entities, {frozen} frozen");
    for cloud in ["car6.pcd", "bun000.ply"] {
        let (n, frozen, coarsened) = check_against_direct(
            cloud,
            Capacity {
                k: 400,
                working: 150,
            },
        );
        // A floor of reach, not of fidelity: the finish merges working clusters finer than the
        // store (bun000 ends with 296 entities of 400 since merge passes among shells cost 40
        // credits, not 80).
        assert!(
            n > 250 && frozen > 150,
            "{cloud}: {n} entities, {frozen} frozen"
        );
        // bun000's 40,256 points fill the frozen store: it coarsens.
        assert!(
            cloud != "bun000.ply" || coarsened > 0,
            "{cloud}: nothing coarsened"
        );
    }
}

#[test]
fn shells_replay_gives_the_same_bytes_for_every_chunking() {
    let dir = Dir::new("stream-shells-replay");
    let car = shared("car6.pcd");
    MemaCommand::new(&dir)
        .args(["scanner-sim", "--port", "car.bin"])
        .arg(&car)
        .run()
        .assert_ok();
    let cloud = load_cloud(&car).expect("car6");
    for (k, working) in [("150", "150"), ("400", "150")] {
        let capacity = Capacity {
            k: k.parse().expect("k"),
            working: working.parse().expect("working"),
        };
        let direct = map_sent_directly_with(
            &cloud,
            stream_params(capacity, 0, Default::default(), 0.0, shells()),
        )
        .expect("direct map");
        let expected = direct.to_mema().expect("encodes");
        for chunk in ["1", "7", "61", "4096", "1000000"] {
            let out = format!("shells-{k}-{chunk}.mema");
            MemaCommand::new(&dir)
                .args(["replay", "car.bin", "-k", k, "--working", working])
                .args(["--model", "shells", "--chunk-bytes", chunk, "-o", &out])
                .run()
                .assert_ok();
            let bytes = std::fs::read(dir.join(&out)).expect("map");
            assert_eq!(
                bytes, expected,
                "-k {k} --working {working}, chunks of {chunk}"
            );
        }
        // Quantized version 2, 14 bytes an entity, and it reads back as the map in memory.
        assert_eq!(&expected[4..8], &[2, 0, 1, 0]);
        assert_eq!(expected.len(), 48 + 14 * direct.entities.len() + 4);
        let read = mema::io::mapfile::HostMap::read(&dir.join(&format!("shells-{k}-1.mema")))
            .expect("reads");
        assert_eq!(read, direct);
        assert!(
            direct
                .entities
                .iter()
                .filter(|e| !e.entity.rotation.is_identity())
                .count()
                > direct.entities.len() / 2
        );
    }
}

#[test]
fn shells_beat_the_papers_fits_in_the_stream_both_ways() {
    let dir = Dir::new("stream-shells-bench");
    let car = shared("car6.pcd");
    let score = |model: &str| {
        let json = MemaCommand::new(&dir)
            .arg("stream-bench")
            .arg(&car)
            .args([
                "-k",
                "400",
                "--working",
                "150",
                "--repetitions",
                "1",
                "--json",
            ])
            .args(["--model", model])
            .run()
            .assert_ok()
            .json();
        let s = &json["stream_score"];
        (
            s["chamfer"].as_f64().expect("chamfer"),
            s["phantom"].as_f64().expect("phantom"),
            json["stream_mean_error"].as_f64().expect("eq. 13"),
        )
    };
    let (paper, shells) = (score("paper"), score("shells"));
    // Measured on car6: Chamfer 0.068 vs 0.039, phantom 0.46 vs 0.14, eq. 13 0.068 vs 0.055.
    assert!(shells.0 < 0.8 * paper.0, "Chamfer {shells:?} vs {paper:?}");
    assert!(shells.1 < 0.5 * paper.1, "phantom {shells:?} vs {paper:?}");
    assert!(shells.2 < paper.2, "eq. 13 {shells:?} vs {paper:?}");
}
