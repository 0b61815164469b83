//! What `fly` reports of holes and how it paces frames: on the wall clock no frame is shorter
//! than one at twice the target rate, however empty; the summary and `stats.csv` say which
//! frames had holes and why; with the PocketPC profile over a model larger than the belts
//! reach, no frame has a hole once the top of the pyramid arrived, in both streaming modes; a
//! flight
//! whose every fetch fails ends with an error naming the failed tiles, and a memory limit that
//! can hold nothing is refused.

use std::path::{Path, PathBuf};
use std::time::Duration;

use stripmask::FrameTiming;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::BuildOptions;
use stripmask::db::source;
use stripmask::db::source::throttle::LinkProfile;
use stripmask::engine::EngineSettings;
use stripmask::engine::paging::stream::{StreamSettings, Streaming};
use stripmask::engine::terrain::TerrainFrame;
use stripmask::sim::clock::{Clock, CostModel};
use stripmask::sim::device::DeviceProfile;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask::sim::fly::{FlyOptions, FlySummary, Length, fly};
use stripmask::sim::report::StatsTable;

use crate::support::cli::{fly_quietly, plain_archive};
use crate::support::hills::synthetic;

/// A ridged model of `n x n` samples 40 m apart in tiles of 65 samples, written into `dir`.
fn ridges(dir: &Path, n: usize) -> PathBuf {
    let options = BuildOptions {
        tile_size: 65,
        spacing: Some(40.0),
        texture_factor: 1,
        ..BuildOptions::default()
    };
    synthetic(dir, &format!("ridges{n}"), (n, n), &options, |i, j| {
        let (i, j) = (i as f32, j as f32);
        600.0 + 400.0 * (i * 0.013).sin() * (j * 0.011).cos() + 60.0 * (i * 0.09 + j * 0.07).sin()
    })
}

