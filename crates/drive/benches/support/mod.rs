//! What the benches of several crates share: the thread's CPU time, the plots' font and
//! legend. Each bench includes it with `#[path]` (a bench is its own crate).
#![allow(dead_code)] // each bench uses a part of it

use std::path::Path;
use std::time::Duration;

/// The CPU time this thread has used (the machine is shared: wall time would count the
/// other processes that preempt the bench).
pub fn thread_cpu_time() -> Duration {
    platform::cpu_time::thread()
}

/// Fonts tried for the plots' labels (a plot needs one; the benches still report without).
const FONTS: [&str; 3] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/Library/Fonts/Arial.ttf",
];

/// Registers a TrueType font as plotters' "sans-serif" (`DRIVETWIN_PLOT_FONT`, else the
/// first of [`FONTS`] found).
pub fn load_font() -> Result<(), String> {
    let path = std::env::var("DRIVETWIN_PLOT_FONT")
        .ok()
        .into_iter()
        .chain(FONTS.iter().map(|s| s.to_string()))
        .find(|p| Path::new(p).exists())
        .ok_or("no TrueType font found (set DRIVETWIN_PLOT_FONT)")?;
    let bytes = std::fs::read(&path).map_err(|e| e.to_string())?;
    plotters::style::register_font(
        "sans-serif",
        plotters::style::FontStyle::Normal,
        Box::leak(bytes.into_boxed_slice()),
    )
    .map_err(|_| format!("{path}: not a usable font"))
}

/// The legend box of the plots: white, framed, 15 px labels, at `position`.
pub fn draw_legend<'a, DB, CT>(
    chart: &mut plotters::chart::ChartContext<'a, DB, CT>,
    position: plotters::chart::SeriesLabelPosition,
) -> Result<(), String>
where
    DB: plotters::prelude::DrawingBackend + 'a,
    CT: plotters::coord::CoordTranslate,
{
    use plotters::style::{Color, BLACK, WHITE};
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(|e| e.to_string())
}

/// A legend entry's swatch for a line drawn in `style`: a 20 px stroke.
pub fn line_swatch(
    style: plotters::style::ShapeStyle,
) -> impl Fn((i32, i32)) -> plotters::element::PathElement<(i32, i32)> {
    move |(x, y)| plotters::element::PathElement::new([(x, y), (x + 20, y)], style)
}
