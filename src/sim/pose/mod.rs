//! A pose feed for the viewer: a GPS and attitude source, a simulator or a recording drives
//! the camera instead of a flight path or the keyboard.
//!
//! One pose a line, numbers separated by spaces or commas, `#` starting a comment:
//!
//! ```text
//! TIME EAST NORTH ALTITUDE HEADING PITCH ROLL
//! geo TIME LATITUDE LONGITUDE ALTITUDE HEADING PITCH ROLL
//! ```
//!
//! `TIME` in seconds (any origin), `EAST` and `NORTH` in the archive's own coordinates (those
//! `info` gives as the origin: projected metres for a UTM model), `ALTITUDE` in metres above
//! the archive's height 0, `HEADING` in degrees clockwise from north, `PITCH` in degrees up
//! from level, `ROLL` in degrees with the right wing down. A `geo` line gives latitude and
//! longitude in degrees and a heading from true north, on a georeferenced archive; NMEA 0183
//! `GGA` and `RMC` sentences do too ([`line`](mod@line)). A live feed (standard input,
//! UDP datagrams) is drawn at its latest pose; a recording (a file) is replayed by its times
//! from the viewer's start. A receiver's void fix leaves the camera where it is and shows the
//! feed stale.

pub mod line;
pub mod nmea;

use std::io::BufRead;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::DVec3;

use crate::engine::Engine;
use crate::engine::camera::{Camera, attitude_forward};
use crate::error::{Error, Result};
use line::{PoseDecoder, Reading, Refused};

/// One pose of the feed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Seconds, on the feed's own clock.
    pub time: f64,
    /// The archive's east and north coordinates, metres.
    pub east: f64,
    /// See `east`.
    pub north: f64,
    /// Metres above the archive's height 0.
    pub altitude: f64,
    /// Radians clockwise from the archive's north.
    pub heading: f64,
    /// Radians up from level.
    pub pitch: f64,
    /// Radians, right wing down.
    pub roll: f64,
}

impl Pose {
    /// The pose of `[time, east, north, altitude, heading, pitch, roll]`, angles in degrees.
    pub fn from_numbers(numbers: [f64; 7]) -> std::result::Result<Pose, String> {
        let [time, east, north, altitude, heading, pitch, roll] = numbers;
        if pitch.abs() > 90.0 {
            return Err(format!("pitch {pitch}° is beyond straight up or down"));
        }
        Ok(Pose {
            time,
            east,
            north,
            altitude,
            heading: heading.to_radians(),
            pitch: pitch.to_radians(),
            roll: roll.to_radians(),
        })
    }

    /// The unit viewing direction in the engine's world (x east, y up, z south).
    pub fn forward(&self) -> DVec3 {
        attitude_forward(self.heading, self.pitch)
    }

    /// The camera of this pose over `engine`'s terrain (the engine keeps it above the ground).
    pub fn camera(&self, engine: &Engine) -> Camera {
        let eye = engine
            .terrain()
            .from_archive(self.east, self.north, self.altitude);
        let mut camera = engine.camera(eye, eye + self.forward(), false);
        camera.roll = self.roll;
        camera
    }
}

/// Where poses come from.
#[derive(Clone, Debug, PartialEq)]
pub enum PoseSource {
    /// Lines on standard input, live.
    Stdin,
    /// One pose per UDP datagram sent to this address (`host:port`), live.
    Udp(String),
    /// A recording, replayed by its times.
    File(PathBuf),
}

impl FromStr for PoseSource {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "stdin" | "-" => Ok(PoseSource::Stdin),
            _ => match s.strip_prefix("udp:") {
                Some(address) if !address.is_empty() => Ok(PoseSource::Udp(address.into())),
                Some(_) => Err("udp: needs an address, e.g. udp:127.0.0.1:5005".into()),
                None => Ok(PoseSource::File(PathBuf::from(
                    s.strip_prefix("file:").unwrap_or(s),
                ))),
            },
        }
    }
}