/// Flies the diagonal over `archive` as `p` for `length` on `clock`, over `p`'s link.
fn fly_as(
    p: &DeviceProfile,
    archive: &Path,
    out: &Path,
    length: Length,
    clock: Clock,
    streaming: Streaming,
) -> FlySummary {
    let reader = ArchiveReader::open(source::open(archive.to_str().unwrap()).unwrap()).unwrap();
    let terrain = TerrainFrame::new(reader.header());
    let mut engine = EngineSettings {
        memory_limit_bytes: p.memory_limit_bytes(),
        threads: p.threads,
        pager_mode: clock.pager_mode(4),
        streaming,
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    engine.budget.target_fps = p.target_fps;
    fly(&FlyOptions {
        source: archive.display().to_string(),
        flight: Flight::builtin(Builtin::Diagonal, &terrain),
        length: Some(length),
        size: (p.width, p.height),
        color: p.color,
        depth: p.depth,
        engine,
        out: out.to_path_buf(),
        every: 0,
        hud: false,
        progress: false,
        clock: clock.with_slowdown(p.cpu_slowdown),
        link: Some(LinkProfile { seed: 3, ..p.link }),
        plots: false,
        http: stripmask::db::source::http::HttpOptions::default(),
    })
    .unwrap()
}

#[test]
fn on_the_wall_clock_frames_waiting_for_tiles_are_paced_and_reported_as_holes() {
    let dir = tempfile::tempdir().unwrap();
    let path = ridges(dir.path(), 257);
    // A link so slow to answer that nothing arrives during the flight.
    let mut p = DeviceProfile::pocketpc();
    p.link.latency = Duration::from_secs(3);
    p.cpu_slowdown = 1.0;
    p.target_fps = 30.0;
    let frames = 30;
    let s = fly_as(
        &p,
        &path,
        &dir.path().join("out"),
        Length::Frames(frames),
        Clock::default(),
        Streaming::Belts,
    );
    assert_eq!(s.frames, frames);
    // No frame shorter than one at twice the target rate.
    let shortest = 0.5 / p.target_fps;
    assert!(
        s.seconds >= frames as f64 * shortest * 0.999,
        "{} s of flight in {frames} frames",
        s.seconds
    );
    let h = s.holes;
    assert_eq!(h.frames, frames);
    assert!(h.hole_frames > 0, "{h}");
    assert_eq!(
        (h.empty_frames, h.waiting_for_top, h.after_top),
        (h.hole_frames, h.hole_frames, 0)
    );
    assert_eq!((h.first_frame_s, h.top_arrived_s), (None, None));
    let text = h.to_string();
    assert!(
        text.contains("drew only sky") && text.contains("while the top was on its way"),
        "{text}"
    );
    let table = StatsTable::read(&dir.path().join("out").join("stats.csv")).unwrap();
    let holes = table.column("holes").unwrap();
    assert_eq!(holes.len() as u64, frames);
    assert_eq!(
        holes.iter().filter(|&&n| n > 0.0).count() as u64,
        h.hole_frames
    );
    assert!(table.column("top_bytes").unwrap().iter().all(|&b| b > 0.0));
}

/// The PocketPC (20 MB, 1 Mbit/s) over 3,969 tiles of 65 x 65 samples, 40 m apart (a model
/// 102 km across): whole-tile belts reach a few tiles, the view kilometres; once the top is
/// resident no frame has a hole, with either streaming mode.
#[test]
fn a_pocketpc_flight_over_a_large_model_has_no_hole_once_the_top_arrived() {
    let dir = tempfile::tempdir().unwrap();
    let path = ridges(dir.path(), 2049);
    let p = DeviceProfile::pocketpc();
    let clock = Clock::Simulated {
        model: CostModel::HOST,
        slowdown: 1.0,
    };
    for (name, streaming) in [
        ("belts", Streaming::Belts),
        (
            "progressive",
            Streaming::Progressive(StreamSettings::default()),
        ),
    ] {
        let out = dir.path().join(name);
        let s = fly_as(&p, &path, &out, Length::Seconds(30.0), clock, streaming);
        let h = s.holes;
        let arrived = h.top_arrived_s.unwrap_or_else(|| panic!("{name}: {h}"));
        assert_eq!(h.after_top, 0, "{name}: {h}");
        assert_eq!(h.hole_frames, h.waiting_for_top, "{name}: {h}");
        assert!(h.top_bytes > 0 && h.top_bytes <= s.memory_limit_bytes);
        assert!(
            h.first_full_frame_s.is_some_and(|t| t >= arrived),
            "{name}: {h}"
        );
        let table = StatsTable::read(&out.join("stats.csv")).unwrap();
        let time = table.column("time_s").unwrap();
        let holes = table.column("holes").unwrap();
        let late = time
            .iter()
            .zip(&holes)
            .filter(|(t, n)| **t >= arrived && **n > 0.0);
        assert_eq!(late.count(), 0, "{name}");
        assert!(s.peak_memory_bytes <= s.memory_limit_bytes);
    }
}

#[test]
fn a_flight_whose_every_fetch_fails_says_which_tiles_failed_and_exits_non_zero() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("broken.smdb");
    plain_archive(&archive);
    let payload_start = {
        let reader = ArchiveReader::open(source::open(archive.to_str().unwrap()).unwrap()).unwrap();
        reader.header().payload_start() as usize
    };
    // Header and directory intact, every byte after them (tiles, index pages, the top) flipped:
    // every fetch fails its checksum.
    let mut bytes = std::fs::read(&archive).unwrap();
    bytes[payload_start..].iter_mut().for_each(|b| *b ^= 0x5a);
    std::fs::write(&archive, bytes).unwrap();
    let out = dir.path().join("run");
    let fly_frames = |archive: &Path, frames: &str| {
        let (code, err, _) = fly_quietly(
            archive.to_str().unwrap(),
            &out,
            &["--clock", "simulated", "--frames", frames],
        );
        (code, err)
    };
    let (code, err) = fly_frames(&archive, "40");
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("no terrain could be drawn in 40 frame(s)")
            && err.contains("fetch(es) failed")
            && err.contains("checksum")
            && err.contains(archive.to_str().unwrap()),
        "{err}"
    );
    // The healthy archive flies and exits 0.
    let healthy = dir.path().join("healthy.smdb");
    plain_archive(&healthy);
    let (code, err) = fly_frames(&healthy, "10");
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn a_memory_limit_that_holds_neither_the_top_nor_one_tile_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("plain.smdb");
    plain_archive(&archive);
    let out = dir.path().join("run");
    for streaming in ["belts", "progressive"] {
        let (code, err, _) = fly_quietly(
            archive.to_str().unwrap(),
            &out,
            &[
                "--memory-mb",
                "0.0001",
                "--streaming",
                streaming,
                "--frames",
                "20",
            ],
        );
        assert_eq!(code, Some(2), "{streaming}: {err}");
        assert!(
            err.contains("memory limit") && err.contains("one tile"),
            "{streaming}: {err}"
        );
    }
}
