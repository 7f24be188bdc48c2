//! Speed against accuracy, measured: every lens model's film-to-scene ray map against the exact
//! backward trace on the same random film-side rays, with what each model costs, and the choice
//! of the cheapest model that keeps a scene's image error under a budget ([`choose::choose_model`]).
//!
//! Rays are drawn the way the renderer draws them ([`renderer_rays`]: film point uniform over the
//! film disk, rear point uniform over the effective-pupil circle), in the domain a table would be
//! baked for. The error of one ray is the angle between the model's and the exact scene-side
//! direction; for a scene whose nearest surface is D away, the perpendicular offset between the
//! rays adds offset / D (the angle the offset subtends there). Image error maps that angle
//! through the EFL onto a frame `pixels` wide ([`pixel_pitch`]).

pub mod choose;
pub mod render;

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::lrtf::bake::{BakeError, BakeRequest, bake, chief_ray_film_radius, first_order};
use crate::lrtf::measure::{Stats, angle_between, distance_to_line, pixel_pitch, renderer_rays};
use crate::lrtf::{LrtfTable, Precision, Ray};
use crate::model::{
    BakedLens, FirstOrderModels, LensModel, ModelError, ModelKind, ParaxialLens, PupilSampling,
    SeidelLens, TracedLens, paraxial_for,
};
use crate::paraxial::ParaxialError;
use crate::render::RenderError;
use crate::system::{LensSystem, SystemAt};
use crate::trace::Tracer;
use render::{RenderBench, RenderCost, render_costs};

#[derive(Debug, thiserror::Error)]
pub enum TradeoffError {
    #[error(transparent)]
    Bake(#[from] BakeError),
    #[error("first-order model: {0}")]
    Paraxial(#[from] ParaxialError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error("{0}")]
    Invalid(String),
}

/// What a scene asks of the lens. `None` fields take the default domain of issue 6.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneRequirements {
    /// Object distance in focus, mm in front of surface 1; None: infinity.
    pub focus_mm: Option<f64>,
    /// Nearest scene surface, mm in front of surface 1; None: everything far away.
    pub nearest_mm: Option<f64>,
    /// Fraction of the default film radius (the real chief ray at the largest traceable field)
    /// that the image uses, in (0, 1].
    pub film_fraction: f64,
    /// None: wide open.
    pub f_number: Option<f64>,
    /// Output width in pixels, for image errors.
    pub pixels: f64,
    /// The renderer traces one wavelength: lateral colour is not asked of the model (and cannot
    /// be given by any), so the choice never turns to three-wavelength tables for it.
    pub monochrome: bool,
}

impl Default for SceneRequirements {
    fn default() -> SceneRequirements {
        SceneRequirements {
            focus_mm: None,
            nearest_mm: None,
            film_fraction: 1.0,
            f_number: None,
            pixels: 1920.0,
            monochrome: false,
        }
    }
}

impl SceneRequirements {
    fn check(&self) -> Result<(), TradeoffError> {
        let bad = |what: String| Err(TradeoffError::Invalid(what));
        if !(self.film_fraction > 0.0 && self.film_fraction <= 1.0) {
            return bad(format!(
                "film fraction must lie in (0, 1], got {}",
                self.film_fraction
            ));
        }
        if !(self.pixels.is_finite() && self.pixels >= 1.0) {
            return bad(format!(
                "pixel width must be at least 1, got {}",
                self.pixels
            ));
        }
        for (name, value) in [
            ("focus distance", self.focus_mm),
            ("nearest depth", self.nearest_mm),
            ("f-number", self.f_number),
        ] {
            if let Some(v) = value
                && !(v.is_finite() && v > 0.0)
            {
                return bad(format!("{name} must be positive and finite, got {v}"));
            }
        }
        Ok(())
    }
}

/// The domain every model is measured in (design wavelength).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Domain {
    pub film_z: f64,
    /// Film radius the rays cover (mm).
    pub film_radius: f64,
    /// The default domain's film radius, before the scene's fraction (mm).
    pub full_film_radius: f64,
    pub f_number: f64,
    pub efl: f64,
    /// Pixel pitch of a frame `pixels` wide inscribed in the used image circle (mm).
    pub pixel_pitch: f64,
    pub focus_mm: Option<f64>,
    pub nearest_mm: Option<f64>,
    pub wavelength_nm: f64,
}

