//! The memory budget: static RAM of the firmware state at K = 150, 400 (all working, and 150
//! working + 250 frozen), 700 (the board's 150 working + 550 frozen) and 1000 (`size_of`, so
//! exact for this build), the image's flash and RAM (`llvm-size`), and what the image measured
//! under QEMU (stack high-water marks, instructions per ingested point).

use std::path::Path;
use std::process::Command;

use mema_core::link::wire::Decoder;
use mema_core::stream::{StreamCluster, StreamMapper};

use crate::board::TARGET_BOARD;
use mema_firmware::{
    BOARD_FROZEN, BOARD_WORKING, Firmware, IMAGE_BUCKETS, IMAGE_FROZEN, IMAGE_WORKING, RX_CAPACITY,
    Snapshot,
};

/// One capacity's static RAM.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StaticRow {
    /// Ellipsoids the map can hold: `working + frozen`.
    pub k: usize,
    /// Clusters in working memory (their moments), and room for frozen entities.
    pub working: usize,
    pub frozen: usize,
    pub buckets: usize,
    pub mapper: usize,
    pub decoder: usize,
    pub ring: usize,
    /// Mapper + decoder + ring: the RAM the firmware state needs.
    pub firmware: usize,
    /// The snapshot (retained RAM or flash) on top.
    pub snapshot: usize,
}

fn row<const K: usize, const G: usize, const F: usize>() -> StaticRow {
    StaticRow {
        k: K + F,
        working: K,
        frozen: F,
        buckets: G,
        mapper: size_of::<StreamMapper<K, G, F>>(),
        decoder: size_of::<Decoder>(),
        ring: RX_CAPACITY,
        firmware: size_of::<Firmware<K, G, F>>(),
        snapshot: size_of::<Snapshot<K, G, F>>(),
    }
}

/// `llvm-size` of the image: flash = text + data, RAM = data + bss (the stack comes on top);
/// `ccm`, the board's core-coupled RAM (its `.ccmram` section: the carver), counted apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageSize {
    pub text: u64,
    pub data: u64,
    pub bss: u64,
    pub ccm: u64,
}

/// The STM32F405's core-coupled RAM.
pub const BOARD_CCM: u64 = 64 * 1024;

/// The image's own report line (`mema-image: key=value ...`).
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct QemuReport {
    pub fields: Vec<(String, u64)>,
}

impl QemuReport {
    pub fn parse(text: &str) -> Option<Self> {
        let line = text.lines().find(|l| l.starts_with("mema-image:"))?;
        let fields = line
            .split_whitespace()
            .skip(1)
            .filter_map(|kv| {
                let (k, v) = kv.split_once('=')?;
                Some((k.to_string(), v.parse().ok()?))
            })
            .collect();
        Some(Self { fields })
    }

    pub fn get(&self, key: &str) -> Option<u64> {
        self.fields.iter().find(|(k, _)| k == key).map(|&(_, v)| v)
    }

    /// Instructions per SysTick tick, from the calibration loop.
    fn per_tick(&self) -> Option<f64> {
        Some(self.get("calib_insns")? as f64 / self.get("calib_ticks")?.max(1) as f64)
    }

    /// Instructions per ingested point (decode + map, refits included).
    pub fn instructions_per_point(&self) -> Option<f64> {
        Some(
            self.get("ingest_ticks")? as f64 * self.per_tick()? / self.get("points")?.max(1) as f64,
        )
    }

    /// Instructions of a SysTick count the image reported under `key`.
    pub fn instructions(&self, key: &str) -> Option<f64> {
        Some(self.get(key)? as f64 * self.per_tick()?)
    }

