//! Table files: `lrtf.exr` (entries) and `lrtf.ron` (sidecar: meaning, domain, pupil, hashes).
//! Layout in docs/lrtf.md. Both files go through the one atomic writer ([`crate::output`]), so a
//! reader never sees half a file. The sidecar records the CRC-32 of the data file's bytes and a
//! CRC-32 of its own fields, so a table verifies as a whole: the data of one bake is never paired
//! with the sidecar of another, and an edited sidecar field is refused.
//!
//! The two files cannot be renamed together, so a re-bake first keeps the old data under
//! `.lrtf.exr.<its CRC-32>.previous` (a hard link); a writer killed after the new data replaced
//! the old but before the new sidecar did leaves the old sidecar, whose data the reader then
//! finds there. The directory is shared with focus-range subdirectories, so it is not published
//! as a whole.

use std::path::{Path, PathBuf};

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, ImageAttributes, IntegerBounds,
    LayerAttributes, ReadChannels, ReadLayers, SmallVec, Vec2, WritableImage, f16, read,
};
use serde::{Deserialize, Serialize};

use super::entries::{Entries, Quantisation};
use super::param::{CHANNEL_NAMES, CHANNELS, Frame};
use super::table::{Layer, LrtfTable, Precision, TableInfo};
use crate::pages::Pages;
use crate::prescription::Prescription;
use crate::pupil::{FocusPupilTable, PupilTable};

/// Version of the file layout (channel set, image packing, sidecar fields). 3: the sidecar
/// records the data file's CRC-32, the aperture channel is the signed margin, and each layer
/// carries its sampling pupil over film radius and focus (two changes made apart, each once
/// called version 2, so a version-2 file of either kind is refused).
/// 4: the sidecar also records a CRC-32 of its own fields.
/// 5: channel names carry their wavelength layer (`wl0.exit.x`, OpenEXR's `layer.channel`
/// naming), so EXR tools list the layers docs/lrtf.md and lensbake_table.h name; version 4
/// (bare `exit.x` in the part named `wl0`) still reads.
pub const FORMAT_VERSION: u32 = 5;
/// The oldest format [`read_table`] reads.
pub const OLDEST_READ_FORMAT_VERSION: u32 = 4;
pub const SIDECAR_FILE: &str = "lrtf.ron";
pub const DATA_FILE: &str = "lrtf.exr";

/// Per-wavelength facts in the sidecar.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayerInfo {
    /// EXR layer name holding this wavelength's entries.
    pub exr_layer: String,
    pub wavelength_nm: f64,
    pub frame: Frame,
    pub pupil: PupilTable,
    pub stop_semi_aperture: f64,
    /// The sampling pupil over film radius and focus (docs/lrtf.md).
    pub sampling_pupil: FocusPupilTable,
    /// How a u16 table's codes decode (each channel's lowest value and step); absent for f32
    /// and f16 tables, and then not written, so their sidecars and checksums are as before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quantisation: Option<Quantisation>,
}

/// The RON sidecar.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    pub format_version: u32,
    pub parameterisation_version: u32,
    /// Lens name or file the table was baked from (for the rebake hint).
    pub lens: String,
    /// [`prescription_hash`] of the lens baked.
    pub prescription_hash: String,
    /// [`data_checksum`] of the `lrtf.exr` written with this sidecar. Absent only in sidecars of
    /// format versions 1 and 2, which are refused by their version before this is read.
    #[serde(default)]
    pub data_crc32: Option<String>,
    /// [`Sidecar::fields_checksum`]: covers every other field, so an edited f-number, frame or
    /// pupil circle is refused. Absent only in sidecars of format versions 1 to 3.
    #[serde(default)]
    pub sidecar_crc32: Option<String>,
    pub info: TableInfo,
    pub layers: Vec<LayerInfo>,
}

impl Sidecar {
    /// CRC-32 of the compact RON of every field but `sidecar_crc32`. Parsing and printing an f64
    /// round-trips exactly, so a sidecar read back hashes as it was written.
    pub fn fields_checksum(&self) -> String {
        let unsealed = Sidecar {
            sidecar_crc32: None,
            ..self.clone()
        };
        data_checksum(ron::to_string(&unsealed).unwrap_or_default().as_bytes())
    }
}

