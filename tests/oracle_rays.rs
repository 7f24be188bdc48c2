//! Every exact ray of the oracle files reproduced: status and event surface exactly, every
//! surface crossing within 1e-9 mm and 1e-12 in direction cosines (rayoptics and optiland agree
//! with each other to 1.1e-10 mm and 4e-13 on these rays).

mod common;

use common::{ORACLE_LENSES, load_oracle, num, vec3};
use lensbake::system::LensSystem;
use lensbake::trace::{Apertures, Outcome, Ray, Tracer, Travel, Vec3};
use serde_json::Value;

const POSITION_TOLERANCE_MM: f64 = 1e-9;
const DIRECTION_TOLERANCE: f64 = 1e-12;

fn outcome(status: &str, surface: &Value) -> Outcome {
    let surface = || surface.as_u64().expect("event surface") as usize;
    match status {
        "ok" => Outcome::Ok,
        "vignetted" => Outcome::Vignetted { surface: surface() },
        "tir" => Outcome::Tir { surface: surface() },
        "missed" | "missed_surface" => Outcome::Missed { surface: surface() },
        other => panic!("unknown oracle status {other}"),
    }
}

struct Check<'a> {
    tracer: &'a Tracer,
    vertex_z: Vec<f64>,
    failures: Vec<String>,
    rays: usize,
}

impl Check<'_> {
    fn close(&mut self, id: &str, what: &str, got: Vec3, want: Vec3, tolerance: f64) {
        let worst = (0..3).map(|k| (got[k] - want[k]).abs()).fold(0.0, f64::max);
        // A NaN fails the comparison and is reported too.
        if worst.is_nan() || worst > tolerance {
            self.failures.push(format!(
                "{id}: {what}: got {got:?}, want {want:?} (off by {worst:e})"
            ));
        }
    }

    fn same(&mut self, id: &str, what: &str, got: Outcome, want: Outcome) {
        if got != want {
            self.failures
                .push(format!("{id}: {what}: got {got:?}, want {want:?}"));
        }
    }

    /// Lens-frame point of a surface crossing recorded in the surface's vertex frame.
    fn lens_frame(&self, surface: usize, local: Vec3) -> Vec3 {
        [local[0], local[1], local[2] + self.vertex_z[surface - 1]]
    }

    /// One oracle ray: `start` traced in `travel`, its record's summary and rayoptics path.
    fn ray(&mut self, record: &Value, start: Ray, travel: Travel) {
        self.rays += 1;
        let id = record["id"].as_str().unwrap().to_string();
        let summary = &record["summary"];
        let original = |key: &str| {
            let renumbered = summary[format!("{key}_original_numbering").as_str()].clone();
            if renumbered.is_null() {
                summary[key].clone()
            } else {
                renumbered
            }
        };

        // With apertures: the outcome, and where the ray stopped.
        let checked = self.tracer.trace(start, travel);
        let want = outcome(
            summary["status"].as_str().unwrap(),
            &original("event_surface"),
        );
        self.same(&id, "status with apertures", checked.outcome, want);

        // Without apertures: the whole path, surface by surface.
        let path = self.tracer.trace_path(start, travel, Apertures::Ignored);
        let geometric = outcome(
            summary["geometric_status_ignoring_apertures"]
                .as_str()
                .unwrap(),
            &original("geometric_event_surface"),
        );
        self.same(&id, "geometric status", path.traced.outcome, geometric);
        let recorded: Vec<&Value> = record["rayoptics"]["surfaces"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| {
                s["surface"]
                    .as_u64()
                    .is_some_and(|k| (k as usize) <= self.vertex_z.len())
            })
            .collect();
        // The oracle lists the surface where TIR happens with the arriving direction only.
        let (crossed, tir): (Vec<&Value>, Vec<&Value>) = recorded
            .into_iter()
            .partition(|s| !s["dir_after"].is_null());
        if let [at] = tir[..] {
            let surface = at["surface"].as_u64().unwrap() as usize;
            let point = self.lens_frame(surface, vec3(&at["point_local"]));
            let end = path.traced.ray;
            self.close(
                &id,
                "geometric TIR point",
                end.position(),
                point,
                POSITION_TOLERANCE_MM,
            );
            let incident = vec3(&at["dir_incident"]);
            self.close(
                &id,
                "geometric TIR direction",
                end.direction(),
                incident,
                DIRECTION_TOLERANCE,
            );
        }
        let recorded = crossed;
        if recorded.len() != path.crossings.len() {
            self.failures.push(format!(
                "{id}: crossed {} surfaces, oracle {}",
                path.crossings.len(),
                recorded.len()
            ));
        }
        for (crossing, want) in path.crossings.iter().zip(&recorded) {
            let surface = want["surface"].as_u64().unwrap() as usize;
            let what = format!("surface {surface}");
            if crossing.surface != surface {
                self.failures
                    .push(format!("{id}: crossed {} for {surface}", crossing.surface));
            }
            let point = self.lens_frame(surface, vec3(&want["point_local"]));
            self.close(
                &id,
                &format!("{what} point"),
                crossing.point,
                point,
                POSITION_TOLERANCE_MM,
            );
            let direction = vec3(&want["dir_after"]);
            self.close(
                &id,
                &format!("{what} direction"),
                crossing.direction,
                direction,
                DIRECTION_TOLERANCE,
            );
        }

        // Where the apertured ray stopped: the hit with the arriving direction.
        if let Some(event) = checked.outcome.surface() {
            let k = path.crossings.iter().position(|c| c.surface == event);
            let arriving = match k {
                Some(0) | None if path.crossings.is_empty() => start.direction(),
                Some(0) => start.direction(),
                Some(k) => path.crossings[k - 1].direction,
                None => path.crossings.last().unwrap().direction,
            };
            self.close(
                &id,
                "stop direction",
                checked.ray.direction(),
                arriving,
                DIRECTION_TOLERANCE,
            );
            if let Some(k) = k {
                let at = path.crossings[k].point;
                self.close(
                    &id,
                    "stop point",
                    checked.ray.position(),
                    at,
                    POSITION_TOLERANCE_MM,
                );
            }
        }
        if let Outcome::Tir { surface } = checked.outcome {
            let point = self.lens_frame(surface, vec3(&summary["tir_point_local"]));
            self.close(
                &id,
                "TIR point",
                checked.ray.position(),
                point,
                POSITION_TOLERANCE_MM,
            );
            let incident = vec3(&summary["incident_dir"]);
            self.close(
                &id,
                "TIR direction",
                checked.ray.direction(),
                incident,
                DIRECTION_TOLERANCE,
            );
        }

        // The geometric ray beyond the lens: image plane (forward) or exit plane (backward).
        let end = path.traced.ray;
        if path.traced.outcome.is_ok() {
            for (key, at) in summary.as_object().unwrap() {
                let plane_z = match key.as_str() {
                    "image_plane_point" => num(&summary["image_plane_z"]),
                    k if k.starts_with("point_on_plane_z_") => {
                        k["point_on_plane_z_".len()..].parse().unwrap()
                    }
                    _ => continue,
                };
                let want = vec3(&Value::from(vec![
                    at[0].clone(),
                    at[1].clone(),
                    plane_z.into(),
                ]));
                let got = end.point_at_z(plane_z).expect("ray crosses the plane");
                self.close(&id, key, got, want, POSITION_TOLERANCE_MM);
            }
        }
    }
}