    /// The tick lines: the longest ticks against the ring's fill time, and the costs per point,
    /// per freeze/merge/refit and per wire byte (the prices of the paced ring test).
    pub fn tick_text(&self) -> Option<String> {
        let ins = |k: &str| self.instructions(k);
        let plain = ins("tick_plain_max_ticks")?;
        let longest_unit = ins("tick_unit_max_ticks")?.max(ins("tick_merge_max_ticks")?);
        let prices = self.prices()?;
        let (fits, passes) = (self.get("unit_ticks")?, self.get("merge_ticks")?);
        let scans = self.get("scan_ticks").unwrap_or(0);
        let longest_scan = ins("tick_scan_max_ticks").unwrap_or(0.0);
        let longest_unit = longest_unit.max(longest_scan);
        let per_byte = ins("ingest_ticks")? / self.get("bytes")?.max(1) as f64;
        let fill_s = RX_CAPACITY as f64 / crate::pacing::LINK_BYTES_PER_S;
        let fill = fill_s * crate::pacing::CPU_HZ / 1.5;
        let cycles_per_byte = crate::pacing::CPU_HZ / crate::pacing::LINK_BYTES_PER_S;
        Some(format!(
            "  ticks: {}; longest {plain:.0} instructions mapping points only (at most {}), {longest_unit:.0} with a fit or a merge pass ({fits} fit ticks, {passes} merge-pass ticks)\n\
             \x20 the {RX_CAPACITY}-byte ring fills in {:.1} ms at 921,600 baud: {fill:.0} instructions at 168 MHz and 1.5 cycles each, {:.1}x the longest tick\n\
             \x20 per point (point-only ticks) {:.0} instructions, per fit (freeze or refit) {:.0}, per merge pass {:.0}, per wire byte over the run {per_byte:.0} (the link leaves {cycles_per_byte:.0} cycles a byte at 168 MHz)\n\
             \x20 per scan of the frozen store for pairs to coarsen (its freezes included) {:.0}, longest {longest_scan:.0} ({scans} scan ticks)\n",
            self.get("ticks")?,
            mema_firmware::TICK_POINTS,
            fill_s * 1e3,
            fill / plain.max(longest_unit),
            prices.per_point,
            prices.per_fit,
            prices.per_merge_pass,
            prices.per_scan,
        ))
    }

    /// The paced ring's prices ([`crate::pacing::TickCost`]): per point from the point-only
    /// ticks, per fit and per merge pass from their ticks less their points.
    pub fn prices(&self) -> Option<crate::pacing::TickCost> {
        let ins = |k: &str| self.instructions(k);
        let per_point = ins("tick_plain_sum_ticks")? / self.get("tick_plain_points")?.max(1) as f64;
        let unit = |kind: &str, count: &str| -> Option<f64> {
            let points = self.get(&format!("tick_{kind}_points"))? as f64;
            Some(
                (ins(&format!("tick_{kind}_sum_ticks"))? - per_point * points)
                    / self.get(count)?.max(1) as f64,
            )
        };
        Some(crate::pacing::TickCost {
            per_point,
            per_fit: unit("unit", "unit_ticks")?,
            per_merge_pass: unit("merge", "merge_ticks")?,
            // A report of an image before scans were timed apart has none.
            per_scan: unit("scan", "scan_ticks").unwrap_or(0.0),
        })
    }

    /// Instructions of `finish` (every cluster refitted) and the map's encoding.
    pub fn finish_instructions(&self) -> Option<f64> {
        Some(self.get("finish_ticks")? as f64 * self.per_tick()?)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub cluster_bytes: usize,
    pub rows: Vec<StaticRow>,
    pub image: Option<ImageSize>,
    pub qemu: Option<QemuReport>,
    /// The STM32F405 board's image, and what one run of it measured (`board.sh`'s summary).
    pub board: Option<ImageSize>,
    pub board_run: Option<BoardRun>,
}

/// The STM32F405 board: 1 MiB of flash, 128 KiB of SRAM (its 64 KiB of CCM aside).
pub const BOARD_FLASH: u64 = 1024 * 1024;
pub const BOARD_SRAM: u64 = 128 * 1024;

/// What the board measured of itself in one run (the timing frame, through `mema device
/// --json`, the last line `firmware-sim/board.sh` prints).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardRun {
    pub per_point: f64,
    pub longest_tick: f64,
    pub stack_bytes: u64,
}

