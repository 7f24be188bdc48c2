//! Chromatic aberration: each colour channel traced at its own wavelength (seed 004: lens rays
//! for the dominant wavelengths of R, G and B).
//!
//! A chromatic render keeps the monochrome camera (its model at the design wavelength places the
//! film, the eye and the layers) and adds one lens per channel, of the same kind:
//! - thin: the same plane and aperture with the focal length at the channel's wavelength;
//! - thick: focal length, principal planes and pupils at the wavelength;
//! - traced: every surface's indices at the wavelength (the stop stays one physical opening);
//! - baked: the table layer baked at the wavelength.
//!
//! The film stays where the design wavelength focuses, so axial colour shows as a per-channel
//! blur and lateral colour as a per-channel shift. Each lens sample (one film point, one pupil
//! point) traces one ray per channel, drawn from a pupil that bounds all three channels' pupils,
//! so every channel is sampled conservatively and with the same strata: up to three times the
//! rays, and no colour noise where the channels agree.

use super::RenderError;
use super::camera::Camera;
use crate::glass::{C_LINE_NM, F_LINE_NM};
use crate::model::{
    BakedLens, FirstOrderModels, LensModel, ParaxialLens, PupilSampling, TracedLens,
    fit_effective_pupil, layer_at,
};
use crate::pupil::{PupilCircle, PupilTable};
use crate::system::LensSystem;

/// Colour channels of a chromatic render, in order R, G, B.
pub const CHANNELS: usize = 3;

/// A paraxial channel passes a ray whose squared distance from the exit-pupil centre is at most
/// the squared radius times 1 + this. The sampling pupil of identical channels is the channel
/// pupil itself, so its rim samples sit on the rim to rounding: f32 rounds the crossing by a few
/// 1e-7 relative, and a rim rejected by rounding would darken a thin or thick render by the rim's
/// share. The tolerance widens the pupil by 5e-6 of its radius, far below a pixel.
pub const PUPIL_EDGE_TOLERANCE: f64 = 1e-5;

/// Colour fringes narrower than this many output pixels are not rendered per channel by
/// `--chromatic auto`. Half a pixel: a fringe that wide tints the pixel column along an edge by
/// up to half the edge's contrast, which is visible on a high-contrast edge; below it the tint
/// drops under the 8-bit step of a typical edge after tone mapping.
pub const VISIBLE_COLOUR_PX: f64 = 0.5;

/// Wavelengths of R, G and B when none are given: the C line, the design wavelength and the F
/// line. C and F are the lines lens designers correct colour for (the Abbe number and the
/// `analyze` report's axial and lateral colour use them), so the fringes rendered are the ones
/// the lens's quoted colour correction predicts; G at the design wavelength keeps the green
/// channel identical to the monochrome render.
pub fn default_wavelengths(system: &LensSystem) -> [f64; CHANNELS] {
    [C_LINE_NM, system.design_wavelength_nm(), F_LINE_NM]
}

/// Whether a render traces its colour channels at their own wavelengths.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChromaticMode {
    On,
    Off,
    /// On when the lens disperses and its colour spread reaches [`VISIBLE_COLOUR_PX`].
    Auto,
}

/// Each channel's lens, of the kind of the camera's model.
#[derive(Clone, Debug, PartialEq)]
pub enum ChannelLenses {
    /// Thin or thick lenses at each wavelength.
    Paraxial([ParaxialLens; CHANNELS]),
    /// The lens traced at each wavelength.
    Traced(Box<[TracedLens; CHANNELS]>),
    /// The layer of the camera's table that each channel reads.
    Baked([usize; CHANNELS]),
}

/// The per-channel lenses of a chromatic render and the pupil all three are sampled from.
#[derive(Clone, Debug, PartialEq)]
pub struct Chromatic {
    pub wavelengths_nm: [f64; CHANNELS],
    pub lenses: ChannelLenses,
    /// Contains every channel's pupil (see [`union_of`] and [`Chromatic::paraxial`]).
    pub sampling: PupilSampling,
}

fn check_wavelengths(
    system: &LensSystem,
    wavelengths_nm: [f64; CHANNELS],
) -> Result<(), RenderError> {
    for nm in wavelengths_nm {
        if !(nm.is_finite() && nm > 0.0) {
            return Err(RenderError::InvalidSetting(format!(
                "wavelength {nm} nm: wavelengths must be positive numbers of nm"
            )));
        }
        system
            .at_checked(nm)
            .map_err(|e| RenderError::InvalidSetting(format!("cannot render at {nm} nm: {e}")))?;
    }
    Ok(())
}

