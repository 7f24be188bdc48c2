//! lensbake: lens prescriptions in; first-order and third-order analysis, exact ray traces,
//! aberration plots, baked lens ray transfer function (LRTF) tables and depth-of-field renders out.
//!
//! Data flows one way: file -> [`prescription::Prescription`] -> [`system::LensSystem`] ->
//! [`system::SystemAt`] (one wavelength) -> paraxial, Seidel and the exact trace -> LRTF tables
//! and effective pupils -> the lens-model layer ([`model`]) -> render and trade-off -> whole
//! jobs ([`job`]). The library never prints; every failure is a typed error. The crate root
//! re-exports what the main jobs need; the modules hold the rest.
//!
//! # Quick start
//!
//! Load a bundled lens (or a lens file: RON, pbrt `.dat`, a table, CODE V `.seq`, Zemax `.zmx`)
//! and read its first-order data:
//!
//! ```
//! use lensbake::{AnalyzeOptions, LoadOptions, analyze, load_lens};
//!
//! let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
//! let report = analyze(&lens.system, &AnalyzeOptions::default())?;
//! // A 50 mm double Gauss: its focal length is 50 mm to within a millimetre.
//! assert!((report.first_order.efl - 50.0).abs() < 1.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Load a lens
//!
//! By bundled name (`lensbake lens list`) or by path; the format follows the extension unless
//! [`LoadOptions`] names one. A lens is validated on loading, and a stale or broken one is a
//! located error (file, line, surface, field):
//!
//! ```
//! use lensbake::{LoadOptions, load_lens};
//!
//! let bundled = load_lens("cooke-triplet", &LoadOptions::default())?;
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/lenses/cooke_triplet.zmx");
//! let from_file = load_lens(path, &LoadOptions::default())?;
//! // Three singlets: six surfaces in both.
//! assert_eq!(from_file.system.prescription.surfaces.len(), 6);
//! assert_eq!(bundled.system.prescription.surfaces.len(), 6);
//! assert!(load_lens("no-such-lens", &LoadOptions::default()).is_err());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Trace rays
//!
//! [`Ray`] is the crate's one public ray (checked finite, direction normalised). One ray, and
//! the same ray in a batch (16 lanes at a time, bit-identical to the one-ray path):
//!
//! ```
//! use lensbake::{Apertures, LoadOptions, Outcome, Ray, RayBatch, Tracer, Travel, load_lens};
//!
//! let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
//! let tracer = Tracer::new(&lens.system.at(lens.system.design_wavelength_nm()));
//! let ray = Ray::new([0.0, 2.0, -10.0], [0.0, 0.0, 1.0])?;
//! let one = tracer.trace(ray, Travel::Forward);
//! assert_eq!(one.outcome, Outcome::Ok);
//!
//! let mut batch = RayBatch::new();
//! batch.push(ray);
//! batch.push(Ray::new([0.0, 500.0, -10.0], [0.0, 0.0, 1.0])?); // far outside the lens
//! let traced = tracer.trace_batch(&batch, Travel::Forward, Apertures::Checked);
//! assert_eq!(traced.outcomes[0], Outcome::Ok);
//! assert_eq!(traced.rays.get(0), Some(one.ray));
//! assert!(!traced.outcomes[1].is_ok());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Bake and load a table
//!
//! A coarse table, written (atomically, with its sidecar) and read back; reading checks the
//! prescription hash and the data checksum:
//!
//! ```
//! use lensbake::{BakeRequest, LoadOptions, bake, load_lens, read_table, write_table};
//!
//! let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
//! let request = BakeRequest { resolution: [8; 3], ..BakeRequest::default() };
//! let table = bake(&lens.system, &request)?;
//! let dir = std::env::temp_dir().join(format!("lensbake-doc-table-{}", std::process::id()));
//! write_table(&table, "dgauss-50mm", &lens.system.prescription, &dir)?;
//! let read = read_table(&dir, Some(&lens.system.prescription))?;
//! assert_eq!(read.info.resolution, [8; 3]);
//! std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Look rays up in a table
//!
//! A film-side ray (travelling -z, towards the lens) goes in with the focus (object distance, mm;
//! None: the table's own) and the f-number (None: as baked); out comes where it leaves the
//! front of the lens, or why it does not. [`LrtfTable::focused`] checks focus and f-number
//! once for many rays:
//!
//! ```
//! use lensbake::{BakeRequest, LoadOptions, Lookup, Ray, bake, load_lens};
//!
//! let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
//! let request = BakeRequest { resolution: [16; 3], focus_mm: Some(2000.0), ..Default::default() };
//! let table = bake(&lens.system, &request)?;
//! let at = table.focused(Some(2000.0), Some(2.8))?;
//! let ray = Ray::new([1.0, 2.0, at.film_z()], [0.0, -0.05, -1.0])?;
//! match at.lookup(&ray) {
//!     Lookup::Passes(_) => assert!(at.lookup(&ray).passed().unwrap().direction()[2] < 0.0),
//!     Lookup::Blocked | Lookup::OutsideDomain => unreachable!("a near-axial ray passes"),
//! }
//! // One ray through the shorthand, the same answer.
//! assert_eq!(table.lookup(&ray, Some(2000.0), Some(2.8))?, at.lookup(&ray));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Wave optics
//!
//! Wavefront, MTF and PSF of one field point take [`WaveOptions`] (field, aperture, spectrum,
//! sampling, defocus; every field defaults):
//!
//! ```
//! use lensbake::{LoadOptions, WaveOptions, load_lens, mtf, psf, wavefront};
//!
//! let lens = load_lens("cooke-triplet", &LoadOptions::default())?;
//! let options = WaveOptions { field_deg: 5.0, ..WaveOptions::default() };
//! let map = wavefront(&lens.system, &options)?;
//! assert!(map.stats().rms_waves > 0.0);
//! let curve = mtf(&lens.system, &options, &[])?; // 41 frequencies up to the cutoff
//! assert_eq!(curve.frequencies_per_mm.len(), 41);
//! let spot = psf(&lens.system, &options)?;
//! assert!(spot.peak() <= 1.0 + 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Map rays through a lens model
//!
//! The five models (thin, thick, Seidel, traced, baked) are one type, [`LensModel`], named by
//! [`ModelKind`]; the renderer, the trade-off and focusing all go through it:
//!
//! ```
//! use lensbake::model::FirstOrderModels;
//! use lensbake::{LensModel, LoadOptions, ModelKind, load_lens};
//!
//! let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
//! let first = FirstOrderModels::of(&lens.system, None)?;
//! let thick = LensModel::Thick(first.thick.clone());
//! assert_eq!(thick.kind(), "thick".parse::<ModelKind>()?);
//! // A film-side ray from the axial image of infinity leaves parallel to the axis.
//! let film_z = first.thick.rear_principal_z + first.thick.focal_length_mm;
//! let ray = lensbake::Ray::new([0.0, 0.0, film_z], [0.0, 0.01, -1.0])?;
//! let out = thick.scene_ray(&ray.into(), film_z).expect("a first-order model passes every ray");
//! assert!(out.direction[0].abs() < 1e-12 && out.direction[1].abs() < 1e-12);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Render
//!
//! A [`RenderJob`] holds every setting of a render (lens, model or error budget, scene, focus
//! mode, sensor shift and tilt, colour, table, backend) and returns the image with what it
//! decided (with the `render` feature, on by default):
//!
//! ```
//! # #[cfg(feature = "render")] {
//! use lensbake::job::{BackendChoice, ModelChoice};
//! use lensbake::{LoadOptions, ModelKind, RenderJob, RenderLens, load_lens};
//!
//! let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
//! let mut job = RenderJob::new(RenderLens::Real(Box::new(lens)));
//! job.model = ModelChoice::Model(ModelKind::Traced);
//! job.backend = BackendChoice::Cpu;
//! job.settings.width = 48;
//! job.settings.height = 32;
//! job.settings.samples_per_pixel = 2;
//! let rendered = job.run()?;
//! assert_eq!(rendered.image.pixels.len(), 48 * 32);
//! assert!(rendered.image.pixels.iter().flatten().all(|v| v.is_finite()));
//! assert_eq!(rendered.prepared.camera.model.kind(), ModelKind::Traced);
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Trade speed for accuracy
//!
//! The cheapest model whose measured image error stays under a budget (pixels of a 1920 px
//! frame) for a scene (with the `render` feature: the trade-off also times renders):
//!
//! ```
//! # #[cfg(feature = "render")] {
//! use lensbake::{LoadOptions, SceneRequirements, choose_model, load_lens};
//!
//! let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
//! let choice = choose_model(&lens.system, &SceneRequirements::default(), 40.0)?;
//! assert!(choice.measured_px <= 40.0);
//! println!("{} within 40 px (measured {:.2} px)", choice.label, choice.measured_px);
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

