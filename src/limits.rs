//! The size policy. Every size and count a user controls (image, samples, table nodes, rays,
//! threads, surfaces, blades, scene nodes, input files) has one limit here, checked before
//! anything is allocated or any loop starts, so an absurd argument ends in one clear error and
//! never in an out-of-memory abort, a capacity-overflow panic or a run that never ends. Each limit
//! is far above any real use and is listed, with what exceeding it gets, in docs/limits.md.

use std::io::Read;
use std::path::Path;

/// Widest or tallest rendered image, in pixels.
pub const MAX_IMAGE_SIDE: u64 = 16_384;
/// Most pixels in one rendered image (8192 x 8192).
pub const MAX_IMAGE_PIXELS: u64 = 1 << 26;
/// Most lens samples per pixel.
pub const MAX_SAMPLES_PER_PIXEL: u64 = 1 << 16;
/// Most lens samples in one render (pixels x samples per pixel): about an hour on two cores.
pub const MAX_RENDER_SAMPLES: u64 = 1 << 32;
/// Most depth layers peeled per pixel.
pub const MAX_LAYERS: u64 = 64;
/// Most pixels in one layered depth image (peeled view or EXR scene), all layers together.
pub const MAX_LAYER_PIXELS: u64 = 1 << 28;
/// Most nodes in a baked table, all wavelength layers together (a 322^3 table of one layer).
pub const MAX_TABLE_NODES: u64 = 1 << 25;
/// Most rays in one batch (`bench trace`, `tradeoff`, `trace`, `lrtf eval`).
pub const MAX_RAYS: u64 = 1 << 26;
/// Most rendered frames a tradeoff averages over.
pub const MAX_RENDER_FRAMES: u64 = 1_000;
/// Most frames one viewer run or one script action renders (hours at interactive rates).
pub const MAX_VIEW_FRAMES: u64 = 10_000_000;
/// Most worker threads.
pub const MAX_THREADS: u64 = 1_024;
/// Most surfaces in a lens (real designs have under 60).
pub const MAX_SURFACES: u64 = 512;
/// Most diaphragm blades.
pub const MAX_BLADES: u64 = 64;
/// Deepest glTF node tree.
pub const MAX_SCENE_DEPTH: u64 = 256;
/// Most triangles in a scene.
pub const MAX_TRIANGLES: u64 = 1 << 24;
/// Largest input file read whole (glTF buffer, ray list, table).
pub const MAX_INPUT_BYTES: u64 = 1 << 30;
/// Largest lens file. The largest real one in tests/data (about 60 files) is 30 KB, and at the
/// most bytes per surface of any of them (3.7 KB, a Zemax file of 8 surfaces) a lens of
/// [`MAX_SURFACES`] surfaces would take 1.9 MB; a larger file is refused before it is read
/// rather than read whole and then refused by its surface count.
pub const MAX_LENS_FILE_BYTES: u64 = 16 << 20;

/// Slowest f-number: a pinhole of 1/1000 of the focal length. Slower stops gave pupils so small
/// that radiance divided by their area overflowed to infinity.
pub const MAX_F_NUMBER: f64 = 1_000.0;
/// Longest focal length of an ideal (`ideal:<mm>`) lens, in mm, and the smallest.
pub const FOCAL_LENGTH_RANGE_MM: [f64; 2] = [1e-3, 1e6];

/// Wavelengths lensbake traces at, in nm: far ultraviolet to far infrared. Every dispersion
/// formula it knows is fitted well inside this range; outside it a formula's value means
/// nothing, and an index of 1e30 nm light gave total internal reflection at every surface.
pub const WAVELENGTH_RANGE_NM: [f64; 2] = [100.0, 100_000.0];

/// Refuses a wavelength outside [`WAVELENGTH_RANGE_NM`] (NaN included).
pub fn check_wavelength(wavelength_nm: f64) -> Result<(), LimitError> {
    let [shortest, longest] = WAVELENGTH_RANGE_NM;
    check_range("the wavelength (nm)", wavelength_nm, shortest, longest)
}

/// Longest length and farthest position in the lens frame, in mm (1000 km): a focus distance
/// beyond it is infinity for every lens, and film positions of 1e22 mm gave infinite colour
/// blur estimates.
pub const MAX_LENGTH_MM: f64 = 1e9;
/// Shortest length that is not zero, in mm (one nanometre).
pub const MIN_LENGTH_MM: f64 = 1e-6;

