//! The receive ring against the link's clock (issue 13). Bytes arrive at the line rate whether
//! or not the main loop is ready; each tick takes what its work costs on the target, and the
//! bytes that arrive meanwhile land in the ring or, when it is full, are lost (as a UART overrun
//! loses them). A tick's cost is its points and its fit (a freeze or a refit) or merge pass (at
//! most one, see [`Firmware::tick`]), each at its price; the prices are the image's, measured under QEMU
//! (`mema-firmware-sim budget` prints them), so this is a model of the device, not a run of it.

use mema_core::map::EncodeError;

use mema_firmware::Firmware;

/// 921,600 baud at 10 bits a byte (start, 8 data, stop).
pub const LINK_BYTES_PER_S: f64 = 92_160.0;
/// The Cortex-M4F.
pub const CPU_HZ: f64 = 168e6;

/// Instructions a tick costs on the target: per point mapped, and per fit (a freeze or a
/// refit), merge pass or scan on top. A scan is a freeze into a full store of shells that
/// first scanned the store for pairs to coarsen: its price is the whole step's, freeze and
/// coarsening merge included (the image times those ticks apart).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickCost {
    pub per_point: f64,
    pub per_fit: f64,
    pub per_merge_pass: f64,
    pub per_scan: f64,
}

/// The link and the processor behind it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Link {
    pub bytes_per_s: f64,
    /// Instructions executed per second: clock over cycles per instruction.
    pub instructions_per_s: f64,
    pub cost: TickCost,
}

#[derive(Clone, Debug, PartialEq)]
pub struct PacedReport {
    /// Bytes lost to a full ring.
    pub overruns: u64,
    /// Most bytes the ring held when a tick began.
    pub ring_peak: usize,
    pub ticks: u64,
    /// Scans of the frozen store for pairs to coarsen.
    pub scans: u64,
    /// The longest tick, and the time the ring takes to fill from empty, in seconds.
    pub longest_tick_s: f64,
    pub ring_fill_s: f64,
    /// When the last byte arrived, and when the last tick ended.
    pub link_s: f64,
    pub done_s: f64,
    /// The `.mema` bytes of the finished map.
    pub map: Vec<u8>,
}

/// Plays `capture` back to back at the link's rate into `firmware`, then finishes the map.
pub fn run_paced<const K: usize, const G: usize, const F: usize>(
    firmware: &mut Firmware<K, G, F>,
    capture: &[u8],
    link: &Link,
) -> Result<PacedReport, EncodeError> {
    let arrived_by = |t: f64| ((t * link.bytes_per_s) as usize).min(capture.len());
    let (mut now, mut sent, mut longest) = (0.0f64, 0usize, 0.0f64);
    let (mut ticks, mut ring_peak) = (0u64, 0usize);
    loop {
        let due = arrived_by(now);
        if due > sent {
            firmware.on_receive(capture.get(sent..due).unwrap_or(&[]));
            sent = due;
        }
        if firmware.busy() {
            ring_peak = ring_peak.max(firmware.pending());
            let work = |f: &Firmware<K, G, F>| {
                let s = f.mapper_stats();
                (s.points, s.merges, s.frozen + s.refits, s.scans)
            };
            let (points, merges, fits, scans) = work(firmware);
            firmware.tick(|_| {});
            let (points_after, merges_after, fits_after, scans_after) = work(firmware);
            let unit = if merges_after != merges {
                link.cost.per_merge_pass
            } else if scans_after != scans {
                link.cost.per_scan
            } else if fits_after != fits {
                link.cost.per_fit
            } else {
                0.0
            };
            let cost = (points_after - points) as f64 * link.cost.per_point + unit;
            let dt = cost / link.instructions_per_s;
            longest = longest.max(dt);
            now += dt;
            ticks += 1;
        } else if sent < capture.len() {
            // Idle until the next byte lands (delivered here: rounding must not stall the clock).
            now = now.max((sent + 1) as f64 / link.bytes_per_s);
            firmware.on_receive(capture.get(sent..sent + 1).unwrap_or(&[]));
            sent += 1;
        } else {
            break;
        }
    }
    let scans = firmware.mapper_stats().scans;
    firmware.finish();
    let mut map = vec![0u8; firmware.mapper().encoded_len()];
    let len = firmware.encode_map(&mut map)?;
    map.truncate(len);
    Ok(PacedReport {
        overruns: firmware.stats().ring_overruns,
        ring_peak,
        ticks,
        scans,
        longest_tick_s: longest,
        ring_fill_s: mema_firmware::RX_CAPACITY as f64 / link.bytes_per_s,
        link_s: capture.len() as f64 / link.bytes_per_s,
        done_s: now,
        map,
    })
}
