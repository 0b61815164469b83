//! A client pins the archive it opened. Over HTTP it sends the archive's `ETag` as `If-Match`
//! and compares every answer's `Content-Range` total and validators; from a file it compares
//! the file's size, modification time and identity when a read fails. An archive replaced,
//! rewritten or truncated under a reader stops it with "the archive at NAME changed while it
//! was read: reopen it", and `fly` exits non-zero saying so, or saying how many reads failed
//! their checksums when the archive stayed but its bytes were damaged.

use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use stripmask::Error;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::BuildOptions;
use stripmask::db::grid::TileId;
use stripmask::db::server::Server;
use stripmask::db::source::file::FileSource;
use stripmask::db::source::http::HttpSource;
use stripmask::db::source::throttle::LinkProfile;
use stripmask::db::source::{CancelToken, TileSource};

use crate::support::cli::{fly_quietly, stripmask};
use crate::support::hills::synthetic;

/// An archive of 8 x 8 tiles named `name`, its heights raised by `lift`, in `dir`.
fn hills(dir: &Path, name: &str, lift: f32) -> PathBuf {
    let options = BuildOptions {
        tile_size: 33,
        spacing: Some(30.0),
        texture_factor: 1,
        ..BuildOptions::default()
    };
    synthetic(dir, name, (257, 257), &options, |i, j| {
        lift + 300.0 + 200.0 * (i as f32 * 0.05).sin() * (j as f32 * 0.04).cos()
    })
}

/// Another build (heights raised) under `path`'s name, in a folder beside it, made before
/// it is needed so that putting it in place takes no time.
fn next_build(path: &Path) -> PathBuf {
    let dir = path.parent().unwrap().join("next");
    std::fs::create_dir_all(&dir).unwrap();
    hills(&dir, path.file_stem().unwrap().to_str().unwrap(), 1000.0)
}

/// Puts `next` at `path`, renamed into place as builds do (a new file under the old name).
fn replace(next: &Path, path: &Path) {
    std::fs::rename(next, path).unwrap();
}

/// Writes `next`'s bytes over `path` in place (the same file, new content).
fn overwrite(next: &Path, path: &Path) {
    std::fs::write(path, std::fs::read(next).unwrap()).unwrap();
}

fn assert_changed(e: Error, name: &str, says: &str) {
    match &e {
        Error::ArchiveChanged { name: n, what } => {
            assert_eq!(n, name);
            assert!(what.contains(says), "{what}");
        }
        other => panic!("{other:?}"),
    }
    let text = e.to_string();
    assert!(says_changed(&text, name), "{text}");
}

/// Whether `text` says that the archive at `name` changed, and what to do.
fn says_changed(text: &str, name: &str) -> bool {
    text.contains(&format!("the archive at {name} changed while it was read"))
        && text.contains("reopen it")
}

/// Level-0 tile `i` of the 8 x 8 tiles, row-major.
fn tile(i: u32) -> TileId {
    TileId::new(i % 8, i / 8)
}

/// Reads every level of level-0 tile `i`.
fn read<S: TileSource>(reader: &ArchiveReader<S>, i: u32) -> stripmask::Result<()> {
    let levels = reader.header().levels();
    reader.read_levels(tile(i), 0..levels).map(|_| ())
}

/// A server of `path` on 127.0.0.1.
fn served(path: &Path) -> Server {
    let loopback: SocketAddr = "127.0.0.1:0".parse().unwrap();
    Server::start(path, loopback, LinkProfile::default()).unwrap()
}

#[test]
fn an_http_reader_stops_when_the_served_archive_is_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills(dir.path(), "hills", 0.0);
    let server = served(&path);
    let url = server.url().to_string();
    let reader = ArchiveReader::open(HttpSource::new(&url)).unwrap();
    read(&reader, 0).unwrap();
    replace(&next_build(&path), &path);
    let e = read(&reader, 1).unwrap_err();
    assert_changed(e, &url, "412 to If-Match");
    // Pinned: every later read fails at once (no server needed), with what showed the change.
    drop(server);
    let e = read(&reader, 2).unwrap_err();
    assert_changed(e, &url, "412 to If-Match");
}

