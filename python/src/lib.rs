//! The `lensbake` Python package's native module: a thin layer over the crate's public API.
//! Arrays cross as NumPy arrays (no Python object per ray), long computations run with the
//! interpreter released, and every library error becomes `lensbake.LensbakeError` carrying the
//! message the command line prints after `error: `.

use std::path::PathBuf;

use lensbake::analysis::DesignConditions;
use lensbake::job::{BackendChoice, FocusMode, ModelChoice};
use lensbake::lrtf::io::{read_table, write_table};
use lensbake::lrtf::table::{LRTF_BLOCKED, LRTF_OUTSIDE, LRTF_PASSES};
use lensbake::lrtf::{Parameterisation, Precision};
use lensbake::paraxial::StopChoice;
use lensbake::prescription::formats::{Format, LoadOptions};
use lensbake::prescription::{Prescription, RayAiming};
use lensbake::trace::{RowResults, StartCheck};
use lensbake::{
    Apertures, BakeRequest, Lookup, LrtfTable, ModelKind, Outcome, Ray, RayBatch, RenderJob,
    RenderLens, SceneRequirements, Tracer, Travel, WaveOptions,
};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayLike2, PyArrayMethods,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rayon::prelude::*;
use serde_json::Value;

pyo3::create_exception!(
    lensbake,
    LensbakeError,
    PyValueError,
    "A lens, a table or an argument lensbake refuses; the message is the command line's."
);

/// The error and its causes, as the command line prints them (`anyhow`'s `{:#}`).
fn refused(error: impl std::error::Error) -> PyErr {
    let mut message = error.to_string();
    let mut cause = error.source();
    while let Some(inner) = cause {
        message.push_str(": ");
        message.push_str(&inner.to_string());
        cause = inner.source();
    }
    LensbakeError::new_err(message)
}

fn argument(message: String) -> PyErr {
    LensbakeError::new_err(message)
}

/// A serialised library value as plain Python objects: the command line's JSON, unprinted.
fn to_python<'py>(py: Python<'py>, value: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64(), n.as_f64()) {
            (Some(i), _, _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u), _) => u.into_pyobject(py)?.into_any(),
            (None, None, f) => f.into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(to_python(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(fields) => {
            let dict = PyDict::new(py);
            for (key, item) in fields {
                dict.set_item(key, to_python(py, item)?)?;
            }
            dict.into_any()
        }
    })
}

fn serialised<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    to_python(py, &serde_json::to_value(value).map_err(refused)?)
}

/// An n x 3 array as n rows, refusing any other shape; a C-ordered float64 array is read in
/// place.
fn rows<'a>(
    name: &str,
    array: &'a PyArrayLike2<'_, f64, AllowTypeChange>,
) -> PyResult<std::borrow::Cow<'a, [[f64; 3]]>> {
    let view = array.as_array();
    if view.ncols() != 3 {
        return Err(argument(format!(
            "{name} must be an n x 3 array, got shape {:?}",
            view.shape()
        )));
    }
    Ok(match view.to_slice() {
        Some(flat) => std::borrow::Cow::Borrowed(flat.as_chunks::<3>().0),
        None => view
            .rows()
            .into_iter()
            .map(|r| [r[0], r[1], r[2]])
            .collect(),
    })
}

/// What `Lens.trace` returns and takes as `out`: end positions, end directions (n x 3 each),
/// outcome codes and outcome surfaces.
type TraceArrays<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<u8>>,
    Bound<'py, PyArray1<u32>>,
);

/// The storage of a writable C-ordered array, refusing any other layout (results are written
/// in place, never into a copy the caller would not see).
fn writable<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    name: &str,
    array: &Bound<'_, numpy::PyArray<T, D>>,
    guard: &'a mut numpy::PyReadwriteArray<'_, T, D>,
) -> PyResult<&'a mut [T]> {
    if !array.is_c_contiguous() {
        return Err(argument(format!(
            "{name} must be a C-ordered (contiguous) array"
        )));
    }
    guard
        .as_slice_mut()
        .map_err(|e| argument(format!("{name}: {e}")))
}

