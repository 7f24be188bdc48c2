//! Per-lens reports: a directory with every plot and an index.html and README.md holding the
//! analysis tables, so a reader sees the lens without building anything.

mod figures;
mod page;
mod wave_figures;

pub use figures::{Figure, FigureError, FigureOptions, PlotKind, figure};
pub use page::{Page, PlotEntry, Table, analysis_tables};

use crate::plot::{PlotError, write_atomic, write_plot};
use crate::system::LensSystem;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
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

/// Writes the report of `system` into `directory` (created if missing).
pub fn write_report(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
    directory: &Path,
) -> Result<Written, ReportError> {
    std::fs::create_dir_all(directory).map_err(|source| ReportError::Io {
        path: directory.to_path_buf(),
        source,
    })?;
    let mut page = Page::for_lens(lens, system);
    let wavelength_nm = options
        .wavelengths_nm
        .first()
        .copied()
        .unwrap_or_else(|| system.design_wavelength_nm());
    match crate::analysis::analyze(
        lens,
        system,
        &figures::analyze_options(options, wavelength_nm),
    ) {
        Ok(analysis) => page.tables.extend(analysis_tables(&analysis)),
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
                let path = directory.join(&file);
                write_plot(&view, &path).map_err(|source| ReportError::Plot {
                    lens: lens.to_string(),
                    kind,
                    source,
                })?;
                page.plots.push(PlotEntry {
                    file,
                    caption: kind.describe().to_string(),
                });
                written.files.push(path);
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
        let path = directory.join(file);
        write_atomic(&path, text.as_bytes()).map_err(|error| match error {
            PlotError::Io { source, .. } => ReportError::Io {
                path: path.clone(),
                source,
            },
            other => ReportError::Plot {
                lens: lens.to_string(),
                kind: PlotKind::Layout,
                source: other,
            },
        })?;
        written.files.push(path);
    }
    Ok(written)
}
