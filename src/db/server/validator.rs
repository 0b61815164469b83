//! The archive's validators (an `ETag` from its size and modification time, and its
//! `Last-Modified` date) and the conditional requests they answer (RFC 9110 section 13):
//! `If-Match`, `If-Unmodified-Since`, `If-None-Match`, `If-Modified-Since` and `If-Range`.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use hyper::header::{self, HeaderMap, HeaderValue};

/// What identifies one version of the archive file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Validator {
    /// The strong entity tag, quotes included: the size and the modification time in
    /// nanoseconds, in hexadecimal.
    etag: String,
    /// The modification time in whole seconds (what an HTTP date holds), never after `now`.
    modified: SystemTime,
}

/// What the preconditions of a request say to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Precondition {
    /// Answer `412 Precondition Failed`.
    Failed,
    /// Answer `304 Not Modified`.
    NotModified,
    /// Answer normally; `honour_range` is false when `If-Range` names another version, so
    /// that the whole file is sent.
    Proceed {
        /// Whether a `Range` header may be applied.
        honour_range: bool,
    },
}

impl Validator {
    /// The validator of a file of `len` bytes last modified at `modified` (the epoch when the
    /// system does not say), as seen at `now`.
    pub(super) fn new(len: u64, modified: Option<SystemTime>, now: SystemTime) -> Self {
        let modified = modified.unwrap_or(UNIX_EPOCH);
        let nanos = modified
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let seconds = modified
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        Validator {
            etag: format!("\"{len:x}-{nanos:x}\""),
            modified: (UNIX_EPOCH + Duration::from_secs(seconds)).min(now),
        }
    }

    /// The `ETag` header's value.
    pub(super) fn etag(&self) -> &str {
        &self.etag
    }

    /// The `Last-Modified` header's value.
    pub(super) fn last_modified(&self) -> String {
        httpdate::fmt_http_date(self.modified)
    }

    /// Evaluates the preconditions of a `GET` or `HEAD` request in the order of RFC 9110
    /// section 13.2.2. Dates that do not parse are ignored, as the RFC says.
    pub(super) fn preconditions(&self, headers: &HeaderMap) -> Precondition {
        if let Some(tags) = joined(headers, header::IF_MATCH) {
            if !self.any_tag(&tags, true) {
                return Precondition::Failed;
            }
        } else if let Some(date) = date(headers, header::IF_UNMODIFIED_SINCE)
            && self.modified > date
        {
            return Precondition::Failed;
        }
        if let Some(tags) = joined(headers, header::IF_NONE_MATCH) {
            if self.any_tag(&tags, false) {
                return Precondition::NotModified;
            }
        } else if let Some(date) = date(headers, header::IF_MODIFIED_SINCE)
            && self.modified <= date
        {
            return Precondition::NotModified;
        }
        Precondition::Proceed {
            honour_range: self.if_range_holds(headers),
        }
    }

    /// Whether `tags` (a list of entity tags, or `*`) names this version: by strong
    /// comparison (both tags strong and equal) or by weak comparison (equal but for `W/`).
    fn any_tag(&self, tags: &str, strong: bool) -> bool {
        if tags.trim() == "*" {
            return true;
        }
        entity_tags(tags).any(|(weak, tag)| tag == self.etag && !(strong && weak))
    }

    /// Whether `If-Range`, when present, names this version: an entity tag by strong
    /// comparison, or exactly this `Last-Modified` date.
    fn if_range_holds(&self, headers: &HeaderMap) -> bool {
        let Some(value) = headers.get(header::IF_RANGE) else {
            return true;
        };
        let Ok(value) = value.to_str() else {
            return false;
        };
        let value = value.trim();
        if value.starts_with('"') || value.starts_with("W/") {
            let mut tags = entity_tags(value);
            matches!((tags.next(), tags.next()), (Some((false, tag)), None) if tag == self.etag)
        } else {
            httpdate::parse_http_date(value).is_ok_and(|d| d == self.modified)
        }
    }
}

/// The values of every `name` header joined with commas (a list split over several lines is
/// one list), or `None` when there is none; a value that is not text makes an empty list.
fn joined(headers: &HeaderMap, name: header::HeaderName) -> Option<String> {
    let mut values = headers.get_all(name).iter().peekable();
    values.peek()?;
    Some(
        values
            .map(|v: &HeaderValue| v.to_str().unwrap_or(""))
            .collect::<Vec<_>>()
            .join(","),
    )
}

/// The date of the `name` header, when there is exactly one that parses.
fn date(headers: &HeaderMap, name: header::HeaderName) -> Option<SystemTime> {
    let mut values = headers.get_all(name).iter();
    match (values.next(), values.next()) {
        (Some(v), None) => httpdate::parse_http_date(v.to_str().ok()?.trim()).ok(),
        _ => None,
    }
}

