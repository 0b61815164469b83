//! `stripmask stream-compare`: the paper's whole-tile belts against progressive tiles (with and
//! without viewpoint prediction), on the same flights over the same links, as the PocketPC
//! profile on the simulated clock — so every figure is reproducible byte for byte.
//!
//! For each run: bytes downloaded; time to the first frame that draws anything; time to the
//! first *complete* view — every tile of the view frustum within the belts the whole-tile
//! square reaches is held with the levels every budget of [`REFERENCE_BAND`] (shares of the
//! device's steady budget) and τ give it at least ([`Engine::holds_view`]), the same reference
//! for every strategy; the share of frames that spend their whole triangle budget (at least 95%
//! of it); rendered quality as the mean over frames of the largest screen-space geometric error
//! of a drawn tile; the share of received bytes drawn within a second of arriving; and the
//! prediction's hit rate.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use stripmask_raster::Framebuffer;

use crate::db::archive::ArchiveReader;
use crate::db::source;
use crate::db::source::throttle::LinkProfile;
use crate::engine::budget::BudgetController;
use crate::engine::paging::PagerMode;
use crate::engine::paging::stream::{PredictionSettings, StreamSettings, Streaming};
use crate::engine::terrain::TerrainFrame;
use crate::engine::viewport::Viewport;
use crate::engine::{Engine, EngineSettings, FrameTiming};
use crate::error::{Error, Result};
use crate::sim::clock::{Clock, CostModel, connect};
use crate::sim::device::DeviceProfile;
use crate::sim::flight::{Builtin, Flight};
use crate::sim::holes::HoleTally;

/// A frame spends its whole budget when it draws at least this share of it.
pub const FULL_BUDGET: f64 = 0.95;

/// A view is complete when every tile holds the levels every budget of this band draws it
/// with at least; the band's ends are shares of the device's steady budget (by its cost model):
/// from below the up to 6% by which the controller settles around that figure to the figure
/// itself, so no strategy is judged by detail its own frames would not ask for. A band rather
/// than one share because the allocation is not monotone in the budget (a few more triangles
/// can pay a costly move that leaves another tile coarser): one share can ask a tile for a
/// level no frame near it draws (docs/streaming.md).
pub const REFERENCE_BAND: (f64, f64) = (0.9, 1.0);

/// Budgets sampled evenly over [`REFERENCE_BAND`], its ends included: 1% apart.
const REFERENCE_SAMPLES: usize = 11;

/// The reference budgets for a device whose cost model holds its target at `steady` triangles.
fn reference_budgets(steady: usize) -> Vec<usize> {
    let (lo, hi) = REFERENCE_BAND;
    (0..REFERENCE_SAMPLES)
        .map(|k| {
            let share = lo + (hi - lo) * k as f64 / (REFERENCE_SAMPLES - 1) as f64;
            (share * steady as f64).round() as usize
        })
        .collect()
}

/// A link to compare over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkCase {
    /// Name in the table.
    pub name: &'static str,
    /// The link.
    pub link: LinkProfile,
}

/// The three links of the comparison: the paper's 1 Mbit/s line, a USB 1.1 cradle (12 Mbit/s
/// signalling, about 8 Mbit/s of payload, a millisecond per request), and the archive on the
/// device itself.
pub const LINKS: [LinkCase; 3] = [
    LinkCase {
        name: "1 Mbit/s",
        link: LinkProfile {
            bandwidth_kbps: Some(1000.0),
            latency: Duration::from_millis(50),
            ..LinkProfile::UNLIMITED
        },
    },
    LinkCase {
        name: "USB",
        link: LinkProfile {
            bandwidth_kbps: Some(8000.0),
            latency: Duration::from_millis(1),
            ..LinkProfile::UNLIMITED
        },
    },
    LinkCase {
        name: "local",
        link: LinkProfile::UNLIMITED,
    },
];

/// How tiles come in, one row of the table each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamingCase {
    /// The paper's whole-tile belts.
    Belts,
    /// Progressive levels as the view needs them, no prediction (the default).
    Progressive,
    /// Progressive levels with viewpoint prediction.
    Predicted,
}