/// [`writable`] of an n x 3 array, as rows.
fn writable_rows<'a>(
    name: &str,
    array: &Bound<'_, PyArray2<f64>>,
    guard: &'a mut numpy::PyReadwriteArray2<'_, f64>,
) -> PyResult<&'a mut [[f64; 3]]> {
    Ok(writable(name, array, guard)?.as_chunks_mut::<3>().0)
}

/// The checked rays of `origins` and `directions` (same length), each also passing `check`;
/// a refused row is named in the error.
fn batch_of(
    origins: &[[f64; 3]],
    directions: &[[f64; 3]],
    check: impl Fn(&Ray) -> Result<(), String> + Sync,
) -> PyResult<RayBatch> {
    if origins.len() != directions.len() {
        return Err(argument(format!(
            "origins has {} rows and directions {}: give one direction per origin",
            origins.len(),
            directions.len()
        )));
    }
    RayBatch::try_from_fn(origins.len(), |row| {
        let ray = Ray::new(origins[row], directions[row]).map_err(|e| e.to_string());
        ray.and_then(|ray| check(&ray).map(|()| ray))
            .map_err(|e| format!("ray {row}: {e}"))
    })
    .map_err(argument)
}

/// Rows of three, in parallel, from `count` rows made by `row`.
fn n_by_3_from(count: usize, row: impl Fn(usize) -> [f64; 3] + Sync) -> Array2<f64> {
    let mut values = vec![0.0; 3 * count];
    values
        .par_chunks_mut(3)
        .enumerate()
        .for_each(|(k, out)| out.copy_from_slice(&row(k)));
    Array2::from_shape_vec((count, 3), values).expect("three values per row")
}

/// A PSF's intensity grid and its (x, y) pixel pitch in mm.
type PsfImage<'py> = (Bound<'py, PyArray2<f64>>, (f64, f64));

/// A lens loaded and validated (`load_lens`).
///
/// The wave methods (`wavefront`, `mtf`, `psf`) take these keyword options: `field_deg` (half
/// field in degrees, in the y-z plane; 0), `wavelengths_nm` (the first is the reference;
/// default the design wavelength) with `weights` (default all 1), `f_number` or `epd_mm`
/// (default: the stop filled), `object_distance_mm` (default infinity), `ray_aiming`
/// ("paraxial" or "real"; default the file's), `samples` (pupil points per side, 64), `grid`
/// (FFT grid per side, 256) and `defocus_mm` (image plane beyond the paraxial image, 0).
#[pyclass(module = "lensbake", frozen)]
pub struct Lens {
    lens: lensbake::LoadedLens,
}

fn ray_aiming(name: Option<&str>) -> PyResult<Option<RayAiming>> {
    name.map(|name| match name {
        "paraxial" => Ok(RayAiming::Paraxial),
        "real" => Ok(RayAiming::Real),
        other => Err(argument(format!(
            "ray_aiming must be \"paraxial\" or \"real\", got {other:?}"
        ))),
    })
    .transpose()
}

/// The wave options (see `Lens`) from the keyword arguments of a wave method; the rest keep
/// the library's defaults.
fn wave_options(keywords: Option<&Bound<'_, PyDict>>) -> PyResult<WaveOptions> {
    let mut options = WaveOptions::default();
    for (key, value) in keywords.into_iter().flat_map(|k| k.iter()) {
        let key: String = key.extract()?;
        match key.as_str() {
            "field_deg" => options.field_deg = value.extract()?,
            "wavelengths_nm" => options.wavelengths_nm = value.extract()?,
            "weights" => options.weights = value.extract()?,
            "f_number" => options.f_number = value.extract()?,
            "epd_mm" => options.epd_mm = value.extract()?,
            "object_distance_mm" => options.object_distance_mm = value.extract()?,
            "ray_aiming" => {
                options.ray_aiming = ray_aiming(value.extract::<Option<String>>()?.as_deref())?
            }
            "samples" => options.sampling.samples = value.extract()?,
            "grid" => options.sampling.grid = value.extract()?,
            "defocus_mm" => options.defocus_mm = value.extract()?,
            other => {
                return Err(PyTypeError::new_err(format!(
                    "unexpected keyword argument {other:?}: the wave options are field_deg, \
                     wavelengths_nm, weights, f_number, epd_mm, object_distance_mm, ray_aiming, \
                     samples, grid and defocus_mm"
                )));
            }
        }
    }
    Ok(options)
}