impl Domain {
    pub fn of(system: &LensSystem, req: &SceneRequirements) -> Result<Domain, TradeoffError> {
        req.check()?;
        let at = system.at(system.design_wavelength_nm());
        let first = first_order(&at, req.focus_mm)?;
        first
            .first_order
            .require_converging()
            .map_err(BakeError::from)?;
        let f_number = req.f_number.unwrap_or(first.f_number);
        if f_number < first.f_number * (1.0 - 1e-9) {
            return Err(BakeError::FNumber {
                asked: f_number,
                wide_open: first.f_number,
            }
            .into());
        }
        let stopped = stopped_down(&at, first.f_number / f_number);
        let full = chief_ray_film_radius(&Tracer::new(&stopped), &at, first.z_image);
        if full <= 0.0 {
            return Err(BakeError::NoChiefRay {
                film_z: first.z_image,
            }
            .into());
        }
        let film_radius = full * req.film_fraction;
        Ok(Domain {
            film_z: first.z_image,
            film_radius,
            full_film_radius: full,
            f_number,
            efl: first.first_order.efl,
            pixel_pitch: pixel_pitch(film_radius, req.pixels),
            focus_mm: req.focus_mm,
            nearest_mm: req.nearest_mm,
            wavelength_nm: at.wavelength_nm,
        })
    }

    /// A bake request for exactly this domain.
    pub fn bake_request(
        &self,
        resolution: usize,
        precision: Precision,
        wavelengths_nm: Vec<f64>,
    ) -> BakeRequest {
        BakeRequest {
            resolution: [resolution; 3],
            precision,
            wavelengths_nm,
            f_number: Some(self.f_number),
            focus_mm: self.focus_mm,
            max_film_radius: Some(self.film_radius),
            ..BakeRequest::default()
        }
    }
}

/// `at` with its stop scaled by `scale` (the stop scales as 1 / f-number).
fn stopped_down(at: &SystemAt, scale: f64) -> SystemAt {
    at.stopped_down(at.surfaces[at.stop].semi_aperture * scale)
}

/// Random film-side rays of the domain and the exact trace's answer for each (None: blocked).
#[derive(Clone, Debug)]
pub struct RaySet {
    pub rays: Vec<Ray>,
    pub exact: Vec<Option<Ray>>,
}

impl RaySet {
    /// `count` renderer rays drawn through `probe`'s effective pupil (a table of this domain).
    pub fn new(
        probe: &LrtfTable,
        traced: &Built,
        domain: &Domain,
        count: usize,
        seed: u64,
    ) -> RaySet {
        let layer = design_layer(probe, domain.wavelength_nm);
        let l = &probe.layers[layer];
        let rays = renderer_rays(
            &l.pupil,
            domain.film_radius,
            l.frame.film_plane_z,
            l.frame.rear_plane_z,
            count,
            seed,
        );
        let exact = rays.par_iter().map(|r| traced.map(r)).collect();
        RaySet { rays, exact }
    }
}

/// The layer of `table` nearest `wavelength_nm`.
pub fn design_layer(table: &LrtfTable, wavelength_nm: f64) -> usize {
    (0..table.layers.len())
        .min_by(|&a, &b| {
            let d = |k: usize| (table.layers[k].wavelength_nm - wavelength_nm).abs();
            d(a).total_cmp(&d(b))
        })
        .unwrap_or(0)
}

/// One model's errors over a ray set.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RayError {
    pub rays: usize,
    /// Rays both the model and the exact trace pass, over which the errors are taken.
    pub compared: usize,
    /// Rays where exactly one of model and trace says the ray passes, over all rays. First-order
    /// and Seidel models have no apertures (a renderer samples their own pupils instead).
    pub validity_mismatch: f64,
    pub direction_mrad: Stats,
    pub image_px: Stats,
}

/// Angle (rad) under which the model's ray misses the exact one as seen from a scene `nearest`
/// mm away (None: direction only).
fn scene_angle(model: &Ray, exact: &Ray, nearest: Option<f64>) -> (f64, f64) {
    let direction = angle_between(model.direction, exact.direction);
    let offset = nearest.map_or(0.0, |d| {
        distance_to_line(exact.origin, model.origin, model.direction) / d
    });
    (direction, direction + offset)
}

