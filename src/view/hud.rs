//! What the viewer writes over its image: the HUD's lines (drawn with the plots' embedded font)
//! and the false-colour map of the split view's error.

use super::{ViewError, Viewer};
use crate::job::BackendUsed;
use crate::plot::font::{FONT_FAMILY, ensure_registered};
use crate::render::image::RgbImage;
use crate::render::reference::psnr;
use plotters::prelude::*;

/// The HUD: frame time, samples so far, model, f-number, focus distance, lens, adapter, and a
/// bake in progress.
pub fn lines(viewer: &Viewer) -> Vec<String> {
    let job = viewer.job();
    let (samples, target) = viewer.samples();
    let shown = viewer.shown_model().name();
    let asked = match job.model {
        crate::job::ModelChoice::Model(kind) => kind.name(),
        crate::job::ModelChoice::ErrorBudgetPx(_) => "budget",
    };
    let model = match (viewer.split(), viewer.bake_progress()) {
        (true, Some(_)) => "split: traced (baked half waiting for its table)".to_string(),
        (true, None) => "split: baked | traced".to_string(),
        (false, Some(_)) => format!("{shown} (showing while {asked} bakes)"),
        (false, None) => shown.to_string(),
    };
    let lens = super::lens_name(&job.lens);
    let lens = match job.lens.real().and_then(|real| real.stop_shape()) {
        Some(crate::prescription::StopShape::Blades {
            count,
            rotation_deg,
            blade_curvature,
        }) => format!(
            "{lens}, {count} blades at {rotation_deg:.0} deg, curvature {blade_curvature:.2} \
             (traced and baked)"
        ),
        _ => lens,
    };
    let focus = match viewer.focus_distance_mm() {
        Some(Some(mm)) => format!("{:.3} m", mm / 1000.0),
        Some(None) => "infinity".to_string(),
        None => format!("sensor at {:.3} mm", viewer.camera().film_z),
    };
    let focus = match &viewer.camera().pixel_focus {
        Some(surface) => format!(
            "{focus} at the centre, focal surface of {} points (beta {})",
            surface.surface.points().len(),
            surface.surface.beta()
        ),
        None => focus,
    };
    let f_number = job.lens.first_order(job.f_number).map_or_else(
        |_| "?".to_string(),
        |(models, f)| format!("{:.1} mm f/{f:.2}", models.thick.focal_length_mm),
    );
    let lens = match viewer.zoom_position() {
        (_, 1) => lens,
        (position, count) => format!("{lens}, zoom {position}/{count}"),
    };
    let adapter = match viewer.backend() {
        BackendUsed::Gpu { adapter } => adapter.clone(),
        BackendUsed::Cpu {
            gpu_unavailable: Some(why),
        } => format!("CPU twin (no GPU: {why})"),
        BackendUsed::Cpu {
            gpu_unavailable: None,
        } => "CPU twin".to_string(),
    };
    let scale = job.aberration_scale;
    let model = match viewer.camera().model.kind() {
        crate::model::ModelKind::Seidel if scale != crate::model::AberrationScale::AS_DESIGNED => {
            let [sa, coma, ast, petz, dist] = scale.to_array();
            format!("{model} x (SA {sa}, coma {coma}, ast {ast}, Petzval {petz}, dist {dist})")
        }
        _ => model,
    };
    let lens = match job.orbit {
        Some(orbit) => format!(
            "{lens}; orbit {:.0} deg right, {:.0} deg up about {:.2} m",
            orbit.angles_deg[0],
            orbit.angles_deg[1],
            orbit.pivot_mm / 1000.0
        ),
        None => lens,
    };
    let mut lines = vec![
        format!(
            "{:.1} ms/frame, {} spp/frame",
            viewer.last_frame().as_secs_f64() * 1e3,
            viewer.spp_per_frame()
        ),
        format!(
            "samples {samples}/{target}{}",
            if viewer.converged() { " (done)" } else { "" }
        ),
        format!("model {model}"),
        format!("{f_number}, focus {focus}"),
        format!(
            "sensor {:.1} x {:.1} mm, exposure {:+.2} EV{}",
            viewer.camera().film.width_mm,
            viewer.camera().film.height_mm,
            viewer.exposure_ev(),
            if viewer.zone() {
                ", green: blur under 1 px"
            } else {
                ""
            }
        ),
        format!("lens {lens}"),
        adapter,
    ];
    // The worker hears of a bake's nodes only once it bakes; until then it is looking for a
    // table on disk or loading one.
    match viewer.bake_progress() {
        Some((done, total)) if total > 0 => lines.push(format!("baking table: {done}/{total}")),
        Some(_) => lines.push("table: loading (baked if none on disk fits)".to_string()),
        None => {}
    }
    match comparison(viewer, samples) {
        Ok(Some(line)) => lines.push(line),
        Ok(None) => {}
        Err(error) => lines.push(format!("baked vs traced: cannot compare ({error})")),
    }
    lines
}

