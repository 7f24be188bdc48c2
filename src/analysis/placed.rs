//! `analyze` for a lens placed off one common axis (tilted or decentred surfaces, tilted image
//! planes): everything from real rays of the 3-D trace ([`PlacedTracer`]), nothing paraxial.
//!
//! - The base of each field is its chief ray, aimed at the stop's centre; the field (0, 0)'s
//!   chief ray is the optical axis ray (OAR), the base of the first-order data.
//! - First-order data are derivatives of real rays about a base ray (parabasal rays): central
//!   differences at three steps, each pair combined by Richardson extrapolation, and the two
//!   extrapolations compared (`agreement`). Directions after the lens are read in a transverse
//!   frame carried along the base ray (rotated with it at each refraction, reflected with it at
//!   each mirror), so a flat fold mirror leaves every number as the unfolded lens has it.
//! - Spot diagrams and ray fans are in the image plane's own frame, about the chief ray's point.
//! - The wavefront is the optical path difference to a sphere centred on the chief ray's point
//!   in the image plane through the real exit pupil (where neighbouring fields' chief rays cross
//!   this one's after the lens), as the centred wave module measures it (`crate::wave`).
//!
//! Seidel sums are not given: they are the coefficients of a power series in field and aperture
//! about an axis of rotational symmetry, and a tilted or decentred lens has none (its aberrations
//! about the OAR hold terms, such as coma and astigmatism on the axis, that no Seidel sum holds).

use crate::trace::placed::{
    PathPoint, PlacedBeamError, PlacedTracer, SPOT_GRID, tangent_direction,
};
use crate::trace::{Vec3, cross, dot, normalised};
use crate::wave::{WavefrontMap, WavefrontStats, inside_pupil, pupil_coordinate};
use serde::Serialize;

/// What to analyse: the file's fields and entrance pupil, as [`crate::trace::placed::PlacedBeam`]
/// gives them, and how finely.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedOptions {
    pub wavelength_nm: f64,
    /// Field angles (x, y) in degrees of an object at infinity.
    pub fields_deg: Vec<[f64; 2]>,
    /// Entrance-pupil diameter (mm), perpendicular to the object side's axis.
    pub pupil_diameter: f64,
    /// Rays per ray fan across the pupil's diameter.
    pub fan_points: usize,
    /// Pupil points per side of the wavefront grid.
    pub wave_samples: usize,
}

impl PlacedOptions {
    /// The file's beam with 21-point fans and a 64 x 64 wavefront grid (the wave module's
    /// default sampling).
    pub fn new(wavelength_nm: f64, fields_deg: Vec<[f64; 2]>, pupil_diameter: f64) -> Self {
        PlacedOptions {
            wavelength_nm,
            fields_deg,
            pupil_diameter,
            fan_points: 21,
            wave_samples: crate::wave::DEFAULT_SAMPLES,
        }
    }
}

/// Why a placed lens could not be analysed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlacedAnalysisError {
    #[error(transparent)]
    Beam(#[from] PlacedBeamError),
    #[error("the entrance-pupil diameter must be a finite number above zero; got {0}")]
    PupilDiameter(f64),
    #[error("{what}: a ray beside it {why}")]
    Differential { what: String, why: String },
}

/// A chief ray (or the OAR) and the first-order data of the rays about it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BaseRay {
    pub field_deg: [f64; 2],
    /// Where the ray crosses the plane z = 0 of the object side's frame (mm).
    pub launch_mm: [f64; 2],
    /// Where it meets the image plane, in the plane's own frame (mm).
    pub image_point_mm: [f64; 2],
    /// Its unit direction after the lens (global frame), and its angle to the image plane's
    /// normal (degrees).
    pub image_direction: Vec3,
    pub incidence_on_image_deg: f64,
    /// Distance (mm) along the ray from the image plane to the focus of a thin collimated beam
    /// about it, in the x and y sections of the carried frame (the real-ray tangential and
    /// sagittal foci of a field in y; positive: beyond the image plane); None where the beam
    /// leaves collimated in that section (afocal).
    pub focus_from_image_mm: [Option<f64>; 2],
    /// Distance (mm) along the ray from the real exit pupil (where the chief rays of
    /// neighbouring fields cross it after the lens) to the image plane, in the x and y sections;
    /// None where they leave parallel to it (telecentric in that section).
    pub exit_pupil_to_image_mm: [Option<f64>; 2],
}

