use super::super::testkit::{assert_same, expect_err, header_count, shared};
use super::super::{Endian, Format, read_cloud_bytes};
use ply_rs_bw::ply::{DefaultElement, Property};

/// An element to write: name, property lines ("float x", "list uchar int vertex_indices")
/// and rows, each holding scalars in order and a list as its count then its items.
type Element<'a> = (&'a str, Vec<&'a str>, Vec<Vec<f64>>);

pub fn write_ply(format: &str, elements: &[Element]) -> Vec<u8> {
    let mut out = format!("ply\nformat {format} 1.0\ncomment written by the tests\n");
    for (name, props, rows) in elements {
        out += &format!("element {name} {}\n", rows.len());
        props.iter().for_each(|p| out += &format!("property {p}\n"));
    }
    let mut out = (out + "end_header\n").into_bytes();
    for (_, props, rows) in elements {
        for row in rows {
            let mut values = row.iter().copied();
            for prop in props {
                let words: Vec<&str> = prop.split(' ').collect();
                let (n, ty) = match words[..] {
                    ["list", c, ty, _] => (put(&mut out, format, c, values.next().unwrap()), ty),
                    [ty, _] => (1.0, ty),
                    _ => panic!("{prop}"),
                };
                (0..n as usize).for_each(|_| _ = put(&mut out, format, ty, values.next().unwrap()));
            }
            if format == "ascii" {
                out.push(b'\n');
            }
        }
    }
    out
}

fn put(out: &mut Vec<u8>, format: &str, ty: &str, v: f64) -> f64 {
    macro_rules! bytes {
        ($t:ty) => {{
            let x = v as $t;
            match format {
                "binary_big_endian" => out.extend_from_slice(&x.to_be_bytes()),
                "binary_little_endian" => out.extend_from_slice(&x.to_le_bytes()),
                _ => out.extend_from_slice(format!("{x} ").as_bytes()),
            }
        }};
    }
    match ty {
        "char" | "int8" => bytes!(i8),
        "uchar" | "uint8" => bytes!(u8),
        "short" | "int16" => bytes!(i16),
        "ushort" | "uint16" => bytes!(u16),
        "int" | "int32" => bytes!(i32),
        "uint" | "uint32" => bytes!(u32),
        "float" | "float32" => bytes!(f32),
        "double" | "float64" => bytes!(f64),
        _ => panic!("{ty}"),
    }
    v
}

/// bun_zipper.ply re-encoded in binary, with its confidence, intensity and faces.
pub fn bunny_binary(endian: Endian) -> Vec<u8> {
    let text = String::from_utf8(shared("bun_zipper.ply")).unwrap();
    let body = text.split("end_header\n").nth(1).unwrap();
    let parse = |l: &str| l.split_whitespace().map(|t| t.parse().unwrap()).collect();
    let rows: Vec<Vec<f64>> = body.lines().map(parse).collect();
    let (vertices, faces) = rows.split_at(header_count(text.as_bytes(), "element vertex"));
    let format = match endian {
        Endian::Little => "binary_little_endian",
        Endian::Big => "binary_big_endian",
    };
    let props = "float x,float y,float z,float confidence,float intensity".split(',');
    let vertices = ("vertex", props.collect(), vertices.to_vec());
    let face_props = vec!["list uchar int vertex_indices"];
    let faces = ("face", face_props, faces.to_vec());
    write_ply(format, &[vertices, faces])
}

/// The vertices as the independent ply-rs-bw crate reads them.
fn ply_rs(bytes: &[u8]) -> Vec<[f64; 3]> {
    let parser = ply_rs_bw::parser::Parser::<DefaultElement>::new();
    let ply = parser.read_ply(&mut &bytes[..]).unwrap();
    let value = |v: &DefaultElement, k: &str| match v[k] {
        Property::Float(f) => f64::from(f),
        ref other => panic!("{k}: {other:?}"),
    };
    ply.payload["vertex"]
        .iter()
        .map(|v| ["x", "y", "z"].map(|k| value(v, k)))
        .collect()
}

#[test]
fn shared_plys_match_ply_rs_bw() {
    for (name, count) in [("bun000.ply", 40_256), ("bun_zipper.ply", 35_947)] {
        let bytes = shared(name);
        let cloud = read_cloud_bytes(name, &bytes).unwrap();
        assert_eq!(cloud.slots, header_count(&bytes, "element vertex"));
        let got = (cloud.slots, cloud.points.len(), cloud.format);
        assert_eq!(got, (count, count, Format::PlyAscii));
        assert_same(&cloud, &ply_rs(&bytes), name);
    }
}

