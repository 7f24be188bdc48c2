//! The embedded plot font: DejaVu Sans (Bitstream Vera licence, assets/fonts/LICENSE-DejaVu.txt).
//!
//! plotters' ab_glyph backend looks fonts up by family name in a process-wide table; registering
//! our bytes there once means no plot ever asks the operating system for a font.

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
