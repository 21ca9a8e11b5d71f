//! Issue 32: figures the guides state about layouts, held to what the code or the format makes
//! of them, each computed here from the layout rather than copied, so that a guide's digit and
//! the code cannot drift apart unnoticed.

use mema::analysis::fidelity::MIN_SAMPLES_PER_ENTITY;
use mema::analysis::stats::CLOUD_BYTES_PER_POINT;
use mema::io::read::READ_OVERHEAD;
use mema::mapping::carve::CARVE_MARGIN;
use mema::render::export::{OBJ_VERTEX_MAX, Tessellation};

use mema_core::Point3;
use mema_core::de32::SLOTS as DE_SLOTS;
use mema_core::grid::CentreGrid;
use mema_core::map::record::rotation_code;
use mema_core::moments::fixed::{MANTISSA_LIMIT, SLOTS};
use mema_core::rotation::Rotation;
use mema_core::stream::shells::QUANTIZED_STEP_ALWAYS;

use crate::guides::says;

/// The largest count `accept` takes, searched upwards from `from` (the bound is what the code
/// refuses, not a constant restated here).
fn largest(from: u32, accept: impl Fn(u32) -> bool) -> u32 {
    let mut n = from;
    while accept(n + 1) {
        n += 1;
    }
    n
}

#[test]
fn the_export_bound_is_each_formats_layout() {
    // PLY: x, y, z as `double` and r, g, b as `uchar`; a face is a `uchar` count and three
    // `int` indices.
    let ply_vertex = 3 * size_of::<f64>() + 3 * size_of::<u8>();
    let ply_face = size_of::<u8>() + 3 * size_of::<i32>();
    says(
        "docs/pictures-meshes.md",
        &format!(
            "exactly for PLY (its header, {ply_vertex} bytes a vertex, {ply_face} a triangle)"
        ),
    );
    // GLB: positions as f32 x 3 and indices as u32 x 3; a 12-byte header and two chunks, each
    // behind a length and a type (u32 each).
    let gl_vertex = 3 * size_of::<f32>();
    let gl_triangle = 3 * size_of::<u32>();
    let framing = 12 + 2 * 2 * size_of::<u32>();
    says(
        "docs/pictures-meshes.md",
        &format!(
            "counted at their longest ({gl_vertex} bytes a vertex, {gl_triangle} a triangle, the \
             JSON and {framing} bytes of framing)"
        ),
    );
    // `v`, three coordinates, three colour channels (`0.4471`), six spaces and the newline.
    let coordinate = (OBJ_VERTEX_MAX - 1 - 3 * 6 - 6 - 1) / 3;
    says(
        "docs/pictures-meshes.md",
        &format!("for OBJ at its longest ({OBJ_VERTEX_MAX} bytes a vertex line,"),
    );
    says(
        "docs/pictures-meshes.md",
        &format!("so none takes more than {coordinate} characters)"),
    );
    // A face line as `write_obj` writes it, less its three indices' digits.
    let v = 123_456u32;
    let face = format!("f {v} {v} {v}\n").len() - 3 * v.to_string().len();
    says(
        "docs/pictures-meshes.md",
        &format!("bytes a vertex line, {face} + 3 digits of the vertex count a face line;"),
    );
}

#[test]
fn the_finest_tessellation_is_the_one_the_code_accepts() {
    let segments = largest(3, |s| Tessellation::checked(s, 2).is_ok());
    let rings = largest(2, |r| Tessellation::checked(3, r).is_ok());
    // What export holds there: the triangles of each shape (an ellipsoid, a tube of one
    // infinite axis, the planes of two), three u32 indices each, and one ellipsoid's vertices,
    // three f64 each.
    let t = Tessellation::checked(segments, rings).expect("the finest");
    let triangles: usize = (0..3).map(|d| t.counts(d).1).sum();
    let bytes = triangles * size_of::<[u32; 3]>() + t.counts(0).0 * size_of::<[f64; 3]>();
    says(
        "docs/pictures-meshes.md",
        &format!(
            "what memory there is (at most {:.0} MB, at {segments} segments and {rings} rings) is \
             reserved fallibly",
            bytes as f64 / 1e6
        ),
    );
}

