//! ROS 2 bags without ROS: `sensor_msgs/msg/PointCloud2` messages from an MCAP file, each put
//! in a chosen frame through the bag's `/tf` and `/tf_static`.
//!
//! A bag (an MCAP file, or a rosbag2 directory of them: [`crate::io::kind::InputKind::Bag`]) is
//! read in two passes over its files with the `mcap` crate's streaming reader, so memory holds
//! one record (or one chunk) at a time, never the file:
//! 1. the channels of type `sensor_msgs/msg/PointCloud2` and their message counts, and, when a
//!    frame is asked for, every `tf2_msgs/msg/TFMessage` on `/tf` (dynamic) and `/tf_static`
//!    (static) into a [`tf::TfTree`];
//! 2. the messages of the chosen topic ([`BagOptions::topic`]; without it, the bag's only
//!    PointCloud2 topic), decoded by hand from their CDR ([`cdr`], [`pointcloud2`]).
//!
//! **Each message is a scan** ([`BagScan`]): its points in its own frame (`header.frame_id`)
//! and, with [`BagOptions::frame`], the pose of that frame in the chosen one at the message's
//! stamp (see [`tf`] for how a time is looked up: the latest transform at or before it, no
//! interpolation). A message whose transform cannot be found is an error naming the frames,
//! never a scan left out or put at a wrong pose. Without a frame, the pose is the identity and
//! the messages' points are taken as they are.
//!
//! **Points** are read as f64 from x, y, z of any layout ([`pointcloud2`]); points with a NaN
//! or infinite coordinate are skipped and counted; a message with none left is counted and
//! skipped. Each message's points then go the way a point-cloud file's do (see
//! [`crate::io::read`]): centred on their bounding box into f32 offsets, kept as `origin +
//! offset` in f64. A scan of a bag therefore holds bit for bit what the same numbers read from
//! a PLY file hold, and a bag of a registration file's scans maps to the same map
//! (`tests/tests/bags.rs`).
//!
//! **Units.** ROS gives lengths in metres (REP 103); `--units` overrides that, scaling points
//! and translations alike.
//!
//! **Limits.** Every length and count in the file is checked against the bytes that hold it
//! before anything is allocated for it; a record is at most [`MAX_RECORD`] bytes. Chunks may
//! be uncompressed or zstd-compressed (lz4 is refused with the `mcap` crate's message).

pub mod cdr;
pub mod pointcloud2;
pub mod tf;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use crate::io::conf::to_world;
use crate::io::read::{Cloud, Ctx, Format, OutlierDrops, Points, ReadError, Screening};
use crate::io::units::{FileUnit, LengthUnit, Units};
use cdr::{CdrError, Stamp};
use pointcloud2::{LayoutError, PointCloud2};
use tf::{TfError, TfTree, Transform, parse_tf_message};

/// The first bytes of every MCAP file.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// The schema name of the point clouds read.
pub const POINTCLOUD2: &str = "sensor_msgs/msg/PointCloud2";

/// The schema name of `/tf` and `/tf_static`.
pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";

/// The largest record (or decompressed record of a chunk) read: 1 GiB, some 45 million points
/// of a 24-byte layout in one message.
pub const MAX_RECORD: usize = 1 << 30;

/// Which messages of a bag make the cloud, and in which frame.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BagOptions {
    /// The PointCloud2 topic (`--topic`); `None`: the bag's only one.
    pub topic: Option<String>,
    /// The frame every message is put in (`--frame`); `None`: each message's points as they
    /// are, in its own frame.
    pub frame: Option<String>,
}

/// One PointCloud2 message as a scan.
#[derive(Clone, Debug)]
pub struct BagScan {
    /// `header.frame_id`.
    pub frame_id: String,
    /// `header.stamp`.
    pub stamp: Stamp,
    /// The pose of `frame_id` in the chosen frame, sensor to world (metres); the identity
    /// without a frame.
    pub pose: Transform,
    /// The points in `frame_id`, in metres: `origin + offset` of the f32-centred cloud.
    pub points: Vec<[f64; 3]>,
}

impl BagScan {
    /// The points in the chosen frame: `R(q) p + t` in f64, exactly as a registration file's
    /// scans are taken to the world ([`crate::io::conf::to_world`]).
    pub fn world_points(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        self.points
            .iter()
            .map(|p| to_world(self.pose.translation, self.pose.rotation, *p))
    }
}

