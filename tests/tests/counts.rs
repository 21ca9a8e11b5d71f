//! Counts that add up (issue 33): for every shared input, `mema map`'s points read plus every
//! point it left out (NaN or infinite, by class, isolated) is the input's slots, on the
//! `points:` line and in `--json`. The slots and the NaN slots are counted here from the files
//! themselves, by a parse of their headers and coordinates of this file's own (PLY, PCD in
//! ascii, binary and LZF-compressed binary, LAS/LAZ headers, `.conf` lines), never from mema's
//! totals. A registration file's scans are screened for outliers as each file alone is.

use std::path::Path;

use crate::util::{Dir, MemaCommand, shared, shared_data};

/// What a cloud file holds, counted here: its slots and those with a NaN or infinite coordinate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Slots {
    slots: usize,
    non_finite: usize,
}

impl std::ops::Add for Slots {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            slots: self.slots + o.slots,
            non_finite: self.non_finite + o.non_finite,
        }
    }
}

/// A header's text up to (and without) the line that starts with `last`, and the byte offset
/// just after that line.
fn header(bytes: &[u8], last: &str) -> (Vec<String>, usize) {
    let mut lines = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let end = bytes[at..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| at + i);
        let line = String::from_utf8_lossy(&bytes[at..end]).trim().to_string();
        at = end + 1;
        let done = line.starts_with(last);
        lines.push(line);
        if done {
            return (lines, at);
        }
    }
    panic!("no `{last}` line in the header");
}

fn word<'a>(lines: &'a [String], key: &str) -> Vec<&'a str> {
    lines
        .iter()
        .find(|l| l.split_whitespace().next() == Some(key))
        .unwrap_or_else(|| panic!("no {key} line"))
        .split_whitespace()
        .skip(1)
        .collect()
}

fn non_finite(points: impl Iterator<Item = [f64; 3]>) -> usize {
    points.filter(|p| p.iter().any(|c| !c.is_finite())).count()
}

/// An ASCII PLY's vertices: `element vertex N`, then N lines whose first three numbers are
/// x y z (as in every shared PLY: x, y, z are its first properties).
fn ply(bytes: &[u8]) -> Slots {
    let (lines, body) = header(bytes, "end_header");
    assert_eq!(word(&lines, "format")[0], "ascii", "an ASCII PLY");
    assert_eq!(word(&lines, "property")[1], "x", "x first");
    let slots: usize = lines
        .iter()
        .find_map(|l| l.strip_prefix("element vertex "))
        .expect("element vertex")
        .trim()
        .parse()
        .expect("a vertex count");
    let text = String::from_utf8_lossy(&bytes[body..]);
    let points = text.lines().take(slots).map(|l| {
        let v: Vec<f64> = l
            .split_whitespace()
            .take(3)
            .map(|w| w.parse().expect("a number"))
            .collect();
        [v[0], v[1], v[2]]
    });
    let non_finite = non_finite(points);
    Slots { slots, non_finite }
}

/// LZF as liblzf writes it: a control byte below 32 copies that many plus one literal bytes;
/// above, its top three bits (7: a length byte follows) plus two are the length of a copy
/// from a distance of its low five bits, the next byte and one back.
fn lzf(input: &[u8], size: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(size);
    let mut i = 0;
    while i < input.len() {
        let ctrl = usize::from(input[i]);
        i += 1;
        if ctrl < 32 {
            out.extend_from_slice(&input[i..i + ctrl + 1]);
            i += ctrl + 1;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                len += usize::from(input[i]);
                i += 1;
            }
            let back = ((ctrl & 31) << 8) + usize::from(input[i]) + 1;
            i += 1;
            let from = out.len() - back;
            for k in 0..len + 2 {
                out.push(out[from + k]);
            }
        }
    }
    assert_eq!(out.len(), size, "LZF output size");
    out
}

