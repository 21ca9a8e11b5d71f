//! Pictures of a street (issue 33): `mema draw` of the three Ouster sweeps. A few returns
//! hundreds of metres out no longer shrink the street to a blob: the default frame holds where
//! the points are dense, and `--around X,Y,Z --radius R` draws the points within R of a world
//! point, framed to them. `--view horizon` looks along a z-up lidar's forward axis. The points
//! kept are counted here from the cloud as the reader gives it; the coverage is read from the
//! PNG's pixels.

use serde_json::Value;

use crate::util::{Dir, MemaCommand, shared};

fn decode_png(path: &std::path::Path) -> (u32, Vec<u8>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).expect("png written"));
    let mut reader = png::Decoder::new(file).read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("frame");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, buf)
}

/// The share of the first panel's plot that is not the white background.
fn covered(path: &std::path::Path, report: &Value) -> f64 {
    let (width, rgb) = decode_png(path);
    let plot: Vec<u32> = report["panels"][0]["plot"]
        .as_array()
        .expect("plot")
        .iter()
        .map(|v| v.as_u64().expect("pixel") as u32)
        .collect();
    let [x0, y0, w, h] = [plot[0], plot[1], plot[2], plot[3]];
    let mut ink = 0usize;
    for y in y0..y0 + h {
        for x in x0..x0 + w {
            let i = 3 * (y * width + x) as usize;
            if rgb[i..i + 3] != [255, 255, 255] {
                ink += 1;
            }
        }
    }
    ink as f64 / f64::from(w * h)
}

fn draw(dir: &Dir, extra: &[&str], out: &str) -> Value {
    let conf = shared("ouster_os1.conf");
    MemaCommand::new(dir)
        .arg("draw")
        .arg(&conf)
        .args(["os.mema", "--view", "top", "--json", "-o", out])
        .args(extra)
        .run()
        .assert_ok()
        .json()
}

/// Acceptance 3: the street with `--around 0,0,0 --radius 30` covers far more of its picture
/// than the whole sweep framed at once, and holds exactly the points within 30 m.
#[test]
fn around_and_the_dense_frame_show_the_street() {
    let dir = Dir::new("street");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(shared("ouster_os1.conf"))
        .args(["-k", "400", "--surface-rounds", "0", "-o", "os.mema"])
        .run()
        .assert_ok();
    let whole = draw(&dir, &[], "whole.png");
    let street = draw(&dir, &["--around", "0,0,0", "--radius", "30"], "street.png");

    // The points within 30 m of the first sweep's sensor, counted here from the read cloud.
    let cloud = mema::io::load_cloud(&shared("ouster_os1.conf")).expect("the sweeps");
    let world = cloud.world_points();
    let near = world
        .iter()
        .filter(|p| p.iter().map(|c| c * c).sum::<f64>() <= 900.0)
        .count();
    assert_eq!(street["points"], near, "{street}");
    assert_eq!(whole["points"], world.len());

    // The whole sweep reaches hundreds of metres; its picture holds where the points are
    // dense, leaving out under 1 % of them, and says how many.
    let far = world
        .iter()
        .map(|p| p[0].abs().max(p[1].abs()))
        .fold(0.0, f64::max);
    assert!(far > 150.0, "{far}");
    let outside = whole["points_outside"].as_u64().expect("outside") as usize;
    assert!(outside > 0 && outside * 100 < world.len(), "{outside}");
    assert_eq!(street["points_outside"], 0);

    let (a, b) = (
        covered(&dir.join("whole.png"), &whole),
        covered(&dir.join("street.png"), &street),
    );
    eprintln!(
        "ouster_os1.conf, top view: {:.1} % of the plot covered framed whole ({outside} of {} \
         points outside), {:.1} % around (0, 0, 0) within 30 m ({near} points)",
        100.0 * a,
        world.len(),
        100.0 * b
    );
    assert!(b > 0.25 && b > 2.5 * a, "whole {a}, street {b}");
}

/// `--view horizon` looks along +x with z up (a z-up lidar's forward); `--view sensor --up z`
/// is refused with a pointer to it.
#[test]
fn the_horizon_view_looks_along_a_lidars_forward_axis() {
    let dir = Dir::new("horizon");
    MemaCommand::new(&dir)
        .arg("map")
        .arg(shared("ouster_os1_0.pcd"))
        .args(["-k", "100", "--surface-rounds", "0", "-o", "os.mema"])
        .run()
        .assert_ok();
    let cloud = shared("ouster_os1_0.pcd");
    let json = MemaCommand::new(&dir)
        .arg("draw")
        .arg(&cloud)
        .args(["os.mema", "--view", "horizon", "--json", "-o", "h.png"])
        .args(["--around", "0,0,0", "--radius", "20"])
        .run()
        .assert_ok()
        .json();
    let frame = &json["panels"][0]["frame"];
    let v = |key: &str| -> Vec<f64> {
        frame[key]
            .as_array()
            .expect(key)
            .iter()
            .map(|x| x.as_f64().expect("number"))
            .collect()
    };
    assert_eq!(
        (v("right"), v("up")),
        (vec![0.0, -1.0, 0.0], vec![0.0, 0.0, 1.0])
    );
    let refused = MemaCommand::new(&dir)
        .arg("draw")
        .arg(&cloud)
        .args(["os.mema", "--view", "sensor", "--up", "z", "-o", "s.png"])
        .run();
    assert_eq!(refused.output.status.code(), Some(2));
    assert!(
        refused.stderr().contains("--view horizon"),
        "{}",
        refused.stderr()
    );
}
