//! Registration files: several scans of one scene, each with its scanner's pose, as Stanford's
//! `.conf` gives them (the bunny's `bun.conf`).
//!
//! A line `bmesh FILE tx ty tz qx qy qz qw` names a scan (`FILE`, relative to the `.conf`) and
//! the pose that takes its points into the common frame:
//!
//! `x_world = R(q)^T x_scan + t`
//!
//! with `R(q)` the rotation matrix of the unit quaternion `q` (scalar last). The transpose is
//! Stanford's convention: applying `R(q)` instead leaves scans of the shared bunny 4-31 mm off
//! its merged reconstruction, the transpose a median 0.53-0.57 mm (its point spacing; tested).
//! So the scanner's pose, sensor to world as the wire carries it, is `(t, conj(q))`. Other
//! lines (`camera ...`, blank, `#` comments) are skipped.

use anyhow::{Context, Result, bail};
use mema_core::rotation::quaternion_matrix;
use std::path::{Path, PathBuf};

/// One scan of a registration file and its pose.
#[derive(Clone, Debug, PartialEq)]
pub struct RegisteredScan {
    pub path: PathBuf,
    /// `t`, in the scans' unit.
    pub translation: [f64; 3],
    /// `q` as the file gives it, `[x, y, z, w]`: world to scanner.
    pub quaternion: [f64; 4],
}

impl RegisteredScan {
    /// The scanner's rotation, sensor to world: `conj(q)`, `[x, y, z, w]`.
    pub fn sensor_to_world(&self) -> [f64; 4] {
        let [x, y, z, w] = self.quaternion;
        [-x, -y, -z, w]
    }

    /// `x_scan` in the common frame: `R(q)^T x_scan + t`, in f64.
    pub fn to_world(&self, p: [f64; 3]) -> [f64; 3] {
        to_world(self.translation, self.sensor_to_world(), p)
    }
}

/// A point of a sensor's frame in the world's, given the sensor's pose (sensor to world):
/// `R(rotation) p + translation`, in f64, with `rotation` `[x, y, z, w]`. Every scan with a
/// pose (a registration file's, a bag's) goes to the world through this one expression, so the
/// same numbers give the same bits.
pub fn to_world(translation: [f64; 3], rotation: [f64; 4], p: [f64; 3]) -> [f64; 3] {
    let m = quaternion_matrix(rotation);
    let t = translation;
    [0, 1, 2].map(|i| m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + t[i])
}

/// Whether `path` is a registration file: its first line that says anything starts with
/// `bmesh` or `camera`. Point-cloud readers recognise their formats by content, and so does
/// this, so a `.conf` is never taken for XYZ text.
pub(crate) fn is_registration(path: &Path) -> bool {
    let Ok(meta) = std::fs::metadata(path) else {
        return false;
    };
    if !meta.is_file() {
        return false;
    }
    let Ok(mut file) = std::fs::File::open(path) else {
        return false;
    };
    let mut head = vec![0u8; 4096];
    let n = std::io::Read::read(&mut file, &mut head).unwrap_or(0);
    let text = String::from_utf8_lossy(head.get(..n).unwrap_or(&[])).into_owned();
    text.lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .and_then(|l| l.split_whitespace().next())
        .is_some_and(|word| word == "bmesh" || word == "camera")
}

/// The scans of registration file `path`, in its order.
pub fn read_registration(path: &Path) -> Result<Vec<RegisteredScan>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the registration file", path.display()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut scans = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("bmesh") => {}
            None | Some("camera") => continue,
            Some(word) if word.starts_with('#') => continue,
            Some(word) => bail!(
                "{}:{}: `{word}`: a registration file has `bmesh FILE tx ty tz qx qy qz qw` lines",
                path.display(),
                i + 1
            ),
        }
        let fields: Vec<&str> = words.collect();
        let [file, numbers @ ..] = fields.as_slice() else {
            bail!("{}:{}: bmesh without a file", path.display(), i + 1);
        };
        let values: Vec<f64> = numbers
            .iter()
            .map(|w| w.parse::<f64>())
            .collect::<Result<_, _>>()
            .ok()
            .filter(|v: &Vec<f64>| v.len() == 7 && v.iter().all(|x| x.is_finite()))
            .with_context(|| {
                format!(
                    "{}:{}: `bmesh {file}` needs seven finite numbers, tx ty tz qx qy qz qw",
                    path.display(),
                    i + 1
                )
            })?;
        let quaternion = [values[3], values[4], values[5], values[6]];
        let norm = quaternion.iter().map(|v| v * v).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            bail!(
                "{}:{}: the rotation of {file} is not a unit quaternion (norm {norm})",
                path.display(),
                i + 1
            );
        }
        scans.push(RegisteredScan {
            path: dir.join(file),
            translation: [values[0], values[1], values[2]],
            quaternion,
        });
    }
    if scans.is_empty() {
        bail!("{}: no `bmesh` line, no scan to read", path.display());
    }
    Ok(scans)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quarter_turn_goes_by_the_transpose() {
        let h = 0.5f64.sqrt();
        // q = a quarter turn about z; R(q)^T turns the other way: (1, 0, 0) -> (0, -1, 0).
        let scan = RegisteredScan {
            path: PathBuf::from("s.ply"),
            translation: [1.0, 2.0, 3.0],
            quaternion: [0.0, 0.0, h, h],
        };
        let w = scan.to_world([1.0, 0.0, 0.0]);
        let want = [1.0, 1.0, 3.0];
        assert!(
            w.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12),
            "{w:?}"
        );
    }
}