impl StreamingCase {
    /// Every strategy, in table order.
    pub const ALL: [StreamingCase; 3] = [
        StreamingCase::Belts,
        StreamingCase::Progressive,
        StreamingCase::Predicted,
    ];

    /// Name in the table.
    pub fn name(self) -> &'static str {
        match self {
            StreamingCase::Belts => "whole-tile belts",
            StreamingCase::Progressive => "progressive",
            StreamingCase::Predicted => "progressive + prediction",
        }
    }

    fn streaming(self) -> Streaming {
        match self {
            StreamingCase::Belts => Streaming::Belts,
            StreamingCase::Progressive => Streaming::Progressive(StreamSettings::default()),
            StreamingCase::Predicted => Streaming::Progressive(StreamSettings {
                prediction: Some(PredictionSettings::default()),
                ..StreamSettings::default()
            }),
        }
    }
}

/// What to compare.
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// The archive (path or URL).
    pub source: String,
    /// The flights.
    pub flights: Vec<Builtin>,
    /// The links.
    pub links: Vec<LinkCase>,
    /// Seconds of each flight (default: all of it).
    pub seconds: Option<f64>,
    /// The device (its link is replaced by each of `links`).
    pub profile: DeviceProfile,
    /// Where the table goes.
    pub out: PathBuf,
    /// Show progress.
    pub progress: bool,
}

/// One run's figures.
#[derive(Clone, Debug, PartialEq)]
pub struct RunResult {
    /// The flight.
    pub flight: Builtin,
    /// The link's name.
    pub link: &'static str,
    /// How tiles came in.
    pub strategy: StreamingCase,
    /// Frames drawn.
    pub frames: u64,
    /// Bytes downloaded.
    pub downloaded_bytes: u64,
    /// Frames with holes and why, the first frame, the first without a hole, the top.
    pub holes: HoleTally,
    /// Flight time of the first complete view.
    pub first_complete_s: Option<f64>,
    /// Frames that drew at least [`FULL_BUDGET`] of their budget.
    pub full_budget_share: f64,
    /// Mean over frames of the largest screen-space error of a drawn tile, pixels.
    pub mean_error_px: f64,
    /// Received bytes drawn within a second (progressive only).
    pub rendered_share: Option<f64>,
    /// The same for the bytes the current view asked for.
    pub view_rendered_share: Option<f64>,
    /// Bytes of the coarse belt fill, which no view asked for (progressive only).
    pub belt_bytes: Option<u64>,
    /// Predicted levels drawn in time (with prediction only).
    pub hit_rate: Option<f64>,
    /// Requests sent (progressive) or tiles fetched (belts).
    pub requests: u64,
    /// Requests cancelled before they were sent.
    pub cancelled: u64,
    /// Peak accounted memory, bytes.
    pub peak_memory_bytes: usize,
}

/// Runs every flight over every link with every strategy.
pub fn compare(o: &CompareOptions) -> Result<Vec<RunResult>> {
    let terrain = {
        let reader = ArchiveReader::open(source::open(&o.source)?)?;
        TerrainFrame::new(reader.header())
    };
    let runs = o.flights.len() * o.links.len() * StreamingCase::ALL.len();
    let bar = if o.progress {
        let bar = ProgressBar::new(runs as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} runs {msg}")
                .expect("a valid template"),
        );
        bar
    } else {
        ProgressBar::hidden()
    };
    let mut results = Vec::with_capacity(runs);
    for &flight in &o.flights {
        let run = |link: LinkCase, strategy| Run {
            options: o,
            terrain: &terrain,
            flight,
            link,
            strategy,
        };
        // The area a view must cover to be complete: the square whole tiles reach when the
        // archive is local (or over the fastest link given), found by a first flight.
        let reference = o
            .links
            .iter()
            .find(|l| l.link.is_unlimited())
            .or(o.links.last())
            .copied();
        let radius = match reference {
            Some(link) => run(link, StreamingCase::Belts).fly(None)?.1,
            None => None,
        };
        for link in &o.links {
            for strategy in StreamingCase::ALL {
                bar.set_message(format!("{flight:?}, {}, {}", link.name, strategy.name()));
                results.push(run(*link, strategy).fly(radius)?.0);
                bar.inc(1);
            }
        }
    }
    bar.finish_and_clear();
    Ok(results)
}

