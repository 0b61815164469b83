//! Nodata in real grids: a border row of nodata, holes filled from the nearest valid samples in
//! 2-D, large nodata areas flat, and heights reported from valid data only; the archive records
//! how many samples were made up, and `info` says so.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;
use stripmask::db::grid::TileId;

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
    // The tiles of samples 64 ..= 96 are all nodata: absent at level 0 and level 1, they cost
    // nothing; the level-2 tile over them holds the fill of the nodata it covers.
    assert!(reader.tile(TileId::new(4, 4)).unwrap().is_none());
    assert!(reader.tile(TileId::at(1, 2, 2)).unwrap().is_none());
    assert!(
        info["header"]["absent_tiles"].as_u64().unwrap() >= 16,
        "{text}"
    );
    // Sample (64, 64) is 50 samples from the nearest valid one, and no valid sample lies within
    // 32 columns of it in the rows within 32 of it: it takes the lowest valid height of those
    // rows (row 32, column 0), not 0 m and not the value of one arbitrary edge.
    let centre = reader
        .tile(TileId::at(2, 1, 1))
        .unwrap()
        .unwrap()
        .height(0, 0);
    let lowest_around = 500.0 + 3.0 * 32.0;
    assert!(
        (centre - lowest_around).abs() < 0.1,
        "{centre} vs {lowest_around}"
    );
}

#[test]
fn the_archive_records_the_nodata_filled_and_flattened_and_info_prints_it() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rows_and_lake.asc");
    // Three rows of nodata in the north, and a 100 x 100 nodata lake far from any valid sample
    // at its centre.
    let (n, rows, lake) = (129, 3, 14..114);
    write_asc(&input, n, n, |i, j| {
        (j >= rows && !(lake.contains(&i) && lake.contains(&j)))
            .then_some(500.0 + 3.0 * j as f32 + i as f32)
    });
    let out = dir.path().join("rows_and_lake.smdb");
    let (text, info) = build_and_info(&input, &out);
    let header = &info["header"];
    let filled = header["nodata_filled"].as_u64().unwrap();
    let flattened = header["nodata_flattened"].as_u64().unwrap();
    assert_eq!(
        filled + flattened,
        (rows * n + 100 * 100) as u64,
        "{header}"
    );
    // The lake's centre is more than the fill radius from any valid sample; the rows are not.
    assert!(
        flattened > 0 && filled > (rows * n) as u64,
        "{filled} {flattened}"
    );
    assert_eq!(header["min_height"], 500.0 + 3.0 * rows as f64);
    let line = format!(
        "{filled} samples filled from their nearest valid neighbours, {flattened} in large \
         nodata areas drawn flat"
    );
    assert!(text.contains(&line), "build: {text}");
    let o = stripmask().arg("info").arg(&out).output().unwrap();
    assert!(o.status.success());
    let printed = String::from_utf8(o.stdout).unwrap();
    assert!(printed.contains(&line), "info: {printed}");

    // A model without nodata says so.
    let full = dir.path().join("full.asc");
    write_asc(&full, 33, 33, |i, j| Some((i + j) as f32));
    let (_, info) = build_and_info(&full, &dir.path().join("full.smdb"));
    assert_eq!(info["header"]["nodata_filled"], 0);
    assert_eq!(info["header"]["nodata_flattened"], 0);
}
