use crate::guides::{says, thousands};
use crate::util::{Dir, MemaCommand, shared};
use mema::io::mapfile::HostMap;
use mema_core::EntityKind;
use serde_json::Value;

fn decode_png(path: &std::path::Path) -> (u32, u32, Vec<u8>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).expect("png written"));
    let mut reader = png::Decoder::new(file).read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("frame");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

fn colour(v: &Value) -> [u8; 3] {
    std::array::from_fn(|i| v[i].as_u64().expect("colour") as u8)
}

fn f3(v: &Value) -> [f64; 3] {
    std::array::from_fn(|i| v[i].as_f64().expect("number"))
}

/// Whether `p` is `c` times a Lambert shade in [ambient, 1] (each channel rounded).
fn is_shade_of(p: [u8; 3], c: [u8; 3]) -> bool {
    let m = (0..3).max_by_key(|&k| c[k]).unwrap_or(0);
    let s = f64::from(p[m]) / f64::from(c[m]);
    (0.34..=1.0).contains(&s)
        && (0..3).all(|k| (f64::from(p[k]) - (f64::from(c[k]) * s)).abs() <= 2.0)
}

fn map_cloud(dir: &Dir, cloud: &str, k: &str, out: &str, extra: &[&str]) {
    MemaCommand::new(dir)
        .arg("map")
        .arg(shared(cloud))
        .args(["--paper", "-k", k, "-o", out])
        .args(extra)
        .run()
        .assert_ok();
}

/// What a top view must show at a world (x, y): the highest entity surface and its kind, from
/// the closed form of an axis-aligned quadric; `None` for the kind when it is too close to an
/// edge (of a silhouette or a clip box) or a tie to call.
struct TopView {
    /// Centre, weights, kind, and the box cutting the infinite axes.
    entities: Vec<([f64; 3], [f64; 3], EntityKind, Box3)>,
}

type Box3 = ([f64; 3], [f64; 3]);

impl TopView {
    fn top(&self, x: f64, y: f64) -> Vec<(f64, EntityKind)> {
        let mut tops = Vec::new();
        for (c, w, kind, clip) in &self.entities {
            let q = [x, y];
            if (0..2).any(|j| w[j] == 0.0 && !(clip.0[j] <= q[j] && q[j] <= clip.1[j])) {
                continue;
            }
            let sum: f64 = (0..2).map(|j| w[j] * (q[j] - c[j]).powi(2)).sum();
            if sum > 1.0 {
                continue;
            }
            let z = if w[2] > 0.0 {
                c[2] + ((1.0 - sum) / w[2]).sqrt()
            } else {
                clip.1[2]
            };
            tops.push((z, *kind));
        }
        tops.sort_by(|a, b| b.0.total_cmp(&a.0));
        tops
    }
}

