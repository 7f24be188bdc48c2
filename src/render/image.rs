//! HDR images in and out: linear OpenEXR (R, G, B float), tone-mapped PNG, and an RGB + Z
//! OpenEXR read as a one-layer scene. Every write goes to a temporary file in the target
//! directory and is renamed into place, so no half-written file is ever left behind.

use super::RenderError;
use super::layers::{LayeredDepthImage, Surfel, View};
use std::path::{Path, PathBuf};

/// Linear RGB radiance, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl RgbImage {
    pub fn pixel(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean over pixels of the channel-averaged value.
    pub fn mean_luminance(&self) -> f64 {
        let sum: f64 = self
            .pixels
            .iter()
            .map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0)
            .sum();
        sum / self.pixels.len().max(1) as f64
    }
}

fn temp_beside(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), String>,
) -> Result<(), RenderError> {
    let temp = temp_beside(path);
    let failed = |reason: String| RenderError::Write {
        path: path.to_path_buf(),
        reason,
    };
    if let Err(reason) = write(&temp) {
        let _ = std::fs::remove_file(&temp);
        return Err(failed(reason));
    }
    std::fs::rename(&temp, path).map_err(|e| {
        let _ = std::fs::remove_file(&temp);
        failed(e.to_string())
    })
}

/// Writes linear R, G, B as 32-bit float channels.
pub fn write_exr(image: &RgbImage, path: &Path) -> Result<(), RenderError> {
    write_atomically(path, |temp| {
        exr::prelude::write_rgb_file(temp, image.width as usize, image.height as usize, |x, y| {
            let p = image.pixels[y * image.width as usize + x];
            (p[0], p[1], p[2])
        })
        .map_err(|e| e.to_string())
    })
}

/// Writes an 8-bit sRGB PNG: radiance scaled by `exposure`, Reinhard tone curve, sRGB encoding.
pub fn write_png(image: &RgbImage, exposure: f32, path: &Path) -> Result<(), RenderError> {
    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| p.map(|c| tone_map(c * exposure)))
        .collect();
    write_atomically(path, |temp| {
        let file = std::fs::File::create(temp).map_err(|e| e.to_string())?;
        let mut encoder =
            png::Encoder::new(std::io::BufWriter::new(file), image.width, image.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
        writer.write_image_data(&bytes).map_err(|e| e.to_string())?;
        writer.finish().map_err(|e| e.to_string())
    })
}

fn tone_map(linear: f32) -> u8 {
    let x = linear.max(0.0);
    let compressed = x / (1.0 + x);
    let srgb = if compressed <= 0.003_130_8 {
        12.92 * compressed
    } else {
        1.055 * compressed.powf(1.0 / 2.4) - 0.055
    };
    (srgb * 255.0 + 0.5).clamp(0.0, 255.0) as u8
}

/// Reads an OpenEXR image with R, G, B and Z channels (Z: distance from the eye along the axis,
/// mm) as a one-layer scene seen from `eye_z` over the field `tan_half`. Pixels whose Z is not a
/// positive finite number are empty.
pub fn read_exr_rgbz(
    path: &Path,
    eye_z: f64,
    tan_half: [f64; 2],
) -> Result<LayeredDepthImage, RenderError> {
    let bad = |reason: String| RenderError::Read {
        path: path.to_path_buf(),
        reason,
    };
    let image =
        exr::prelude::read_first_flat_layer_from_file(path).map_err(|e| bad(e.to_string()))?;
    let layer = &image.layer_data;
    let channel = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.eq(name))
            .map(|c| c.sample_data.values_as_f32().collect::<Vec<f32>>())
            .ok_or_else(|| bad(format!("no `{name}` channel (need R, G, B and Z)")))
    };
    let (r, g, b, z) = (channel("R")?, channel("G")?, channel("B")?, channel("Z")?);
    let view = View {
        eye_z,
        tan_half,
        width: layer.size.0 as u32,
        height: layer.size.1 as u32,
    };
    let lists = (0..z.len())
        .map(|i| {
            let depth_ok = z[i].is_finite() && z[i] > 0.0;
            let colour = [r[i], g[i], b[i]];
            if depth_ok && colour.iter().all(|c| c.is_finite()) {
                vec![Surfel {
                    depth_mm: z[i],
                    radiance: colour,
                }]
            } else {
                Vec::new()
            }
        })
        .collect();
    Ok(LayeredDepthImage::from_pixel_lists(view, lists, 1))
}

/// Writes radiance plus a Z channel: the inverse of [`read_exr_rgbz`] for the first layer.
pub fn write_exr_rgbz(ldi: &LayeredDepthImage, path: &Path) -> Result<(), RenderError> {
    use exr::prelude::*;
    let first = ldi.layers.first().ok_or(RenderError::EmptyScene)?;
    let size = (ldi.view.width as usize, ldi.view.height as usize);
    let samples = |f: &dyn Fn(&Surfel) -> f32| {
        FlatSamples::F32(
            first
                .samples
                .iter()
                .map(|s| s.as_ref().map_or(0.0, f))
                .collect(),
        )
    };
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![
        AnyChannel::new("R", samples(&|s| s.radiance[0])),
        AnyChannel::new("G", samples(&|s| s.radiance[1])),
        AnyChannel::new("B", samples(&|s| s.radiance[2])),
        AnyChannel::new("Z", samples(&|s| s.depth_mm)),
    ]));
    let image = Image::from_layer(Layer::new(
        size,
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        channels,
    ));
    write_atomically(path, |temp| {
        image.write().to_file(temp).map_err(|e| e.to_string())
    })
}
