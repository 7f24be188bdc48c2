//! `lensbake render`: depth of field through a lens model by image-based ray tracing. Parses the
//! arguments into a [`RenderJob`], runs it, writes the image and prints what the job decided.

use super::lens::ReadArgs;
use clap::{Args, ValueEnum};
use lensbake::analysis::{FileDefaults, FocusFrom};
use lensbake::job::JobError;
use lensbake::job::{
    BackendChoice, BackendUsed, ChromaticReason, DEFAULT_FOCUS_MM, FilmSize, FocalSurfaceSpec,
    FocusMode, ModelChoice, PeelMode, RenderJob, RenderLens, Rendered, SceneSpec,
};
use lensbake::model::{AberrationScale, ModelKind};
use lensbake::realtime::layered::DEFAULT_LAYERS;
use lensbake::realtime::{KernelOrigin, PostfxPath};
use lensbake::render::RenderSettings;
use lensbake::render::chromatic::{CHANNELS, ChromaticMode};
use lensbake::render::image::{png_beside, write_exr, write_png};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendArg {
    Gpu,
    Cpu,
    Auto,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PeelArg {
    Plain,
    Umbra,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Lens: a lens file or bundled lens name (see `lensbake lens list`), or `ideal:<EFL_MM>`
    /// for an ideal thin lens of that focal length (thin and thick models only).
    #[arg(long)]
    lens: String,
    #[command(flatten)]
    read: ReadArgs,
    /// Lens model: thin and thick from the paraxial data, seidel (thick plus third-order
    /// aberration), traced (the exact trace in the kernel), baked (an LRTF table lookup),
    /// postfx (the real-time gather post-process with kernels traced through the lens; CPU),
    /// layered (seed 002's layered depth of field with the same kernels; CPU).
    #[arg(long, default_value = "traced", value_parser = super::lens::model_parser())]
    model: ModelKind,
    /// Table directory for `--model baked`; default: the first table under tables/<lens>/ whose
    /// focus range covers the render's focus (a range table serves every focus inside it), else
    /// tables/<lens>/ (infinity) or tables/<lens>/focus-<D>mm/, baked there when missing.
    #[arg(long)]
    table: Option<PathBuf>,
    /// Nodes per axis when a table has to be baked.
    #[arg(long, default_value_t = 64)]
    bake_resolution: usize,
    /// `demo`, a glTF 2.0 file (.gltf or .glb; metres, seen from its first camera node), or an
    /// OpenEXR file with R, G, B and Z (mm from the entrance pupil) channels.
    #[arg(long, default_value = "demo")]
    scene: String,
    /// Depth peeling of mesh scenes: `umbra` skips surfaces hidden from the whole entrance
    /// pupil behind a nearer layer's pixel (fewer layers), `plain` keeps every surface.
    #[arg(long, value_enum, default_value = "umbra")]
    peel: PeelArg,
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    #[arg(long, default_value_t = 800)]
    width: u32,
    #[arg(long, default_value_t = 600)]
    height: u32,
    /// f-number; default: the lens wide open (f/2.8 for `ideal:`).
    #[arg(long)]
    f_number: Option<f64>,
    /// Focus on the plane this far in front of the first vertex (mm); default: the lens file's
    /// object distance, else 2000 mm.
    #[arg(long, conflicts_with_all = ["focus_pixel", "sensor_mm"])]
    focus_mm: Option<f64>,
    /// Focus on the nearest surface under output pixel X,Y.
    #[arg(long, value_parser = parse_pair::<u32>, conflicts_with = "sensor_mm")]
    focus_pixel: Option<(u32, u32)>,
    /// Put the film this far behind the first vertex (mm).
    #[arg(long)]
    sensor_mm: Option<f64>,
    /// Sensor width (mm), its height following the image's aspect [default: full frame, 36 x
    /// 24 mm cropped to the aspect; for a lens whose image circle is smaller than half the full
    /// frame's height (a phone or machine-vision lens), the largest frame inside that circle].
    #[arg(long)]
    film_mm: Option<f64>,
    /// Sensor shift X,Y (mm).
    #[arg(long, value_parser = parse_pair::<f64>, default_value = "0,0")]
    shift_mm: (f64, f64),
    /// Sensor tilt X,Y (degrees): right-handed rotations about the lens-frame x axis, then the
    /// y axis, through the sensor centre. X > 0 moves the bottom edge of the image away from the
    /// lens, Y > 0 its left edge towards the lens. Focus modes place the sensor centre.
    #[arg(long, value_parser = parse_pair::<f64>, default_value = "0,0", allow_hyphen_values = true)]
    tilt_deg: (f64, f64),
    /// Tilt the sensor to focus on the plane through the scene points under three pixels,
    /// "X1,Y1;X2,Y2;X3,Y3" (quote it), picked in the untilted frame focused at infinity.
    /// Thin and thick: the paraxial (Scheimpflug) solution; traced and baked: the plane
    /// through the real-ray best-focus points. Prints the tilt and the sensor distance.
    #[arg(long, value_parser = parse_focus_points,
          conflicts_with_all = ["focus_mm", "focus_pixel", "sensor_mm", "tilt_deg"])]
    focus_points: Option<[(u32, u32); 3]>,
    /// Focus per pixel on a focal surface through focus points (seed 004):
    /// "X,Y[,TARGET[,ALPHA]];..." (quote it), TARGET a distance in mm, `scene` (the surface under
    /// the pixel; the default) or N`dpt` (that surface defocused by N dioptres, + nearer), ALPHA
    /// the point's weight (default 1). Pixels between points take the moving-least-squares blend
    /// of the points' focus (weights ALPHA / distance^BETA). See docs/focal-surface.md.
    #[arg(long, conflicts_with_all = ["focus_mm", "focus_pixel", "sensor_mm", "focus_points"])]
    focal_surface: Option<String>,
    /// Falloff exponent BETA of the focal surface's weights (1 to 8; the seed suggests 2 to 4).
    #[arg(long, default_value_t = lensbake::render::focal_surface::DEFAULT_BETA,
          requires = "focal_surface")]
    focal_beta: f64,
    /// Factors on the Seidel model's five sums, for effect: SPHERICAL,COMA,ASTIGMATISM,
    /// PETZVAL,DISTORTION (1 as designed, 0 removes it; all 0 is the paraxial lens). Seidel
    /// model only: a traced or baked lens takes its aberrations from its surfaces.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    seidel_scale: Option<Vec<f64>>,
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// Most depth-peeled layers per pixel.
    #[arg(long, default_value_t = 8)]
    max_layers: usize,
    /// Output OpenEXR (linear R, G, B); a tone-mapped PNG is written beside it.
    #[arg(long)]
    out: PathBuf,
    /// Trace R, G and B each at its own wavelength (chromatic aberration): on, off, or auto =
    /// on when the lens disperses and its colour spread on this film reaches half a pixel.
    #[arg(long, value_enum, default_value = "auto")]
    chromatic: ChromaticArg,
    /// Wavelengths of R,G,B in nm; default: the C line, the design wavelength, the F line.
    #[arg(long, value_delimiter = ',')]
    wavelengths_nm: Option<Vec<f64>>,
    /// Render with the cheapest model (and table size and precision) whose p99 image error, in
    /// pixels of this render, stays under this for the scene's depth range, film use and
    /// f-number; prints the choice with its predicted and measured error.
    #[arg(long, conflicts_with_all = ["model", "table"])]
    error_budget_px: Option<f64>,
    /// For `--model postfx`: `fast` (half resolution, at most 81 taps a pass; the real-time
    /// path) or `exact` (full resolution, every tap's lens kernel fitted on the fly).
    #[arg(long, value_enum, default_value = "fast")]
    postfx: PostfxArg,
    /// For `--model layered`: depth layers, at equal circle-of-confusion steps about the plane
    /// in focus (3 to 64).
    #[arg(long, default_value_t = DEFAULT_LAYERS)]
    layers: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PostfxArg {
    Fast,
    Exact,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ChromaticArg {
    On,
    Off,
    Auto,
}

impl From<BackendArg> for BackendChoice {
    fn from(arg: BackendArg) -> BackendChoice {
        match arg {
            BackendArg::Gpu => BackendChoice::Gpu,
            BackendArg::Cpu => BackendChoice::Cpu,
            BackendArg::Auto => BackendChoice::Auto,
        }
    }
}

impl From<ChromaticArg> for ChromaticMode {
    fn from(arg: ChromaticArg) -> ChromaticMode {
        match arg {
            ChromaticArg::On => ChromaticMode::On,
            ChromaticArg::Off => ChromaticMode::Off,
            ChromaticArg::Auto => ChromaticMode::Auto,
        }
    }
}

pub fn parse_pair<T: std::str::FromStr>(text: &str) -> Result<(T, T), String> {
    let (a, b) = text
        .split_once(',')
        .ok_or_else(|| format!("expected X,Y, got `{text}`"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<T>()
            .map_err(|_| format!("not a number: `{s}`"))
    };
    Ok((parse(a)?, parse(b)?))
}

fn parse_focus_points(text: &str) -> Result<[(u32, u32); 3], String> {
    let pixels = text
        .split(';')
        .map(parse_pair::<u32>)
        .collect::<Result<Vec<_>, _>>()?;
    <[(u32, u32); 3]>::try_from(pixels)
        .map_err(|p| format!("expected three pixels X1,Y1;X2,Y2;X3,Y3, got {}", p.len()))
}

impl RenderArgs {
    /// The job these arguments describe, and what it takes from the lens file's stated
    /// conditions where no flag is given (one line each, for the user).
    fn job(&self) -> anyhow::Result<(RenderJob, Vec<String>, Option<&'static str>)> {
        let lens = super::lens::render_lens(&self.lens, &self.read)?;
        let no_focus_flag = self.focus_points.is_none()
            && self.focal_surface.is_none()
            && self.focus_mm.is_none()
            && self.focus_pixel.is_none()
            && self.sensor_mm.is_none();
        let focus_from = if no_focus_flag {
            FocusFrom::File
        } else {
            FocusFrom::Flag
        };
        let defaults = match &lens {
            RenderLens::Real(loaded) => FileDefaults::of(&loaded.system, focus_from)?,
            RenderLens::Ideal { .. } => FileDefaults::default(),
        };
        let mut from_file = defaults.notes.clone();
        let file_f_number = self
            .f_number
            .is_none()
            .then_some(defaults.f_number)
            .flatten();
        if let Some(f) = file_f_number {
            from_file.push(format!("f/{f:.3} from the lens file"));
        }
        let file_focus = defaults.focus_mm;
        if let Some(d) = file_focus {
            from_file.push(format!("focus {d:.3} mm: the lens file's object distance"));
        }
        let file_wavelengths = self
            .wavelengths_nm
            .is_none()
            .then_some(defaults.rgb_wavelengths_nm)
            .flatten();
        if let Some([r, g, b]) = file_wavelengths {
            from_file.push(format!(
                "R/G/B wavelengths {r:.1}/{g:.1}/{b:.1} nm from the lens file"
            ));
        }
        let wavelengths_nm = match &self.wavelengths_nm {
            Some(list) => Some(<[f64; CHANNELS]>::try_from(list.as_slice()).map_err(|_| {
                anyhow::anyhow!(
                    "--wavelengths-nm takes three wavelengths R,G,B, got {}",
                    list.len()
                )
            })?),
            None => file_wavelengths,
        };
        let unasked_focus = no_focus_flag.then_some(if file_focus.is_some() {
            "the lens file's object distance"
        } else {
            "render's default focus"
        });
        let surface = self
            .focal_surface
            .as_deref()
            .map(|text| FocalSurfaceSpec::parse(text, self.focal_beta))
            .transpose()
            .map_err(|e| anyhow::anyhow!("--focal-surface: {e}"))?;
        let focus = match (
            self.focus_points,
            self.focus_mm,
            self.focus_pixel,
            self.sensor_mm,
        ) {
            (Some(pixels), ..) => FocusMode::Points(pixels.map(|(x, y)| [x, y])),
            (_, Some(d), _, _) => FocusMode::Distance(d),
            (_, _, _, Some(z)) => FocusMode::Sensor(z),
            (_, _, Some((x, y)), _) => FocusMode::Pixel([x, y]),
            (None, None, None, None) => match surface {
                Some(surface) => FocusMode::Surface(surface),
                None => FocusMode::Distance(file_focus.unwrap_or(DEFAULT_FOCUS_MM)),
            },
        };
        let aberration_scale = match &self.seidel_scale {
            None => AberrationScale::AS_DESIGNED,
            Some(_) if self.model != ModelKind::Seidel || self.error_budget_px.is_some() => {
                anyhow::bail!(
                    "--seidel-scale scales the Seidel model's sums: it needs --model seidel (a \
                     traced or baked lens takes its aberrations from its surfaces)"
                )
            }
            Some(list) => {
                let factors = <[f64; 5]>::try_from(list.as_slice()).map_err(|_| {
                    anyhow::anyhow!(
                        "--seidel-scale takes five factors SPHERICAL,COMA,ASTIGMATISM,PETZVAL,\
                         DISTORTION, got {}",
                        list.len()
                    )
                })?;
                AberrationScale::from_array(factors)
                    .map_err(|e| anyhow::anyhow!("--seidel-scale: {e}"))?
            }
        };
        let job = RenderJob {
            model: match self.error_budget_px {
                Some(budget) => ModelChoice::ErrorBudgetPx(budget),
                None => ModelChoice::Model(self.model),
            },
            table: self.table.clone(),
            bake_resolution: self.bake_resolution,
            scene: SceneSpec::parse(&self.scene),
            peel: match self.peel {
                PeelArg::Plain => PeelMode::Plain,
                PeelArg::Umbra => PeelMode::Umbra,
            },
            backend: self.backend.into(),
            settings: RenderSettings {
                width: self.width,
                height: self.height,
                samples_per_pixel: self.spp,
                seed: self.seed,
                max_layers: self.max_layers,
            },
            f_number: self.f_number.or(file_f_number),
            focus,
            film_width_mm: self.film_mm,
            shift_mm: [self.shift_mm.0, self.shift_mm.1],
            tilt_deg: [self.tilt_deg.0, self.tilt_deg.1],
            chromatic: self.chromatic.into(),
            wavelengths_nm,
            postfx_path: match self.postfx {
                PostfxArg::Fast => PostfxPath::Fast,
                PostfxArg::Exact => PostfxPath::Exact,
            },
            layers: self.layers,
            aberration_scale,
            ..RenderJob::new(lens)
        };
        Ok((job, from_file, unasked_focus))
    }
}

pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let png = png_beside(&args.out)?;
    let (job, from_file, unasked_focus) = args.job()?;
    job.settings.check()?;
    for line in &from_file {
        say!("lens file: {line}");
    }
    // A spinner on a terminal only (indicatif hides it elsewhere): a large render is silent
    // for seconds otherwise.
    let progress = super::demo::stage(&format!(
        "rendering {}x{}, {} spp",
        job.settings.width, job.settings.height, job.settings.samples_per_pixel
    ));
    let rendered = job.run();
    progress.finish_and_clear();
    let rendered = rendered.map_err(|error| say_how_to_focus(error, unasked_focus))?;
    // Released only now, so that a render the job refuses prints its error line first.
    super::notes::release();
    print_decisions(&job, &rendered);
    let image = &rendered.image;
    write_exr(image, &args.out)?;
    write_png(image, 1.0, &png)?;
    let camera = &rendered.prepared.camera;
    let peel = &rendered.prepared.peel;
    let frame_ms = rendered.trace_time.as_secs_f64() * 1e3;
    // postfx filters the pinhole layer instead of sampling the lens: no samples, no trace.
    let frame = match &rendered.prepared.kernels {
        Some(prepared) => {
            let kernels = &prepared.kernels;
            let ms = prepared.time.as_secs_f64() * 1e3;
            let how = match &prepared.origin {
                KernelOrigin::Stored(path) => format!("read from {} in {ms:.1} ms", path.display()),
                KernelOrigin::Traced { refused, saved } => {
                    if let Some(why) = refused {
                        say!("note: stored lens kernels not used: {why}");
                    }
                    match saved {
                        Ok(path) => format!("traced in {ms:.1} ms, saved to {}", path.display()),
                        Err(why) => format!("traced in {ms:.1} ms, not saved ({why})"),
                    }
                }
            };
            let filter = match prepared.model {
                ModelKind::Layered => format!("layered filter ({} layers)", job.layers),
                _ => format!("{} filter", job.postfx_path.name()),
            };
            format!(
                "{} lens kernels ({} depths x {} field radii) {how}, {filter} {frame_ms:.1} ms",
                kernels.kernels.len(),
                kernels.inverse_depths.len(),
                kernels.field_tangents.len(),
            )
        }
        None => format!(
            "{} spp, trace {frame_ms:.1} ms",
            job.settings.samples_per_pixel
        ),
    };
    say!(
        "model {}, film centre at z = {:.3} mm, tilt ({:.3}, {:.3}) deg, {} layers ({}x{}): peel \
         {:.1} ms, {frame}",
        rendered.prepared.kind(),
        camera.film_z,
        camera.film.tilt_deg[0],
        camera.film.tilt_deg[1],
        peel.layers,
        peel.view_size[0],
        peel.view_size[1],
        peel.time.as_secs_f64() * 1e3,
    );
    say!("wrote {} and {}", args.out.display(), png.display());
    Ok(())
}

/// A focus nobody asked for that the lens cannot reach (a telescope's front focal point lies
/// kilometres out, beyond render's 2000 mm) is refused saying where the distance came from and
/// which flags set another.
fn say_how_to_focus(error: JobError, unasked_focus: Option<&str>) -> anyhow::Error {
    let cannot_focus = error.cannot_focus().map(|refused| refused.front_focal_mm);
    match (cannot_focus, unasked_focus) {
        (Some(front_focal_mm), Some(origin)) => anyhow::anyhow!(
            "{error}; that distance is {origin}: give --focus-mm farther than \
             {front_focal_mm:.3} or --sensor-mm"
        ),
        _ => error.into(),
    }
}

/// Prints what the job decided, in the order it decided it.
fn print_decisions(job: &RenderJob, rendered: &Rendered) {
    if let FilmSize::ImageCircle { diameter_mm } = rendered.prepared.film_size {
        let film = &rendered.prepared.camera.film;
        say!(
            "film {:.3} x {:.3} mm: the largest frame inside the lens's {diameter_mm:.3} mm image \
             circle, which would light a speck of a full frame (--film-mm sets the width)",
            film.width_mm,
            film.height_mm
        );
    }
    if let Some(triangles) = rendered.prepared.scene.triangles {
        let on = match &rendered.prepared.scene.peeled_on_gpu {
            Some(adapter) => format!("the gpu ({adapter})"),
            None => "the cpu".to_string(),
        };
        say!("scene: {triangles} triangles, peeled on {on}");
    }
    if let Some(focus) = &rendered.prepared.camera.pixel_focus {
        let distance = |mm: f64| match mm.is_finite() {
            true => format!("{mm:.1} mm"),
            false => "infinity".to_string(),
        };
        for (k, p) in focus.surface.points().iter().enumerate() {
            say!(
                "focal surface point {}: pixel ({:.1}, {:.1}) sharp at {} (weight {})",
                k + 1,
                p.pixel[0],
                p.pixel[1],
                distance(p.distance_mm),
                p.weight
            );
        }
        say!(
            "focal surface: beta {}, film plane focused at {} (the image centre), film shifts              {:+.4} to {:+.4} mm along the chief rays",
            focus.surface.beta(),
            distance(focus.reference_mm),
            focus.shift_range_mm[0],
            focus.shift_range_mm[1]
        );
    }
    if let Some(plane) = &rendered.prepared.focus_plane {
        for (k, p) in plane.objects.iter().enumerate() {
            say!(
                "focus point {}: ({:.1}, {:.1}, {:.1}) mm in the lens frame",
                k + 1,
                p[0],
                p[1],
                p[2]
            );
        }
        for (name, (p, blur)) in ["real-ray", "paraxial"]
            .iter()
            .zip(plane.compared.iter().flatten())
        {
            say!(
                "{name} focus plane: tilt ({:.3}, {:.3}) deg, centre at z = {:.3} mm; RMS spot \
                 radius of the three points {:.1}, {:.1}, {:.1} um",
                p.tilt_deg[0],
                p.tilt_deg[1],
                p.film_z,
                blur[0],
                blur[1],
                blur[2]
            );
        }
        let placement = &plane.placement;
        say!(
            "sensor tilt ({:.3}, {:.3}) deg, sensor centre {:.3} mm behind the first vertex",
            placement.tilt_deg[0],
            placement.tilt_deg[1],
            placement.film_z
        );
    }
    if let (Some(budget), ModelChoice::ErrorBudgetPx(budget_px)) =
        (&rendered.prepared.budget, job.model)
    {
        if budget.film_corner_mm > budget.full_film_radius_mm {
            say!(
                "note: the film corner ({:.3} mm off the axis) lies beyond the largest \
                 traceable field ({:.3} mm); the budget covers the field up to there",
                budget.film_corner_mm,
                budget.full_film_radius_mm
            );
        }
        let choice = &budget.choice;
        say!(
            "model: {} (the cheapest within {budget_px} px at this render's pixel pitch: film \
             radius {:.3} mm, f/{:.3}, focus {}, nearest surface {})",
            choice.label,
            choice.domain.film_radius,
            choice.domain.f_number,
            budget
                .focus_mm
                .map_or("infinity".into(), |d| format!("{d:.1} mm")),
            budget
                .nearest_mm
                .map_or("far".into(), |d| format!("{d:.1} mm"))
        );
        say!("predicted error: {:.3} px (p99)", choice.predicted_px);
        say!(
            "measured error: {:.3} px (p99 against the exact trace on fresh rays of the domain)",
            choice.measured_px
        );
    }
    let chromatic = &rendered.prepared.chromatic;
    let why = match chromatic.reason {
        ChromaticReason::Off => None,
        ChromaticReason::SeidelModel => Some("the Seidel model is monochrome".to_string()),
        ChromaticReason::RealtimeModel(kind) => {
            Some(format!("the {kind} model's lens kernels are monochrome"))
        }
        ChromaticReason::IdealLens => Some("ideal lens".to_string()),
        ChromaticReason::Spread {
            lateral_px,
            axial_blur_px,
            disperses,
        } => Some(format!(
            "lateral colour {lateral_px:.2} px, axial colour blur {axial_blur_px:.2} px{}",
            if disperses {
                ""
            } else {
                "; the lens does not disperse"
            }
        )),
    };
    match (chromatic.wavelengths_nm, why) {
        (Some(nm), Some(why)) => {
            let nm = nm.map(|w| format!("{w:.1}")).join("/");
            say!("chromatic: on, R/G/B at {nm} nm ({why})");
        }
        (_, Some(why)) => say!("chromatic: off ({why})"),
        (_, None) => say!("chromatic: off"),
    }
    if let Some(table) = &rendered.prepared.table {
        if table.baked_now {
            say!("baked {}", table.dir.display());
        }
        let (covered, needed) = (table.covered_film_radius_mm, table.needed_film_radius_mm);
        if covered < needed * (1.0 - 1e-9) {
            say!(
                "note: table {} covers film radii to {covered:.3} mm, this sensor reaches \
                 {needed:.3} mm: rays from beyond render black (rebake into another --table)",
                table.dir.display()
            );
        }
    }
    if let Some((peel, surfels)) = rendered.prepared.peel.mesh {
        say!(
            "peeled {} layers ({peel:?}, cap {}), {surfels} surfels",
            rendered.prepared.peel.layers,
            job.settings.max_layers
        );
    }
    say!("{}", backend_line(&rendered.backend));
}

/// `backend: gpu (<adapter>)`, `backend: cpu (<why no GPU>)` or `backend: cpu`.
pub fn backend_line(backend: &BackendUsed) -> String {
    match backend {
        BackendUsed::Gpu { adapter } => format!("backend: gpu ({adapter})"),
        BackendUsed::Cpu {
            gpu_unavailable: Some(why),
        } => format!("backend: cpu ({why})"),
        BackendUsed::Cpu {
            gpu_unavailable: None,
        } => "backend: cpu".to_string(),
    }
}
