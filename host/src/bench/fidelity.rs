//! `mema bench --only fidelity`: every shared cloud and registered set (`.conf`) at each byte
//! budget, four maps side by side, each scored two ways (`crate::analysis::fidelity`) as read
//! back from the file it was written to:
//!
//! - **default**: the shell model filling the budget (`mema map --model shells --bytes B`);
//! - **paper**: the paper's method at the same budget (`mema map --bytes B --paper`);
//! - **GMM**: a converged full-covariance Gaussian mixture of `B / 40` components
//!   (scikit-learn, `scripts/gmm_fit.py`), each component its 2-sigma shell ([`super::gmm`]);
//! - **streamed**: the map a robot gets of the same cloud, sent as `mema scanner-sim` sends it
//!   (a set scan by scan with its poses, as `scanner-sim --conf` does) and mapped by the
//!   streaming mapper (`mema map --stream -k K`, shells, K = B / 14), at most [`MAX_CLUSTERS`]
//!   entities.
//!
//! A cloud the readers refuse, or a map a budget cannot make (more entities than points), is
//! reported and the run goes on.

use anyhow::{Context, Result, bail};
use serde::Serialize;
use std::cell::OnceCell;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::gmm::{self, GmmSummary};
use super::write_npy;
use crate::analysis::eval::{FileBytes, points_in_map_frame};
use crate::analysis::fidelity::{FidelityScore, two_way_score};
use crate::batch::map_cloud_with;
use crate::io::bag::BagOptions;
use crate::io::cloud::{LocalCloud, load_cloud_in_metres, load_input_keeping};
use crate::io::mapfile::HostMap;
use crate::io::read::Screening;
use crate::link::scanner::{SensorScan, scans_of_input};
use crate::link::stream::{Capacity, MAX_CLUSTERS, link_params, stream_scans};
use crate::mapping::options::{
    EntityChoice, MIN_POINTS_PER_ENTITY, Model, PipelineConfig, ShellModel,
};

/// The budgets: 60, 240 and 960 components of 40 bytes.
pub const DEFAULT_BUDGETS: [usize; 3] = [2_400, 9_600, 38_400];

/// Extensions of the inputs the benchmark takes from the data directory: clouds, and registered
/// sets of scans (`.conf`), whose streamed map is the one a robot builds scan by scan from
/// their poses (issue 31 asks for every shared cloud and set).
pub const CLOUD_EXTENSIONS: [&str; 5] = ["ply", "pcd", "las", "laz", "conf"];

/// What one run does; everything the command line chose, and nothing of its types.
pub struct FidelityOptions {
    pub data: PathBuf,
    /// A Python with numpy and scikit-learn (scripts/bench.sh installs one).
    pub python: PathBuf,
    /// File names to keep (all clouds of `data` when empty).
    pub clouds: Vec<String>,
    pub budgets: Vec<usize>,
    /// `mema map`'s configuration with its defaults; `k` follows from each budget.
    pub base: PipelineConfig,
    /// Surface samples and their seed, as `mema eval` defaults them.
    pub samples: usize,
    pub seed: u64,
    /// Where GMM fits are kept and reused (see [`gmm::fit_gmm`]); `None` fits every one.
    pub gmm_cache: Option<PathBuf>,
}

/// The four maps of one row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    Default,
    Paper,
    Gmm,
    Streamed,
}

impl Method {
    /// The methods in the order of a row's cells.
    pub const ALL: [Method; 4] = [
        Method::Default,
        Method::Paper,
        Method::Gmm,
        Method::Streamed,
    ];

    /// The method's name in the tables.
    pub fn name(self) -> &'static str {
        match self {
            Method::Default => "default",
            Method::Paper => "paper",
            Method::Gmm => "GMM",
            Method::Streamed => "streamed",
        }
    }

    /// Entities (components) that `budget` bytes hold.
    pub fn entities(self, budget: usize) -> usize {
        budget
            / match self {
                Method::Default | Method::Streamed => Model::Shells.bytes_per_entity(),
                Method::Paper => Model::Paper.bytes_per_entity(),
                Method::Gmm => gmm::BYTES_PER_COMPONENT,
            }
    }
}