/// An object distance as every analysis takes it: None (infinity) at [`MAX_LENGTH_MM`] or
/// farther, where a finite distance would only lose digits (files write 1e10 for infinity). NaN
/// is refused; a negative distance is a virtual object, zero the paraxial model's to refuse.
pub fn object_distance(what: &str, mm: f64) -> Result<Option<f64>, LimitError> {
    if mm.is_nan() {
        return Err(LimitError::NotANumber {
            what: what.to_string(),
        });
    }
    Ok((mm.abs() < MAX_LENGTH_MM).then_some(mm))
}

/// An object distance (mm from the first vertex) as a reader wants it: `d mm before surface 1`,
/// or behind it for a virtual object; `decimals` digits after the point.
pub fn object_place(distance_mm: f64, decimals: usize) -> String {
    if distance_mm < 0.0 {
        format!("{:.decimals$} mm behind surface 1 (virtual)", -distance_mm)
    } else {
        format!("{distance_mm:.decimals$} mm before surface 1")
    }
}

/// Refuses a length (a diameter, a film size) outside [[`MIN_LENGTH_MM`], [`MAX_LENGTH_MM`]].
pub fn check_length(what: &str, mm: f64) -> Result<(), LimitError> {
    check_range(what, mm, MIN_LENGTH_MM, MAX_LENGTH_MM)
}

/// Refuses a lens-frame coordinate or signed distance beyond +-[`MAX_LENGTH_MM`] (NaN too).
pub fn check_position(what: &str, mm: f64) -> Result<(), LimitError> {
    check_range(what, mm, -MAX_LENGTH_MM, MAX_LENGTH_MM)
}

/// Brightest radiance a scene may hold: the sum over every sample of a pixel stays finite in f32.
pub const MAX_RADIANCE: f64 = 1e30;

/// Whether `value` is a radiance a scene may hold: finite, not negative, at most
/// [`MAX_RADIANCE`].
pub fn is_radiance(value: f64) -> bool {
    (0.0..=MAX_RADIANCE).contains(&value)
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LimitError {
    #[error("{what} is {requested}, over the limit of {limit} (docs/limits.md)")]
    OverLimit {
        what: String,
        requested: u64,
        limit: u64,
    },
    #[error("{what} is {}, outside [{}, {}] (docs/limits.md)", short(*.value), short(*.low), short(*.high))]
    OutOfRange {
        what: String,
        value: f64,
        low: f64,
        high: f64,
    },
    #[error("{what} is NaN, not a number")]
    NotANumber { what: String },
    #[error("{what} must be positive and finite, got {}", short(*.value))]
    NotPositive { what: String, value: f64 },
    #[error(
        "{what} needs about {needed_mib} MiB of memory and only {available_mib} MiB is available"
    )]
    Memory {
        what: String,
        needed_mib: u64,
        available_mib: u64,
    },
}

/// Refuses `requested` above `limit`.
pub fn check(what: &str, requested: u64, limit: u64) -> Result<(), LimitError> {
    if requested > limit {
        return Err(LimitError::OverLimit {
            what: what.to_string(),
            requested,
            limit,
        });
    }
    Ok(())
}

/// Refuses `value` unless it is finite and above 0 (NaN included).
pub fn check_positive(what: &str, value: f64) -> Result<(), LimitError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(LimitError::NotPositive {
            what: what.to_string(),
            value,
        })
    }
}

/// Refuses `value` outside `low..=high` (NaN included).
pub fn check_range(what: &str, value: f64, low: f64, high: f64) -> Result<(), LimitError> {
    if value.is_nan() {
        return Err(LimitError::NotANumber {
            what: what.to_string(),
        });
    }
    if !(low..=high).contains(&value) {
        return Err(LimitError::OutOfRange {
            what: what.to_string(),
            value,
            low,
            high,
        });
    }
    Ok(())
}

/// Refuses an f-number that is not finite, not faster than [`MAX_F_NUMBER`], or faster than the
/// lens wide open (`wide_open`, within rounding).
pub fn check_f_number(f_number: f64, wide_open: f64) -> Result<(), LimitError> {
    check_range(
        "the f-number",
        f_number,
        wide_open * (1.0 - 1e-9),
        MAX_F_NUMBER.max(wide_open),
    )
}

