//! The flyover report: the paper's figures, drawn from a run's `stats.csv` as PNG plots over
//! flight time — frame rate against its target, triangles per frame against the budget,
//! downloads per second, loaded and rendered tiles, memory against its limit.
//!
//! Plots are drawn with plotters' bitmap backend; text uses DejaVu Sans Mono, embedded in the
//! binary (`DejaVuSansMono-LICENSE.txt` beside it), through plotters' `ab_glyph` feature, so no
//! system font library is needed. PNGs are encoded by `image`.

mod table;

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::register_font;

use crate::error::{Error, Result};
pub use table::StatsTable;

/// Width and height of every plot, pixels.
pub const PLOT_SIZE: (u32, u32) = (800, 400);

/// The plots [`draw`] writes, by file name.
pub const PLOT_FILES: [&str; 5] = [
    "fps.png",
    "triangles.png",
    "downloads.png",
    "tiles.png",
    "memory.png",
];

const FONT: &[u8] = include_bytes!("DejaVuSansMono.ttf");
const FAMILY: &str = "sans-serif";

/// One line of a plot.
struct Series {
    label: &'static str,
    color: RGBColor,
    points: Vec<(f64, f64)>,
}

/// Reads `dir/stats.csv` and writes the plots of [`PLOT_FILES`] into `dir`; returns their paths.
pub fn draw(dir: &Path) -> Result<Vec<PathBuf>> {
    let table = StatsTable::read(&dir.join("stats.csv"))?;
    let time = table.column("time_s")?;
    let with_time = |values: Vec<f64>| time.iter().copied().zip(values).collect::<Vec<_>>();
    let mb = |values: Vec<f64>| values.into_iter().map(|v| v / 1e6).collect();
    let plots = [
        (
            "Frame rate",
            "frames per second",
            vec![
                series("fps", BLUE, with_time(table.column("fps")?)),
                series("target", RED, with_time(table.column("target_fps")?)),
            ],
        ),
        (
            "Triangles per frame",
            "triangles",
            vec![
                series("triangles", BLUE, with_time(table.column("triangles")?)),
                series("budget", RED, with_time(table.column("budget")?)),
            ],
        ),
        (
            "Downloads per second",
            "tiles per second",
            vec![series(
                "downloads",
                BLUE,
                per_second(&time, &table.column("downloads")?),
            )],
        ),
        (
            "Tiles",
            "tiles",
            vec![
                series("loaded", BLUE, with_time(table.column("loaded_tiles")?)),
                series(
                    "rendered",
                    GREEN,
                    with_time(table.column("rendered_tiles")?),
                ),
            ],
        ),
        (
            "Memory",
            "MB",
            vec![
                series("memory", BLUE, with_time(mb(table.column("memory_bytes")?))),
                series(
                    "limit",
                    RED,
                    with_time(mb(table.column("memory_limit_bytes")?)),
                ),
            ],
        ),
    ];
    let mut written = Vec::new();
    for ((title, unit, lines), file) in plots.into_iter().zip(PLOT_FILES) {
        let path = dir.join(file);
        plot(&path, title, unit, &lines)?;
        written.push(path);
    }
    Ok(written)
}

fn series(label: &'static str, color: RGBColor, points: Vec<(f64, f64)>) -> Series {
    Series {
        label,
        color,
        points,
    }
}

/// Events per second of flight time from a cumulative count, in one-second bins, as steps.
fn per_second(time: &[f64], cumulative: &[f64]) -> Vec<(f64, f64)> {
    let Some(&end) = time.last() else {
        return Vec::new();
    };
    let mut points = Vec::new();
    let mut k = 0;
    let mut before = 0.0;
    let mut second = 0.0;
    while second <= end {
        while k < time.len() && time[k] < second + 1.0 {
            k += 1;
        }
        let now = if k > 0 { cumulative[k - 1] } else { 0.0 };
        points.push((second, now - before));
        points.push((second + 1.0, now - before));
        before = now;
        second += 1.0;
    }
    points
}

/// Registers the embedded font with plotters (once) and returns its family name, for every
/// plot the crate draws.
pub(crate) fn font_family() -> &'static str {
    static FONT_ONCE: Once = Once::new();
    FONT_ONCE.call_once(|| {
        let parsed = register_font(FAMILY, FontStyle::Normal, FONT).is_ok();
        assert!(parsed, "the embedded font parses");
    });
    FAMILY
}

/// A drawing failure, from any plotters back end.
pub(crate) type PlotError = Box<dyn std::error::Error>;

/// Draws a `size` plot with `draw` on a white bitmap (the embedded font registered) and saves
/// it as the PNG `path`; errors name the file.
pub(crate) fn save_plot(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(
        &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    ) -> std::result::Result<(), PlotError>,
) -> Result<()> {
    font_family();
    let name = path.display().to_string();
    let (w, h) = size;
    let mut pixels = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        root.fill(&WHITE)
            .map_err(PlotError::from)
            .and_then(|()| draw(&root))
            .and_then(|()| root.present().map_err(PlotError::from))
            .map_err(|e| Error::invalid(&name, format!("plotting failed: {e}")))?;
    }
    let image = image::RgbImage::from_raw(w, h, pixels).expect("the buffer is w x h x 3");
    image
        .save(path)
        .map_err(|e| Error::invalid(&name, format!("writing the plot failed: {e}")))
}

fn plot(path: &Path, title: &str, unit: &str, lines: &[Series]) -> Result<()> {
    save_plot(path, PLOT_SIZE, |root| {
        let points = || lines.iter().flat_map(|s| s.points.iter());
        let x_max = points().map(|p| p.0).fold(0.0, f64::max).max(1.0);
        let y_max = points().map(|p| p.1).fold(0.0, f64::max).max(1.0) * 1.1;
        let mut chart = ChartBuilder::on(root)
            .caption(title, (FAMILY, 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..x_max, 0.0..y_max)?;
        chart
            .configure_mesh()
            .x_desc("flight time, s")
            .y_desc(unit)
            .label_style((FAMILY, 14))
            .draw()?;
        for s in lines {
            let color = s.color;
            chart
                .draw_series(LineSeries::new(
                    s.points.iter().copied(),
                    color.stroke_width(2),
                ))?
                .label(s.label)
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((FAMILY, 14))
            .draw()?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downloads_per_second_are_counted_in_one_second_bins() {
        let time = [0.0, 0.4, 0.9, 1.3, 2.5];
        let cumulative = [1.0, 2.0, 2.0, 5.0, 6.0];
        let points = per_second(&time, &cumulative);
        let rates: Vec<f64> = points.iter().step_by(2).map(|p| p.1).collect();
        assert_eq!(rates, [2.0, 3.0, 1.0]);
        assert!(per_second(&[], &[]).is_empty());
    }
}
