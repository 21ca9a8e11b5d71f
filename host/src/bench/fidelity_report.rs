//! The fidelity benchmark's tables: markdown, one per budget, with its summary.

use std::io::Write;

use super::fidelity::{Cell, FidelityReport, Method};

/// Three significant digits, without an exponent for the lengths the clouds have.
pub fn sig(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".into();
    }
    let magnitude = x.abs().log10().floor() as i32;
    if !(-6..=6).contains(&magnitude) {
        return format!("{x:.2e}");
    }
    let decimals = (2 - magnitude).max(0) as usize;
    format!("{x:.decimals$}")
}

fn ratio(q: Option<f64>) -> String {
    q.map_or("-".into(), |q| format!("{q:.2}"))
}

/// The report as markdown: a table per budget, its summary, notes, and the stage times.
pub fn print_tables(report: &FidelityReport, out: &mut dyn Write) -> std::io::Result<()> {
    let columns = [
        "bytes",
        "entities",
        "Chamfer",
        "acc mean",
        "compl mean",
        "phantom",
        "F",
    ];
    for (budget, summary) in report.budgets.iter().zip(&report.summaries) {
        writeln!(out)?;
        writeln!(out, "#### B = {budget} bytes")?;
        writeln!(out)?;
        let mut header = vec!["cloud".to_string(), "points".to_string()];
        for m in Method::ALL {
            header.extend(columns.iter().map(|c| format!("{} {c}", m.name())));
        }
        writeln!(out, "| {} |", header.join(" | "))?;
        let align: Vec<&str> = std::iter::once(":--")
            .chain(std::iter::repeat_n("--:", header.len() - 1))
            .collect();
        writeln!(out, "|{}|", align.join("|"))?;
        let mut notes = Vec::new();
        for row in report.rows.iter().filter(|r| r.budget == *budget) {
            let mut cells = vec![row.cloud.clone(), row.points.to_string()];
            for cell in &row.cells {
                match cell {
                    Cell::Scored(s) => {
                        let f = &s.score;
                        cells.extend([
                            s.file_bytes.to_string(),
                            s.entities.to_string(),
                            sig(f.chamfer),
                            sig(f.accuracy.mean),
                            sig(f.completeness.mean),
                            format!("{:.0}%", 100.0 * f.phantom),
                            format!("{:.3}", f.f_score),
                        ]);
                        if let Some(g) = s.gmm.as_ref().filter(|g| !g.converged || g.dropped > 0) {
                            notes.push(format!(
                                "{}: GMM {} after {} of {} EM iterations, {} components without a shell",
                                row.cloud,
                                if g.converged { "converged" } else { "did not converge" },
                                g.iterations,
                                g.max_iter,
                                g.dropped
                            ));
                        }
                    }
                    Cell::Failed(f) => {
                        cells.extend(std::iter::repeat_n("-".to_string(), columns.len()));
                        notes.push(format!(
                            "{}: no {} map of {} entities: {}",
                            row.cloud,
                            f.method.name(),
                            f.asked,
                            f.error
                        ));
                    }
                }
            }
            writeln!(out, "| {} |", cells.join(" | "))?;
        }
        writeln!(out)?;
        writeln!(
            out,
            "B = {budget}: the default's Chamfer is below the GMM's on {} of {} clouds (geometric mean of default/GMM {}) and below the paper's on {} of {} (default/paper {}).",
            summary.default_beats_gmm,
            summary.versus_gmm,
            ratio(summary.chamfer_ratio_gmm),
            summary.default_beats_paper,
            summary.versus_paper,
            ratio(summary.chamfer_ratio_paper)
        )?;
        writeln!(
            out,
            "B = {budget}: the streamed map's Chamfer is {} times the default's (geometric mean over {} clouds; at most {}).",
            ratio(summary.streamed_ratio),
            summary.versus_streamed,
            ratio(summary.streamed_ratio_max)
        )?;
        for n in notes {
            writeln!(out, "- {n}")?;
        }
    }
    if !report.refused.is_empty() {
        writeln!(out)?;
        for r in &report.refused {
            writeln!(out, "- {}: refused by the reader: {}", r.cloud, r.error)?;
        }
    }
    let gmm: Vec<_> = report
        .rows
        .iter()
        .flat_map(|r| r.cells.iter().filter_map(Cell::scored))
        .filter_map(|s| s.gmm.as_ref())
        .collect();
    let converged = gmm.iter().filter(|g| g.converged).count();
    let cached = gmm.iter().filter(|g| g.cached).count();
    let sklearn = gmm.iter().find_map(|g| g.sklearn.as_deref()).unwrap_or("?");
    let s = &report.stages;
    writeln!(out)?;
    writeln!(
        out,
        "GMMs (scikit-learn {sklearn}): {converged} of {} converged (EM's own tolerance, at most {} iterations){}; {} surface samples a map, seed {}, {} threads.",
        gmm.len(),
        gmm.iter().map(|g| g.max_iter).max().unwrap_or(0),
        if cached > 0 {
            format!(", {cached} read from the fit cache")
        } else {
            String::new()
        },
        report.samples,
        report.seed,
        report.threads
    )?;
    writeln!(
        out,
        "Wall time: {:.0} s in all; read {:.1} s, .npy {:.1} s, default maps {:.1} s, paper maps {:.1} s, streamed maps {:.1} s, GMM fits (Python) {:.1} s, GMM shells {:.2} s, write and read back {:.1} s, scoring {:.1} s.",
        s.total_s,
        s.read_s,
        s.npy_s,
        s.default_map_s,
        s.paper_map_s,
        s.streamed_map_s,
        s.gmm_fit_s,
        s.gmm_map_s,
        s.write_read_s,
        s.score_s
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.000_335_2), "0.000335");
        assert_eq!(sig(1.526), "1.53");
        assert_eq!(sig(12.34), "12.3");
        assert_eq!(sig(1234.4), "1234");
        assert_eq!(sig(0.0), "0");
    }
}