impl BoardRun {
    /// From `board.sh`'s summary line.
    pub fn parse(text: &str) -> Option<Self> {
        let line = text.lines().rev().find(|l| l.contains("\"per_point\""))?;
        let number = |key: &str| -> Option<f64> {
            let at = line.find(&format!("\"{key}\":"))? + key.len() + 3;
            let rest = line.get(at..)?;
            let end = rest
                .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
                .unwrap_or(rest.len());
            rest.get(..end)?.parse().ok()
        };
        Some(Self {
            per_point: number("per_point")?,
            longest_tick: number("longest_tick")?,
            stack_bytes: number("stack_bytes")? as u64,
        })
    }
}

#[derive(Debug)]
pub enum BudgetError {
    LlvmSize(String),
    QemuReport(String),
}

impl std::fmt::Display for BudgetError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::LlvmSize(m) => write!(f, "llvm-size: {m}"),
            Self::QemuReport(m) => write!(f, "QEMU report: {m}"),
        }
    }
}

impl std::error::Error for BudgetError {}

pub fn llvm_size(image: &Path) -> Result<ImageSize, BudgetError> {
    let out = Command::new("llvm-size")
        .arg(image)
        .output()
        .map_err(|e| BudgetError::LlvmSize(format!("cannot run it ({e}); install llvm")))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let numbers: Vec<u64> = text
        .lines()
        .nth(1)
        .unwrap_or("")
        .split_whitespace()
        .take(3)
        .filter_map(|v| v.parse().ok())
        .collect();
    // The Berkeley totals count a section of no contents as bss wherever it lies: the CCM's
    // is taken back out, from the sections' own sizes.
    let ccm = Command::new("llvm-size")
        .args(["-A"])
        .arg(image)
        .output()
        .ok()
        .and_then(|out| {
            String::from_utf8_lossy(&out.stdout)
                .lines()
                .find(|l| l.starts_with(".ccmram"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0);
    match numbers[..] {
        [text, data, bss] => Ok(ImageSize {
            text,
            data,
            bss: bss.saturating_sub(ccm),
            ccm,
        }),
        _ => Err(BudgetError::LlvmSize(format!(
            "{}: unexpected output {text:?} {}",
            image.display(),
            String::from_utf8_lossy(&out.stderr)
        ))),
    }
}

/// The budget: static RAM by layout, and each image given (the 64 KiB image with its QEMU
/// report, the board's with its run's summary).
pub fn report(
    image: Option<&Path>,
    qemu: Option<&Path>,
    board: Option<&Path>,
    board_run: Option<&Path>,
) -> Result<Report, BudgetError> {
    let image = image.map(llvm_size).transpose()?;
    let board = board.map(llvm_size).transpose()?;
    let board_run = match board_run {
        None => None,
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| BudgetError::QemuReport(format!("{}: {e}", path.display())))?;
            Some(BoardRun::parse(&text).ok_or_else(|| {
                BudgetError::QemuReport(format!("{}: no board.sh summary", path.display()))
            })?)
        }
    };
    let qemu = match qemu {
        None => None,
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| BudgetError::QemuReport(format!("{}: {e}", path.display())))?;
            Some(QemuReport::parse(&text).ok_or_else(|| {
                BudgetError::QemuReport(format!("{}: no `mema-image:` line", path.display()))
            })?)
        }
    };
    Ok(Report {
        cluster_bytes: size_of::<StreamCluster>(),
        rows: vec![
            row::<150, 512, 0>(),
            row::<400, 1024, 0>(),
            row::<IMAGE_WORKING, IMAGE_BUCKETS, IMAGE_FROZEN>(),
            row::<BOARD_WORKING, IMAGE_BUCKETS, BOARD_FROZEN>(),
            row::<1000, 2048, 0>(),
        ],
        image,
        qemu,
        board,
        board_run,
    })
}

fn kib(b: u64) -> String {
    format!("{:.1} KiB", b as f64 / 1024.0)
}