/// A bag's scans and what reading them counted.
#[derive(Clone, Debug)]
pub struct BagScans {
    pub topic: String,
    /// The frame the poses are in (`None`: none asked for).
    pub frame: Option<String>,
    pub scans: Vec<BagScan>,
    /// Messages on the topic.
    pub messages: usize,
    /// Messages skipped for want of a finite point.
    pub empty_messages: usize,
    /// Point slots declared (height x width, over all messages).
    pub slots: u64,
    /// Points skipped for a NaN or infinite coordinate.
    pub dropped_non_finite: u64,
    /// Points left out as no-returns: at (within the screening's `min_range` of) the sensor,
    /// the origin of the message's own frame.
    pub no_returns: u64,
    /// Isolated points left out, each message screened on its own as a file is
    /// ([`read_bag_keeping`]); the worst is placed in the chosen frame.
    pub outliers: OutlierDrops,
    pub units: Units,
}

/// Why a bag gives no scans. Each Display is one line that starts with the bag's name.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BagError {
    #[error("{}: {cause}", path.display())]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    /// The MCAP container is damaged or cut (the `mcap` crate's reason).
    #[error("{name}: not a readable MCAP file: {cause}")]
    Mcap { name: String, cause: String },
    /// A channel that claims a schema but is not CDR.
    #[error("{name}: topic {topic} is {encoding}-encoded; only ROS 2's cdr is read")]
    Encoding {
        name: String,
        topic: String,
        encoding: String,
    },
    /// A message whose CDR bytes are not its schema's.
    #[error("{name}: {topic} message {index}: {cause}")]
    Message {
        name: String,
        topic: String,
        index: usize,
        cause: CdrError,
    },
    /// A PointCloud2 whose layout gives no points.
    #[error("{name}: {topic} message {index}: {cause}")]
    Layout {
        name: String,
        topic: String,
        index: usize,
        cause: LayoutError,
    },
    /// The topic asked for is not a PointCloud2 topic of the bag.
    #[error("{name}: no PointCloud2 topic {topic}; {}", topics_hint(.available))]
    NoSuchTopic {
        name: String,
        topic: String,
        available: Vec<String>,
    },
    /// No topic asked for, and the bag has none or several.
    #[error("{name}: {}", choose_hint(.available))]
    ChooseTopic {
        name: String,
        available: Vec<String>,
    },
    /// A message's frame has no transform to the frame asked for.
    #[error("{name}: {topic} message {index}: {cause}")]
    NoTransform {
        name: String,
        topic: String,
        index: usize,
        cause: Box<TfError>,
    },
    /// Every message of the topic is empty or all NaN.
    #[error("{name}: {topic}: no finite points in its {messages} messages ({slots} slots)")]
    NoPoints {
        name: String,
        topic: String,
        messages: usize,
        slots: u64,
    },
    /// The points of a message cannot be centred into f32, or taken to metres.
    #[error(transparent)]
    Points(ReadError),
}

impl BagError {
    /// Whether the error is in what the user asked for (a topic, a frame) rather than in the
    /// file: the command line reports these as usage errors.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            BagError::NoSuchTopic { .. }
                | BagError::ChooseTopic { .. }
                | BagError::NoTransform { .. }
        )
    }
}

fn topics_hint(available: &[String]) -> String {
    match available {
        [] => "the bag has no PointCloud2 topic".into(),
        [one] => format!("consider --topic {one}"),
        many => format!("consider one of --topic {}", many.join(", ")),
    }
}

fn choose_hint(available: &[String]) -> String {
    match available {
        [] => "no PointCloud2 topic in the bag".into(),
        many => format!(
            "{} PointCloud2 topics; choose one with --topic ({})",
            many.len(),
            many.join(", ")
        ),
    }
}

/// Whether `path` is a bag: an MCAP file (a regular file that starts with the MCAP magic), or
/// a rosbag2 directory (as `ros2 bag record` and rosbags write it: `metadata.yaml` beside one
/// or more MCAP files).
pub(crate) fn is_bag(path: &Path) -> bool {
    bag_files(path).is_some()
}

fn is_mcap(path: &Path) -> bool {
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return false;
    }
    let mut head = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| &head == MAGIC)
}

/// The MCAP files of bag `path`, in recording order: the file itself, or a rosbag2
/// directory's `*.mcap` files by their split index (`name_0.mcap`, `name_1.mcap`, ...,
/// `name_10.mcap`: shorter names first, then by name).
fn bag_files(path: &Path) -> Option<Vec<PathBuf>> {
    if is_mcap(path) {
        return Some(vec![path.to_owned()]);
    }
    if !path.join("metadata.yaml").is_file() {
        return None;
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "mcap") && is_mcap(p))
        .collect();
    files.sort_by_key(|p| (p.as_os_str().len(), p.clone()));
    (!files.is_empty()).then_some(files)
}