impl Chromatic {
    /// The chromatic form of `camera` (built at the design wavelength of `system`, with
    /// `first_order` its first-order models): channels of the camera's model kind at
    /// `wavelengths_nm`. A traced camera fits each channel's effective pupil at `pupil_nodes`
    /// film radii.
    pub fn for_camera(
        camera: &Camera,
        system: &LensSystem,
        first_order: &FirstOrderModels,
        wavelengths_nm: [f64; CHANNELS],
        pupil_nodes: usize,
    ) -> Result<Chromatic, RenderError> {
        let film_radius = camera.film_corner_radius();
        match &camera.model {
            LensModel::Thin(_) | LensModel::Thick(_) => Chromatic::paraxial(
                system,
                first_order,
                matches!(camera.model, LensModel::Thin(_)),
                wavelengths_nm,
                camera.film_z,
                film_radius,
            ),
            LensModel::Traced(_) => Chromatic::traced(
                system,
                first_order,
                wavelengths_nm,
                camera.film_z,
                film_radius,
                pupil_nodes,
            ),
            LensModel::Baked(lens) => Chromatic::baked(lens, wavelengths_nm),
            // Its Seidel sums hold the design wavelength alone; a channel per wavelength would
            // need the chromatic sums as well.
            LensModel::Seidel(_) => Err(RenderError::InvalidSetting(
                "a chromatic render needs the thin, thick, traced or baked model: the Seidel \
                 model's sums hold the design wavelength only"
                    .into(),
            )),
        }
    }

    /// Thin (`thin`) or thick channels from the paraxial data at each wavelength, for a film at
    /// `film_z` reaching `max_film_radius` from the axis. Samples are drawn on the design exit
    /// pupil's plane from an axial disc containing every channel's exit pupil as seen from
    /// every film point ([`sampling_radius`]); each channel then passes only the rays inside its
    /// own exit pupil.
    pub fn paraxial(
        system: &LensSystem,
        first_order: &FirstOrderModels,
        thin: bool,
        wavelengths_nm: [f64; CHANNELS],
        film_z: f64,
        max_film_radius: f64,
    ) -> Result<Chromatic, RenderError> {
        check_wavelengths(system, wavelengths_nm)?;
        let pick = |models: FirstOrderModels| if thin { models.thin } else { models.thick };
        let design = pick(first_order.clone());
        let mut lenses = Vec::with_capacity(CHANNELS);
        for nm in wavelengths_nm {
            lenses.push(pick(first_order.at_wavelength(system, nm)?));
        }
        let radius = sampling_radius(&lenses, design.exit_pupil_z, film_z, max_film_radius)?;
        let lenses: [ParaxialLens; CHANNELS] =
            lenses.try_into().expect("one lens per channel was pushed");
        Ok(Chromatic {
            wavelengths_nm,
            lenses: ChannelLenses::Paraxial(lenses),
            sampling: PupilSampling::disc(design.exit_pupil_z, radius),
        })
    }

    /// The lens traced at each wavelength through the stop of `first_order`'s f-number, each
    /// channel's effective pupil fitted for the film plane `film_z` up to `max_film_radius` at
    /// `nodes` film radii, sampled from their union.
    pub fn traced(
        system: &LensSystem,
        first_order: &FirstOrderModels,
        wavelengths_nm: [f64; CHANNELS],
        film_z: f64,
        max_film_radius: f64,
        nodes: usize,
    ) -> Result<Chromatic, RenderError> {
        check_wavelengths(system, wavelengths_nm)?;
        let mut lenses = Vec::with_capacity(CHANNELS);
        for nm in wavelengths_nm {
            let placeholder = PupilSampling::disc(0.0, 0.0).circles;
            let mut lens = TracedLens::at_wavelength(
                system,
                first_order,
                first_order.f_number,
                nm,
                placeholder,
            );
            lens.pupil = fit_effective_pupil(&lens.system, film_z, max_film_radius, nodes)?;
            lenses.push(lens);
        }
        let circles = union_of(&[&lenses[0].pupil, &lenses[1].pupil, &lenses[2].pupil])?;
        let z = lenses[0].rear_plane_z;
        let lenses: [TracedLens; CHANNELS] =
            lenses.try_into().expect("one lens per channel was pushed");
        Ok(Chromatic {
            wavelengths_nm,
            lenses: ChannelLenses::Traced(Box::new(lenses)),
            sampling: PupilSampling { z, circles },
        })
    }