/// First-order data about the OAR from real rays (parabasal rays), for an object at infinity.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AxisFirstOrder {
    /// Effective focal length -h / u' in the x and y sections of the frame carried along the
    /// OAR (h the height of a ray of the collimated beam beside the OAR, u' its slope to the OAR
    /// after the lens); positive where the beam converges. None where the lens is afocal in
    /// that section. For a lens without mirrors this is the paraxial EFL; lensbake's paraxial
    /// EFL of a centred lens with mirrors carries the sign of the image index (n'/power).
    pub efl_mm: [Option<f64>; 2],
    /// Back focal distance: from where the OAR leaves the last surface, along it, to the focus
    /// of each section.
    pub bfd_mm: [Option<f64>; 2],
    /// How far each section's focus lies beyond the image plane along the OAR (defocus).
    pub focus_from_image_mm: [Option<f64>; 2],
    /// How the chief ray's point moves on the image plane (its frame) per unit tangent of the
    /// field angle: rows image x, y; columns field x, y. For a centred lens focused at infinity,
    /// the diagonal is the EFL (with the sign of the image's orientation).
    pub image_scale_mm: [[f64; 2]; 2],
    /// Largest relative difference between the two Richardson extrapolations of the
    /// derivatives these numbers come from: how well the differences converged.
    pub agreement: f64,
    /// Largest launch step (mm) and field-tangent step of the differences.
    pub steps: [f64; 2],
}

/// A spot diagram about the chief ray, in the image plane's frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpotAbout {
    pub launched: usize,
    pub arrived: usize,
    /// Centroid relative to the chief ray's point (mm).
    pub centroid_mm: Option<[f64; 2]>,
    pub rms_radius_about_chief_mm: Option<f64>,
    pub rms_radius_about_centroid_mm: Option<f64>,
    pub max_radius_about_chief_mm: Option<f64>,
}

/// One ray of a fan: its pupil coordinate (-1..1) and where it meets the image plane relative
/// to the chief ray (x, y, mm), None where it does not get there.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FanRay {
    pub pupil: f64,
    pub error_mm: Option<[f64; 2]>,
}

/// Transverse ray aberrations across the pupil: tangential along pupil y, sagittal along x.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Fans {
    pub tangential: Vec<FanRay>,
    pub sagittal: Vec<FanRay>,
}

/// The wavefront about the chief ray.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlacedWave {
    #[serde(flatten)]
    pub stats: WavefrontStats,
    /// exp(-(2π σ)²) for the RMS σ in waves (Maréchal), beside the sampled pupil's Strehl.
    pub marechal_strehl: f64,
    pub reference_radius_mm: f64,
    pub samples: usize,
}

/// One field's analysis.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlacedField {
    pub chief: BaseRay,
    pub spot: SpotAbout,
    pub fans: Fans,
    /// The wavefront, or why it has none (a telecentric exit pupil, no light).
    pub wave: Option<PlacedWave>,
    pub wave_note: Option<String>,
}

/// The whole real-ray analysis of a placed lens.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlacedAnalysis {
    pub wavelength_nm: f64,
    pub pupil_diameter_mm: f64,
    pub object_index: f64,
    pub image_index: f64,
    pub axis_ray: BaseRay,
    pub first_order: AxisFirstOrder,
    pub fields: Vec<PlacedField>,
    /// Why no Seidel sums are given.
    pub seidel: &'static str,
}

/// Why [`PlacedAnalysis::seidel`] is empty-handed.
pub const NO_SEIDEL: &str = "not given: Seidel sums expand the aberrations of a rotationally \
    symmetric lens in powers of field and aperture about its axis; a tilted or decentred lens has \
    no such axis, and its aberrations about the OAR hold terms (coma and astigmatism on the axis, \
    anamorphic focal lengths) that no Seidel sum holds";