#[pymethods]
impl Lens {
    /// The lens's name: the bundled name, or the file's path as given.
    #[getter]
    fn name(&self) -> String {
        self.lens.source.origin.name()
    }

    /// The prescription's title.
    #[getter]
    fn title(&self) -> String {
        self.lens.system.prescription.provenance.title.clone()
    }

    /// Design wavelength, nm.
    #[getter]
    fn design_wavelength_nm(&self) -> f64 {
        self.lens.system.design_wavelength_nm()
    }

    /// Surfaces 1..N from the object side, as dicts (lensbake's RON field names; lengths in
    /// mm, curvature in 1/mm, each row's medium the one after the surface).
    #[getter]
    fn surfaces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        serialised(py, &self.lens.system.prescription.surfaces)
    }

    /// The conditions the lens is analysed under by default (wavelengths, field, aperture,
    /// object distance), each with where it came from: the `conditions` of `analyze`.
    #[getter]
    fn conditions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let conditions =
            DesignConditions::resolve(&self.lens.system, &Default::default()).map_err(refused)?;
        serialised(py, &conditions)
    }

    /// Writes the lens to `path` as lensbake RON (.ron), Zemax (.zmx) or pbrt (.dat), as
    /// `lensbake lens convert` does.
    fn convert(&self, path: PathBuf) -> PyResult<()> {
        lensbake::lenses::write_lens(&self.lens.system, &path).map_err(refused)?;
        Ok(())
    }

    /// First-order data, pupils, paraxial rays, Seidel sums and real-ray distortion: the dict
    /// `lensbake analyze --json` prints. Unset arguments take the lens's design conditions.
    /// Lengths in mm, angles in degrees, wavelength in nm; `ray_aiming` is "paraxial" or "real";
    /// `find_stop` takes the surface that limits the axial beam as the stop.
    #[pyo3(signature = (*, wavelength_nm=None, field_deg=None, epd_mm=None, object_distance_mm=None, find_stop=false, ray_aiming=None))]
    #[allow(clippy::too_many_arguments)]
    fn analyze<'py>(
        &self,
        py: Python<'py>,
        wavelength_nm: Option<f64>,
        field_deg: Option<f64>,
        epd_mm: Option<f64>,
        object_distance_mm: Option<f64>,
        find_stop: bool,
        ray_aiming: Option<&str>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let options = lensbake::AnalyzeOptions {
            wavelength_nm,
            field_deg,
            epd_mm,
            object_distance_mm,
            stop: if find_stop {
                StopChoice::LimitingAxialBeam
            } else {
                StopChoice::Marked
            },
            ray_aiming: self::ray_aiming(ray_aiming)?,
        };
        let system = &self.lens.system;
        let mut analysis = py
            .detach(|| lensbake::analyze(system, &options))
            .map_err(refused)?;
        analysis.lens = self.name();
        serialised(py, &analysis)
    }

    /// Traces rays through the lens (exact, f64, on every core, without the interpreter).
    ///
    /// `origins` and `directions` are n x 3 arrays in the lens frame: mm, z along the axis,
    /// origin at surface 1's vertex, light travelling +z. Directions need not be unit length.
    /// Forward rays must start in front of surface 1 (backward rays, `backward=True`, behind
    /// the last surface travelling -z, as a renderer's film rays do). `wavelength_nm` defaults
    /// to the design wavelength; `apertures=False` ignores every clear aperture.
    ///
    /// Returns (positions, directions, outcome, surface): where each ray ends (after the last
    /// surface it crossed) and its unit direction there (n x 3 float64), an outcome code per
    /// ray (uint8: 0 ok, 1 vignetted, 2 total internal reflection, 3 missed a surface) and the
    /// surface (1-based, uint32) the outcome happened at (0 for ok).
    ///
    /// `out`, a tuple of four such arrays (C-ordered, writable), receives the results instead
    /// of new arrays and is returned: a caller tracing batch after batch allocates once.
    #[pyo3(signature = (origins, directions, wavelength_nm=None, *, apertures=true, backward=false, out=None))]
    #[allow(clippy::type_complexity, clippy::too_many_arguments)]
    fn trace<'py>(
        &self,
        py: Python<'py>,
        origins: PyArrayLike2<'py, f64, AllowTypeChange>,
        directions: PyArrayLike2<'py, f64, AllowTypeChange>,
        wavelength_nm: Option<f64>,
        apertures: bool,
        backward: bool,
        out: Option<TraceArrays<'py>>,
    ) -> PyResult<TraceArrays<'py>> {
        let origins = rows("origins", &origins)?;
        let directions = rows("directions", &directions)?;
        let n = origins.len();
        let out = match out {
            Some(out) => out,
            None => (
                PyArray2::zeros(py, [n, 3], false),
                PyArray2::zeros(py, [n, 3], false),
                PyArray1::zeros(py, n, false),
                PyArray1::zeros(py, n, false),
            ),
        };
        let mut end_positions = out.0.try_readwrite()?;
        let mut end_directions = out.1.try_readwrite()?;
        let mut kinds = out.2.try_readwrite()?;
        let mut surfaces = out.3.try_readwrite()?;
        let results = RowResults {
            positions: writable_rows("out[0]", &out.0, &mut end_positions)?,
            directions: writable_rows("out[1]", &out.1, &mut end_directions)?,
            outcome_kinds: writable("out[2]", &out.2, &mut kinds)?,
            outcome_surfaces: writable("out[3]", &out.3, &mut surfaces)?,
        };
        let system = &self.lens.system;
        let travel = if backward {
            Travel::Backward
        } else {
            Travel::Forward
        };
        let apertures = if apertures {
            Apertures::Checked
        } else {
            Apertures::Ignored
        };
        py.detach(|| -> PyResult<()> {
            let nm = wavelength_nm.unwrap_or_else(|| system.design_wavelength_nm());
            let at = system.at_checked(nm).map_err(refused)?;
            let starts = StartCheck::new(&at, travel);
            Tracer::new(&at)
                .trace_rows_into(&origins, &directions, travel, apertures, &starts, results)
                .map_err(|e| argument(e.to_string()))?;
            Ok(())
        })?;
        drop((end_positions, end_directions, kinds, surfaces));
        Ok(out)
    }

    /// Optical path difference over the exit pupil of one field point at one wavelength, as
    /// `lensbake wavefront` measures it: a dict with `opd_waves` (samples x samples float64,
    /// rows along pupil y, piston kept, 0 where `transmitted` is False), `transmitted` (bool),
    /// `rms_waves`, `pv_waves`, `strehl` and the reference sphere. Takes the wave options
    /// (`help(lensbake.Lens)`), with at most one wavelength.
    #[pyo3(signature = (**options))]
    fn wavefront<'py>(
        &self,
        py: Python<'py>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let options = wave_options(options)?;
        let system = &self.lens.system;
        let map = py
            .detach(|| lensbake::wavefront(system, &options))
            .map_err(refused)?;
        let stats = map.stats();
        let side = map.samples;
        let opd: Vec<f64> = map.opd_waves.iter().map(|w| w.unwrap_or(0.0)).collect();
        let transmitted: Vec<bool> = map.opd_waves.iter().map(Option::is_some).collect();
        let dict = PyDict::new(py);
        dict.set_item("wavelength_nm", map.wavelength_nm)?;
        dict.set_item("field_deg", map.field_deg)?;
        dict.set_item("samples", side)?;
        let grid_shape = (side, side);
        let opd = Array2::from_shape_vec(grid_shape, opd).expect("samples² values");
        let transmitted = Array2::from_shape_vec(grid_shape, transmitted).expect("samples² values");
        dict.set_item("opd_waves", opd.into_pyarray(py))?;
        dict.set_item("transmitted", transmitted.into_pyarray(py))?;
        dict.set_item("rms_waves", stats.rms_waves)?;
        dict.set_item("pv_waves", stats.pv_waves)?;
        dict.set_item("strehl", stats.strehl)?;
        dict.set_item("pupil_samples", stats.pupil_samples)?;
        dict.set_item("transmitted_samples", stats.transmitted_samples)?;
        dict.set_item("reference_centre_mm", map.reference_point_mm.to_vec())?;
        dict.set_item("reference_radius_mm", map.reference_radius_mm)?;
        Ok(dict)
    }

    /// Diffraction MTF of one field point, as `lensbake mtf --json`: a dict of float64 arrays
    /// `frequencies_per_mm`, `tangential`, `sagittal`, `diffraction_limit` and the scalar
    /// `cutoff_per_mm`. `frequencies_per_mm` (cycles/mm) defaults to 41 from 0 to the cutoff;
    /// several `wavelengths_nm` give the polychromatic MTF. Takes the wave options
    /// (`help(lensbake.Lens)`).
    #[pyo3(signature = (frequencies_per_mm=None, **options))]
    fn mtf<'py>(
        &self,
        py: Python<'py>,
        frequencies_per_mm: Option<Vec<f64>>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let options = wave_options(options)?;
        let system = &self.lens.system;
        let frequencies = frequencies_per_mm.unwrap_or_default();
        let curve = py
            .detach(|| lensbake::mtf(system, &options, &frequencies))
            .map_err(refused)?;
        let dict = PyDict::new(py);
        dict.set_item("field_deg", curve.field_deg)?;
        dict.set_item("cutoff_per_mm", curve.cutoff_per_mm)?;
        for (key, values) in [
            ("frequencies_per_mm", curve.frequencies_per_mm),
            ("tangential", curve.tangential),
            ("sagittal", curve.sagittal),
            ("diffraction_limit", curve.diffraction_limit),
        ] {
            dict.set_item(key, Array1::from(values).into_pyarray(py))?;
        }
        Ok(dict)
    }

    /// Point spread function of one field point on the FFT grid (`grid` x `grid` float64, 1 =
    /// the aberration-free peak, rows running up from the smallest image y), as `lensbake psf`
    /// writes it; returns (intensity, pixel_mm) with pixel_mm the (x, y) pixel pitch in mm.
    /// Takes the wave options (`help(lensbake.Lens)`).
    #[pyo3(signature = (**options))]
    fn psf<'py>(
        &self,
        py: Python<'py>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<PsfImage<'py>> {
        let options = wave_options(options)?;
        let system = &self.lens.system;
        let image = py
            .detach(|| lensbake::psf(system, &options))
            .map_err(refused)?;
        let intensity = Array2::from_shape_vec((image.size, image.size), image.intensity)
            .expect("size² values");
        Ok((
            intensity.into_pyarray(py),
            (image.pixel_mm[0], image.pixel_mm[1]),
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "<lensbake.Lens {:?}: {} surfaces>",
            self.name(),
            self.lens.system.prescription.surfaces.len()
        )
    }
}

