use super::super::lzf::tests::literal_stream;
use super::super::points::Wide;
use super::super::testkit::{DATA, XorShift, assert_same, expect_err, header_count, shared};
use super::super::{Ctx, Format, Points, ReadError, Scalar, read_cloud_bytes};
use super::body::{Columns, UPFRONT};
use super::{Coord, coord};

/// (name, TYPE, SIZE, COUNT) of a field to write.
type Field<'a> = (&'a str, char, usize, usize);

/// Writes a PCD; each row holds every value of a point, in field order.
pub fn write_pcd(data: &str, fields: &[Field], width: usize, rows: &[Vec<f64>]) -> Vec<u8> {
    let list = |f: fn(&Field) -> String| fields.iter().map(f).collect::<Vec<_>>().join(" ");
    let (height, points) = (rows.len() / width, rows.len());
    let mut out = format!(
        "# .PCD v0.7 - written by the tests\nVERSION 0.7\nFIELDS {}\nSIZE {}\nTYPE {}\nCOUNT {}\n\
         WIDTH {width}\nHEIGHT {height}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\nDATA {data}\n",
        list(|f| f.0.into()),
        list(|f| f.2.to_string()),
        list(|f| f.1.into()),
        list(|f| f.3.to_string()),
    )
    .into_bytes();
    let put = |out: &mut Vec<u8>, f: &Field, v: f64| match (f.1, f.2) {
        _ if data == "ascii" => out.extend_from_slice(format!("{} ", v as f32).as_bytes()),
        ('F', 4) => out.extend_from_slice(&(v as f32).to_le_bytes()),
        ('F', 8) => out.extend_from_slice(&v.to_le_bytes()),
        ('U', 1) => out.push(v as u8),
        ('U', 4) => out.extend_from_slice(&(v as u32).to_le_bytes()),
        ('I', 2) => out.extend_from_slice(&(v as i16).to_le_bytes()),
        other => panic!("{other:?}"),
    };
    // (field, index of its first value in a row)
    let starts = fields
        .iter()
        .scan(0, |n, f| Some((f, std::mem::replace(n, *n + f.3))));
    if data == "binary_compressed" {
        // Field-major, without the padding fields, as PCL writes it.
        let mut columns = Vec::new();
        for (f, start) in starts.filter(|(f, _)| f.0 != "_") {
            rows.iter()
                .for_each(|r| (0..f.3).for_each(|c| put(&mut columns, f, r[start + c])));
        }
        let stream = literal_stream(&columns);
        out.extend_from_slice(&(stream.len() as u32).to_le_bytes());
        out.extend_from_slice(&(columns.len() as u32).to_le_bytes());
        return [out, stream].concat();
    }
    let starts: Vec<_> = starts.collect();
    for row in rows {
        for &(f, start) in &starts {
            (0..f.3).for_each(|c| put(&mut out, f, row[start + c]));
        }
        if data == "ascii" {
            out.push(b'\n');
        }
    }
    out
}

/// All slots of a shared PCD as the independent pcd-rs crate reads them.
fn pcd_rs(name: &str) -> Vec<[f64; 3]> {
    let reader = pcd_rs::DynReader::open(format!("{DATA}/{name}")).unwrap();
    let defs = &reader.meta().field_defs;
    let index = ["x", "y", "z"].map(|a| defs.iter().position(|f| f.name == a).unwrap());
    let value = |f: &pcd_rs::Field| match f {
        pcd_rs::Field::F32(v) => f64::from(v[0]),
        other => panic!("{other:?}"),
    };
    let records: Vec<pcd_rs::DynRecord> = reader.collect::<Result<_, _>>().unwrap();
    let point = |r: &pcd_rs::DynRecord| index.map(|i| value(&r.0[i]));
    records.iter().map(point).collect()
}

fn finite(points: impl IntoIterator<Item = [f64; 3]>) -> Vec<[f64; 3]> {
    let ok = |p: &[f64; 3]| p.iter().all(|c| c.is_finite());
    points.into_iter().filter(ok).collect()
}