/// One map, scored: or why there is none.
#[derive(Clone, Debug, Serialize)]
pub struct Scored {
    pub method: Method,
    /// Entities the budget holds: k of the map (fewer on a cloud of under 4 points an entity,
    /// as `mema map --bytes` caps it), or the mixture's components.
    pub asked: usize,
    pub file_bytes: u64,
    pub header_bytes: u64,
    pub entities: usize,
    pub score: FidelityScore,
    /// Seconds: making the map (k-means and fit, or the whole Python process), writing and
    /// reading it back, and scoring it.
    pub build_s: f64,
    pub io_s: f64,
    pub score_s: f64,
    pub gmm: Option<GmmSummary>,
}

/// A map a budget could not make, and why.
#[derive(Clone, Debug, Serialize)]
pub struct Failed {
    pub method: Method,
    pub asked: usize,
    pub error: String,
}

/// One method's map of a row: scored, or failed.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum Cell {
    Scored(Box<Scored>),
    Failed(Failed),
}

impl Cell {
    /// The scored map, if there is one.
    pub fn scored(&self) -> Option<&Scored> {
        match self {
            Cell::Scored(s) => Some(s),
            Cell::Failed(_) => None,
        }
    }
}

/// One cloud at one budget: the default, paper and GMM cells in that order.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub cloud: String,
    /// Finite points: what every map is scored against.
    pub points: usize,
    /// Of them, the points `mema map` maps (isolated ones left out, [`Screening::MAPPING`]):
    /// what the default, paper and GMM maps are made from.
    pub mapped_points: usize,
    pub budget: usize,
    pub cells: Vec<Cell>,
}

impl Row {
    /// The scored map of `method`, if there is one.
    pub fn cell(&self, method: Method) -> Option<&Scored> {
        self.cells
            .iter()
            .filter_map(Cell::scored)
            .find(|s| s.method == method)
    }
}

/// A cloud the readers refused.
#[derive(Clone, Debug, Serialize)]
pub struct Refused {
    pub cloud: String,
    pub error: String,
}

/// Wall seconds spent in each stage over the whole run.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Stages {
    pub read_s: f64,
    pub npy_s: f64,
    pub default_map_s: f64,
    pub paper_map_s: f64,
    /// Sending each cloud as scanner-sim does and mapping it as `mema stream` does.
    pub streamed_map_s: f64,
    /// The Python processes, start to finish (EM itself is each summary's `fit_s`).
    pub gmm_fit_s: f64,
    /// Shells of the components.
    pub gmm_map_s: f64,
    pub write_read_s: f64,
    pub score_s: f64,
    pub total_s: f64,
}

/// A whole run: its settings, every row, the clouds refused, summaries and stage times.
#[derive(Clone, Debug, Serialize)]
pub struct FidelityReport {
    pub data: String,
    pub budgets: Vec<usize>,
    pub samples: usize,
    pub seed: u64,
    pub threads: usize,
    pub rows: Vec<Row>,
    pub refused: Vec<Refused>,
    pub summaries: Vec<Summary>,
    pub stages: Stages,
}

/// The clouds of `data` the benchmark reads, by file name; `only` keeps those it names.
pub fn cloud_files(data: &Path, only: &[String]) -> Result<Vec<String>> {
    let mut names: Vec<String> = std::fs::read_dir(data)
        .with_context(|| format!("{}: cannot list the shared clouds", data.display()))?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| {
            Path::new(n)
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| CLOUD_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
        })
        .collect();
    names.sort();
    if !only.is_empty() {
        if let Some(missing) = only.iter().find(|n| !names.contains(n)) {
            bail!(
                "--clouds: {missing} is not a cloud of {} (there: {})",
                data.display(),
                names.join(", ")
            );
        }
        names.retain(|n| only.contains(n));
    }
    Ok(names)
}

/// An input in metres (autzen_trim.laz is in feet) twice: every finite point, as `mema eval`
/// scores against them, and the points `mema map` maps, its isolated ones left out. A map made
/// of every point answers for a few stray returns a user's map never has: the Ouster sweeps'
/// hundred isolated points made their 2,400-byte default maps four times worse, and their
/// mixtures twice.
pub fn scored_and_mapped(path: &Path) -> Result<(LocalCloud, LocalCloud)> {
    let (scored, _) = load_cloud_in_metres(path, None)?;
    let (mapped, _) = load_input_keeping(path, None, &BagOptions::default(), Screening::MAPPING)?;
    Ok((scored, mapped))
}