fn scaled(a: Vec3, k: f64) -> Vec3 {
    a.map(|v| v * k)
}

fn minus(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The unit vector of `v` perpendicular to unit `d`.
fn perpendicular(v: Vec3, d: Vec3) -> Vec3 {
    normalised(minus(v, scaled(d, dot(v, d))))
}

/// A transverse frame (x, y) perpendicular to a ray, carried along its path from the object
/// side's x and y: at a refraction both turn with the ray about the normal of its plane of
/// incidence, at a mirror both are reflected by the mirror's plane.
fn carried_frame(start: Vec3, points: &[PathPoint]) -> [Vec3; 2] {
    let mut frame = [
        perpendicular([1.0, 0.0, 0.0], start),
        perpendicular([0.0, 1.0, 0.0], start),
    ];
    let mut before = start;
    for point in points {
        let after = point.direction;
        frame = frame.map(|v| {
            if point.reflects {
                // The mirror's normal lies along the change of direction.
                let n = minus(after, before);
                let nn = dot(n, n);
                if nn == 0.0 {
                    v
                } else {
                    minus(v, scaled(n, 2.0 * dot(v, n) / nn))
                }
            } else {
                let k = cross(before, after);
                let (sine_sq, cosine) = (dot(k, k), dot(before, after));
                if sine_sq == 0.0 {
                    v
                } else {
                    // Rodrigues: v cos + (k x v) + k (k.v)(1 - cos)/sin², k = before x after.
                    let turned = scaled(v, cosine);
                    let twist = cross(k, v);
                    let along = scaled(k, dot(k, v) * (1.0 - cosine) / sine_sq);
                    std::array::from_fn(|i| turned[i] + twist[i] + along[i])
                }
            }
        });
        // Rounding: keep the frame orthonormal and perpendicular to the ray.
        let x = perpendicular(frame[0], after);
        let y = perpendicular(minus(frame[1], scaled(x, dot(frame[1], x))), after);
        frame = [x, y];
        before = after;
    }
    frame
}

/// A base ray's line after the lens, the frame carried along it, and where it left the last
/// surface it met.
#[derive(Clone, Copy, Debug)]
struct BaseLine {
    point: Vec3,
    direction: Vec3,
    frame: [Vec3; 2],
    last_surface: Vec3,
}

/// The quantities differentiated about a base ray: the stop crossing (x, y), the height and
/// slope of the ray in the base ray's transverse frame at the plane through its image point
/// normal to it, and the image-plane point (x, y).
type Probe = [f64; 8];
const STOP: usize = 0;
const HEIGHT: usize = 2;
const SLOPE: usize = 4;
const IMAGE: usize = 6;

/// Derivatives of the probe in launch x, y (per mm) and field tangent x, y.
type Jacobian = [[f64; 4]; 8];

fn probe(
    tracer: &PlacedTracer,
    base: &BaseLine,
    launch: [f64; 2],
    tangent: [f64; 2],
) -> Option<Probe> {
    let direction = tangent_direction(tangent);
    let start = [launch[0], launch[1], 0.0];
    let stop = tracer.stop_crossing(start, direction)?;
    let path = tracer.trace_path(start, direction, false);
    if !path.ray.outcome.is_ok() {
        return None;
    }
    let (p, d) = (path.ray.position, path.ray.direction);
    let along = dot(d, base.direction);
    if along <= 0.0 {
        return None;
    }
    // Back (or on) to the plane through the base's image point normal to it.
    let q = minus(
        p,
        scaled(d, dot(minus(p, base.point), base.direction) / along),
    );
    let offset = minus(q, base.point);
    let image = tracer.image_coordinates(p);
    Some([
        stop[0],
        stop[1],
        dot(offset, base.frame[0]),
        dot(offset, base.frame[1]),
        dot(d, base.frame[0]) / along,
        dot(d, base.frame[1]) / along,
        image[0],
        image[1],
    ])
}

/// The Jacobian of the probe about (launch, tangent) by central differences with steps
/// (launch, tangent) `steps / 2^level`, Richardson-extrapolated from levels k and k + 1: the
/// estimates from levels (0, 1) and (1, 2).
fn jacobians(
    tracer: &PlacedTracer,
    base: &BaseLine,
    launch: [f64; 2],
    tangent: [f64; 2],
    steps: [f64; 2],
) -> Result<[Jacobian; 2], String> {
    let mut central = [[[0.0; 4]; 8]; 3];
    for (level, estimate) in central.iter_mut().enumerate() {
        let scale = 0.5_f64.powi(level as i32);
        for variable in 0..4 {
            let h = steps[variable / 2] * scale;
            let at = |sign: f64| {
                let (mut l, mut t) = (launch, tangent);
                if variable < 2 {
                    l[variable] += sign * h;
                } else {
                    t[variable - 2] += sign * h;
                }
                probe(tracer, base, l, t)
            };
            let (Some(plus), Some(minus)) = (at(1.0), at(-1.0)) else {
                return Err("misses the stop, a surface or the image plane".into());
            };
            for (row, (a, b)) in estimate.iter_mut().zip(plus.iter().zip(&minus)) {
                row[variable] = (a - b) / (2.0 * h);
            }
        }
    }
    let richardson = |fine: &Jacobian, coarse: &Jacobian| -> Jacobian {
        std::array::from_fn(|r| std::array::from_fn(|c| (4.0 * fine[r][c] - coarse[r][c]) / 3.0))
    };
    Ok([
        richardson(&central[1], &central[0]),
        richardson(&central[2], &central[1]),
    ])
}

type Matrix2 = [[f64; 2]; 2];

/// The 2 x 2 block of `j` at rows `row..row+2`, columns `column..column+2`.
fn block(j: &Jacobian, row: usize, column: usize) -> Matrix2 {
    [
        [j[row][column], j[row][column + 1]],
        [j[row + 1][column], j[row + 1][column + 1]],
    ]
}

fn product(a: &Matrix2, b: &Matrix2) -> Matrix2 {
    std::array::from_fn(|r| std::array::from_fn(|c| a[r][0].mul_add(b[0][c], a[r][1] * b[1][c])))
}

fn sum(a: &Matrix2, b: &Matrix2) -> Matrix2 {
    std::array::from_fn(|r| std::array::from_fn(|c| a[r][c] + b[r][c]))
}

fn inverse(m: &Matrix2) -> Option<Matrix2> {
    let det = m[0][0].mul_add(m[1][1], -(m[0][1] * m[1][0]));
    (det != 0.0 && det.is_finite()).then(|| {
        [
            [m[1][1] / det, -m[0][1] / det],
            [-m[1][0] / det, m[0][0] / det],
        ]
    })
}

/// A finite number, or None.
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// What one Jacobian says about its base ray.
#[derive(Clone, Copy, Debug)]
struct Differential {
    /// Collimated beam about the base: heights and slopes per mm of launch offset.
    beam_height: Matrix2,
    beam_slope: Matrix2,
    /// Chief rays of neighbouring fields (kept on the stop's centre): heights, slopes and
    /// image points per unit field tangent.
    chief_height: Matrix2,
    chief_slope: Matrix2,
    image_scale: Matrix2,
}

impl Differential {
    fn of(j: &Jacobian) -> Option<Differential> {
        let on_stop = inverse(&block(j, STOP, 0))?;
        // Launch change per field tangent that keeps the ray on the stop's centre.
        let follow = product(&on_stop, &block(j, STOP, 2)).map(|r| r.map(|v| -v));
        let chief = |row: usize| sum(&block(j, row, 2), &product(&block(j, row, 0), &follow));
        Some(Differential {
            beam_height: block(j, HEIGHT, 0),
            beam_slope: block(j, SLOPE, 0),
            chief_height: chief(HEIGHT),
            chief_slope: chief(SLOPE),
            image_scale: chief(IMAGE),
        })
    }

    fn efl(&self) -> [f64; 2] {
        [0, 1].map(|i| -1.0 / self.beam_slope[i][i])
    }

    fn focus(&self) -> [f64; 2] {
        [0, 1].map(|i| -self.beam_height[i][i] / self.beam_slope[i][i])
    }

    fn exit_pupil_to_image(&self) -> [f64; 2] {
        [0, 1].map(|i| self.chief_height[i][i] / self.chief_slope[i][i])
    }

    /// Every number the report takes from it, for the convergence check.
    fn figures(&self) -> Vec<f64> {
        let mut all = self.efl().to_vec();
        all.extend(self.focus());
        all.extend(self.exit_pupil_to_image());
        all.extend(self.image_scale.iter().flatten());
        all
    }
}

/// The largest relative difference between two lists of figures (absolute below a scale of 1
/// mm, where a figure near zero has no meaningful relative change); infinite ones must agree.
fn disagreement(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            if x.is_finite() && y.is_finite() {
                (x - y).abs() / x.abs().max(y.abs()).max(1.0)
            } else if x == y {
                0.0
            } else {
                f64::INFINITY
            }
        })
        .fold(0.0, f64::max)
}

