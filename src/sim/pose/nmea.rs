//! NMEA 0183 position sentences, as a GPS receiver writes them: `$xxGGA` (position, altitude,
//! fix quality) and `$xxRMC` (position, course over ground, validity), any talker (`GP`, `GN`,
//! `GL`, ...). A checksum (`*hh`) is verified when the sentence has one; other sentence types
//! are not positions and read as nothing.

/// A position fix one sentence gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fix {
    /// Seconds since midnight UTC.
    pub time: f64,
    /// Degrees north, degrees east; `None` when the receiver has no valid fix (GGA quality 0,
    /// RMC status `V` or mode `N`).
    pub position: Option<(f64, f64)>,
    /// GGA's altitude: metres above mean sea level.
    pub altitude: Option<f64>,
    /// RMC's course over ground: degrees clockwise from true north.
    pub course: Option<f64>,
}

/// The fix of the sentence `line` (without its line end), `None` for a sentence of another
/// type, or what is wrong with it.
pub fn parse(line: &str) -> Result<Option<Fix>, String> {
    let body = line
        .trim_end()
        .strip_prefix('$')
        .ok_or("an NMEA sentence starts with '$'")?;
    let body = match body.split_once('*') {
        Some((body, sum)) => {
            let given = u8::from_str_radix(sum, 16)
                .ok()
                .filter(|_| sum.len() == 2)
                .ok_or_else(|| format!("checksum {sum:?} is not two hexadecimal digits"))?;
            let computed = body.bytes().fold(0u8, |x, b| x ^ b);
            if given != computed {
                return Err(format!(
                    "checksum {given:02X} where the sentence's is {computed:02X}"
                ));
            }
            body
        }
        None => body,
    };
    let fields: Vec<&str> = body.split(',').collect();
    let address = fields[0];
    if address.len() != 5 || !address.is_ascii() {
        return Err(format!("{address:?} is not a sentence address like GPGGA"));
    }
    let field = |k: usize| fields.get(k).copied().unwrap_or("");
    match &address[2..] {
        "GGA" => {
            let time = time_of_day(field(1))?;
            let quality = field(6);
            if quality.is_empty() || quality == "0" {
                return Ok(Some(Fix {
                    time,
                    position: None,
                    altitude: None,
                    course: None,
                }));
            }
            let position = position(field(2), field(3), field(4), field(5))?;
            let altitude = number(field(9), "altitude")?;
            if !matches!(field(10), "M" | "") {
                return Err(format!("altitude in {:?}, not metres (M)", field(10)));
            }
            Ok(Some(Fix {
                time,
                position: Some(position),
                altitude: Some(altitude),
                course: None,
            }))
        }
        "RMC" => {
            let time = time_of_day(field(1))?;
            let valid = match field(2) {
                "A" => field(12) != "N",
                "V" => false,
                s => return Err(format!("RMC status {s:?}, neither A (valid) nor V (void)")),
            };
            if !valid {
                return Ok(Some(Fix {
                    time,
                    position: None,
                    altitude: None,
                    course: None,
                }));
            }
            let course = match field(8) {
                "" => None,
                c => Some(number(c, "course")?),
            };
            Ok(Some(Fix {
                time,
                position: Some(position(field(3), field(4), field(5), field(6))?),
                altitude: None,
                course,
            }))
        }
        _ => Ok(None),
    }
}

/// A finite number, or an error naming `what`.
fn number(s: &str, what: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("{what} {s:?} is not a number"))
}

/// Seconds since midnight of `hhmmss.ss`.
fn time_of_day(s: &str) -> Result<f64, String> {
    let bad = || format!("time {s:?} is not hhmmss.ss");
    if s.len() < 6 || !s.is_char_boundary(2) || !s.is_char_boundary(4) {
        return Err(bad());
    }
    let part = |r: std::ops::Range<usize>| s[r].parse::<u32>().map_err(|_| bad());
    let (h, m) = (part(0..2)?, part(2..4)?);
    let seconds = number(&s[4..], "seconds").map_err(|_| bad())?;
    if h > 23 || m > 59 || !(0.0..61.0).contains(&seconds) {
        return Err(bad());
    }
    Ok(f64::from(h * 3600 + m * 60) + seconds)
}

