//! The standard forward ray bundle used to measure throughput: field angle uniform over the
//! traceable field in the y-z plane, pupil point uniform over the paraxial entrance pupil.

use super::aim::traceable_field_deg;
use super::{AimError, Ray, RayBatch, Tracer};
use crate::paraxial::Pupil;
use rand_core::{Rng, SeedableRng};
use rand_xoshiro::SplitMix64;

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
        let mut random = UnitDraws::new(seed);
        (0..n)
            .map(|_| {
                let field = (random.next() * self.max_field_deg).to_radians();
                let radius = 0.5 * self.pupil.diameter * random.next().sqrt();
                let azimuth = std::f64::consts::TAU * random.next();
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

/// Uniform draws in [0, 1) from Steele, Lea and Flood's SplitMix64 (rand_xoshiro's, whose state
/// is the seed itself): tiny, fast, and the same sequence on every machine, so bundles and
/// measurements repeat exactly.
#[derive(Clone, Debug)]
pub(crate) struct UnitDraws(SplitMix64);

impl UnitDraws {
    pub(crate) fn new(seed: u64) -> UnitDraws {
        UnitDraws(SplitMix64::seed_from_u64(seed))
    }

    /// The next draw: the top 53 bits of the next word, scaled exactly into [0, 1).
    pub(crate) fn next(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::UnitDraws;

    /// The draws are Vigna's reference splitmix64.c from seed 0 (words 0xe220a8397b1dcdaf,
    /// 0x6e789e6aa1b965f4, 0x06c45d188009454f, 0xf88bb8a8724c81ec), top 53 bits over 2^53.
    #[test]
    fn draws_follow_the_reference_splitmix64() {
        let mut draws = UnitDraws::new(0);
        let words: [u64; 4] = [
            0xe220_a839_7b1d_cdaf,
            0x6e78_9e6a_a1b9_65f4,
            0x06c4_5d18_8009_454f,
            0xf88b_b8a8_724c_81ec,
        ];
        for word in words {
            assert_eq!(draws.next(), (word >> 11) as f64 / (1u64 << 53) as f64);
        }
    }
}