/// A traced base ray with the derivatives about it.
struct Based {
    ray: BaseRay,
    line: BaseLine,
    launch: [f64; 2],
    direction: Vec3,
    optical_path: f64,
    differential: Differential,
    agreement: f64,
}

/// Differential steps: a thousandth of the pupil radius in launch, a thousandth in field
/// tangent (halved twice). Central differences err by the square of the step over the aperture
/// or field scale, Richardson's combination by the fourth power; rounding of 1e-16 in the
/// coordinates over steps of 1e-4 of the scale grows as the steps shrink. The two extrapolations
/// agree to 7e-11 to 2e-9 on the corpus files with power, below 1e-9 on five bundled centred
/// lenses.
const LAUNCH_STEP: f64 = 1e-3;
const TANGENT_STEP: f64 = 1e-3;

fn based(
    tracer: &PlacedTracer,
    field_deg: [f64; 2],
    pupil_radius: f64,
    what: &str,
) -> Result<Based, PlacedAnalysisError> {
    let (start, direction) = tracer.chief_ray(field_deg, pupil_radius)?;
    let path = tracer.trace_path(start, direction, false);
    if !path.ray.outcome.is_ok() {
        return Err(PlacedBeamError::ChiefRayStopped {
            field_deg,
            outcome: path.ray.outcome,
        }
        .into());
    }
    let line = BaseLine {
        point: path.ray.position,
        direction: path.ray.direction,
        frame: carried_frame(direction, &path.points),
        last_surface: path.points.last().map_or(start, |p| p.position),
    };
    let launch = [start[0], start[1]];
    let tangent = [direction[0] / direction[2], direction[1] / direction[2]];
    let steps = [LAUNCH_STEP * pupil_radius, TANGENT_STEP];
    let fail = |why: String| PlacedAnalysisError::Differential {
        what: what.to_string(),
        why,
    };
    let [coarse, fine] = jacobians(tracer, &line, launch, tangent, steps).map_err(fail)?;
    let singular = || fail("sees no change of the stop crossing (singular stop)".into());
    let differential = Differential::of(&fine).ok_or_else(singular)?;
    let agreement = disagreement(
        &Differential::of(&coarse).ok_or_else(singular)?.figures(),
        &differential.figures(),
    );
    let image_normal = tracer.image_normal();
    let cosine = dot(line.direction, image_normal).abs().min(1.0);
    let ray = BaseRay {
        field_deg,
        launch_mm: launch,
        image_point_mm: tracer.image_coordinates(line.point),
        image_direction: line.direction,
        incidence_on_image_deg: cosine.acos().to_degrees(),
        focus_from_image_mm: differential.focus().map(finite),
        exit_pupil_to_image_mm: differential.exit_pupil_to_image().map(finite),
    };
    Ok(Based {
        ray,
        line,
        launch,
        direction,
        optical_path: path.optical_path,
        differential,
        agreement,
    })
}

