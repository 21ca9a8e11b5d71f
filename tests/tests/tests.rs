//! One integration binary, as ripgrep does; each module is one concern.

// Helpers: temp dirs, the mema binary, the shared data.
mod util;
// Helpers: the guides' text, their result blocks, and a sentence a guide must say.
mod guides;

// Bad input: every kind of broken file or argument gives a one-line error and an exit code.
mod bad_input;
// Eq. 13's closest point against a brute-force search on the surface.
mod closest_point;
// The CLI end to end on real clouds: determinism, formats, eval, info, demo.
mod cli;
// eval's two-way fidelity score against brute force, a drawn cloud and a moved entity.
mod fidelity;
// Fault injection on the wire: corrupted frames refused, clean frames used once.
mod faults;
// LAS/LAZ against their raw integer records, KITTI scans, --crop and --voxel.
mod lidar;
// The no_std, no-panic contract of core, checked on its source.
mod core_contract;
// The host's layers, checked on its source: no clap or CLI in the library, no import circles.
mod layering;
// The core as firmware runs it: chunking, faults, resets, replay, the f64 reference, fuzzing.
mod firmware;
// The receive ring against the link's clock: pacing keeps a 168 MHz part up with the link.
mod pacing;
// The fidelity benchmark's GMM baseline: a component becomes its 2-sigma oriented shell.
mod gmm_shell;
// The fuzz targets' properties on mutated maps of every layout and mutated captures.
mod fuzzing;
// A memory limit: one line and exit 1, never an abort or a backtrace.
mod memory_limit;
// Eq. 12 from moments against the direct per-point f64 sum on real clusters.
mod fitness;
// Accelerated k-means against the plain reference on real clouds, on 1 and 2 threads.
mod kmeans;
// The paper's tables on the shared clouds: ellipsoids beat spheres.
mod paper_tables;
// Map queries (distance, occupancy, rays) through the index vs brute force; rigid transforms.
mod queries;
// Automatic k: the tolerance mode meets T with fewer ellipsoids.
mod tolerance;
// The board under QEMU behind a faulty relay: what was lost is sent or asked again.
mod board_link;
// Sessions against one running board under QEMU, and a reset mid-session.
mod board_sessions;
// The board carving a walker out of its map, its retractions through a faulty relay.
mod board_carving;
// A sensor wired to the board's USART1 under QEMU, its map to a listener on USART2.
mod board_sensor;
// mema device's session against the firmware in a thread, through faulty lines both ways.
mod session;
// The serial link over a real pty pair: stream = replay = direct mapper, unplug, Ctrl-C.
mod stream;
// The link's faults (issue 12): frames after the end, a sender that starts again, units out of
// range, points 2,000 km out, SIGTERM and SIGHUP, the idle timeout, a failed snapshot.
mod link_faults;
// Protocol version 2: poses and sessions through the real binary; version 1 maps as it did.
mod poses;
// Multi-view data: the bunny scans of bun.conf registered, streamed with their poses, mapped.
mod multiview;
// The moving robot through the demo scene, streamed with its poses.
mod drive;
// The map back over the link: downlink frames rebuild replay's map; faults never a wrong one.
mod device;
// Outliers in files: a far point dropped before centring, or the precision check refusing.
mod outliers;
// The documentation's commands, run as documented (README.md, PROTOCOL.md, docs/).
mod docs;
// PROTOCOL.md's worked examples: every frame type, the script's bytes, read and emitted by mema.
mod protocol_doc;
// PROTOCOL.md's field tables: offsets and sizes that add up to the frames the examples are.
mod protocol_tables;
// PROTOCOL.md's words for its examples, made from the examples' own bytes.
mod protocol_prose;
// The figures the guides quote: copies of docs/results.md, the figures quoted in prose, and its
// car6 rows computed again.
mod results;
// The figures the guides quote in prose, each held to its cell of docs/results.md.
mod quoted;
// The constants the guides state (frame sizes, layouts, pacing), each held to the code's.
mod doc_constants;
// The layouts, budgets, clocks and defaults the device and design guides state, held to the
// code's, and every K they name one of the code's layouts.
mod doc_device;
// Links that resolve: every relative link and anchor of the documentation, every section a
// --help text cites.
mod links;
// The independent sender written from PROTOCOL.md alone.
mod sender;
// ROS 2 bags written by rosbags: the bunny scans in frame world map as bun.conf does, bit for
// bit; awkward layouts decode as numpy does; missing topics, transforms and damage are errors.
mod bags;
// Surface following: closer maps on real scans, labels that match the shells, thread-free.
mod surface_clusters;
// Shells in the streaming mapper: each entity against its cluster's direct f64 covariance,
// replay's bytes whatever the chunking, shells against the paper's fits.
mod stream_shells;
// draw (pixels against projections computed here), export (re-read by gltf and ply-rs-bw),
// completions and man.
mod toolbox;
// draw and export of oriented maps: a turned map meshes and draws as the turned original.
mod toolbox_oriented;
// draw and export within bounds: export's size counted first and limited, draw's --up,
// sensor view, frame, scale-bar unit and work.
mod toolbox_bounds;
// .mema versions: a version-1 file written here by hand still loads; --paper writes version 1,
// shells version 2 quantized, both within --bytes, decoded here from the documented layout.
mod map_versions;
// Units: LAS CRS units (autzen in feet), --units, geographic clouds refused, the warning.
mod units;
// Exact rotation: a cloud and its map turned by the same random rotation score the same.
mod rotation_invariance;
// A first run that explains itself: the demo's files and next commands, man pages, one-line
// usage errors, scanner-sim to a file, clouds on standard input.
mod first_run;
// What map and eval say beside their tables: NaN points dropped, a map and a cloud apart,
// fits the search box chose.
mod honest_reports;
// Counts that add up: read and every drop make the slots of every shared input, counted here.
mod counts;
// Data a user can get: scripts/fetch-data.sh's list and checksums are the shared files'.
mod data_sources;
// One figure per name: map, eval, draw, info and Python agree on eq. 13 and bytes.
mod one_figure;
// Pictures of a street: the dense frame, --around and --radius, the horizon view.
mod lidar_pictures;
// Issue 23: the world frame, reach, far frames and poses.
mod world_frame;
// What the receiver refuses: far frames and poses, a first-point glitch, a stream refused whole.
mod refused;
// Issue 23: LAS/LAZ classes, noise and withheld points.
mod las_classes;
// Issue 29: sensor origins, no-returns, held-out rays (`mema eval --rays`).
mod rays;
// Issue 29: free, occupied, unknown: the map's free space and `mema query --points`.
mod free_space;
// Forgetting what moved: the demo drive's walker leaves no trail.
mod walker;
// Issue 32: layout figures of the guides (export sizes, a cloud's bytes) computed from layouts.
mod doc_figures;