#[test]
fn oracle_rays_reproduced() {
    let mut total = 0;
    let mut report = Vec::new();
    for name in ORACLE_LENSES {
        let oracle = load_oracle(name);
        {
            let lens = oracle.lens();
            let prescription = oracle.prescription.clone();
            let vertex_z = prescription.vertex_z();
            let system = LensSystem::from_prescription(prescription).expect("oracle lens is valid");
            let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
            let mut check = Check {
                tracer: &tracer,
                vertex_z,
                failures: Vec::new(),
                rays: 0,
            };
            for conjugate in ["infinite_conjugate", "finite_conjugate"] {
                for record in lens[conjugate]["real_rays"]["rays"].as_array().unwrap() {
                    let start =
                        Ray::new(vec3(&record["start_point"]), vec3(&record["start_dir"])).unwrap();
                    check.ray(record, start, Travel::Forward);
                }
            }
            for record in lens["sensor_side_rays"]["rays"].as_array().unwrap() {
                let start =
                    Ray::new(vec3(&record["sensor_point"]), vec3(&record["start_dir"])).unwrap();
                check.ray(record, start, Travel::Backward);
            }
            total += check.rays;
            report.extend(check.failures.iter().map(|f| format!("{name}: {f}")));
        }
    }
    assert!(
        report.is_empty(),
        "{} mismatches:\n{}",
        report.len(),
        report.join("\n")
    );
    // 4 lenses: 28-29 infinite, 15 finite and 25 sensor-side rays each.
    assert_eq!(total, 273, "every oracle ray checked");
}
