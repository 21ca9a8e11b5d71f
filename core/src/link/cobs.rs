//! Consistent Overhead Byte Stuffing: removes every zero from a frame so `0x00` can delimit.

/// Worst-case encoded size (without the delimiter): one code byte per 254 data bytes, plus one.
pub const fn cobs_max_encoded_len(raw_len: usize) -> usize {
    raw_len + raw_len / 254 + 1
}

/// Encodes `raw` into `out` (no delimiter); returns the bytes written, or `None` if `out` is short.
pub fn cobs_encode(raw: &[u8], out: &mut [u8]) -> Option<usize> {
    let mut code_at = 0;
    let mut write = 1;
    let mut code: u8 = 1;
    for &byte in raw {
        if byte == 0 {
            *out.get_mut(code_at)? = code;
            code_at = write;
            write += 1;
            code = 1;
        } else {
            *out.get_mut(write)? = byte;
            write += 1;
            code += 1;
            if code == 0xFF {
                *out.get_mut(code_at)? = code;
                code_at = write;
                write += 1;
                code = 1;
            }
        }
    }
    *out.get_mut(code_at)? = code;
    Some(write)
}

/// Decodes a COBS block (delimiter already removed) in place; returns the raw length, or `None`
/// for a malformed block (a zero byte, or a code pointing past the end).
pub fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    let len = buf.len();
    let mut read = 0;
    let mut write = 0;
    while read < len {
        let code = *buf.get(read)? as usize;
        if code == 0 || read + code > len {
            return None;
        }
        read += 1;
        for _ in 1..code {
            let byte = *buf.get(read)?;
            if byte == 0 {
                return None;
            }
            *buf.get_mut(write)? = byte;
            write += 1;
            read += 1;
        }
        // A code below 0xFF stands for a zero that follows, unless the block ends here.
        if code < 0xFF && read < len {
            *buf.get_mut(write)? = 0;
            write += 1;
        }
    }
    Some(write)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{OrFail, TestResult};

    #[test]
    fn round_trips_the_textbook_cases_and_long_runs() -> TestResult {
        // Wikipedia's examples plus runs around the 254-byte boundary.
        let mut cases: [([u8; 600], usize); 8] = [([0u8; 600], 0); 8];
        cases[0].1 = 1;
        cases[1].1 = 2;
        cases[2].0[..4].copy_from_slice(&[0x11, 0x22, 0x00, 0x33]);
        cases[2].1 = 4;
        cases[3].0[..4].copy_from_slice(&[0x11, 0x00, 0x00, 0x00]);
        cases[3].1 = 4;
        for (i, case) in cases.iter_mut().enumerate().skip(4) {
            let len = [253, 254, 255, 600][i - 4];
            for (j, b) in case.0[..len].iter_mut().enumerate() {
                *b = (j % 255 + 1) as u8;
            }
            case.1 = len;
        }
        for (raw, len) in cases {
            let raw = &raw[..len];
            let mut enc = [0u8; 700];
            let n = cobs_encode(raw, &mut enc).or_fail("fits")?;
            assert!(n <= cobs_max_encoded_len(len));
            assert!(!enc[..n].contains(&0), "encoded block holds a zero");
            let mut dec = enc;
            let m = cobs_decode_in_place(&mut dec[..n]).or_fail("decodes")?;
            assert_eq!(&dec[..m], raw);
        }
        let mut textbook = [0u8; 8];
        let n = cobs_encode(&[0x11, 0x22, 0x00, 0x33], &mut textbook).or_fail("fits")?;
        assert_eq!(&textbook[..n], &[0x03, 0x11, 0x22, 0x02, 0x33]);
        Ok(())
    }

    #[test]
    fn malformed_blocks_are_refused() {
        assert_eq!(cobs_decode_in_place(&mut [0x05, 0x11]), None);
        assert_eq!(cobs_decode_in_place(&mut [0x02, 0x00]), None);
        assert_eq!(cobs_decode_in_place(&mut [0x00]), None);
        let mut short = [0u8; 2];
        assert_eq!(cobs_encode(&[1, 2, 3], &mut short), None);
    }
}
