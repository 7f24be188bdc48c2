//! `lensbake wavefront`, `lensbake mtf` and `lensbake psf`: wave optics of one field point.

use super::lens::{AimingArg, ReadArgs};
use anyhow::{Context, bail};
use clap::Args;
use lensbake::glass::D_LINE_NM;
use lensbake::system::LensSystem;
use lensbake::wave::{
    DEFAULT_MTF_FREQUENCIES, FieldTrace, PupilTrace, Sampling, Spectrum, WaveLens, WaveOptions,
    ZernikeOrdering, fft_assumptions, frequencies_to, huygens_psf, psf, zernike_fit,
};
use lensbake::{lenses, limits};
use serde_json::json;
use std::path::PathBuf;

/// The lens, field, aperture, spectrum and sampling every wave command takes.
#[derive(Args, Debug)]
pub struct WaveArgs {
    /// A lens file, a bundled lens name, or `ideal:<EFL_MM>` for an aberration-free lens.
    #[arg(value_name = "LENS")]
    pub lens: String,
    #[command(flatten)]
    pub read: ReadArgs,
    /// Half-field angle in degrees, field in the y-z plane: for a finite object, the angle its
    /// point's chief ray makes at the entrance-pupil centre.
    #[arg(long, allow_negative_numbers = true)]
    pub field_deg: f64,
    /// Object distance from the first vertex in mm [default: infinity], negative for a virtual
    /// object; the image plane is its paraxial conjugate.
    #[arg(long, allow_negative_numbers = true)]
    pub object_distance_mm: Option<f64>,
    /// Entrance-pupil diameter in mm [default: the stop's clear aperture imaged to object space].
    #[arg(long, allow_negative_numbers = true, conflicts_with = "f_number")]
    pub epd_mm: Option<f64>,
    /// f-number EFL / EPD [default: wide open; f/2.8 for `ideal:`].
    #[arg(long, allow_negative_numbers = true)]
    pub f_number: Option<f64>,
    /// Wavelength in nm; repeat it (with --weight) for a polychromatic analysis, the first being
    /// the reference [default: the lens's design wavelength, 587.56 nm for `ideal:`].
    #[arg(long, allow_negative_numbers = true)]
    pub wavelength_nm: Vec<f64>,
    /// Spectral weight of each --wavelength-nm, in the same order [default: all 1].
    #[arg(long, allow_negative_numbers = true)]
    pub weight: Vec<f64>,
    /// Pupil samples per side.
    #[arg(long, default_value_t = lensbake::wave::DEFAULT_SAMPLES)]
    pub samples: usize,
    /// FFT grid per side (at least twice --samples).
    #[arg(long, default_value_t = lensbake::wave::DEFAULT_GRID)]
    pub grid: usize,
    /// How a pupil sample becomes a real ray: at that point of the paraxial entrance pupil, or
    /// through that point of the stop [default: the lens file's (Zemax RAIM), else paraxial].
    #[arg(long, value_enum)]
    pub ray_aiming: Option<AimingArg>,
}

