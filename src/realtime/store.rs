//! Lens kernels kept on disk, so that a render pays for tracing them once per lens, f-number,
//! focus, view and depth range ([`KernelKey`]), not once per frame.
//!
//! A file holds its key in full, then the kernel set, then an FNV-1a 64 checksum of everything
//! before it. [`read`] refuses a file of another format version, another key, a damaged body or
//! values a traced set cannot have (unevenly spaced nodes, negative or non-finite values), each
//! with its own error, so the caller can trace again and say why.

use super::kernels::{Kernel, KernelSettings, LensKernels};
use crate::render::layers::View;
use std::path::{Path, PathBuf};

/// Bumped whenever the layout or the meaning of a stored value changes.
pub const FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"LBKERNEL";

/// Everything a kernel set depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelKey {
    /// [`crate::lrtf::io::prescription_hash`] of the lens.
    pub prescription_hash: String,
    pub f_number: f64,
    /// Film plane (mm, lens frame): the focus.
    pub film_z: f64,
    pub view: View,
    /// Near and far depth (mm from the eye) the kernels cover.
    pub depth_range_mm: [f64; 2],
    pub settings: KernelSettings,
}

impl KernelKey {
    fn bytes(&self) -> Vec<u8> {
        let mut out = Bytes::default();
        out.text(&self.prescription_hash);
        for v in [
            self.f_number,
            self.film_z,
            self.view.eye_z,
            self.view.tan_half[0],
            self.view.tan_half[1],
            self.depth_range_mm[0],
            self.depth_range_mm[1],
        ] {
            out.f64(v);
        }
        let s = &self.settings;
        for n in [
            self.view.width as usize,
            self.view.height as usize,
            s.depth_nodes,
            s.field_nodes,
            s.rays_per_side,
            s.grid_side,
        ] {
            out.u32(n as u32);
        }
        out.0
    }

    /// The file name of this key's set: 16 hex digits of its hash.
    pub fn file_name(&self) -> String {
        format!("{:016x}.kernels", fnv1a(&self.bytes()))
    }

    /// Where this key's set lives under `folder`.
    pub fn path_in(&self, folder: &Path) -> PathBuf {
        folder.join(self.file_name())
    }
}