/// Analyses `tracer`'s lens for `options` (object at infinity).
///
/// ```
/// use lensbake::analysis::placed::{PlacedOptions, analyze_placed};
/// use lensbake::prescription::formats::{LoadOptions, read_str, Format};
/// use lensbake::prescription::Problem;
/// use lensbake::trace::placed::PlacedTracer;
///
/// // An ideal lens of 100 mm (the stop), then a 10 mm plate of n = 1.5 tilted 10 degrees
/// // about x in its converging beam.
/// let text = "\
/// UNIT MM X W X CM MR CPMR\nENPD 10\nWAVL 0.5875618\nSURF 0\n  DISZ INFINITY\n\
/// SURF 1\n  STOP\n  TYPE PARAXIAL\n  PARM 1 100\n  DISZ 20\n\
/// SURF 2\n  TYPE COORDBRK\n  PARM 3 10\n  DISZ 0\n\
/// SURF 3\n  GLAS ___BLANK 1 0 1.5 60\n  DISZ 10\n\
/// SURF 4\n  DISZ 0\n\
/// SURF 5\n  TYPE COORDBRK\n  PARM 3 -10\n  DISZ 50\n\
/// SURF 6\n";
/// let read = read_str(text, None, Format::Zemax, &LoadOptions::default());
/// let lens = match read.unwrap_err().problem {
///     Problem::NotRotationallySymmetric { lens, .. } => lens,
///     other => panic!("{other}"),
/// };
/// let tracer = PlacedTracer::new(&lens, 587.5618).unwrap();
/// let options = PlacedOptions::new(587.5618, vec![[0.0, 0.0]], 10.0);
/// let analysis = analyze_placed(&tracer, &options).unwrap();
/// // A plate changes no focal length, but splits the focus (astigmatism).
/// let [efl_x, efl_y] = analysis.first_order.efl_mm.map(Option::unwrap);
/// assert!((efl_x - 100.0).abs() < 1e-9 && (efl_y - 100.0).abs() < 1e-9);
/// let [bfd_x, bfd_y] = analysis.first_order.bfd_mm.map(Option::unwrap);
/// assert!(bfd_y - bfd_x > 0.1);
/// ```
pub fn analyze_placed(
    tracer: &PlacedTracer,
    options: &PlacedOptions,
) -> Result<PlacedAnalysis, PlacedAnalysisError> {
    let diameter = options.pupil_diameter;
    if !(diameter.is_finite() && diameter > 0.0) {
        return Err(PlacedAnalysisError::PupilDiameter(diameter));
    }
    let radius = diameter / 2.0;
    let axis = based(tracer, [0.0, 0.0], radius, "the OAR")?;
    let d = &axis.differential;
    let to_image = dot(
        minus(axis.line.point, axis.line.last_surface),
        axis.line.direction,
    );
    let focus = d.focus();
    let first_order = AxisFirstOrder {
        efl_mm: d.efl().map(finite),
        bfd_mm: focus.map(|t| finite(to_image + t)),
        focus_from_image_mm: focus.map(finite),
        image_scale_mm: d.image_scale,
        agreement: axis.agreement,
        steps: [LAUNCH_STEP * radius, TANGENT_STEP],
    };
    let fields = options
        .fields_deg
        .iter()
        .map(|&field| analyse_field(tracer, options, field))
        .collect::<Result<Vec<_>, _>>()?;
    let [object_index, image_index] = tracer.indices();
    Ok(PlacedAnalysis {
        wavelength_nm: options.wavelength_nm,
        pupil_diameter_mm: diameter,
        object_index,
        image_index,
        axis_ray: axis.ray,
        first_order,
        fields,
        seidel: NO_SEIDEL,
    })
}