/// The entity tags of a comma-separated list, each as (weak, the tag in its quotes, without
/// `W/`);
/// the list ends at the first element that is not an entity tag.
fn entity_tags(list: &str) -> impl Iterator<Item = (bool, &str)> {
    let mut rest = list;
    std::iter::from_fn(move || {
        rest = rest.trim_start_matches([',', ' ', '\t']);
        let (weak, tail) = match rest.strip_prefix("W/") {
            Some(tail) => (true, tail),
            None => (false, rest),
        };
        let body = tail.strip_prefix('"')?;
        let end = body.find('"')?;
        let tag = &tail[..end + 2];
        rest = &body[end + 1..];
        Some((weak, tag))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn validator() -> Validator {
        let modified = UNIX_EPOCH + Duration::new(1_700_000_000, 123_456_789);
        Validator::new(1000, Some(modified), SystemTime::now())
    }

    fn with(pairs: &[(header::HeaderName, &str)]) -> HeaderMap {
        let mut headers = HeaderMap::new();
        for (name, value) in pairs {
            headers.append(name.clone(), HeaderValue::from_str(value).unwrap());
        }
        headers
    }

    #[test]
    fn the_etag_changes_with_the_size_and_the_nanoseconds() {
        let v = validator();
        assert_eq!(v.etag(), "\"3e8-17979cfe3d85cd15\"");
        assert_eq!(v.last_modified(), "Tue, 14 Nov 2023 22:13:20 GMT");
        let later = UNIX_EPOCH + Duration::new(1_700_000_000, 123_456_790);
        assert_ne!(
            Validator::new(1000, Some(later), SystemTime::now()).etag(),
            v.etag()
        );
        assert_ne!(
            Validator::new(1001, Some(later), SystemTime::now()).etag(),
            v.etag()
        );
    }

    #[test]
    fn preconditions_follow_rfc_9110_in_order() {
        use Precondition::*;
        let v = validator();
        let tag = v.etag().to_string();
        let weak = format!("W/{tag}");
        let date = v.last_modified();
        let earlier = "Tue, 14 Nov 2023 22:13:19 GMT";
        let plain = Proceed { honour_range: true };
        let whole = Proceed {
            honour_range: false,
        };
        let cases: Vec<(Vec<(header::HeaderName, &str)>, Precondition)> = vec![
            (vec![], plain),
            (vec![(header::IF_MATCH, &tag)], plain),
            (vec![(header::IF_MATCH, "*")], plain),
            (vec![(header::IF_MATCH, "\"a\", \"b\"")], Failed),
            (
                vec![(header::IF_MATCH, "\"a\""), (header::IF_MATCH, &tag)],
                plain,
            ),
            (vec![(header::IF_MATCH, &weak)], Failed),
            (vec![(header::IF_UNMODIFIED_SINCE, earlier)], Failed),
            (vec![(header::IF_UNMODIFIED_SINCE, &date)], plain),
            (vec![(header::IF_UNMODIFIED_SINCE, "not a date")], plain),
            // If-Match wins over If-Unmodified-Since.
            (
                vec![
                    (header::IF_MATCH, &tag),
                    (header::IF_UNMODIFIED_SINCE, earlier),
                ],
                plain,
            ),
            (vec![(header::IF_NONE_MATCH, &tag)], NotModified),
            (vec![(header::IF_NONE_MATCH, &weak)], NotModified),
            (vec![(header::IF_NONE_MATCH, "*")], NotModified),
            (vec![(header::IF_NONE_MATCH, "\"other\"")], plain),
            (vec![(header::IF_MODIFIED_SINCE, &date)], NotModified),
            (vec![(header::IF_MODIFIED_SINCE, earlier)], plain),
            // If-None-Match wins over If-Modified-Since.
            (
                vec![
                    (header::IF_NONE_MATCH, "\"other\""),
                    (header::IF_MODIFIED_SINCE, &date),
                ],
                plain,
            ),
            (
                vec![(header::IF_MATCH, "\"a\""), (header::IF_NONE_MATCH, &tag)],
                Failed,
            ),
            (vec![(header::IF_RANGE, &tag)], plain),
            (vec![(header::IF_RANGE, "\"other\"")], whole),
            (vec![(header::IF_RANGE, &weak)], whole),
            (vec![(header::IF_RANGE, &date)], plain),
            (vec![(header::IF_RANGE, earlier)], whole),
            (vec![(header::IF_RANGE, "garbage")], whole),
        ];
        for (headers, expected) in cases {
            assert_eq!(v.preconditions(&with(&headers)), expected, "{headers:?}");
        }
    }

    #[test]
    fn entity_tag_lists_keep_commas_inside_tags() {
        let tags: Vec<_> = entity_tags(" \"a,b\" ,W/\"c\",\"\"").collect();
        assert_eq!(tags, [(false, "\"a,b\""), (true, "\"c\""), (false, "\"\"")]);
        assert_eq!(entity_tags("junk, \"a\"").count(), 0);
        assert_eq!(entity_tags("\"open").count(), 0);
    }
}
