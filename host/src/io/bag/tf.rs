//! `tf2_msgs/msg/TFMessage` and the transform tree of a bag's `/tf` and `/tf_static`.
//!
//! A `TransformStamped` is `header` (stamp, frame_id: the parent), `child_frame_id` and a
//! `Transform`: translation (Vector3, three f64) and rotation (Quaternion, f64 x, y, z, w).
//! It takes a point of the child frame to the parent's: `x_parent = R(q) x_child + t`.
//!
//! **Lookups** ([`TfTree::lookup`]): static transforms (`/tf_static`) hold at every time. A
//! dynamic one (`/tf`) holds from its stamp until the next of the same child: a lookup at time
//! `s` takes, for each frame on the way, the latest transform stamped at or before `s`, with no
//! interpolation (tf2 interpolates between the two around `s`; holding the last one keeps a
//! transform stamped exactly at a scan's time exact, bit for bit, and never invents a pose
//! between two that were measured). A frame whose dynamic transforms all come after `s` has
//! none at `s`. The path may go up from the source and down to the target through their
//! nearest common ancestor, over any number of frames. Names compare without a leading `/`.

use std::collections::HashMap;

use super::cdr::{Cdr, CdrError, Stamp};
use mema_core::rotation::quaternion_matrix;

/// A rigid transform: `x_parent = R(rotation) x_child + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub translation: [f64; 3],
    /// `[x, y, z, w]`, scalar last.
    pub rotation: [f64; 4],
}

impl Transform {
    pub const IDENTITY: Self = Self {
        translation: [0.0; 3],
        rotation: [0.0, 0.0, 0.0, 1.0],
    };

    /// `R p`.
    fn rotate(&self, p: [f64; 3]) -> [f64; 3] {
        let m = quaternion_matrix(self.rotation);
        [0, 1, 2].map(|i| m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2])
    }

    /// `self ∘ inner`: first `inner`, then `self`.
    pub fn then(inner: &Self, outer: &Self) -> Self {
        let r = outer.rotate(inner.translation);
        let [x1, y1, z1, w1] = outer.rotation;
        let [x2, y2, z2, w2] = inner.rotation;
        Self {
            translation: [0, 1, 2].map(|i| r[i] + outer.translation[i]),
            rotation: [
                w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
                w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            ],
        }
    }

    /// The inverse: parent to child.
    pub fn inverse(&self) -> Self {
        let [x, y, z, w] = self.rotation;
        let inv = Self {
            translation: [0.0; 3],
            rotation: [-x, -y, -z, w],
        };
        let t = inv.rotate(self.translation);
        Self {
            translation: t.map(|v| -v),
            ..inv
        }
    }
}

/// One `geometry_msgs/msg/TransformStamped`.
#[derive(Clone, Debug, PartialEq)]
pub struct TransformStamped {
    pub stamp: Stamp,
    pub parent: String,
    pub child: String,
    pub transform: Transform,
}

/// The fewest bytes a `TransformStamped` takes: stamp, two empty strings' lengths, 7 f64.
const LEAST_TRANSFORM: usize = 8 + 4 + 4 + 7 * 8;

/// Decodes the CDR bytes of one `TFMessage`.
pub fn parse_tf_message(message: &[u8]) -> Result<Vec<TransformStamped>, CdrError> {
    let mut c = Cdr::new(message)?;
    let n = c.count(LEAST_TRANSFORM, "transforms")?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let header = c.header()?;
        let child = c.string("child_frame_id")?.to_owned();
        let mut f = |what| c.f64(what);
        let translation = [
            f("translation.x")?,
            f("translation.y")?,
            f("translation.z")?,
        ];
        let rotation = [
            f("rotation.x")?,
            f("rotation.y")?,
            f("rotation.z")?,
            f("rotation.w")?,
        ];
        out.push(TransformStamped {
            stamp: header.stamp,
            parent: header.frame_id,
            child,
            transform: Transform {
                translation,
                rotation,
            },
        });
    }
    Ok(out)
}

