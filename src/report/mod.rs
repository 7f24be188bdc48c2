//! Per-lens reports: a directory with every plot and an index.html and README.md holding the
//! analysis tables, so a reader sees the lens without building anything.

mod figures;
mod page;
mod wave_figures;

pub use figures::{Figure, FigureError, FigureOptions, PlotKind, figure, placed_spot_plot};
pub use page::{Page, PlotEntry, Table, analysis_tables, conditions_table};

use crate::analysis::AnalysisError;
use crate::output::{OutputError, publish_dir, write_bytes};
use crate::plot::{PlotError, write_plot};
use crate::system::LensSystem;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A condition the lens file states that no analysis can use: every plot would fail.
    #[error(transparent)]
    Conditions(AnalysisError),
    #[error("{kind} plot of {lens}: {source}")]
    Plot {
        lens: String,
        kind: PlotKind,
        #[source]
        source: PlotError,
    },
}

/// What a report wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    pub directory: PathBuf,
    pub files: Vec<PathBuf>,
    /// Plots left out, with the reason (an analysis this build lacks).
    pub skipped: Vec<(PlotKind, String)>,
}

/// Publishes the report of `system` as the directory `directory`: the old report stays whole
/// until the new one is complete ([`publish_dir`]).
pub fn write_report(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
    directory: &Path,
) -> Result<Written, ReportError> {
    publish_dir(directory, |stage| {
        fill_report(lens, system, options, stage, directory)
    })
}

/// Writes the report's files into `stage`, listing them as they will be named in `directory`.
fn fill_report(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
    stage: &Path,
    directory: &Path,
) -> Result<Written, ReportError> {
    let mut page = Page::for_lens(lens, system);
    match crate::analysis::analyze(system, &options.analyze_options()) {
        Ok(analysis) => {
            page.tables
                .insert(0, conditions_table(&analysis.conditions));
            page.tables.extend(analysis_tables(&analysis));
        }
        // Every plot would fail too: the report is refused, and the staged directory with it
        // (`publish_dir`), rather than written as a page of skipped plots.
        Err(error @ AnalysisError::Stated { .. }) => return Err(ReportError::Conditions(error)),
        Err(error) => page
            .notes
            .push(format!("Paraxial analysis failed: {error}.")),
    }
    let mut written = Written {
        directory: directory.to_path_buf(),
        files: Vec::new(),
        skipped: Vec::new(),
    };
    for kind in PlotKind::ALL {
        match figure(kind, lens, system, options) {
            Ok(view) => {
                let file = format!("{}.png", kind.name());
                write_plot(&view, &stage.join(&file)).map_err(|source| ReportError::Plot {
                    lens: lens.to_string(),
                    kind,
                    source,
                })?;
                written.files.push(directory.join(&file));
                page.plots.push(PlotEntry {
                    file,
                    caption: kind.describe().to_string(),
                });
            }
            Err(FigureError::Plot(source)) => {
                return Err(ReportError::Plot {
                    lens: lens.to_string(),
                    kind,
                    source,
                });
            }
            Err(reason) => {
                page.notes
                    .push(format!("{}: not drawn ({reason}).", kind.describe()));
                written.skipped.push((kind, reason.to_string()));
            }
        }
    }
    for (file, text) in [("README.md", page.markdown()), ("index.html", page.html())] {
        write_bytes(&stage.join(file), text.as_bytes())?;
        written.files.push(directory.join(file));
    }
    Ok(written)
}
