//! `build` never loses or corrupts an archive, and refuses up front what a reader would refuse:
//! two builds to one path at once, an output that is a directory, numbers no reader accepts,
//! tile counts and index sizes over the reader's limits, and headers claiming more samples than
//! their file holds.

use std::path::{Path, PathBuf};
use std::sync::Barrier;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use stripmask::Error;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{DemInfo, DemReader, MemoryReader, NodataFill};
use stripmask::db::source::file::FileSource;

use crate::support::cli::stripmask;

fn dem(name: &str, side: usize, lift: f32) -> NodataFill<MemoryReader> {
    let samples = (0..side * side)
        .map(|k| ((k % side) as f32 * 0.3).sin() * 50.0 + lift)
        .collect();
    NodataFill::new(MemoryReader::new(name, side, side, samples).unwrap(), None)
}

fn small() -> BuildOptions {
    BuildOptions {
        tile_size: 17,
        ..BuildOptions::default()
    }
}

/// A DEM that only claims its size: reading a row of it is a failure of the test.
struct Claim {
    info: DemInfo,
    rows_read: &'static AtomicUsize,
}

impl DemReader for Claim {
    fn info(&self) -> &DemInfo {
        &self.info
    }
    fn read_row(&mut self, row: &mut [f32]) -> stripmask::Result<()> {
        self.rows_read.fetch_add(1, Ordering::Relaxed);
        row.fill(0.0);
        Ok(())
    }
}

fn claim(width: usize, height: usize, rows_read: &'static AtomicUsize) -> NodataFill<Claim> {
    let info = DemInfo::new("claim.raw", width, height);
    NodataFill::new(Claim { info, rows_read }, None)
}

fn leftovers(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".partial"))
        .collect()
}

#[test]
fn two_builds_to_one_path_at_once_leave_one_whole_archive() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.smdb");
    // Both builds have created their output before either writes a tile.
    let both_started = Barrier::new(2);
    let run = |lift: f32| {
        let waited = AtomicBool::new(false);
        let progress = |_: usize, _: usize| {
            if !waited.swap(true, Ordering::Relaxed) {
                both_started.wait();
            }
        };
        build(dem("x", 97, lift), &out, &small(), &progress)
    };
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(|| run(0.0));
        let b = s.spawn(|| run(1000.0));
        (a.join().unwrap(), b.join().unwrap())
    });
    assert!(a.is_ok() && b.is_ok(), "{a:?} {b:?}");
    let reader = ArchiveReader::open(FileSource::open(&out).unwrap()).unwrap();
    let report = reader.check().unwrap();
    assert_eq!(report.tiles, reader.pyramid().tile_count());
    let low = reader.header().min_height;
    assert!(
        !(-40.0..=900.0).contains(&low),
        "one build's heights: {low}"
    );
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );
}

#[test]
fn an_output_that_is_a_directory_is_refused_before_any_tile() {
    let dir = tempfile::tempdir().unwrap();
    let tiles = AtomicUsize::new(0);
    let e = build(dem("d", 97, 0.0), dir.path(), &small(), &|done, _| {
        tiles.store(done, Ordering::Relaxed)
    })
    .unwrap_err();
    assert_eq!(tiles.load(Ordering::Relaxed), 0, "built before refusing");
    let e = e.to_string();
    assert!(e.contains("directory"), "{e}");
    assert!(leftovers(dir.path()).is_empty());
}

#[test]
fn numbers_no_reader_accepts_are_refused_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("n.smdb");
    let cases = [
        BuildOptions {
            origin: Some((f64::NAN, 0.0)),
            ..small()
        },
        BuildOptions {
            origin: Some((0.0, f64::INFINITY)),
            ..small()
        },
        BuildOptions {
            origin: Some((1e300, 0.0)),
            ..small()
        },
        BuildOptions {
            spacing: Some(1e307),
            ..small()
        },
        BuildOptions {
            vertical_scale: 1e300,
            ..small()
        },
    ];
    for options in cases {
        let e = build(dem("n", 33, 0.0), &out, &options, &|_, _| {});
        assert!(e.is_err(), "{options:?} built");
        assert!(!out.exists());
        assert!(leftovers(dir.path()).is_empty());
    }
}

#[test]
fn tile_counts_over_the_formats_limits_are_refused_unread() {
    static ROWS: AtomicUsize = AtomicUsize::new(0);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.smdb");
    // 2^26 samples across in 3-sample tiles: 2^25 tiles, more than a level may have across.
    let three = BuildOptions {
        tile_size: 3,
        ..BuildOptions::default()
    };
    let e = build(claim(1 << 26, 3, &ROWS), &out, &three, &|_, _| {}).unwrap_err();
    assert!(
        e.to_string().contains("tiles") && e.to_string().contains("16777216"),
        "{e}"
    );
    assert_eq!(ROWS.load(Ordering::Relaxed), 0);
    assert!(!out.exists() && leftovers(dir.path()).is_empty());
}