/// Why no transform joins two frames at a time.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TfError {
    /// The frames are in different trees (or one is in none).
    #[error(
        "no transform from `{from}` to `{to}` at {stamp}: `{from}` reaches {from_root}, `{to}` reaches {to_root}, and the two never meet (frames on /tf and /tf_static: {known})"
    )]
    NotConnected {
        from: String,
        to: String,
        stamp: Stamp,
        from_root: String,
        to_root: String,
        known: String,
    },
    /// A frame's only transforms are dynamic and all stamped after the time asked for.
    #[error(
        "no transform from `{from}` to `{to}` at {stamp}: `{child}`'s transform to `{parent}` is first stamped {first}, after it"
    )]
    BeforeFirst {
        from: String,
        to: String,
        stamp: Stamp,
        child: String,
        parent: String,
        first: Stamp,
    },
    /// A transform that is not a rotation and a translation of finite numbers.
    #[error(
        "the transform from `{child}` to `{parent}` at {stamp} is not a finite unit quaternion and translation ({transform:?})"
    )]
    NotRigid {
        child: String,
        parent: String,
        stamp: Stamp,
        transform: Transform,
    },
    /// The parents run in a circle (or deeper than any real tree).
    #[error("the frames above `{from}` run in a circle or deeper than {MAX_DEPTH} frames")]
    TooDeep { from: String },
}

/// A frame's name as tf2 compares it: without a leading `/` (ROS 1's `/base_link` is ROS 2's
/// `base_link`).
pub fn frame_name(name: &str) -> &str {
    name.strip_prefix('/').unwrap_or(name)
}

/// The most frames from a frame up to its root.
pub const MAX_DEPTH: usize = 256;

/// A bag's transforms, by child frame.
#[derive(Debug, Default)]
pub struct TfTree {
    statics: HashMap<String, (String, Transform, Stamp)>,
    /// Each child's transforms, sorted by stamp once [`TfTree::finish`] ran.
    dynamic: HashMap<String, Vec<(Stamp, String, Transform)>>,
}

/// Where a frame's walk up ended without a parent: the root, or a frame whose transforms
/// start after the time.
enum Up {
    Parent(String, Transform),
    Root,
}

impl TfTree {
    /// A transform from `/tf_static`: the latest one read for a child wins, as tf2 keeps it.
    pub fn add_static(&mut self, t: TransformStamped) {
        self.statics.insert(
            frame_name(&t.child).to_owned(),
            (frame_name(&t.parent).to_owned(), t.transform, t.stamp),
        );
    }

    /// A transform from `/tf`.
    pub fn add_dynamic(&mut self, t: TransformStamped) {
        self.dynamic
            .entry(frame_name(&t.child).to_owned())
            .or_default()
            .push((t.stamp, frame_name(&t.parent).to_owned(), t.transform));
    }

    /// Sorts each child's transforms by stamp (stable: of equal stamps, the one read last wins).
    pub fn finish(&mut self) {
        for list in self.dynamic.values_mut() {
            list.sort_by_key(|(stamp, ..)| *stamp);
        }
    }

    /// Whether the tree holds any transform.
    pub fn is_empty(&self) -> bool {
        self.statics.is_empty() && self.dynamic.is_empty()
    }

    /// Every frame named, sorted, for messages.
    fn known(&self) -> String {
        let mut names: Vec<&str> = self
            .statics
            .iter()
            .map(|(c, (p, ..))| [c.as_str(), p.as_str()])
            .chain(
                self.dynamic
                    .iter()
                    .flat_map(|(c, l)| l.iter().map(move |(_, p, _)| [c.as_str(), p.as_str()])),
            )
            .flatten()
            .collect();
        names.sort_unstable();
        names.dedup();
        if names.is_empty() {
            "none".into()
        } else {
            names.join(", ")
        }
    }

    /// `child`'s parent at `stamp`.
    fn up(&self, child: &str, stamp: Stamp, from: &str, to: &str) -> Result<Up, Box<TfError>> {
        let (parent, transform, at) = if let Some((p, t, s)) = self.statics.get(child) {
            (p, *t, *s)
        } else if let Some(list) = self.dynamic.get(child) {
            let held = list.partition_point(|(s, ..)| *s <= stamp);
            match held.checked_sub(1).and_then(|i| list.get(i)) {
                Some((s, p, t)) => (p, *t, *s),
                None => {
                    let Some((first, parent, _)) = list.first() else {
                        return Ok(Up::Root);
                    };
                    return Err(Box::new(TfError::BeforeFirst {
                        from: from.into(),
                        to: to.into(),
                        stamp,
                        child: child.into(),
                        parent: parent.clone(),
                        first: *first,
                    }));
                }
            }
        } else {
            return Ok(Up::Root);
        };
        let norm = transform.rotation.iter().map(|v| v * v).sum::<f64>().sqrt();
        let finite = transform.translation.iter().all(|v| v.is_finite());
        if !finite || !norm.is_finite() || (norm - 1.0).abs() > 1e-3 {
            return Err(Box::new(TfError::NotRigid {
                child: child.into(),
                parent: parent.clone(),
                stamp: at,
                transform,
            }));
        }
        Ok(Up::Parent(parent.clone(), transform))
    }

