//! Table files: round trip, refusal of stale or mismatched tables, and clear errors (no panic)
//! for truncated or corrupted data.

mod common;

use lensbake::lrtf::io::{DATA_FILE, SIDECAR_FILE, Sidecar, TableError, read_table, write_table};
use lensbake::lrtf::param::{CHANNELS, Frame};
use lensbake::lrtf::{
    Entries, FocusRange, Layer, LrtfTable, Parameterisation, Precision, TableInfo,
};
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::pupil::{FocusPupilTable, PupilCircle, PupilTable};

fn singlet(radius: f64) -> Prescription {
    Prescription {
        provenance: Provenance {
            title: "test singlet".into(),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces: vec![
            Surface {
                shape: Shape::from_radius(radius),
                thickness: 5.0,
                medium: Medium::Index(1.5),
                semi_aperture: 10.0,
                stop: Some(StopShape::Circle),
                obscuration: None,
            },
            Surface {
                shape: Shape::from_radius(-radius),
                thickness: 95.0,
                medium: Medium::Air,
                semi_aperture: 10.0,
                stop: None,
                obscuration: None,
            },
        ],
    }
}

fn synthetic_table(precision: Precision) -> LrtfTable {
    let resolution = [5, 4, 3];
    let n: usize = resolution.iter().product();
    // Values spanning several magnitudes, so f16 rounding is visible.
    let entries: Vec<_> = (0..n)
        .map(|k| {
            std::array::from_fn::<f32, CHANNELS, _>(|c| (k * CHANNELS + c) as f32 * 0.137 - 3.0)
        })
        .collect();
    let pupil = PupilTable {
        max_film_radius: 20.0,
        circles: vec![
            PupilCircle {
                centre_x: 0.0,
                radius: 10.0,
            },
            PupilCircle {
                centre_x: -1.5,
                radius: 8.25,
            },
        ],
    };
    LrtfTable {
        info: TableInfo {
            parameterisation: Parameterisation::PupilPlanes,
            resolution,
            precision,
            f_number: 2.0,
            // A 50 mm lens focused at infinity on z = 100: rear focal point there.
            focus: FocusRange {
                far_mm: None,
                near_mm: None,
                rear_focal_z: 100.0,
                front_focal_z: -40.0,
                focal_product: 2500.0,
            },
        },
        layers: vec![Layer {
            wavelength_nm: 587.56,
            frame: Frame {
                rear_plane_z: 5.0,
                film_plane_z: 100.0,
                max_film_radius: 20.0,
                max_rear_radius: 11.0,
                max_polar_angle: 0.3,
            },
            pupil: pupil.clone(),
            sampling: FocusPupilTable::single(100.0, pupil),
            stop_semi_aperture: 10.0,
            entries: Entries::from_row_major(resolution, precision, &entries),
        }],
    }
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("lensbake-lrtf-io-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn write_then_read_round_trips_exactly_in_every_precision() {
    for precision in [Precision::F32, Precision::F16, Precision::U16] {
        let dir = temp_dir(precision.name());
        let table = synthetic_table(precision);
        let lens = singlet(50.0);
        write_table(&table, "singlet", &lens, &dir).unwrap();
        let back = read_table(&dir, Some(&lens)).unwrap();
        assert_eq!(back, table);
        // No temporary files are left behind.
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// A table its reader would refuse (here a film of radius 0) is not written: neither into a
/// new folder nor over a table already there.
#[test]
fn a_table_that_could_not_be_read_back_is_not_written() {
    let lens = singlet(50.0);
    let mut unreadable = synthetic_table(Precision::F32);
    unreadable.layers[0].frame.max_film_radius = 0.0;
    let dir = temp_dir("unreadable");
    let error = write_table(&unreadable, "singlet", &lens, &dir).unwrap_err();
    assert!(matches!(error, TableError::Unreadable { .. }), "{error:?}");
    assert!(error.to_string().contains("max_film_radius = 0"), "{error}");
    assert!(!dir.exists());
    let table = synthetic_table(Precision::F32);
    write_table(&table, "singlet", &lens, &dir).unwrap();
    assert!(write_table(&unreadable, "singlet", &lens, &dir).is_err());
    assert_eq!(read_table(&dir, Some(&lens)).unwrap(), table);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_table_of_another_prescription_is_refused_with_a_rebake_hint() {
    let dir = temp_dir("stale");
    write_table(
        &synthetic_table(Precision::F32),
        "singlet",
        &singlet(50.0),
        &dir,
    )
    .unwrap();
    let error = read_table(&dir, Some(&singlet(51.0))).unwrap_err();
    assert!(matches!(error, TableError::StaleHash { .. }), "{error:?}");
    let message = error.to_string();
    assert!(message.contains("lensbake bake singlet --out"), "{message}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_table_of_another_version_is_refused() {
    let dir = temp_dir("version");
    let lens = singlet(50.0);
    write_table(&synthetic_table(Precision::F32), "singlet", &lens, &dir).unwrap();
    let sidecar = dir.join(SIDECAR_FILE);
    let text = std::fs::read_to_string(&sidecar).unwrap();
    std::fs::write(
        &sidecar,
        text.replace("parameterisation_version: 1", "parameterisation_version: 0"),
    )
    .unwrap();
    let error = read_table(&dir, Some(&lens)).unwrap_err();
    assert!(
        matches!(
            error,
            TableError::Version {
                found: 0,
                expected: 1,
                ..
            }
        ),
        "{error:?}"
    );
    assert!(error.to_string().contains("rebake"), "{error}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn truncated_corrupted_and_mismatched_files_give_errors_not_panics() {
    let lens = singlet(50.0);
    let dir = temp_dir("broken");
    write_table(&synthetic_table(Precision::F32), "singlet", &lens, &dir).unwrap();
    let data = dir.join(DATA_FILE);
    let original = std::fs::read(&data).unwrap();

    std::fs::write(&data, &original[..original.len() / 2]).unwrap();
    let error = read_table(&dir, Some(&lens)).unwrap_err();
    assert!(
        matches!(error, TableError::Data { .. }),
        "truncated: {error:?}"
    );

    let mut corrupted = original.clone();
    for byte in corrupted.iter_mut().skip(8).step_by(7) {
        *byte ^= 0x5a;
    }
    std::fs::write(&data, &corrupted).unwrap();
    let error = read_table(&dir, Some(&lens)).unwrap_err();
    assert!(
        matches!(error, TableError::Data { .. }),
        "corrupted: {error:?}"
    );

    // A sidecar whose resolution disagrees with the data names both sizes.
    std::fs::write(&data, &original).unwrap();
    let sidecar = dir.join(SIDECAR_FILE);
    let text = std::fs::read_to_string(&sidecar).unwrap();
    std::fs::write(
        &sidecar,
        common::sealed(&text.replacen("resolution: (5, 4, 3)", "resolution: (5, 4, 4)", 1)),
    )
    .unwrap();
    let error = read_table(&dir, Some(&lens)).unwrap_err();
    assert!(error.to_string().contains("needs 5x16"), "{error}");

    std::fs::write(&sidecar, "not ron at all (").unwrap();
    let error = read_table(&dir, Some(&lens)).unwrap_err();
    assert!(matches!(error, TableError::Sidecar { .. }), "{error:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Channel names carry their layer (`wl0.exit.x`, format 5), and a format-4 table (bare
/// `exit.x` in the part `wl0`; tests/data/lrtf-format-4 was baked by the lensbake before the
/// change with the same command) still reads, to the same table.
#[cfg(feature = "cli")]
#[test]
fn channels_are_named_by_layer_and_format_4_tables_still_read() {
    let dir = temp_dir("format-5");
    let out = common::lensbake(&[
        "bake",
        "cooke-triplet",
        "--resolution",
        "4",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let fresh = read_table(&dir, None).unwrap();
    let old = read_table(&common::test_data("lrtf-format-4"), None).unwrap();
    assert_eq!(old, fresh);
    let data = std::fs::read(dir.join(DATA_FILE)).unwrap();
    let names_channel = |name: &str| data.windows(name.len()).any(|w| w == name.as_bytes());
    for channel in lensbake::lrtf::param::CHANNEL_NAMES {
        assert!(names_channel(&format!("wl0.{channel}\0")), "{channel}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A u16 table's file holds its codes and its sidecar the quantisation that decodes them; a
/// sidecar without it, or with one that cannot decode, and a damaged data file are refused by
/// name, never read as a different table.
#[test]
fn a_u16_table_needs_its_quantisation_and_intact_codes() {
    let lens = singlet(50.0);
    let dir = temp_dir("u16");
    let table = synthetic_table(Precision::U16);
    write_table(&table, "singlet", &lens, &dir).unwrap();
    let sidecar = dir.join(SIDECAR_FILE);
    let text = std::fs::read_to_string(&sidecar).unwrap();
    assert!(text.contains("quantisation: Some("), "{text}");
    let data = dir.join(DATA_FILE);
    let original = std::fs::read(&data).unwrap();
    let edited = |edit: &dyn Fn(&mut Sidecar)| {
        let mut sidecar: Sidecar = ron::from_str(&text).unwrap();
        edit(&mut sidecar);
        common::sealed(&ron::ser::to_string_pretty(&sidecar, Default::default()).unwrap())
    };
    std::fs::write(&sidecar, edited(&|s| s.layers[0].quantisation = None)).unwrap();
    let error = read_table(&dir, Some(&lens)).unwrap_err();
    assert!(
        error.to_string().contains("needs wl0.quantisation"),
        "{error}"
    );

    let negative_step = edited(&|s| {
        if let Some(q) = &mut s.layers[0].quantisation {
            q.step[2] = -q.step[2] - 1.0;
        }
    });
    std::fs::write(&sidecar, negative_step).unwrap();
    let error = read_table(&dir, Some(&lens)).unwrap_err();
    assert!(
        error.to_string().contains("cannot decode a table"),
        "{error}"
    );

    std::fs::write(&sidecar, &text).unwrap();
    let mut damaged = original.clone();
    let last = damaged.len() - 3;
    damaged[last] ^= 0x40;
    std::fs::write(&data, &damaged).unwrap();
    let error = read_table(&dir, Some(&lens)).unwrap_err();
    assert!(
        matches!(error, TableError::DataMismatch { .. }),
        "{error:?}"
    );

    std::fs::write(&data, &original).unwrap();
    assert_eq!(read_table(&dir, Some(&lens)).unwrap(), table);
    std::fs::remove_dir_all(&dir).unwrap();
}
