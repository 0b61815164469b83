//! The lines of a pose feed, in any of its three forms, made poses in the archive's own
//! coordinates.
//!
//! ```text
//! TIME EAST NORTH ALTITUDE HEADING PITCH ROLL        the archive's own coordinates
//! geo TIME LATITUDE LONGITUDE ALTITUDE HEADING PITCH ROLL
//! $GPGGA,...  $GPRMC,...                             NMEA 0183 (any talker)
//! ```
//!
//! Latitudes and longitudes are placed through the archive's georeferencing
//! ([`Header::locate`]); headings they come with are from true north and are turned to the
//! archive's grid north (UTM's grid convergence). NMEA gives no attitude: the heading is the
//! last RMC course over ground, the camera level.

use super::Pose;
use super::nmea;
use crate::db::archive::{Header, Located};
use crate::error::Error;

/// What one line of a feed says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reading {
    /// A pose.
    Pose(Pose),
    /// The receiver has no valid fix at this time (feed seconds): the camera stays where it
    /// is and the feed counts as stale.
    NoFix(f64),
    /// A blank line, a comment, or a sentence that is not a position.
    Nothing,
}

/// Why a line gives no pose.
#[derive(Debug)]
pub enum Refused {
    /// The line is malformed: what is wrong with it.
    Line(String),
    /// The line is well formed but the archive cannot place it (latitude and longitude on an
    /// archive without georeferencing, or in a CRS not supported): no later line will do
    /// better.
    Archive(Error),
}

/// A day, seconds: NMEA times of day that go back by more than half of one crossed midnight.
const DAY: f64 = 86_400.0;

/// Reads the lines of one feed over one archive, keeping what NMEA spreads over sentences.
#[derive(Clone, Debug)]
pub struct PoseDecoder {
    /// The archive's name, for errors.
    archive: String,
    header: Header,
    /// The last GGA altitude, metres.
    altitude: Option<f64>,
    /// The last RMC course, degrees from true north.
    course: Option<f64>,
    /// Seconds added to NMEA times of day: a day for each midnight crossed.
    days: f64,
    /// The last NMEA time, with `days`.
    last_time: Option<f64>,
}

impl PoseDecoder {
    /// A decoder for poses over the archive `archive` whose header is `header`.
    pub fn new(archive: &str, header: Header) -> PoseDecoder {
        PoseDecoder {
            archive: archive.to_string(),
            header,
            altitude: None,
            course: None,
            days: 0.0,
            last_time: None,
        }
    }

    /// What `line` says.
    pub fn line(&mut self, line: &str) -> Result<Reading, Refused> {
        let trimmed = line.trim();
        if trimmed.starts_with('$') {
            return self.nmea(trimmed);
        }
        let text = trimmed.split('#').next().unwrap_or("").trim();
        match text.strip_prefix("geo") {
            Some(rest) if rest.starts_with(|c: char| c.is_whitespace() || c == ',') => {
                let [time, latitude, longitude, altitude, heading, pitch, roll] = numbers(
                    rest,
                    "geo time latitude longitude altitude heading pitch roll",
                )?;
                let at = self.locate(latitude, longitude)?;
                let archive = [time, at.east, at.north, altitude, 0.0, pitch, roll];
                let mut pose = Pose::from_numbers(archive).map_err(Refused::Line)?;
                pose.heading = heading.to_radians() - at.convergence;
                Ok(Reading::Pose(pose))
            }
            _ if text.is_empty() => Ok(Reading::Nothing),
            _ => {
                let n = numbers(text, "time east north altitude heading pitch roll")?;
                Pose::from_numbers(n)
                    .map(Reading::Pose)
                    .map_err(Refused::Line)
            }
        }
    }

    fn locate(&self, latitude: f64, longitude: f64) -> Result<Located, Refused> {
        // An archive that places no latitude will not place a later one: the feed stops. A
        // place its CRS cannot project is one bad line.
        self.header
            .placing(&self.archive)
            .map_err(Refused::Archive)?;
        self.header
            .locate(latitude, longitude, &self.archive)
            .map_err(|e| Refused::Line(e.to_string()))
    }

    fn nmea(&mut self, sentence: &str) -> Result<Reading, Refused> {
        let Some(fix) = nmea::parse(sentence).map_err(Refused::Line)? else {
            return Ok(Reading::Nothing);
        };
        let mut time = fix.time + self.days;
        if self.last_time.is_some_and(|last| time < last - DAY / 2.0) {
            self.days += DAY;
            time += DAY;
        }
        self.last_time = Some(time);
        let Some((latitude, longitude)) = fix.position else {
            return Ok(Reading::NoFix(time));
        };
        self.altitude = fix.altitude.or(self.altitude);
        self.course = fix.course.or(self.course);
        let at = self.locate(latitude, longitude)?;
        Ok(Reading::Pose(Pose {
            time,
            east: at.east,
            north: at.north,
            altitude: self.altitude.unwrap_or(0.0),
            heading: self.course.unwrap_or(0.0).to_radians() - at.convergence,
            pitch: 0.0,
            roll: 0.0,
        }))
    }
}

/// The seven numbers of `text`, separated by spaces or commas, named `names` in errors.
fn numbers(text: &str, names: &str) -> Result<[f64; 7], Refused> {
    let numbers: Vec<f64> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|w| !w.is_empty())
        .map(|w| {
            w.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| Refused::Line(format!("{w:?} is not a finite number")))
        })
        .collect::<Result<_, _>>()?;
    numbers.as_slice().try_into().map_err(|_| {
        Refused::Line(format!(
            "{} numbers where a pose has 7: {names}",
            numbers.len()
        ))
    })
}

