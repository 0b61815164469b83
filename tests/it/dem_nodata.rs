//! Nodata in real grids: a border row of nodata, holes filled from the nearest valid samples in
//! 2-D, large nodata areas flat, and heights reported from valid data only.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

fn stripmask() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stripmask"))
}

/// Writes an ESRI ASCII grid of `w x h` samples (`None` = nodata, written as -9999).
fn write_asc(path: &Path, w: usize, h: usize, sample: impl Fn(usize, usize) -> Option<f32>) {
    let mut text = format!(
        "ncols {w}\nnrows {h}\nxllcorner 500000\nyllcorner 4000000\ncellsize 30\nNODATA_value -9999\n"
    );
    for j in 0..h {
        for i in 0..w {
            let v = sample(i, j).unwrap_or(-9999.0);
            write!(text, "{v} ").unwrap();
        }
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

/// Builds `input` with the command, returning its text summary and `info --json`.
fn build_and_info(input: &Path, out: &Path) -> (String, serde_json::Value) {
    let o = stripmask()
        .args(["build", "--tile-size", "17", "-o"])
        .arg(out)
        .arg(input)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let info = stripmask()
        .args(["info", "--json"])
        .arg(out)
        .output()
        .unwrap();
    assert!(info.status.success());
    (
        String::from_utf8(o.stdout).unwrap(),
        serde_json::from_slice(&info.stdout).unwrap(),
    )
}

#[test]
fn a_nodata_first_row_is_filled_and_heights_come_from_valid_data() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("border.asc");
    // Valid heights 141 ..= 141 + 2 * 32 + 32 m; the whole first row is nodata.
    write_asc(&input, 33, 33, |i, j| {
        (j > 0).then_some(141.0 + 2.0 * i as f32 + j as f32 - 1.0)
    });
    let (text, info) = build_and_info(&input, &dir.path().join("border.smdb"));
    assert_eq!(info["header"]["min_height"], 141.0, "{text}");
    assert_eq!(info["header"]["max_height"], 141.0 + 64.0 + 31.0);
    assert!(text.contains("141 .. 236 m (valid samples)"), "{text}");
    assert!(text.contains("33 samples filled"), "{text}");
}

#[test]
fn a_large_nodata_area_is_flat_at_the_lowest_height_around_it() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("lake.asc");
    // A 100-sample square of nodata inside a slope: its centre is far from any valid sample.
    let (n, lake) = (129, 14..114);
    write_asc(&input, n, n, |i, j| {
        (!(lake.contains(&i) && lake.contains(&j))).then_some(500.0 + 3.0 * j as f32 + i as f32)
    });
    let out = dir.path().join("lake.smdb");
    let (text, info) = build_and_info(&input, &out);
    assert_eq!(info["header"]["min_height"], 500.0);
    assert!(text.contains("drawn flat"), "{text}");
    let reader = stripmask::ArchiveReader::open(
        stripmask::db::source::file::FileSource::open(&out).unwrap(),
    )
    .unwrap();
    // Sample (64, 64) is 50 samples from the nearest valid one, and no valid sample lies within
    // 32 columns of it in the rows within 32 of it: it takes the lowest valid height of those
    // rows (row 32, column 0), not 0 m and not the value of one arbitrary edge.
    let centre = reader.tile(4, 4).unwrap().height(0, 0);
    let lowest_around = 500.0 + 3.0 * 32.0;
    assert!(
        (centre - lowest_around).abs() < 0.1,
        "{centre} vs {lowest_around}"
    );
}
