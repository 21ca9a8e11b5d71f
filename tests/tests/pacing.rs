//! Issue 13: the receive ring against the link's clock, in the link model
//! (`mema_firmware_sim::pacing`), and the table docs/firmware.md quotes from docs/results.md,
//! which this test computes again (`scripts/results.sh` runs it to write that table).

use mema::link::frames::{encode_stream, quantise};
use mema_core::Point3;
use mema_core::stream::StreamModel;
use mema_firmware::{Firmware, model_params};
use mema_firmware_sim::harness::frames_of;

use crate::firmware::{capture_of, wire_points_of};
use crate::guides::{regenerating, result_block, thousands};
use crate::util::{Dir, MemaCommand};

/// `cloud`'s capture with its points in a fixed pseudo-random order (Fisher-Yates on a 64-bit
/// LCG): a scan without its sweep, so almost every point is far from the one before.
fn shuffled_capture_of(cloud: &str) -> Vec<u8> {
    let mut wire = wire_points_of(cloud);
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for i in (1..wire.len()).rev() {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        wire.swap(i, ((state >> 33) % (i as u64 + 1)) as usize);
    }
    encode_stream(&wire).expect("encodes")
}

/// Points in `capture`, as the firmware maps them.
fn unpaced_points(capture: &[u8]) -> u64 {
    frames_of(capture, None)
        .values()
        .map(|points| points.len() as u64)
        .sum()
}

/// New ground at every point: a line whose spacing grows 0.07% a point (1 cm to 11 m over
/// 10,000 points, 15.7 km in all), with a small zigzag across it, so no point lies within the
/// join radius the earlier merges gave and every one asks for room: the most a capture can
/// ask of the pacing's credit.
fn receding_capture() -> Vec<u8> {
    let (mut x, mut step) = (0.0f64, 0.01f64);
    let wire: Vec<[i32; 3]> = (0..10_000)
        .map(|i| {
            x += step;
            step *= 1.0007;
            let p = Point3::new(x as f32, 0.05 * (i % 7) as f32, 0.02 * (i % 3) as f32);
            quantise(p).expect("fits")
        })
        .collect();
    encode_stream(&wire).expect("encodes")
}

