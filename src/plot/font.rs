//! The embedded plot font: DejaVu Sans (Bitstream Vera licence, assets/fonts/LICENSE-DejaVu.txt).
//!
//! plotters' ab_glyph backend looks fonts up by family name in a process-wide table; registering
//! our bytes there once means no plot ever asks the operating system for a font. SVG output
//! carries the same bytes in an `@font-face` rule (`svg_font_face`), so it renders alike on
//! machines without the font, at the cost of about 1 MB per file.

use super::PlotError;
use std::sync::OnceLock;

/// Family name the plots ask for; SVG output names it in `font-family`.
pub const FONT_FAMILY: &str = "DejaVu Sans";

const DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Registers the embedded font with plotters (idempotent, thread safe).
pub(crate) fn ensure_registered() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT_FAMILY, plotters::style::FontStyle::Normal, DEJAVU_SANS)
            .is_ok()
    });
    if ok { Ok(()) } else { Err(PlotError::Font) }
}

/// A `<style>` element defining [`FONT_FAMILY`] from the embedded font's bytes (a base64 data
/// URL), for the start of an SVG document.
pub(crate) fn svg_font_face() -> String {
    format!(
        "<style>@font-face{{font-family:\"{FONT_FAMILY}\";src:url(data:font/ttf;base64,{})format(\"truetype\");}}</style>",
        base64(DEJAVU_SANS)
    )
}

/// Standard base64 (RFC 4648, with padding).
fn base64(bytes: &[u8]) -> String {
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

#[cfg(test)]
mod tests {
    use super::base64;

    #[test]
    fn base64_matches_rfc_4648_test_vectors() {
        let vectors = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, encoded) in vectors {
            assert_eq!(base64(plain.as_bytes()), encoded, "{plain:?}");
        }
    }
}
