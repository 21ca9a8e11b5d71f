//! The simulator's main loop: a byte source (optionally behind the fault injector) delivers a
//! chunk, the "interrupt" copies it into the ring, the board runs one tick, and so on until the
//! end-of-stream frame or the end of the source. It logs the sequence number of every frame the
//! final mapper holds, so a test can rebuild the same map from those frames alone.

use std::collections::HashMap;

use mema_core::Point3;
use mema_core::link::receiver::{Receiver, metres_of_nm};
use mema_core::link::wire::DecoderStats;
use mema_core::map::EncodeError;
use mema_core::stream::{StreamMapper, StreamParams, StreamStats};

use crate::board::{Board, BoardError};
use crate::fault::{FaultConfig, FaultInjector, FaultStats};
use mema_firmware::source::{ByteSource, Delivery, UartSource};
use mema_firmware::{Firmware, FirmwareStats, Snapshot};

/// How a capture is played.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunConfig {
    /// Seeds the chunk sizes.
    pub chunk_seed: u64,
    /// Chunks are 1..=max_chunk bytes.
    pub max_chunk: usize,
    /// A snapshot is saved after every this many accepted frames (0: never).
    pub snapshot_every: u64,
    pub faults: Option<FaultConfig>,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            chunk_seed: 0,
            max_chunk: 256,
            snapshot_every: 16,
            faults: None,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct RunReport {
    /// The `.mema` bytes of the final map.
    pub map: Vec<u8>,
    /// Sequence numbers of the frames the final mapper holds, in the order it took them.
    pub accepted: Vec<u32>,
    pub firmware: FirmwareStats,
    pub decoder: DecoderStats,
    pub mapper: StreamStats,
    pub faults: FaultStats,
    pub ticks: u64,
    pub deliveries: u64,
    pub peak_pending: usize,
    pub peak_clusters: usize,
    /// Whether the end-of-stream frame arrived (after the last restart).
    pub end_of_stream: bool,
    /// The map's origin the receiver took (whole nanometres in the world): the first point of
    /// the first frame it accepted.
    pub origin: Option<[i64; 3]>,
}

#[derive(Debug)]
pub enum RunError {
    Board(BoardError),
    Encode(EncodeError),
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Board(e) => write!(f, "board: {e}"),
            Self::Encode(e) => write!(f, "map encoding: {e}"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<BoardError> for RunError {
    fn from(e: BoardError) -> Self {
        Self::Board(e)
    }
}

/// Plays `capture` into `firmware` on `board`, then finishes and encodes the map.
pub fn run<const K: usize, const G: usize, const F: usize>(
    board: &Board,
    firmware: &mut Firmware<K, G, F>,
    snapshot: &mut Snapshot<K, G, F>,
    capture: &[u8],
    config: &RunConfig,
) -> Result<RunReport, RunError> {
    let uart = UartSource::new(capture, config.chunk_seed, config.max_chunk);
    match config.faults {
        None => drive(board, firmware, snapshot, uart, config, |_| {
            FaultStats::default()
        }),
        Some(faults) => drive(
            board,
            firmware,
            snapshot,
            FaultInjector::new(uart, faults),
            config,
            |f| *f.stats(),
        ),
    }
}

fn drive<
    const K: usize,
    const G: usize,
    const F: usize,
    S: ByteSource<Error = core::convert::Infallible>,
>(
    board: &Board,
    firmware: &mut Firmware<K, G, F>,
    snapshot: &mut Snapshot<K, G, F>,
    mut source: S,
    config: &RunConfig,
    fault_stats: impl Fn(&S) -> FaultStats,
) -> Result<RunReport, RunError> {
    let mut accepted: Vec<u32> = Vec::new();
    let mut buf = [0u8; 1024];
    let mut deliveries = 0u64;
    loop {
        let delivery = match source.deliver(&mut buf) {
            Ok(d) => d,
            Err(e) => match e {},
        };
        deliveries += 1;
        match delivery {
            Delivery::End => break,
            Delivery::Reset => {
                firmware.restart_from(snapshot);
                accepted.truncate(snapshot.frames() as usize);
            }
            Delivery::Bytes(n) => {
                firmware.on_receive(buf.get(..n).unwrap_or(&[]));
                board.observe(firmware.pending(), firmware.mapper().clusters().len());
                while firmware.busy() {
                    board.tick(|| {
                        firmware.tick(|f| {
                            // A map started again keeps none of the frames before.
                            accepted.truncate(f.place as usize);
                            accepted.push(f.sequence);
                        })
                    })?;
                    board.observe(firmware.pending(), firmware.mapper().clusters().len());
                }
                let since = firmware.stats().frames.saturating_sub(snapshot.frames());
                let stale = !snapshot.is_of(firmware.stats());
                if config.snapshot_every > 0 && (since >= config.snapshot_every || stale) {
                    firmware.save(snapshot);
                }
                if firmware.stats().end_of_stream {
                    break;
                }
            }
        }
    }
    firmware.finish();
    let mut map = vec![0u8; firmware.mapper().encoded_len()];
    let len = firmware.encode_map(&mut map).map_err(RunError::Encode)?;
    map.truncate(len);
    Ok(RunReport {
        map,
        accepted,
        firmware: *firmware.stats(),
        decoder: *firmware.decoder_stats(),
        mapper: *firmware.mapper_stats(),
        faults: fault_stats(&source),
        ticks: board.ticks(),
        deliveries,
        peak_pending: board.peak_pending(),
        peak_clusters: board.peak_clusters(),
        end_of_stream: firmware.stats().end_of_stream,
        origin: firmware.map_origin(),
    })
}

/// Every points frame of a clean capture, by sequence number, as the mapper receives its points
/// (through their pose, around `origin`, whole nanometres in the world; `None`: the capture's
/// first point, as a receiver that gets every frame takes it).
pub fn frames_of(capture: &[u8], origin: Option<[i64; 3]>) -> HashMap<u32, Vec<Point3>> {
    // A restart (a glitched first pose outvoted) leaves the frames before it out of the map.
    let frames = std::cell::RefCell::new(HashMap::new());
    Receiver::resuming(origin, mema_core::link::receiver::DEFAULT_REACH).feed_all(
        capture,
        |frame, placement| {
            frames
                .borrow_mut()
                .insert(frame.sequence(), placement.points(&frame).collect());
        },
        || frames.borrow_mut().clear(),
    );
    frames.into_inner()
}

/// The map of an uninterrupted mapper fed exactly these frames, in this order: what a faulty or
/// reset run must equal. Frames missing from `frames` are an error (they were never sent).
pub fn map_of_frames<const K: usize, const G: usize, const F: usize>(
    params: StreamParams,
    sequences: &[u32],
    frames: &HashMap<u32, Vec<Point3>>,
    origin: Option<[i64; 3]>,
) -> Result<Vec<u8>, u32> {
    let mut mapper: Box<StreamMapper<K, G, F>> = Box::new(StreamMapper::new(params));
    for s in sequences {
        mapper.add_all(frames.get(s).ok_or(*s)?);
    }
    mapper.finish();
    let mut out = vec![0u8; mapper.encoded_len()];
    mapper
        .encode_into(metres_of_nm(origin.unwrap_or([0; 3])), &mut out)
        .map_err(|_| u32::MAX)?;
    Ok(out)
}