/// Degrees north and east of `ddmm.mm`, `N|S`, `dddmm.mm`, `E|W`.
fn position(lat: &str, ns: &str, lon: &str, ew: &str) -> Result<(f64, f64), String> {
    let angle = |s: &str, what: &str, max: f64| -> Result<f64, String> {
        let v = number(s, what)?;
        let degrees = (v / 100.0).trunc();
        let minutes = v - degrees * 100.0;
        if v < 0.0 || minutes >= 60.0 || degrees > max {
            return Err(format!(
                "{what} {s:?} is not a valid angle in degrees and minutes"
            ));
        }
        Ok(degrees + minutes / 60.0)
    };
    let latitude = angle(lat, "latitude", 90.0)?;
    let longitude = angle(lon, "longitude", 180.0)?;
    let latitude = match ns {
        "N" => latitude,
        "S" => -latitude,
        s => return Err(format!("latitude hemisphere {s:?}, neither N nor S")),
    };
    let longitude = match ew {
        "E" => longitude,
        "W" => -longitude,
        s => return Err(format!("longitude hemisphere {s:?}, neither E nor W")),
    };
    if latitude.abs() > 90.0 || longitude.abs() > 180.0 {
        return Err(format!(
            "latitude {latitude}, longitude {longitude} is off the Earth"
        ));
    }
    Ok((latitude, longitude))
}

/// `sentence` (between `$` and `*`) with its checksum: what a test or a simulator sends.
pub fn with_checksum(sentence: &str) -> String {
    let sum = sentence.bytes().fold(0u8, |x, b| x ^ b);
    format!("${sentence}*{sum:02X}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gga_and_rmc_of_a_receiver() {
        // The NMEA standard's own examples, as gpsd's documentation quotes them.
        let gga = parse("$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47")
            .unwrap()
            .unwrap();
        assert_eq!(gga.time, 12.0 * 3600.0 + 35.0 * 60.0 + 19.0);
        let (lat, lon) = gga.position.unwrap();
        assert!((lat - (48.0 + 7.038 / 60.0)).abs() < 1e-12);
        assert!((lon - (11.0 + 31.0 / 60.0)).abs() < 1e-12);
        assert_eq!((gga.altitude, gga.course), (Some(545.4), None));
        let rmc = parse("$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A")
            .unwrap()
            .unwrap();
        assert_eq!((rmc.course, rmc.altitude), (Some(84.4), None));
        assert_eq!(rmc.position, gga.position);
    }

    #[test]
    fn void_fixes_have_no_position_and_other_sentences_are_nothing() {
        let void = with_checksum("GNRMC,000001.00,V,,,,,,,010125,,,N");
        assert_eq!(parse(&void).unwrap().unwrap().position, None);
        let none = with_checksum("GPGGA,235959.5,,,,,0,00,99.9,,,,,,");
        let fix = parse(&none).unwrap().unwrap();
        assert_eq!((fix.time, fix.position), (86399.5, None));
        assert_eq!(parse(&with_checksum("GPGSV,3,1,11,03,03,111,00")), Ok(None));
        // No checksum: accepted as it is.
        assert!(parse("$GPRMC,123519,A,4807.038,S,01131.000,W,0,,230394,,").is_ok());
    }

    #[test]
    fn damaged_sentences_say_what_is_wrong() {
        let e = parse("$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*48");
        assert!(e.unwrap_err().contains("checksum 48"));
        for (bad, says) in [
            (
                "GPGGA,123519,4867.038,N,01131.000,E,1,08,0.9,545.4,M,,,,",
                "latitude",
            ),
            (
                "GPGGA,123519,4807.038,X,01131.000,E,1,08,0.9,545.4,M,,,,",
                "hemisphere",
            ),
            (
                "GPGGA,993519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,,,",
                "time",
            ),
            (
                "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,x,M,,,,",
                "altitude",
            ),
            (
                "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,F,,,,",
                "metres",
            ),
            (
                "GPRMC,123519,Q,4807.038,N,01131.000,E,0,0,230394,,",
                "status",
            ),
            ("GPRMCX,123519", "address"),
        ] {
            let e = parse(&with_checksum(bad)).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
        assert!(parse("GPGGA").unwrap_err().contains("'$'"));
        assert!(parse("$GPGGA,1*4").unwrap_err().contains("two hexadecimal"));
    }
}