    /// The layers of `lens`'s table baked at `wavelengths_nm` (each within
    /// [`crate::model::WAVELENGTH_MATCH_NM`]), sampled from the union of their sampling pupils.
    pub fn baked(
        lens: &BakedLens,
        wavelengths_nm: [f64; CHANNELS],
    ) -> Result<Chromatic, RenderError> {
        let mut layers = [0; CHANNELS];
        for (layer, nm) in layers.iter_mut().zip(wavelengths_nm) {
            *layer = layer_at(&lens.table, nm)?;
        }
        // Each channel's sampling pupil on the render's film plane (the coordinate pupils are
        // the reference plane's, which a focus range moves the film away from).
        let pupils = layers.map(|k| lens.pupil(k).circles);
        let circles = union_of(&[&pupils[0], &pupils[1], &pupils[2]])?;
        Ok(Chromatic {
            wavelengths_nm,
            lenses: ChannelLenses::Baked(layers),
            sampling: PupilSampling {
                z: lens.table.layers[layers[0]].frame.rear_plane_z,
                circles,
            },
        })
    }

    /// Refuses channels of another kind than `model` (thin and thick both take paraxial ones).
    pub(crate) fn check_matches(&self, model: &LensModel) -> Result<(), RenderError> {
        let matches = matches!(
            (&self.lenses, model),
            (
                ChannelLenses::Paraxial(_),
                LensModel::Thin(_) | LensModel::Thick(_)
            ) | (ChannelLenses::Traced(_), LensModel::Traced(_))
                | (ChannelLenses::Baked(_), LensModel::Baked(_))
        );
        if matches {
            Ok(())
        } else {
            Err(RenderError::InvalidSetting(format!(
                "chromatic channels do not match the {} model",
                model.name()
            )))
        }
    }
}

/// Radius of the axial disc on the plane `sampling_z` that contains every one of `lenses`' exit
/// pupils as seen from every point of a film at `film_z` within `max_film_radius` of the axis.
///
/// A pupil (z_c, r_c) seen from film point F projects onto the plane as a disc of radius r_c s
/// centred at F (1 - s), s = (film_z - sampling_z) / (film_z - z_c); the farthest film point
/// fixes the bound. A pupil on the plane gives exactly its own radius.
pub fn sampling_radius(
    lenses: &[ParaxialLens],
    sampling_z: f64,
    film_z: f64,
    max_film_radius: f64,
) -> Result<f64, RenderError> {
    let sampling_distance = film_z - sampling_z;
    let mut radius: f64 = 0.0;
    for lens in lenses {
        let distance = film_z - lens.exit_pupil_z;
        if !(distance > 0.0 && sampling_distance > 0.0) {
            return Err(RenderError::InvalidSetting(format!(
                "the exit pupil at z = {:.3} mm is not in front of the film (z = {film_z:.3} mm)",
                lens.exit_pupil_z.max(sampling_z)
            )));
        }
        let s = sampling_distance / distance;
        radius = radius.max(max_film_radius * (1.0 - s).abs() + lens.exit_pupil_radius_mm * s);
    }
    Ok(radius)
}

/// Whether the film ray from `film` towards `pupil` crosses `lens`'s exit-pupil plane inside its
/// radius (widened by [`PUPIL_EDGE_TOLERANCE`]): a paraxial channel's aperture.
pub fn inside_exit_pupil(lens: &ParaxialLens, film: [f64; 3], pupil: [f64; 3]) -> bool {
    let t = (lens.exit_pupil_z - film[2]) / (pupil[2] - film[2]);
    let x = film[0] + t * (pupil[0] - film[0]);
    let y = film[1] + t * (pupil[1] - film[1]);
    let r2 = lens.exit_pupil_radius_mm * lens.exit_pupil_radius_mm;
    x * x + y * y <= r2 * (1.0 + PUPIL_EDGE_TOLERANCE)
}

/// Circles containing every table's circle at every film radius, at the tables' common nodes.
///
/// All circles of a film radius are centred on the line through the film point, so each is the
/// interval [c - r, c + r] there, and the circle on the intervals' hull contains them all. The
/// hull's ends are the minimum and maximum of the ends, so between two nodes the interpolated
/// hull's ends lie beyond every table's interpolated ends: the union is as conservative under
/// the renderer's linear interpolation as each table is. Where one circle already contains the
/// others it is kept unchanged (identical channels sample exactly as monochrome).
pub fn union_of(tables: &[&PupilTable]) -> Result<PupilTable, RenderError> {
    let first = tables
        .first()
        .ok_or_else(|| RenderError::InvalidSetting("no pupil tables to bound".into()))?;
    if tables.iter().any(|t| {
        t.circles.len() != first.circles.len() || t.max_film_radius != first.max_film_radius
    }) {
        return Err(RenderError::InvalidSetting(
            "the channels' pupil tables have different film-radius nodes; a chromatic render \
             needs one set (rebake the table with all wavelengths at once)"
                .into(),
        ));
    }
    let circles = (0..first.circles.len())
        .map(|k| {
            let at = |t: &&PupilTable| t.circles[k];
            let low = tables
                .iter()
                .map(|t| at(t).centre_x - at(t).radius)
                .fold(f64::INFINITY, f64::min);
            let high = tables
                .iter()
                .map(|t| at(t).centre_x + at(t).radius)
                .fold(f64::NEG_INFINITY, f64::max);
            tables
                .iter()
                .map(at)
                .find(|c| c.centre_x - c.radius == low && c.centre_x + c.radius == high)
                .unwrap_or(PupilCircle {
                    centre_x: 0.5 * (low + high),
                    radius: 0.5 * (high - low),
                })
        })
        .collect();
    Ok(PupilTable {
        max_film_radius: first.max_film_radius,
        circles,
    })
}

