//! Whole tasks composed from the layers below, for any program that calls the library: a render
//! with every decision it takes ([`RenderJob`]), where its tables live ([`tables`]), and the
//! matched traced and baked cameras the demo and the render benchmark compare.
//!
//! A job takes plain settings and returns its results together with what it decided (focus,
//! colour, table, backend, model under an error budget), so a caller can report them; the
//! library itself never prints. This layer sits above `render` and `tradeoff`, which it joins
//! (an error budget picks the model the render then uses), so neither of them depends on the
//! other's callers.

mod budget;
mod focal;
mod render;
pub mod tables;

pub use budget::{BudgetChoice, choose_for_render};
pub use focal::{FocalSurfaceSpec, FocusPointSpec, FocusTarget};
pub use render::{
    BackendChoice, BackendUsed, ChromaticDecision, ChromaticReason, DEFAULT_FOCUS_MM, FilmSize,
    FocusMode, FocusPlaneReport, ModelChoice, Orbit, PeelMode, PeelReport, PreparedRender,
    RenderJob, Rendered, SceneReport, SceneSpec, TableUse,
};
pub use tables::{BakeFallback, TableNeeds, default_table_dir, find_covering_table, load_or_bake};

use crate::lenses::LoadedLens;
use crate::lrtf::FocusError;
use crate::lrtf::bake::{BakeError, BakeProgress};
use crate::lrtf::io::TableError;
use crate::model::{
    BakedLens, FirstOrderModels, LensModel, ModelError, ModelKind, ParaxialLens, SeidelLens,
    TracedLens,
};
use crate::paraxial::{CannotFocus, ObjectPosition, ParaxialError, object_in_focus};
use crate::render::RenderError;
use crate::render::camera::{Camera, Film, Focus};
use crate::render::chromatic::{CHANNELS, Chromatic};
use crate::tradeoff::TradeoffError;
use std::path::{Path, PathBuf};

/// Why a job failed.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Tradeoff(#[from] TradeoffError),
    #[error(transparent)]
    Table(#[from] TableError),
    #[error(transparent)]
    Bake(#[from] BakeError),
    #[error(transparent)]
    Paraxial(#[from] ParaxialError),
    #[error("table {} (name another table, --table, or rebake): {cause}", dir.display())]
    TableFocus { dir: PathBuf, cause: FocusError },
    #[error(
        "an ideal lens (`ideal:<EFL_MM>`) has no surfaces to trace or bake: use the thin or thick \
         model (--model thin or thick)"
    )]
    IdealHasNoSurfaces,
    #[error(
        "chromatic on: the Seidel model has its sums at the design wavelength only; use the thin, \
         thick, traced or baked model, or chromatic off (--model, --chromatic off)"
    )]
    SeidelIsMonochrome,
    #[error("chromatic on: an ideal lens has no glass to disperse; use a lens file")]
    IdealDoesNotDisperse,
    #[error("a traced twin needs the baked model of a real lens")]
    NoTracedTwin,
    #[error(
        "chromatic on: the {0} model's lens kernels are traced at the design wavelength only; \
         use chromatic off or the traced or baked model (--chromatic off, --model)"
    )]
    RealtimeIsMonochrome(ModelKind),
    #[error(
        "the {0} model runs on the CPU only so far (its WGSL twin is not written yet); use \
         --backend cpu or auto"
    )]
    RealtimeOnGpu(ModelKind),
}

impl JobError {
    /// The refusal of a focus nearer than the lens's front focal point, wherever in the job it
    /// came from (the models' focusing, the renderer's camera).
    pub fn cannot_focus(&self) -> Option<&CannotFocus> {
        match self {
            JobError::Model(ModelError::CannotFocus(refused))
            | JobError::Render(RenderError::Model(ModelError::CannotFocus(refused))) => {
                Some(refused)
            }
            _ => None,
        }
    }
}

/// The lens a job renders through: an ideal thin lens of a focal length, or a real prescription.
#[derive(Clone, Debug, PartialEq)]
pub enum RenderLens {
    Ideal { focal_length_mm: f64 },
    Real(Box<LoadedLens>),
}

/// f-number of an ideal lens when none is asked for.
pub const IDEAL_F_NUMBER: f64 = 2.8;

impl RenderLens {
    /// Thin and thick first-order models and the f-number used (wide open when None; f/2.8 for
    /// an ideal lens).
    pub fn first_order(&self, f_number: Option<f64>) -> Result<(FirstOrderModels, f64), JobError> {
        match self {
            RenderLens::Ideal { focal_length_mm } => {
                let f_number = f_number.unwrap_or(IDEAL_F_NUMBER);
                let thin = ParaxialLens::thin(*focal_length_mm, f_number)?;
                let models = FirstOrderModels {
                    thick: thin.clone(),
                    thin,
                    wide_open_f_number: f_number,
                    f_number,
                };
                Ok((models, f_number))
            }
            RenderLens::Real(lens) => {
                let models = FirstOrderModels::of(&lens.system, f_number)?;
                let f_number = models.f_number;
                Ok((models, f_number))
            }
        }
    }

    pub fn real(&self) -> Option<&LoadedLens> {
        match self {
            RenderLens::Real(lens) => Some(lens),
            RenderLens::Ideal { .. } => None,
        }
    }
}

/// The object distance (mm in front of surface 1; None: infinity) that the film at `film_z`
/// is focused on, paraxially at the design wavelength.
pub fn focus_of_film(lens: &LoadedLens, film_z: f64) -> Result<Option<f64>, ParaxialError> {
    let design = lens.system.at(lens.system.design_wavelength_nm());
    Ok(match object_in_focus(&design, film_z)? {
        ObjectPosition::Infinite => None,
        ObjectPosition::Finite { distance } => Some(distance),
    })
}

