//! Helpers shared by the readers' tests.

use super::{Cloud, ReadError, read_cloud_bytes};

/// The real clouds; read in place, never copied into the repository.
pub const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data");

pub fn shared(name: &str) -> Vec<u8> {
    std::fs::read(format!("{DATA}/{name}")).unwrap_or_else(|e| panic!("{DATA}/{name}: {e}"))
}

/// The number after `keyword` in a text header, e.g. `POINTS` or `element vertex`.
pub fn header_count(bytes: &[u8], keyword: &str) -> usize {
    let head = String::from_utf8_lossy(bytes.get(..4096).unwrap_or(bytes));
    let line = head
        .lines()
        .find(|l| l.starts_with(keyword))
        .expect(keyword);
    line[keyword.len()..].trim().parse().expect(line)
}

/// Requires reading `bytes` to fail with the `variant` (its Debug name), and the message to
/// be one line starting with the file's name.
pub fn expect_err(name: &str, bytes: &[u8], variant: &str) -> ReadError {
    let e = read_cloud_bytes(name, bytes).expect_err(name);
    let msg = e.to_string();
    assert!(
        msg.starts_with(&format!("{name}: ")) && !msg.contains('\n'),
        "{msg}"
    );
    assert!(
        format!("{e:?}").starts_with(variant),
        "want {variant}: {e:?}"
    );
    e
}

/// Requires `cloud` to hold exactly `want`, in order, to 1e-6 of the cloud's extent.
pub fn assert_same(cloud: &Cloud, want: &[[f64; 3]], what: &str) {
    assert_eq!(cloud.points.len(), want.len(), "{what}: point count");
    let axis = |k: usize| want.iter().map(move |p| p[k]);
    let span = |k| axis(k).fold(f64::MIN, f64::max) - axis(k).fold(f64::MAX, f64::min);
    let tolerance = 1e-6 * span(0).max(span(1)).max(span(2));
    for (i, (p, w)) in cloud.points.iter().zip(want).enumerate() {
        let got: [f64; 3] = std::array::from_fn(|k| cloud.origin[k] + f64::from(p[k]));
        let err = (0..3).map(|k| (got[k] - w[k]).abs()).fold(0.0, f64::max);
        assert!(err <= tolerance, "{what}: point {i} is {got:?}, want {w:?}");
    }
}

/// xorshift64: enough randomness for mutation tests, and the same on every machine.
pub struct XorShift(pub u64);

impl XorShift {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Holds a guide (a path from the repository's root) to a sentence a test made from the code's
/// constants or what it measured: a figure changed on either side fails until they agree.
/// `scripts/doc_digits.py` reads these calls to tell which of a guide's numbers a test holds.
pub fn guide_says(file: &str, sentence: &str) {
    let path = format!("{}/../{file}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let one_space = |t: &str| t.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(
        one_space(&text).contains(&one_space(sentence)),
        "{file} does not say `{sentence}`, which the test computes"
    );
}

/// A count as the guides write it: thousands separated by commas.
pub fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}