#[derive(Args, Debug)]
pub struct WavefrontArgs {
    #[command(flatten)]
    pub wave: WaveArgs,
    /// Zernike ordering: fringe (37 terms, unnormalised) or standard (Noll, RMS-normalised).
    #[arg(long, default_value = "fringe")]
    pub zernike: String,
    /// Number of Zernike terms fitted.
    #[arg(long, default_value_t = 37)]
    pub terms: usize,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct MtfArgs {
    #[command(flatten)]
    pub wave: WaveArgs,
    /// Frequencies in cycles/mm [default: 41 from 0 to the diffraction cutoff].
    #[arg(long)]
    pub frequency: Vec<f64>,
    /// Image-plane shift from the paraxial image, mm (positive away from the lens).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub defocus_mm: f64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct PsfArgs {
    #[command(flatten)]
    pub wave: WaveArgs,
    /// Output image: .exr (linear float, 1 = the aberration-free peak) or .png (16-bit grey,
    /// scaled to this PSF's peak).
    #[arg(long)]
    pub out: PathBuf,
    /// Sum one wavelet per pupil sample along its real exit direction instead of the FFT (for
    /// pupils whose exit directions are not an affine map of the pupil grid).
    #[arg(long)]
    pub huygens: bool,
}

/// A lens resolved from its argument.
enum Subject {
    Real {
        name: String,
        system: Box<LensSystem>,
    },
    Ideal {
        efl_mm: f64,
    },
}

/// Everything a wave command needs, resolved and checked.
struct Setup {
    name: String,
    subject: Subject,
    options: WaveOptions,
    spectrum: Spectrum,
    sampling: Sampling,
}

impl Setup {
    fn new(args: &WaveArgs) -> anyhow::Result<Setup> {
        if !(args.field_deg.is_finite() && args.field_deg.abs() < 90.0) {
            bail!(
                "--field-deg must be an angle below 90 degrees, got {}",
                args.field_deg
            );
        }
        // The limits every other command applies (f/0.5 is the fastest cone a lens in air
        // can form), so a tiny pupil cannot shrink the wave grids' lag step to nothing.
        if let Some(epd) = args.epd_mm {
            limits::check_length("--epd-mm", epd)?;
        }
        if let Some(f_number) = args.f_number {
            limits::check_range("--f-number", f_number, 0.5, limits::MAX_F_NUMBER)?;
        }
        let object_distance_mm = args
            .object_distance_mm
            .map(|d| limits::object_distance("--object-distance-mm", d))
            .transpose()?
            .flatten();
        let (name, subject) = match args.lens.strip_prefix("ideal:") {
            Some(_) if args.object_distance_mm.is_some() => bail!(
                "an ideal lens (`ideal:`) images an object at infinity: leave out \
                 --object-distance-mm"
            ),
            Some(_) if args.ray_aiming.is_some() => {
                bail!("an ideal lens (`ideal:`) has no stop to aim rays at: leave out --ray-aiming")
            }
            Some(efl) => {
                let efl_mm: f64 = efl
                    .parse()
                    .ok()
                    .filter(|f: &f64| f.is_finite() && *f > 0.0)
                    .with_context(|| {
                        format!(
                            "`{}`: expected ideal:<EFL_MM> with a positive focal length",
                            args.lens
                        )
                    })?;
                (args.lens.clone(), Subject::Ideal { efl_mm })
            }
            None => {
                let lens = lenses::load(&args.lens, &args.read.options())?;
                super::lens::note_reading(&lens.source);
                let name = lens.source.origin.name();
                (
                    name.clone(),
                    Subject::Real {
                        name,
                        system: Box::new(lens.system),
                    },
                )
            }
        };
        if !args.weight.is_empty() && args.weight.len() != args.wavelength_nm.len().max(1) {
            bail!(
                "--weight given {} times for {} wavelengths: give one per --wavelength-nm",
                args.weight.len(),
                args.wavelength_nm.len().max(1)
            );
        }
        let options = WaveOptions {
            field_deg: args.field_deg,
            wavelengths_nm: args.wavelength_nm.clone(),
            weights: args.weight.clone(),
            epd_mm: args.epd_mm,
            f_number: args.f_number,
            object_distance_mm,
            ray_aiming: args.ray_aiming.map(Into::into),
            sampling: Sampling {
                samples: args.samples,
                grid: args.grid,
            },
            defocus_mm: 0.0,
        };
        let spectrum = match &subject {
            Subject::Real { system, .. } => options.spectrum(system)?,
            Subject::Ideal { .. } => {
                Spectrum::or_default(&options.wavelengths_nm, &options.weights, D_LINE_NM)?
            }
        };
        let sampling = options.sampling.checked()?;
        Ok(Setup {
            name,
            subject,
            options,
            spectrum,
            sampling,
        })
    }

    fn lens(&self) -> anyhow::Result<WaveLens<'_>> {
        Ok(match &self.subject {
            Subject::Ideal { efl_mm } => WaveLens::Ideal {
                efl_mm: *efl_mm,
                f_number: match (self.options.f_number, self.options.epd_mm) {
                    (Some(n), _) => n,
                    (None, Some(epd)) => efl_mm / epd,
                    (None, None) => IDEAL_F_NUMBER,
                },
            },
            Subject::Real { name, system } => self
                .options
                .lens(system)
                .with_context(|| format!("{name}: the beam"))?,
        })
    }

    fn trace(&self) -> anyhow::Result<FieldTrace> {
        FieldTrace::new(
            &self.lens()?,
            self.options.field_deg,
            &self.spectrum,
            self.sampling,
        )
        .with_context(|| format!("{} at {}°", self.name, self.options.field_deg))
    }