/// Loads a lens by bundled name (`lensbake lens list`) or from a file (RON, pbrt .dat, a
/// plain table, CODE V .seq, Zemax .zmx; the extension says which unless `format` does).
/// The lens is validated; a broken one raises LensbakeError naming file, line and field.
#[pyfunction]
#[pyo3(signature = (path_or_name, format=None))]
fn load_lens(py: Python<'_>, path_or_name: &str, format: Option<&str>) -> PyResult<Lens> {
    let format = format
        .map(|name| {
            Format::ALL
                .into_iter()
                .find(|f| f.name() == name)
                .ok_or_else(|| {
                    let names: Vec<_> = Format::ALL.iter().map(|f| f.name()).collect();
                    argument(format!(
                        "format must be one of {}, got {name:?}",
                        names.join(", ")
                    ))
                })
        })
        .transpose()?;
    let options = LoadOptions {
        format,
        ..LoadOptions::default()
    };
    let lens = py
        .detach(|| lensbake::load_lens(path_or_name, &options))
        .map_err(refused)?;
    Ok(Lens { lens })
}

/// A baked lens ray transfer function table (`bake`, `Table.read`).
#[pyclass(module = "lensbake", frozen)]
pub struct Table {
    table: LrtfTable,
    /// The lens it was baked from, for writing it with its prescription hash.
    source: Option<(String, Prescription)>,
}