    /// The frames from `frame` up to its root at `stamp`, each with the transform from
    /// `frame` to it (the first is `frame` itself, at the identity).
    fn chain(
        &self,
        frame: &str,
        stamp: Stamp,
        from: &str,
        to: &str,
    ) -> Result<Vec<(String, Transform)>, Box<TfError>> {
        let mut chain = vec![(frame.to_owned(), Transform::IDENTITY)];
        while let Some((name, acc)) = chain.last() {
            match self.up(name, stamp, from, to)? {
                Up::Root => break,
                Up::Parent(parent, t) => {
                    // The first step is the transform itself, not composed with the identity,
                    // so a frame one step below its target gets the bag's numbers exactly.
                    let next = if chain.len() == 1 {
                        t
                    } else {
                        Transform::then(acc, &t)
                    };
                    if chain.len() > MAX_DEPTH || chain.iter().any(|(n, _)| *n == parent) {
                        return Err(Box::new(TfError::TooDeep { from: frame.into() }));
                    }
                    chain.push((parent, next));
                }
            }
        }
        Ok(chain)
    }

    /// The transform taking points of frame `from` to frame `to` at `stamp`.
    /// The error is boxed: it names the frames, and a lookup runs per message.
    pub fn lookup(&self, from: &str, to: &str, stamp: Stamp) -> Result<Transform, Box<TfError>> {
        let (from, to) = (frame_name(from), frame_name(to));
        if from == to {
            return Ok(Transform::IDENTITY);
        }
        let up = self.chain(from, stamp, from, to)?;
        if let Some((_, t)) = up.iter().find(|(name, _)| name == to) {
            return Ok(*t);
        }
        let down = self.chain(to, stamp, from, to)?;
        for (name, from_to_common) in &up {
            if let Some((_, to_to_common)) = down.iter().find(|(n, _)| n == name) {
                return Ok(Transform::then(from_to_common, &to_to_common.inverse()));
            }
        }
        let root = |c: &[(String, Transform)]| c.last().map(|(n, _)| n.clone()).unwrap_or_default();
        Err(Box::new(TfError::NotConnected {
            from: from.into(),
            to: to.into(),
            stamp,
            from_root: root(&up),
            to_root: root(&down),
            known: self.known(),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stamped(parent: &str, child: &str, sec: i32, t: [f64; 3], q: [f64; 4]) -> TransformStamped {
        TransformStamped {
            stamp: Stamp { sec, nanosec: 0 },
            parent: parent.into(),
            child: child.into(),
            transform: Transform {
                translation: t,
                rotation: q,
            },
        }
    }

    fn near(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn chains_hold_the_latest_and_go_down_too() {
        let h = 0.5f64.sqrt();
        let mut tree = TfTree::default();
        // robot turned a quarter about z, 1 m along x; scanner 1 m ahead of the robot.
        tree.add_dynamic(stamped(
            "world",
            "robot",
            10,
            [1.0, 0.0, 0.0],
            [0.0, 0.0, h, h],
        ));
        tree.add_dynamic(stamped(
            "world",
            "robot",
            20,
            [5.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ));
        tree.add_static(stamped(
            "/robot",
            "scanner",
            0,
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ));
        tree.finish();
        let at = |sec| Stamp { sec, nanosec: 0 };
        let t = tree.lookup("scanner", "world", at(15)).unwrap();
        assert!(near(t.translation, [1.0, 1.0, 0.0]), "{t:?}");
        let t = tree.lookup("/scanner", "world", at(20)).unwrap();
        assert!(near(t.translation, [6.0, 0.0, 0.0]), "{t:?}");
        // Down: world in the scanner's frame at 20 s.
        let t = tree.lookup("world", "scanner", at(20)).unwrap();
        assert!(near(t.translation, [-6.0, 0.0, 0.0]), "{t:?}");
        assert!(matches!(
            tree.lookup("scanner", "world", at(5)).map_err(|e| *e),
            Err(TfError::BeforeFirst { .. })
        ));
        let e = tree.lookup("scanner", "map", at(15)).unwrap_err();
        assert!(e.to_string().contains("`scanner` reaches world"), "{e}");
    }
}