/// A number as a reader wants it in a message: plain when short, in exponent form when plain
/// would run to many digits (1e300 printed plainly has 301).
pub fn short(value: f64) -> String {
    let magnitude = value.abs();
    if value != 0.0 && value.is_finite() && !(1e-4..1e7).contains(&magnitude) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

/// The product of `factors`, saturating: a product that overflows is over every limit.
pub fn product(factors: &[u64]) -> u64 {
    factors
        .iter()
        .fold(1u64, |total, &f| total.saturating_mul(f))
}

/// Refuses an allocation of `bytes` larger than the memory the system reports available (Linux
/// `MemAvailable`; elsewhere only the fixed limits apply).
pub fn check_memory(what: &str, bytes: u64) -> Result<(), LimitError> {
    let Some(available) = available_memory() else {
        return Ok(());
    };
    if bytes > available {
        return Err(LimitError::Memory {
            what: what.to_string(),
            needed_mib: bytes.div_ceil(1 << 20),
            available_mib: available >> 20,
        });
    }
    Ok(())
}

fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// Reads a whole input file, refusing what is not a regular file (a FIFO or device would block or
/// never end) and files over [`MAX_INPUT_BYTES`]. The errors are `std::io::Error`s, so each
/// reader keeps its own way of naming the file.
pub fn read_input(path: &Path) -> std::io::Result<Vec<u8>> {
    read_input_within(path, MAX_INPUT_BYTES)
}

/// [`read_input`] with a limit of `max_bytes` (a lens file's is [`MAX_LENS_FILE_BYTES`]).
pub fn read_input_within(path: &Path, max_bytes: u64) -> std::io::Result<Vec<u8>> {
    read_bounded(path, max_bytes)
        .map_err(|error| std::io::Error::new(error.kind(), crate::output::describe_io(&error)))
}

fn read_bounded(path: &Path, max_bytes: u64) -> std::io::Result<Vec<u8>> {
    // Looked at before opening: opening a FIFO for reading blocks until a writer comes.
    let metadata = std::fs::metadata(path)?;
    if metadata.is_dir() {
        return Err(std::io::Error::other("is a directory, not a file"));
    }
    if !metadata.is_file() {
        return Err(std::io::Error::other(
            "is not a regular file (a pipe, socket or device); lensbake reads only files",
        ));
    }
    if metadata.len() > max_bytes {
        return Err(std::io::Error::other(format!(
            "is {} bytes, over the input limit of {max_bytes} bytes (docs/limits.md)",
            metadata.len()
        )));
    }
    // A file that grows while it is read still stops at the limit.
    read_capped(
        std::fs::File::open(path)?,
        metadata.len() as usize,
        max_bytes,
    )
}

/// Everything `source` gives up to `max_bytes`, refusing more.
fn read_capped(
    source: impl Read,
    expected_bytes: usize,
    max_bytes: u64,
) -> std::io::Result<Vec<u8>> {
    let mut bytes = Vec::with_capacity(expected_bytes);
    source.take(max_bytes + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(std::io::Error::other(format!(
            "went past the input limit of {max_bytes} bytes (docs/limits.md)"
        )));
    }
    Ok(bytes)
}

/// Standard input as UTF-8 text, at most [`MAX_INPUT_BYTES`] of it (a pipe from /dev/zero
/// would otherwise fill the memory).
pub fn read_stdin_text() -> std::io::Result<String> {
    utf8(read_capped(std::io::stdin().lock(), 0, MAX_INPUT_BYTES)?)
}

fn utf8(bytes: Vec<u8>) -> std::io::Result<String> {
    String::from_utf8(bytes)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()))
}

/// [`read_input`] as UTF-8 text.
pub fn read_input_text(path: &Path) -> std::io::Result<String> {
    utf8(read_input(path)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_numbers_are_printed_short_and_nan_is_out_of_every_range() {
        assert_eq!(short(1e300), "1e300");
        assert_eq!(short(2.5), "2.5");
        assert!(check_range("x", f64::NAN, 0.0, 1.0).is_err());
        assert!(check_f_number(f64::INFINITY, 2.0).is_err());
        assert!(check_f_number(1e22, 2.0).is_err());
        assert!(check_f_number(16.0, 2.0).is_ok());
        assert!(check_f_number(1.9, 2.0).is_err());
    }

    #[test]
    fn a_product_that_overflows_is_over_every_limit() {
        assert_eq!(product(&[u64::MAX, 2]), u64::MAX);
        assert!(check("nodes", product(&[100_000; 3]), MAX_TABLE_NODES).is_err());
        assert!(check("nodes", product(&[128; 3]), MAX_TABLE_NODES).is_ok());
    }

    #[test]
    fn an_allocation_larger_than_memory_is_refused() {
        if available_memory().is_some() {
            assert!(matches!(
                check_memory("a table", u64::MAX),
                Err(LimitError::Memory { .. })
            ));
        }
        assert!(check_memory("a table", 1024).is_ok());
    }

    #[test]
    fn a_fifo_and_a_directory_are_refused_without_blocking() {
        let dir = std::env::temp_dir().join(format!("lensbake-limits-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        assert!(read_input(&dir).is_err());
        let fifo = dir.join("fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            // No writer ever opens it: a reader that opened it first would block forever.
            let error = read_input(&fifo).unwrap_err();
            assert!(error.to_string().contains("not a regular file"), "{error}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