#[test]
fn shared_pcds_match_pcd_rs() {
    use Format::{PcdAscii as Ascii, PcdBinaryCompressed as Lzf};
    for (name, slots, kept, format) in [
        ("car6.pcd", 10_031, 10_031, Lzf),
        ("milk.pcd", 13_704, 13_704, Lzf),
        ("lamppost.pcd", 1_771, 1_771, Ascii),
        ("rops_cloud.pcd", 32_087, 32_087, Ascii),
        ("cturtle.pcd", 167_198, 167_198, Lzf),
        ("five_people.pcd", 307_200, 239_075, Lzf),
        ("office1.pcd", 307_200, 254_456, Lzf),
    ] {
        let bytes = shared(name);
        let cloud = read_cloud_bytes(name, &bytes).unwrap();
        assert_eq!(cloud.slots, header_count(&bytes, "POINTS"), "{name}");
        let counts = (cloud.slots, cloud.points.len(), cloud.dropped_non_finite);
        assert_eq!(counts, (slots, kept, slots - kept), "{name}");
        assert_eq!(cloud.format, format, "{name}");
        assert_same(&cloud, &finite(pcd_rs(name)), name);
    }
}

/// car6's points with a NaN hole every tenth slot, as an organized 5015 × 2 cloud with
/// fields around x y z (padding among them).
pub fn car6_as(data: &str, coord_size: usize) -> Vec<u8> {
    let fields = [
        ("intensity", 'F', 4, 1),
        ("x", 'F', coord_size, 1),
        ("_", 'U', 1, 4),
        ("ring", 'I', 2, 1),
        ("y", 'F', coord_size, 1),
        ("normal", 'F', 4, 3),
        ("z", 'F', coord_size, 1),
        ("label", 'U', 4, 1),
    ];
    let hole = |i: usize, c: f64| if i % 10 == 3 { f64::NAN } else { c };
    let rows: Vec<Vec<f64>> = (pcd_rs("car6.pcd")[..10_030].iter().enumerate())
        .map(|(i, p)| {
            let mut row = vec![i as f64, hole(i, p[0]), 0.0, 1.0, 2.0, 3.0, 7.0];
            row.extend([p[1], 0.5, 0.2, 0.1, p[2], 255.0]);
            row
        })
        .collect();
    write_pcd(data, &fields, 5015, &rows)
}

#[test]
fn car6_in_every_encoding_and_coordinate_type() {
    let car6 = pcd_rs("car6.pcd");
    let holes = car6[..10_030].iter().enumerate();
    let want = finite(holes.map(|(i, p)| if i % 10 == 3 { [f64::NAN; 3] } else { *p }));
    use Format::{PcdAscii, PcdBinary, PcdBinaryCompressed};
    for (data, format) in [
        ("ascii", PcdAscii),
        ("binary", PcdBinary),
        ("binary_compressed", PcdBinaryCompressed),
    ] {
        for size in [4, 8] {
            let cloud = read_cloud_bytes("car6.pcd", &car6_as(data, size)).unwrap();
            let got = (cloud.format, cloud.slots, cloud.dropped_non_finite);
            assert_eq!(got, (format, 10_030, 1003), "{data} F{size}");
            assert_same(&cloud, &want, &format!("{data} F{size}"));
        }
    }
}