#[test]
fn a_clouds_size_is_three_f32_a_point() {
    assert_eq!(CLOUD_BYTES_PER_POINT, 3 * size_of::<f32>());
    says(
        "docs/performance.md",
        &format!("The cloud's size is {CLOUD_BYTES_PER_POINT} bytes a point, the paper's count."),
    );
}

#[test]
fn the_mappers_bounds_are_the_codes() {
    says(
        "docs/command-line.md",
        &format!("at least {MIN_SAMPLES_PER_ENTITY} per entity, seeded by `--seed`"),
    );
    says(
        "docs/queries.md",
        &format!("lies nearer than its pixel's nearest return by {CARVE_MARGIN} m,"),
    );
    let step_mm = QUANTIZED_STEP_ALWAYS * 1e3;
    says(
        "docs/streaming.md",
        &format!(
            "grid (and a step is over {step_mm} mm and over a quarter of the unit the link sent \
             the points in), the grid would move them"
        ),
    );
    says(
        "docs/streaming.md",
        &format!("instead; `mema info` says so, with the count. Below {step_mm} mm, half a step"),
    );
}

#[test]
fn a_working_cluster_keeps_the_fourth_order_sums() {
    // Per axis its first four powers, per pair of axes the four products eq. 12 needs.
    let axes = 3;
    let pairs = 3;
    assert_eq!(SLOTS, axes * 4 + pairs * 4);
    says(
        "docs/streaming.md",
        &format!("almost all of it its {SLOTS} integer moment sums"),
    );
}

#[test]
fn a_frozen_entitys_rotation_is_its_quantized_code() {
    // The code is a u32 whatever the rotation, and the identity's is 0.
    let identity = rotation_code(&Rotation::IDENTITY);
    let width = size_of_val(&identity);
    says(
        "docs/streaming.md",
        &format!(
            "({width} bytes, within a quarter of a degree, which is what a shells file stores \
             anyway; {identity}, the identity, for the paper's fits)"
        ),
    );
}

#[test]
fn a_sums_mantissa_is_exact_below_its_limit() {
    let bits = MANTISSA_LIMIT.trailing_zeros();
    says(
        "docs/design.md",
        &format!("exact until it outgrows {bits} bits, then rounded once per halving"),
    );
}

#[test]
fn the_nearest_centre_comes_from_the_cells_the_grid_walks() {
    // A centre in every unit cell around the origin; a search that never narrows walks every
    // cell that can hold a centre within half a cell of the point.
    let mut grid = CentreGrid::<64, 4096>::new(1.0);
    let mut index = 0;
    for i in -2..2 {
        for j in -2..2 {
            for k in -2..2 {
                let centre = Point3::new(i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5);
                grid.insert(index, centre);
                index += 1;
            }
        }
    }
    let mut walked = std::collections::BTreeSet::new();
    grid.for_each_within_half_cell(Point3::new(0.3, 0.3, 0.3), f32::INFINITY, |i| {
        walked.insert(i);
        f32::INFINITY
    });
    let cells = walked.len();
    says(
        "docs/streaming.md",
        &format!("The nearest centre comes from {cells} cells of the hash, not a scan of K."),
    );
}

#[test]
fn reading_holds_its_buffer_and_window() {
    let kib = READ_OVERHEAD >> 10;
    says(
        "docs/performance.md",
        &format!("Reading costs the points and {kib} KiB (the stream's buffer and the LZF window)"),
    );
}

#[test]
fn the_f32_des_population_has_its_slots() {
    // A power of two, so that a member index is bounded by a mask.
    assert!(DE_SLOTS.is_power_of_two());
    says(
        "docs/firmware.md",
        &format!("the population in {DE_SLOTS} slots, the start sphere by Newton"),
    );
}