/// The split view's line comparing its halves (None outside the split view). On the GPU it
/// reads both renders back: the comparison is the one HUD entry that needs the pixels.
fn comparison(viewer: &Viewer, samples: u32) -> Result<Option<String>, ViewError> {
    let Some(traced) = viewer.twin_image()? else {
        return Ok(None);
    };
    if samples == 0 {
        return Ok(Some("baked vs traced: no samples yet".to_string()));
    }
    let baked = viewer.image()?;
    let (_, scale) = error_map(&baked, &traced);
    Ok(Some(format!(
        "baked vs traced: PSNR {:.1} dB; overlay white = {}",
        psnr(&baked, &traced),
        significant(scale)
    )))
}

/// `value` with three significant digits, in plain notation (0.00213, 0.126, 4.50).
fn significant(value: f32) -> String {
    let magnitude = f64::from(value.abs());
    let decimals = if magnitude > 0.0 {
        (2 - magnitude.log10().floor() as i32).max(0) as usize
    } else {
        1
    };
    format!("{value:.decimals$}")
}

/// The colour scale of the error map: black, blue, magenta, orange, white at 0, 1/4, 1/2, 3/4
/// and 1 of the scale, linear between.
const RAMP: [[f32; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [0.1, 0.1, 0.8],
    [0.8, 0.1, 0.7],
    [1.0, 0.6, 0.1],
    [1.0, 1.0, 1.0],
];

/// A value in \[0, 1\] on `RAMP`, as 8-bit sRGB.
pub fn ramp(t: f32) -> [u8; 3] {
    let x = t.clamp(0.0, 1.0) * (RAMP.len() - 1) as f32;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - i as f32;
    std::array::from_fn(|c| {
        let v = RAMP[i][c] * (1.0 - f) + RAMP[i + 1][c] * f;
        (v * 255.0 + 0.5) as u8
    })
}

/// Per pixel the channel mean of |baked - traced| on `RAMP`, as 8-bit sRGB, with a colour bar
/// along the bottom 8 rows; and the scale: the error at the top of the ramp, the 99.5th
/// percentile of the pixels' errors (so a few edge pixels do not wash the map out).
pub fn error_map(baked: &RgbImage, traced: &RgbImage) -> (Vec<u8>, f32) {
    let errors: Vec<f32> = baked
        .pixels
        .iter()
        .zip(&traced.pixels)
        .map(|(b, t)| ((b[0] - t[0]).abs() + (b[1] - t[1]).abs() + (b[2] - t[2]).abs()) / 3.0)
        .collect();
    let mut sorted = errors.clone();
    sorted.sort_by(f32::total_cmp);
    let at = ((sorted.len() as f64 * 0.995) as usize).min(sorted.len().saturating_sub(1));
    let scale = sorted
        .get(at)
        .copied()
        .unwrap_or(0.0)
        .max(f32::MIN_POSITIVE);
    let width = baked.width as usize;
    let height = baked.height as usize;
    let bar_rows = 8.min(height);
    let mut bytes = Vec::with_capacity(errors.len() * 3);
    for (i, e) in errors.iter().enumerate() {
        let (x, y) = (i % width, i / width);
        let t = if y >= height - bar_rows {
            x as f32 / (width.max(2) - 1) as f32
        } else {
            e / scale
        };
        bytes.extend(ramp(t));
    }
    (bytes, scale)
}

/// The HUD's text height (px).
const TEXT_SIZE: i32 = 14;
/// The opacity of the black box under the HUD's text (`shaders/compose.wgsl` has its own copy:
/// the `view` tests hold the two equal).
pub const HUD_SHADE: f64 = 0.55;

/// The HUD's box for `lines` in a `width` x `height` frame: its width and height (px).
fn text_box(lines: &[String], width: u32, height: u32) -> [u32; 2] {
    let longest = lines.iter().map(|l| l.len()).max().unwrap_or(0) as i32;
    let box_width = (longest * TEXT_SIZE * 55 / 100 + 12).min(width as i32);
    let box_height = (lines.len() as i32 * (TEXT_SIZE + 3) + 8).min(height as i32);
    [box_width.max(0) as u32, box_height.max(0) as u32]
}

/// `lines`' text as [`draw_lines`] draws it in a `width` x `height` frame, as coverage over its
/// box (one byte a pixel, 255 where the text is opaque): what the GPU's compose pass draws over
/// the frame. None where [`draw_lines`] would draw nothing.
pub fn text_coverage(lines: &[String], width: u32, height: u32) -> Option<([u32; 2], Vec<u8>)> {
    let [box_width, box_height] = text_box(lines, width, height);
    // White text drawn over black is its own coverage; the box's black shade leaves it black.
    let mut rgb = vec![0u8; box_width as usize * box_height as usize * 3];
    (width >= 32 && height >= 32 && draw_lines(&mut rgb, box_width, box_height, lines)).then(|| {
        (
            [box_width, box_height],
            rgb.chunks_exact(3).map(|p| p[0]).collect(),
        )
    })
}

/// Draws `lines` in the top-left corner of an 8-bit RGB frame, white on a dark box. Returns false
/// (drawing nothing) where the font cannot be registered or the frame is too small.
pub fn draw_lines(rgb: &mut [u8], width: u32, height: u32, lines: &[String]) -> bool {
    if ensure_registered().is_err() || width < 32 || height < 32 {
        return false;
    }
    let root = BitMapBackend::with_buffer(rgb, (width, height)).into_drawing_area();
    let [box_width, box_height] = text_box(lines, width, height).map(|n| n as i32);
    let shade = RGBAColor(0, 0, 0, HUD_SHADE).filled();
    let ok = root
        .draw(&Rectangle::new([(0, 0), (box_width, box_height)], shade))
        .is_ok();
    let font = (FONT_FAMILY, TEXT_SIZE).into_font().color(&WHITE);
    let drawn = lines.iter().enumerate().all(|(i, line)| {
        root.draw(&Text::new(
            line.as_str(),
            (6, 4 + i as i32 * (TEXT_SIZE + 3)),
            font.clone(),
        ))
        .is_ok()
    });
    ok && drawn && root.present().is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hud_text_lands_inside_its_box_and_nowhere_else() {
        let (width, height) = (320, 120);
        let mut rgb = vec![0u8; width as usize * height as usize * 3];
        let lines = [
            "12.5 ms/frame, 4 spp/frame".to_string(),
            "lens dgauss-50mm".to_string(),
        ];
        assert!(draw_lines(&mut rgb, width, height, &lines));
        let lit = |x0: u32, x1: u32, y0: u32, y1: u32| {
            let mut n = 0;
            for y in y0..y1 {
                for x in x0..x1 {
                    let i = (y * width + x) as usize * 3;
                    n += usize::from(rgb[i] > 128 && rgb[i + 1] > 128 && rgb[i + 2] > 128);
                }
            }
            n
        };
        // White glyph pixels on both lines' rows, none below the box or right of it.
        assert!(lit(0, 200, 0, 20) > 50, "first line");
        assert!(lit(0, 200, 20, 38) > 50, "second line");
        assert_eq!(lit(0, width, 45, height), 0);
        assert_eq!(lit(220, width, 0, height), 0);
    }

    #[test]
    fn scales_keep_three_significant_digits() {
        assert_eq!(significant(0.000_213_4), "0.000213");
        assert_eq!(significant(0.126_14), "0.126");
        assert_eq!(significant(4.5), "4.50");
        assert_eq!(significant(1234.4), "1234");
    }

    #[test]
    fn the_error_ramp_runs_black_to_white_and_the_bar_spans_it() {
        assert_eq!(ramp(0.0), [0, 0, 0]);
        assert_eq!(ramp(1.0), [255, 255, 255]);
        assert_eq!(ramp(2.0), [255, 255, 255]);
        let image = |v: f32| RgbImage {
            width: 10,
            height: 10,
            pixels: vec![[v; 3]; 100],
        };
        let (bytes, scale) = error_map(&image(0.5), &image(0.25));
        assert!((scale - 0.25).abs() < 1e-6);
        // Above the bar every pixel is at the top of the scale; the bar starts black.
        assert_eq!(&bytes[0..3], &[255, 255, 255]);
        assert_eq!(&bytes[9 * 30..9 * 30 + 3], &[0, 0, 0]);
    }
}
