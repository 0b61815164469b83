//! The archive behind a real static server: nginx, started on 127.0.0.1 from a generated config,
//! serves a built archive; `info --check` and a short flight read it through nginx, and a
//! reader notices a new build put in its place. Skipped, with
//! a message, when nginx is not installed (`.ci/run` installs it).

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use stripmask::Error;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::grid::TileId;
use stripmask::db::source::http::HttpSource;

use crate::support::cli::{plain_archive, stripmask};

/// The nginx binary, from PATH or its Debian place.
fn nginx() -> Option<PathBuf> {
    let on_path = std::env::var_os("PATH").into_iter().flat_map(|p| {
        std::env::split_paths(&p)
            .map(|d| d.join("nginx"))
            .collect::<Vec<_>>()
    });
    on_path
        .chain([PathBuf::from("/usr/sbin/nginx")])
        .find(|p| p.is_file())
}

/// nginx in the foreground, stopped when dropped.
struct Nginx(Child);

impl Drop for Nginx {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A config serving `root` on 127.0.0.1:`port`, everything under `dir` (no system paths).
fn config(dir: &Path, root: &Path, port: u16) -> String {
    let d = dir.display();
    format!(
        "daemon off;\n\
         master_process off;\n\
         worker_processes 1;\n\
         pid {d}/nginx.pid;\n\
         error_log {d}/error.log warn;\n\
         events {{ worker_connections 64; }}\n\
         http {{\n\
             access_log off;\n\
             client_body_temp_path {d}/body;\n\
             proxy_temp_path {d}/proxy;\n\
             fastcgi_temp_path {d}/fastcgi;\n\
             uwsgi_temp_path {d}/uwsgi;\n\
             scgi_temp_path {d}/scgi;\n\
             default_type application/octet-stream;\n\
             server {{\n\
                 listen 127.0.0.1:{port};\n\
                 root {};\n\
             }}\n\
         }}\n",
        root.display()
    )
}

#[test]
fn an_archive_served_by_nginx_checks_and_flies() {
    let Some(nginx) = nginx() else {
        eprintln!("nginx is not installed: skipping the test of an archive behind nginx");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("www");
    std::fs::create_dir(&root).unwrap();
    plain_archive(&root.join("plain.smdb"));

    // A free port: bound, then let go for nginx.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let conf = dir.path().join("nginx.conf");
    std::fs::write(&conf, config(dir.path(), &root, port)).unwrap();
    let _server = Nginx(
        Command::new(&nginx)
            .arg("-c")
            .arg(&conf)
            .arg("-p")
            .arg(dir.path())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let deadline = Instant::now() + Duration::from_secs(10);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        let log = std::fs::read_to_string(dir.path().join("error.log")).unwrap_or_default();
        assert!(Instant::now() < deadline, "nginx did not start: {log}");
        std::thread::sleep(Duration::from_millis(50));
    }
    let url = format!("http://127.0.0.1:{port}/plain.smdb");

    let info = stripmask()
        .args(["info", "--json", "--check", &url])
        .output()
        .unwrap();
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    // 3 x 2 tiles, 2 x 1 above them, and the root.
    assert_eq!(v["check"]["tiles"], 9);

    let out = dir.path().join("fly");
    let fly = stripmask()
        .args([
            "fly",
            &url,
            "--quiet",
            "--no-plots",
            "--frames",
            "20",
            "--every",
            "0",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        fly.status.success(),
        "{}",
        String::from_utf8_lossy(&fly.stderr)
    );
    let stats = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    assert_eq!(stats.lines().count(), 21, "a header and 20 frames");

    // nginx's validators pin the archive too: a reader opened before a new build (larger by a
    // few bytes, so that its ETag differs even within the same second) is renamed into place
    // stops with the change named.
    let reader = ArchiveReader::open(HttpSource::new(&url)).unwrap();
    let next = dir.path().join("plain.smdb");
    plain_archive(&next);
    let mut bytes = std::fs::read(&next).unwrap();
    bytes.extend_from_slice(b"a newer build");
    std::fs::write(&next, bytes).unwrap();
    std::fs::rename(&next, root.join("plain.smdb")).unwrap();
    let levels = reader.header().levels();
    match reader.read_levels(TileId::new(0, 0), 0..levels) {
        Err(Error::ArchiveChanged { name, what }) => {
            assert_eq!(name, url);
            assert!(what.contains("412"), "{what}");
        }
        other => panic!("{other:?}"),
    }
}