/// One flight over one link with one strategy.
struct Run<'a> {
    options: &'a CompareOptions,
    terrain: &'a TerrainFrame,
    flight: Builtin,
    link: LinkCase,
    strategy: StreamingCase,
}

impl Run<'_> {
    /// Flies; a view is complete when it covers `radius` belts (`None`: never). Returns the
    /// figures and the largest square of belts completed.
    fn fly(&self, radius: Option<u32>) -> Result<(RunResult, Option<u32>)> {
        let p = &self.options.profile;
        let clock = Clock::Simulated {
            model: CostModel::HOST,
            slowdown: p.cpu_slowdown,
        };
        let mut settings = EngineSettings {
            memory_limit_bytes: p.memory_limit_bytes(),
            threads: p.threads,
            pager_mode: PagerMode::Simulated { queue_depth: 4 },
            streaming: self.strategy.streaming(),
            allocation: p.allocation,
            frame_timing: FrameTiming::Told,
            lift_to_clearance: true,
            ..EngineSettings::default()
        };
        settings.budget = p.budget(clock);
        // A view is complete against shares of the budget the cost model says holds the
        // target (where the controller starts), not against the budgets the run's frames had.
        let steady = BudgetController::new(settings.budget).budget();
        let reference_budgets = reference_budgets(steady);
        let link = (!self.link.link.is_unlimited()).then_some(self.link.link);
        let (source, meter) = connect(source::open(&self.options.source)?, link, &clock);
        let mut engine = Engine::new(source, settings, Viewport::new(p.width, p.height))?;
        if let Some(meter) = meter {
            engine.set_transfer_clock(meter);
        }
        let mut fb = Framebuffer::new(p.width, p.height, p.color, p.depth)?;
        let flight = Flight::builtin(self.flight, self.terrain);
        let length = self
            .options
            .seconds
            .unwrap_or(flight.duration())
            .min(flight.duration());
        let (mut t, mut frames, mut full, mut error_sum) = (0.0, 0u64, 0u64, 0.0);
        let (mut holes, mut first_complete_s, mut reached) = (HoleTally::default(), None, None);
        while t < length {
            let (eye, target) = flight.at(t);
            let camera = engine.camera(eye, target, flight.above_ground);
            engine.set_time(t);
            let report = engine.render(&camera, &mut fb)?;
            let seconds = clock.frame_seconds(&report);
            engine.record_frame(seconds, report.draw.triangles as usize);
            holes.add(t, &report);
            reached = reached.max(report.pager.complete_belts);
            if first_complete_s.is_none()
                && report.rendered_tiles > 0
                && radius
                    .is_some_and(|r| engine.holds_view(&report.view.camera, r, &reference_budgets))
            {
                first_complete_s = Some(t);
            }
            if report.triangles as f64 >= FULL_BUDGET * report.budget as f64 {
                full += 1;
            }
            error_sum += report
                .rendered
                .iter()
                .map(|r| r.error_px)
                .fold(0.0, f64::max);
            frames += 1;
            t += seconds;
        }
        let pager = engine.pager().stats();
        let stream = engine.stream_stats();
        let result = RunResult {
            flight: self.flight,
            link: self.link.name,
            strategy: self.strategy,
            frames,
            downloaded_bytes: pager.downloaded_bytes,
            holes,
            first_complete_s,
            full_budget_share: full as f64 / frames.max(1) as f64,
            mean_error_px: error_sum / frames.max(1) as f64,
            rendered_share: stream.and_then(|s| s.rendered_share()),
            view_rendered_share: stream.and_then(|s| s.view_rendered_share()),
            belt_bytes: stream.map(|s| s.belt_bytes),
            hit_rate: stream.and_then(|s| s.hit_rate()),
            requests: stream.map_or(pager.fetches, |s| s.requests),
            cancelled: stream.map_or(0, |s| s.cancelled),
            peak_memory_bytes: pager.memory_peak_bytes,
        };
        Ok((result, reached))
    }
}

