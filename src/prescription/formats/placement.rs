//! Decentres, tilts and coordinate breaks as Zemax and CODE V files write them, and the centred
//! lens they describe.
//!
//! A reader records where each surface sits ([`Placement`]); [`centre_if_placed`] walks the surfaces in
//! three dimensions and rewrites the lens as the centred system lensbake models, when that is
//! exact:
//! - a plane mirror tilted to the axis whose following surfaces sit on the reflected axis is a
//!   pure fold: reflecting everything after it through its plane (unfolding) changes no ray, so
//!   the mirror becomes a plane in the medium it was met in (for a stated clear aperture, the
//!   circle inscribed in the mirror's elliptical footprint, r·cos θ);
//! - a plane between two equal media with no stated aperture (a coordinate break, a dummy)
//!   bends no ray, so its tilt or decentre is dropped and it keeps its vertex's place along the
//!   axis;
//! - decentres that return (CODE V `DAR`, `REV`, a Zemax break undone by another) leave the
//!   later surfaces on the axis again.
//!
//! Anything else off the axis (a tilted lens or curved mirror, a decentred stop, a tilted image
//! plane) is refused with the surface and line: lensbake's paraxial, Seidel, pupil, bake and
//! render code all need a rotationally symmetric system.
//!
//! Conventions: a frame maps local to global coordinates, x_g = R x_l + o. Tilts are right-handed
//! rotations (degrees) about x, then the new y, then the new z (Zemax's "tilt about x, y, z";
//! CODE V's alpha and beta are left-handed, so the CODE V reader negates them).

use super::super::error::{Location, PrescriptionError, Problem};
use super::super::model::{Medium, Prescription, Shape};
use super::{LoadNote, Source};

/// How a decentre moves the frames of its surface and of the surfaces after it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum PlacementKind {
    /// Decentre, then tilt; the surface and every later one use the moved frame (CODE V's
    /// basic decentre, a Zemax coordinate break with order 0).
    Basic,
    /// Tilt about z, the new y and the new x, then decentre: the inverse of `Basic` with the
    /// values negated (a Zemax coordinate break with order flag 1).
    TiltThenDecentre,
    /// The surface only; the frame after it is the one before (CODE V `DAR`).
    DecentreAndReturn,
    /// As `Basic`, and the frame after the surface turns by the tilt once more, so that after a
    /// fold mirror the axis follows the reflected ray (CODE V `BEN`).
    Bend,
    /// The surface stays in the incoming frame; after it the frame moves by the inverse of a
    /// basic decentre with these values (CODE V `REV`).
    Reverse,
}

/// One surface's decentre and tilt as its file states them.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Placement {
    pub kind: PlacementKind,
    /// Vertex decentre x, y, z in the file's length unit.
    pub decentre: [f64; 3],
    /// Right-handed tilts in degrees about x, the new y and the new z.
    pub tilt_deg: [f64; 3],
    /// Where the file states it, for errors: line and keyword; and the line and keyword of
    /// each decentre component it states.
    pub line: usize,
    pub keyword: String,
    pub decentre_at: [Option<(usize, &'static str)>; 3],
}

impl Placement {
    pub fn new(kind: PlacementKind, line: usize, keyword: &str) -> Placement {
        Placement {
            kind,
            decentre: [0.0; 3],
            tilt_deg: [0.0; 3],
            line,
            keyword: keyword.to_string(),
            decentre_at: [None; 3],
        }
    }

    /// The frame of the surface in the incoming frame, and the frame after it in the surface's.
    fn frames(&self, mm_per_unit: f64) -> (Frame, Frame) {
        let d = self.decentre.map(|v| v * mm_per_unit);
        let [a, b, c] = self.tilt_deg.map(f64::to_radians);
        let tilt = mul(mul(rot_x(a), rot_y(b)), rot_z(c));
        let basic = Frame::translation(d).then(&Frame::rotation(tilt));
        match self.kind {
            PlacementKind::Basic => (basic, Frame::IDENTITY),
            PlacementKind::TiltThenDecentre => (
                Frame::rotation(mul(mul(rot_z(c), rot_y(b)), rot_x(a)))
                    .then(&Frame::translation(d)),
                Frame::IDENTITY,
            ),
            PlacementKind::DecentreAndReturn => (basic, basic.inverse()),
            PlacementKind::Bend => (basic, Frame::rotation(tilt)),
            PlacementKind::Reverse => (Frame::IDENTITY, basic.inverse()),
        }
    }
}

type Matrix = [[f64; 3]; 3];

fn rot_x(a: f64) -> Matrix {
    let (s, c) = a.sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
}

fn rot_y(a: f64) -> Matrix {
    let (s, c) = a.sin_cos();
    [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
}

fn rot_z(a: f64) -> Matrix {
    let (s, c) = a.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

fn mul(a: Matrix, b: Matrix) -> Matrix {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum()))
}

fn apply(m: &Matrix, v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| (0..3).map(|k| m[r][k] * v[k]).sum())
}

