//! Data a user can get (issue 33): `scripts/fetch-data.sh` lists every file of ../shared/data
//! with its SHA-256 and its public source, at the repository and commit SOURCES.md gives. The
//! checksums are computed here (SHA-256 as FIPS 180-4 gives it, checked on its published
//! vectors), from the shared files themselves; nothing goes to the network.

use std::collections::BTreeMap;
use std::path::Path;

use crate::util::shared_data;

/// SHA-256 (FIPS 180-4).
fn sha256(data: &[u8]) -> String {
    const K: [u32; 64] = [
        0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4,
        0xab1c5ed5, 0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe,
        0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f,
        0x4a7484aa, 0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7,
        0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85, 0x2e1b2138, 0x4d2c6dfc,
        0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b,
        0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116,
        0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
        0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7,
        0xc67178f2,
    ];
    let mut h: [u32; 8] = [
        0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab,
        0x5be0cd19,
    ];
    // The message, a 1 bit, zeros to 56 mod 64 bytes, and its length in bits, big-endian.
    let mut padded = data.to_vec();
    padded.push(0x80);
    while padded.len() % 64 != 56 {
        padded.push(0);
    }
    padded.extend_from_slice(&((data.len() as u64) * 8).to_be_bytes());
    for block in padded.chunks_exact(64) {
        let mut w = [0u32; 64];
        for (i, word) in block.chunks_exact(4).enumerate() {
            w[i] = u32::from_be_bytes(word.try_into().expect("4 bytes"));
        }
        for i in 16..64 {
            let s0 = w[i - 15].rotate_right(7) ^ w[i - 15].rotate_right(18) ^ (w[i - 15] >> 3);
            let s1 = w[i - 2].rotate_right(17) ^ w[i - 2].rotate_right(19) ^ (w[i - 2] >> 10);
            w[i] = w[i - 16]
                .wrapping_add(s0)
                .wrapping_add(w[i - 7])
                .wrapping_add(s1);
        }
        let [mut a, mut b, mut c, mut d, mut e, mut f, mut g, mut hh] = h;
        for i in 0..64 {
            let s1 = e.rotate_right(6) ^ e.rotate_right(11) ^ e.rotate_right(25);
            let ch = (e & f) ^ (!e & g);
            let t1 = hh
                .wrapping_add(s1)
                .wrapping_add(ch)
                .wrapping_add(K[i])
                .wrapping_add(w[i]);
            let s0 = a.rotate_right(2) ^ a.rotate_right(13) ^ a.rotate_right(22);
            let maj = (a & b) ^ (a & c) ^ (b & c);
            let t2 = s0.wrapping_add(maj);
            (hh, g, f, e, d, c, b, a) = (g, f, e, d.wrapping_add(t1), c, b, a, t1.wrapping_add(t2));
        }
        for (x, y) in h.iter_mut().zip([a, b, c, d, e, f, g, hh]) {
            *x = x.wrapping_add(y);
        }
    }
    h.iter().map(|x| format!("{x:08x}")).collect()
}

/// One line of the script's manifest.
#[derive(Debug)]
struct Row {
    sha256: String,
    how: String,
    repository: String,
    commit: String,
    path: String,
}

/// The manifest of `scripts/fetch-data.sh`: the lines between `<<'MANIFEST'` and `MANIFEST`.
fn manifest() -> BTreeMap<String, Row> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/fetch-data.sh");
    let text = std::fs::read_to_string(&script).expect("scripts/fetch-data.sh");
    let start = text.find("<<'MANIFEST'\n").expect("a manifest") + "<<'MANIFEST'\n".len();
    let end = start + text[start..].find("\nMANIFEST\n").expect("its end");
    text[start..end]
        .lines()
        .map(|line| {
            let w: Vec<&str> = line.split_whitespace().collect();
            assert_eq!(w.len(), 6, "manifest line {line:?}");
            let row = Row {
                sha256: w[1].into(),
                how: w[2].into(),
                repository: w[3].into(),
                commit: w[4].into(),
                path: w[5].into(),
            };
            (w[0].to_string(), row)
        })
        .collect()
}

#[test]
fn sha256_gives_the_published_vectors() {
    assert_eq!(
        sha256(b""),
        "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    );
    assert_eq!(
        sha256(b"abc"),
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    );
    // Two blocks: the padding spills over.
    assert_eq!(
        sha256(b"abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
        "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1"
    );
}

#[test]
fn the_fetch_scripts_list_and_checksums_are_the_shared_files() {
    let rows = manifest();
    let data = shared_data();
    let mut files: Vec<String> = std::fs::read_dir(&data)
        .expect("../shared/data")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n != "SOURCES.md")
        .collect();
    files.sort();
    for name in &files {
        let row = rows
            .get(name)
            .unwrap_or_else(|| panic!("{name} is in ../shared/data but not in fetch-data.sh"));
        let bytes = std::fs::read(data.join(name)).expect("read a shared file");
        assert_eq!(
            sha256(&bytes),
            row.sha256,
            "{name}: its checksum in fetch-data.sh"
        );
    }
    // Every file the script makes is one of the shared files; the rest are its own sources.
    for (name, row) in &rows {
        assert!(
            files.contains(name) || (row.how == "source" && name.starts_with("ouster-source/")),
            "fetch-data.sh makes {name}, which ../shared/data does not have"
        );
        assert!(
            ["download", "subset", "poses", "decoded", "source"].contains(&row.how.as_str()),
            "{name}: {}",
            row.how
        );
    }
    // Each source is the one SOURCES.md names: its repository, its commit, its path.
    let sources = std::fs::read_to_string(data.join("SOURCES.md")).expect("SOURCES.md");
    for (name, row) in &rows {
        assert!(
            sources.contains(&row.repository) && sources.contains(&row.commit),
            "{name}: {}@{} is not in SOURCES.md",
            row.repository,
            row.commit
        );
        let file = row.path.rsplit('/').next().expect("a file name");
        assert!(
            sources.contains(&row.path) || sources.contains(file),
            "{name}: {} is not in SOURCES.md",
            row.path
        );
        assert_eq!(row.commit.len(), 40, "{name}: a whole commit");
    }
}