// `!(x > 0.0)` is this crate's way of refusing NaN together with the values out of range: a NaN
// fails every comparison, so the negated test is true for it. The partial_cmp spelling clippy
// suggests says the same thing at three times the length.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod analysis;
#[cfg(feature = "export")]
pub mod export;
pub mod glass;
#[cfg(feature = "render")]
pub mod job;
pub mod lenses;
pub mod limits;
pub mod lrtf;
pub mod model;
pub mod output;
mod pages;
pub mod paraxial;
#[cfg(feature = "plot")]
pub mod plot;
pub mod prescription;
pub mod pupil;
#[cfg(feature = "render")]
pub mod render;
#[cfg(feature = "plot")]
pub mod report;
pub mod seidel;
pub mod system;
pub mod trace;
#[cfg(feature = "render")]
pub mod tradeoff;
#[cfg(feature = "view")]
pub mod view;
pub mod wave;

pub use analysis::{Analysis, AnalyzeOptions, analyze};
#[cfg(feature = "render")]
pub use job::{JobError, RenderJob, RenderLens, Rendered};
pub use lenses::{LoadedLens, load as load_lens};
pub use lrtf::bake::{BakeRequest, bake, bake_with_progress};
pub use lrtf::io::{read_table, write_table};
pub use lrtf::{FocusedTable, Lookup, LookupError, LrtfTable};
pub use model::{LensModel, ModelKind};
pub use prescription::formats::LoadOptions;
pub use system::{LensSystem, SystemAt};
pub use trace::{Apertures, Outcome, Ray, RayBatch, Tracer, Travel};
#[cfg(feature = "render")]
pub use tradeoff::choose::{Choice, choose_model};
#[cfg(feature = "render")]
pub use tradeoff::{SceneRequirements, tradeoff};
pub use wave::lens::{mtf, psf, wavefront};
pub use wave::{Mtf, Psf, WaveError, WaveOptions, WavefrontMap};
