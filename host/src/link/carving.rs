//! A host's stream with `--free-space` (issue 29): the core's carver judges the clusters each
//! scan saw through ([`mema_core::stream::carve`]), and each scan's image, brought down to the
//! map file's 8 x 64 pixels, is the streamed map's free-space part, as the batch map keeps it.

use mema_core::Point3;
use mema_core::free_space::{Geometry, NO_RETURN, range_of};
use mema_core::stream::{Carver, StreamMapper};

use crate::io::free_space::{COLUMNS, FreeImage, ROWS, image_from, kept_scans};

/// Rows and columns of the images a host's stream carves with: the whole sphere at 0.35 degrees,
/// an OS-1-128's spacing (measured on the shared sweeps' ghost, `tests/free_space.rs`: 0.7
/// degrees left 5.3 % of the ghost on surface, 0.35 degrees 4.4 %).
pub const CARVE_IMAGE: [u16; 2] = [512, 1024];

/// The carver of a host's stream (512 KiB): images of [`CARVE_IMAGE`] pixels or fewer.
pub type HostCarver = Carver<{ CARVE_IMAGE[0] as usize * CARVE_IMAGE[1] as usize }>;

/// The carver and the images of the scans it ended, in the frame of the receiver's origin.
pub struct Carving {
    carver: Box<HostCarver>,
    images: Vec<FreeImage>,
    /// Whether the map keeps free space: each ended scan's image is kept (a device's map
    /// keeps none).
    keep_images: bool,
}

impl Carving {
    /// A carving with whole-sphere images of `[rows, columns]` pixels (at most
    /// [`CARVE_IMAGE`]'s count; `None` otherwise) taking every `every`-th return of a scan
    /// ([`Carver::sample`]), keeping each scan's image for the map's free space if
    /// `keep_images`.
    pub fn new([rows, columns]: [u16; 2], every: u16, keep_images: bool) -> Option<Self> {
        let mut carver = Box::new(HostCarver::whole_sphere(rows, columns)?);
        carver.sample(every);
        Some(Self {
            carver,
            images: Vec::new(),
            keep_images,
        })
    }

    /// The points that follow were seen from `sensor`: a new scan if it is not the current
    /// one's, which then ends.
    pub fn sensor_at<const K: usize, const G: usize, const F: usize>(
        &mut self,
        sensor: Point3,
        mapper: &mut StreamMapper<K, G, F>,
    ) {
        if self.carver.begins_scan(sensor) {
            self.end_scan(mapper);
            self.carver.begin_scan(sensor, mapper);
        }
    }

    pub fn add_return(&mut self, p: Point3) {
        self.carver.add_return(p);
    }

    /// Ends the current scan, if one is under way: it carves `mapper`, and its image is kept.
    pub fn end_scan<const K: usize, const G: usize, const F: usize>(
        &mut self,
        mapper: &mut StreamMapper<K, G, F>,
    ) {
        let scanning = self.carver.scanning();
        self.carver.end_scan(mapper, &mut ());
        if scanning && self.keep_images {
            let image = self.carver.image();
            self.images
                .extend(map_image(image.geometry(), image.cells()));
        }
    }

    /// The map started again: what was scanned is forgotten.
    pub fn restart(&mut self) {
        self.carver.restart();
        self.images.clear();
    }

    /// The images a map keeps ([`crate::io::free_space::MAX_IMAGES`] at most, spread evenly
    /// over the scans), their origins moved from the receiver's origin `from` to the map
    /// file's `to` (both in the world frame).
    pub fn images_at(&self, from: [f64; 3], to: [f64; 3]) -> Vec<FreeImage> {
        kept_scans(self.images.len())
            .into_iter()
            .filter_map(|i| self.images.get(i))
            .map(|image| {
                let o = image.geometry.origin;
                let moved = [o.x, o.y, o.z]
                    .iter()
                    .zip(from.iter().zip(&to))
                    .map(|(v, (f, t))| (f64::from(*v) + f - t) as f32)
                    .collect::<Vec<_>>();
                FreeImage {
                    geometry: Geometry {
                        origin: Point3::new(moved[0], moved[1], moved[2]),
                        ..image.geometry
                    },
                    cells: image.cells.clone(),
                }
            })
            .collect()
    }
}

/// A carving image as the map keeps a scan's: each pixel's nearest return, at its pixel's
/// centre and its range rounded down, into an image of the map's size that spans them, coded
/// from the same nearest range (a return nearer than it, code 0, leaves nothing free in
/// either).
fn map_image(geometry: &Geometry, cells: &[u8]) -> Option<FreeImage> {
    let (rows, columns) = (usize::from(geometry.rows), usize::from(geometry.columns));
    let [low, high] = geometry.elevation;
    let [start, width] = geometry.azimuth;
    let returns = cells.iter().enumerate().filter(|(_, c)| **c != NO_RETURN);
    let points = returns.map(|(i, &c)| {
        let (row, column) = (i / columns.max(1), i % columns.max(1));
        let elevation = low + (row as f32 + 0.5) / rows as f32 * (high - low);
        let azimuth = start + (column as f32 + 0.5) / columns as f32 * width;
        // Code 0 stands for a return nearer than `near`: kept nearer than it.
        let r = if c == 0 {
            geometry.near / 2.0
        } else {
            range_of(c, geometry.near)
        };
        let o = geometry.origin;
        Point3::new(
            o.x + r * elevation.cos() * azimuth.cos(),
            o.y + r * elevation.cos() * azimuth.sin(),
            o.z + r * elevation.sin(),
        )
    });
    image_from(
        geometry.origin,
        points,
        [ROWS, COLUMNS],
        Some(geometry.near),
    )
}
