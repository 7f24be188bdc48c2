//! The standard forward ray bundle used to measure throughput: field angle uniform over the
//! traceable field in the y-z plane, pupil point uniform over the paraxial entrance pupil.

use super::aim::traceable_field_deg;
use super::{AimError, Ray, RayBatch, Tracer};
use crate::paraxial::Pupil;

/// Scan step (degrees) when searching for the traceable field.
const FIELD_SCAN_DEG: f64 = 0.5;

/// A collimated-beam bundle over a field range and the entrance pupil.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldBundle {
    /// Field angles are drawn from [0, max_field_deg].
    pub max_field_deg: f64,
    /// The paraxial entrance pupil the stop fills.
    pub pupil: Pupil,
    /// Plane the rays start on.
    pub start_z: f64,
}

impl FieldBundle {
    /// The bundle over the lens's whole traceable field (see [`traceable_field_deg`]); fails
    /// when the entrance pupil lies at infinity.
    pub fn over_traceable_field(tracer: &Tracer) -> Result<FieldBundle, AimError> {
        Ok(FieldBundle {
            pupil: tracer
                .paraxial_entrance_pupil()
                .ok_or(AimError::EntrancePupilAtInfinity)?,
            max_field_deg: traceable_field_deg(tracer, FIELD_SCAN_DEG),
            start_z: tracer.front_start_z(),
        })
    }

    /// `n` rays drawn with a fixed-seed generator, so runs are repeatable. Pupil points are
    /// uniform in area (radius from the square root of a uniform number).
    pub fn sample(&self, n: usize, seed: u64) -> RayBatch {
        let mut random = SplitMix64(seed);
        (0..n)
            .map(|_| {
                let field = (random.unit() * self.max_field_deg).to_radians();
                let radius = 0.5 * self.pupil.diameter * random.unit().sqrt();
                let azimuth = std::f64::consts::TAU * random.unit();
                let direction = [0.0, field.sin(), field.cos()];
                let back = (self.pupil.z - self.start_z) / direction[2];
                let position = [
                    radius * azimuth.cos(),
                    radius * azimuth.sin() - back * direction[1],
                    self.start_z,
                ];
                Ray::new(position, direction).expect("finite start and unit direction")
            })
            .collect()
    }
}

/// Steele, Lea and Flood's SplitMix64: tiny, fast, and good enough to spread rays.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}