pub fn model_error(model: &Built, set: &RaySet, domain: &Domain) -> RayError {
    let outcomes: Vec<(bool, Option<(f64, f64)>)> = set
        .rays
        .par_iter()
        .zip(&set.exact)
        .map(|(ray, exact)| match (model.map(ray), exact) {
            (Some(m), Some(e)) => (false, Some(scene_angle(&m, e, domain.nearest_mm))),
            (Some(_), None) | (None, Some(_)) => (true, None),
            (None, None) => (false, None),
        })
        .collect();
    let angles: Vec<(f64, f64)> = outcomes.iter().filter_map(|o| o.1).collect();
    let px_per_rad = domain.efl.abs() / domain.pixel_pitch;
    RayError {
        rays: set.rays.len(),
        compared: angles.len(),
        validity_mismatch: outcomes.iter().filter(|o| o.0).count() as f64
            / set.rays.len().max(1) as f64,
        direction_mrad: Stats::of(angles.iter().map(|a| a.0 * 1e3).collect()),
        image_px: Stats::of(angles.iter().map(|a| a.1 * px_per_rad).collect()),
    }
}

/// One row of the trade-off: what the model costs and how wrong it is. The JSON shape of
/// `lensbake tradeoff --json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Entry {
    pub model: ModelKind,
    pub resolution: Option<usize>,
    pub precision: Option<&'static str>,
    /// Time to build the model from the prescription (bake, pupil fit, or paraxial setup).
    pub bake_seconds: f64,
    /// Bytes of the model's data as held in memory (table entries for a baked table).
    pub table_bytes: usize,
    /// Median wall-clock ms of a frame of the demo scene on the CPU twin ([`RenderBench`]).
    pub render_ms_per_frame: f64,
    pub ray_error_p99_mrad: f64,
    pub image_error_px_p99: f64,
}

/// A built model with what it cost to build.
pub struct Built {
    pub model: LensModel,
    /// The film plane the model is focused on (see [`LensModel::scene_ray`]): thin and thick
    /// their own image of the domain's focus, the others the domain's film plane.
    pub film_z: f64,
    pub resolution: Option<usize>,
    pub precision: Option<Precision>,
    pub bake_seconds: f64,
}

impl Built {
    /// The model's scene-side ray for the domain's film-side `ray`.
    pub fn map(&self, ray: &Ray) -> Option<Ray> {
        self.model.scene_ray(ray, self.film_z)
    }

    pub fn entry(&self, error: &RayError, render: &RenderCost) -> Entry {
        Entry {
            model: self.model.kind(),
            resolution: self.resolution,
            precision: self.precision.map(Precision::name),
            bake_seconds: self.bake_seconds,
            table_bytes: self.model.data_bytes(),
            render_ms_per_frame: render.ms_per_frame,
            ray_error_p99_mrad: error.direction_mrad.p99,
            image_error_px_p99: error.image_px.p99,
        }
    }

    pub fn label(&self) -> String {
        match (self.resolution, self.precision) {
            (Some(n), Some(p)) => format!("baked {n}^3 {}", p.name()),
            _ => self.model.kind().name().to_string(),
        }
    }
}

/// The first-order, Seidel and traced models of `system` for `domain` (design wavelength).
pub fn analytic_models(system: &LensSystem, domain: &Domain) -> Result<Vec<Built>, TradeoffError> {
    let at = system.at(domain.wavelength_nm);
    let started = Instant::now();
    let paraxial = paraxial_for(&at, domain.focus_mm)?;
    let FirstOrderModels { thin, thick, .. } = FirstOrderModels::of(system, Some(domain.f_number))?;
    let film_z = |lens: &ParaxialLens| match domain.focus_mm {
        None => Ok(lens.rear_principal_z + lens.focal_length_mm),
        Some(d) => lens.film_z_for_object(d),
    };
    let first_order_seconds = started.elapsed().as_secs_f64();
    let paraxial_model = |kind: ModelKind, lens: &ParaxialLens| {
        Ok::<_, TradeoffError>(Built {
            film_z: film_z(lens)?,
            model: match kind {
                ModelKind::Thin => LensModel::Thin(lens.clone()),
                _ => LensModel::Thick(lens.clone()),
            },
            resolution: None,
            precision: None,
            bake_seconds: first_order_seconds,
        })
    };
    let mut built = vec![
        paraxial_model(ModelKind::Thin, &thin)?,
        paraxial_model(ModelKind::Thick, &thick)?,
    ];
    let started = Instant::now();
    let seidel = SeidelLens::new(&at, &paraxial, thick.clone());
    built.push(Built {
        bake_seconds: first_order_seconds + started.elapsed().as_secs_f64(),
        film_z: seidel.image_z,
        model: LensModel::Seidel(Box::new(seidel)),
        resolution: None,
        precision: None,
    });
    built.push(traced_model(&at, thick, domain));
    Ok(built)
}

