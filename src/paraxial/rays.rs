//! Paraxial ray trace surface by surface.

use super::matrix::{paraxial_curvature, surface_power};
use crate::system::SystemAt;
use serde::Serialize;

/// A paraxial ray at one surface. Slopes are real slopes dy/dz (not reduced), positive when
/// the ray climbs; `incidence` is the refraction invariant A = n i = n' i'.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RayAtSurface {
    /// Height at the vertex plane (mm).
    pub y: f64,
    /// Slope in the medium before the surface.
    pub u_before: f64,
    /// Slope in the medium after the surface.
    pub u_after: f64,
    /// n i with i = u + y c the paraxial angle of incidence.
    pub incidence: f64,
}

/// A paraxial ray through the whole system.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParaxialRay {
    /// One entry per surface, in order.
    pub surfaces: Vec<RayAtSurface>,
    #[serde(skip)]
    z_last_vertex: f64,
}

impl ParaxialRay {
    /// Traces the ray that meets the vertex plane of surface 1 at height `y` with slope `u`
    /// in object space.
    pub fn trace(system: &SystemAt, y: f64, u: f64) -> ParaxialRay {
        let mut height = y;
        let mut optical_slope = system.object_index * u;
        let mut surfaces = Vec::with_capacity(system.surfaces.len());
        for (i, surface, n_before, n_after) in system.path() {
            let u_before = optical_slope / n_before;
            let incidence = n_before * (u_before + height * paraxial_curvature(&surface.shape));
            optical_slope -= height * surface_power(system, i);
            let u_after = optical_slope / n_after;
            surfaces.push(RayAtSurface {
                y: height,
                u_before,
                u_after,
                incidence,
            });
            if i + 1 < system.surfaces.len() {
                height += surface.thickness * u_after;
            }
        }
        ParaxialRay {
            surfaces,
            z_last_vertex: system.last_vertex_z(),
        }
    }

    /// Slope in object space.
    pub fn object_slope(&self) -> f64 {
        self.surfaces[0].u_before
    }

    /// Slope in image space.
    pub fn image_slope(&self) -> f64 {
        self.last().u_after
    }

    /// Height at surface 1's vertex plane.
    pub fn first_height(&self) -> f64 {
        self.surfaces[0].y
    }

    /// Height at the last vertex plane.
    pub fn last_height(&self) -> f64 {
        self.last().y
    }

    fn last(&self) -> &RayAtSurface {
        self.surfaces
            .last()
            .expect("a system has at least one surface")
    }

    /// Height in object space at axial position `z` (the straight line before surface 1).
    pub fn object_space_height(&self, z: f64) -> f64 {
        self.first_height() + self.object_slope() * z
    }

    /// Height in image space at axial position `z` (the straight line after the last surface).
    pub fn image_space_height(&self, z: f64) -> f64 {
        self.last_height() + self.image_slope() * (z - self.z_last_vertex)
    }
}