/// A server that ignores preconditions: `HEAD` answers say a file of `len` bytes with
/// `ETag: "a"`, and every range of it (zeros) is answered with a `Content-Range` total of
/// `total` and `etag`; its URL.
fn careless_server(len: usize, total: usize, etag: &'static str) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        for stream in listener.incoming().take(8) {
            let Ok(mut stream) = stream else { return };
            let mut reader = BufReader::new(stream.try_clone().unwrap());
            let mut lines = Vec::new();
            loop {
                let mut line = String::new();
                if reader.read_line(&mut line).unwrap_or(0) == 0 || line == "\r\n" {
                    break;
                }
                lines.push(line.to_ascii_lowercase());
            }
            let answer = if lines.first().is_some_and(|l| l.starts_with("head")) {
                format!(
                    "HTTP/1.1 200 OK\r\nContent-Length: {len}\r\nETag: \"a\"\r\nConnection: close\r\n\r\n"
                )
            } else {
                let range = lines
                    .iter()
                    .find_map(|l| l.strip_prefix("range: bytes="))
                    .unwrap_or("0-0");
                let (a, b) = range.trim().split_once('-').unwrap();
                let (a, b): (usize, usize) = (a.parse().unwrap(), b.parse().unwrap());
                let body = "\0".repeat(b + 1 - a);
                format!(
                    "HTTP/1.1 206 Partial Content\r\nContent-Length: {}\r\n\
                     Content-Range: bytes {a}-{b}/{total}\r\nETag: {etag}\r\n\
                     Connection: close\r\n\r\n{body}",
                    body.len()
                )
            };
            let _ = stream.write_all(answer.as_bytes());
        }
    });
    format!("http://{addr}/x.smdb")
}

#[test]
fn an_http_source_compares_every_answer_with_the_archive_it_opened() {
    // The total size in Content-Range changed.
    let url = careless_server(1000, 900, "\"a\"");
    let source = HttpSource::new(&url);
    assert_eq!(source.size().unwrap(), 1000);
    let e = source.read_range(0, 10).unwrap_err();
    assert_changed(e, &url, "its size went from 1000 to 900 bytes");
    assert_changed(source.read_range(0, 10).unwrap_err(), &url, "1000 to 900");

    // The ETag changed.
    let url = careless_server(1000, 1000, "\"b\"");
    let source = HttpSource::new(&url);
    source.size().unwrap();
    let e = source.read_range(0, 10).unwrap_err();
    assert_changed(e, &url, "its ETag went from \"a\" to \"b\"");

    // The same archive: nothing to say.
    let url = careless_server(1000, 1000, "\"a\"");
    let source = HttpSource::new(&url);
    source.size().unwrap();
    assert_eq!(source.read_range(5, 10).unwrap(), vec![0; 10]);
}

#[test]
fn a_file_reader_stops_when_its_archive_is_rewritten_or_truncated_in_place() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills(dir.path(), "hills", 0.0);
    let name = path.display().to_string();

    let next = next_build(&path);
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    read(&reader, 0).unwrap();
    overwrite(&next, &path);
    // Some tile's bytes are now another build's: its checksum fails, and the source sees why.
    let e = (0..64)
        .find_map(|i| read(&reader, i).err())
        .expect("a tile of the other build passed the checksums of this one");
    assert_changed(e, &name, "");
    assert!(matches!(
        read(&reader, 0),
        Err(Error::ArchiveChanged { .. })
    ));

    let path = hills(dir.path(), "short", 0.0);
    let name = path.display().to_string();
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let len = std::fs::metadata(&path).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(len / 2)
        .unwrap();
    let e = (0..64)
        .rev()
        .find_map(|i| read(&reader, i).err())
        .expect("a tile in the half cut off");
    assert_changed(
        e,
        &name,
        &format!("its size went from {len} to {} bytes", len / 2),
    );
}

