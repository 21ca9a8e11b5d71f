//! The stable half of the fuzzing: the properties of `mema_core::fuzz_checks` and of
//! `mema::io::read::fuzz_checks`, which the cargo-fuzz targets in `core/fuzz` and `host/fuzz`
//! check in long campaigns (`scripts/fuzz.sh`), checked here on mutations of the same seeds:
//! maps of the shared clouds in every layout, their captures, and the clouds themselves in
//! every format the readers take.

use mema::link::frames::{encode_stream, quantise};
use mema_core::fuzz_checks::{map_file, wire_stream};
use mema_core::map::{Layout, MapFile, encode_as};

use crate::util::{Dir, MemaCommand, shared};

/// xorshift64: the mutations are the same on every run.
struct Mutator(u64);

impl Mutator {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    /// One to four byte changes, and sometimes a cut, a run of zeros or a repeated span.
    fn mutate(&mut self, seed: &[u8], round: usize) -> Vec<u8> {
        let mut bytes = seed.to_vec();
        for _ in 0..1 + round % 4 {
            let at = self.below(bytes.len());
            bytes[at] = self.next() as u8;
        }
        match round % 7 {
            0 => bytes.truncate(self.below(bytes.len())),
            1 => {
                let at = self.below(bytes.len());
                let run = 1 + self.below(600);
                bytes.splice(at..at, std::iter::repeat_n(0u8, run));
            }
            2 => {
                let from = self.below(bytes.len());
                let len = self.below(64).min(bytes.len() - from);
                let span = bytes[from..from + len].to_vec();
                let at = self.below(bytes.len());
                bytes.splice(at..at, span);
            }
            _ => {}
        }
        bytes
    }
}

fn map_bytes(dir: &Dir, cloud: &str, extra: &[&str]) -> Vec<u8> {
    let out = dir.join(&format!("{cloud}.{}.mema", extra.join("")));
    MemaCommand::new(dir)
        .arg("map")
        .arg(shared(cloud))
        .args(extra)
        .arg("-o")
        .arg(&out)
        .run()
        .assert_ok();
    std::fs::read(out).expect("map")
}

/// The map a cargo-fuzz campaign found accepted but not re-encoding to its own entities
/// (`../shared/repro/map_decoder_no_round_trip.mema`, read in place).
#[test]
fn the_campaigns_no_round_trip_map_holds_the_properties() {
    let path = crate::util::shared_data().join("../repro/map_decoder_no_round_trip.mema");
    let bytes = std::fs::read(&path).expect("the repro map");
    assert_eq!(map_file(&bytes), Ok(()));
}

#[test]
fn map_decoder_holds_its_properties_on_mutated_maps_of_every_layout() {
    let dir = Dir::new("fuzz-maps");
    let paper = map_bytes(&dir, "car6.pcd", &["-k", "60", "--paper"]);
    let shells = map_bytes(&dir, "bun_zipper.ply", &["--bytes", "1400"]);
    let oriented = {
        let file = MapFile::new_checked(&shells).expect("shells map");
        let mut out = vec![0u8; Layout::Oriented.encoded_len(file.len())];
        encode_as(Layout::Oriented, file.origin(), file.entities(), &mut out).expect("encodes");
        out
    };
    let mut m = Mutator(0x9e37_79b9_7f4a_7c15);
    for (name, seed) in [
        ("v1", &paper),
        ("v2 f32", &oriented),
        ("v2 quantized", &shells),
    ] {
        assert_eq!(map_file(seed), Ok(()), "{name}: the seed itself");
        assert!(MapFile::new_checked(seed).is_ok(), "{name}: seed decodes");
        let mut passed_crc = 0;
        for round in 0..6_000 {
            let bytes = m.mutate(seed, round);
            assert_eq!(map_file(&bytes), Ok(()), "{name}, round {round}");
            passed_crc += usize::from(bytes != *seed && MapFile::new_checked(&bytes).is_ok());
        }
        // A CRC guards the file: random mutations essentially never pass it as they are.
        assert!(
            passed_crc <= 1,
            "{name}: {passed_crc} changed maps passed the CRC"
        );
    }
}

#[test]
fn wire_decoder_gives_the_same_frames_in_any_pieces_of_mutated_captures() {
    let mut m = Mutator(0x2545_f491_4f6c_dd1d);
    for cloud in ["car6.pcd", "lamppost.pcd"] {
        let points = mema::io::load_cloud(&shared(cloud)).expect("cloud").points;
        let wire: Vec<[i32; 3]> = points.iter().map(|p| quantise(*p).expect("fits")).collect();
        let capture = encode_stream(&wire).expect("encodes");
        assert_eq!(
            wire_stream(&capture, 1),
            Ok(()),
            "{cloud}: the capture itself"
        );
        for round in 0..400 {
            let bytes = m.mutate(&capture, round);
            let piece = 1 + m.below(if round % 2 == 0 { 16 } else { 5000 });
            assert_eq!(wire_stream(&bytes, piece), Ok(()), "{cloud}, round {round}");
        }
    }
}