#[pymethods]
impl Table {
    /// Nodes per axis.
    #[getter]
    fn resolution(&self) -> (usize, usize, usize) {
        let [n0, n1, n2] = self.table.info.resolution;
        (n0, n1, n2)
    }

    /// One wavelength (nm) per layer.
    #[getter]
    fn wavelengths_nm(&self) -> Vec<f64> {
        self.table.layers.iter().map(|l| l.wavelength_nm).collect()
    }

    /// The f-number it was baked at; it serves this and slower.
    #[getter]
    fn f_number(&self) -> f64 {
        self.table.info.f_number
    }

    /// z of the film plane (lens frame, mm) for an object `focus_mm` in front of surface 1
    /// (None: the table's far focus): where film-side rays of `lookup` start.
    #[pyo3(signature = (focus_mm=None))]
    fn film_z(&self, focus_mm: Option<f64>) -> PyResult<f64> {
        Ok(self
            .table
            .focused(focus_mm, None)
            .map_err(refused)?
            .film_z())
    }

    /// Looks film-side rays up, as the renderer samples the table.
    ///
    /// `origins` and `directions` are n x 3 arrays (lens frame, mm), rays travelling -z from
    /// the film towards the lens. `focus_mm` is the object distance in focus (None: the
    /// table's own), `f_number` the stop (None: as baked; faster than baked is refused),
    /// `layer` the wavelength layer. Returns (positions, directions, status): where each ray
    /// leaves surface 1 and its unit direction into object space (n x 3 float64; zeros where it
    /// does not pass), and a status per ray (uint8: 0 passes, 1 blocked, 2 outside the table).
    #[pyo3(signature = (origins, directions, *, focus_mm=None, f_number=None, layer=0))]
    #[allow(clippy::type_complexity)]
    fn lookup<'py>(
        &self,
        py: Python<'py>,
        origins: PyArrayLike2<'py, f64, AllowTypeChange>,
        directions: PyArrayLike2<'py, f64, AllowTypeChange>,
        focus_mm: Option<f64>,
        f_number: Option<f64>,
        layer: usize,
    ) -> PyResult<(
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray1<u8>>,
    )> {
        let origins = rows("origins", &origins)?;
        let directions = rows("directions", &directions)?;
        let table = &self.table;
        let (positions, headings, status) = py.detach(|| -> PyResult<_> {
            let at = table
                .focused(focus_mm, f_number)
                .and_then(|at| at.layer(layer))
                .map_err(refused)?;
            let rays = batch_of(&origins, &directions, |_| Ok(()))?;
            let looked: Vec<Lookup> = (0..rays.len())
                .into_par_iter()
                .map(|k| at.lookup(&rays.get(k).expect("k < len")))
                .collect();
            let passed = |k: usize| match looked[k] {
                Lookup::Passes(out) => (out.origin, out.direction),
                Lookup::Blocked | Lookup::OutsideDomain => ([0.0; 3], [0.0; 3]),
            };
            let status: Vec<u8> = looked
                .iter()
                .map(|l| match l {
                    Lookup::Passes(_) => LRTF_PASSES,
                    Lookup::Blocked => LRTF_BLOCKED,
                    Lookup::OutsideDomain => LRTF_OUTSIDE,
                } as u8)
                .collect();
            Ok((
                n_by_3_from(rays.len(), |k| passed(k).0),
                n_by_3_from(rays.len(), |k| passed(k).1),
                status,
            ))
        })?;
        Ok((
            positions.into_pyarray(py),
            headings.into_pyarray(py),
            Array1::from(status).into_pyarray(py),
        ))
    }

    /// Writes the table into directory `path` (OpenEXR + RON sidecar, atomically), as
    /// `lensbake lrtf bake` does. A table read without its lens cannot be written again.
    fn write(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let Some((name, prescription)) = &self.source else {
            return Err(argument(
                "this table was read without its lens: read it with `lens=` to write it".into(),
            ));
        };
        py.detach(|| write_table(&self.table, name, prescription, &path))
            .map_err(refused)?;
        Ok(())
    }

    /// Reads the table in directory `path`; with `lens`, refuses a table baked from another
    /// prescription (the sidecar's hash).
    #[staticmethod]
    #[pyo3(signature = (path, lens=None))]
    fn read(py: Python<'_>, path: PathBuf, lens: Option<&Lens>) -> PyResult<Table> {
        let prescription = lens.map(|l| &l.lens.system.prescription);
        let table = py
            .detach(|| read_table(&path, prescription))
            .map_err(refused)?;
        Ok(Table {
            table,
            source: lens.map(|l| (l.name(), l.lens.system.prescription.clone())),
        })
    }

    fn __repr__(&self) -> String {
        let [n0, n1, n2] = self.table.info.resolution;
        format!(
            "<lensbake.Table {n0}x{n1}x{n2}, {} layer(s), f/{:.3}>",
            self.table.layers.len(),
            self.table.info.f_number
        )
    }
}

