//! The stable half of the fuzzing: the properties of `mema_core::fuzz_checks`, which the
//! cargo-fuzz targets in `core/fuzz` check in long campaigns (`scripts/fuzz.sh`), checked here on
//! mutations of the same seeds: maps of the shared clouds in every layout, and their captures.

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