fn transpose(m: &Matrix) -> Matrix {
    std::array::from_fn(|r| std::array::from_fn(|c| m[c][r]))
}

/// A coordinate frame: x_parent = linear x_local + origin. `linear` is a rotation, or after an
/// unfolding a rotation times a reflection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub linear: [[f64; 3]; 3],
    pub origin: [f64; 3],
}

impl Frame {
    pub const IDENTITY: Frame = Frame {
        linear: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        origin: [0.0; 3],
    };

    fn translation(d: [f64; 3]) -> Frame {
        Frame {
            origin: d,
            ..Frame::IDENTITY
        }
    }

    fn rotation(linear: Matrix) -> Frame {
        Frame {
            linear,
            origin: [0.0; 3],
        }
    }

    /// `child` given in this frame's coordinates, expressed in this frame's parent.
    fn then(&self, child: &Frame) -> Frame {
        let moved = apply(&self.linear, child.origin);
        Frame {
            linear: mul(self.linear, child.linear),
            origin: std::array::from_fn(|k| moved[k] + self.origin[k]),
        }
    }

    /// The inverse of a rigid motion (its linear part orthogonal).
    fn inverse(&self) -> Frame {
        let linear = transpose(&self.linear);
        let back = apply(&linear, self.origin);
        Frame {
            linear,
            origin: back.map(|v| -v),
        }
    }

    /// A point given in the parent's coordinates, in this frame's.
    pub fn point_to_local(&self, point: [f64; 3]) -> [f64; 3] {
        let offset: [f64; 3] = std::array::from_fn(|k| point[k] - self.origin[k]);
        apply(&transpose(&self.linear), offset)
    }

    /// A direction given in the parent's coordinates, in this frame's.
    pub fn direction_to_local(&self, direction: [f64; 3]) -> [f64; 3] {
        apply(&transpose(&self.linear), direction)
    }

    /// A point given in this frame's coordinates, in the parent's.
    pub fn point_to_parent(&self, point: [f64; 3]) -> [f64; 3] {
        let turned = apply(&self.linear, point);
        std::array::from_fn(|k| turned[k] + self.origin[k])
    }

    /// A direction given in this frame's coordinates, in the parent's.
    pub fn direction_to_parent(&self, direction: [f64; 3]) -> [f64; 3] {
        apply(&self.linear, direction)
    }

    /// The frame's z axis in the parent's coordinates.
    pub fn axis(&self) -> [f64; 3] {
        [self.linear[0][2], self.linear[1][2], self.linear[2][2]]
    }
}

/// A clear aperture that is not a circle centred on its surface's axis: a rectangle, or a
/// decentred circle or rectangle (off-axis segments of a mirror). Lengths in mm, in the
/// surface's own frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ApertureOutline {
    pub shape: OutlineShape,
    /// Where the aperture's centre sits (x, y); a central obscuration on the surface is centred
    /// there too (OpticStudio and CODE V decentre a surface's apertures together).
    pub centre: [f64; 2],
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OutlineShape {
    Circle {
        radius: f64,
    },
    Rectangle {
        half_width: f64,
        half_height: f64,
    },
    /// Semi-axes along x (`half_width`) and y (`half_height`).
    Ellipse {
        half_width: f64,
        half_height: f64,
    },
}

