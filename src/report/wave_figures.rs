//! The wave-optics plots of a report, filled from [`crate::wave`].

use super::figures::{FigureError, FigureOptions, Spectrum as Drawn};
use crate::plot::{
    FanCurve, FanField, Grid, MtfField, MtfFieldPlot, MtfPlot, OpdFanPlot, PsfPlot,
    ThroughFocusPlot, WavefrontMapPlot,
};
use crate::system::LensSystem;
use crate::wave::{
    FieldTrace, Sampling, Spectrum, WaveError, WaveLens, frequencies_to, mtf_across_field, psf,
};

/// Odd pupil sampling for the fans and maps, so the pupil's centre lines are sampled.
const FAN_SAMPLING: Sampling = Sampling {
    samples: 65,
    grid: 256,
};
/// Steps of the search, from the design field down, for the largest field the wave analysis
/// reaches (its chief ray may be vignetted at the design field).
const FIELD_SEARCH_STEPS: usize = 40;
/// Points of the MTF curves, from 0 to the cutoff.
const MTF_POINTS: usize = 41;
/// Fields of the MTF-across-field curves (axis and edge included).
const FIELD_POINTS: usize = 12;
/// Frequencies of the MTF-across-field curves and the through-focus frequency, as fractions
/// of the cutoff.
const FIELD_FREQUENCIES: [f64; 3] = [0.125, 0.25, 0.5];
const THROUGH_FOCUS_FREQUENCY: f64 = 0.25;
/// Half-range of the through-focus scan in units of λ N_w² (eight times the Rayleigh quarter
/// wave depth of focus, ±2 λ N²) and its steps.
const THROUGH_FOCUS_HALF_RANGE: f64 = 8.0;
const THROUGH_FOCUS_STEPS: usize = 33;
/// PSF pixels shown per side (the centre of the FFT grid).
const PSF_CROP: usize = 96;

/// The lens, its spectrum with equal weights, and the fields the wave plots draw.
struct WaveSet<'a> {
    lens: WaveLens<'a>,
    spectrum: Spectrum,
    label: String,
    fields: Vec<f64>,
}