#[test]
fn old_headers_bad_headers_and_lying_counts() {
    // v0.5/0.6 style: no VERSION, COLUMNS, no SIZE/TYPE (4-byte floats), no WIDTH.
    let old = b"COLUMNS x y z\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 nan\n";
    let cloud = read_cloud_bytes("old.pcd", old).unwrap();
    assert_eq!((cloud.slots, cloud.points.len()), (2, 1));
    assert_eq!(cloud.origin, [1.0, 2.0, 3.0]);
    // XYZ stands for the field lines of x y z as 4-byte floats.
    let check = |header: &str, data: &str, body: &[u8], variant: &str| {
        let fields = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1";
        let head = format!("VERSION 0.7\n{header}\nDATA {data}\n").replace("XYZ", fields);
        expect_err("bad.pcd", &[head.as_bytes(), body].concat(), variant)
    };
    let e = check("XYZ\nWIDTH 3", "ascii", b"1 2 3\n4 5\n6 7 8\n", "BadValue");
    assert_eq!(
        e.to_string(),
        "bad.pcd: line 9: 2 values; the fields need 3"
    );
    let huge = "XYZ\nWIDTH 1000000000000000000\nHEIGHT 1\nPOINTS 1000000000000000000";
    check(huge, "binary", &[0; 100], "Truncated");
    check(huge, "ascii", b"1 2 3\n", "Truncated");
    check("XYZ\nWIDTH 1", "lzma", b"", "Unsupported");
    check(
        "XYZ\nWIDTH 2",
        "ascii",
        b"nan nan nan\nnan 1 1\n",
        "NoFinitePoints",
    );
    let count = "FIELDS x y z w\nCOUNT 1 1 1 1000000000000000000000\nWIDTH 1";
    let size = "FIELDS x y z w\nSIZE 4 4 4 1000000000000\nCOUNT 1 1 1 1000000000\nWIDTH 1";
    for (header, variant) in [
        ("XYZ\nWIDTH 4294967296\nHEIGHT 4294967296", "BadHeader"),
        ("XYZ\nWIDTH 3\nPOINTS 4", "BadHeader"),
        ("XYZ\nHEIGHT 3", "BadHeader"),
        ("XYZ\nWIDTH 0", "NoFinitePoints"),
        ("XYZ\nWIDTH 1\nFOO 3", "BadHeader"),
        ("FIELDS x y q\nWIDTH 1", "BadHeader"),
        ("FIELDS x y z\nSIZE 4 4\nWIDTH 1", "BadHeader"),
        ("FIELDS x y z\nTYPE F F Q\nWIDTH 1", "BadHeader"),
        ("FIELDS x y z\nSIZE 2 4 4\nWIDTH 1", "Unsupported"),
        ("FIELDS x y z\nCOUNT 2 1 1\nWIDTH 1", "Unsupported"),
        (count, "BadHeader"),
        (size, "BadHeader"),
    ] {
        check(header, "binary", b"", variant);
    }
}

/// Fields as the header parser makes them, from (name, TYPE, SIZE, COUNT).
fn header_fields<'a>(fields: &[Field<'a>]) -> Vec<super::Field<'a>> {
    let field = |&(name, ty, size, count): &Field<'a>| super::Field {
        name: name.as_bytes(),
        size,
        ty: ty as u8,
        count,
    };
    fields.iter().map(field).collect()
}

fn coords(fields: &[super::Field]) -> [Coord; 3] {
    ["x", "y", "z"].map(|axis| coord(Ctx::new("t"), fields, axis).unwrap())
}

/// LZF's 88× bound lets 49 MB of data claim 358 million points of f64 slots: before the data
/// backs a claim, at most `UPFRONT` bytes of slots are reserved, and each value of the first
/// coordinate column brings its slot.
#[test]
fn claimed_slots_come_with_the_data() {
    let fields = header_fields(&[("x", 'I', 4, 1), ("y", 'I', 4, 1), ("z", 'I', 4, 1)]);
    let n = 357_913_941;
    let columns = Columns::<Wide>::new(coords(&fields), n, UPFRONT).unwrap();
    assert!(columns.slots.is_empty());
    assert!(columns.slots.capacity() * size_of::<Wide>() <= UPFRONT);
    let xs: Vec<u8> = (0..1000i32).flat_map(|i| (i - 500).to_le_bytes()).collect();
    // Past the first reservation (none here) the slots double, never beyond the values seen.
    let mut columns = Columns::<Wide>::new(coords(&fields), n, 0).unwrap();
    for (i, piece) in xs.chunks(7).enumerate() {
        columns.take(7 * i, piece);
        columns.grown().unwrap();
        let (len, capacity) = (columns.slots.len(), columns.slots.capacity());
        assert_eq!(len, (7 * i + piece.len()) / 4);
        assert!(
            capacity <= 2 * len.max(2),
            "{capacity} slots for {len} values"
        );
    }
    let x = |s: &Wide| s.get()[0];
    assert!((columns.slots.iter().map(x)).eq((0..1000).map(|i| f64::from(i - 500))));
    // A reservation the machine cannot make is an error, not an abort.
    assert!(Columns::<Wide>::new(coords(&fields), usize::MAX / 8, usize::MAX).is_err());
    let e = Points::with_capacity(Ctx::new("big.pcd"), usize::MAX / 8)
        .err()
        .unwrap();
    assert!(matches!(e, ReadError::OutOfMemory { .. }), "{e:?}");
    assert!(e.to_string().starts_with("big.pcd: out of memory: "), "{e}");
    // The whole file: a claim past `UPFRONT` with data that decodes to far less.
    let bogus = claim_beyond_its_data();
    let e = expect_err("claim.pcd", &bogus, "BadValue");
    assert!(e.to_string().contains("LZF data decompresses to"), "{e}");
}