impl ApertureOutline {
    /// The outline with every length multiplied by `factor` (a file's unit to mm).
    fn scaled(&self, factor: f64) -> ApertureOutline {
        let mut shape = self.shape;
        match &mut shape {
            OutlineShape::Circle { radius } => *radius *= factor,
            OutlineShape::Rectangle {
                half_width,
                half_height,
            }
            | OutlineShape::Ellipse {
                half_width,
                half_height,
            } => {
                *half_width *= factor;
                *half_height *= factor;
            }
        }
        ApertureOutline {
            shape,
            centre: self.centre.map(|v| v * factor),
        }
    }

    /// The largest distance (mm) from the surface's axis of a point inside the aperture.
    pub fn reach(&self) -> f64 {
        let half_diagonal = match self.shape {
            OutlineShape::Circle { radius } => radius,
            OutlineShape::Rectangle {
                half_width,
                half_height,
            } => half_width.hypot(half_height),
            OutlineShape::Ellipse {
                half_width,
                half_height,
            } => half_width.max(half_height),
        };
        self.centre[0].hypot(self.centre[1]) + half_diagonal
    }

    /// Whether a point (x, y) of the surface's frame passes the aperture.
    pub fn passes(&self, x: f64, y: f64) -> bool {
        let (u, v) = (x - self.centre[0], y - self.centre[1]);
        match self.shape {
            OutlineShape::Circle { radius } => u.mul_add(u, v * v) <= radius * radius,
            OutlineShape::Rectangle {
                half_width,
                half_height,
            } => u.abs() <= half_width && v.abs() <= half_height,
            OutlineShape::Ellipse {
                half_width,
                half_height,
            } => {
                let (p, q) = (u / half_width, v / half_height);
                p.mul_add(p, q * q) <= 1.0
            }
        }
    }
}

/// An outline as a reader found it: in the file's length unit, with the line and keyword that
/// made it other than a centred circle.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct StatedOutline {
    pub outline: ApertureOutline,
    pub line: usize,
    pub keyword: String,
}

impl StatedOutline {
    /// What makes the aperture break the lens's symmetry, for the refusal.
    fn offence(&self, surface: usize) -> String {
        let [x, y] = self.outline.centre;
        let shape = match self.outline.shape {
            OutlineShape::Circle { .. } => "circular",
            OutlineShape::Rectangle { .. } => "rectangular",
            OutlineShape::Ellipse { .. } => "elliptical",
        };
        if x == 0.0 && y == 0.0 {
            format!("surface {surface} has a {shape} clear aperture")
        } else {
            format!(
                "surface {surface} has a {shape} clear aperture decentred {:.6} mm from its axis",
                x.hypot(y)
            )
        }
    }
}

/// A toroid as a reader found it: the y-z curve is the surface's shape, turned about a line
/// parallel to y at `rotation_radius` from the vertex (file units; infinite for a cylinder).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct StatedToroid {
    pub rotation_radius: f64,
    pub line: usize,
}

/// What a reader found on a surface that no rotationally symmetric lens holds.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Asymmetry {
    pub outline: Option<StatedOutline>,
    pub toroid: Option<StatedToroid>,
}

/// A lens whose file places surfaces off one common axis where no centred lens describes it
/// exactly (a tilted lens or curved mirror, a decentred stop, a tilted image plane), as the file
/// writes it: what [`crate::trace::placed::PlacedTracer`] traces in three dimensions. Carried by
/// [`Problem::NotRotationallySymmetric`], the error every reader returns for such a file, since
/// everything else in lensbake needs a rotationally symmetric lens.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedLens {
    /// The file's surfaces in mm, each shape in its own frame. Thicknesses are as written; they
    /// place nothing here (`frames` does). A coordinate break is a plane in the medium it sits in.
    pub prescription: Prescription,
    /// Each surface's frame in the frame of surface 1 before any decentre (the object side's
    /// axis is its z axis): the vertex at `origin`, the surface's own axis along `axis()`.
    pub frames: Vec<Frame>,
    /// The image plane's frame.
    pub image: Frame,
    /// Whether each surface's semi-aperture is a clear aperture the file states (Zemax `CLAP`,
    /// CODE V `CIR`), which clips rays; a Zemax `DIAM` only records the beam's extent, and a
    /// surface without either clips nothing.
    pub clips: Vec<bool>,
    /// Each surface's clear aperture where it is rectangular or decentred (it replaces the
    /// semi-aperture there).
    pub outlines: Vec<Option<ApertureOutline>>,
    /// For a toroid, the radius (mm) of the circle its y-z curve (the surface's shape, read in
    /// y) turns on about a line parallel to y; infinite for a cylinder.
    pub rotation_radii: Vec<Option<f64>>,
}