impl<'a> WaveSet<'a> {
    fn new(system: &'a LensSystem, options: &FigureOptions) -> Result<WaveSet<'a>, FigureError> {
        let conditions = options.conditions(system)?;
        let drawn = Drawn::of(&conditions);
        let reference = drawn
            .drawn_nm
            .iter()
            .position(|&w| w == drawn.reference_nm)
            .unwrap_or(0);
        let spectrum = Spectrum::new(
            drawn.drawn_nm.clone(),
            vec![1.0; drawn.drawn_nm.len()],
            reference,
        )
        .map_err(FigureError::Wave)?;
        let label = match spectrum.wavelengths_nm.as_slice() {
            [one] => format!("{one:.1} nm"),
            many => format!(
                "{} nm, equal weights",
                many.iter()
                    .map(|w| format!("{w:.1}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        let lens = WaveLens::Real {
            system,
            epd_mm: Some(conditions.epd_mm),
            object_distance_mm: conditions.object_distance_mm,
            ray_aiming: conditions.ray_aiming,
        };
        let probe = Sampling {
            samples: 16,
            grid: 32,
        };
        // Every drawn field and wavelength must trace, or a whole plot would be lost: the
        // design fields shrink together until they all do (the plots' titles give the fields
        // drawn).
        let traces_at = |scale: f64| -> Result<(), WaveError> {
            conditions.fields_deg.iter().try_for_each(|f| {
                FieldTrace::new(&lens, f * scale, &spectrum, probe)
                    .and_then(|t| t.wavefronts(0.0).map(|_| ()))
            })
        };
        // When no scale traces, the reason is the one at the smallest (on axis): a lens wave
        // optics cannot take says so there, as a lens that passes no light does.
        let mut failure = WaveError::NoLight { field_deg: 0.0 };
        let scale = (0..=FIELD_SEARCH_STEPS)
            .map(|i| 1.0 - i as f64 / FIELD_SEARCH_STEPS as f64)
            .find(|&scale| traces_at(scale).map_err(|e| failure = e).is_ok())
            .ok_or(FigureError::Wave(failure))?;
        Ok(WaveSet {
            lens,
            label,
            fields: conditions.fields_deg.iter().map(|f| f * scale).collect(),
            spectrum,
        })
    }

    fn trace(&self, field_deg: f64, sampling: Sampling) -> Result<FieldTrace, FigureError> {
        FieldTrace::new(&self.lens, field_deg, &self.spectrum, sampling).map_err(FigureError::Wave)
    }

    fn cutoff(&self) -> Result<f64, FigureError> {
        Ok(self
            .trace(0.0, Sampling::default())?
            .reference()
            .cutoff_per_mm)
    }
}

pub(super) fn opd_fan_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<OpdFanPlot, FigureError> {
    let set = WaveSet::new(system, options)?;
    let n = FAN_SAMPLING.samples;
    let centre = n / 2;
    let coordinate = |k: usize| -1.0 + 2.0 * k as f64 / (n - 1) as f64;
    let mut fields = Vec::new();
    for field_deg in set.fields.clone() {
        let trace = set.trace(field_deg, FAN_SAMPLING)?;
        let mut field = FanField {
            field_deg,
            tangential: Vec::new(),
            sagittal: Vec::new(),
            dropped_nm: Vec::new(),
        };
        for (map, _) in trace.wavefronts(0.0).map_err(FigureError::Wave)? {
            let cut = |index: &dyn Fn(usize) -> usize| FanCurve {
                wavelength_nm: map.wavelength_nm,
                points: (0..n)
                    .filter_map(|k| map.opd_waves[index(k)].map(|w| (coordinate(k), w)))
                    .collect(),
            };
            field.tangential.push(cut(&|k| k * n + centre));
            field.sagittal.push(cut(&|k| centre * n + k));
        }
        fields.push(field);
    }
    Ok(OpdFanPlot {
        lens: lens.to_string(),
        fields,
    })
}

pub(super) fn wavefront_map_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<WavefrontMapPlot, FigureError> {
    let set = WaveSet::new(system, options)?;
    let trace = set.trace(set.fields[0], FAN_SAMPLING)?;
    let map = trace
        .reference()
        .wavefront(0.0)
        .map_err(FigureError::Wave)?;
    let stats = map.stats();
    let n = map.samples;
    let pitch = 2.0 / (n - 1) as f64;
    Ok(WavefrontMapPlot {
        lens: lens.to_string(),
        field_deg: map.field_deg,
        wavelength_nm: map.wavelength_nm,
        rms_waves: stats.rms_waves,
        pv_waves: stats.pv_waves,
        opd: Grid {
            size: n,
            origin: (-1.0, -1.0),
            pitch: (pitch, pitch),
            values: map.opd_waves,
        },
    })
}

pub(super) fn psf_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<PsfPlot, FigureError> {
    let set = WaveSet::new(system, options)?;
    let sampling = Sampling::default();
    let trace = set.trace(set.fields[0], sampling)?;
    let map = trace
        .reference()
        .wavefront(0.0)
        .map_err(FigureError::Wave)?;
    let image = psf(&map, sampling.grid).map_err(FigureError::Wave)?;
    let start = (image.size - PSF_CROP) / 2;
    let values = (0..PSF_CROP * PSF_CROP)
        .map(|i| Some(image.intensity[(start + i / PSF_CROP) * image.size + start + i % PSF_CROP]))
        .collect();
    let corner = image.position(start, start);
    Ok(PsfPlot {
        lens: lens.to_string(),
        field_deg: map.field_deg,
        wavelength_nm: map.wavelength_nm,
        strehl: map.stats().strehl,
        intensity: Grid {
            size: PSF_CROP,
            origin: (corner[0] * 1e3, corner[1] * 1e3),
            pitch: (image.pixel_mm[0] * 1e3, image.pixel_mm[1] * 1e3),
            values,
        },
    })
}

pub(super) fn mtf_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<MtfPlot, FigureError> {
    let set = WaveSet::new(system, options)?;
    let frequencies = frequencies_to(set.cutoff()?, MTF_POINTS);
    let mut fields = Vec::new();
    let mut diffraction_limit = Vec::new();
    for field_deg in set.fields.clone() {
        let mtf = set
            .trace(field_deg, Sampling::default())?
            .mtf(0.0, &frequencies)
            .map_err(FigureError::Wave)?;
        diffraction_limit = frequencies
            .iter()
            .copied()
            .zip(mtf.diffraction_limit.iter().copied())
            .collect();
        fields.push(MtfField {
            field_deg,
            frequencies_per_mm: mtf.frequencies_per_mm,
            tangential: mtf.tangential,
            sagittal: mtf.sagittal,
        });
    }
    Ok(MtfPlot {
        lens: lens.to_string(),
        spectrum: set.label,
        fields,
        diffraction_limit,
    })
}

pub(super) fn through_focus_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<ThroughFocusPlot, FigureError> {
    let set = WaveSet::new(system, options)?;
    let axis = set.trace(0.0, Sampling::default())?;
    let cutoff = axis.reference().cutoff_per_mm;
    let frequency = (THROUGH_FOCUS_FREQUENCY * cutoff).round().max(1.0);
    // λ N_w² from the cutoff 1 / (λ N_w): the depth-of-focus scale.
    let wavelength_mm = axis.reference().wavelength_nm * 1e-6;
    let f_number = 1.0 / (wavelength_mm * cutoff);
    let half = THROUGH_FOCUS_HALF_RANGE * wavelength_mm * f_number * f_number;
    let defocus: Vec<f64> = (0..THROUGH_FOCUS_STEPS)
        .map(|i| -half + 2.0 * half * i as f64 / (THROUGH_FOCUS_STEPS - 1) as f64)
        .collect();
    let mut fields = Vec::new();
    for field_deg in set.fields.clone() {
        let curve = set
            .trace(field_deg, Sampling::default())?
            .through_focus(frequency, &defocus)
            .map_err(FigureError::Wave)?;
        fields.push((
            field_deg,
            defocus
                .iter()
                .zip(curve.tangential.iter().zip(&curve.sagittal))
                .map(|(&z, (&t, &s))| (z, t, s))
                .collect(),
        ));
    }
    Ok(ThroughFocusPlot {
        lens: lens.to_string(),
        spectrum: set.label,
        frequency_per_mm: frequency,
        fields,
    })
}

pub(super) fn mtf_field_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<MtfFieldPlot, FigureError> {
    let set = WaveSet::new(system, options)?;
    let cutoff = set.cutoff()?;
    let frequencies: Vec<f64> = FIELD_FREQUENCIES
        .iter()
        .map(|f| (f * cutoff).round().max(1.0))
        .collect();
    let fields: Vec<f64> = (0..FIELD_POINTS)
        .map(|i| set.fields[0] * i as f64 / (FIELD_POINTS - 1) as f64)
        .collect();
    let across = mtf_across_field(
        &set.lens,
        &fields,
        &set.spectrum,
        Sampling::default(),
        &frequencies,
    );
    Ok(MtfFieldPlot {
        lens: lens.to_string(),
        spectrum: set.label,
        frequencies: frequencies
            .iter()
            .enumerate()
            .map(|(k, &f)| {
                (
                    f,
                    across
                        .fields
                        .iter()
                        .map(|p| (p.field_deg, p.tangential[k], p.sagittal[k]))
                        .collect(),
                )
            })
            .collect(),
    })
}