/// The largest recording read (about a day of poses at 10 a second).
const MAX_RECORDING_BYTES: u64 = 64 << 20;

/// What a live feed has received.
#[derive(Debug, Default)]
struct Received {
    latest: Option<(Instant, Pose)>,
    /// Whether the last position the receiver sent was a void fix.
    no_fix: bool,
    /// Lines or datagrams that were not a pose.
    refused: u64,
    /// Why the feed cannot go on: the first line the archive could not place.
    fatal: Option<Error>,
}

/// A recording: its poses and the times of its void fixes, both in time order.
#[derive(Debug)]
struct Recording {
    poses: Vec<Pose>,
    no_fix: Vec<f64>,
    /// The time of its first line, pose or void fix: the viewer's start.
    start: f64,
}

/// A feed of poses.
pub struct PoseFeed {
    live: Arc<Mutex<Received>>,
    recording: Option<Recording>,
}

/// Poses older than this show as stale on the HUD.
pub const STALE_SECONDS: f64 = 1.0;

impl PoseFeed {
    /// Opens `source`, its lines read by `decoder` (which knows the archive): reads a
    /// recording whole (a line that is not a pose is an error naming the file and the line),
    /// or starts a thread that keeps the latest live pose.
    pub fn open(source: &PoseSource, mut decoder: PoseDecoder) -> Result<PoseFeed> {
        let live = Arc::new(Mutex::new(Received::default()));
        let recording = match source {
            PoseSource::File(path) => Some(read_recording(path, &mut decoder)?),
            PoseSource::Stdin => {
                let received = Arc::clone(&live);
                std::thread::spawn(move || {
                    for line in std::io::stdin().lock().lines() {
                        let Ok(line) = line else { break };
                        receive(&received, &mut decoder, "standard input", &line);
                    }
                });
                None
            }
            PoseSource::Udp(address) => {
                let name = format!("udp:{address}");
                let socket = UdpSocket::bind(address).map_err(|e| Error::io(&name, e))?;
                let received = Arc::clone(&live);
                std::thread::spawn(move || {
                    let mut buf = [0u8; 1024];
                    while let Ok(n) = socket.recv(&mut buf) {
                        let datagram = String::from_utf8_lossy(&buf[..n]);
                        receive(&received, &mut decoder, &name, &datagram);
                    }
                });
                None
            }
        };
        Ok(PoseFeed { live, recording })
    }