/// Seeds for the readers, from the shared clouds: the small files whole (LZF-compressed and
/// ascii PCD, LAS, LAZ), and the first points of larger clouds re-encoded in the layouts the
/// shared data lacks (binary PCD, binary PLY in both byte orders, ascii PLY, XYZ text, KITTI
/// `.bin`), each with the fuzz target's first byte: the name it is read under.
fn reader_seeds() -> Vec<(&'static str, u8, Vec<u8>)> {
    use mema::io::read::fuzz_checks::NAMES;
    let pick = |name: &str| NAMES.iter().position(|n| *n == name).expect(name) as u8;
    let mut seeds = Vec::new();
    for (file, name) in [
        ("car6.pcd", "fuzz.pcd"),
        ("milk.pcd", "fuzz.pcd"),
        ("lamppost.pcd", "fuzz.pcd"),
        ("simple.las", "fuzz.las"),
        ("autzen_trim.laz", "fuzz.laz"),
    ] {
        let bytes = std::fs::read(shared(file)).expect(file);
        seeds.push((file, pick(name), bytes));
    }
    let cloud = mema::io::read::read_cloud(&shared("bun000.ply")).expect("bun000");
    let points: Vec<[f32; 3]> = cloud.points.iter().take(1500).copied().collect();
    let n = points.len();
    let floats = |big: bool, w: usize| -> Vec<u8> {
        points
            .iter()
            .flat_map(|p| {
                let mut q = p.to_vec();
                q.resize(w, 0.5);
                q
            })
            .flat_map(|c| {
                if big {
                    c.to_be_bytes()
                } else {
                    c.to_le_bytes()
                }
            })
            .collect()
    };
    let text: String = points
        .iter()
        .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
        .collect();
    let ply = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex {n}\nproperty float x\n\
             property float y\nproperty float z\nend_header\n"
        )
        .into_bytes()
    };
    let pcd = format!(
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\n\
         HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
    );
    seeds.push((
        "binary PCD",
        pick("fuzz.pcd"),
        [pcd.into_bytes(), floats(false, 3)].concat(),
    ));
    for (format, big) in [("binary_little_endian", false), ("binary_big_endian", true)] {
        seeds.push((
            "binary PLY",
            pick("fuzz.ply"),
            [ply(format), floats(big, 3)].concat(),
        ));
    }
    let ascii = [ply("ascii"), text.clone().into_bytes()].concat();
    seeds.push(("ascii PLY", pick("fuzz.ply"), ascii));
    seeds.push(("XYZ", pick("fuzz.xyz"), text.into_bytes()));
    seeds.push(("KITTI", pick("fuzz.bin"), floats(false, 4)));
    seeds
}

/// Every reader on mutations of real files in every format: never a panic, and either an
/// error of one line naming the file or a cloud of finite points whose counts agree
/// (`fuzz_checks::cloud_bytes`, the cargo-fuzz target's property). The seeds themselves must
/// read as clouds, so the mutations start from inputs that reach the readers' depths.
#[test]
fn cloud_readers_hold_their_properties_on_mutated_real_files() {
    use mema::io::read::fuzz_checks::{Outcome, cloud_bytes};
    let mut m = Mutator(0x5851_f42d_4c95_7f2d);
    let (mut clouds, mut errors) = (0, 0);
    for (what, pick, seed) in reader_seeds() {
        let whole = cloud_bytes(pick, &seed);
        assert!(
            matches!(whole, Ok(Outcome::Cloud { .. })),
            "{what}: the seed itself: {whole:?}"
        );
        // LAZ decodes a chunk at a time; fewer rounds keep its share of the time in line.
        let rounds = if seed.len() > 200_000 { 150 } else { 600 };
        for round in 0..rounds {
            let bytes = m.mutate(&seed, round);
            let result = std::panic::catch_unwind(|| cloud_bytes(pick, &bytes));
            let checked = result.unwrap_or_else(|_| panic!("{what}, round {round}: a panic"));
            match checked {
                Ok(Outcome::Cloud { .. }) => clouds += 1,
                Ok(Outcome::Refused) => errors += 1,
                Err(violation) => panic!("{what}, round {round}: {violation:?}"),
            }
        }
    }
    // Both outcomes are reached: the mutations neither all break nor all spare the files.
    assert!(
        clouds > 1_000 && errors > 500,
        "{clouds} clouds, {errors} errors"
    );
}

/// The link's seeds for `target` (`mema_firmware_sim::fuzz_checks::link_seeds`, what
/// `scripts/fuzz.sh` seeds the campaigns with).
fn link_seeds(target: &str) -> Vec<(String, Vec<u8>)> {
    let seeds: Vec<_> = mema_firmware_sim::fuzz_checks::link_seeds()
        .into_iter()
        .filter(|(t, _, _)| *t == target)
        .map(|(_, name, bytes)| (name, bytes))
        .collect();
    assert!(seeds.len() >= 6, "{target}: {} seeds", seeds.len());
    seeds
}