#[test]
fn draw_puts_entities_and_points_where_their_projections_fall() {
    let dir = Dir::new("draw");
    // The threshold search box lets axes degenerate, so every kind of solid is exercised.
    map_cloud(
        &dir,
        "bun_zipper.ply",
        "100",
        "b.mema",
        &["--bounds", "threshold"],
    );
    let report = MemaCommand::new(&dir)
        .arg("draw")
        .arg(shared("bun_zipper.ply"))
        .args([
            "b.mema", "--view", "top", "--size", "800x600", "--json", "-o", "top.png",
        ])
        .run()
        .assert_ok()
        .json();
    let (w, h, rgb) = decode_png(&dir.join("top.png"));
    assert_eq!((w, h), (800, 600));
    let pixel = |x: i64, y: i64| -> [u8; 3] {
        let i = 3 * (y as usize * w as usize + x as usize);
        [rgb[i], rgb[i + 1], rgb[i + 2]]
    };
    // The legend lists exactly the kinds `mema info` counts, with their colours.
    let info = MemaCommand::new(&dir)
        .args(["info", "b.mema", "--json"])
        .run()
        .assert_ok()
        .json();
    let panel = &report["panels"][0];
    let legend: Vec<(String, u64)> = panel["legend"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["kind"].as_str().unwrap().to_owned(),
                e["count"].as_u64().unwrap(),
            )
        })
        .collect();
    let counted: Vec<(String, u64)> = EntityKind::ALL
        .iter()
        .map(|k| {
            (
                k.name().to_owned(),
                info["kinds"][k.name()].as_u64().unwrap(),
            )
        })
        .filter(|(_, n)| *n > 0)
        .collect();
    assert_eq!(legend, counted);
    for e in panel["legend"].as_array().unwrap() {
        let s: Vec<i64> = e["swatch"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_i64().unwrap())
            .collect();
        for (x, y) in [(s[0], s[1]), (s[0] + s[2] - 1, s[1] + s[3] - 1)] {
            assert_eq!(pixel(x, y), colour(&e["colour"]), "{e}");
        }
    }
    // The geometry, computed here from the map, the cloud and the reported projection.
    let map = HostMap::read(&dir.join("b.mema")).unwrap();
    assert!(
        map.entities.iter().any(|e| e.entity.degenerated_axes() > 0),
        "want tubes too"
    );
    let cloud = mema::io::read::read_cloud(&shared("bun_zipper.ply")).unwrap();
    let world: Vec<[f64; 3]> = cloud
        .points
        .iter()
        .map(|p| [0, 1, 2].map(|j| cloud.origin[j] + f64::from(p[j])))
        .collect();
    let centres: Vec<[f64; 3]> = map
        .entities
        .iter()
        .map(|e| map.world_center(&e.entity))
        .collect();
    let mut boxes = vec![([f64::MAX; 3], [f64::MIN; 3]); centres.len()];
    for p in &world {
        let d = |c: &[f64; 3]| (0..3).map(|j| (p[j] - c[j]).powi(2)).sum::<f64>();
        let nearest = (0..centres.len()).min_by(|&a, &b| d(&centres[a]).total_cmp(&d(&centres[b])));
        let b = &mut boxes[nearest.unwrap()];
        for (j, &c) in p.iter().enumerate() {
            b.0[j] = b.0[j].min(c);
            b.1[j] = b.1[j].max(c);
        }
    }
    let view = TopView {
        entities: map
            .entities
            .iter()
            .zip(&centres)
            .zip(&boxes)
            .map(|((e, c), b)| (*c, e.entity.weights.map(f64::from), e.kind, *b))
            .collect(),
    };
    let frame = &panel["frame"];
    assert_eq!(
        (f3(&frame["right"]), f3(&frame["up"])),
        ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    );
    let (origin, scale) = (f3(&frame["origin"]), frame["scale"].as_f64().unwrap());
    let offset = [
        frame["offset"][0].as_f64().unwrap(),
        frame["offset"][1].as_f64().unwrap(),
    ];
    let to_world = |x: f64, y: f64| {
        (
            origin[0] + (x - offset[0]) / scale,
            origin[1] + (offset[1] - y) / scale,
        )
    };
    let plot: Vec<i64> = panel["plot"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_i64().unwrap())
        .collect();
    // The cloud lies inside the plot, which is fitted to it and to the entities (see
    // toolbox_bounds); entities may widen it at most twice, so the cloud fills half of it at
    // least (this map's threshold box lets the paper's fits grow metres long).
    let span = |j: usize| {
        world.iter().map(|p| p[j]).fold(f64::MIN, f64::max)
            - world.iter().map(|p| p[j]).fold(f64::MAX, f64::min)
    };
    let filled = (span(0) * scale / plot[2] as f64).max(span(1) * scale / plot[3] as f64);
    assert!((0.5 - 1e-9..=1.0 + 1e-9).contains(&filled), "{filled}");
    // Highest point per pixel its dot covers.
    let size = report["point_size"].as_i64().unwrap();
    let mut dots = std::collections::HashMap::<(i64, i64), f64>::new();
    for p in &world {
        let x = (offset[0] + scale * (p[0] - origin[0])).floor() as i64;
        let y = (offset[1] - scale * (p[1] - origin[1])).floor() as i64;
        for (dx, dy) in (0..size).flat_map(|dx| (0..size).map(move |dy| (dx, dy))) {
            let z = dots.entry((x + dx, y + dy)).or_insert(f64::MIN);
            *z = z.max(p[2]);
        }
    }
    let point_colour = colour(&report["point_colour"]);
    let (mut entity_px, mut point_px, mut empty_px) = (0, 0, 0);
    for y in plot[1]..plot[1] + plot[3] {
        for x in plot[0]..plot[0] + plot[2] {
            let (wx, wy) = to_world(x as f64 + 0.5, y as f64 + 0.5);
            let tops = view.top(wx, wy);
            // Skip pixels near an edge: the coverage must agree a third of a pixel away.
            let near_edge = [(-0.35, 0.0), (0.35, 0.0), (0.0, -0.35), (0.0, 0.35)]
                .iter()
                .any(|(dx, dy)| {
                    let (ax, ay) = to_world(x as f64 + 0.5 + dx, y as f64 + 0.5 + dy);
                    let t = view.top(ax, ay);
                    t.first().map(|v| v.1) != tops.first().map(|v| v.1)
                        || t.is_empty() != tops.is_empty()
                });
            let tie = tops.len() > 1 && tops[0].0 - tops[1].0 < 1e-6;
            if near_edge || tie {
                continue;
            }
            let got = pixel(x, y);
            let dot = dots.get(&(x, y)).copied();
            match (tops.first(), dot) {
                (_, Some(z)) if tops.first().is_none_or(|t| z > t.0 + 1e-6) => {
                    assert_eq!(
                        got, point_colour,
                        "pixel ({x}, {y}): a point above any entity"
                    );
                    point_px += 1;
                }
                (Some((z, kind)), d) if d.is_none_or(|dz| dz < z - 1e-6) => {
                    let want = mema::render::export::kind_colour(*kind);
                    assert!(
                        is_shade_of(got, want),
                        "pixel ({x}, {y}) is {got:?}, want a shade of {kind:?}"
                    );
                    entity_px += 1;
                }
                (None, None) => {
                    assert_eq!(got, [255, 255, 255], "pixel ({x}, {y}) should be empty");
                    empty_px += 1;
                }
                _ => {}
            }
        }
    }
    eprintln!("top view: {entity_px} entity, {point_px} point, {empty_px} empty pixels checked");
    assert!(
        entity_px > 20_000 && point_px > 500 && empty_px > 5_000,
        "{entity_px} {point_px} {empty_px}"
    );
    says(
        "docs/testing.md",
        &format!(
            "every unambiguous pixel of the plot ({} of its {};",
            thousands((entity_px + point_px + empty_px) as u64),
            thousands((plot[2] * plot[3]) as u64)
        ),
    );
}