    /// The error that stops a live feed: a line the archive cannot place (latitude and
    /// longitude on an archive without georeferencing), named by the feed and the archive.
    /// The viewer checks it every frame.
    pub fn check(&self) -> Result<()> {
        match self.live.lock().expect("pose feed lock").fatal.take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// The pose to draw `t` seconds after the viewer started, and its age in seconds; `None`
    /// before the first.
    pub fn at(&self, t: f64) -> Option<(Pose, f64)> {
        match &self.recording {
            Some(r) => {
                let k = r.poses.partition_point(|p| p.time - r.start <= t);
                let pose = r.poses[k.checked_sub(1)?];
                Some((pose, t - (pose.time - r.start)))
            }
            None => {
                let received = self.live.lock().expect("pose feed lock");
                let (when, pose) = received.latest?;
                Some((pose, when.elapsed().as_secs_f64()))
            }
        }
    }

    /// Live lines or datagrams that were not a pose.
    pub fn refused(&self) -> u64 {
        self.live.lock().expect("pose feed lock").refused
    }

    /// Whether the receiver's last word at viewer time `t` is a void fix.
    pub fn no_fix(&self, t: f64) -> bool {
        match &self.recording {
            Some(r) => {
                let k = r.no_fix.partition_point(|v| v - r.start <= t);
                let void = k.checked_sub(1).map(|k| r.no_fix[k]);
                let pose = self.at(t).map(|(p, _)| p.time);
                void.is_some_and(|v| pose.is_none_or(|p| v > p))
            }
            None => self.live.lock().expect("pose feed lock").no_fix,
        }
    }

    /// The HUD's line for the feed at viewer time `t`.
    pub fn status(&self, t: f64) -> String {
        let refused = match self.refused() {
            0 => String::new(),
            n => format!(" {n} BAD"),
        };
        let no_fix = self.no_fix(t);
        let refused = if no_fix {
            format!(" NO FIX{refused}")
        } else {
            refused
        };
        match self.at(t) {
            None => format!("POSE WAITING{refused}"),
            Some((_, age)) if no_fix || age > STALE_SECONDS => {
                format!("POSE STALE {age:.1} S{refused}")
            }
            Some((_, age)) => format!("POSE {:.0} MS OLD{refused}", age * 1e3),
        }
    }
}

/// Keeps the pose of the live `lines` from the feed `name`, or counts them refused.
fn receive(received: &Mutex<Received>, decoder: &mut PoseDecoder, name: &str, lines: &str) {
    let mut r = received.lock().expect("pose feed lock");
    for line in lines.lines() {
        match decoder.line(line) {
            Ok(Reading::Pose(pose)) => {
                r.latest = Some((Instant::now(), pose));
                r.no_fix = false;
            }
            Ok(Reading::NoFix(_)) => r.no_fix = true,
            Ok(Reading::Nothing) => {}
            Err(Refused::Line(_)) => r.refused += 1,
            Err(Refused::Archive(e)) => {
                if r.fatal.is_none() {
                    r.fatal = Some(Error::invalid(name, format!("{line:?}: {e}")));
                }
            }
        }
    }
}

/// The poses and void fixes of the recording `path`, in time order.
fn read_recording(path: &Path, decoder: &mut PoseDecoder) -> Result<Recording> {
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|e| Error::io(&name, e))?;
    let len = file.metadata().map_err(|e| Error::io(&name, e))?.len();
    if len > MAX_RECORDING_BYTES {
        return Err(Error::invalid(
            &name,
            format!("a recording of {len} bytes, more than the {MAX_RECORDING_BYTES} read"),
        ));
    }
    let mut poses: Vec<Pose> = Vec::new();
    let mut no_fix: Vec<f64> = Vec::new();
    let mut last: Option<f64> = None;
    for (k, line) in std::io::BufReader::new(file).lines().enumerate() {
        let at_line = |e: String| Error::invalid(&name, format!("line {}: {e}", k + 1));
        let line = line.map_err(|e| Error::io(&name, e))?;
        let time = match decoder.line(&line) {
            Ok(Reading::Pose(pose)) => {
                poses.push(pose);
                pose.time
            }
            Ok(Reading::NoFix(time)) => {
                no_fix.push(time);
                time
            }
            Ok(Reading::Nothing) => continue,
            Err(Refused::Line(e)) => return Err(at_line(e)),
            Err(Refused::Archive(e)) => return Err(at_line(e.to_string())),
        };
        if last.is_some_and(|last| time < last) {
            return Err(at_line(format!("time {time} goes back")));
        }
        last = Some(time);
    }
    let start = match (poses.first(), no_fix.first()) {
        (Some(p), Some(v)) => p.time.min(*v),
        (Some(p), None) => p.time,
        (None, _) => return Err(Error::invalid(&name, "the recording holds no pose")),
    };
    Ok(Recording {
        poses,
        no_fix,
        start,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::pose::line::decoder_for;

    #[test]
    fn sources_are_named_as_the_command_line_gives_them() {
        assert_eq!("stdin".parse(), Ok(PoseSource::Stdin));
        assert_eq!(
            "udp:127.0.0.1:5005".parse(),
            Ok(PoseSource::Udp("127.0.0.1:5005".into()))
        );
        assert!("udp:".parse::<PoseSource>().is_err());
        assert_eq!(
            "file:poses.txt".parse(),
            Ok(PoseSource::File("poses.txt".into()))
        );
    }

    #[test]
    fn a_recording_replays_by_its_times_and_goes_stale_after_its_last() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("poses.txt");
        std::fs::write(
            &path,
            "100 0 0 10 0 0 0\n100.5 5 0 10 0 0 0\n102 9 0 10 0 0 0\n",
        )
        .unwrap();
        let feed = PoseFeed::open(&PoseSource::File(path.clone()), decoder_for(None)).unwrap();
        assert_eq!(feed.at(0.4).unwrap().0.east, 0.0);
        assert_eq!(feed.at(0.5).unwrap().0.east, 5.0);
        let (last, age) = feed.at(5.0).unwrap();
        assert_eq!((last.east, age), (9.0, 3.0));
        assert!(feed.status(5.0).starts_with("POSE STALE 3.0"));
        std::fs::write(&path, "1 0 0 10 0 0 0\n0 0 0 10 0 0 0\n").unwrap();
        let e = PoseFeed::open(&PoseSource::File(path.clone()), decoder_for(None))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("poses.txt") && e.contains("line 2"), "{e}");
    }