#[test]
fn a_damaged_file_that_did_not_change_fails_its_checksum_as_before() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills(dir.path(), "hills", 0.0);
    let offset = {
        let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
        reader.entry(tile(3), &CancelToken::new()).unwrap().0.offset
    };
    // Damaged before it is opened: this archive is the one the reader pins.
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[offset as usize] ^= 0x55;
    std::fs::write(&path, bytes).unwrap();
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    match read(&reader, 3) {
        Err(Error::Checksum { tile: t, .. }) => assert_eq!(t, tile(3).to_string()),
        other => panic!("{other:?}"),
    }
    read(&reader, 2).unwrap();
}

/// `fly SOURCE` for 8 s over a link of 300 ms a request, keeping every frame: the process,
/// and the folder its first frame appears in.
fn slow_fly(source: &str, out: &Path) -> (Child, PathBuf) {
    let child = stripmask()
        .args([
            "fly",
            source,
            "--seconds",
            "8",
            "--every",
            "1",
            "--no-plots",
            "--quiet",
        ])
        .args(["--size", "64x48", "--latency-ms", "300", "--out"])
        .arg(out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    (child, out.join("frames"))
}

/// Waits for the flight's first frame: its engine has opened the archive.
fn first_frame(frames: &Path, child: &mut Child) {
    let started = Instant::now();
    loop {
        let any = std::fs::read_dir(frames)
            .map(|mut d| d.next().is_some())
            .unwrap_or(false);
        if any {
            return;
        }
        if started.elapsed() > Duration::from_secs(60) || child.try_wait().unwrap().is_some() {
            let _ = child.kill();
            panic!("the flight drew no frame");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The exit code, stdout and stderr of the flight, which must end within a minute.
fn ended(mut child: Child) -> (Option<i32>, String, String) {
    let started = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("the flight did not end");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let output = child.wait_with_output().unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// Flies from `source` slowly, makes `change` once the first frame is drawn, and checks that
/// the flight then exits 1 saying that the archive at `source` changed.
fn fly_through_a_change(source: &str, out: &Path, change: impl FnOnce()) {
    let (mut child, frames) = slow_fly(source, out);
    first_frame(&frames, &mut child);
    change();
    let (code, _, err) = ended(child);
    assert_eq!(code, Some(1), "{err}");
    assert!(says_changed(&err, source), "{err}");
}

#[test]
fn fly_over_http_stops_with_an_error_when_the_archive_is_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills(dir.path(), "hills", 0.0);
    let server = served(&path);
    let next = next_build(&path);
    fly_through_a_change(server.url(), &dir.path().join("run"), || {
        replace(&next, &path)
    });
}

#[test]
fn fly_from_a_file_stops_with_an_error_when_the_archive_is_rewritten() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills(dir.path(), "hills", 0.0);
    let next = next_build(&path);
    fly_through_a_change(path.to_str().unwrap(), &dir.path().join("run"), || {
        overwrite(&next, &path)
    });
}

#[test]
fn fly_says_how_many_reads_failed_their_checksums_and_exits_non_zero() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills(dir.path(), "hills", 0.0);
    // The last byte of the top, the root and the levels under it, which every flight reads
    // first.
    let header = ArchiveReader::open(FileSource::open(&path).unwrap())
        .unwrap()
        .header()
        .clone();
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[(header.top_offset + header.top_len - 1) as usize] ^= 0x55;
    std::fs::write(&path, bytes).unwrap();
    let out = dir.path().join("run");
    let (code, err, _) = fly_quietly(
        path.to_str().unwrap(),
        &out,
        &["--clock", "simulated", "--frames", "30"],
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains(path.to_str().unwrap()) && err.contains("failed their checksums"),
        "{err}"
    );
    let refused: u64 = err
        .split(": ")
        .find_map(|part| part.split(" read(s) of tiles").next()?.trim().parse().ok())
        .unwrap_or_else(|| panic!("no count in {err}"));
    assert!(refused >= 1, "{err}");
}