/// A PCD: `WIDTH` x `HEIGHT` slots, x y z read from ascii lines, binary records, or the
/// field-by-field arrays of binary_compressed.
fn pcd(bytes: &[u8]) -> Slots {
    let (lines, body) = header(bytes, "DATA");
    let fields = word(&lines, "FIELDS");
    let sizes: Vec<usize> = word(&lines, "SIZE")
        .iter()
        .map(|s| s.parse().unwrap())
        .collect();
    let types = word(&lines, "TYPE");
    let counts: Vec<usize> =
        lines
            .iter()
            .find(|l| l.starts_with("COUNT"))
            .map_or(vec![1; fields.len()], |l| {
                l.split_whitespace()
                    .skip(1)
                    .map(|s| s.parse().unwrap())
                    .collect()
            });
    let dim = |key: &str| -> usize { word(&lines, key)[0].parse().unwrap() };
    let slots = dim("WIDTH") * dim("HEIGHT");
    let field = |name: &str| fields.iter().position(|f| *f == name).expect("x y z");
    let [x, y, z] = ["x", "y", "z"].map(field);
    for f in [x, y, z] {
        assert_eq!(
            (types[f], sizes[f], counts[f]),
            ("F", 4, 1),
            "f32 coordinates"
        );
    }
    let f32_at =
        |b: &[u8], at: usize| f64::from(f32::from_le_bytes(b[at..at + 4].try_into().unwrap()));
    let points: Vec<[f64; 3]> = match word(&lines, "DATA")[0] {
        "ascii" => {
            // Each field's first value's column: the counts of the fields before it.
            let column = |f: usize| counts[..f].iter().sum::<usize>();
            String::from_utf8_lossy(&bytes[body..])
                .lines()
                .filter(|l| !l.trim().is_empty())
                .take(slots)
                .map(|l| {
                    let w: Vec<&str> = l.split_whitespace().collect();
                    [x, y, z].map(|f| w[column(f)].parse::<f64>().expect("a number"))
                })
                .collect()
        }
        "binary" => {
            let record: usize = sizes.iter().zip(&counts).map(|(s, c)| s * c).sum();
            let offset = |f: usize| -> usize {
                sizes[..f]
                    .iter()
                    .zip(&counts[..f])
                    .map(|(s, c)| s * c)
                    .sum()
            };
            (0..slots)
                .map(|i| [x, y, z].map(|f| f32_at(bytes, body + i * record + offset(f))))
                .collect()
        }
        "binary_compressed" => {
            let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
            let packed = u32_at(body) as usize;
            let size = u32_at(body + 4) as usize;
            let data = lzf(&bytes[body + 8..body + 8 + packed], size);
            // Field-major: every slot's value of the first field, then of the next.
            let start = |f: usize| -> usize {
                sizes[..f]
                    .iter()
                    .zip(&counts[..f])
                    .map(|(s, c)| s * c * slots)
                    .sum()
            };
            (0..slots)
                .map(|i| [x, y, z].map(|f| f32_at(&data, start(f) + 4 * i)))
                .collect()
        }
        other => panic!("DATA {other}"),
    };
    assert_eq!(points.len(), slots, "every slot's coordinates");
    let non_finite = non_finite(points.into_iter());
    Slots { slots, non_finite }
}

/// A LAS or LAZ file: the header's legacy point count (offset 107; a LAZ header is not
/// compressed). Integer coordinates have no NaN.
fn las(bytes: &[u8]) -> Slots {
    assert_eq!(&bytes[..4], b"LASF");
    let slots = u32::from_le_bytes(bytes[107..111].try_into().unwrap()) as usize;
    Slots {
        slots,
        non_finite: 0,
    }
}

/// A registration file: the sum over its `bmesh` lines' scans.
fn conf(path: &Path) -> Slots {
    let text = std::fs::read_to_string(path).expect("conf");
    text.lines()
        .filter_map(|l| l.strip_prefix("bmesh "))
        .map(|l| counted(&path.with_file_name(l.split_whitespace().next().expect("a file"))))
        .fold(Slots::default(), |a, b| a + b)
}

fn counted(path: &Path) -> Slots {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    match ext {
        "conf" => conf(path),
        _ => {
            let bytes = std::fs::read(path).expect("read the cloud");
            match ext {
                "ply" => ply(&bytes),
                "pcd" => pcd(&bytes),
                "las" | "laz" => las(&bytes),
                other => panic!("{}: no count for .{other}", path.display()),
            }
        }
    }
}

/// Every input the shared data holds: its cloud files and registration files.
fn inputs() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(shared_data())
        .expect("../shared/data")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| !n.ends_with(".md"))
        .collect();
    names.sort();
    names
}

/// `mema map NAME` at a small k: its JSON report.
fn map_json(dir: &Dir, name: &str) -> serde_json::Value {
    MemaCommand::new(dir)
        .arg("map")
        .arg(shared(name))
        .args([
            "-k",
            "20",
            "--surface-rounds",
            "0",
            "--json",
            "-o",
            "m.mema",
        ])
        .run()
        .assert_ok()
        .json()
}

fn n(v: &serde_json::Value) -> usize {
    v.as_u64().unwrap_or_else(|| panic!("{v} is not a count")) as usize
}

/// The numbers of a `points:` line, in order.
fn numbers(line: &str) -> Vec<usize> {
    line.split(|c: char| !c.is_ascii_digit())
        .filter(|w| !w.is_empty())
        .map(|w| w.parse().unwrap())
        .collect()
}

#[test]
fn the_independent_counts_see_what_the_files_document() {
    // SOURCES.md's figures for the organized frames: the parse here finds them.
    let five = counted(&shared("five_people.pcd"));
    assert_eq!(
        (five.slots, five.slots - five.non_finite),
        (307_200, 239_075)
    );
    let sweeps: Vec<Slots> = (0..3)
        .map(|i| counted(&shared(&format!("ouster_os1_{i}.pcd"))))
        .collect();
    let finite: Vec<usize> = sweeps.iter().map(|s| s.slots - s.non_finite).collect();
    assert_eq!(finite, [107_647, 107_357, 107_532]);
    assert!(sweeps.iter().all(|s| s.slots == 1024 * 128));
    // A PLY's NaN, seen by the parse: a coordinate written `nan`.
    let ply_nan = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                    property float z\nend_header\n0 0 0\nnan 1 2\n1 inf 0\n";
    assert_eq!(
        ply(ply_nan),
        Slots {
            slots: 3,
            non_finite: 2
        }
    );
}