    fn monochromatic(&self, command: &str) -> anyhow::Result<PupilTrace> {
        if self.spectrum.wavelengths_nm.len() > 1 {
            bail!("`{command}` takes one --wavelength-nm; `mtf` and `psf` take several");
        }
        Ok(self.trace()?.traces.remove(0))
    }
}

/// The f-number of an `ideal:` lens when none is given (the renderer's default too).
const IDEAL_F_NUMBER: f64 = 2.8;

pub fn run_wavefront(args: WavefrontArgs) -> anyhow::Result<()> {
    let ordering = match args.zernike.as_str() {
        "fringe" => ZernikeOrdering::Fringe,
        "standard" => ZernikeOrdering::Standard,
        other => bail!("--zernike must be fringe or standard, got {other:?}"),
    };
    let setup = Setup::new(&args.wave)?;
    let trace = setup.monochromatic("wavefront")?;
    let map = trace.wavefront(0.0)?;
    let stats = map.stats();
    let zernike = zernike_fit(&map, ordering, args.terms)?;
    let assumptions = fft_assumptions(&map, setup.sampling.grid);
    if args.json {
        let value = json!({
            "lens": setup.name,
            "field_deg": setup.options.field_deg,
            "wavelength_nm": map.wavelength_nm,
            "sampling": setup.sampling,
            "rms_waves": stats.rms_waves,
            "pv_waves": stats.pv_waves,
            "strehl": stats.strehl,
            "pupil_samples": stats.pupil_samples,
            "transmitted_samples": stats.transmitted_samples,
            "reference_sphere": {
                "centre_mm": map.reference_point_mm,
                "radius_mm": map.reference_radius_mm,
            },
            "zernike": zernike,
            "fft_assumptions_broken": assumptions,
        });
        say!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    say!(
        "{}  field {}°  {} nm  ({} x {} pupil samples, {} transmitted)",
        setup.name,
        setup.options.field_deg,
        map.wavelength_nm,
        map.samples,
        map.samples,
        stats.transmitted_samples
    );
    say!(
        "  RMS wavefront error   {:.4} waves (piston removed)",
        stats.rms_waves
    );
    say!("  peak to valley        {:.4} waves", stats.pv_waves);
    say!("  Strehl ratio          {:.4}", stats.strehl);
    say!("  Zernike ({:?}), waves:", zernike.ordering);
    for term in zernike.terms.iter().filter(|t| t.waves.abs() >= 5e-4) {
        say!(
            "    Z{:<3} n={:<2} m={:<3} {:>10.4}",
            term.j,
            term.n,
            term.m,
            term.waves
        );
    }
    say!(
        "  fit residual RMS      {:.4} waves",
        zernike.residual_rms_waves
    );
    print_assumptions(&assumptions);
    Ok(())
}

fn print_assumptions(assumptions: &[lensbake::wave::FftAssumption]) {
    for a in assumptions {
        note!("the FFT's assumptions fail here: {a}");
    }
}

pub fn run_mtf(args: MtfArgs) -> anyhow::Result<()> {
    let setup = Setup::new(&args.wave)?;
    if !args.defocus_mm.is_finite() {
        bail!(
            "--defocus-mm must be a finite number, got {}",
            args.defocus_mm
        );
    }
    for &f in &args.frequency {
        if !(f.is_finite() && f >= 0.0) {
            bail!("--frequency must be zero or positive, got {f}");
        }
    }
    let trace = setup.trace()?;
    let frequencies = if args.frequency.is_empty() {
        frequencies_to(trace.reference().cutoff_per_mm, DEFAULT_MTF_FREQUENCIES)
    } else {
        args.frequency.clone()
    };
    let mtf = trace.mtf(args.defocus_mm, &frequencies)?;
    let geometric = trace.geometric_mtf(args.defocus_mm, &frequencies)?;
    let reference_map = trace.reference().wavefront(args.defocus_mm)?;
    let assumptions = fft_assumptions(&reference_map, setup.sampling.grid);
    if args.json {
        let value = json!({
            "lens": setup.name,
            "field_deg": setup.options.field_deg,
            "wavelengths_nm": setup.spectrum.wavelengths_nm,
            "weights": setup.spectrum.weights,
            "defocus_mm": args.defocus_mm,
            "sampling": setup.sampling,
            "cutoff_per_mm": mtf.cutoff_per_mm,
            "frequencies_per_mm": mtf.frequencies_per_mm,
            "tangential": mtf.tangential,
            "sagittal": mtf.sagittal,
            "diffraction_limit": mtf.diffraction_limit,
            "geometric": {"tangential": geometric.tangential, "sagittal": geometric.sagittal},
            "fft_assumptions_broken": assumptions,
        });
        say!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    say!(
        "{}  field {}°  cutoff {:.1} cycles/mm",
        setup.name,
        setup.options.field_deg,
        mtf.cutoff_per_mm
    );
    say!("  cycles/mm  tangential  sagittal  diffraction limit");
    for (i, frequency) in frequencies.iter().enumerate() {
        say!(
            "  {:>9.2}  {:>10.4}  {:>8.4}  {:>17.4}",
            frequency,
            mtf.tangential[i],
            mtf.sagittal[i],
            mtf.diffraction_limit[i]
        );
    }
    print_assumptions(&assumptions);
    Ok(())
}

pub fn run_psf(args: PsfArgs) -> anyhow::Result<()> {
    let setup = Setup::new(&args.wave)?;
    let extension = args
        .out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let exr = match extension.as_deref() {
        Some("exr") => true,
        Some("png") => false,
        _ => bail!("{}: the PSF is written as .exr or .png", args.out.display()),
    };
    let field = setup.trace()?;
    let map = field.reference().wavefront(0.0)?;
    let image = if setup.spectrum.wavelengths_nm.len() > 1 {
        if args.huygens {
            bail!("--huygens computes one wavelength; give one --wavelength-nm");
        }
        print_assumptions(&fft_assumptions(&map, setup.sampling.grid));
        field.psf(0.0, setup.sampling.grid)?
    } else if args.huygens {
        let fft = psf(&map, setup.sampling.grid)?;
        huygens_psf(&map, fft.size, fft.pixel_mm)?
    } else {
        print_assumptions(&fft_assumptions(&map, setup.sampling.grid));
        psf(&map, setup.sampling.grid)?
    };
    let bytes = if exr {
        encode_exr(&image)?
    } else {
        encode_png(&image)?
    };
    lensbake::output::write_bytes(&args.out, &bytes)?;
    say!(
        "{}: {} x {} PSF, pixel {:.3} x {:.3} µm, peak {:.4} (Strehl {:.4} at {} nm)",
        args.out.display(),
        image.size,
        image.size,
        image.pixel_mm[0] * 1e3,
        image.pixel_mm[1] * 1e3,
        image.peak(),
        map.stats().strehl,
        map.wavelength_nm
    );
    Ok(())
}

/// Image rows run top (largest y) to bottom; the PSF's rows run up from the smallest y.
fn image_value(psf: &lensbake::wave::Psf, x: usize, y: usize) -> f64 {
    psf.intensity[(psf.size - 1 - y) * psf.size + x]
}

fn encode_exr(psf: &lensbake::wave::Psf) -> anyhow::Result<Vec<u8>> {
    use exr::prelude::*;
    let size = psf.size;
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_encoded_channels(
        (size, size),
        lensbake::output::reproducible_exr_encoding(),
        SpecificChannels::build()
            .with_channel("Y")
            .with_pixel_fn(|position: Vec2<usize>| {
                (image_value(psf, position.0, position.1) as f32,)
            }),
    )
    .write()
    .to_buffered(&mut bytes)
    .context("encoding the PSF as OpenEXR")?;
    Ok(bytes.into_inner())
}

fn encode_png(psf: &lensbake::wave::Psf) -> anyhow::Result<Vec<u8>> {
    let size = psf.size;
    let peak = psf.peak().max(f64::MIN_POSITIVE);
    let mut samples = Vec::with_capacity(size * size * 2);
    for y in 0..size {
        for x in 0..size {
            let level = (image_value(psf, x, y) / peak * 65535.0)
                .round()
                .clamp(0.0, 65535.0) as u16;
            samples.extend_from_slice(&level.to_be_bytes());
        }
    }
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, size as u32, size as u32);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Sixteen);
        let mut writer = encoder.write_header().context("encoding the PSF as PNG")?;
        writer
            .write_image_data(&samples)
            .context("encoding the PSF as PNG")?;
    }
    Ok(bytes)
}
