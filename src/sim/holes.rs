//! Frames where terrain in view was not drawn, and why: what `fly`, the demo and
//! `stream-compare` report of a flight's holes, its first frames and the top of the pyramid.

use std::fmt;

use crate::engine::FrameReport;

/// A flight's holes so far: frames where the view met the terrain and some of it (or all of it)
/// had nothing to draw, sorted by what the top of the pyramid was doing at the time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HoleTally {
    /// Frames counted.
    pub frames: u64,
    /// Frames with at least one hole.
    pub hole_frames: u64,
    /// Frames that met terrain and drew none of it: only sky.
    pub empty_frames: u64,
    /// Hole frames while the top was on its way.
    pub waiting_for_top: u64,
    /// Hole frames with no top: it does not fit the memory limit, or every attempt to fetch it
    /// failed.
    pub without_top: u64,
    /// Hole frames with the top resident (none is expected: the top covers the terrain).
    pub after_top: u64,
    /// Flight time of the first frame that drew terrain, seconds.
    pub first_frame_s: Option<f64>,
    /// Flight time of the first frame that drew terrain and had no hole, seconds.
    pub first_full_frame_s: Option<f64>,
    /// Flight time of the first frame with the top resident, seconds.
    pub top_arrived_s: Option<f64>,
    /// Bytes the top holds once resident.
    pub top_bytes: usize,
}

impl HoleTally {
    /// Counts the frame of `report`, drawn at flight time `t`.
    pub fn add(&mut self, t: f64, report: &FrameReport) {
        let pager = &report.pager;
        let top_resident = pager.top_tiles > 0;
        if top_resident && self.top_arrived_s.is_none() {
            self.top_arrived_s = Some(t);
            self.top_bytes = pager.top_bytes;
        }
        let drew = report.rendered_tiles > 0;
        if drew {
            self.first_frame_s = self.first_frame_s.or(Some(t));
        }
        if report.holes == 0 {
            if drew {
                self.first_full_frame_s = self.first_full_frame_s.or(Some(t));
            }
        } else {
            self.hole_frames += 1;
            if !drew {
                self.empty_frames += 1;
            }
            if top_resident {
                self.after_top += 1;
            } else if pager.top_bytes > 0 {
                self.waiting_for_top += 1;
            } else {
                self.without_top += 1;
            }
        }
        self.frames += 1;
    }
}

/// One line: how many frames had holes and why, when the top arrived, the first frames.
impl fmt::Display for HoleTally {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let secs = |t: Option<f64>| t.map_or("never".into(), |t| format!("{t:.2} s"));
        write!(
            f,
            "{} of {} frames had holes ({} drew only sky)",
            self.hole_frames, self.frames, self.empty_frames
        )?;
        let causes = [
            (self.waiting_for_top, "while the top was on its way"),
            (
                self.without_top,
                "with no top (over the memory limit, or its fetch failed)",
            ),
            (self.after_top, "with the top resident"),
        ];
        let mut first = true;
        for (n, cause) in causes.iter().filter(|(n, _)| *n > 0) {
            write!(f, "{} {n} {cause}", if first { ":" } else { ";" })?;
            first = false;
        }
        match self.top_arrived_s {
            Some(t) => write!(
                f,
                "; top of {:.2} MB resident at {t:.2} s",
                self.top_bytes as f64 / 1e6
            )?,
            None => write!(f, "; no top resident")?,
        }
        write!(
            f,
            "; first frame at {}, first without a hole at {}",
            secs(self.first_frame_s),
            secs(self.first_full_frame_s)
        )
    }
}