/// The command that rebakes a table a [`TableError`] refuses: the lens the sidecar names and the
/// table's directory. Boxed in the errors: with both inline, every `Result` carrying a
/// `TableError` was 128 bytes.
#[derive(Debug)]
pub struct Rebake {
    pub lens: String,
    pub dir: PathBuf,
}

impl std::fmt::Display for Rebake {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // The lens name comes from the sidecar, a file anyone may have edited: escaped, so a
        // line break or terminal control in it cannot forge lines of the message.
        write!(
            f,
            "`lensbake bake {} --out {}`",
            self.lens.escape_debug(),
            self.dir.display()
        )
    }
}

#[derive(Debug, thiserror::Error)]
pub enum TableError {
    #[error("{path}: {}", crate::output::describe_io(.cause))]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error("{path}: not a readable LRTF sidecar: {message}")]
    Sidecar { path: PathBuf, message: String },
    #[error("{path}: not a readable LRTF data file: {message}")]
    Data { path: PathBuf, message: String },
    #[error(
        "{path}: table has {what} {found}, this lensbake expects {expected}; rebake it with {rebake}"
    )]
    Version {
        path: PathBuf,
        what: &'static str,
        found: u32,
        expected: u32,
        rebake: Box<Rebake>,
    },
    #[error(
        "{path}: table was baked from a different prescription (hash {found}, lens now hashes to {expected}); rebake it with {rebake}"
    )]
    StaleHash {
        path: PathBuf,
        found: String,
        expected: String,
        rebake: Box<Rebake>,
    },
    #[error(
        "{path}: the sidecar's fields were altered (CRC-32 {found}, the sidecar records {expected}); rebake it with {rebake}"
    )]
    SidecarAltered {
        path: PathBuf,
        found: String,
        expected: String,
        rebake: Box<Rebake>,
    },
    #[error(
        "{dir}: holds {DATA_FILE} but no {SIDECAR_FILE}: not a table lensbake wrote, or a damaged one; refusing to overwrite it (move it away first)"
    )]
    DataWithoutSidecar { dir: PathBuf },
    #[error(
        "{path}: the data file does not belong to its sidecar (CRC-32 {found}, the sidecar records {expected}): the two come from different bakes or the data was altered; rebake it with {rebake}"
    )]
    DataMismatch {
        path: PathBuf,
        found: String,
        expected: String,
        rebake: Box<Rebake>,
    },
    #[error("{dir}: not writing a table that could not be read back: {message}")]
    Unreadable { dir: PathBuf, message: String },
}

/// FNV-1a 64 of the prescription's canonical RON text, as 16 hex digits. Any change to a surface,
/// medium, aperture or stop changes it.
pub fn prescription_hash(prescription: &Prescription) -> String {
    fnv1a_hex(&ron::to_string(prescription).unwrap_or_default())
}

fn fnv1a_hex(text: &str) -> String {
    use std::hash::Hasher;
    let mut hasher = fnv::FnvHasher::default();
    hasher.write(text.as_bytes());
    format!("{:016x}", hasher.finish())
}

/// CRC-32 (IEEE 802.3, the checksum of zlib and PNG) of a data file's bytes, as 8 hex digits.
/// It guards against accident (files of two bakes, a damaged copy), not against forgery.
pub fn data_checksum(bytes: &[u8]) -> String {
    format!("{:08x}", crc32fast::hash(bytes))
}

impl From<crate::output::OutputError> for TableError {
    fn from(error: crate::output::OutputError) -> TableError {
        match error {
            crate::output::OutputError::Io { path, error } => TableError::Io { path, cause: error },
            crate::output::OutputError::Refused { path, reason } => TableError::Io {
                path,
                cause: std::io::Error::other(format!("refusing to replace it: {reason}")),
            },
        }
    }
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> TableError + '_ {
    move |cause| TableError::Io {
        path: path.to_path_buf(),
        cause,
    }
}

/// Where a re-bake keeps the data file that the sidecar with `crc32` describes until the new
/// sidecar is in place.
fn previous_data_path(dir: &Path, crc32: &str) -> PathBuf {
    dir.join(format!(".{DATA_FILE}.{crc32}.previous"))
}

