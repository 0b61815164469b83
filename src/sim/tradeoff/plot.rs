//! The error-against-frame-time plot: every setting as a point, the Pareto front as a line
//! through its named points, the defaults marked.

use std::path::Path;

use plotters::prelude::*;

use super::TradeoffReport;
use crate::error::Result;
use crate::sim::report::{font_family, save_plot};

/// Width and height of the plot, pixels.
pub const SIZE: (u32, u32) = (1000, 650);
/// Errors below this are drawn at it (the y axis is logarithmic).
const FLOOR: f64 = 1e-5;

/// Draws `report`'s settings into the PNG `path`: x the frame CPU time as a ratio to the defaults,
/// y `1 - SSIM` against the first reference, both on log scales.
pub fn draw(path: &Path, report: &TradeoffReport) -> Result<()> {
    let family = font_family();
    let point = |r: &super::Row| (r.ratio, (1.0 - r.measurement.errors[0].ssim).max(FLOOR));
    let points: Vec<(f64, f64)> = report.rows.iter().map(point).collect();
    let x_min = points.iter().map(|p| p.0).fold(1.0, f64::min) / 1.25;
    let x_max = points.iter().map(|p| p.0).fold(1.0, f64::max) * 1.25;
    let y_min = points.iter().map(|p| p.1).fold(1.0, f64::min) / 1.5;
    let y_max = points.iter().map(|p| p.1).fold(FLOOR, f64::max) * 1.5;
    save_plot(path, SIZE, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("Error against frame time: {}", report.source),
                (family, 20),
            )
            .margin(14)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d((x_min..x_max).log_scale(), (y_min..y_max).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("frame CPU time / defaults' frame CPU time")
            .y_desc(format!("1 - SSIM against {}", report.references[0]))
            .label_style((family, 14))
            .draw()?;
        chart
            .draw_series(
                points
                    .iter()
                    .map(|&p| Circle::new(p, 3, RGBColor(150, 150, 150).filled())),
            )?
            .label("setting")
            .legend(|(x, y)| Circle::new((x + 10, y), 3, RGBColor(150, 150, 150).filled()));
        let mut front: Vec<_> = report.rows.iter().filter(|r| r.pareto).collect();
        front.sort_by(|a, b| a.ratio.total_cmp(&b.ratio));
        chart
            .draw_series(LineSeries::new(
                front.iter().map(|r| point(r)),
                BLUE.stroke_width(2),
            ))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE.stroke_width(2)));
        chart.draw_series(front.iter().map(|r| {
            EmptyElement::at(point(r))
                + Circle::new((0, 0), 4, BLUE.filled())
                + Text::new(r.entry.name.clone(), (6, -14), (family, 12))
        }))?;
        let defaults = point(&report.rows[0]);
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(defaults)
                    + TriangleMarker::new((0, 0), 9, RED.filled())
                    + Text::new("defaults", (8, 4), (family, 14).into_font().color(&RED)),
            ))?
            .label("defaults")
            .legend(|(x, y)| TriangleMarker::new((x + 10, y), 6, RED.filled()));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((family, 14))
            .draw()?;
        Ok(())
    })
}