/// Bakes a table of `lens`: `resolution` nodes per axis, at `f_number` (None: wide open),
/// focused at `focus_mm` in front of surface 1 (None: infinity; with `focus_near_mm` a focus
/// range), at `wavelengths_nm` (one, or three for R, G, B; None: the design wavelength), stored
/// as "f32", "f16" or "u16" (16-bit codes over each channel's range: f32's error at f16's bytes).
#[pyfunction]
#[pyo3(signature = (lens, resolution=32, *, f_number=None, focus_mm=None, focus_near_mm=None, wavelengths_nm=None, precision="f32"))]
#[allow(clippy::too_many_arguments)]
fn bake(
    py: Python<'_>,
    lens: &Lens,
    resolution: usize,
    f_number: Option<f64>,
    focus_mm: Option<f64>,
    focus_near_mm: Option<f64>,
    wavelengths_nm: Option<Vec<f64>>,
    precision: &str,
) -> PyResult<Table> {
    let precision = Precision::from_name(precision).ok_or_else(|| {
        argument(format!(
            "precision must be \"f32\", \"f16\" or \"u16\", got {precision:?}"
        ))
    })?;
    let request = BakeRequest {
        parameterisation: Parameterisation::PupilPlanes,
        resolution: [resolution; 3],
        precision,
        wavelengths_nm: wavelengths_nm.unwrap_or_default(),
        f_number,
        focus_mm,
        focus_near_mm,
        ..BakeRequest::default()
    };
    let system = &lens.lens.system;
    let table = py
        .detach(|| lensbake::bake(system, &request))
        .map_err(refused)?;
    Ok(Table {
        table,
        source: Some((lens.name(), system.prescription.clone())),
    })
}