/// Removes the run's scratch directory however the run ends.
struct Scratch(PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        std::fs::remove_dir_all(&self.0).ok();
    }
}

/// Maps and scores every cloud of `opts.data` at every budget, three ways.
pub fn run(opts: &FidelityOptions) -> Result<FidelityReport> {
    if opts.budgets.is_empty() {
        bail!("no budget to run");
    }
    let start = Instant::now();
    let names = cloud_files(&opts.data, &opts.clouds)?;
    let scratch =
        Scratch(std::env::temp_dir().join(format!("mema-fidelity-{}", std::process::id())));
    std::fs::create_dir_all(&scratch.0)
        .with_context(|| format!("creating {}", scratch.0.display()))?;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/gmm_fit.py");
    let mut stages = Stages::default();
    let mut refused = Vec::new();
    // Every cloud is read first (about 1.3 M points in all, 16 MB), so the run can go budget
    // by budget: the small budgets' tables are complete long before the largest one's fits.
    let mut clouds = Vec::new();
    for name in &names {
        let t = Instant::now();
        let read = scored_and_mapped(&opts.data.join(name));
        stages.read_s += t.elapsed().as_secs_f64();
        let error = match read {
            Ok((c, mapped)) if !c.points.is_empty() && !mapped.points.is_empty() => {
                let t = Instant::now();
                let npy = scratch.0.join(format!("cloud-{}.npy", clouds.len()));
                write_npy(&npy, &mapped.points)?;
                stages.npy_s += t.elapsed().as_secs_f64();
                clouds.push((name, c, mapped, npy));
                continue;
            }
            Ok(_) => "no finite points".to_string(),
            Err(e) => format!("{e:#}"),
        };
        eprintln!("fidelity: {name}: refused: {error}");
        refused.push(Refused {
            cloud: name.clone(),
            error,
        });
    }
    let mut rows = Vec::new();
    // Each cloud's scans as scanner-sim sends them, read once for all its budgets.
    let scans: Vec<OnceCell<Vec<SensorScan>>> = clouds.iter().map(|_| OnceCell::new()).collect();
    for &budget in &opts.budgets {
        for ((name, cloud, mapped, npy), scans) in clouds.iter().zip(&scans) {
            let case = Case {
                opts,
                path: &opts.data.join(name),
                scans,
                cloud,
                mapped,
                dir: &scratch.0,
                npy,
                script: &script,
            };
            let cells = Method::ALL
                .map(|m| {
                    let cell = case.cell(m, budget, &mut stages);
                    eprintln!(
                        "fidelity: {name} ({} points) B={budget} {}",
                        cloud.points.len(),
                        describe(&cell)
                    );
                    cell
                })
                .to_vec();
            rows.push(Row {
                cloud: name.to_string(),
                points: cloud.points.len(),
                mapped_points: mapped.points.len(),
                budget,
                cells,
            });
        }
    }
    stages.total_s = start.elapsed().as_secs_f64();
    Ok(FidelityReport {
        data: opts.data.display().to_string(),
        budgets: opts.budgets.clone(),
        samples: opts.samples,
        seed: opts.seed,
        threads: rayon::current_num_threads(),
        summaries: summaries(&rows, &opts.budgets),
        rows,
        refused,
        stages,
    })
}

/// One line of progress for stderr: the run can take an hour.
fn describe(cell: &Cell) -> String {
    match cell {
        Cell::Scored(s) => {
            let gmm = s.gmm.as_ref().map_or(String::new(), |g| {
                format!(
                    ", EM {} in {} iterations ({:.1} s{})",
                    if g.converged {
                        "converged"
                    } else {
                        "NOT converged"
                    },
                    g.iterations,
                    g.fit_s,
                    if g.cached { ", cached" } else { "" }
                )
            });
            format!(
                "{}: {} entities, {} bytes, Chamfer {:.6}{gmm}; build {:.1} s, score {:.1} s",
                s.method.name(),
                s.entities,
                s.file_bytes,
                s.score.chamfer,
                s.build_s,
                s.score_s
            )
        }
        Cell::Failed(f) => format!("{}: no map: {}", f.method.name(), f.error),
    }
}

