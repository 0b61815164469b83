//! The answers about the one archive served: its paths, its methods, its validators and
//! conditional requests, and byte ranges.

use std::fs::{File, Metadata};
use std::future::Ready;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::SystemTime;

use hyper::body::Incoming;
use hyper::header::{self, HeaderValue};
use hyper::service::Service;
use hyper::{Method, Request, Response, StatusCode};

use super::body::{Answer, Body, text};
use super::range::{RangeRequest, parse_range};
use super::validator::{Precondition, Validator};

/// The archive as a service: `GET` and `HEAD` of `/` and `/<file name>`.
pub(super) struct Archive {
    path: PathBuf,
    url_path: String,
    /// The file last opened and what identifies it, kept while the path names that file.
    open: Mutex<Option<(Identity, Arc<File>)>>,
}

/// What tells one file at the archive's path from another: the device and inode on unix, the
/// size and modification time elsewhere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Identity(u64, u128);

impl Identity {
    #[cfg(unix)]
    fn of(meta: &Metadata) -> Self {
        use std::os::unix::fs::MetadataExt;
        Identity(meta.dev(), u128::from(meta.ino()))
    }

    #[cfg(not(unix))]
    fn of(meta: &Metadata) -> Self {
        let modified = meta
            .modified()
            .ok()
            .and_then(|m| m.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos());
        Identity(meta.len(), modified)
    }
}

impl Archive {
    /// The archive at `path`, served at `url_path`.
    pub(super) fn new(path: PathBuf, url_path: String) -> Self {
        Archive {
            path,
            url_path,
            open: Mutex::new(None),
        }
    }

    /// The archive as it is now: the file at its path (opened again only when the path names
    /// another file) and its metadata, taken from the open file when it is new, so that the
    /// validator describes the bytes sent.
    fn current(&self) -> std::io::Result<(Arc<File>, Metadata)> {
        let meta = std::fs::metadata(&self.path)?;
        let identity = Identity::of(&meta);
        let mut open = self.open.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((known, file)) = open.as_ref()
            && *known == identity
        {
            return Ok((Arc::clone(file), meta));
        }
        let file = Arc::new(File::open(&self.path)?);
        let meta = file.metadata()?;
        *open = Some((Identity::of(&meta), Arc::clone(&file)));
        Ok((file, meta))
    }

    /// The answer to `request`.
    fn answer(&self, request: &Request<Incoming>) -> Response<Body> {
        let head = request.method() == Method::HEAD;
        let path = request.uri().path();
        if path != "/" && path != self.url_path {
            return text(StatusCode::NOT_FOUND, "not found\n", head);
        }
        if request.method() != Method::GET && !head {
            let mut answer = text(StatusCode::METHOD_NOT_ALLOWED, "only GET and HEAD\n", head);
            answer
                .headers_mut()
                .insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
            return answer;
        }
        let Ok((file, meta)) = self.current() else {
            return text(
                StatusCode::INTERNAL_SERVER_ERROR,
                "archive unreadable\n",
                head,
            );
        };
        let len = meta.len();
        let validator = Validator::new(len, meta.modified().ok(), SystemTime::now());
        let honour_range = match validator.preconditions(request.headers()) {
            Precondition::Failed => {
                let answer = text(
                    StatusCode::PRECONDITION_FAILED,
                    "the archive is not the version asked for\n",
                    head,
                );
                return described(answer, &validator);
            }
            Precondition::NotModified => {
                let mut answer = Response::new(Body::Empty);
                *answer.status_mut() = StatusCode::NOT_MODIFIED;
                return described(answer, &validator);
            }
            Precondition::Proceed { honour_range } => honour_range,
        };
        // Range applies to GET only (RFC 9110 section 14.2): HEAD describes the whole file.
        let range = match request.headers().get(header::RANGE) {
            Some(value) if honour_range && !head => value
                .to_str()
                .map_or(RangeRequest::Whole, |v| parse_range(v, len)),
            _ => RangeRequest::Whole,
        };
        let (status, first, count) = match range {
            RangeRequest::Unsatisfiable => {
                let mut answer = text(
                    StatusCode::RANGE_NOT_SATISFIABLE,
                    "range not satisfiable\n",
                    head,
                );
                answer.headers_mut().insert(
                    header::CONTENT_RANGE,
                    HeaderValue::from_str(&format!("bytes */{len}")).expect("ASCII"),
                );
                return described(answer, &validator);
            }
            RangeRequest::Whole => (StatusCode::OK, 0, len),
            RangeRequest::Part(a, b) => (StatusCode::PARTIAL_CONTENT, a, b - a + 1),
        };
        let body = if head {
            Body::Empty
        } else {
            Body::file(file, first, count)
        };
        let mut answer = Response::new(body);
        *answer.status_mut() = status;
        let headers = answer.headers_mut();
        headers.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/octet-stream"),
        );
        headers.insert(header::CONTENT_LENGTH, HeaderValue::from(count));
        if status == StatusCode::PARTIAL_CONTENT {
            let range = format!("bytes {first}-{}/{len}", first + count - 1);
            headers.insert(
                header::CONTENT_RANGE,
                HeaderValue::from_str(&range).expect("ASCII"),
            );
        }
        described(answer, &validator)
    }
}

/// `answer` with the archive's validators and `Accept-Ranges`.
fn described(mut answer: Response<Body>, validator: &Validator) -> Response<Body> {
    let headers = answer.headers_mut();
    headers.insert(
        header::ETAG,
        HeaderValue::from_str(validator.etag()).expect("ASCII"),
    );
    headers.insert(
        header::LAST_MODIFIED,
        HeaderValue::from_str(&validator.last_modified()).expect("ASCII"),
    );
    headers.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
    answer
}

impl Service<Request<Incoming>> for Archive {
    type Response = Response<Body>;
    type Error = std::convert::Infallible;
    type Future = Ready<Answer>;

    /// Answers at once: looking at the file's metadata takes microseconds, and its bytes are
    /// read by the body on the blocking threads.
    fn call(&self, request: Request<Incoming>) -> Self::Future {
        std::future::ready(Ok(self.answer(&request)))
    }
}