/// Why a stored set was not used.
#[derive(Debug, thiserror::Error)]
pub enum KernelStoreError {
    #[error("{path}: {error}")]
    Read {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{path}: not a lens-kernel file")]
    NotKernels { path: PathBuf },
    #[error("{path}: kernel format version {found}, this lensbake writes {FORMAT_VERSION}")]
    Version { path: PathBuf, found: u32 },
    #[error("{path}: traced for another lens, focus, f-number, view or depth range")]
    OtherKey { path: PathBuf },
    #[error("{path}: damaged ({what})")]
    Damaged { path: PathBuf, what: &'static str },
    #[error(transparent)]
    Write(#[from] crate::output::OutputError),
}

/// Writes `kernels`, traced for `key`, to `path` (whole or not at all).
pub fn write(path: &Path, key: &KernelKey, kernels: &LensKernels) -> Result<(), KernelStoreError> {
    let mut out = Bytes::default();
    out.0.extend_from_slice(MAGIC);
    out.u32(FORMAT_VERSION);
    let key = key.bytes();
    out.u32(key.len() as u32);
    out.0.extend_from_slice(&key);
    out.u32(kernels.inverse_depths.len() as u32);
    out.u32(kernels.field_tangents.len() as u32);
    out.f64(kernels.pixel_tangent);
    for &v in kernels.inverse_depths.iter().chain(&kernels.field_tangents) {
        out.f64(v);
    }
    for k in &kernels.kernels {
        out.u32(k.side as u32);
        for v in [
            k.origin[0],
            k.origin[1],
            k.spacing,
            k.flux,
            k.centroid[0],
            k.centroid[1],
            k.rms_radius,
            k.support,
        ] {
            out.f64(v);
        }
        for &v in &k.values {
            out.0.extend_from_slice(&v.to_le_bytes());
        }
    }
    let sum = fnv1a(&out.0);
    out.0.extend_from_slice(&sum.to_le_bytes());
    crate::output::write_bytes(path, &out.0)?;
    Ok(())
}

/// The set stored at `path` for `key`. A missing file is [`KernelStoreError::Read`] with
/// [`std::io::ErrorKind::NotFound`].
pub fn read(path: &Path, key: &KernelKey) -> Result<LensKernels, KernelStoreError> {
    let bytes = crate::limits::read_input(path).map_err(|error| KernelStoreError::Read {
        path: path.to_path_buf(),
        error,
    })?;
    let damaged = |what| KernelStoreError::Damaged {
        path: path.to_path_buf(),
        what,
    };
    if bytes.len() < MAGIC.len() + 12 || &bytes[..MAGIC.len()] != MAGIC {
        return Err(KernelStoreError::NotKernels {
            path: path.to_path_buf(),
        });
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    let mut r = Reader {
        bytes: body,
        at: MAGIC.len(),
    };
    let version = r.u32().ok_or_else(|| damaged("truncated header"))?;
    if version != FORMAT_VERSION {
        return Err(KernelStoreError::Version {
            path: path.to_path_buf(),
            found: version,
        });
    }
    if fnv1a(body).to_le_bytes() != sum {
        return Err(damaged("checksum"));
    }
    let key_len = r.u32().ok_or_else(|| damaged("truncated key"))? as usize;
    if r.take(key_len) != Some(&key.bytes()[..]) {
        return Err(KernelStoreError::OtherKey {
            path: path.to_path_buf(),
        });
    }
    let parsed = parse_body(&mut r, &key.settings).ok_or_else(|| damaged("kernel values"))?;
    if r.at != body.len() {
        return Err(damaged("trailing bytes"));
    }
    Ok(parsed)
}

/// The kernel set after the key; None where a count disagrees with the settings, a node list
/// is not evenly spaced, or a value is not one a traced set has.
fn parse_body(r: &mut Reader, settings: &KernelSettings) -> Option<LensKernels> {
    let (depths, fields) = (r.u32()? as usize, r.u32()? as usize);
    if depths != settings.depth_nodes || fields != settings.field_nodes {
        return None;
    }
    let pixel_tangent = r.f64()?;
    let inverse_depths: Vec<f64> = (0..depths).map(|_| r.f64()).collect::<Option<_>>()?;
    let field_tangents: Vec<f64> = (0..fields).map(|_| r.f64()).collect::<Option<_>>()?;
    let even = |nodes: &[f64]| {
        let step = (nodes[nodes.len() - 1] - nodes[0]) / (nodes.len() - 1) as f64;
        step > 0.0
            && nodes
                .iter()
                .enumerate()
                .all(|(i, &v)| (v - (nodes[0] + step * i as f64)).abs() <= 1e-9 * step.max(v.abs()))
    };
    if !(pixel_tangent > 0.0 && even(&inverse_depths) && even(&field_tangents)) {
        return None;
    }
    let mut kernels = Vec::with_capacity(depths * fields);
    for _ in 0..depths * fields {
        let side = r.u32()? as usize;
        if side != 0 && side != settings.grid_side {
            return None;
        }
        let mut f = [0.0; 8];
        for v in &mut f {
            *v = r.f64()?;
        }
        let values: Vec<f32> = (0..side * side)
            .map(|_| r.f32().filter(|v| *v >= 0.0 && v.is_finite()))
            .collect::<Option<_>>()?;
        let [ox, oy, spacing, flux, cx, cy, rms_radius, support] = f;
        if f.iter().any(|v| !v.is_finite()) || spacing <= 0.0 || flux < 0.0 {
            return None;
        }
        kernels.push(Kernel {
            origin: [ox, oy],
            spacing,
            side,
            values,
            flux,
            centroid: [cx, cy],
            rms_radius,
            support,
        });
    }
    Some(LensKernels {
        inverse_depths,
        field_tangents,
        pixel_tangent,
        kernels,
    })
}

/// Little-endian output.
#[derive(Default)]
struct Bytes(Vec<u8>);

impl Bytes {
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn text(&mut self, v: &str) {
        self.u32(v.len() as u32);
        self.0.extend_from_slice(v.as_bytes());
    }
}

/// Little-endian input; None past the end.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let slice = self.bytes.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(slice)
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn f32(&mut self) -> Option<f32> {
        Some(f32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

fn fnv1a(bytes: &[u8]) -> u64 {
    use std::hash::Hasher;
    let mut hasher = fnv::FnvHasher::default();
    hasher.write(bytes);
    hasher.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small_set() -> LensKernels {
        let kernel = |flux: f64| Kernel {
            origin: [-2.0, -2.0],
            spacing: 1.0,
            side: 4,
            values: (0..16).map(|i| i as f32 * 0.01).collect(),
            flux,
            centroid: [0.1, 0.0],
            rms_radius: 1.2,
            support: 2.5,
        };
        LensKernels {
            inverse_depths: vec![0.001, 0.002],
            field_tangents: vec![0.0, 0.1, 0.2],
            pixel_tangent: 0.001,
            kernels: (0..6).map(|i| kernel(1.0 - 0.1 * i as f64)).collect(),
        }
    }

    fn key() -> KernelKey {
        KernelKey {
            prescription_hash: "0123456789abcdef".into(),
            f_number: 2.0,
            film_z: 90.5,
            view: View {
                eye_z: 10.0,
                tan_half: [0.4, 0.3],
                width: 80,
                height: 60,
            },
            depth_range_mm: [500.0, 9000.0],
            settings: KernelSettings {
                depth_nodes: 2,
                field_nodes: 3,
                rays_per_side: 8,
                grid_side: 4,
            },
        }
    }

    #[test]
    fn a_stored_set_reads_back_whole_and_only_for_its_own_key() {
        let dir = std::env::temp_dir().join(format!("lensbake-kernels-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (set, key) = (small_set(), key());
        let path = key.path_in(&dir);
        write(&path, &key, &set).unwrap();
        assert_eq!(read(&path, &key).unwrap(), set);
        let other_focus = KernelKey {
            film_z: 90.6,
            ..key.clone()
        };
        assert_ne!(other_focus.file_name(), key.file_name());
        assert!(matches!(
            read(&path, &other_focus),
            Err(KernelStoreError::OtherKey { .. })
        ));
        // One flipped bit in a kernel value is caught by the checksum.
        let mut bytes = std::fs::read(&path).unwrap();
        let middle = bytes.len() / 2;
        bytes[middle] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        assert!(matches!(
            read(&path, &key),
            Err(KernelStoreError::Damaged { .. })
        ));
        // Another format version is named as such.
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[MAGIC.len()] = 9;
        std::fs::write(&path, &bytes).unwrap();
        assert!(matches!(
            read(&path, &key),
            Err(KernelStoreError::Version { found: 9, .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