/// Writes `table` into `dir` (created if missing) as lrtf.exr + lrtf.ron.
pub fn write_table(
    table: &LrtfTable,
    lens: &str,
    prescription: &Prescription,
    dir: &Path,
) -> Result<(), TableError> {
    // Writers of tables in one folder take turns (readers never wait): two runs that bake the
    // same table at once would otherwise interleave their file-by-file replacements.
    let _turn = crate::output::lock_folder(dir.parent().unwrap_or(Path::new(".")))?;
    let data_path = dir.join(DATA_FILE);
    let sidecar_path = dir.join(SIDECAR_FILE);
    if data_path.exists() && !sidecar_path.exists() {
        return Err(TableError::DataWithoutSidecar {
            dir: dir.to_path_buf(),
        });
    }
    let [n0, n1, n2] = table.info.resolution;
    let size = Vec2(n0, n1 * n2);
    let exr_layers: Vec<exr::image::Layer<AnyChannels<FlatSamples>>> = table
        .layers
        .iter()
        .enumerate()
        .map(|(k, layer)| {
            let codes = layer.entries.codes();
            let channels = (0..CHANNELS)
                .map(|c| {
                    let values = layer.entries.row_major().map(|e| e[c]);
                    // OpenEXR has no 16-bit integers: a u16 table's codes go into 32-bit ones.
                    let samples = match (&codes, table.info.precision) {
                        (Some((_, codes)), _) => {
                            FlatSamples::U32(codes.iter().map(|q| u32::from(q[c])).collect())
                        }
                        (None, Precision::F16) => {
                            FlatSamples::F16(values.map(f16::from_f32).collect())
                        }
                        (None, _) => FlatSamples::F32(values.collect()),
                    };
                    AnyChannel::new(
                        channel_name(&layer_name(k), c, FORMAT_VERSION).as_str(),
                        samples,
                    )
                })
                .collect::<Vec<_>>();
            exr::image::Layer::new(
                size,
                LayerAttributes::named(layer_name(k).as_str()),
                // Run-length coding gained nothing on these smooth floats and cost a tenth of the bake.
                Encoding::UNCOMPRESSED,
                AnyChannels::sort(SmallVec::from_vec(channels)),
            )
        })
        .collect();
    let image = Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions(size)),
        SmallVec::from_vec(exr_layers),
    );
    // Encoded in memory first, so the checksum the sidecar records is of the exact bytes written.
    let mut data = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut data)
        .map_err(|e| TableError::Data {
            path: data_path.clone(),
            message: e.to_string(),
        })?;
    let data = data.into_inner();
    let mut sidecar = Sidecar {
        format_version: FORMAT_VERSION,
        parameterisation_version: table.info.parameterisation.version(),
        lens: lens.to_string(),
        prescription_hash: prescription_hash(prescription),
        data_crc32: Some(data_checksum(&data)),
        sidecar_crc32: None,
        info: table.info.clone(),
        layers: table
            .layers
            .iter()
            .enumerate()
            .map(|(k, l)| LayerInfo {
                exr_layer: layer_name(k),
                wavelength_nm: l.wavelength_nm,
                frame: l.frame.clone(),
                pupil: l.pupil.clone(),
                stop_semi_aperture: l.stop_semi_aperture,
                sampling_pupil: l.sampling.clone(),
                quantisation: l.entries.codes().map(|(quantisation, _)| quantisation),
            })
            .collect(),
    };
    // What the reader would refuse is not written: nothing on disk claims to be a table that
    // no lensbake can load.
    if let Some(message) = implausible_number(&sidecar) {
        return Err(TableError::Unreadable {
            dir: dir.to_path_buf(),
            message,
        });
    }
    sidecar.sidecar_crc32 = Some(sidecar.fields_checksum());
    let text = ron::ser::to_string_pretty(&sidecar, ron::ser::PrettyConfig::default())
        .expect("sidecar is plain data");
    // A new table appears whole; only a table that already exists is replaced file by file.
    if !dir.exists()
        && crate::output::create_dir_whole(
            dir,
            &[(DATA_FILE, &data), (SIDECAR_FILE, text.as_bytes())],
        )?
    {
        return Ok(());
    }
    // The old data stays reachable from the old sidecar until the new sidecar replaces it.
    let previous = read_sidecar(dir)
        .ok()
        .and_then(|old| old.data_crc32)
        .map(|crc32| previous_data_path(dir, &crc32));
    if let Some(previous) = &previous
        && data_path.exists()
        && !previous.exists()
    {
        std::fs::hard_link(&data_path, previous).map_err(io_error(previous))?;
    }
    crate::output::write_bytes(&data_path, &data)?;
    crate::output::write_bytes(&sidecar_path, text.as_bytes())?;
    if let Some(previous) = previous {
        let _ = std::fs::remove_file(previous);
    }
    Ok(())
}