/// Both decoders on mutations of a tiny session's frames, each block also with its CRC made
/// right: whatever they accept re-encodes to its raw frame, within the protocol's bounds
/// (`fuzz_checks::{uplink_frames, downlink_frames}`, the campaigns' properties). Both outcomes
/// are reached: mutations past the CRC are refused and taken alike.
#[test]
fn link_decoders_re_encode_what_they_take_from_mutated_session_frames() {
    use mema_core::fuzz_checks::{FramesOutcome, downlink_frames, uplink_frames};
    let mut m = Mutator(0x6a09_e667_f3bc_c909);
    type Check = fn(&[u8]) -> Result<FramesOutcome, mema_core::fuzz_checks::Violation>;
    for (target, check) in [
        ("uplink_decoder", uplink_frames as Check),
        ("downlink_decoder", downlink_frames as Check),
    ] {
        let mut total = FramesOutcome::default();
        for (name, seed) in link_seeds(target) {
            let itself = check(&seed).unwrap_or_else(|v| panic!("{target} {name}: {v:?}"));
            assert!(
                itself.decoded > 0 && itself.refused == 0,
                "{name}: {itself:?}"
            );
            for round in 0..1_500 {
                let bytes = m.mutate(&seed, round);
                let got = check(&bytes).unwrap_or_else(|v| panic!("{name}, round {round}: {v:?}"));
                total.decoded += got.decoded;
                total.refused += got.refused;
            }
        }
        assert!(
            total.decoded > 10_000 && total.refused > 5_000,
            "{target}: {total:?}"
        );
    }
}

/// The board's carrier on mutations of a tiny session's line (its body, and now and then
/// its piece and drain sizes): it passes on exactly the carry frames' bytes, hands on exactly
/// the requests and reports what a plain model of the same bytes says
/// (`mema_firmware_sim::fuzz_checks::carrier`).
#[test]
fn carrier_passes_on_what_a_plain_model_says_of_mutated_lines() {
    use mema_firmware_sim::fuzz_checks::{CARRIER_HEADER, carrier};
    let mut m = Mutator(0xbb67_ae85_84ca_a73b);
    let (mut passed, mut refused, mut requests) = (0, 0, 0);
    for (name, seed) in link_seeds("carrier") {
        let itself = carrier(&seed).unwrap_or_else(|v| panic!("{name}: {v:?}"));
        assert!(
            itself.passed > 0 && itself.requests > 0,
            "{name}: {itself:?}"
        );
        let (header, body) = seed.split_at(CARRIER_HEADER);
        for round in 0..1_500 {
            let mut input = header.to_vec();
            if round % 5 == 0 {
                input[0] = m.next() as u8;
                input[1] = m.next() as u8;
            }
            // Every other round with the CRCs made right, so mutations reach the fields.
            input[2] = (round % 2) as u8;
            input.extend(m.mutate(body, round));
            let got = carrier(&input).unwrap_or_else(|v| panic!("{name}, round {round}: {v:?}"));
            passed += got.passed;
            refused += got.refused;
            requests += got.requests;
        }
    }
    assert!(
        passed > 1_000_000 && refused > 5_000 && requests > 5_000,
        "{passed} bytes passed on, {refused} refused, {requests} requests"
    );
}

/// The host's assembler on mutations of a tiny session's downlink: the same account in any
/// pieces, the model's counts, and a map only of the end's length and CRC that reads back,
/// also once they are made right (`mema::link::fuzz_checks::map_frames`). The seeds reach
/// the map (but the one with a frame lost), and so do many mutations.
#[test]
fn map_frames_give_one_account_and_only_the_devices_map_on_mutated_downlinks() {
    use mema::link::fuzz_checks::{FRAMES_HEADER, map_frames};
    let mut m = Mutator(0x3c6e_f372_fe94_f82b);
    let (mut maps, mut made_right, mut ended) = (0, 0, 0);
    for (name, seed) in link_seeds("map_frames") {
        let itself = map_frames(&seed).unwrap_or_else(|v| panic!("{name}: {v:?}"));
        // With a frame lost, no map; the oriented end's length and CRC are made right.
        let (lost, oriented) = (name.ends_with("lost"), name.ends_with("oriented"));
        assert_eq!(itself.map, !lost && !oriented, "{name}: {itself:?}");
        assert_eq!(itself.map_made_right, !lost, "{name}: {itself:?}");
        assert!(itself.ended && itself.entities > 0, "{name}: {itself:?}");
        let (header, body) = seed.split_at(FRAMES_HEADER);
        for round in 0..1_000 {
            let mut input = header.to_vec();
            if round % 5 == 0 {
                input[0] = m.next() as u8;
            }
            input[1] = (round % 2) as u8;
            input.extend(m.mutate(body, round));
            let got = map_frames(&input).unwrap_or_else(|v| panic!("{name}, round {round}: {v:?}"));
            maps += usize::from(got.map);
            made_right += usize::from(got.map_made_right);
            ended += usize::from(got.ended);
        }
    }
    // Floors of how far the mutations reach, not a property of any one: 864 maps, 1,752 made
    // right and 6,817 ended with shells' freezes at their own price (1,069, 2,019 and 6,769
    // before, when the session froze fewer entities and its downlink was shorter).
    assert!(
        maps > 500 && made_right > 1_000 && ended > 3_000,
        "{maps} maps, {made_right} made right, {ended} ended"
    );
}
