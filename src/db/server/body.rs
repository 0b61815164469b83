//! The bodies of the server's answers: nothing, a short text, or a range of the archive read a
//! piece at a time, when the connection can take it, so that memory per answer stays at one
//! piece whatever the range's length.

use std::convert::Infallible;
use std::fs::File;
use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};

use bytes::Bytes;
use http_body::{Frame, SizeHint};
use hyper::header::{self, HeaderValue};
use hyper::{Response, StatusCode};

use crate::db::source::file::read_at;

/// The most of the archive read at once for an answer.
pub(super) const PIECE: u64 = 64 * 1024;

/// An answer's body.
pub(super) enum Body {
    /// No body: a `HEAD` answer, a `304`.
    Empty,
    /// A short text, sent in one frame.
    Text(Option<Bytes>),
    /// Bytes `next .. end` of the archive.
    File(FileRange),
}

/// A range of the archive still to send.
pub(super) struct FileRange {
    file: Arc<File>,
    next: u64,
    end: u64,
}

impl Body {
    /// Bytes `first .. first + len` of `file`.
    pub(super) fn file(file: Arc<File>, first: u64, len: u64) -> Body {
        Body::File(FileRange {
            file,
            next: first,
            end: first + len,
        })
    }
}

impl http_body::Body for Body {
    type Data = Bytes;
    type Error = io::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        _: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, io::Error>>> {
        match self.get_mut() {
            Body::Empty => Poll::Ready(None),
            Body::Text(text) => Poll::Ready(text.take().map(|t| Ok(Frame::data(t)))),
            Body::File(range) => Poll::Ready(range.next_piece()),
        }
    }

    fn is_end_stream(&self) -> bool {
        match self {
            Body::Empty => true,
            Body::Text(text) => text.is_none(),
            Body::File(range) => range.next >= range.end,
        }
    }

    fn size_hint(&self) -> SizeHint {
        SizeHint::with_exact(match self {
            Body::Empty => 0,
            Body::Text(text) => text.as_ref().map_or(0, |t| t.len() as u64),
            Body::File(range) => range.end - range.next,
        })
    }
}

impl FileRange {
    /// The next piece, read on the runtime's thread: from the page cache that takes
    /// microseconds, less than handing the read to another thread and back (which costs a
    /// fifth of the requests per second on loopback); a read from a cold disk holds one worker
    /// for the disk's time. A file that shrank under the answer ends it with an error, so
    /// that the connection closes rather than break the promised length.
    fn next_piece(&mut self) -> Option<io::Result<Frame<Bytes>>> {
        if self.next >= self.end {
            return None;
        }
        let mut piece = vec![0; (self.end - self.next).min(PIECE) as usize];
        if let Err(e) = read_at(&self.file, &mut piece, self.next) {
            return Some(Err(e));
        }
        self.next += piece.len() as u64;
        Some(Ok(Frame::data(Bytes::from(piece))))
    }
}

/// A short plain-text answer (no body for a `HEAD` request), with `Content-Length`.
pub(super) fn text(status: StatusCode, text: &'static str, head: bool) -> Response<Body> {
    let body = if head {
        Body::Empty
    } else {
        Body::Text(Some(Bytes::from_static(text.as_bytes())))
    };
    let mut response = Response::new(body);
    *response.status_mut() = status;
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; charset=utf-8"),
    );
    headers.insert(header::CONTENT_LENGTH, HeaderValue::from(text.len()));
    response
}

/// The result type of the server's services, which never fail: every problem is an answer.
pub(super) type Answer<B = Body> = Result<Response<B>, Infallible>;
