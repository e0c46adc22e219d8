//! Plot helpers shared by every figure: the bundled font (pure Rust text rendering).

use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static INIT: Once = Once::new();

/// Registers the bundled DejaVu Sans as plotters' "sans-serif" family (idempotent).
pub fn register_fonts() {
    INIT.call_once(|| {
        for style in [
            plotters::style::FontStyle::Normal,
            plotters::style::FontStyle::Bold,
            plotters::style::FontStyle::Italic,
            plotters::style::FontStyle::Oblique,
        ] {
            // The font is bundled and valid; registration only fails on malformed bytes.
            let _ = plotters::style::register_font("sans-serif", style, FONT);
        }
    });
}
