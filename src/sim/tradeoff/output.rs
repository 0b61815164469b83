//! The report's files: `tradeoff.md` (tables), `tradeoff.csv` (every number), `pareto.png`
//! (error against frame time) and the reference pictures.

use std::fmt::Write as _;
use std::path::Path;

use image::RgbaImage;

use super::knobs::knobs;
use super::metrics::psnr;
use super::{Row, TradeoffReport, plot};
use crate::error::{Error, Result};

/// Writes every output of `report` into `out` (created if missing); `images` are the
/// reference pictures, per reference and view.
pub fn write(out: &Path, report: &TradeoffReport, images: &[Vec<RgbaImage>]) -> Result<()> {
    let dir = out.display().to_string();
    std::fs::create_dir_all(out).map_err(|e| Error::io(&dir, e))?;
    let save = |name: &str, text: String| {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| Error::io(path.display().to_string(), e))
    };
    save("tradeoff.csv", csv(report))?;
    save("tradeoff.md", markdown(report))?;
    plot::draw(&out.join("pareto.png"), report)?;
    for (name, per_view) in report.references.iter().zip(images) {
        for (k, (view, image)) in report.views.iter().zip(per_view).enumerate() {
            let file = format!("reference-{}-{k}-{}.png", slug(name), slug(&view.name));
            let path = out.join(file);
            image
                .save(&path)
                .map_err(|e| Error::invalid(path.display().to_string(), e.to_string()))?;
        }
    }
    Ok(())
}

fn slug(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect()
}

/// One line per setting; per-reference columns are prefixed with the reference's name.
pub fn csv(report: &TradeoffReport) -> String {
    let mut text = String::from(
        "setting,cpu_ms,ratio,wall_ms,triangles,geometric_max_px,geometric_mean_px,pareto",
    );
    for name in &report.references {
        write!(
            text,
            ",{name}_psnr_db,{name}_ssim,{name}_pixels_off,{name}_pixels_off_pct"
        )
        .expect("writing to a String");
    }
    text.push('\n');
    for row in &report.rows {
        let m = &row.measurement;
        write!(
            text,
            "{},{:.4},{:.4},{:.4},{:.0},{:.3},{:.3},{}",
            row.entry.name,
            m.frame_seconds * 1e3,
            row.ratio,
            m.wall_seconds * 1e3,
            m.triangles,
            m.geometric_max_px,
            m.geometric_mean_px,
            row.pareto
        )
        .expect("writing to a String");
        for e in &m.errors {
            write!(
                text,
                ",{:.3},{:.5},{},{:.3}",
                psnr(e.mse),
                e.ssim,
                e.pixels_off,
                100.0 * e.pixels_off as f64 / e.pixels.max(1) as f64
            )
            .expect("writing to a String");
        }
        text.push('\n');
    }
    text
}

fn table_row(row: &Row) -> String {
    let m = &row.measurement;
    let e = &m.errors[0];
    format!(
        "| {}{} | {:.2} | {:.2} | {:.2} | {:.0} | {:.1} | {:.4} | {:.2} | {:.1} / {:.1} |{}",
        row.entry.name,
        if row.entry.changes.is_empty() {
            " **(defaults)**"
        } else {
            ""
        },
        m.frame_seconds * 1e3,
        row.ratio,
        m.wall_seconds * 1e3,
        m.triangles,
        psnr(e.mse),
        e.ssim,
        100.0 * e.pixels_off as f64 / e.pixels.max(1) as f64,
        m.geometric_max_px,
        m.geometric_mean_px,
        if row.pareto { " yes |" } else { " |" }
    )
}

const HEADER: &str = "| setting | CPU ms | ratio | wall ms | triangles | PSNR dB | SSIM | pixels off % | \
geometric error px (max / mean) | Pareto |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n";

/// The Markdown report: how it was measured, every setting, the feature costs, the front.
pub fn markdown(report: &TradeoffReport) -> String {
    let mut md = String::new();
    intro(&mut md, report);
    let _ = writeln!(md, "## Every setting\n");
    md.push_str(HEADER);
    for row in &report.rows {
        let _ = writeln!(md, "{}", table_row(row));
    }
    features(&mut md, report);
    pareto(&mut md, report);
    md
}

/// The title and how the figures were taken.
fn intro(w: &mut String, report: &TradeoffReport) {
    let views: Vec<_> = report.views.iter().map(|v| v.name.as_str()).collect();
    let _ = writeln!(w, "# Speed against accuracy: {}\n", report.source);
    let _ = writeln!(
        w,
        "{} views ({}) at {}x{}; each frame time is the median of {} repeats of the mean over \
         the views, in process CPU time (what a one-core device pays; other processes do not \
         inflate it) and wall time (what threads buy), and ratios are of CPU times to \
         `defaults` from the same run (settings are timed round-robin). Errors are against the reference `{}` (every tile at full resolution, \
         f32 pipeline, exact perspective, bilinear mipmapped texels, 32-bit depth, RGBA8888); \
         PSNR over RGB pooled over the views, SSIM (Wang et al. 2004, luma) the mean of the \
         views', a pixel is off when a channel differs by more than {}. The geometric error is \
         each drawn tile's mask-level height error over the archive, in pixels at its distance; \
         max over all views, and the mean of each view's worst.\n",
        views.len(),
        views.join(", "),
        report.size.0,
        report.size.1,
        report.repeats,
        report.references[0],
        report.threshold
    );
}

/// Each rendering feature off alone (and all of them off) against the defaults.
fn features(w: &mut String, report: &TradeoffReport) {
    let defaults = &report.rows[0];
    let line = |name: &str, off: &Row| {
        format!(
            "| {} | {:.2} | {:.2} | {:.2} | {:.1} |",
            name,
            defaults.measurement.frame_seconds * 1e3,
            off.measurement.frame_seconds * 1e3,
            off.ratio,
            psnr(off.measurement.errors[0].mse)
        )
    };
    let mut lines: Vec<_> = knobs()
        .into_iter()
        .filter(|k| k.feature)
        .filter_map(|knob| {
            let off = report
                .rows
                .iter()
                .find(|r| r.entry.changes == [(knob.name, "off")])?;
            Some(line(knob.name, off))
        })
        .collect();
    if let Some(off) = report.rows.iter().find(|r| r.entry.name == "features-off") {
        lines.push(line("all of them", off));
    }
    if lines.is_empty() {
        return;
    }
    let _ = writeln!(
        w,
        "\n## Rendering features on and off\n\nEach feature off alone, everything else at \
         the defaults: what a scene that does not need it saves (CPU time).\n\n| feature | \
         on: ms | off: ms | off / on | PSNR dB off |\n| --- | ---: | ---: | ---: | ---: |"
    );
    for line in lines {
        let _ = writeln!(w, "{line}");
    }
}

/// The settings no other setting beats on both speed and accuracy, fastest first.
fn pareto(w: &mut String, report: &TradeoffReport) {
    let mut front: Vec<_> = report.rows.iter().filter(|r| r.pareto).collect();
    front.sort_by(|a, b| {
        a.measurement
            .frame_seconds
            .total_cmp(&b.measurement.frame_seconds)
    });
    let _ = writeln!(
        w,
        "\n## Pareto front\n\nFastest first; no other setting is both as fast and as close to \
         the reference (by SSIM). Plot: `pareto.png`.\n"
    );
    w.push_str(HEADER);
    for row in front {
        let _ = writeln!(w, "{}", table_row(row));
    }
}