/// How far apart the colour channels land on the film, from the thick (first-order) lens at
/// each wavelength: the same quantities the `analyze` report gives as axial and lateral colour,
/// for this render's film, focus and aperture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourSpread {
    /// Largest film-plane distance between two channels' chief rays from the object point that
    /// the design wavelength images at the film corner (mm).
    pub lateral_mm: f64,
    /// Largest difference between two channels' blur-disc diameters for an on-axis point in the
    /// plane of focus (mm): axial colour on the film.
    pub axial_blur_mm: f64,
}

/// Where the design model images things: the object side of the film's conjugate.
enum Object {
    /// In the plane at this z.
    Plane(f64),
    Infinity,
}

/// The image (z, height) of the object point on the object ray (origin, slope) through `lens`.
fn image_of(lens: &ParaxialLens, object: &Object, origin: [f64; 3], slope: f64) -> (f64, f64) {
    match *object {
        Object::Infinity => (
            lens.rear_principal_z + lens.focal_length_mm,
            lens.focal_length_mm * slope,
        ),
        Object::Plane(z) => {
            let height = origin[0] + slope * (z - origin[2]);
            let s = lens.front_principal_z - z;
            let v = 1.0 / (1.0 / lens.focal_length_mm - 1.0 / s);
            (lens.rear_principal_z + v, -v / s * height)
        }
    }
}

impl ColourSpread {
    /// The spread of the channels at `wavelengths_nm` of `system` stopped to `first_order`'s
    /// f-number, for a film at `film_z` whose farthest point lies `film_radius` off the axis.
    pub fn of(
        system: &LensSystem,
        first_order: &FirstOrderModels,
        wavelengths_nm: [f64; CHANNELS],
        film_z: f64,
        film_radius: f64,
    ) -> Result<ColourSpread, RenderError> {
        check_wavelengths(system, wavelengths_nm)?;
        let design = &first_order.thick;
        let image_distance = film_z - design.rear_principal_z;
        let vergence = 1.0 / design.focal_length_mm - 1.0 / image_distance;
        let object = if vergence > 0.0 {
            Object::Plane(design.front_principal_z - 1.0 / vergence)
        } else {
            Object::Infinity
        };
        let (origin, slope) =
            design.object_ray([film_radius, 0.0, film_z], [0.0, 0.0, design.exit_pupil_z]);
        let mut landing = Vec::with_capacity(CHANNELS);
        let mut blur = Vec::with_capacity(CHANNELS);
        for nm in wavelengths_nm {
            let lens = first_order.at_wavelength(system, nm)?.thick;
            let to_film = |(z, height): (f64, f64)| {
                height * (film_z - lens.exit_pupil_z) / (z - lens.exit_pupil_z)
            };
            let (axial_z, _) = image_of(&lens, &object, [0.0; 3], 0.0);
            landing.push(to_film(image_of(&lens, &object, origin, slope[0])));
            blur.push(
                2.0 * lens.exit_pupil_radius_mm * (film_z - axial_z).abs()
                    / (axial_z - lens.exit_pupil_z).abs(),
            );
        }
        let spread = |v: &[f64]| {
            let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let min = v.iter().copied().fold(f64::INFINITY, f64::min);
            max - min
        };
        let (lateral_mm, axial_blur_mm) = (spread(&landing), spread(&blur));
        // A channel imaging at infinity or behind its exit pupil spreads without bound.
        let finite = |v: f64| if v.is_finite() { v } else { f64::INFINITY };
        Ok(ColourSpread {
            lateral_mm: finite(lateral_mm),
            axial_blur_mm: finite(axial_blur_mm),
        })
    }