/// A binary_compressed PCD of `TYPE I I I` claiming 4 million points (96 MB of f64 slots)
/// with the fewest compressed bytes LZF's bound allows, all of them one-byte literal runs
/// that decode to 273 KB.
fn claim_beyond_its_data() -> Vec<u8> {
    let (points, record) = (4_000_000usize, 12);
    let unpacked = points * record;
    let packed = unpacked.div_ceil(88).next_multiple_of(2);
    let header = format!(
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE I I I\nCOUNT 1 1 1\nWIDTH {points}\n\
         HEIGHT 1\nPOINTS {points}\nDATA binary_compressed\n"
    );
    let sizes = [packed as u32, unpacked as u32]
        .map(u32::to_le_bytes)
        .concat();
    [header.into_bytes(), sizes, vec![0; packed]].concat()
}

/// Every coordinate type, in fields among padding and extra ones and in any axis order, from
/// field-major output fed one byte at a time: the slots hold exactly the values written, as
/// f64 and, where every axis fits, as f32.
#[test]
fn columns_take_every_coordinate_type_from_single_bytes() {
    use Scalar::{F32, F64, I8, I16, I32, I64, U8, U16, U32, U64};
    let mut rng = XorShift(0xc0ff_ee11);
    // A value exact in the type (and in f64), and its little-endian bytes.
    let value = |s: Scalar, r: u64| -> (f64, Vec<u8>) {
        match s {
            I8 => (f64::from(r as i8), (r as i8).to_le_bytes().to_vec()),
            U8 => (f64::from(r as u8), vec![r as u8]),
            I16 => (f64::from(r as i16), (r as i16).to_le_bytes().to_vec()),
            U16 => (f64::from(r as u16), (r as u16).to_le_bytes().to_vec()),
            I32 => (f64::from(r as i32), (r as i32).to_le_bytes().to_vec()),
            U32 => (f64::from(r as u32), (r as u32).to_le_bytes().to_vec()),
            I64 => (
                (r as i64 >> 11) as f64,
                (r as i64 >> 11).to_le_bytes().to_vec(),
            ),
            U64 => ((r >> 11) as f64, (r >> 11).to_le_bytes().to_vec()),
            F32 => {
                let v = r as i32 as f32 / 64.0;
                (f64::from(v), v.to_le_bytes().to_vec())
            }
            F64 => {
                let v = (r as i64 >> 11) as f64 / 1024.0;
                (v, v.to_le_bytes().to_vec())
            }
        }
    };
    let spec = |s: Scalar| match s {
        F32 | F64 => ('F', s.size()),
        I8 | I16 | I32 | I64 => ('I', s.size()),
        U8 | U16 | U32 | U64 => ('U', s.size()),
    };
    let n = 37;
    for (types, names) in [
        ([I8, U8, I16], ["x", "y", "z"]),
        ([U16, F32, I8], ["z", "x", "y"]),
        ([I32, U32, F64], ["y", "z", "x"]),
        ([F64, F32, U8], ["x", "z", "y"]),
        ([I64, U64, U16], ["z", "y", "x"]),
    ] {
        let [a, b, c] = [0, 1, 2].map(|k| {
            let (ty, size) = spec(types[k]);
            (names[k], ty, size, 1)
        });
        let fields = [
            ("_", 'U', 1, 3),
            a,
            ("extra", 'F', 4, 2),
            b,
            ("_", 'I', 2, 1),
            c,
            ("label", 'U', 4, 1),
        ];
        // The output as PCL writes it: each field's column in turn, padding left out.
        let (mut out, mut want) = (Vec::new(), vec![[f64::NAN; 3]; n]);
        for &(name, _, size, count) in fields.iter().filter(|f| f.0 != "_") {
            let axis = ["x", "y", "z"].iter().position(|&a| a == name);
            let scalar = names.iter().position(|&a| a == name).map(|k| types[k]);
            for p in want.iter_mut() {
                match (axis, scalar) {
                    (Some(axis), Some(s)) => {
                        let (v, bytes) = value(s, rng.next());
                        p[axis] = v;
                        out.extend(bytes);
                    }
                    _ => out.extend((0..size * count).map(|_| rng.next() as u8)),
                }
            }
        }
        let what = format!("{types:?} as {names:?}");
        let coords = coords(&header_fields(&fields));
        // Single bytes cut every value; the whole output in one piece is the direct decode.
        for (piece, upfront) in [(1, 0), (1, UPFRONT), (out.len(), UPFRONT)] {
            let how = format!("{what}, pieces of {piece}, upfront {upfront}");
            let mut wide = Columns::<Wide>::new(coords, n, upfront).unwrap();
            (out.chunks(piece).enumerate()).for_each(|(i, b)| wide.take(i * piece, b));
            wide.grown().unwrap();
            let got: Vec<[f64; 3]> = wide.slots.iter().map(|s| s.get()).collect();
            assert_eq!(got, want, "{how}, f64 slots");
            if types.iter().all(|s| s.size() <= 2 || *s == F32) {
                let mut narrow = Columns::<[f32; 3]>::new(coords, n, upfront).unwrap();
                (out.chunks(piece).enumerate()).for_each(|(i, b)| narrow.take(i * piece, b));
                narrow.grown().unwrap();
                let got: Vec<[f64; 3]> = narrow.slots.iter().map(|p| p.map(f64::from)).collect();
                assert_eq!(got, want, "{how}, f32 slots");
            }
        }
    }
}

