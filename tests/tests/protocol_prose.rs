//! PROTOCOL.md's words for its worked examples (issue 32): each description is made here from
//! the example's own bytes, read at the offsets the field tables give, so a value changed in the
//! prose and not in the bytes (or the other way) fails. protocol_doc.rs holds the bytes to
//! `scripts/protocol_examples.py` and to mema.

use crate::guides::{says, thousands};
use crate::protocol_doc::document_examples;

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes(b[at..at + 2].try_into().unwrap())
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn i32_at(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

/// As the document writes a value: its shortest form, a true minus sign, and thousands
/// separated where `separated`.
fn shown(v: f64, separated: bool) -> String {
    let sign = if v < 0.0 { "−" } else { "" };
    let text = format!("{}", v.abs());
    let (whole, fraction) = text.split_once('.').unwrap_or((&text, ""));
    let whole = if separated {
        thousands(whole.parse().expect("digits"))
    } else {
        whole.to_string()
    };
    let dot = if fraction.is_empty() { "" } else { "." };
    format!("{sign}{whole}{dot}{fraction}")
}

/// `(a, b, c)` of three values.
fn triple(v: [f64; 3], separated: bool) -> String {
    format!("({})", v.map(|x| shown(x, separated)).join(", "))
}

fn ints(b: &[u8], at: usize) -> [f64; 3] {
    [0, 4, 8].map(|o| f64::from(i32_at(b, at + o)))
}

fn floats(b: &[u8], at: usize) -> [f64; 3] {
    // An f32 as its shortest decimal, as the document writes it.
    [0, 4, 8].map(|o| f32_at(b, at + o).to_string().parse().expect("a number"))
}

/// A quaternion (x, y, z, w) in units of 2^-30 applied to `p` (normalised, so its units do
/// not matter).
fn turned(q: [f64; 4], p: [f64; 3]) -> [f64; 3] {
    let m = crate::util::quaternion_matrix(q);
    [0, 1, 2].map(|i| (0..3).map(|j| m[i][j] * p[j]).sum())
}

#[test]
fn the_examples_are_what_their_words_say() {
    let e: Vec<Vec<u8>> = document_examples().into_iter().map(|e| e.raw).collect();
    assert_eq!(e.len(), 17, "the examples, in the script's order");
    // The rangefinder's wire: version 1 points, then version 2's pose, points and wide pose.
    let v1 = &e[0];
    let end = |b: &[u8]| b[1] & 1 == 1;
    assert!(end(v1) && v1[8] as i8 == -3 && u16_at(v1, 6) == 2);
    says(
        "PROTOCOL.md",
        &format!(
            "A version 1 frame with sequence {}, the end-of-stream flag, unit millimetres, and \
             two points: {} mm and {} mm.",
            u32_at(v1, 2),
            triple(ints(v1, 10), false),
            triple(ints(v1, 22), false)
        ),
    );
    let (pose, points) = (&e[1], &e[2]);
    let q = [26, 30, 34, 38].map(|o| i32_at(pose, o));
    says(
        "PROTOCOL.md",
        &format!(
            "a pose frame that starts a session (sequence {}, pose number {}, millimetres), with \
             the sensor at {} mm, turned a quarter turn about z (`q = (0, 0, sin 45°, cos 45°)`, \
             on the wire `({})`)",
            u32_at(pose, 2),
            u32_at(pose, 10),
            triple(ints(pose, 14), false),
            q.map(|c| c.to_string()).join(", ")
        ),
    );
    assert!(
        pose[1] & 2 == 2
            && q[2] == (f64::sin(std::f64::consts::FRAC_PI_4) * 2f64.powi(30)).round() as i32
    );
    let world = |at: usize| {
        let local = ints(points, at);
        let r = turned(q.map(f64::from), local);
        let t = ints(pose, 14);
        // Metres, to the millimetre the example's unit gives.
        [0, 1, 2].map(|j| ((r[j] + t[j]).round()) / 1e3)
    };
    assert!(end(points) && u32_at(points, 10) == u32_at(pose, 10));
    says(
        "PROTOCOL.md",
        &format!(
            "then the points measured at it (sequence {}, end of stream, pose number {}), {} mm \
             and {} mm in the sensor frame, which land at {} m and {} m in the world:",
            u32_at(points, 2),
            u32_at(points, 10),
            triple(ints(points, 14), false),
            triple(ints(points, 26), false),
            triple(world(14), false),
            triple(world(26), false)
        ),
    );
    let wide = &e[3];
    let at = [14, 22, 30].map(|o| u64_at(wide, o) as i64);
    says(
        "PROTOCOL.md",
        &format!(
            "A wide pose (sequence {}, pose number {}, millimetres): the sensor at the ECEF-like \
             {} m, unturned, as i64 ({}):",
            u32_at(wide, 2),
            u32_at(wide, 10),
            triple(at.map(|v| v as f64 / 1e3), true),
            at.map(|v| v.to_string()).join(", ")
        ),
    );

    // The device's frames: the header's session and boot at 2 and 6, its sequence at 10.
    let (booted, started) = (&e[4], &e[5]);
    assert_eq!(u32_at(booted, 2), 0);
    assert_eq!(
        (booted[14], started[14], started[24]),
        (0, 1, 1),
        "booted, started, shells"
    );
    says(
        "PROTOCOL.md",
        &format!(
            "From boot {}, in session `{:#010x}` where there is one: the session frame at boot \
             (sequence {}, no session) and after the start (sequence {}), each saying {} \
             entities, {} working, shells;",
            u32_at(started, 6),
            u32_at(started, 2),
            u32_at(booted, 10),
            u32_at(started, 10),
            u32_at(started, 16),
            u32_at(started, 20)
        ),
    );
    let entity = &e[6];
    assert_eq!(entity[18], 2, "a pseudocylinder");
    assert_eq!(floats(entity, 43), [0.0; 3], "not turned");
    says(
        "PROTOCOL.md",
        &format!(
            "an entity frame (sequence {}, index {}, a pseudocylinder at {} m with weights {}, \
             not turned);",
            u32_at(entity, 10),
            u32_at(entity, 14),
            triple(floats(entity, 19), false),
            triple(floats(entity, 31), false)
        ),
    );
    let progress = &e[7];
    says(
        "PROTOCOL.md",
        &format!(
            "a progress frame (sequence {}, {} bytes taken, {} frames mapped, carry frame {} \
             expected next, {} frame refused);",
            u32_at(progress, 10),
            thousands(u32_at(progress, 14).into()),
            u32_at(progress, 18),
            u32_at(progress, 22),
            u32_at(progress, 26)
        ),
    );
    let end_frame = &e[8];
    assert_eq!(
        (u32_at(end_frame, 14), end_frame[18]),
        (1, 1),
        "one entity, oriented"
    );
    says(
        "PROTOCOL.md",
        &format!(
            "an end frame (sequence {}, one entity, oriented layout, shift {} m, origin {} m, a \
             file of {} bytes with CRC-32 `{:#010x}`, {} points in {} frames mapped);",
            u32_at(end_frame, 10),
            triple(floats(end_frame, 31), false),
            triple([43, 51, 59].map(|o| f64_at(end_frame, o)), true),
            u32_at(end_frame, 67),
            u32_at(end_frame, 71),
            u32_at(end_frame, 75),
            u32_at(end_frame, 79)
        ),
    );
    let timing = &e[9];
    let t = |i: usize| thousands(u64_at(timing, 14 + 8 * i));
    assert_eq!(u32_at(timing, 70), 0, "no ring overrun");
    says(
        "PROTOCOL.md",
        &format!(
            "a timing frame (sequence {}: {} busy ticks, {} in the interrupt, longest tick {}, {} \
             calibration ticks for {} instructions, {} bytes of stack, {} cycles, no ring overrun \
             and {} UART overruns);",
            u32_at(timing, 10),
            t(0),
            t(1),
            t(2),
            t(3),
            t(4),
            t(5),
            t(6),
            u32_at(timing, 74)
        ),
    );
    let answer = &e[10];
    assert_eq!(answer[18], 1, "a ray");
    says(
        "PROTOCOL.md",
        &format!(
            "the answer to query {}, a ray, which met entity {} at {} m in {} ticks (sequence \
             {});",
            u32_at(answer, 14),
            u32_at(answer, 19),
            f64_at(answer, 23),
            thousands(u32_at(answer, 31).into()),
            u32_at(answer, 10)
        ),
    );
    let retract = &e[11];
    assert_eq!(retract[1], 6, "a retraction");
    says(
        "PROTOCOL.md",
        &format!(
            "and the retraction of entity {} (sequence {}).",
            u32_at(retract, 14),
            u32_at(retract, 10)
        ),
    );

    // The host's: start, carry, resend, resend the end, query.
    let (start, carry, resend, query) = (&e[12], &e[13], &e[14], &e[16]);
    let first = u32_at(resend, 14);
    let last = first + u32::from(u16_at(resend, 18)) - 1;
    assert_eq!(query[14], 1, "a ray");
    says(
        "PROTOCOL.md",
        &format!(
            "In session `{:#010x}` to boot {}: the start request (to any boot, carry frames from \
             {}), carry frame {} holding the first {} bytes of a stream (the leading delimiter and \
             the start of the pose frame above), a request for entities {first}, {} and {last}, a \
             request for the end, and query {}, a ray from {} m along {}:",
            u32_at(carry, 2),
            u32_at(carry, 6),
            u32_at(start, 14),
            u32_at(carry, 10),
            carry.len() - 18,
            first + 1,
            u32_at(query, 10),
            triple(floats(query, 15), false),
            triple(floats(query, 27), false)
        ),
    );
}

#[test]
fn values_are_shown_as_the_document_writes_them() {
    assert_eq!(shown(-2000.0, false), "−2000");
    assert_eq!(shown(4_198_000.4, true), "4,198,000.4");
    assert_eq!(shown(0.499, false), "0.499");
    assert_eq!(triple([1.0, -1.0, 0.5], false), "(1, −1, 0.5)");
}
