//! The properties the readers' fuzz target checks (`host/fuzz/`, run by `scripts/fuzz.sh`
//! under cargo-fuzz) and the test suite's stable mutation loop checks on the same seeds: one
//! definition, as `mema_core::fuzz_checks` is for the core's decoders. A panic is the target's
//! own failure; the rest come back as the first [`Violation`].

use super::{Cloud, read_cloud_bytes};

/// The names the fuzzer's first byte picks from: the readers go by content, but KITTI `.bin`,
/// having no header, is chosen by its extension, and the errors name the file.
pub const NAMES: [&str; 7] = [
    "fuzz.ply", "fuzz.pcd", "fuzz.las", "fuzz.laz", "fuzz.xyz", "fuzz.bin", "fuzz.txt",
];

/// A property a reader broke.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Violation {
    /// A cloud came back with a point or its origin not finite.
    NonFinite { index: Option<usize> },
    /// A cloud came back with no points (that is an error: `NoFinitePoints`).
    EmptyCloud,
    /// The counts disagree: kept points plus dropped ones (not finite, left out by class,
    /// isolated, no-returns at their sensor) are not the slots read.
    Counts {
        points: usize,
        slots: usize,
        dropped: usize,
    },
    /// An error that is not one line starting with the file's name.
    Message(String),
}

/// What a reader made of the bytes, when it kept its promises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// A cloud of this many finite points.
    Cloud { points: usize },
    /// A one-line error naming the file.
    Refused,
}

/// Reads `bytes` under the name `NAMES[pick % 7]`: either a cloud of finite points whose
/// counts agree, or an error of one line naming the file.
pub fn cloud_bytes(pick: u8, bytes: &[u8]) -> Result<Outcome, Violation> {
    let name = NAMES[usize::from(pick) % NAMES.len()];
    match read_cloud_bytes(name, bytes) {
        Ok(cloud) => check_cloud(&cloud).map(|()| Outcome::Cloud {
            points: cloud.points.len(),
        }),
        Err(e) => {
            let msg = e.to_string();
            if msg.starts_with(&format!("{name}: ")) && !msg.contains('\n') {
                Ok(Outcome::Refused)
            } else {
                Err(Violation::Message(msg))
            }
        }
    }
}

/// What every cloud a reader returns must be.
pub fn check_cloud(cloud: &Cloud) -> Result<(), Violation> {
    if !cloud.origin.iter().all(|c| c.is_finite()) {
        return Err(Violation::NonFinite { index: None });
    }
    if let Some(index) = cloud
        .points
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(Violation::NonFinite { index: Some(index) });
    }
    if cloud.points.is_empty() {
        return Err(Violation::EmptyCloud);
    }
    // Slots hold every record read: kept, not finite, left out by its ASPRS class or isolated.
    let (points, slots) = (cloud.points.len(), cloud.slots);
    let dropped = cloud.dropped_non_finite
        + cloud.dropped_by_class.total()
        + cloud.outliers.dropped
        + cloud.no_returns;
    if points + dropped != slots {
        return Err(Violation::Counts {
            points,
            slots,
            dropped,
        });
    }
    Ok(())
}