/// Renders the built-in demo scene through `lens` on the CPU twin of the renderer and returns
/// a height x width x 3 float32 array of linear RGB. `model` is "thin", "thick", "seidel",
/// "baked" or "traced"; `focus_mm` the object distance in focus (default 2000 mm); `f_number`
/// None: wide open. A baked model reads the table in `table_dir`, or bakes one there (default:
/// under ./tables/<lens>/).
#[pyfunction]
#[pyo3(signature = (lens, *, model="traced", width=160, height=120, samples_per_pixel=8, f_number=None, focus_mm=None, table_dir=None, seed=1))]
#[allow(clippy::too_many_arguments)]
fn render<'py>(
    py: Python<'py>,
    lens: &Lens,
    model: &str,
    width: u32,
    height: u32,
    samples_per_pixel: u32,
    f_number: Option<f64>,
    focus_mm: Option<f64>,
    table_dir: Option<PathBuf>,
    seed: u32,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let kind: ModelKind = model.parse().map_err(refused)?;
    let mut job = RenderJob::new(RenderLens::Real(Box::new(lens.lens.clone())));
    job.model = ModelChoice::Model(kind);
    job.backend = BackendChoice::Cpu;
    job.settings.width = width;
    job.settings.height = height;
    job.settings.samples_per_pixel = samples_per_pixel;
    job.settings.seed = seed;
    job.f_number = f_number;
    if let Some(distance) = focus_mm {
        job.focus = FocusMode::Distance(distance);
    }
    job.table = table_dir;
    let rendered = py.detach(|| job.run()).map_err(refused)?;
    let image = rendered.image;
    let values: Vec<f32> = image.pixels.into_iter().flatten().collect();
    let array = Array3::from_shape_vec((image.height as usize, image.width as usize, 3), values)
        .expect("three channels per pixel");
    Ok(array.into_pyarray(py))
}