#[test]
fn draw_compare_views_styles_and_bad_arguments() {
    let dir = Dir::new("draw-compare");
    map_cloud(&dir, "car6.pcd", "80", "e.mema", &[]);
    map_cloud(&dir, "car6.pcd", "80", "s.mema", &["--entity", "sphere"]);
    let run = |extra: &[&str], out: &str| {
        MemaCommand::new(&dir)
            .arg("draw")
            .arg(shared("car6.pcd"))
            .arg("e.mema")
            .args(extra)
            .args(["--json", "-o", out])
            .run()
            .assert_ok()
            .json()
    };
    let both = run(&["--compare", "s.mema", "--size", "1000x500"], "both.png");
    let panels = both["panels"].as_array().unwrap();
    assert_eq!(panels.len(), 2);
    assert_eq!(panels[1]["legend"][0]["kind"], "sphere");
    assert_eq!(panels[1]["legend"].as_array().unwrap().len(), 1);
    assert_eq!(panels[0]["frame"]["scale"], panels[1]["frame"]["scale"]);
    assert_eq!(panels[0]["rect"][2], 500);
    // Fig. 12's point: the ellipsoids fit better than the spheres on the same clusters.
    assert!(panels[0]["mean_error"].as_f64() < panels[1]["mean_error"].as_f64());
    let count_kind = |file: &str| {
        let (_, _, rgb) = decode_png(&dir.join(file));
        rgb.chunks_exact(3)
            .filter(|p| is_shade_of([p[0], p[1], p[2]], [0, 114, 178]))
            .count()
    };
    run(&["--view", "front"], "shaded.png");
    run(&["--view", "front", "--style", "outline"], "outline.png");
    let (shaded, outline) = (count_kind("shaded.png"), count_kind("outline.png"));
    assert!(
        outline > 500 && outline * 2 < shaded,
        "{outline} vs {shaded}"
    );
    for view in ["iso", "side"] {
        let r = run(&["--view", view], &format!("{view}.png"));
        assert_eq!(r["view"], view);
    }
    let bad = |args: &[&str], code: i32, needle: &str| {
        MemaCommand::new(&dir)
            .arg("draw")
            .arg(shared("car6.pcd"))
            .args(args)
            .run()
            .assert_error(code, needle);
    };
    bad(&["e.mema", "-o", "x.jpg"], 2, "x.jpg");
    // clap rejects a malformed or tiny --size itself (its usage text follows, exit 2).
    let tiny = MemaCommand::new(&dir)
        .arg("draw")
        .arg(shared("car6.pcd"))
        .args(["e.mema", "-o", "x.png", "--size", "100x100"])
        .run();
    assert_eq!(tiny.output.status.code(), Some(2));
    assert!(
        tiny.stderr().contains("outside 160x120"),
        "{}",
        tiny.stderr()
    );
    bad(&["missing.mema", "-o", "x.png"], 1, "missing.mema");
    bad(&["e.mema", "-o", "no/dir/x.png"], 1, "does not exist");
    assert!(!dir.join("x.png").exists());
}