fn layer_name(k: usize) -> String {
    format!("wl{k}")
}

/// The EXR name of channel `channel` (an index of [`CHANNEL_NAMES`]) of the layer `exr_layer`
/// in files of format `format_version`.
pub fn channel_name(exr_layer: &str, channel: usize, format_version: u32) -> String {
    if format_version >= 5 {
        format!("{exr_layer}.{}", CHANNEL_NAMES[channel])
    } else {
        CHANNEL_NAMES[channel].to_string()
    }
}

/// Reads the sidecar alone (for `lrtf info`), checking nothing but its syntax.
pub fn read_sidecar(dir: &Path) -> Result<Sidecar, TableError> {
    let path = dir.join(SIDECAR_FILE);
    let text = crate::limits::read_input_text(&path).map_err(io_error(&path))?;
    ron::from_str(&text).map_err(|e| TableError::Sidecar {
        path: path.clone(),
        message: e.to_string(),
    })
}

/// The first sidecar number that cannot describe a table (NaN, infinite, or of the wrong sign
/// where a length, wavelength or f-number must be positive), named by its field.
fn implausible_number(sidecar: &Sidecar) -> Option<String> {
    let positive = |value: f64| value.is_finite() && value > 0.0;
    let info = &sidecar.info;
    let mut checks: Vec<(String, f64, bool)> = vec![(
        "info.f_number".into(),
        info.f_number,
        positive(info.f_number),
    )];
    let focus = &info.focus;
    for (name, distance) in [("far_mm", focus.far_mm), ("near_mm", focus.near_mm)] {
        if let Some(d) = distance {
            checks.push((format!("info.focus.{name}"), d, positive(d)));
        }
    }
    if let (Some(far), Some(near)) = (focus.far_mm, focus.near_mm)
        && near > far
    {
        return Some(format!(
            "info.focus.near_mm = {near} lies beyond info.focus.far_mm = {far}"
        ));
    }
    if focus.far_mm.is_some() && focus.near_mm.is_none() {
        return Some("info.focus.near_mm is infinity but far_mm is not".into());
    }
    checks.extend([
        (
            "info.focus.rear_focal_z".into(),
            focus.rear_focal_z,
            focus.rear_focal_z.is_finite(),
        ),
        (
            "info.focus.front_focal_z".into(),
            focus.front_focal_z,
            focus.front_focal_z.is_finite(),
        ),
        (
            "info.focus.focal_product".into(),
            focus.focal_product,
            positive(focus.focal_product),
        ),
    ]);
    for (k, layer) in sidecar.layers.iter().enumerate() {
        let f = &layer.frame;
        let field = |name: &str| format!("layers[{k}].{name}");
        checks.extend([
            (
                field("wavelength_nm"),
                layer.wavelength_nm,
                positive(layer.wavelength_nm),
            ),
            (
                field("stop_semi_aperture"),
                layer.stop_semi_aperture,
                positive(layer.stop_semi_aperture),
            ),
            (
                field("frame.rear_plane_z"),
                f.rear_plane_z,
                f.rear_plane_z.is_finite(),
            ),
            (
                field("frame.film_plane_z"),
                f.film_plane_z,
                f.film_plane_z.is_finite(),
            ),
            (
                field("frame.max_film_radius"),
                f.max_film_radius,
                positive(f.max_film_radius),
            ),
            (
                field("frame.max_rear_radius"),
                f.max_rear_radius,
                f.max_rear_radius.is_finite() && f.max_rear_radius >= 0.0,
            ),
            (
                field("frame.max_polar_angle"),
                f.max_polar_angle,
                f.max_polar_angle.is_finite() && f.max_polar_angle >= 0.0,
            ),
            (
                field("pupil.max_film_radius"),
                layer.pupil.max_film_radius,
                positive(layer.pupil.max_film_radius),
            ),
        ]);
        if layer.pupil.circles.len() < 2 {
            return Some(format!(
                "{} has {} pupil circles; a table needs at least 2",
                field("pupil.circles"),
                layer.pupil.circles.len()
            ));
        }
        let circle_checks = |pupil: &str, circles: &[crate::pupil::PupilCircle]| {
            circles
                .iter()
                .enumerate()
                .flat_map(|(j, circle)| {
                    let at = |name: &str| field(&format!("{pupil}.circles[{j}].{name}"));
                    [
                        (at("centre_x"), circle.centre_x, circle.centre_x.is_finite()),
                        (
                            at("radius"),
                            circle.radius,
                            circle.radius.is_finite() && circle.radius >= 0.0,
                        ),
                    ]
                })
                .collect::<Vec<_>>()
        };
        checks.extend(circle_checks("pupil", &layer.pupil.circles));
        if let Some(q) = &layer.quantisation
            && let Some(c) = q.implausible_channel()
        {
            return Some(format!(
                "{} of channel {} (low {}, step {}) cannot decode a table",
                field("quantisation"),
                super::param::CHANNEL_NAMES[c],
                q.low[c],
                q.step[c]
            ));
        }
        let sampling = &layer.sampling_pupil;
        if sampling.nodes.is_empty() {
            return Some(format!(
                "{} has no focus nodes",
                field("sampling_pupil.nodes")
            ));
        }
        let [first, last] = sampling.film_z;
        if !(first.is_finite() && last.is_finite() && first <= last) {
            return Some(format!(
                "{} = [{first}, {last}] is not a film-plane range",
                field("sampling_pupil.film_z")
            ));
        }
        let expected = focus.film_z_range();
        let agrees = |a: f64, b: f64| (a - b).abs() <= 1e-6 * a.abs().max(b.abs()).max(1.0);
        if !(agrees(first, expected[0])
            && agrees(last, expected[1])
            && agrees(f.film_plane_z, first))
        {
            return Some(format!(
                "{} = [{first}, {last}] and frame.film_plane_z = {} disagree with info.focus (film planes {:?})",
                field("sampling_pupil.film_z"),
                f.film_plane_z,
                expected
            ));
        }
        let radii = sampling.nodes[0].circles.len();
        for (j, node) in sampling.nodes.iter().enumerate() {
            let name = format!("sampling_pupil.nodes[{j}]");
            if node.circles.len() < 2 || node.circles.len() != radii {
                return Some(format!(
                    "{} has {} circles; every focus node needs the same number, at least 2",
                    field(&name),
                    node.circles.len()
                ));
            }
            checks.push((
                field(&format!("{name}.max_film_radius")),
                node.max_film_radius,
                positive(node.max_film_radius),
            ));
            checks.extend(circle_checks(&name, &node.circles));
        }
    }
    checks
        .into_iter()
        .find(|(_, _, ok)| !ok)
        .map(|(name, value, _)| format!("{name} = {value} cannot describe a table"))
}

