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
        let mut pixels = vec![0u8; 3 * size.0 as usize * size.1 as usize];
        {
            let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
            root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
            figure.draw(&root)?;
            root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
        }
        write_png(&png, size, &pixels)?;
    }
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
        figure.draw(&root)?;
        root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    Ok(())
}

/// Write 8-bit RGB `pixels` as a PNG file, encoded as plotters' own file target did through
/// the `image` crate (fast deflate, adaptive filtering from Sub), so the charts keep their
/// bytes: drawing into a buffer and encoding with `png` here spares a fresh build the
/// `image` crate and its JPEG and BMP codecs, which nothing else uses.
fn write_png(path: &Path, size: (u32, u32), pixels: &[u8]) -> anyhow::Result<()> {
    use anyhow::Context;
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), size.0, size.1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    encoder.set_filter(png::FilterType::Sub);
    encoder.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
    let mut writer = encoder.write_header()?;
    writer
        .write_image_data(pixels)
        .with_context(|| format!("writing {}", path.display()))?;
    writer.finish()?;
    Ok(())
}