/// Film-radius nodes of the traced channels' own pupil fit (replaced by the table's circles).
const CHROMATIC_PUPIL_NODES: usize = 16;

/// The traced twin of a baked camera: the exact lens at the same f-number on the same film,
/// drawing the baked model's lens samples (its table's effective-pupil circles), so the
/// difference between their images is the table's error, not noise. Monochrome.
pub fn traced_twin(
    lens: &RenderLens,
    f_number: Option<f64>,
    baked: &Camera,
) -> Result<Camera, JobError> {
    let (LensModel::Baked(table), Some(real)) = (&baked.model, lens.real()) else {
        return Err(JobError::NoTracedTwin);
    };
    let (first_order, f_number) = lens.first_order(f_number)?;
    let pupil = table.pupil(table.layer).circles;
    let traced = TracedLens::new(&real.system, &first_order, f_number, pupil);
    let twin = Camera::new(
        LensModel::Traced(Box::new(traced)),
        baked.film,
        Focus::FilmZ(baked.film_z),
    )?;
    // The same focal surface: both halves shift their film points alike.
    Ok(match &baked.pixel_focus {
        Some(focus) => twin.with_focal_surface(focus.surface.clone(), focus.reference_mm)?,
        None => twin,
    })
}

/// The traced and the baked camera of a real lens focused at `focus_mm`, drawing identical lens
/// samples: both sample the table's effective-pupil circles on its film plane, so the difference
/// between their images is the table's error, not noise. The table comes from `table_dir`,
/// baked there first when missing. With `wavelengths_nm` both render R, G and B at their own
/// wavelengths (a table with a layer per channel), still from one set of sampling circles: the
/// union of the table's channel pupils.
#[derive(Clone, Debug)]
pub struct TracedAndBaked {
    pub traced: Camera,
    pub baked: Camera,
    pub baked_now: bool,
    pub table_resolution: [usize; 3],
}

impl TracedAndBaked {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        real: &LoadedLens,
        first_order: &FirstOrderModels,
        f_number: f64,
        film: Film,
        focus_mm: f64,
        table_dir: &Path,
        bake_resolution: usize,
        wavelengths_nm: Option<[f64; CHANNELS]>,
        progress: &(dyn Fn(BakeProgress) + Sync),
    ) -> Result<TracedAndBaked, JobError> {
        let fallback = BakeFallback {
            focus_mm: Some(focus_mm),
            max_film_radius: (film.width_mm / 2.0).hypot(film.height_mm / 2.0),
            resolution: bake_resolution,
            wavelengths_nm: wavelengths_nm.map_or_else(Vec::new, |w| w.to_vec()),
        };
        let (table, baked_now) = load_or_bake(real, table_dir, &fallback, progress)?;
        let pupil = table.layers[0].pupil.clone();
        let table_resolution = table.info.resolution;
        let baked = BakedLens::new(table, first_order, f_number)?;
        let film_z = baked.film_z();
        let traced = TracedLens::new(&real.system, first_order, f_number, pupil);
        let mut traced = Camera::new(
            LensModel::Traced(Box::new(traced)),
            film,
            Focus::FilmZ(film_z),
        )?;
        let mut baked = Camera::new(
            LensModel::Baked(Box::new(baked)),
            film,
            Focus::FilmZ(film_z),
        )?;
        if let Some(nm) = wavelengths_nm {
            let baked_channels = Chromatic::for_camera(
                &baked,
                &real.system,
                first_order,
                nm,
                CHROMATIC_PUPIL_NODES,
            )?;
            let mut traced_channels = Chromatic::for_camera(
                &traced,
                &real.system,
                first_order,
                nm,
                CHROMATIC_PUPIL_NODES,
            )?;
            // The table's circles contain every channel's pupil (they are fitted conservative);
            // sampling the same ones keeps the two images' difference the table's error.
            traced_channels.sampling = baked_channels.sampling.clone();
            traced = traced.with_chromatic(traced_channels)?;
            baked = baked.with_chromatic(baked_channels)?;
        }
        Ok(TracedAndBaked {
            traced,
            baked,
            baked_now,
            table_resolution,
        })
    }

    /// The camera of `kind` focused at `focus_mm` on `film`: thin, thick and Seidel from
    /// `first_order` (Seidel for that conjugate), traced and baked these two.
    pub fn camera(
        &self,
        kind: ModelKind,
        real: &LoadedLens,
        first_order: &FirstOrderModels,
        film: Film,
        focus_mm: f64,
    ) -> Result<Camera, JobError> {
        let focus = Focus::ObjectDistance(focus_mm);
        Ok(match kind {
            ModelKind::Thin => Camera::new(LensModel::Thin(first_order.thin.clone()), film, focus)?,
            ModelKind::Thick => {
                Camera::new(LensModel::Thick(first_order.thick.clone()), film, focus)?
            }
            ModelKind::Seidel => {
                let seidel = SeidelLens::in_focus(&real.system, first_order, Some(focus_mm))?;
                Camera::new(LensModel::Seidel(Box::new(seidel)), film, focus)?
            }
            // The post-process filters with spots traced through the traced camera.
            ModelKind::Traced | ModelKind::Postfx | ModelKind::Layered => self.traced.clone(),
            ModelKind::Baked => self.baked.clone(),
        })
    }
}
