//! Turning a view into PNG or SVG bytes, and writing files atomically.

use super::font::{FONT_FAMILY, ensure_registered, svg_font_face};
use super::{Drawn, PlotError, View, draw_error};
use plotters::prelude::{BitMapBackend, IntoDrawingArea, SVGBackend, WHITE};
use std::path::Path;

/// Output format, chosen by the file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Png,
    Svg,
}

impl Format {
    /// The format a file name asks for (`.png` or `.svg`, any case).
    pub fn of_path(path: &Path) -> Result<Format, PlotError> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("png") => Ok(Format::Png),
            Some("svg") => Ok(Format::Svg),
            _ => Err(PlotError::UnknownFormat {
                path: path.display().to_string(),
            }),
        }
    }
}

/// An encoded plot and the summary of what was drawn on it.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub bytes: Vec<u8>,
    pub drawn: Drawn,
}

/// Draws `view` and encodes it.
pub fn render<V: View>(view: &V, format: Format) -> Result<Rendered, PlotError> {
    ensure_registered()?;
    let (width, height) = view.size();
    match format {
        Format::Png => {
            let mut pixels = vec![0u8; width as usize * height as usize * 3];
            let drawn = {
                let root =
                    BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
                root.fill(&WHITE).map_err(draw_error)?;
                let drawn = view.draw(&root)?;
                root.present().map_err(draw_error)?;
                drawn
            };
            Ok(Rendered {
                bytes: encode_png(&pixels, width, height)?,
                drawn,
            })
        }
        Format::Svg => {
            let mut text = String::new();
            let drawn = {
                let root = SVGBackend::with_string(&mut text, (width, height)).into_drawing_area();
                root.fill(&WHITE).map_err(draw_error)?;
                let drawn = view.draw(&root)?;
                root.present().map_err(draw_error)?;
                drawn
            };
            // The font travels inside the file; the generic family only matters to viewers
            // that ignore @font-face.
            let text = text.replace(
                &format!("font-family=\"{FONT_FAMILY}\""),
                &format!("font-family=\"{FONT_FAMILY}, sans-serif\""),
            );
            let text = embed_font(&text);
            Ok(Rendered {
                bytes: text.into_bytes(),
                drawn,
            })
        }
    }
}

/// `svg` with the embedded font's `@font-face` rule as the root element's first child.
fn embed_font(svg: &str) -> String {
    match svg
        .find("<svg")
        .and_then(|start| svg[start..].find('>').map(|end| start + end + 1))
    {
        Some(after_root) => format!(
            "{}{}{}",
            &svg[..after_root],
            svg_font_face(),
            &svg[after_root..]
        ),
        None => svg.to_string(),
    }
}

fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>, PlotError> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder
        .write_header()
        .map_err(|e| PlotError::Encode(e.to_string()))?;
    writer
        .write_image_data(rgb)
        .map_err(|e| PlotError::Encode(e.to_string()))?;
    writer
        .finish()
        .map_err(|e| PlotError::Encode(e.to_string()))?;
    Ok(bytes)
}

/// Draws `view` into `path` (format from its extension), atomically.
pub fn write_plot<V: View>(view: &V, path: &Path) -> Result<Drawn, PlotError> {
    let rendered = render(view, Format::of_path(path)?)?;
    crate::output::write_bytes(path, &rendered.bytes)?;
    Ok(rendered.drawn)
}