/// Writes `stream-compare.md` and `stream-compare.csv` into `out`; returns the Markdown.
pub fn write(out: &Path, results: &[RunResult], options: &CompareOptions) -> Result<String> {
    let name = out.display().to_string();
    std::fs::create_dir_all(out).map_err(|e| Error::io(&name, e))?;
    let markdown = markdown(results, options);
    let md = out.join("stream-compare.md");
    std::fs::write(&md, &markdown).map_err(|e| Error::io(md.display().to_string(), e))?;
    let csv_path = out.join("stream-compare.csv");
    let mut csv = String::from(
        "flight,link,strategy,frames,downloaded_bytes,first_frame_s,first_full_frame_s,\
         hole_frames,empty_frames,top_bytes,first_complete_s,full_budget_share,mean_error_px,rendered_share,view_rendered_share,belt_bytes,\
         hit_rate,requests,cancelled,peak_memory_bytes\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    for r in results {
        writeln!(
            csv,
            "{:?},{},{},{},{},{},{},{},{},{},{},{:.4},{:.4},{},{},{},{},{},{},{}",
            r.flight,
            r.link,
            r.strategy.name(),
            r.frames,
            r.downloaded_bytes,
            opt(r.holes.first_frame_s),
            opt(r.holes.first_full_frame_s),
            r.holes.hole_frames,
            r.holes.empty_frames,
            r.holes.top_bytes,
            opt(r.first_complete_s),
            r.full_budget_share,
            r.mean_error_px,
            opt(r.rendered_share),
            opt(r.view_rendered_share),
            r.belt_bytes.map_or(String::new(), |b| b.to_string()),
            opt(r.hit_rate),
            r.requests,
            r.cancelled,
            r.peak_memory_bytes
        )
        .expect("writing to a String");
    }
    std::fs::write(&csv_path, csv).map_err(|e| Error::io(csv_path.display().to_string(), e))?;
    Ok(markdown)
}

/// One table per flight: a row per link and strategy.
fn markdown(results: &[RunResult], o: &CompareOptions) -> String {
    let p = &o.profile;
    let mut md = format!(
        "Device {}: {}x{}, {} MB for tiles, {} fps target, simulated clock; archive {}.\n",
        p.name, p.width, p.height, p.memory_mb, p.target_fps, o.source
    );
    let secs = |v: Option<f64>| v.map_or("never".into(), |v| format!("{v:.2} s"));
    let pct = |v: Option<f64>| v.map_or("–".into(), |v| format!("{:.1}%", 100.0 * v));
    for flight in &o.flights {
        let _ = write!(
            md,
            "\n**{flight:?}**\n\n| link | tiles | downloaded | first frame | first without a hole | \
             frames with holes (only sky) | top | first complete view | frames at full budget | mean screen error | drawn within 1 s: all bytes (asked by the view) | \
             belt fill | prediction hits | requests (cancelled) | peak memory |\n\
             | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n"
        );
        for r in results.iter().filter(|r| r.flight == *flight) {
            let _ = writeln!(
                md,
                "| {} | {} | {:.2} MB | {} | {} | {} ({}) | {:.2} MB | {} | {:.1}% | {:.2} px | {} ({}) | {} | {} | {} ({}) | {:.1} MB |",
                r.link,
                r.strategy.name(),
                r.downloaded_bytes as f64 / 1e6,
                secs(r.holes.first_frame_s),
                secs(r.holes.first_full_frame_s),
                r.holes.hole_frames,
                r.holes.empty_frames,
                r.holes.top_bytes as f64 / 1e6,
                secs(r.first_complete_s),
                100.0 * r.full_budget_share,
                r.mean_error_px,
                pct(r.rendered_share),
                pct(r.view_rendered_share),
                r.belt_bytes
                    .map_or("–".into(), |b| format!("{:.2} MB", b as f64 / 1e6)),
                pct(r.hit_rate),
                r.requests,
                r.cancelled,
                r.peak_memory_bytes as f64 / 1e6
            );
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reference_budgets_span_the_band_one_percent_apart() {
        let budgets = reference_budgets(2963);
        assert_eq!(budgets.len(), REFERENCE_SAMPLES);
        assert_eq!((budgets[0], budgets[REFERENCE_SAMPLES - 1]), (2667, 2963));
        assert!(budgets.windows(2).all(|w| w[1] > w[0]));
        assert_eq!(budgets[5], 2815, "95% of the steady budget");
    }
}
