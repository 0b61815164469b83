//! A pose feed for the viewer: a GPS and attitude source, a simulator or a recording drives
//! the camera instead of a flight path or the keyboard.
//!
//! One pose a line, numbers separated by spaces or commas, `#` starting a comment:
//!
//! ```text
//! TIME EAST NORTH ALTITUDE HEADING PITCH ROLL
//! ```
//!
//! `TIME` in seconds (any origin), `EAST` and `NORTH` in the archive's own coordinates (those
//! `info` gives as the origin: projected metres for a UTM model), `ALTITUDE` in metres above
//! the archive's height 0, `HEADING` in degrees clockwise from north, `PITCH` in degrees up
//! from level, `ROLL` in degrees with the right wing down. A live feed (standard input, UDP
//! datagrams) is drawn at its latest pose; a recording (a file) is replayed by its times from
//! the viewer's start.

use std::io::BufRead;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::DVec3;

use crate::engine::Engine;
use crate::engine::camera::Camera;
use crate::error::{Error, Result};

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
    /// Radians clockwise from north.
    pub heading: f64,
    /// Radians up from level.
    pub pitch: f64,
    /// Radians, right wing down.
    pub roll: f64,
}

impl Pose {
    /// The pose a line gives; `None` for a blank line or a comment.
    pub fn parse(line: &str) -> std::result::Result<Option<Pose>, String> {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            return Ok(None);
        }
        let numbers: Vec<f64> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|w| !w.is_empty())
            .map(|w| {
                w.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("{w:?} is not a finite number"))
            })
            .collect::<std::result::Result<_, _>>()?;
        let [time, east, north, altitude, heading, pitch, roll] = numbers[..] else {
            return Err(format!(
                "{} numbers where a pose has 7: time east north altitude heading pitch roll",
                numbers.len()
            ));
        };
        if pitch.abs() > 90.0 {
            return Err(format!("pitch {pitch}° is beyond straight up or down"));
        }
        Ok(Some(Pose {
            time,
            east,
            north,
            altitude,
            heading: heading.to_radians(),
            pitch: pitch.to_radians(),
            roll: roll.to_radians(),
        }))
    }

    /// The unit viewing direction in the engine's world (x east, y up, z south).
    pub fn forward(&self) -> DVec3 {
        let (sh, ch) = self.heading.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        DVec3::new(sh * cp, sp, -ch * cp)
    }

    /// The camera of this pose over `engine`'s terrain (the engine keeps it above the ground).
    pub fn camera(&self, engine: &Engine) -> Camera {
        let terrain = engine.terrain();
        let (east, north) = terrain.archive_origin;
        let eye = DVec3::new(self.east - east, self.altitude, north - self.north);
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
    /// Lines or datagrams that were not a pose.
    refused: u64,
}

/// A feed of poses.
pub struct PoseFeed {
    live: Arc<Mutex<Received>>,
    recording: Option<Vec<Pose>>,
}

/// Poses older than this show as stale on the HUD.
pub const STALE_SECONDS: f64 = 1.0;

impl PoseFeed {
    /// Opens `source`: reads a recording whole (a line that is not a pose is an error naming
    /// the file and the line), or starts a thread that keeps the latest live pose.
    pub fn open(source: &PoseSource) -> Result<PoseFeed> {
        let live = Arc::new(Mutex::new(Received::default()));
        let recording = match source {
            PoseSource::File(path) => Some(read_recording(path)?),
            PoseSource::Stdin => {
                let received = Arc::clone(&live);
                std::thread::spawn(move || {
                    for line in std::io::stdin().lock().lines() {
                        let Ok(line) = line else { break };
                        receive(&received, &line);
                    }
                });
                None
            }
            PoseSource::Udp(address) => {
                let socket =
                    UdpSocket::bind(address).map_err(|e| Error::io(format!("udp:{address}"), e))?;
                let received = Arc::clone(&live);
                std::thread::spawn(move || {
                    let mut buf = [0u8; 1024];
                    while let Ok(n) = socket.recv(&mut buf) {
                        receive(&received, &String::from_utf8_lossy(&buf[..n]));
                    }
                });
                None
            }
        };
        Ok(PoseFeed { live, recording })
    }