/// Largest sine of the angle between a centred surface's axis and the lens axis, and largest
/// distance of its vertex from the axis per mm of lens: rounding in the sines and cosines of the
/// file's angles stays orders of magnitude below these, a real tilt or decentre far above.
const AXIS_TOLERANCE: f64 = 1e-12;
const OFFSET_TOLERANCE: f64 = 1e-10;

/// The centred lens a file's placements describe, for a reader: nothing when the file places no
/// surface; otherwise `prescription` (in mm, thicknesses and curvatures as the file writes them
/// in each surface's own frame) rewritten as the centred lens that `placements` (one per
/// surface) and `image_placement` describe, and the note saying what was done; or the lens
/// refused where no centred lens describes it exactly. `derived` lists the 0-based surfaces
/// whose clear aperture the file does not state (they are sized later, on the centred lens, so
/// they cannot clip where the file's would not). `envelopes` lists those whose stated aperture
/// only records the beam's extent and clips no ray (Zemax `DIAM`): an unfolded fold mirror whose
/// envelope lies off the axis joins `derived` instead of being refused. `asymmetries` (one per
/// surface) lists the toroids and non-circular or decentred apertures the file states; any of
/// them leaves the lens to the 3-D trace even when its geometry is centred.
#[allow(clippy::too_many_arguments)]
pub(super) fn centre_if_placed(
    prescription: &mut Prescription,
    placements: &[Option<Placement>],
    image_placement: Option<&Placement>,
    asymmetries: &[Asymmetry],
    derived: &mut Vec<usize>,
    envelopes: &[usize],
    mm_per_unit: f64,
    lines: &[usize],
    image_line: usize,
    source: &Source,
) -> Result<Option<LoadNote>, PrescriptionError> {
    if placements.iter().all(Option::is_none)
        && image_placement.is_none()
        && asymmetries.iter().all(|a| *a == Asymmetry::default())
    {
        return Ok(None);
    }
    let as_written = prescription.clone();
    let object_medium = &prescription.object_medium;
    let surfaces = &mut prescription.surfaces;
    let stated_aperture: Vec<bool> = (0..surfaces.len()).map(|i| !derived.contains(&i)).collect();
    let clips: Vec<bool> = (0..surfaces.len())
        .map(|i| stated_aperture[i] && !envelopes.contains(&i))
        .collect();
    // Each surface's frame in the frame of surface 1, as the file places it.
    let mut frames = Vec::with_capacity(surfaces.len() + 1);
    let mut incoming = Frame::IDENTITY;
    for (surface, placement) in surfaces.iter().zip(placements) {
        let (before, after) = placement
            .as_ref()
            .map_or((Frame::IDENTITY, Frame::IDENTITY), |p| {
                p.frames(mm_per_unit)
            });
        let frame = incoming.then(&before);
        frames.push(frame);
        incoming = frame
            .then(&after)
            .then(&Frame::translation([0.0, 0.0, surface.thickness]));
    }
    let image_frame =
        incoming.then(&image_placement.map_or(Frame::IDENTITY, |p| p.frames(mm_per_unit).0));
    let surface_count = surfaces.len();
    // Where to report surface i (the image plane for i = surface_count): the line of its own
    // placement when it has one, else its own line; the keyword of the placement that moved it
    // (its own, else the nearest before it).
    let own = |i: usize| placements.get(i).map_or(image_placement, Option::as_ref);
    let locate = |i: usize, field: &str| {
        let line = own(i).map_or_else(|| lines.get(i).copied().unwrap_or(image_line), |p| p.line);
        let location = source.location(Some(line)).with_field(field);
        if i < surface_count {
            location.with_surface(i + 1)
        } else {
            location
        }
    };
    // A decentre beyond the lens frame's reach overflowed the 3-D trace's squares (a 1e300 mm
    // `YDE` printed an infinite RMS spot).
    let stated = placements
        .iter()
        .map(Option::as_ref)
        .chain([image_placement]);
    for (i, placement) in stated.enumerate() {
        let Some(placement) = placement else { continue };
        for (value, at) in placement.decentre.iter().zip(placement.decentre_at) {
            let Some((line, keyword)) = at else { continue };
            crate::limits::check_position("the decentre (mm)", value * mm_per_unit).map_err(
                |e| {
                    let location = locate(i, keyword);
                    PrescriptionError::new(
                        Location {
                            line: Some(line),
                            ..location
                        },
                        e.into(),
                    )
                },
            )?;
        }
    }
    // Readers give one entry per surface, in the file's length unit.
    let scaled_outlines: Vec<Option<ApertureOutline>> = asymmetries
        .iter()
        .map(|a| a.outline.as_ref().map(|o| o.outline.scaled(mm_per_unit)))
        .collect();
    let rotation_radii: Vec<Option<f64>> = asymmetries
        .iter()
        .map(|a| a.toroid.as_ref().map(|t| t.rotation_radius * mm_per_unit))
        .collect();
    let off_axis = |location: Location, offence: String| {
        PrescriptionError::new(
            location,
            Problem::NotRotationallySymmetric {
                offence,
                lens: Box::new(PlacedLens {
                    prescription: as_written.clone(),
                    frames: frames.clone(),
                    image: image_frame,
                    clips: clips.clone(),
                    outlines: scaled_outlines.clone(),
                    rotation_radii: rotation_radii.clone(),
                }),
            },
        )
    };
    let refuse = |i: usize, why: String| {
        let keyword = own(i)
            .or_else(|| {
                placements[..i.min(surface_count)]
                    .iter()
                    .rev()
                    .flatten()
                    .next()
            })
            .map_or("thickness".to_string(), |p| p.keyword.clone());
        off_axis(locate(i, &keyword), format!("{why} (moved by `{keyword}`)"))
    };
    let name = |i: usize| {
        if i < surface_count {
            format!("surface {}", i + 1)
        } else {
            "the image plane".to_string()
        }
    };

    // Decentres of 1e300 mm or thicknesses that overflow along a tilted axis: refused before
    // any comparison with infinity or NaN could pass a surface as centred.
    let overflow = frames.iter().chain([&image_frame]).position(|f| {
        !(f.origin.iter().all(|v| v.is_finite())
            && f.linear.iter().flatten().all(|v| v.is_finite()))
    });
    if let Some(i) = overflow {
        return Err(PrescriptionError::new(
            locate(i, "thickness"),
            Problem::Unsupported(format!(
                "the decentres, tilts and thicknesses place {} beyond any finite position",
                name(i)
            )),
        ));
    }
    let scale = 1.0
        + frames
            .iter()
            .chain([&image_frame])
            .map(|f| f.origin.iter().fold(0.0_f64, |m, v| m.max(v.abs())))
            .fold(0.0, f64::max);
    // Whether a frame (as unfolded) leaves the axis: tilted, decentred, and the message.
    let leaves_axis = |i: usize, frame: &Frame| -> Option<String> {
        let axis = frame.axis();
        let offset = frame.origin[0].hypot(frame.origin[1]);
        let tilted = axis[0].hypot(axis[1]) > AXIS_TOLERANCE;
        let off_axis = offset > OFFSET_TOLERANCE * scale;
        let tilt = axis[0].hypot(axis[1]).atan2(axis[2].abs()).to_degrees();
        let name = name(i);
        match (tilted, off_axis) {
            (false, false) => None,
            (true, true) => Some(format!(
                "{name} is tilted {tilt:.6} deg to the axis and its vertex lies {offset:.6} mm \
                 off it"
            )),
            (true, false) => Some(format!("{name} is tilted {tilt:.6} deg to the axis")),
            (false, true) => Some(format!("{name} is decentred {offset:.6} mm from the axis")),
        }
    };

    // Unfold: `unfolding` maps the file's space to one where every fold so far is straightened.
    let mut unfolding = Frame::IDENTITY;
    let mut vertex_z = Vec::with_capacity(surface_count + 1);
    // Tilted plane mirrors unfolded (1-based).
    let mut folds = Vec::new();
    let mut medium_before = object_medium.clone();
    for (i, surface) in surfaces.iter_mut().enumerate() {
        let frame = unfolding.then(&frames[i]);
        let axis = frame.axis();
        let [x, y, z] = frame.origin;
        let plane = surface.shape == Shape::Plane;
        let is_mirror = surface.medium == Medium::Mirror;
        let Some(offence) = leaves_axis(i, &frame) else {
            // On the axis; facing -z after an odd number of unfoldings, so its profile flips.
            if axis[2] < 0.0 {
                surface.shape = surface.shape.mirrored();
            }
            vertex_z.push(z);
            if !is_mirror {
                medium_before = surface.medium.clone();
            }
            continue;
        };
        let tilted = axis[0].hypot(axis[1]) > AXIS_TOLERANCE;
        if plane && is_mirror && tilted && axis[2].abs() > AXIS_TOLERANCE {
            let off_axis = stated_aperture[i] && x.hypot(y) > OFFSET_TOLERANCE * scale;
            if off_axis && envelopes.contains(&i) {
                derived.push(i);
            } else if off_axis {
                return Err(refuse(
                    i,
                    format!(
                        "{} is a fold mirror whose stated clear aperture is centred {:.6} mm off \
                         the axis",
                        name(i),
                        x.hypot(y)
                    ),
                ));
            }
            if surface.stop.is_some() || surface.obscuration.is_some() {
                return Err(refuse(
                    i,
                    format!(
                        "{} is a fold mirror that is also the stop or obscured",
                        name(i)
                    ),
                ));
            }
            // Reflect everything after it through its plane, which crosses the axis here.
            let crossing = z + (axis[0] * x + axis[1] * y) / axis[2];
            let reflect: Matrix = std::array::from_fn(|r| {
                std::array::from_fn(|c| f64::from(u8::from(r == c)) - 2.0 * axis[r] * axis[c])
            });
            let offset = 2.0 * axis[2] * crossing;
            unfolding = Frame {
                linear: reflect,
                origin: axis.map(|n| n * offset),
            }
            .then(&unfolding);
            surface.medium = medium_before.clone();
            if stated_aperture[i] && !derived.contains(&i) {
                surface.semi_aperture *= axis[2].abs();
            }
            folds.push(i + 1);
            vertex_z.push(crossing);
        } else if plane
            && !is_mirror
            && surface.medium == medium_before
            && !stated_aperture[i]
            && surface.stop.is_none()
            && surface.obscuration.is_none()
        {
            // A plane that bends no ray: where it sits along the axis changes no ray, so it
            // keeps its vertex's place in the sequence.
            vertex_z.push(z);
        } else {
            return Err(refuse(i, offence));
        }
    }
    derived.sort_unstable();
    let image = unfolding.then(&image_frame);
    if let Some(offence) = leaves_axis(surface_count, &image) {
        return Err(refuse(surface_count, offence));
    }
    // The geometry is centred; a toroid or an aperture that is not still makes the lens
    // asymmetric.
    for (i, asymmetry) in asymmetries.iter().enumerate() {
        if let Some(toroid) = &asymmetry.toroid {
            let location = source
                .location(Some(toroid.line))
                .with_surface(i + 1)
                .with_field("TYPE TOROIDAL");
            let what = if toroid.rotation_radius.is_infinite() {
                "a cylinder"
            } else {
                "a toroid"
            };
            return Err(off_axis(location, format!("surface {} is {what}", i + 1)));
        }
        if let Some(stated) = &asymmetry.outline {
            let location = source
                .location(Some(stated.line))
                .with_surface(i + 1)
                .with_field(stated.keyword.clone());
            return Err(off_axis(location, stated.offence(i + 1)));
        }
    }
    vertex_z.push(image.origin[2]);
    for (i, surface) in surfaces.iter_mut().enumerate() {
        surface.thickness = vertex_z[i + 1] - vertex_z[i];
    }
    Ok(Some(LoadNote::Centred { folds }))
}