    #[test]
    fn a_live_feed_keeps_the_latest_pose_and_counts_what_is_not_one() {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        let address = socket.local_addr().unwrap().to_string();
        drop(socket);
        let feed = PoseFeed::open(&PoseSource::Udp(address.clone()), decoder_for(None)).unwrap();
        assert!(feed.status(0.0).starts_with("POSE WAITING"));
        let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
        sender.send_to(b"garbage", &address).unwrap();
        sender.send_to(b"1 2 3 4 5 6 7", &address).unwrap();
        let started = Instant::now();
        while feed.at(0.0).is_none() && started.elapsed().as_secs() < 10 {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        assert_eq!(feed.at(0.0).unwrap().0.east, 2.0);
        assert_eq!(feed.refused(), 1);
    }

    #[test]
    fn a_void_fix_leaves_the_camera_where_it_was_and_shows_the_feed_stale() {
        use crate::sim::pose::nmea::with_checksum;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("gps.nmea");
        let lines = [
            with_checksum("GPGGA,120000,4700.000,N,12300.000,W,1,08,0.9,300.0,M,,,,"),
            with_checksum("GPGGA,120000.5,,,,,0,00,,,,,,,"),
            with_checksum("GPGGA,120001,4700.010,N,12300.000,W,1,08,0.9,300.0,M,,,,"),
        ];
        std::fs::write(&path, lines.join("\r\n")).unwrap();
        let utm = crate::db::georef::Georef {
            crs: "EPSG:32610".into(),
            units: crate::db::dem::Units::Linear(1.0),
            first: (500_000.0, 5_200_000.0),
            cell: (10.0, 10.0),
        };
        let feed = PoseFeed::open(&PoseSource::File(path), decoder_for(Some(utm))).unwrap();
        let (first, _) = feed.at(0.7).unwrap();
        assert_eq!(feed.at(0.2).unwrap().0, first);
        assert!(feed.no_fix(0.7) && !feed.no_fix(0.2) && !feed.no_fix(1.0));
        assert!(feed.status(0.7).starts_with("POSE STALE 0.7 S NO FIX"));
        assert!(feed.at(1.0).unwrap().0.north > first.north);
    }

    #[test]
    fn a_live_feed_in_latitude_and_longitude_over_an_archive_without_georeferencing_stops() {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        let address = socket.local_addr().unwrap().to_string();
        drop(socket);
        let feed = PoseFeed::open(&PoseSource::Udp(address.clone()), decoder_for(None)).unwrap();
        let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
        sender
            .send_to(b"geo 1 47 -122 100 0 0 0", &address)
            .unwrap();
        let started = Instant::now();
        let error = loop {
            if let Err(e) = feed.check() {
                break e.to_string();
            }
            assert!(started.elapsed().as_secs() < 10, "no error");
            std::thread::sleep(std::time::Duration::from_millis(5));
        };
        assert!(
            error.contains(&address) && error.contains("test.smdb"),
            "{error}"
        );
    }
}
