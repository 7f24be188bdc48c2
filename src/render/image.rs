//! HDR images in and out: linear OpenEXR (R, G, B float), tone-mapped PNG, and an RGB + Z
//! OpenEXR read as a one-layer scene. Every write goes to a temporary file in the target
//! directory and is renamed into place, so no half-written file is ever left behind.

use super::RenderError;
use super::layers::{LayerBuilder, LayeredDepthImage, Surfel, View};
use crate::limits;
use std::fs::File;
use std::io::BufWriter;
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

/// Writes `path` through the one atomic writer, naming the file in any failure.
fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&File>) -> Result<(), String>,
) -> Result<(), RenderError> {
    crate::output::write_file(path, |out| write(out).map_err(std::io::Error::other)).map_err(
        |error| RenderError::Write {
            path: path.to_path_buf(),
            reason: error.cause(),
        },
    )
}

/// The tone-mapped PNG written beside the EXR `exr_path`. Refuses a path that does not end in
/// `.exr`, whose PNG would otherwise land on the EXR itself (`--out x.png`).
pub fn png_beside(exr_path: &Path) -> Result<PathBuf, RenderError> {
    let is_exr = exr_path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if !is_exr {
        return Err(RenderError::Write {
            path: exr_path.to_path_buf(),
            reason: "the image is OpenEXR, so its name must end in .exr (a tone-mapped .png is \
                     written beside it)"
                .into(),
        });
    }
    Ok(exr_path.with_extension("png"))
}

/// Writes linear R, G, B as 32-bit float channels.
pub fn write_exr(image: &RgbImage, path: &Path) -> Result<(), RenderError> {
    use exr::prelude::WritableImage;
    let channels = exr::prelude::SpecificChannels::rgb(|position: exr::prelude::Vec2<usize>| {
        let p = image.pixels[position.y() * image.width as usize + position.x()];
        (p[0], p[1], p[2])
    });
    let exr_image = exr::prelude::Image::from_encoded_channels(
        (image.width as usize, image.height as usize),
        crate::output::reproducible_exr_encoding(),
        channels,
    );
    write_atomically(path, |out| {
        exr_image
            .write()
            .to_buffered(out)
            .map_err(|e| e.to_string())
    })
}

/// Writes an 8-bit sRGB PNG: radiance scaled by `exposure`, Reinhard tone curve, sRGB encoding.
pub fn write_png(image: &RgbImage, exposure: f32, path: &Path) -> Result<(), RenderError> {
    write_rgb8_png(&srgb8(image, exposure), image.width, image.height, path)
}

/// The image as 8-bit sRGB, RGB interleaved: radiance scaled by `exposure`, Reinhard tone
/// curve, sRGB encoding (what [`write_png`] writes).
pub fn srgb8(image: &RgbImage, exposure: f32) -> Vec<u8> {
    image
        .pixels
        .iter()
        .flat_map(|p| p.map(|c| tone_map(c * exposure)))
        .collect()
}

/// Writes `width` x `height` 8-bit sRGB pixels (RGB interleaved) as a PNG.
pub fn write_rgb8_png(
    bytes: &[u8],
    width: u32,
    height: u32,
    path: &Path,
) -> Result<(), RenderError> {
    if bytes.len() != width as usize * height as usize * 3 {
        return Err(RenderError::Write {
            path: path.to_path_buf(),
            reason: format!("{} bytes are not {width}x{height} RGB pixels", bytes.len()),
        });
    }
    write_atomically(path, |out| {
        let mut encoder = png::Encoder::new(out, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
        writer.write_image_data(bytes).map_err(|e| e.to_string())?;
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
    let bytes = crate::limits::read_input(path).map_err(|e| bad(e.to_string()))?;
    // The header's size is checked before the decoder allocates the pixels it claims.
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes), false)
        .map_err(|e| bad(e.to_string()))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| bad("the file holds no image".into()))?;
    let (width, height) = (header.layer_size.0 as u64, header.layer_size.1 as u64);
    for (what, value, limit) in [
        ("the image's width", width, limits::MAX_IMAGE_SIDE),
        ("the image's height", height, limits::MAX_IMAGE_SIDE),
        (
            "the image's pixel count",
            width * height,
            limits::MAX_LAYER_PIXELS,
        ),
    ] {
        limits::check(what, value, limit).map_err(|e| bad(e.to_string()))?;
    }
    use exr::prelude::{ReadChannels, ReadLayers};
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(&bytes))
        .map_err(|e| bad(e.to_string()))?;
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
    let mut layers = LayerBuilder::new(view, 1);
    for i in 0..z.len() {
        // A pixel without a finite positive depth is background: nothing there.
        if !(z[i].is_finite() && z[i] > 0.0) {
            layers.push_pixel(&mut []);
            continue;
        }
        let colour = [r[i], g[i], b[i]];
        if let Some(c) = colour.iter().find(|&&c| !limits::is_radiance(c as f64)) {
            return Err(bad(format!(
                "pixel ({}, {}) has radiance {c}, not a light level in [0, {:e}]",
                i % view.width.max(1) as usize,
                i / view.width.max(1) as usize,
                limits::MAX_RADIANCE
            )));
        }
        layers.push_pixel(&mut [Surfel {
            depth_mm: z[i],
            radiance: colour,
        }]);
    }
    Ok(layers.finish())
}

/// Writes radiance plus a Z channel: the inverse of [`read_exr_rgbz`] for the first layer.
pub fn write_exr_rgbz(ldi: &LayeredDepthImage, path: &Path) -> Result<(), RenderError> {
    use exr::prelude::*;
    let first = ldi.layer(0);
    let size = (ldi.view.width as usize, ldi.view.height as usize);
    let samples = |f: &dyn Fn(&Surfel) -> f32| {
        FlatSamples::F32(first.samples().map(|s| s.as_ref().map_or(0.0, f)).collect())
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
        crate::output::reproducible_exr_encoding(),
        channels,
    ));
    write_atomically(path, |out| {
        image.write().to_buffered(out).map_err(|e| e.to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same image is written as the same bytes, however the parallel compressor's threads
    /// finish its tiles: blocks are stored in increasing order, which the file's header states.
    #[test]
    fn exr_files_are_byte_reproducible() {
        let (width, height) = (320, 200);
        // Tiles of very different run lengths, so they take different times to compress.
        let pixels = (0..width * height)
            .map(|i: u32| {
                let v = if i % width < 150 {
                    0.25
                } else {
                    i.wrapping_mul(2654435761) as f32
                };
                [v, 0.5 * v, 1.0]
            })
            .collect();
        let image = RgbImage {
            width,
            height,
            pixels,
        };
        let dir = std::env::temp_dir().join(format!("lensbake-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap();
        let written: Vec<Vec<u8>> = (0..6)
            .map(|k| {
                let path = dir.join(format!("{k}.exr"));
                pool.install(|| write_exr(&image, &path)).unwrap();
                std::fs::read(&path).unwrap()
            })
            .collect();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(written.iter().all(|bytes| *bytes == written[0]));
        let meta =
            exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&written[0]), false)
                .unwrap();
        assert_eq!(
            meta.headers[0].line_order,
            exr::prelude::LineOrder::Increasing
        );
    }
}
