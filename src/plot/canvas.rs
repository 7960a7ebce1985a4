//! Drawing helpers shared by every picture: fonts, the title block, legend
//! swatches and writing the PNG.

use std::path::Path;
use std::sync::Once;

use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

/// Width of the legend column right of a map [px].
pub(super) const LEGEND_WIDTH: u32 = 330;
/// The family name the bundled DejaVu Sans is registered under.
const FONT: &str = "sans-serif";

/// Registers the bundled fonts with plotters, once per process.
fn register_fonts() {
    static FONTS: Once = Once::new();
    FONTS.call_once(|| {
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
        let _ = plotters::style::register_font(FONT, FontStyle::Bold, dejavu::sans::bold());
    });
}

/// Plain black text of `size` px.
pub(super) fn font(size: u32) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

/// Bold black text of `size` px.
fn bold(size: u32) -> TextStyle<'static> {
    (FONT, size, FontStyle::Bold).into_font().color(&BLACK)
}

/// A drawing area of a picture in memory.
pub(super) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Draws a bold first line and plain further lines at the top of `area`
/// and returns the area below them.
pub(super) fn title_block<'a>(area: &Area<'a>, lines: &[String]) -> Result<Area<'a>> {
    let height = 20 + 32 + 22 * lines.len().saturating_sub(1) as u32;
    let (top, rest) = area.split_vertically(height);
    let mut y = 10;
    for (k, line) in lines.iter().enumerate() {
        let style = if k == 0 { bold(22) } else { font(16) };
        top.draw_text(line, &style, (20, y))?;
        y += if k == 0 { 32 } else { 22 };
    }
    Ok(rest)
}

/// Draws one legend entry (a swatch and its text) at `(x, y)` of `area`.
pub(super) fn swatch(area: &Area<'_>, x: i32, y: i32, colour: RGBColor, text: &str) -> Result<()> {
    area.draw(&Rectangle::new([(x, y), (x + 18, y + 18)], colour.filled()))?;
    area.draw(&Rectangle::new(
        [(x, y), (x + 18, y + 18)],
        BLACK.stroke_width(1),
    ))?;
    area.draw_text(text, &font(14), (x + 26, y + 2))?;
    Ok(())
}

/// Draws a picture in memory and writes it as a PNG at the best
/// compression (about half the size plotters' own encoder gives). Pictures
/// are written into the staging folder (see `staging`), so a failure here
/// leaves nothing in the output folder.
pub(super) fn save(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&Area<'_>) -> Result<()>,
) -> Result<()> {
    register_fonts();
    let mut pixels = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        root.fill(&WHITE)?;
        draw(&root)?;
        root.present()?;
    }
    let write = || -> Result<()> {
        let file = std::io::BufWriter::new(std::fs::File::create(path)?);
        let mut encoder = png::Encoder::new(file, size.0, size.1);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Best);
        encoder.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&pixels)?;
        writer.finish()?;
        Ok(())
    };
    write().with_context(|| format!("cannot write {}", path.display()))
}