/// Every message of the bag, in file order, with its topic, schema and encoding.
fn messages(
    files: &[PathBuf],
    name: &str,
    mut each: impl FnMut(&mcap::Message<'static>) -> Result<(), BagError>,
) -> Result<(), BagError> {
    for path in files {
        let file = File::open(path).map_err(|cause| BagError::Io {
            path: path.to_owned(),
            cause,
        })?;
        let options =
            mcap::sans_io::LinearReaderOptions::default().with_record_length_limit(MAX_RECORD);
        let reader = mcap::io::MessageReader::new_with_options(BufReader::new(file), options);
        for message in reader {
            let message = message.map_err(|e| BagError::Mcap {
                name: if files.len() == 1 {
                    name.to_owned()
                } else {
                    path.display().to_string()
                },
                cause: e.to_string(),
            })?;
            each(&message)?;
        }
    }
    Ok(())
}

fn schema_of<'a>(channel: &'a mcap::Channel<'_>) -> &'a str {
    channel.schema.as_ref().map_or("", |s| s.name.as_str())
}

/// Refuses a channel that is not CDR-encoded.
fn cdr_only(name: &str, channel: &mcap::Channel) -> Result<(), BagError> {
    if channel.message_encoding == "cdr" {
        Ok(())
    } else {
        Err(BagError::Encoding {
            name: name.to_owned(),
            topic: channel.topic.clone(),
            encoding: channel.message_encoding.clone(),
        })
    }
}

/// Pass 1 over the bag: its PointCloud2 topics with their message counts, and, if `with_tf`,
/// the transforms of `/tf` and `/tf_static`.
fn survey(
    files: &[PathBuf],
    name: &str,
    with_tf: bool,
) -> Result<(BTreeMap<String, usize>, TfTree), BagError> {
    let mut topics: BTreeMap<String, usize> = BTreeMap::new();
    let mut tree = TfTree::default();
    let mut tf_index = 0usize;
    messages(files, name, |m| {
        let schema = schema_of(&m.channel);
        if schema == POINTCLOUD2 {
            *topics.entry(m.channel.topic.clone()).or_default() += 1;
            return Ok(());
        }
        let topic = m.channel.topic.as_str();
        let fixed = topic == "/tf_static";
        if !(with_tf && schema == TF_MESSAGE && (fixed || topic == "/tf")) {
            return Ok(());
        }
        cdr_only(name, &m.channel)?;
        let transforms = parse_tf_message(&m.data).map_err(|cause| BagError::Message {
            name: name.to_owned(),
            topic: topic.to_owned(),
            index: tf_index,
            cause,
        })?;
        tf_index += 1;
        for t in transforms {
            if fixed {
                tree.add_static(t);
            } else {
                tree.add_dynamic(t);
            }
        }
        Ok(())
    })?;
    tree.finish();
    Ok((topics, tree))
}

/// The scans of bag `path`: the PointCloud2 messages of `options.topic`, each with its pose in
/// `options.frame`, in metres (`given`: `--units`, else REP 103's metres).
///
/// ```no_run
/// use mema::io::bag::{BagOptions, read_bag};
///
/// let options = BagOptions { topic: Some("/points".into()), frame: Some("world".into()) };
/// let bag = read_bag("bags/bunny/bunny.mcap".as_ref(), &options, None)?;
/// for scan in &bag.scans {
///     let first = scan.world_points().next();
///     let (frame, stamp, n) = (&scan.frame_id, scan.stamp, scan.points.len());
///     println!("{frame} at {stamp}: {n} points, the first at {first:?} in world");
/// }
/// println!("{} points dropped for NaN or inf", bag.dropped_non_finite);
/// # Ok::<(), mema::io::bag::BagError>(())
/// ```
pub fn read_bag(
    path: &Path,
    options: &BagOptions,
    given: Option<&LengthUnit>,
) -> Result<BagScans, BagError> {
    read_bag_keeping(path, options, given, Screening::DEFAULT)
}

/// [`read_bag`] leaving out of each message what `screening` says, in the message's own frame,
/// as a cloud file of that scan would be screened: a registration file's scans and a bag of the
/// same scans then lose the same points.
pub fn read_bag_keeping(
    path: &Path,
    options: &BagOptions,
    given: Option<&LengthUnit>,
    screening: Screening,
) -> Result<BagScans, BagError> {
    let name = path.display().to_string();
    let files = bag_files(path).ok_or_else(|| BagError::Mcap {
        name: name.clone(),
        cause: "neither an MCAP file nor a rosbag2 directory (metadata.yaml and .mcap files)"
            .into(),
    })?;
    let cdr_only = |channel: &mcap::Channel| cdr_only(&name, channel);
    // Pass 1: the PointCloud2 topics, and the transforms if a frame is asked for.
    let (topics, tree) = survey(&files, &name, options.frame.is_some())?;
    let available: Vec<String> = topics.keys().cloned().collect();
    let topic = match &options.topic {
        Some(t) if topics.contains_key(t) => t.clone(),
        Some(t) => {
            return Err(BagError::NoSuchTopic {
                name,
                topic: t.clone(),
                available,
            });
        }
        None if available.len() == 1 => available[0].clone(),
        None => return Err(BagError::ChooseTopic { name, available }),
    };
    // Pass 2: the topic's messages.
    let rep103 = FileUnit::Length {
        unit: LengthUnit::metre(),
        source: "REP 103, ROS's metres",
    };
    let ctx = Ctx::in_metres_keeping(&name, given, screening);
    let mut out = BagScans {
        topic: topic.clone(),
        frame: options.frame.clone(),
        scans: Vec::new(),
        messages: 0,
        empty_messages: 0,
        slots: 0,
        dropped_non_finite: 0,
        no_returns: 0,
        outliers: OutlierDrops::default(),
        units: Units::assumed(),
    };
    messages(&files, &name, |m| {
        if m.channel.topic != topic || schema_of(&m.channel) != POINTCLOUD2 {
            return Ok(());
        }
        cdr_only(&m.channel)?;
        let index = out.messages;
        out.messages += 1;
        let at = |cause| BagError::Message {
            name: name.clone(),
            topic: topic.clone(),
            index,
            cause,
        };
        let cloud = PointCloud2::parse(&m.data).map_err(at)?;
        let layout = cloud.layout().map_err(|cause| BagError::Layout {
            name: name.clone(),
            topic: topic.clone(),
            index,
            cause,
        })?;
        out.slots += cloud.slots();
        let slots = usize::try_from(cloud.slots()).unwrap_or(usize::MAX);
        // Bounded by the data: `layout` checked that the rows fit in it.
        let mut points = Points::with_capacity(ctx, slots).map_err(BagError::Points)?;
        for p in cloud.points(layout) {
            points.push(p);
        }
        // A PointCloud2 is in its sensor's frame (`header.frame_id`): each point a ray from
        // that frame's origin, which the pose below puts in the chosen frame.
        points.set_sensor([0.0; 3]);
        let read: Cloud = match points.finish_in(ctx, Format::RosBag, Some(rep103.clone())) {
            Ok(read) => read,
            Err(ReadError::NoFinitePoints { slots, .. }) => {
                out.empty_messages += 1;
                out.dropped_non_finite += slots as u64;
                return Ok(());
            }
            Err(e) => return Err(BagError::Points(e)),
        };
        out.dropped_non_finite += read.dropped_non_finite as u64;
        out.no_returns += read.no_returns as u64;
        let units = read.units.clone().unwrap_or_else(Units::assumed);
        let scale = units.unit.metres;
        out.units = units;
        let pose = match &options.frame {
            None => Transform::IDENTITY,
            Some(frame) => {
                let mut pose = tree
                    .lookup(&cloud.header.frame_id, frame, cloud.header.stamp)
                    .map_err(|cause| BagError::NoTransform {
                        name: name.clone(),
                        topic: topic.clone(),
                        index,
                        cause,
                    })?;
                if scale != 1.0 {
                    pose.translation = pose.translation.map(|v| v * scale);
                }
                pose
            }
        };
        out.outliers.add(read.outliers, |p| {
            to_world(pose.translation, pose.rotation, p)
        });
        let o = read.origin;
        out.scans.push(BagScan {
            frame_id: cloud.header.frame_id.clone(),
            stamp: cloud.header.stamp,
            pose,
            points: read
                .points
                .iter()
                .map(|p| [0, 1, 2].map(|j| o[j] + f64::from(p[j])))
                .collect(),
        });
        Ok(())
    })?;
    if out.scans.is_empty() {
        return Err(BagError::NoPoints {
            name,
            topic,
            messages: out.messages,
            slots: out.slots,
        });
    }
    Ok(out)
}
