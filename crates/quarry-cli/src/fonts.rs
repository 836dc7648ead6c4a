//! The font for text in plots and annotated frames.
//!
//! plotters' lean `ab_glyph` backend has no system font lookup (no fontconfig at build time, no
//! font at run time), so quarry bundles one: DejaVu Sans Mono (Bitstream Vera licence, see
//! `assets/DejaVu-LICENSE`). [`register`] makes it plotters' `"sans-serif"` family (the family
//! plotters' defaults ask for), once per process.

use std::sync::OnceLock;

/// The bundled TrueType font.
pub static DEJAVU_SANS_MONO: &[u8] = include_bytes!("../assets/DejaVuSansMono.ttf");

/// Registers the bundled font as plotters' `"sans-serif"` (and `"monospace"`) family.
///
/// Idempotent and cheap after the first call. Errors only if the bundled bytes are not a
/// font, which a test rules out.
pub fn register() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        for family in ["sans-serif", "monospace"] {
            plotters::style::register_font(
                family,
                plotters::style::FontStyle::Normal,
                DEJAVU_SANS_MONO,
            )
            .map_err(|_| "the bundled plot font is not a valid TrueType font".to_string())?;
        }
        Ok(())
    })
    .clone()
}

#[cfg(test)]
mod tests {
    use plotters::prelude::*;

    #[test]
    fn bundled_font_renders_text() {
        super::register().unwrap();
        let (w, h) = (120u32, 40u32);
        let mut buf = vec![255u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            root.draw(&Text::new(
                "quarry 0.5 m",
                (4, 10),
                ("sans-serif", 16).into_font(),
            ))
            .unwrap();
            root.present().unwrap();
        }
        let dark = buf.chunks(3).filter(|p| p[0] < 128).count();
        assert!(dark > 30, "text drew {dark} dark pixels");
    }
}
