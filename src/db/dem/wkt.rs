//! The CRS a WKT text names (a GDAL VRT's `SRS`, an ASCII grid's `.prj`): what it is called
//! and how its coordinates become metres. Only what placing a grid needs is read.

use super::placement::{FOOT, US_SURVEY_FOOT, Units, WEB_MERCATOR};

/// One `KEYWORD[...]` of a WKT text.
#[derive(Clone, Debug, PartialEq)]
struct Node {
    keyword: String,
    items: Vec<Item>,
}

/// What a node lists.
#[derive(Clone, Debug, PartialEq)]
enum Item {
    Text(String),
    Number(f64),
    /// A bare word (an axis direction, say).
    Word(String),
    Node(Node),
}

/// Nodes nested deeper than this are refused: no CRS comes close, and recursion stays bounded.
const MAX_DEPTH: usize = 32;

/// A cursor over WKT text.
struct Parser<'a> {
    text: &'a [u8],
    at: usize,
}

impl Parser<'_> {
    fn skip_space(&mut self) {
        while self.text.get(self.at).is_some_and(u8::is_ascii_whitespace) {
            self.at += 1;
        }
    }

    fn word(&mut self) -> String {
        let start = self.at;
        while self
            .text
            .get(self.at)
            .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
        {
            self.at += 1;
        }
        String::from_utf8_lossy(&self.text[start..self.at]).into_owned()
    }

    fn node(&mut self, depth: usize) -> Result<Node, String> {
        if depth > MAX_DEPTH {
            return Err("nested too deep".into());
        }
        self.skip_space();
        let keyword = self.word();
        if keyword.is_empty() {
            return Err(format!("a keyword expected at byte {}", self.at));
        }
        self.skip_space();
        let close = match self.text.get(self.at) {
            Some(b'[') => b']',
            Some(b'(') => b')',
            _ => return Err(format!("[ expected after {keyword}")),
        };
        self.at += 1;
        let mut items = Vec::new();
        loop {
            self.skip_space();
            match self.text.get(self.at) {
                Some(c) if *c == close => {
                    self.at += 1;
                    return Ok(Node { keyword, items });
                }
                Some(b',') if !items.is_empty() => self.at += 1,
                Some(_) if items.is_empty() => {}
                Some(c) => {
                    return Err(format!("',' expected in {keyword}, found {:?}", *c as char));
                }
                None => return Err(format!("{keyword} is not closed")),
            }
            self.skip_space();
            items.push(self.item(depth)?);
        }
    }

    fn item(&mut self, depth: usize) -> Result<Item, String> {
        match self.text.get(self.at) {
            Some(b'"') => {
                let mut text = Vec::new();
                self.at += 1;
                loop {
                    match self.text.get(self.at) {
                        Some(b'"') if self.text.get(self.at + 1) == Some(&b'"') => {
                            text.push(b'"');
                            self.at += 2;
                        }
                        Some(b'"') => {
                            self.at += 1;
                            return Ok(Item::Text(String::from_utf8_lossy(&text).into_owned()));
                        }
                        Some(c) => {
                            text.push(*c);
                            self.at += 1;
                        }
                        None => return Err("a quoted text is not closed".into()),
                    }
                }
            }
            Some(c) if c.is_ascii_digit() || matches!(c, b'-' | b'+' | b'.') => {
                let start = self.at;
                while self
                    .text
                    .get(self.at)
                    .is_some_and(|c| c.is_ascii_alphanumeric() || matches!(c, b'-' | b'+' | b'.'))
                {
                    self.at += 1;
                }
                let s = String::from_utf8_lossy(&self.text[start..self.at]).into_owned();
                s.parse()
                    .map(Item::Number)
                    .map_err(|_| format!("{s:?} is not a number"))
            }
            Some(_) => {
                let start = self.at;
                let word = self.word();
                self.skip_space();
                if matches!(self.text.get(self.at), Some(b'[' | b'(')) {
                    self.at = start;
                    Ok(Item::Node(self.node(depth + 1)?))
                } else if word.is_empty() {
                    Err(format!("unexpected byte at {}", self.at))
                } else {
                    Ok(Item::Word(word))
                }
            }
            None => Err("the text ends inside a node".into()),
        }
    }
}

impl Node {
    fn children<'a>(&'a self, keywords: &'a [&str]) -> impl Iterator<Item = &'a Node> + 'a {
        self.items.iter().filter_map(move |i| match i {
            Item::Node(n) if keywords.iter().any(|k| n.keyword.eq_ignore_ascii_case(k)) => Some(n),
            _ => None,
        })
    }

    fn name(&self) -> Option<&str> {
        match self.items.first() {
            Some(Item::Text(t)) => Some(t),
            _ => None,
        }
    }

    fn number(&self, index: usize) -> Option<f64> {
        match self.items.get(index) {
            Some(Item::Number(n)) => Some(*n),
            Some(Item::Text(t)) => t.parse().ok(),
            _ => None,
        }
    }

    /// The EPSG code of this node's own `AUTHORITY` (WKT 1) or `ID` (WKT 2).
    fn epsg(&self) -> Option<u32> {
        self.children(&["AUTHORITY", "ID"])
            .filter(|a| a.name().is_some_and(|n| n.eq_ignore_ascii_case("EPSG")))
            .find_map(|a| a.number(1))
            .filter(|c| c.fract() == 0.0 && *c > 0.0 && *c < 1e9)
            .map(|c| c as u32)
    }

    /// Metres per unit of a projected CRS: its own `UNIT`/`LENGTHUNIT` (WKT 1), or its axes'
    /// (WKT 2).
    fn linear_unit(&self) -> Option<f64> {
        let own = |n: &Node| {
            n.children(&["UNIT", "LENGTHUNIT"])
                .find_map(|u| u.number(1))
        };
        own(self).or_else(|| {
            self.children(&["CS", "AXIS"])
                .chain(self.children(&["AXIS"]))
                .find_map(own)
        })
    }
}