impl Report {
    pub fn text(&self) -> String {
        let target = TARGET_BOARD.ram_bytes as u64;
        let stack = TARGET_BOARD.stack_bytes as u64;
        let mut s = format!(
            "static RAM of the firmware state (size_of; a working cluster is {} bytes: 24 integer moment sums with their exponents, centre, entity; a frozen entity {} bytes)\n\
             {:>5} {:>8} {:>7} {:>7} {:>12} {:>10} {:>8} {:>14} {:>12}  under 64 KiB? (+ {} stack)\n",
            self.cluster_bytes,
            size_of::<mema_core::stream::FrozenEntity>(),
            "K",
            "working",
            "frozen",
            "buckets",
            "mapper",
            "decoder",
            "ring",
            "firmware",
            "snapshot",
            kib(stack),
        );
        for r in &self.rows {
            let fits = |bytes: u64| if bytes < target { "yes" } else { "no" };
            s += &format!(
                "{:>5} {:>8} {:>7} {:>7} {:>12} {:>10} {:>8} {:>14} {:>12}  {} ({})\n",
                r.k,
                r.working,
                r.frozen,
                r.buckets,
                kib(r.mapper as u64),
                kib(r.decoder as u64),
                kib(r.ring as u64),
                kib(r.firmware as u64),
                kib(r.snapshot as u64),
                fits(r.firmware as u64),
                fits(r.firmware as u64 + stack),
            );
        }
        let per_cluster = self
            .rows
            .first()
            .map_or(0, |r| (r.firmware as f64 / r.k as f64).round() as usize);
        s += &format!(
            "  K that fits 64 KiB beside an 8 KiB stack at this layout: about {}\n",
            (TARGET_BOARD.ram_bytes - TARGET_BOARD.stack_bytes - 2 * RX_CAPACITY)
                / per_cluster.max(1)
        );
        // The floor under any all-working layout that keeps the agreement: the 24 sums (u..u^4
        // per axis; uv, u^2 v, u v^2, u^2 v^2 per pair) at 62-bit mantissas, since 48-bit f64
        // sums already fail the reference. Hence frozen entities for K = 400 in 64 KiB.
        s += &format!(
            "  the moment sums alone of 400 working clusters: {} (24 x 8-byte mantissas + 24 exponent bytes each); narrower f64 sums: `reference --sum-bits N`\n",
            kib(400 * 24 * (size_of::<i64>() + 1) as u64)
        );
        if let Some(i) = self.image {
            let yes = |fits: bool| if fits { "yes" } else { "no" };
            s += &format!(
                "image (thumbv7em-none-eabihf, K = {}: {IMAGE_WORKING} working + {IMAGE_FROZEN} frozen): flash {} (text {} + data {}), static RAM {} (data + bss {}); flash under 64 KiB: {}\n",
                IMAGE_WORKING + IMAGE_FROZEN,
                kib(i.text + i.data),
                i.text,
                i.data,
                kib(i.data + i.bss),
                i.data + i.bss,
                yes(i.text + i.data < 64 * 1024),
            );
            if let Some(q) = &self.qemu {
                let stack = ["stack_boot", "stack_tick", "stack_finish"]
                    .iter()
                    .filter_map(|k| q.get(k))
                    .max()
                    .unwrap_or(0);
                let ram = i.data + i.bss + stack;
                s += &format!(
                    "  RAM in use: static {} + stack high-water {} = {}; under 64 KiB: {}\n",
                    kib(i.data + i.bss),
                    kib(stack),
                    kib(ram),
                    yes(ram < target),
                );
            }
        }
        if let Some(q) = &self.qemu {
            let g = |k: &str| q.get(k).unwrap_or(0);
            // Shells are made, not fitted: no DE at a freeze nor at the end.
            let (model, made, at_finish) = if g("shells") == 1 {
                ("shells", "made a shell", "shells made")
            } else {
                ("paper", "fitted by DE", "refitted")
            };
            s += &format!(
                "QEMU mps2-an386 (-icount shift=0), model {model}: {} points, {} entities\n\
                 \x20 stack high-water: boot {} B, ingest ticks {} B, finish {} B (painted stack)\n\
                 \x20 instructions per ingested point: {:.0} ({} clusters frozen, each {made} as it froze); finish ({} working clusters {at_finish} + encode): {:.3e} instructions\n\
                 \x20 (QEMU counts instructions, not cycles: a Cortex-M4F takes about 1-1.5 cycles per\n\
                 \x20 instruction on this integer and soft-float f64 code)\n",
                g("points"),
                g("entities"),
                g("stack_boot"),
                g("stack_tick"),
                g("stack_finish"),
                q.instructions_per_point().unwrap_or(0.0),
                g("frozen"),
                g("entities").saturating_sub(g("frozen")),
                q.finish_instructions().unwrap_or(0.0),
            );
            s += &q.tick_text().unwrap_or_default();
        }
        s += &self.board_text();
        s
    }