#[test]
fn binary_bunny_in_both_byte_orders() {
    let ascii = read_cloud_bytes("bun_zipper.ply", &shared("bun_zipper.ply")).unwrap();
    let origin = ascii.origin;
    let to_f64 = |p: &[f32; 3]| std::array::from_fn(|k| origin[k] + f64::from(p[k]));
    let want: Vec<[f64; 3]> = ascii.points.iter().map(to_f64).collect();
    for (endian, format) in [
        (Endian::Little, Format::PlyBinaryLittleEndian),
        (Endian::Big, Format::PlyBinaryBigEndian),
    ] {
        let bytes = bunny_binary(endian);
        let cloud = read_cloud_bytes("bunny.ply", &bytes).unwrap();
        assert_eq!((cloud.format, cloud.slots), (format, 35_947));
        assert_same(&cloud, &ply_rs(&bytes), "binary vs ply-rs-bw");
        assert_same(&cloud, &want, "binary vs ascii");
    }
}

/// x, y, z of every type and alias, among other properties (a list among them), after
/// elements that must be skipped, in all three encodings.
#[test]
fn every_type_and_layout_in_every_encoding() {
    let types = [
        "char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8",
        "int16", "uint16", "int32", "uint32", "float32", "float64",
    ];
    let want: Vec<[f64; 3]> = (0..20)
        .map(|k| [f64::from(k * 3), f64::from(100 - k), f64::from(k)])
        .collect();
    let row = |k: usize, [x, y, z]: [f64; 3]| {
        let list = (0..k % 3).map(|j| j as f64 + 0.5);
        [z, (k % 3) as f64]
            .into_iter()
            .chain(list)
            .chain([7.0, x, y])
            .collect()
    };
    let grid: Vec<Vec<f64>> = (0..9).map(|k| vec![(k % 4) as f64; 1 + k % 4]).collect();
    let rows: Vec<Vec<f64>> = want.iter().enumerate().map(|(k, p)| row(k, *p)).collect();
    for (i, ty) in types.iter().enumerate() {
        let z = format!("{ty} z");
        let x = format!("{} x", types[(i + 3) % 16]);
        let y = format!("{} y", types[(i + 7) % 16]);
        let vertex = vec![z.as_str(), "list uchar float junk", "ushort w", &x, &y];
        let (grid_props, camera) = (vec!["list uchar int i"], vec!["double u", "char v"]);
        let elements = [
            ("range_grid", grid_props, grid.clone()),
            ("nothing", vec![], vec![vec![]; 5]),
            ("camera", camera, vec![vec![1.5, -1.0]; 3]),
            ("vertex", vertex, rows.clone()),
            (
                "face",
                vec!["list uchar uint i"],
                vec![vec![3.0, 0.0, 1.0, 2.0]],
            ),
        ];
        for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
            let cloud = read_cloud_bytes("types.ply", &write_ply(format, &elements)).unwrap();
            assert_same(&cloud, &want, &format!("{format} {ty}"));
        }
    }
}