/// One cloud's inputs, shared by its cells.
struct Case<'a> {
    opts: &'a FidelityOptions,
    /// The cloud's file, which the streamed map is sent from as a sensor would send it.
    path: &'a Path,
    /// The file's scans, once the streamed map has read them.
    scans: &'a OnceCell<Vec<SensorScan>>,
    /// Every finite point, which each map is scored against.
    cloud: &'a LocalCloud,
    /// The points `mema map` maps: the default's, the paper's and the GMM's.
    mapped: &'a LocalCloud,
    dir: &'a Path,
    npy: &'a Path,
    script: &'a Path,
}

impl Case<'_> {
    fn cell(&self, method: Method, budget: usize, stages: &mut Stages) -> Cell {
        let asked = method.entities(budget);
        match self.scored(method, asked, stages) {
            Ok(s) => Cell::Scored(Box::new(s)),
            Err(e) => Cell::Failed(Failed {
                method,
                asked,
                error: format!("{e:#}"),
            }),
        }
    }

    fn scored(&self, method: Method, asked: usize, stages: &mut Stages) -> Result<Scored> {
        let points = self.mapped.points.len();
        if asked == 0 {
            bail!("the budget holds no entity");
        }
        if method == Method::Gmm && asked > points {
            bail!("{asked} components for {points} points");
        }
        let path = self.dir.join(format!("{}.mema", method.name()));
        let t = Instant::now();
        let mut summary = None;
        match method {
            Method::Default | Method::Paper => {
                let model = if method == Method::Default {
                    Model::Shells
                } else {
                    Model::Paper
                };
                // As `mema map --bytes` does: a budget is an upper bound, and a small cloud
                // gets at most one cluster per MIN_POINTS_PER_ENTITY points.
                let most = (points / MIN_POINTS_PER_ENTITY).max(1);
                let config = PipelineConfig {
                    k: asked.min(most),
                    ..self.opts.base
                };
                map_cloud_with(
                    self.mapped,
                    &config,
                    model,
                    ShellModel::default(),
                    EntityChoice::Ellipsoid,
                    &path,
                    None,
                )?;
                let s = t.elapsed().as_secs_f64();
                if method == Method::Default {
                    stages.default_map_s += s;
                } else {
                    stages.paper_map_s += s;
                }
            }
            Method::Gmm => {
                let (fit, cached) = gmm::fit_gmm(
                    &self.opts.python,
                    self.script,
                    self.npy,
                    asked,
                    self.opts.gmm_cache.as_deref(),
                )?;
                stages.gmm_fit_s += t.elapsed().as_secs_f64();
                let m = Instant::now();
                let (map, dropped) = gmm::gmm_map(self.mapped.origin, &fit)?;
                stages.gmm_map_s += m.elapsed().as_secs_f64();
                summary = Some(GmmSummary {
                    sklearn: fit.sklearn.clone(),
                    cached,
                    scale: fit.scale,
                    components: fit.means.len(),
                    converged: fit.converged,
                    iterations: fit.iterations,
                    max_iter: fit.max_iter,
                    fit_s: fit.fit_s,
                    peak_rss_bytes: fit.peak_rss_bytes,
                    dropped,
                });
                let w = Instant::now();
                map.write(&path)?;
                stages.write_read_s += w.elapsed().as_secs_f64();
            }
            Method::Streamed => {
                // As `mema map --stream --bytes` would: one cluster per MIN_POINTS_PER_ENTITY
                // points at most, and the host's stream holds MAX_CLUSTERS.
                let most = (points / MIN_POINTS_PER_ENTITY).clamp(1, MAX_CLUSTERS);
                let capacity = Capacity::checked(asked.min(most), None, false)?;
                let config = PipelineConfig {
                    k: capacity.k,
                    ..self.opts.base
                };
                if self.scans.get().is_none() {
                    let read = scans_of_input(self.path, None, &BagOptions::default())?;
                    let _ = self.scans.set(read);
                }
                let scans = self.scans.get().map_or(&[][..], |s| &s[..]);
                let params = link_params(&config, capacity, None, Model::Shells);
                let (_, _, map) = stream_scans(scans, params, false)?;
                stages.streamed_map_s += t.elapsed().as_secs_f64();
                let w = Instant::now();
                map.write(&path)?;
                stages.write_read_s += w.elapsed().as_secs_f64();
            }
        }
        let build_s = t.elapsed().as_secs_f64();
        let io = Instant::now();
        let map = HostMap::read(&path)?;
        let bytes = FileBytes::of(&path, &map)?;
        let io_s = io.elapsed().as_secs_f64();
        stages.write_read_s += io_s;
        let s = Instant::now();
        let score = score_map(self.cloud, &map, self.opts.seed, self.opts.samples)?;
        let score_s = s.elapsed().as_secs_f64();
        stages.score_s += score_s;
        std::fs::remove_file(&path).ok();
        Ok(Scored {
            method,
            asked,
            file_bytes: bytes.file_bytes,
            header_bytes: bytes.header_bytes,
            entities: map.entities.len(),
            score,
            build_s,
            io_s,
            score_s,
            gmm: summary,
        })
    }
}

