//! `stats.csv` read back: columns by name.

use std::path::Path;

use crate::error::{Error, Result};

/// The numbers of a `stats.csv`, column by column.
#[derive(Clone, Debug, PartialEq)]
pub struct StatsTable {
    name: String,
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl StatsTable {
    /// Reads and parses `path`.
    pub fn read(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(&name, e))?;
        Self::parse(&text, &name)
    }

    /// Parses CSV text with a header line; `name` goes into error messages.
    pub fn parse(text: &str, name: &str) -> Result<Self> {
        let mut lines = text.lines();
        let header: Vec<String> = lines
            .next()
            .ok_or_else(|| Error::invalid(name, "empty file, no header line"))?
            .split(',')
            .map(str::to_string)
            .collect();
        let rows = lines
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
            .map(|(k, line)| {
                let row: Vec<f64> = line
                    .split(',')
                    .map(|v| v.trim().parse::<f64>())
                    .collect::<std::result::Result<_, _>>()
                    .map_err(|e| Error::invalid(name, format!("line {}: {e}", k + 2)))?;
                if row.len() != header.len() {
                    return Err(Error::invalid(
                        name,
                        format!(
                            "line {}: {} values for {} columns",
                            k + 2,
                            row.len(),
                            header.len()
                        ),
                    ));
                }
                Ok(row)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(StatsTable {
            name: name.to_string(),
            header,
            rows,
        })
    }

    /// Rows (frames).
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The values of column `column`, one per row.
    pub fn column(&self, column: &str) -> Result<Vec<f64>> {
        let k = self
            .header
            .iter()
            .position(|h| h == column)
            .ok_or_else(|| Error::invalid(&self.name, format!("no column {column:?}")))?;
        Ok(self.rows.iter().map(|r| r[k]).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_by_name_and_errors_that_name_the_line() {
        let t = StatsTable::parse("a,b\n1,2\n3,4.5\n", "s.csv").unwrap();
        assert_eq!(t.len(), 2);
        assert_eq!(t.column("b").unwrap(), [2.0, 4.5]);
        let e = t.column("c").unwrap_err().to_string();
        assert!(e.contains("s.csv") && e.contains("\"c\""), "{e}");
        let e = StatsTable::parse("a,b\n1\n", "s.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2"), "{e}");
        let e = StatsTable::parse("a\nx\n", "s.csv")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2"), "{e}");
        assert!(StatsTable::parse("", "s.csv").is_err());
    }
}
