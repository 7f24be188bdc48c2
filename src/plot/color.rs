//! Colours: wavelengths drawn in roughly their own hue, darkened enough to read on white.

use plotters::style::RGBColor;

/// A colour for light of `wavelength_nm`: blue for the F line, green-yellow for d, red for C.
/// Piecewise linear through the visible hues, then darkened so yellow stays legible on white.
pub fn wavelength_color(wavelength_nm: f64) -> RGBColor {
    // (nm, r, g, b) anchors of the visible spectrum.
    const ANCHORS: [(f64, f64, f64, f64); 7] = [
        (380.0, 0.45, 0.0, 0.75),
        (440.0, 0.0, 0.0, 1.0),
        (490.0, 0.0, 0.75, 1.0),
        (530.0, 0.0, 0.8, 0.0),
        (580.0, 0.85, 0.75, 0.0),
        (620.0, 1.0, 0.35, 0.0),
        (700.0, 0.85, 0.0, 0.0),
    ];
    let w = wavelength_nm.clamp(ANCHORS[0].0, ANCHORS[ANCHORS.len() - 1].0);
    let upper = ANCHORS
        .iter()
        .position(|a| a.0 >= w)
        .unwrap_or(ANCHORS.len() - 1)
        .max(1);
    let (a, b) = (ANCHORS[upper - 1], ANCHORS[upper]);
    let t = (w - a.0) / (b.0 - a.0);
    let mix = |x: f64, y: f64| (0.8 * 255.0 * (x + (y - x) * t)).round() as u8;
    RGBColor(mix(a.1, b.1), mix(a.2, b.2), mix(a.3, b.3))
}

/// Colours for series that are not wavelengths (fields, Seidel terms), distinct and print safe.
pub(crate) const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 60, 20),
    RGBColor(230, 159, 0),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fraunhofer_lines_get_their_hues() {
        let f = wavelength_color(486.13);
        let d = wavelength_color(587.56);
        let c = wavelength_color(656.27);
        assert!(f.2 > f.0 && f.2 > 100, "F line should be blue: {f:?}");
        assert!(c.0 > c.1 && c.0 > c.2, "C line should be red: {c:?}");
        assert!(
            d.0 > d.2 && d.1 > d.2,
            "d line should be yellow-orange: {d:?}"
        );
        // Nothing out of range or equal to the white background.
        for nm in [300.0, 400.0, 550.0, 800.0] {
            assert_ne!(wavelength_color(nm), RGBColor(255, 255, 255));
        }
    }
}