/// The CRS a WKT text names: what to call it, and its units.
pub(crate) fn crs(text: &str) -> Result<(String, Units), String> {
    let mut parser = Parser {
        text: text.trim().as_bytes(),
        at: 0,
    };
    let mut root = parser.node(0)?;
    parser.skip_space();
    if parser.at != parser.text.len() {
        return Err(format!("text after the CRS at byte {}", parser.at));
    }
    // A compound CRS (horizontal + vertical): its horizontal part places the grid.
    if ["COMPD_CS", "COMPOUNDCRS"].contains(&root.keyword.to_ascii_uppercase().as_str()) {
        let horizontal = root
            .children(&[
                "PROJCS",
                "PROJCRS",
                "PROJECTEDCRS",
                "GEOGCS",
                "GEOGCRS",
                "GEODCRS",
            ])
            .next()
            .cloned()
            .ok_or("a compound CRS without a horizontal part")?;
        root = horizontal;
    }
    let label = match (root.epsg(), root.name()) {
        (Some(code), _) => format!("EPSG:{code}"),
        (None, Some(name)) => format!("\"{name}\""),
        (None, None) => format!("an unnamed {}", root.keyword),
    };
    let units = match root.keyword.to_ascii_uppercase().as_str() {
        "GEOGCS" | "GEOGCRS" | "GEOGRAPHICCRS" | "GEODCRS" | "GEODETICCRS" => Units::Degrees,
        "PROJCS" | "PROJCRS" | "PROJECTEDCRS" => {
            let metres = root.linear_unit().unwrap_or(1.0);
            if !(metres.is_finite() && metres > 0.0) {
                return Err(format!("{label} has a linear unit of {metres} m"));
            }
            let snapped = [1.0, FOOT, US_SURVEY_FOOT]
                .into_iter()
                .find(|u| (u - metres).abs() < 1e-9)
                .unwrap_or(metres);
            let mercator = root.epsg().is_some_and(|c| WEB_MERCATOR.contains(&c))
                || root.name().is_some_and(|n| n.contains("Pseudo-Mercator"));
            if mercator {
                Units::WebMercator(snapped)
            } else {
                Units::Linear(snapped)
            }
        }
        other => return Err(format!("{other} is not a CRS that places a grid")),
    };
    Ok((label, units))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wkt1_geographic_and_utm_and_state_plane_feet() {
        let wgs84 = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AXIS["Latitude",NORTH],AXIS["Longitude",EAST],AUTHORITY["EPSG","4326"]]"#;
        assert_eq!(crs(wgs84), Ok(("EPSG:4326".into(), Units::Degrees)));
        let utm = r#"PROJCS["WGS 84 / UTM zone 10N",GEOGCS["WGS 84",AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",-123],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AUTHORITY["EPSG","32610"]]"#;
        assert_eq!(crs(utm), Ok(("EPSG:32610".into(), Units::Linear(1.0))));
        let feet = r#"PROJCS["NAD83(HARN) / Washington North (ftUS)",GEOGCS["NAD83(HARN)"],UNIT["US survey foot",0.304800609601219]]"#;
        assert_eq!(
            crs(feet),
            Ok((
                "\"NAD83(HARN) / Washington North (ftUS)\"".into(),
                Units::Linear(US_SURVEY_FOOT)
            ))
        );
    }

    #[test]
    fn wkt2_web_mercator_and_compound() {
        let merc = r#"PROJCRS["WGS 84 / Pseudo-Mercator",BASEGEOGCRS["WGS 84",ID["EPSG",4326]],CONVERSION["Popular Visualisation Pseudo-Mercator"],CS[Cartesian,2],AXIS["easting (X)",east,ORDER[1],LENGTHUNIT["metre",1]],ID["EPSG",3857]]"#;
        assert_eq!(crs(merc), Ok(("EPSG:3857".into(), Units::WebMercator(1.0))));
        let compound =
            r#"COMPD_CS["x",GEOGCS["NAD83",AUTHORITY["EPSG","4269"]],VERT_CS["NAVD88"]]"#;
        assert_eq!(crs(compound), Ok(("EPSG:4269".into(), Units::Degrees)));
    }

    #[test]
    fn broken_text_is_an_error_not_a_panic() {
        for bad in [
            "",
            "GEOGCS",
            "GEOGCS[\"x\"",
            "PROJCS[\"x\",UNIT[\"m\",-1]]",
            "VERT_CS[\"x\"]",
            "GEOGCS[\"x\"] tail",
        ] {
            assert!(crs(bad).is_err(), "{bad}");
        }
        let deep = "A[".repeat(100) + &"]".repeat(100);
        assert!(crs(&deep).is_err());
    }
}
