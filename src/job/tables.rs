//! Where a render finds its LRTF table: a directory per lens under a tables root, searched by
//! sidecar for a table that covers the render, or baked there when none does.

use super::JobError;
use crate::lenses::LoadedLens;
use crate::lrtf::bake::{BakeProgress, BakeRequest, bake_with_progress};
use crate::lrtf::io::{SIDECAR_FILE, prescription_hash, read_sidecar, read_table, write_table};
use crate::lrtf::{LrtfTable, Precision};
use crate::model::WAVELENGTH_MATCH_NM;
use crate::render::chromatic::CHANNELS;
use std::path::{Path, PathBuf};

/// The tables root the command line uses, relative to the working directory.
pub const DEFAULT_TABLES_ROOT: &str = "tables";

/// Where the table of `lens_name` focused at `focus_mm` (None: infinity) lives under `root`:
/// `<root>/<lens>/` or `<root>/<lens>/focus-<D>mm/`.
pub fn default_table_dir(root: &Path, lens_name: &str, focus_mm: Option<f64>) -> PathBuf {
    let base = root.join(lens_name);
    match focus_mm {
        None => base,
        Some(d) => base.join(format!("focus-{d:.0}mm")),
    }
}

/// Where a chromatic render keeps its table, beside the monochrome one in `base`.
pub fn chromatic_table_dir(base: &Path, wavelengths_nm: [f64; CHANNELS]) -> PathBuf {
    let [r, g, b] = wavelengths_nm;
    base.join(format!("rgb-{r:.1}-{g:.1}-{b:.1}nm"))
}

/// What a render needs of a table.
#[derive(Clone, Debug, PartialEq)]
pub struct TableNeeds {
    /// The film plane the render focuses on.
    pub film_z: f64,
    /// The table may be baked at this f-number or faster.
    pub f_number: f64,
    /// Largest film radius the render's rays start from.
    pub film_radius: f64,
    /// A layer for each (within [`WAVELENGTH_MATCH_NM`]).
    pub wavelengths_nm: Vec<f64>,
}

/// The first table under `<root>/<lens>/` (the directory itself, then its subdirectories by
/// name) baked from this prescription that meets `needs`: its focus range holds the film plane
/// (a focus-range table serves every focus inside its range without a rebake), it is no slower,
/// it covers the film radius and it has every wavelength. Only sidecars are read.
pub fn find_covering_table(lens: &LoadedLens, root: &Path, needs: &TableNeeds) -> Option<PathBuf> {
    let base = default_table_dir(root, &lens.source.origin.name(), None);
    let mut subdirs: Vec<PathBuf> = std::fs::read_dir(&base)
        .into_iter()
        .flatten()
        .flatten()
        .map(|entry| entry.path())
        .filter(|path| path.is_dir())
        .collect();
    subdirs.sort();
    let hash = prescription_hash(&lens.source.loaded.prescription);
    std::iter::once(base).chain(subdirs).find(|dir| {
        read_sidecar(dir).is_ok_and(|sidecar| {
            let sampling = sidecar.layers.first().map(|l| &l.sampling_pupil);
            sidecar.prescription_hash == hash
                && sidecar.info.f_number <= needs.f_number * (1.0 + 1e-12)
                && sidecar.info.focus.check_film_z(needs.film_z, "").is_ok()
                && sampling.is_some_and(|s| s.max_film_radius() >= needs.film_radius * (1.0 - 1e-9))
                && needs.wavelengths_nm.iter().all(|nm| {
                    sidecar
                        .layers
                        .iter()
                        .any(|l| (l.wavelength_nm - nm).abs() <= WAVELENGTH_MATCH_NM)
                })
        })
    })
}

/// What [`load_or_bake`] bakes when the directory holds no table.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeFallback {
    /// Object distance in focus (mm; None: infinity).
    pub focus_mm: Option<f64>,
    pub max_film_radius: f64,
    /// Nodes per axis.
    pub resolution: usize,
    /// Layers to bake (empty: the design wavelength).
    pub wavelengths_nm: Vec<f64>,
}

/// Loads the table in `dir`, or bakes one there as `fallback` says when the directory holds
/// none; true when it baked. A loaded table must serve `fallback.focus_mm`. `progress` sees the
/// bake's node counts.
pub fn load_or_bake(
    lens: &LoadedLens,
    dir: &Path,
    fallback: &BakeFallback,
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<(LrtfTable, bool), JobError> {
    let prescription = &lens.source.loaded.prescription;
    if dir.join(SIDECAR_FILE).exists() {
        let table = read_table(dir, Some(prescription))?;
        // The render derives its focus from the film position: the range check allows rounding.
        table
            .info
            .focus
            .film_z_for(fallback.focus_mm)
            .map_err(|cause| JobError::TableFocus {
                dir: dir.to_path_buf(),
                cause,
            })?;
        return Ok((table, false));
    }
    let request = BakeRequest {
        resolution: [fallback.resolution; 3],
        // 16-bit codes: the f32 table's error (docs/lrtf.md, accuracy per byte) at half its
        // bytes, so more of the table a frame reads stays in cache.
        precision: Precision::U16,
        focus_mm: fallback.focus_mm,
        max_film_radius: Some(fallback.max_film_radius),
        wavelengths_nm: fallback.wavelengths_nm.clone(),
        ..BakeRequest::default()
    };
    let table = bake_with_progress(&lens.system, &request, progress)?;
    write_table(&table, &lens.source.origin.name(), prescription, dir)?;
    Ok((table, true))
}