/// The exact trace through the lens stopped down to the domain's f-number. It samples no pupil
/// of its own: the trade-off draws its rays from a table's.
fn traced_model(at: &SystemAt, thick: ParaxialLens, domain: &Domain) -> Built {
    let started = Instant::now();
    let wide_open = first_order(at, domain.focus_mm)
        .map(|f| f.f_number)
        .unwrap_or(domain.f_number);
    let stopped = stopped_down(at, wide_open / domain.f_number);
    let no_pupil = PupilSampling::disc(0.0, 0.0).circles;
    let traced = TracedLens::from_stopped(thick, stopped, no_pupil);
    Built {
        bake_seconds: started.elapsed().as_secs_f64(),
        film_z: domain.film_z,
        model: LensModel::Traced(Box::new(traced)),
        resolution: None,
        precision: None,
    }
}

/// A baked model of `system` from `table` (a table of `domain`, already baked in
/// `bake_seconds`), at the domain's f-number, reading its design-wavelength layer.
pub fn baked_model(
    system: &LensSystem,
    table: LrtfTable,
    domain: &Domain,
    bake_seconds: f64,
) -> Result<Built, TradeoffError> {
    let first = FirstOrderModels::of(system, Some(domain.f_number))?;
    let resolution = table.info.resolution[0];
    let precision = table.info.precision;
    let baked =
        BakedLens::new(table, &first, domain.f_number)?.with_wavelength(domain.wavelength_nm)?;
    Ok(Built {
        resolution: Some(resolution),
        precision: Some(precision),
        bake_seconds,
        film_z: baked.film_z(),
        model: LensModel::Baked(Box::new(baked)),
    })
}

/// Bakes an f32 table for `domain` and times it.
pub fn bake_timed(
    system: &LensSystem,
    domain: &Domain,
    resolution: usize,
    wavelengths_nm: Vec<f64>,
) -> Result<(LrtfTable, f64), TradeoffError> {
    let started = Instant::now();
    let table = bake(
        system,
        &domain.bake_request(resolution, Precision::F32, wavelengths_nm),
    )?;
    Ok((table, started.elapsed().as_secs_f64()))
}

/// The table an f16 bake of the same request stores: the bake rounds every f64 value to f32 and
/// then to the precision, so rounding the f32 entries again gives the identical table.
pub fn to_f16(table: &LrtfTable) -> LrtfTable {
    table.to_precision(Precision::F16)
}

/// Resolutions the trade-off bakes.
pub const RESOLUTIONS: [usize; 4] = [16, 32, 64, 128];

/// A measured model: its row and the full error statistics.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Measured {
    pub label: String,
    pub entry: Entry,
    pub error: RayError,
    /// The frame's cost and PSNR against the traced frame.
    pub render: RenderCost,
}

/// Every model of `system` measured over `rays` rays of the scene's domain: thin, thick, Seidel,
/// baked at each of [`RESOLUTIONS`] in f32 and f16, and traced (last, the reference); each
/// model also renders `bench`'s frame of the demo scene.
pub fn tradeoff(
    system: &LensSystem,
    req: &SceneRequirements,
    rays: usize,
    seed: u64,
    bench: &RenderBench,
) -> Result<(Domain, Vec<Measured>), TradeoffError> {
    let domain = Domain::of(system, req)?;
    let mut built = analytic_models(system, &domain)?;
    let traced = built
        .pop()
        .expect("analytic_models ends with the traced model");
    for &n in &RESOLUTIONS {
        let (table, seconds) = bake_timed(system, &domain, n, Vec::new())?;
        built.push(baked_model(system, to_f16(&table), &domain, seconds)?);
        built.push(baked_model(system, table, &domain, seconds)?);
    }
    let probe = built
        .last()
        .and_then(|b| b.model.table())
        .expect("the last model built is a baked table")
        .clone();
    let set = RaySet::new(&probe, &traced, &domain, rays, seed);
    built.push(traced);
    let renders = render_costs(system, &domain, &built, &probe, bench)?;
    let measured = built
        .iter()
        .zip(renders)
        .map(|(b, render)| {
            let error = model_error(b, &set, &domain);
            Measured {
                label: b.label(),
                entry: b.entry(&error, &render),
                error,
                render,
            }
        })
        .collect();
    Ok((domain, measured))
}
