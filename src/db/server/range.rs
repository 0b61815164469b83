//! The `Range` header of a request for one file (RFC 9110 section 14): one range or the whole file.

/// What a `Range` header asks of a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangeRequest {
    /// No usable single range: send the whole file.
    Whole,
    /// Bytes `first ..= last`.
    Part(u64, u64),
    /// A range that starts past the end: 416.
    Unsatisfiable,
}

/// Parses a `Range` header value against a file of `len` bytes.
pub fn parse_range(value: &str, len: u64) -> RangeRequest {
    parse_single_range(value, len).unwrap_or(RangeRequest::Whole)
}

fn parse_single_range(value: &str, len: u64) -> Option<RangeRequest> {
    let spec = value.trim().strip_prefix("bytes=")?;
    if spec.contains(',') {
        return None;
    }
    let (a, b) = spec.split_once('-')?;
    let (a, b) = (a.trim(), b.trim());
    let range = if a.is_empty() {
        let n = b.parse::<u64>().ok()?;
        if n == 0 || len == 0 {
            return Some(RangeRequest::Unsatisfiable);
        }
        (len.saturating_sub(n), len - 1)
    } else {
        let first = a.parse::<u64>().ok()?;
        let last = if b.is_empty() {
            len.saturating_sub(1)
        } else {
            match b.parse::<u64>() {
                Ok(l) if l >= first => l.min(len.saturating_sub(1)),
                _ => return None,
            }
        };
        if first >= len {
            return Some(RangeRequest::Unsatisfiable);
        }
        (first, last)
    };
    Some(RangeRequest::Part(range.0, range.1))
}

#[cfg(test)]
mod tests {
    use super::{RangeRequest::*, parse_range};

    #[test]
    fn ranges_follow_rfc_9110() {
        assert_eq!(parse_range("bytes=0-9", 100), Part(0, 9));
        assert_eq!(parse_range("bytes=90-", 100), Part(90, 99));
        assert_eq!(parse_range("bytes=-10", 100), Part(90, 99));
        assert_eq!(parse_range("bytes=95-200", 100), Part(95, 99));
        assert_eq!(parse_range("bytes=100-", 100), Unsatisfiable);
        assert_eq!(parse_range("bytes=0-1,5-6", 100), Whole);
        assert_eq!(parse_range("items=0-1", 100), Whole);
        assert_eq!(parse_range("bytes=5-1", 100), Whole);
    }
}