    /// The larger spread in output pixels of `pixel_pitch_mm`.
    pub fn pixels(&self, pixel_pitch_mm: f64) -> f64 {
        self.lateral_mm.max(self.axial_blur_mm) / pixel_pitch_mm
    }
}

/// Whether `mode` renders `system` per channel: `Auto` when the lens disperses and `spread` (in
/// output pixels of `pixel_pitch_mm`) reaches [`VISIBLE_COLOUR_PX`].
pub fn wants_chromatic(
    mode: ChromaticMode,
    system: &LensSystem,
    spread: &ColourSpread,
    pixel_pitch_mm: f64,
) -> bool {
    match mode {
        ChromaticMode::On => true,
        ChromaticMode::Off => false,
        ChromaticMode::Auto => {
            system.disperses() && spread.pixels(pixel_pitch_mm) >= VISIBLE_COLOUR_PX
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pupil(z: f64, radius: f64) -> ParaxialLens {
        ParaxialLens {
            exit_pupil_z: z,
            exit_pupil_radius_mm: radius,
            ..ParaxialLens::thin(50.0, 2.0).unwrap()
        }
    }

    #[test]
    fn sampling_disc_contains_every_pupil_from_every_film_point() {
        // Pupils before and behind the sampling plane, larger and smaller: the rays from any
        // film point through any point of any pupil cross the sampling plane inside the disc,
        // and the bound is tight (some ray reaches 99.9 % of it).
        let lenses = [pupil(20.0, 11.0), pupil(21.5, 12.5), pupil(18.0, 10.0)];
        let (sampling_z, film_z, film_radius) = (20.0, 60.0, 21.6);
        let radius = sampling_radius(&lenses, sampling_z, film_z, film_radius).unwrap();
        let mut farthest: f64 = 0.0;
        for lens in &lenses {
            for f in 0..=8 {
                let film = [
                    film_radius * f as f64 / 8.0 * 0.6,
                    -film_radius * f as f64 / 8.0 * 0.8,
                ];
                for k in 0..64 {
                    let a = k as f64 * std::f64::consts::TAU / 64.0;
                    let p = [
                        lens.exit_pupil_radius_mm * a.cos(),
                        lens.exit_pupil_radius_mm * a.sin(),
                    ];
                    let t = (sampling_z - film_z) / (lens.exit_pupil_z - film_z);
                    let x = film[0] + t * (p[0] - film[0]);
                    let y = film[1] + t * (p[1] - film[1]);
                    farthest = farthest.max(x.hypot(y));
                }
            }
        }
        assert!(farthest <= radius * (1.0 + 1e-12), "{farthest} > {radius}");
        assert!(farthest > 0.999 * radius, "{farthest} << {radius}");
        // One pupil on the plane samples exactly its own disc.
        assert_eq!(
            sampling_radius(&[pupil(20.0, 11.0)], 20.0, 60.0, film_radius).unwrap(),
            11.0
        );
        assert!(sampling_radius(&[pupil(70.0, 1.0)], 20.0, 60.0, 1.0).is_err());
    }

    #[test]
    fn union_contains_each_table_between_nodes_too() {
        // Three tables whose circles cross each other between the nodes: at every film radius
        // the interpolated union holds each table's interpolated circle.
        let table = |centres: [f64; 3], radii: [f64; 3]| PupilTable {
            max_film_radius: 10.0,
            circles: centres
                .iter()
                .zip(radii)
                .map(|(&centre_x, radius)| PupilCircle { centre_x, radius })
                .collect(),
        };
        let tables = [
            table([0.0, 1.0, 3.0], [5.0, 4.0, 2.0]),
            table([0.5, 0.0, 2.0], [4.0, 5.0, 3.5]),
            table([-0.5, 2.0, 1.0], [4.5, 3.0, 4.0]),
        ];
        let refs: Vec<&PupilTable> = tables.iter().collect();
        let union = union_of(&refs).unwrap();
        for k in 0..=100 {
            let r = 10.0 * k as f64 / 100.0;
            let u = union.circle_at(r);
            for t in &tables {
                let c = t.circle_at(r);
                assert!(
                    c.centre_x - c.radius >= u.centre_x - u.radius - 1e-12,
                    "{r}"
                );
                assert!(
                    c.centre_x + c.radius <= u.centre_x + u.radius + 1e-12,
                    "{r}"
                );
            }
        }
        // At a node where one circle holds the others it is kept bit for bit.
        assert_eq!(union.circles[1], tables[1].circles[1]);
        let short = table([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
        let mut fewer = short.clone();
        fewer.circles.pop();
        assert!(union_of(&[&short, &fewer]).is_err());
    }
}