#[test]
fn bad_headers_and_lying_counts() {
    let check = |format: &str, header: &str, body: &[u8], variant: &str| {
        let xyz = "property float x\nproperty float y\nproperty float z\n";
        let header = header.replace("XYZ", xyz);
        let head = format!("ply\nformat {format} 1.0\n{header}end_header\n");
        expect_err("h.ply", &[head.as_bytes(), body].concat(), variant)
    };
    let (a, le, be) = ("ascii", "binary_little_endian", "binary_big_endian");
    let huge = "element vertex 1000000000000000000\nXYZ";
    let grid = format!("element grid 1000000000000000000\nproperty list uchar int i\n{huge}");
    let fixed = format!("element grid 1000000000000000000\nproperty int i\n{huge}");
    check(le, huge, &[0; 24], "Truncated");
    check(be, &grid, &[1, 0, 0, 0, 0], "Truncated");
    check(be, &fixed, &[0; 24], "Truncated");
    check(a, huge, b"1 2 3\n4 5 6\n", "Truncated");
    check(a, &grid, b"1 2\n", "Truncated");
    let negative = "element g 1\nproperty list char int i\nelement vertex 1\nXYZ";
    check(le, negative, &[255], "BadValue");
    let (no_z, no_vertex) = (
        "element vertex 1\nproperty float x\nproperty float y\n",
        "element face 1\n",
    );
    check(a, no_z, b"", "BadHeader");
    check(a, no_vertex, b"", "BadHeader");
    let list_x = "element vertex 1\nproperty list uchar float x\nXYZ";
    check(a, list_x, b"", "Unsupported");
    check(a, "element vertex 1\nproperty flt x\n", b"", "BadHeader");
    check(a, "property float x\n", b"", "BadHeader");
    check(a, "element vertex 0\nXYZ", b"", "NoFinitePoints");
    check(a, "element vertex 1\nXYZ", b"1 2 3 4\n", "BadValue");
    check("2.0", "", b"", "BadHeader");
    check(a, "XYZ", b"", "BadHeader");
    let version = b"ply\nformat ascii 2.0\nend_header\n";
    expect_err("v.ply", version, "Unsupported");
    let e = check(a, "element vertex 2\nXYZ", b"1 2 3\n1 abc 3\n", "BadValue");
    let want = "h.ply: line 9: 'abc' is not a number; expected vertex y";
    assert_eq!(e.to_string(), want);
}

/// A header costs memory for what it declares, not a `String` per line: past 65,536
/// properties, 4,096 elements or a 64 KiB line it is too large, and a message lists a few of
/// the names, not all of them.
#[test]
fn header_lines_are_bounded() {
    let xyz = "property float x\nproperty float y\nproperty float z\n";
    let ply = |header: &str, body: &[u8]| {
        let head = format!("ply\nformat binary_little_endian 1.0\n{header}end_header\n");
        [head.as_bytes(), body].concat()
    };
    let props = |n: usize| "property char p\n".repeat(n);
    // Properties count over every element, kept or not: after the vertex too.
    let wide = format!("element vertex 1\n{}{xyz}", props(65_534));
    let e = expect_err("wide.ply", &ply(&wide, &[0; 65_546]), "TooLarge");
    let want = "wide.ply: too large: PLY header line 65540 declares property 65537; at most 65536 are read";
    assert_eq!(e.to_string(), want);
    let after = format!("element vertex 1\n{xyz}element face 0\n{}", props(65_534));
    expect_err("after.ply", &ply(&after, &[0; 12]), "TooLarge");
    let elements = format!("{}element vertex 1\n{xyz}", "element e 0\n".repeat(4096));
    let e = expect_err("many.ply", &ply(&elements, &[0; 12]), "TooLarge");
    let want =
        "many.ply: too large: PLY header line 4099 declares element 4097; at most 4096 are read";
    assert_eq!(e.to_string(), want);
    let long = format!("element {} 1\n{xyz}", "v".repeat(70_000));
    let e = expect_err("long.ply", &ply(&long, &[0; 12]), "TooLarge");
    assert!(e.to_string().contains("line 3 is 70010 bytes"), "{e}");
    // Just under every limit, with a long comment (comments are not kept), reads.
    let comment = format!("comment {}\n", "c".repeat(100_000));
    let name = "v".repeat(65_000);
    let most = format!(
        "{comment}{}element {name} 1\nproperty char {name}\nelement vertex 1\n{}{xyz}element face 2\n{}",
        "element e 0\n".repeat(4093),
        props(32_000),
        props(33_532),
    );
    let body = [
        vec![0; 1 + 32_000],
        [1.0f32, 2.0, 3.0].map(f32::to_le_bytes).concat(),
    ]
    .concat();
    let cloud = read_cloud_bytes("most.ply", &ply(&most, &body)).unwrap();
    assert_eq!((cloud.slots, cloud.origin), (1, [1.0, 2.0, 3.0]));
    // Messages name eight properties or elements, and how many there are.
    let no_z = format!("element vertex 1\n{}property float x\n", props(20));
    let e = expect_err("noz.ply", &ply(&no_z, b""), "BadHeader");
    let want = "noz.ply: header: element vertex has no property y (it has: p p p p p p p p ... 21 properties in all)";
    assert_eq!(e.to_string(), want);
    let e = expect_err(
        "nov.ply",
        &ply(&"element e 0\n".repeat(9), b""),
        "BadHeader",
    );
    let want =
        "nov.ply: header: no vertex element (elements: e e e e e e e e ... 9 elements in all)";
    assert_eq!(e.to_string(), want);
}