/// A header costs memory for what it says, not for each token it has: past 65,536 fields or a
/// 1 MiB line it is too large, and a missing axis lists a few of the names, not all of them.
#[test]
fn header_lines_are_bounded() {
    let names = |n: usize| {
        (0..n)
            .map(|i| format!("f{i}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let pcd = |fields: &str, extra: &str, values: usize| {
        let head = format!("VERSION 0.7\nFIELDS {fields}\n{extra}WIDTH 1\nDATA ascii\n");
        [head, "1 ".repeat(values), "\n".into()]
            .concat()
            .into_bytes()
    };
    let fields = format!("{} x y z", names(99_997));
    let e = expect_err("wide.pcd", &pcd(&fields, "", 100_000), "TooLarge");
    let want = "wide.pcd: too large: FIELDS on line 2 names 100000 fields; at most 65536 are read";
    assert_eq!(e.to_string(), want);
    let viewpoint = format!("VIEWPOINT{}\n", " 0".repeat(600_000));
    let e = expect_err("long.pcd", &pcd("x y z", &viewpoint, 3), "TooLarge");
    assert!(e.to_string().contains("line 3 is 1200000 bytes"), "{e}");
    // Just under both limits, and the later of COLUMNS and FIELDS is the one read.
    let fields = format!("{} x y z", names(65_533));
    let cloud = read_cloud_bytes("ok.pcd", &pcd(&fields, "", 65_536)).unwrap();
    assert_eq!(cloud.slots, 1);
    let old = pcd("a b c", "COLUMNS x y z\n", 3);
    assert_eq!(read_cloud_bytes("old.pcd", &old).unwrap().origin, [1.0; 3]);
    let e = expect_err("noz.pcd", &pcd(&names(1000), "", 1000), "BadHeader");
    let want =
        "noz.pcd: header: no field x (FIELDS f0 f1 f2 f3 f4 f5 f6 f7 ... 1000 fields in all)";
    assert_eq!(e.to_string(), want);
}