/// Vertex and face counts by the documented tessellation, from the map's own kinds.
fn expected_counts(map: &HostMap, segments: usize, rings: usize) -> (usize, usize) {
    map.entities.iter().fold((0, 0), |(v, f), e| {
        let (dv, df) = match e.entity.degenerated_axes() {
            0 => ((rings - 1) * segments + 2, 2 * segments * (rings - 1)),
            1 => (2 * segments + 2, 4 * segments),
            _ => (8, 4),
        };
        (v + dv, f + df)
    })
}

#[test]
fn export_ply_glb_obj_reread_by_independent_parsers() {
    let dir = Dir::new("export");
    // The threshold search box lets axes degenerate, so every kind of solid is exercised.
    map_cloud(
        &dir,
        "bun_zipper.ply",
        "100",
        "b.mema",
        &["--bounds", "threshold"],
    );
    let map = HostMap::read(&dir.join("b.mema")).unwrap();
    assert!(
        map.entities.iter().any(|e| e.entity.degenerated_axes() > 0),
        "want degenerated entities"
    );
    let export = |out: &str, extra: &[&str]| {
        MemaCommand::new(&dir)
            .args(["export", "b.mema", "-o", out, "--json"])
            .args(extra)
            .run()
            .assert_ok()
            .json()
    };
    let (v, f) = expected_counts(&map, 24, 12);
    // PLY through ply-rs-bw, in world coordinates: every ellipsoid vertex is on its surface.
    let r = export(
        "m.ply",
        &["--cloud", shared("bun_zipper.ply").to_str().unwrap()],
    );
    assert_eq!(
        (r["vertices"].as_u64(), r["triangles"].as_u64()),
        (Some(v as u64), Some(f as u64))
    );
    assert_eq!(r["bounds_source"], "cloud");
    let parser = ply_rs_bw::parser::Parser::<ply_rs_bw::ply::DefaultElement>::new();
    let mut file = std::io::BufReader::new(std::fs::File::open(dir.join("m.ply")).unwrap());
    let ply = parser
        .read_ply(&mut file)
        .expect("ply-rs-bw reads the export");
    let (verts, faces) = (&ply.payload["vertex"], &ply.payload["face"]);
    assert_eq!((verts.len(), faces.len()), (v, f));
    let coord = |e: &ply_rs_bw::ply::DefaultElement, k: &str| match e[k] {
        ply_rs_bw::ply::Property::Double(d) => d,
        _ => panic!("{k} is not a double"),
    };
    let mut at = 0;
    for kind in EntityKind::ALL {
        for e in map.entities.iter().filter(|e| e.kind == kind) {
            let (n, _) = expected_counts(&HostMap::new(map.origin, vec![*e]), 24, 12);
            if e.entity.degenerated_axes() == 0 {
                let c = map.world_center(&e.entity);
                for vert in &verts[at..at + n] {
                    let q: f64 = ["x", "y", "z"]
                        .iter()
                        .enumerate()
                        .map(|(j, k)| {
                            f64::from(e.entity.weights[j]) * (coord(vert, k) - c[j]).powi(2)
                        })
                        .sum();
                    assert!(
                        (q - 1.0).abs() < 1e-4,
                        "{kind:?} vertex off its surface: {q}"
                    );
                }
            }
            at += n;
        }
    }
    // glTF through the gltf crate: a primitive per kind with the counts of its entities.
    let r = export("m.glb", &["--segments", "10", "--rings", "6"]);
    assert_eq!(r["bounds_source"], "map");
    let glb = std::fs::read(dir.join("m.glb")).unwrap();
    let gltf = gltf::Gltf::from_slice(&glb).expect("gltf reads the export");
    let blob = gltf.blob.clone().expect("binary chunk");
    let node = gltf.nodes().next().unwrap();
    let t = node.transform().decomposed().0;
    assert!((0..3).all(|j| (f64::from(t[j]) - map.origin[j]).abs() <= 1e-6 * map.origin[j].abs().max(1.0)));
    let mesh = gltf.meshes().next().unwrap();
    let kinds: Vec<EntityKind> = EntityKind::ALL
        .into_iter()
        .filter(|k| map.entities.iter().any(|e| e.kind == *k))
        .collect();
    assert_eq!(mesh.primitives().count(), kinds.len());
    for (p, kind) in mesh.primitives().zip(&kinds) {
        let of_kind = HostMap::new(
            map.origin,
            map.entities
                .iter()
                .filter(|e| e.kind == *kind)
                .copied()
                .collect(),
        );
        let (v, f) = expected_counts(&of_kind, 10, 6);
        let reader = p.reader(|_| Some(&blob));
        assert_eq!(reader.read_positions().unwrap().count(), v, "{kind:?}");
        let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        assert_eq!(indices.len(), 3 * f, "{kind:?}");
        assert!(indices.iter().all(|&i| (i as usize) < v));
        let colour = p.material().pbr_metallic_roughness().base_color_factor();
        let want = mema::render::export::kind_colour(*kind).map(|c| f32::from(c) / 255.0);
        assert!((0..3).all(|j| (colour[j] - want[j]).abs() < 1e-6));
    }
    // OBJ: counted line by line.
    export("m.obj", &[]);
    let obj = std::fs::read_to_string(dir.join("m.obj")).unwrap();
    assert_eq!(obj.lines().filter(|l| l.starts_with("v ")).count(), v);
    assert_eq!(obj.lines().filter(|l| l.starts_with("f ")).count(), f);
    MemaCommand::new(&dir)
        .args(["export", "b.mema", "-o", "m.stl"])
        .run()
        .assert_error(2, "m.stl");
    MemaCommand::new(&dir)
        .args(["export", "b.mema", "-o", "m.ply", "--segments", "2"])
        .run()
        .assert_error(2, "--segments 2");
}