/// `mema eval`'s two-way score of a map against the cloud it was made from.
pub fn score_map(
    cloud: &LocalCloud,
    map: &HostMap,
    seed: u64,
    samples: usize,
) -> Result<FidelityScore> {
    let entities: Vec<_> = map.entities.iter().map(|e| e.entity).collect();
    two_way_score(&points_in_map_frame(cloud, map), &entities, seed, samples)
}

/// One budget over all clouds: how the default map compares with the GMM and the paper.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub budget: usize,
    /// Clouds with both a default and a GMM map, and those where the default's Chamfer is
    /// lower (strictly) than the GMM's.
    pub versus_gmm: usize,
    pub default_beats_gmm: usize,
    /// Geometric means of the Chamfer ratios over those clouds (below 1: the default is closer).
    pub chamfer_ratio_gmm: Option<f64>,
    pub versus_paper: usize,
    pub default_beats_paper: usize,
    pub chamfer_ratio_paper: Option<f64>,
    /// Clouds with both a streamed and a default map, and the streamed map's Chamfer over the
    /// default's: geometric mean and largest (above 1: the robot's map is the farther).
    pub versus_streamed: usize,
    pub streamed_ratio: Option<f64>,
    pub streamed_ratio_max: Option<f64>,
}

pub fn summaries(rows: &[Row], budgets: &[usize]) -> Vec<Summary> {
    budgets
        .iter()
        .map(|&budget| {
            let of = |other: Method| {
                let ratios: Vec<f64> = rows
                    .iter()
                    .filter(|r| r.budget == budget)
                    .filter_map(|r| Some((r.cell(Method::Default)?, r.cell(other)?)))
                    .map(|(d, o)| d.score.chamfer / o.score.chamfer)
                    .collect();
                let beats = ratios.iter().filter(|&&q| q < 1.0).count();
                (ratios.len(), beats, geometric_mean(&ratios))
            };
            let (versus_gmm, default_beats_gmm, chamfer_ratio_gmm) = of(Method::Gmm);
            let (versus_paper, default_beats_paper, chamfer_ratio_paper) = of(Method::Paper);
            let streamed: Vec<f64> = rows
                .iter()
                .filter(|r| r.budget == budget)
                .filter_map(|r| Some((r.cell(Method::Streamed)?, r.cell(Method::Default)?)))
                .map(|(s, d)| s.score.chamfer / d.score.chamfer)
                .collect();
            Summary {
                budget,
                versus_gmm,
                default_beats_gmm,
                chamfer_ratio_gmm,
                versus_paper,
                default_beats_paper,
                chamfer_ratio_paper,
                versus_streamed: streamed.len(),
                streamed_ratio: geometric_mean(&streamed),
                streamed_ratio_max: streamed.iter().copied().reduce(f64::max),
            }
        })
        .collect()
}

/// `None` for no ratios, or for any that is not a positive finite number (a zero Chamfer).
fn geometric_mean(ratios: &[f64]) -> Option<f64> {
    if ratios.is_empty() || !ratios.iter().all(|q| q.is_finite() && *q > 0.0) {
        return None;
    }
    Some((ratios.iter().map(|q| q.ln()).sum::<f64>() / ratios.len() as f64).exp())
}

#[cfg(test)]
mod tests;