#[test]
fn a_tile_far_larger_than_the_dem_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let options = BuildOptions {
        tile_size: 4097,
        ..BuildOptions::default()
    };
    let samples = vec![1.0, 2.0, 3.0, 4.0];
    let reader = NodataFill::new(MemoryReader::new("2x2", 2, 2, samples).unwrap(), None);
    match build(reader, &dir.path().join("t.smdb"), &options, &|_, _| {}) {
        Err(Error::InvalidSetting { name, .. }) => assert_eq!(name, "tile size"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn ascii_grids_claiming_more_than_they_hold_or_an_infinite_corner_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.smdb");
    let bomb = dir.path().join("bomb.asc");
    std::fs::write(&bomb, "ncols 1048576\nnrows 1048576\n").unwrap();
    let far = dir.path().join("far.asc");
    std::fs::write(
        &far,
        "ncols 3\nnrows 3\nxllcorner 1e309\nyllcorner 0\ncellsize 30\n1 2 3\n4 5 6\n7 8 9\n",
    )
    .unwrap();
    for (input, says) in [(&bomb, "claims"), (&far, "far.asc")] {
        let o = stripmask()
            .args(["build", "--quiet", "--tile-size", "3", "-o"])
            .arg(&out)
            .arg(input)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{input:?} built");
        assert!(err.contains(says), "{err}");
        assert!(!out.exists() && leftovers(dir.path()).is_empty());
    }
}

#[cfg(target_os = "linux")]
#[test]
fn a_build_removes_what_killed_builds_of_its_output_left_and_nothing_else() {
    use stripmask::db::archive::partial::partial_path;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.smdb");
    // A process that has ended (spawned and reaped), and one that runs.
    let mut ended = std::process::Command::new("true").spawn().unwrap();
    ended.wait().unwrap();
    let mut running = std::process::Command::new("sleep")
        .arg("60")
        .spawn()
        .unwrap();
    let stale = partial_path(&out, ended.id(), 0).unwrap();
    let live = partial_path(&out, running.id(), 3).unwrap();
    let other = partial_path(&dir.path().join("y.smdb"), ended.id(), 0).unwrap();
    for p in [&stale, &live, &other] {
        std::fs::write(p, b"half an archive").unwrap();
    }
    let report = build(dem("x", 33, 0.0), &out, &small(), &|_, _| {}).unwrap();
    let _ = running.kill();
    let _ = running.wait();
    assert!(!stale.exists(), "the killed build's file is removed");
    assert!(live.exists(), "a running build's file stays");
    assert!(other.exists(), "another output's file stays");
    assert!(
        report
            .notes
            .iter()
            .any(|n| n.contains(&stale.display().to_string())),
        "{:?}",
        report.notes
    );
    ArchiveReader::open(FileSource::open(&out).unwrap()).unwrap();
}

#[test]
fn an_output_that_is_the_input_is_refused_before_reading_through_any_path_or_link() {
    let dir = tempfile::tempdir().unwrap();
    let fixture = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/plain.asc");
    let input = dir.path().join("in.asc");
    std::fs::copy(&fixture, &input).unwrap();
    let original = std::fs::read(&input).unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let mut outputs = vec![
        input.clone(),
        dir.path().join("sub/../in.asc"),
        dir.path().join("./in.asc"),
    ];
    #[cfg(unix)]
    {
        let symlink = dir.path().join("link.smdb");
        std::os::unix::fs::symlink(&input, &symlink).unwrap();
        let hard = dir.path().join("hard.smdb");
        std::fs::hard_link(&input, &hard).unwrap();
        outputs.extend([symlink, hard]);
    }
    for output in &outputs {
        let (code, err) = build_into(output, &input, None);
        assert_eq!(code, Some(1), "{output:?}: {err}");
        assert!(
            err.contains(&format!(
                "{} is the build's input {}",
                output.display(),
                input.display()
            )),
            "{err}"
        );
        assert_eq!(std::fs::read(&input).unwrap(), original, "{output:?}");
        assert!(leftovers(dir.path()).is_empty());
    }
    // The texture image is read too.
    let texture = dir.path().join("texture.png");
    image::RgbImage::new(8, 8).save(&texture).unwrap();
    let (code, err) = build_into(&texture, &input, Some(&texture));
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("is the build's texture"), "{err}");
    // Another output beside the input builds.
    let (code, err) = build_into(&dir.path().join("in.smdb"), &input, None);
    assert_eq!(code, Some(0), "{err}");
}

/// `stripmask build INPUT -o OUTPUT` (with a texture image): its exit code and stderr.
fn build_into(output: &Path, input: &Path, texture: Option<&Path>) -> (Option<i32>, String) {
    let mut command = stripmask();
    command.args(["build", "--quiet", "--tile-size", "17", "-o"]);
    command.arg(output).arg(input);
    if let Some(texture) = texture {
        command.arg("--texture").arg(texture);
    }
    let o = command.output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A build whose writes fail once the file passes a size (`ulimit -f`, with the signal that
/// would kill it ignored) fails while finishing, after every tile was written: it removes its
/// temporary file and leaves no output.
#[cfg(unix)]
#[test]
fn a_build_that_fails_while_finishing_leaves_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let fixture = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/plain.asc");
    let out = dir.path().join("x.smdb");
    let script = "trap '' XFSZ; ulimit -f 1; exec \"$0\" \"$@\"";
    let o = std::process::Command::new("sh")
        .args(["-c", script, env!("CARGO_BIN_EXE_stripmask")])
        .args(["build", "--quiet", "--tile-size", "17", "-o"])
        .arg(&out)
        .arg(&fixture)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains(".partial") && err.contains("too large"),
        "{err}"
    );
    assert!(!out.exists());
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );
}