#[test]
fn completions_man_page_and_quiet_progress() {
    let dir = Dir::new("completions");
    let bash = MemaCommand::new(&dir)
        .args(["completions", "bash"])
        .run()
        .assert_ok()
        .stdout();
    for word in [
        "draw",
        "export",
        "--crop",
        "--voxel",
        "--compare",
        "completions",
    ] {
        assert!(bash.contains(word), "bash completions lack {word}");
    }
    let zsh = MemaCommand::new(&dir)
        .args(["completions", "zsh"])
        .run()
        .assert_ok()
        .stdout();
    assert!(zsh.starts_with("#compdef mema"));
    let man = MemaCommand::new(&dir).arg("man").run().assert_ok().stdout();
    assert!(man.contains(".TH mema") && man.contains("draw") && man.contains("export"));
    // stderr is a pipe here: no progress bar, no control sequences, only the final note.
    let ran = MemaCommand::new(&dir)
        .arg("map")
        .arg(shared("bun_zipper.ply"))
        .args(["-k", "150", "-o", "b.mema"])
        .run()
        .assert_ok();
    let err = ran.stderr();
    assert!(!err.contains('\r') && !err.contains('\u{1b}'), "{err:?}");
    assert_eq!(err.lines().count(), 1, "{err:?}");
}