/// A decoder over a 2 x 2 tile archive of 10 m spacing whose own coordinates are those of
/// `georef`'s CRS at the same spacing, origin (500 000, 5 200 000).
#[cfg(test)]
pub(crate) fn decoder_for(georef: Option<crate::db::georef::Georef>) -> PoseDecoder {
    use crate::db::archive::Codec;
    let header = Header {
        tiles_x: 2,
        tiles_y: 2,
        tile_size: 9,
        texture_size: 8,
        codec: Codec::Lz4,
        source_width: 17,
        source_height: 17,
        spacing: 10.0,
        vertical_scale: 1.0,
        origin_x: 500_000.0,
        origin_y: 5_200_000.0,
        min_height: 0.0,
        max_height: 100.0,
        height_quantum: 0.0625,
        nodata_filled: 0,
        nodata_flattened: 0,
        absent_tiles: 0,
        top_level: 0,
        top_offset: 0,
        top_len: 0,
        archive_len: 0,
        georef,
    };
    PoseDecoder::new("test.smdb", header)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::dem::Units;
    use crate::db::georef::Georef;

    fn utm10() -> Georef {
        Georef {
            crs: "EPSG:32610".into(),
            units: Units::Linear(1.0),
            first: (500_000.0, 5_200_000.0),
            cell: (10.0, 10.0),
        }
    }

    fn pose(reading: Result<Reading, Refused>) -> Pose {
        match reading {
            Ok(Reading::Pose(p)) => p,
            other => panic!("{other:?}"),
        }
    }

    fn refusal(reading: Result<Reading, Refused>) -> String {
        match reading {
            Err(Refused::Line(e)) => e,
            Err(Refused::Archive(e)) => e.to_string(),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn an_archive_line_is_seven_numbers_and_comments_and_blanks_are_nothing() {
        let mut d = decoder_for(None);
        let p = pose(d.line("12.5, 500100 5200200 900 90 -10 15 # over the ridge"));
        assert_eq!(
            (p.time, p.east, p.north, p.altitude),
            (12.5, 500100.0, 5200200.0, 900.0)
        );
        assert!((p.heading - 90f64.to_radians()).abs() < 1e-12);
        let f = p.forward();
        assert!(f.x > 0.98 && f.y < 0.0 && f.z.abs() < 1e-12, "{f}");
        assert_eq!(d.line("  # nothing").unwrap(), Reading::Nothing);
        assert!(refusal(d.line("1 2 3")).contains("3 numbers"));
        assert!(refusal(d.line("1 2 3 4 5 nan 7")).contains("nan"));
        assert!(refusal(d.line("1 2 3 4 5 95 7")).contains("pitch"));
        assert!(refusal(d.line("geo 1 2 3")).contains("latitude longitude"));
        assert!(refusal(d.line("geox 1 2 3 4 5 6 7")).contains("geox"));
    }

    #[test]
    fn a_geo_line_lands_where_the_projection_says_and_turns_true_north_to_grid_north() {
        let mut d = decoder_for(Some(utm10()));
        // On the central meridian (123 W) the grid's north is true north.
        let p = pose(d.line("geo 3 46.95 -123 1200 45 -5 2"));
        let expected = d.header.locate(46.95, -123.0, "x").unwrap();
        assert_eq!((p.east, p.north), (500_000.0, expected.north));
        assert!((p.heading - 45f64.to_radians()).abs() < 1e-15);
        assert_eq!(p.altitude, 1200.0);
        // East of it the grid's north lies east of true north: a true heading of north is a
        // little west of the grid's.
        let east = pose(d.line("geo 3 46.95 -122.99 1200 0 0 0"));
        assert!(
            east.heading < 0.0 && east.heading > -1e-3,
            "{}",
            east.heading
        );
        assert!(
            east.east > 500_700.0 && east.east < 500_800.0,
            "{}",
            east.east
        );
    }

    #[test]
    fn latitude_and_longitude_on_an_archive_without_georeferencing_name_the_archive() {
        let mut d = decoder_for(None);
        for line in [
            "geo 1 47 -122 100 0 0 0",
            "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47",
        ] {
            let Err(Refused::Archive(e)) = d.line(line) else {
                panic!("{line}")
            };
            let e = e.to_string();
            assert!(
                e.contains("test.smdb") && e.contains("no georeferencing"),
                "{e}"
            );
        }
        // A void fix places nothing, so it is no error.
        let void = crate::sim::pose::nmea::with_checksum("GPRMC,123520,V,,,,,,,230394,,");
        assert_eq!(d.line(&void).unwrap(), Reading::NoFix(45320.0));
    }

    #[test]
    fn nmea_takes_altitude_from_gga_and_heading_from_rmc_and_crosses_midnight() {
        let mut d = decoder_for(Some(utm10()));
        let rmc = crate::sim::pose::nmea::with_checksum(
            "GPRMC,235959.0,A,4700.000,N,12300.000,W,10.0,090.0,010125,,,A",
        );
        let p = pose(d.line(&rmc));
        assert_eq!((p.altitude, p.pitch, p.roll), (0.0, 0.0, 0.0));
        assert!((p.heading - 90f64.to_radians()).abs() < 1e-15);
        let gga = crate::sim::pose::nmea::with_checksum(
            "GNGGA,000000.5,4700.000,N,12300.000,W,1,08,0.9,321.5,M,-20.1,M,,",
        );
        let p = pose(d.line(&gga));
        assert_eq!((p.time, p.altitude), (86_400.5, 321.5));
        assert!((p.heading - 90f64.to_radians()).abs() < 1e-15);
        let lost = crate::sim::pose::nmea::with_checksum("GNGGA,000001.5,,,,,0,00,,,,,,,");
        assert_eq!(d.line(&lost).unwrap(), Reading::NoFix(86_401.5));
        assert!(refusal(d.line("$GPGGA,000001*00")).contains("checksum"));
    }
}