/// Acceptance 2: read + each drop = slots on the `points:` line and in `--json` for every shared
/// input, and the NaN slots counted are the file's.
#[test]
fn read_and_every_drop_add_up_to_the_slots_of_every_shared_input() {
    let dir = Dir::new("counts");
    let mut checked = 0;
    for name in inputs() {
        let want = counted(&shared(&name));
        let json = map_json(&dir, &name);
        let class = &json["dropped_by_class"];
        let drops = [
            n(&json["dropped_non_finite"]),
            n(&class["noise"]),
            n(&class["withheld"]),
            n(&class["other_classes"]),
            n(&json["outliers"]["dropped"]),
        ];
        let read = n(&json["filter"]["read"]);
        assert_eq!(
            read + drops.iter().sum::<usize>(),
            want.slots,
            "{name}: read {read} and drops {drops:?} vs {} slots",
            want.slots
        );
        assert_eq!(n(&json["slots"]), want.slots, "{name}");
        assert_eq!(drops[0], want.non_finite, "{name}: NaN or infinite slots");
        assert_eq!(
            n(&json["memory"]["points"]),
            read,
            "{name}: the points mapped"
        );

        let text = MemaCommand::new(&dir)
            .arg("map")
            .arg(shared(&name))
            .args(["-k", "20", "--surface-rounds", "0", "-o", "m.mema"])
            .run()
            .assert_ok()
            .stdout();
        let line = text
            .lines()
            .find(|l| l.starts_with("points: "))
            .unwrap_or_else(|| panic!("{name}: no points line:\n{text}"));
        // `points: R read, D more dropped ..., [C left out by class,] [I as isolated]: S in
        // the input`: every number but the last adds up to the last.
        let mut figures = numbers(line);
        let total = figures.pop().expect("the total");
        assert_eq!(total, want.slots, "{name}: {line}");
        assert_eq!(figures.iter().sum::<usize>(), want.slots, "{name}: {line}");
        eprintln!("{name}: {line}");
        checked += 1;
    }
    assert!(checked >= 19, "only {checked} inputs");
}

/// A registration file's scans lose to the outlier screening what each file alone loses, and
/// its NaN slots are its scans' (70,680 of the Ouster sweeps' 393,216).
#[test]
fn a_registration_file_is_screened_as_its_scans_are() {
    let dir = Dir::new("conf-screening");
    for conf_name in ["ouster_os1.conf", "bun.conf"] {
        let text = std::fs::read_to_string(shared(conf_name)).expect("conf");
        let scans: Vec<String> = text
            .lines()
            .filter_map(|l| l.strip_prefix("bmesh "))
            .map(|l| l.split_whitespace().next().expect("file").to_string())
            .collect();
        let alone: Vec<serde_json::Value> = scans.iter().map(|s| map_json(&dir, s)).collect();
        let together = map_json(&dir, conf_name);
        let sum = |key: &dyn Fn(&serde_json::Value) -> usize| alone.iter().map(key).sum::<usize>();
        assert_eq!(
            n(&together["outliers"]["dropped"]),
            sum(&|j| n(&j["outliers"]["dropped"])),
            "{conf_name}: isolated points"
        );
        assert_eq!(
            n(&together["dropped_non_finite"]),
            sum(&|j| n(&j["dropped_non_finite"])),
            "{conf_name}: NaN slots"
        );
        assert_eq!(
            n(&together["filter"]["read"]),
            sum(&|j| n(&j["filter"]["read"])),
            "{conf_name}: points kept"
        );
    }
    let ouster = counted(&shared("ouster_os1.conf"));
    let json = map_json(&dir, "ouster_os1.conf");
    assert_eq!(n(&json["dropped_non_finite"]), ouster.non_finite);
    eprintln!(
        "ouster_os1.conf: {} of {} slots NaN; {} isolated",
        ouster.non_finite, ouster.slots, json["outliers"]["dropped"]
    );
}

/// eval reads the cloud as its file holds it (no outlier screening): its `cloud points:` line
/// adds up to the same slots.
#[test]
fn evals_points_line_adds_up_too() {
    let dir = Dir::new("eval-counts");
    for name in ["ouster_os1.conf", "five_people.pcd", "office1.pcd"] {
        let want = counted(&shared(name));
        map_json(&dir, name);
        let text = MemaCommand::new(&dir)
            .arg("eval")
            .arg(shared(name))
            .args(["m.mema", "--samples", "2000"])
            .run()
            .assert_ok()
            .stdout();
        let line = text
            .lines()
            .find(|l| l.starts_with("cloud points: "))
            .unwrap_or_else(|| panic!("{name}: no points line:\n{text}"));
        let mut figures = numbers(line);
        let total = figures.pop().expect("the total");
        assert_eq!(total, want.slots, "{name}: {line}");
        assert_eq!(figures.iter().sum::<usize>(), want.slots, "{name}: {line}");
        assert_eq!(figures[1], want.non_finite, "{name}: {line}");
    }
}
