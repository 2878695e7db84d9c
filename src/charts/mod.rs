//! Shared chart set-up for `plotters`: a bundled font (DejaVu Sans, Bitstream Vera
//! licence) registered once, so PNG and SVG charts render on machines without any
//! system font libraries, and helpers that draw one figure to both formats.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

/// Family name to use in `TextStyle`s ("sans-serif" is registered to the bundled font).
pub const FONT: &str = "sans-serif";

static REGISTER: Once = Once::new();

/// Register the bundled font (idempotent). Call before drawing any text.
pub fn init_fonts() {
    REGISTER.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("DejaVuSans.ttf");
        for style in [
            FontStyle::Normal,
            FontStyle::Bold,
            FontStyle::Italic,
            FontStyle::Oblique,
        ] {
            // The bundled file is a valid TrueType font; failure would only lose labels.
            let _ = plotters::style::register_font(FONT, style, bytes);
        }
    });
}

/// A figure that can be drawn on any plotters backend (so one description gives PNG and SVG).
pub trait Figure {
    /// Draw the figure on `area`.
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static;
}

/// Draw `figure` as `<stem>.png` and `<stem>.svg` in `dir`, `size` = (width, height) pixels.
pub fn save_png_and_svg(
    dir: &Path,
    stem: &str,
    size: (u32, u32),
    figure: &impl Figure,
) -> anyhow::Result<()> {
    init_fonts();
    let png = dir.join(format!("{stem}.png"));
    let svg = dir.join(format!("{stem}.svg"));
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
        figure.draw(&root)?;
        root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
        figure.draw(&root)?;
        root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    Ok(())
}