/// Issue 13: the receive ring against the link's clock. Each capture is played back to back at
/// 921,600 baud (the most the link can deliver) into the image's layout (K = 400: 150 working +
/// 250 frozen), every tick taking what its work costs on the target: its points, and its fit
/// (freeze or refit), merge pass or scan of the frozen store, at the prices the image measured
/// under QEMU (`mema-firmware-sim budget` on each capture, rounded up: car6's are at least what
/// `firmware-sim/check.sh` measured, docs/results.md's `firmware-ticks`). Six captures, four in
/// the paper's model: car6 and the demo drive as scanned, car6's points in a shuffled order (no
/// point near the last: the worst order for the join search), and a receding line, new ground
/// at every point (room wanted at 9 points in 10: the pacing's credit all spent, and a scan of
/// every centre for each point it could not pay for); and two in shells whose store fills (the
/// demo drive and bun000), so their freezes coarsen and scan the store (car6 in the paper's model never does).
///
/// A 168 MHz Cortex-M4F at 1.5 cycles an instruction (112 M instructions/s) loses no byte on
/// any of them, the map is the unpaced one, and the longest tick is under a third of the
/// ring's fill time. The pacing's credit ([`mema_core::stream::Pacing`]) is what makes that
/// hold by construction: a fit or merge pass is paid for by the points before it. The slowest
/// processor that keeps up is found by bisection; the rows are docs/results.md's `pacing` block.
#[test]
fn the_ring_keeps_up_with_the_link_on_a_168_mhz_part() {
    use mema_firmware::{IMAGE_BUCKETS, IMAGE_FROZEN, IMAGE_WORKING};
    use mema_firmware_sim::pacing::{LINK_BYTES_PER_S, Link, PacedReport, TickCost, run_paced};
    type Image = Firmware<IMAGE_WORKING, IMAGE_BUCKETS, IMAGE_FROZEN>;
    let dir = Dir::new("fw-paced");
    MemaCommand::new(&dir)
        .args(["scanner-sim", "--port", "demo.bin"])
        .run()
        .assert_ok();
    let demo = std::fs::read(dir.join("demo.bin")).expect("demo capture");
    let paper = model_params(0, IMAGE_WORKING, IMAGE_FROZEN, StreamModel::Paper);
    let shells = model_params(0, IMAGE_WORKING, IMAGE_FROZEN, mema_firmware::SHELLS);
    // The paper's fits never coarsen, so never scan.
    let cost = |per_point, per_fit, per_merge_pass, per_scan| TickCost {
        per_point,
        per_fit,
        per_merge_pass,
        per_scan,
    };
    // While scripts/results.sh writes docs/results.md, its `firmware-ticks` may not be there yet.
    let measured = (!regenerating()).then(car6_prices_measured);
    let mut rows = Vec::new();
    let mut slowest = 0.0f64;
    for (name, capture, params, cost) in [
        (
            "car6",
            capture_of("car6.pcd"),
            paper,
            cost(4_700.0, 120_000.0, 495_000.0, 0.0),
        ),
        (
            "demo drive",
            demo.clone(),
            paper,
            cost(4_600.0, 149_000.0, 500_000.0, 0.0),
        ),
        (
            "car6, points shuffled (the worst order for the join search)",
            shuffled_capture_of("car6.pcd"),
            paper,
            cost(4_000.0, 115_000.0, 480_000.0, 0.0),
        ),
        (
            "a receding line (`receding_capture`: new ground at every point)",
            receding_capture(),
            paper,
            cost(6_800.0, 107_000.0, 320_000.0, 0.0),
        ),
        // Shells fill the image's store on these two, so their freezes coarsen and scan.
        (
            "demo drive, shells",
            demo,
            shells,
            cost(3_000.0, 51_000.0, 315_000.0, 1_110_000.0),
        ),
        (
            "bun000, shells",
            capture_of("bun000.ply"),
            shells,
            cost(2_800.0, 83_000.0, 230_000.0, 1_080_000.0),
        ),
    ] {
        if let (Some(measured), "car6") = (measured, name) {
            let priced = [cost.per_point, cost.per_fit, cost.per_merge_pass];
            assert!(
                priced.iter().zip(measured).all(|(p, m)| *p >= m),
                "car6's prices {priced:?} are under what check.sh measured, {measured:?}"
            );
        }
        let play = |instructions_per_s: f64| -> PacedReport {
            let link = Link {
                bytes_per_s: LINK_BYTES_PER_S,
                instructions_per_s,
                cost,
            };
            let mut firmware: Box<Image> = Box::new(Firmware::new(params));
            run_paced(&mut firmware, &capture, &link).expect("encodes")
        };
        let unpaced = play(1e15);
        assert_eq!(unpaced.overruns, 0);
        assert_eq!(
            unpaced.scans > 0,
            cost.per_scan > 0.0,
            "{name}: {} scans of the store, priced {}",
            unpaced.scans,
            cost.per_scan
        );
        let m4f = play(168e6 / 1.5);
        assert_eq!(m4f.overruns, 0, "{name}: a 168 MHz part loses bytes");
        assert_eq!(m4f.map, unpaced.map, "{name}: pacing changed the map");
        assert!(m4f.longest_tick_s * 3.0 < m4f.ring_fill_s, "{name}");
        // The construction's bound: a point's own work, plus at most the dearest instructions a
        // credit buys (each point earns one), plus its share of the periodic refit.
        let pacing = params.pacing;
        let scan_credits = pacing.scan + 2 * pacing.freeze;
        let per_credit = (cost.per_fit / f64::from(pacing.freeze))
            .max(cost.per_merge_pass / f64::from(pacing.merge_pass))
            .max(cost.per_scan / f64::from(scan_credits));
        let per_point_bound =
            cost.per_point + per_credit + cost.per_fit / f64::from(mema_firmware::REFIT_INTERVAL);
        let points = unpaced_points(&capture);
        let bound = per_point_bound * points as f64 / m4f.link_s;
        // Bisection on the rate, in M instructions per second, for the README.
        let (mut slow, mut fast) = (10.0f64, 112.0f64);
        while fast - slow > 1.0 {
            let mid = 0.5 * (slow + fast);
            if play(mid * 1e6).overruns == 0 {
                fast = mid;
            } else {
                slow = mid;
            }
        }
        assert!(
            fast * 1e6 <= bound,
            "{name}: needs {fast} M/s, over the bound {bound}"
        );
        eprintln!(
            "{name}: {} bytes over {:.2} s; keeps up from {fast:.0} M instructions/s; at 112 M/s: \
             {} ticks, longest {:.1} ms (ring fills in {:.1} ms), ring peak {} bytes",
            capture.len(),
            m4f.link_s,
            m4f.ticks,
            m4f.longest_tick_s * 1e3,
            m4f.ring_fill_s * 1e3,
            m4f.ring_peak
        );
        let price = |x: f64| thousands(x as u64);
        rows.push(format!(
            "| {name} | {}, {}, {}, {} | {fast:.0} M/s | {:.0} M/s | {} B | {:.1} ms |",
            price(cost.per_point),
            price(cost.per_fit),
            price(cost.per_merge_pass),
            if cost.per_scan > 0.0 {
                price(cost.per_scan)
            } else {
                "none".to_string()
            },
            bound / 1e6,
            thousands(m4f.ring_peak as u64),
            m4f.longest_tick_s * 1e3
        ));
        slowest = slowest.max(fast);
    }
    let mut block = vec![
        "| capture | prices (point, fit, merge pass, scan) | keeps up from | the bound | ring peak at 112 M/s | longest tick |".to_string(),
        "|---|---|---|---|---|---|".to_string(),
    ];
    block.extend(rows);
    block.push(String::new());
    block.push(format!(
        "A 168 MHz part keeps up with all {} at up to {:.2} cycles an instruction.",
        block.len() - 3,
        168.0 / slowest
    ));
    let block = block.join("\n");
    if regenerating() {
        // scripts/results.sh writes docs/results.md's `pacing` block from these lines.
        for line in block.lines() {
            println!("pacing: {line}");
        }
    } else {
        assert_eq!(
            block,
            result_block("pacing"),
            "docs/results.md's `pacing` block is not what the link model gives; run scripts/results.sh"
        );
    }
}

/// What `firmware-sim/check.sh` measured on car6 with the paper's model (docs/results.md's
/// `firmware-ticks`): a point (point-only ticks), a fit, a merge pass, in instructions.
fn car6_prices_measured() -> [f64; 3] {
    let block = result_block("firmware-ticks");
    let row = block
        .lines()
        .find(|l| l.starts_with("| paper |"))
        .expect("the paper model's row");
    let cells: Vec<f64> = row
        .trim_matches('|')
        .split('|')
        .skip(5)
        .take(3)
        .map(|c| c.trim().replace(',', "").parse().expect("a count"))
        .collect();
    [cells[0], cells[1], cells[2]]
}