    fn board_text(&self) -> String {
        let Some(b) = self.board else {
            return String::new();
        };
        let (flash, ram) = (b.text + b.data, b.data + b.bss);
        let mut s = format!(
            "board image (STM32F405, thumbv7em-none-eabihf, K = {}: {BOARD_WORKING} working + {BOARD_FROZEN} frozen): flash {} (text {} + data {}) of 1 MiB, static RAM {} (data + bss {}) of 128 KiB SRAM, and the carver's {} of its 64 KiB of CCM ({} bytes; fits: {})\n",
            BOARD_WORKING + BOARD_FROZEN,
            kib(flash),
            b.text,
            b.data,
            kib(ram),
            ram,
            kib(b.ccm),
            b.ccm,
            if b.ccm <= BOARD_CCM { "yes" } else { "no" },
        );
        if let Some(r) = self.board_run {
            let used = ram + r.stack_bytes;
            s += &format!(
                "  RAM in use: static {} + stack high-water {} = {}; under 128 KiB: {}\n\
                 \x20 under QEMU netduinoplus2 (-icount shift=0): {:.0} instructions per ingested point (receive interrupt and downlink included), longest tick {:.0}\n",
                kib(ram),
                kib(r.stack_bytes),
                kib(used),
                if used < BOARD_SRAM && flash < BOARD_FLASH {
                    "yes"
                } else {
                    "no"
                },
                r.per_point,
                r.longest_tick,
            );
        }
        s
    }

    pub fn json(&self) -> String {
        let rows: Vec<String> = self
            .rows
            .iter()
            .map(|r| {
                format!(
                    "{{\"k\":{},\"working\":{},\"frozen\":{},\"buckets\":{},\"mapper\":{},\"decoder\":{},\"ring\":{},\"firmware\":{},\"snapshot\":{}}}",
                    r.k, r.working, r.frozen, r.buckets, r.mapper, r.decoder, r.ring, r.firmware, r.snapshot
                )
            })
            .collect();
        let image = self.image.map_or("null".to_string(), |i| {
            format!(
                "{{\"text\":{},\"data\":{},\"bss\":{}}}",
                i.text, i.data, i.bss
            )
        });
        let qemu = self.qemu.as_ref().map_or("null".to_string(), |q| {
            let fields: Vec<String> = q
                .fields
                .iter()
                .map(|(k, v)| format!("\"{k}\":{v}"))
                .collect();
            format!(
                "{{{},\"instructions_per_point\":{:.1}}}",
                fields.join(","),
                q.instructions_per_point().unwrap_or(0.0)
            )
        });
        let board = self.board.map_or("null".to_string(), |b| {
            let run = self.board_run.map_or("null".to_string(), |r| {
                format!(
                    "{{\"per_point\":{:.1},\"longest_tick\":{:.0},\"stack_bytes\":{}}}",
                    r.per_point, r.longest_tick, r.stack_bytes
                )
            });
            format!(
                "{{\"text\":{},\"data\":{},\"bss\":{},\"ccm\":{},\"run\":{run}}}",
                b.text, b.data, b.bss, b.ccm
            )
        });
        format!(
            "{{\"cluster_bytes\":{},\"static\":[{}],\"image\":{},\"qemu\":{},\"board\":{}}}",
            self.cluster_bytes,
            rows.join(","),
            image,
            qemu,
            board
        )
    }
}