fn analyse_field(
    tracer: &PlacedTracer,
    options: &PlacedOptions,
    field_deg: [f64; 2],
) -> Result<PlacedField, PlacedAnalysisError> {
    let radius = options.pupil_diameter / 2.0;
    let what = format!(
        "the chief ray of field ({:.6}, {:.6}) deg",
        field_deg[0], field_deg[1]
    );
    let chief = based(tracer, field_deg, radius, &what)?;
    let chief_point = chief.ray.image_point_mm;
    let spot = tracer.collimated_spot(field_deg, options.pupil_diameter, SPOT_GRID)?;
    let about: Vec<[f64; 2]> = spot
        .points
        .iter()
        .map(|p| [p[0] - chief_point[0], p[1] - chief_point[1]])
        .collect();
    let count = about.len() as f64;
    let mean_square = |c: [f64; 2]| {
        about
            .iter()
            .map(|p| (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2))
            .sum::<f64>()
            / count
    };
    let centroid = spot
        .centroid
        .map(|c| [c[0] - chief_point[0], c[1] - chief_point[1]]);
    let spot = SpotAbout {
        launched: spot.launched,
        arrived: spot.arrived,
        centroid_mm: centroid,
        rms_radius_about_chief_mm: centroid.map(|_| mean_square([0.0, 0.0]).sqrt()),
        rms_radius_about_centroid_mm: centroid.map(|c| mean_square(c).sqrt()),
        max_radius_about_chief_mm: centroid
            .map(|_| about.iter().map(|p| p[0].hypot(p[1])).fold(0.0, f64::max)),
    };
    let launch = |u: f64, v: f64| {
        [
            u.mul_add(radius, chief.launch[0]),
            v.mul_add(radius, chief.launch[1]),
            0.0,
        ]
    };
    let fan = |along_y: bool| -> Vec<FanRay> {
        let n = options.fan_points.max(2);
        (0..n)
            .map(|k| {
                let pupil = pupil_coordinate(n, k);
                let (u, v) = if along_y { (0.0, pupil) } else { (pupil, 0.0) };
                let ray = tracer.trace(launch(u, v), chief.direction);
                let error_mm = ray.outcome.is_ok().then(|| {
                    let p = tracer.image_coordinates(ray.position);
                    [p[0] - chief_point[0], p[1] - chief_point[1]]
                });
                FanRay { pupil, error_mm }
            })
            .collect()
    };
    let fans = Fans {
        tangential: fan(true),
        sagittal: fan(false),
    };
    let (wave, wave_note) = match wavefront(tracer, options, &chief) {
        Ok(map) => {
            let stats = map.stats();
            let phase = std::f64::consts::TAU * stats.rms_waves;
            (
                Some(PlacedWave {
                    stats,
                    marechal_strehl: (-phase * phase).exp(),
                    reference_radius_mm: map.reference_radius_mm,
                    samples: map.samples,
                }),
                None,
            )
        }
        Err(why) => (None, Some(why)),
    };
    Ok(PlacedField {
        chief: chief.ray,
        spot,
        fans,
        wave,
        wave_note,
    })
}