/// The cheapest lens model whose measured image error stays under `budget_px` (pixels of a
/// `pixels`-wide frame) for a scene focused at `focus_mm` (None: infinity) whose nearest
/// surface is `nearest_mm` away, using `film_fraction` of the image circle at `f_number`
/// (None: wide open): the dict `lensbake tradeoff --budget-px` reports.
#[pyfunction]
#[pyo3(signature = (lens, budget_px, *, focus_mm=None, nearest_mm=None, f_number=None, film_fraction=1.0, pixels=1920.0, monochrome=false))]
#[allow(clippy::too_many_arguments)]
fn tradeoff<'py>(
    py: Python<'py>,
    lens: &Lens,
    budget_px: f64,
    focus_mm: Option<f64>,
    nearest_mm: Option<f64>,
    f_number: Option<f64>,
    film_fraction: f64,
    pixels: f64,
    monochrome: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let scene = SceneRequirements {
        focus_mm,
        nearest_mm,
        film_fraction,
        f_number,
        pixels,
        monochrome,
    };
    let system = &lens.lens.system;
    let choice = py
        .detach(|| lensbake::choose_model(system, &scene, budget_px))
        .map_err(refused)?;
    serialised(py, &choice)
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("LensbakeError", m.py().get_type::<LensbakeError>())?;
    m.add_class::<Lens>()?;
    m.add_class::<Table>()?;
    m.add_function(wrap_pyfunction!(load_lens, m)?)?;
    m.add_function(wrap_pyfunction!(bake, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(tradeoff, m)?)?;
    for (name, code) in [
        ("OUTCOME_OK", Outcome::CODE_OK),
        ("OUTCOME_VIGNETTED", Outcome::CODE_VIGNETTED),
        ("OUTCOME_TIR", Outcome::CODE_TIR),
        ("OUTCOME_MISSED", Outcome::CODE_MISSED),
        ("LOOKUP_PASSES", LRTF_PASSES as u8),
        ("LOOKUP_BLOCKED", LRTF_BLOCKED as u8),
        ("LOOKUP_OUTSIDE", LRTF_OUTSIDE as u8),
    ] {
        m.add(name, code)?;
    }
    Ok(())
}