    /// The pose to draw `t` seconds after the viewer started, and its age in seconds; `None`
    /// before the first.
    pub fn at(&self, t: f64) -> Option<(Pose, f64)> {
        match &self.recording {
            Some(poses) => {
                let start = poses.first()?.time;
                let k = poses.partition_point(|p| p.time - start <= t);
                let pose = poses[k.checked_sub(1)?];
                Some((pose, t - (pose.time - start)))
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

    /// The HUD's line for the feed at viewer time `t`.
    pub fn status(&self, t: f64) -> String {
        let refused = match self.refused() {
            0 => String::new(),
            n => format!(" {n} BAD"),
        };
        match self.at(t) {
            None => format!("POSE WAITING{refused}"),
            Some((_, age)) if age > STALE_SECONDS => format!("POSE STALE {age:.1} S{refused}"),
            Some((_, age)) => format!("POSE {:.0} MS OLD{refused}", age * 1e3),
        }
    }
}

/// Keeps the pose of a live `line`, or counts it refused.
fn receive(received: &Mutex<Received>, line: &str) {
    let mut r = received.lock().expect("pose feed lock");
    for line in line.lines() {
        match Pose::parse(line) {
            Ok(Some(pose)) => r.latest = Some((Instant::now(), pose)),
            Ok(None) => {}
            Err(_) => r.refused += 1,
        }
    }
}

/// The poses of the recording `path`, in time order.
fn read_recording(path: &Path) -> Result<Vec<Pose>> {
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
    for (k, line) in std::io::BufReader::new(file).lines().enumerate() {
        let line = line.map_err(|e| Error::io(&name, e))?;
        match Pose::parse(&line) {
            Ok(Some(pose)) => {
                if poses.last().is_some_and(|last| pose.time < last.time) {
                    return Err(Error::invalid(
                        &name,
                        format!("line {}: time {} goes back", k + 1, pose.time),
                    ));
                }
                poses.push(pose);
            }
            Ok(None) => {}
            Err(e) => return Err(Error::invalid(&name, format!("line {}: {e}", k + 1))),
        }
    }
    if poses.is_empty() {
        return Err(Error::invalid(&name, "the recording holds no pose"));
    }
    Ok(poses)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_is_seven_numbers_and_comments_and_blanks_are_nothing() {
        let p = Pose::parse("12.5, 500100 5200200 900 90 -10 15 # over the ridge")
            .unwrap()
            .unwrap();
        assert_eq!(
            (p.time, p.east, p.north, p.altitude),
            (12.5, 500100.0, 5200200.0, 900.0)
        );
        assert!((p.heading - 90f64.to_radians()).abs() < 1e-12);
        let f = p.forward();
        assert!(f.x > 0.98 && f.y < 0.0 && f.z.abs() < 1e-12, "{f}");
        assert_eq!(Pose::parse("  # nothing"), Ok(None));
        assert!(Pose::parse("1 2 3").unwrap_err().contains("3 numbers"));
        assert!(Pose::parse("1 2 3 4 5 nan 7").unwrap_err().contains("nan"));
        assert!(Pose::parse("1 2 3 4 5 95 7").unwrap_err().contains("pitch"));
    }

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
        let feed = PoseFeed::open(&PoseSource::File(path.clone())).unwrap();
        assert_eq!(feed.at(0.4).unwrap().0.east, 0.0);
        assert_eq!(feed.at(0.5).unwrap().0.east, 5.0);
        let (last, age) = feed.at(5.0).unwrap();
        assert_eq!((last.east, age), (9.0, 3.0));
        assert!(feed.status(5.0).starts_with("POSE STALE 3.0"));
        std::fs::write(&path, "1 0 0 10 0 0 0\n0 0 0 10 0 0 0\n").unwrap();
        let e = PoseFeed::open(&PoseSource::File(path.clone()))
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
        let feed = PoseFeed::open(&PoseSource::Udp(address.clone())).unwrap();
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
}