/// Loads a table, refusing one whose format or parameterisation version differs from this
/// build's, or (when `prescription` is given) one baked from another prescription.
pub fn read_table(
    dir: &Path,
    prescription: Option<&Prescription>,
) -> Result<LrtfTable, TableError> {
    let sidecar = read_sidecar(dir)?;
    let sidecar_path = dir.join(SIDECAR_FILE);
    let rebake = || {
        Box::new(Rebake {
            lens: sidecar.lens.clone(),
            dir: dir.to_path_buf(),
        })
    };
    let version_error = |what, found, expected| TableError::Version {
        path: sidecar_path.clone(),
        what,
        found,
        expected,
        rebake: rebake(),
    };
    if !(OLDEST_READ_FORMAT_VERSION..=FORMAT_VERSION).contains(&sidecar.format_version) {
        return Err(version_error(
            "format version",
            sidecar.format_version,
            FORMAT_VERSION,
        ));
    }
    let expected_param = sidecar.info.parameterisation.version();
    if sidecar.parameterisation_version != expected_param {
        return Err(version_error(
            "parameterisation version",
            sidecar.parameterisation_version,
            expected_param,
        ));
    }
    if let Some(prescription) = prescription {
        let expected = prescription_hash(prescription);
        if expected != sidecar.prescription_hash {
            return Err(TableError::StaleHash {
                path: sidecar_path,
                found: sidecar.prescription_hash,
                expected,
                rebake: rebake(),
            });
        }
    }
    implausible_number(&sidecar).map_or(Ok(()), |message| {
        Err(TableError::Sidecar {
            path: dir.join(SIDECAR_FILE),
            message,
        })
    })?;
    let fields = sidecar.fields_checksum();
    if sidecar.sidecar_crc32.as_deref() != Some(fields.as_str()) {
        return Err(TableError::SidecarAltered {
            path: sidecar_path,
            found: fields,
            expected: sidecar.sidecar_crc32.unwrap_or_else(|| "nothing".into()),
            rebake: rebake(),
        });
    }
    // Each data layer is moved out of the decoded image once it is read: a second sidecar layer
    // naming it would find it gone and call it missing.
    let layers = &sidecar.layers;
    if let Some(twice) = (1..layers.len()).find(|&k| {
        layers[..k]
            .iter()
            .any(|l| l.exr_layer == layers[k].exr_layer)
    }) {
        return Err(TableError::Sidecar {
            path: dir.join(SIDECAR_FILE),
            message: format!("names the data layer {} twice", layers[twice].exr_layer),
        });
    }
    let mut data_path = dir.join(DATA_FILE);
    let mut bytes = crate::limits::read_input(&data_path).map_err(|e| TableError::Data {
        path: data_path.clone(),
        message: e.to_string(),
    })?;
    let mut found = data_checksum(&bytes);
    // A re-bake killed between its two renames leaves this sidecar's data under its CRC.
    if let Some(expected) = &sidecar.data_crc32
        && *expected != found
    {
        let previous = previous_data_path(dir, expected);
        if let Ok(kept) = crate::limits::read_input(&previous)
            && data_checksum(&kept) == *expected
        {
            (data_path, bytes, found) = (previous, kept, expected.clone());
        }
    }
    let data_error = |message: String| TableError::Data {
        path: data_path.clone(),
        message,
    };
    let [n0, n1, n2] = sidecar.info.resolution;
    if n0 < 2 || n1 < 2 || n2 < 2 {
        return Err(TableError::Sidecar {
            path: dir.join(SIDECAR_FILE),
            message: format!("resolution {n0}x{n1}x{n2} needs at least 2 nodes per axis"),
        });
    }
    // Reading reports corrupted or truncated files as errors; catch_unwind guards against a
    // decoder panic on hostile input so a bad file can never abort the caller.
    let mut image = std::panic::catch_unwind(|| {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_buffered(std::io::Cursor::new(&bytes))
    })
    .map_err(|_| data_error("the EXR decoder failed on this file".into()))?
    .map_err(|e| data_error(e.to_string()))?;
    // Each copy of the entries is freed as soon as the next one is made (the file's bytes, the
    // decoded layer, the row-major entries, the bricks): a 128^3 table held all four at once,
    // 272 MB at its peak for 67 MB of table.
    drop(bytes);
    // After decoding, so a file the decoder cannot read keeps its precise message; a file that
    // decodes but is not the one this sidecar was written with is refused here.
    if sidecar.data_crc32.as_deref() != Some(found.as_str()) {
        return Err(TableError::DataMismatch {
            path: data_path,
            found,
            expected: sidecar.data_crc32.unwrap_or_else(|| "nothing".into()),
            rebake: rebake(),
        });
    }
    let mut layers = Vec::with_capacity(sidecar.layers.len());
    for info in &sidecar.layers {
        let position = image
            .layer_data
            .iter()
            .position(|l| {
                l.attributes.layer_name.as_ref().map(|n| n.to_string())
                    == Some(info.exr_layer.clone())
            })
            .ok_or_else(|| {
                data_error(format!(
                    "layer {} named in the sidecar is missing",
                    info.exr_layer
                ))
            })?;
        let exr_layer = image.layer_data.swap_remove(position);
        if exr_layer.size != Vec2(n0, n1 * n2) {
            return Err(data_error(format!(
                "layer {} is {}x{}, the sidecar's resolution {n0}x{n1}x{n2} needs {n0}x{}",
                info.exr_layer,
                exr_layer.size.0,
                exr_layer.size.1,
                n1 * n2
            )));
        }
        let quantisation = match (sidecar.info.precision, info.quantisation) {
            (Precision::U16, Some(q)) => Some(q),
            (Precision::U16, None) => {
                return Err(TableError::Sidecar {
                    path: dir.join(SIDECAR_FILE),
                    message: format!(
                        "a u16 table needs {}.quantisation, and it is missing",
                        info.exr_layer
                    ),
                });
            }
            (_, None) => None,
            (precision, Some(_)) => {
                return Err(TableError::Sidecar {
                    path: dir.join(SIDECAR_FILE),
                    message: format!(
                        "{}.quantisation is given for a {} table, which has none",
                        info.exr_layer,
                        precision.name()
                    ),
                });
            }
        };
        // Only the kind the table holds is allocated.
        let nodes = n0 * n1 * n2;
        let (mut entries, mut codes) = match quantisation {
            Some(_) => (Vec::new(), vec![[0u16; CHANNELS]; nodes]),
            None => (vec![[0.0f32; CHANNELS]; nodes], Vec::new()),
        };
        for c in 0..CHANNELS {
            let name = channel_name(&info.exr_layer, c, sidecar.format_version);
            let channel = exr_layer
                .channel_data
                .list
                .iter()
                .find(|ch| ch.name.to_string() == name)
                .ok_or_else(|| {
                    data_error(format!("layer {} lacks channel {name}", info.exr_layer))
                })?;
            if quantisation.is_some() {
                let FlatSamples::U32(stored) = &channel.sample_data else {
                    return Err(data_error(format!(
                        "layer {} channel {name} of a u16 table holds floats, not codes",
                        info.exr_layer
                    )));
                };
                for (code, &value) in codes.iter_mut().zip(stored) {
                    code[c] = u16::try_from(value).map_err(|_| {
                        data_error(format!(
                            "layer {} channel {name} holds the code {value}, above {}",
                            info.exr_layer,
                            Quantisation::LEVELS
                        ))
                    })?;
                }
                continue;
            }
            for (entry, value) in entries.iter_mut().zip(channel.sample_data.values_as_f32()) {
                if !value.is_finite() {
                    return Err(data_error(format!(
                        "layer {} channel {name} holds a non-finite value",
                        info.exr_layer
                    )));
                }
                entry[c] = value;
            }
        }
        drop(exr_layer);
        layers.push(Layer {
            wavelength_nm: info.wavelength_nm,
            frame: info.frame.clone(),
            pupil: info.pupil.clone(),
            sampling: info.sampling_pupil.clone(),
            stop_semi_aperture: info.stop_semi_aperture,
            entries: match quantisation {
                Some(q) => Entries::from_codes(sidecar.info.resolution, q, &codes),
                None => Entries::from_row_major_on(
                    Pages::Huge,
                    sidecar.info.resolution,
                    sidecar.info.precision,
                    &entries,
                ),
            },
        });
    }
    if layers.is_empty() {
        return Err(TableError::Sidecar {
            path: dir.join(SIDECAR_FILE),
            message: "no wavelength layers listed".into(),
        });
    }
    Ok(LrtfTable {
        info: sidecar.info,
        layers,
    })
}

#[cfg(test)]
mod tests {
    /// The hash is FNV-1a 64 as its authors define it (their test vectors), so tables baked
    /// before it came from the fnv crate keep their hashes.
    #[test]
    fn the_hash_is_fnv_1a_64() {
        for (text, hash) in [
            ("", "cbf29ce484222325"),
            ("a", "af63dc4c8601ec8c"),
            ("foobar", "85944171f73967e8"),
        ] {
            assert_eq!(super::fnv1a_hex(text), hash, "{text:?}");
        }
    }
}