/// The optical path difference over the pupil about `chief`, to the sphere centred on its image
/// point through its real exit pupil (the mean of the two sections' distances), in waves; or
/// why there is none.
fn wavefront(
    tracer: &PlacedTracer,
    options: &PlacedOptions,
    chief: &Based,
) -> Result<WavefrontMap, String> {
    if !chief.differential.focus().iter().all(|t| t.is_finite()) {
        return Err(
            "the beam about the chief ray leaves collimated (afocal) in a section: no image \
             point to centre a reference sphere on"
                .into(),
        );
    }
    let [to_x, to_y] = chief.differential.exit_pupil_to_image();
    let reference_radius = (to_x + to_y) / 2.0;
    if !reference_radius.is_finite() || reference_radius == 0.0 {
        return Err(
            "the exit pupil lies at infinity (telecentric): no reference sphere centred on the \
             image"
                .into(),
        );
    }
    let wavelength_mm = options.wavelength_nm * 1e-6;
    let [object_index, image_index] = tracer.indices();
    let centre = chief.line.point;
    let start = [chief.launch[0], chief.launch[1], 0.0];
    // The optical path from the plane through the chief ray's start normal to the beam onto
    // the reference sphere, for a ray that ended at `point` along `direction`.
    let to_sphere = |optical_path: f64, start_offset: Vec3, point: Vec3, direction: Vec3| {
        let from_centre = minus(point, centre);
        let b = dot(from_centre, direction);
        let c = dot(from_centre, from_centre) - reference_radius * reference_radius;
        let disc = b.mul_add(b, -c);
        (disc >= 0.0).then(|| {
            // The root on the exit pupil's side of the centre.
            let back = -b - reference_radius.signum() * disc.sqrt();
            object_index * dot(start_offset, chief.direction) + optical_path + image_index * back
        })
    };
    let chief_path = to_sphere(
        chief.optical_path,
        [0.0; 3],
        chief.line.point,
        chief.line.direction,
    )
    .ok_or("the chief ray misses its own reference sphere")?;
    let n = options.wave_samples;
    let radius = options.pupil_diameter / 2.0;
    let chief_point = tracer.image_coordinates(centre);
    let mut opd_waves = vec![None; n * n];
    let mut image_points_mm = vec![None; n * n];
    let mut exit_directions = vec![None; n * n];
    for iy in 0..n {
        for ix in 0..n {
            if !inside_pupil(n, ix, iy) {
                continue;
            }
            let (u, v) = (pupil_coordinate(n, ix), pupil_coordinate(n, iy));
            let offset = [u * radius, v * radius, 0.0];
            let begin = std::array::from_fn(|k| start[k] + offset[k]);
            let path = tracer.trace_path(begin, chief.direction, true);
            if !path.ray.outcome.is_ok() {
                continue;
            }
            let (p, d) = (path.ray.position, path.ray.direction);
            let Some(optical_path) = to_sphere(path.optical_path, offset, p, d) else {
                continue;
            };
            let i = iy * n + ix;
            opd_waves[i] = Some((chief_path - optical_path) / wavelength_mm);
            let q = tracer.image_coordinates(p);
            image_points_mm[i] = Some([q[0] - chief_point[0], q[1] - chief_point[1]]);
            exit_directions[i] = Some(chief.line.frame.map(|e| image_index * dot(d, e)));
        }
    }
    if opd_waves.iter().all(Option::is_none) {
        return Err("no ray of the pupil grid reaches the image".into());
    }
    // The affine pupil-to-direction map of the collimated beam about the chief ray gives the
    // frequency of one sample's lag and the numerical aperture.
    let slope = chief.differential.beam_slope;
    let per_lag = 2.0 * radius / (n - 1) as f64;
    let lag = |i: usize| (slope[i][i] * image_index * per_lag / wavelength_mm).abs();
    let numerical_aperture = image_index * radius * (slope[0][0].abs() + slope[1][1].abs()) / 2.0;
    let field = chief.direction;
    Ok(WavefrontMap {
        wavelength_nm: options.wavelength_nm,
        field_deg: field[0].hypot(field[1]).atan2(field[2]).to_degrees(),
        samples: n,
        opd_waves,
        image_points_mm,
        exit_directions,
        lag_frequency_per_mm: [lag(1), lag(0)],
        mirrored: [slope[1][1] < 0.0, slope[0][0] < 0.0],
        cutoff_per_mm: 2.0 * numerical_aperture / wavelength_mm,
        reference_point_mm: centre,
        reference_radius_mm: reference_radius,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_carried_through_a_fold_mirror_is_reflected_with_the_ray() {
        // A 45-degree mirror sends +z to +y: x stays, y is reflected to +z.
        let point = PathPoint {
            surface: 1,
            position: [0.0; 3],
            direction: [0.0, 1.0, 0.0],
            index: 1.0,
            reflects: true,
        };
        let [x, y] = carried_frame([0.0, 0.0, 1.0], &[point]);
        let near = |a: Vec3, b: Vec3| minus(a, b).iter().all(|v| v.abs() < 1e-15);
        assert!(near(x, [1.0, 0.0, 0.0]), "{x:?}");
        assert!(near(y, [0.0, 0.0, 1.0]), "{y:?}");
        // A refraction turns y with the ray about x instead.
        let bent = PathPoint {
            reflects: false,
            ..point
        };
        let [x, y] = carried_frame([0.0, 0.0, 1.0], &[bent]);
        assert!(near(x, [1.0, 0.0, 0.0]), "{x:?}");
        assert!(near(y, [0.0, 0.0, -1.0]), "{y:?}");
    }
}
