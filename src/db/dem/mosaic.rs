//! Many DEM files read as one grid: tiles placed by their georeferencing, or where a GDAL VRT
//! puts them.
//!
//! Each file is a [`Lane`]: a map from the mosaic's samples to the file's, opened when the
//! mosaic's rows reach it and closed after its last row, so only the files under the current
//! row are open and each holds what its own reader holds (one strip or row of tiles) and two
//! rows. A file on the mosaic's grid is copied sample for sample; one of other cells, or offset
//! by a fraction of a cell, is resampled bilinearly. Where files overlap, the last one listed
//! that has data there wins (GDAL's rule for VRTs and `gdalbuildvrt`); where none lies, the
//! samples are nodata.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};

use super::placement::Placement;
use super::{DemInfo, DemReader, OpenOptions, check_dimensions, open_reader};
use crate::error::{Error, Result};

/// Closer to a whole sample than this, a source coordinate is that sample: grids in degrees
/// (1/3600 and such) do not add up exactly in floating point.
const SNAP: f64 = 1e-6;

/// One axis of the map from mosaic samples to a source's: `source = offset + step * mosaic`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Axis {
    /// Source coordinate of mosaic sample 0.
    pub offset: f64,
    /// Source samples per mosaic sample.
    pub step: f64,
    /// The source coordinates a mosaic sample must fall in to be covered, `lo <= c < hi`.
    pub cover: (f64, f64),
    /// The first and last source sample read (a covered coordinate is clamped to them).
    pub samples: (usize, usize),
}

impl Axis {
    /// The source coordinate of mosaic sample `i`, snapped to a whole sample when within
    /// [`SNAP`].
    fn source(&self, i: usize) -> f64 {
        let c = self.offset + self.step * i as f64;
        if (c - c.round()).abs() < SNAP {
            c.round()
        } else {
            c
        }
    }

    /// Whether mosaic sample `i` falls on the source.
    fn covers(&self, i: usize) -> bool {
        let c = self.source(i);
        c >= self.cover.0 && c < self.cover.1
    }

    /// The mosaic samples `first..=last` (of `n`) that fall on the source; `None` when none.
    fn covered(&self, n: usize) -> Option<(usize, usize)> {
        let guess = |c: f64| ((c - self.offset) / self.step).clamp(0.0, n as f64 - 1.0);
        let mut first = guess(self.cover.0).floor() as usize;
        while first > 0 && self.covers(first - 1) {
            first -= 1;
        }
        while first < n && !self.covers(first) {
            first += 1;
        }
        if first == n {
            return None;
        }
        let mut last = (guess(self.cover.1).ceil() as usize).max(first);
        while last > first && !self.covers(last) {
            last -= 1;
        }
        while last + 1 < n && self.covers(last + 1) {
            last += 1;
        }
        Some((first, last))
    }

    /// The source sample at or before mosaic sample `i` and the weight of the one after it.
    fn weights(&self, i: usize) -> (usize, f32) {
        let (lo, hi) = self.samples;
        let c = self.source(i).clamp(lo as f64, hi as f64);
        let k = (c.floor() as usize).min(hi);
        (k, (c - k as f64) as f32)
    }
}

/// How a source's raw values become the mosaic's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Transform {
    /// A raw source value that is nodata (a VRT ComplexSource's `NODATA`).
    pub nodata: Option<f64>,
    /// `value = raw * scale + offset` (a ComplexSource's `ScaleRatio`, `ScaleOffset`).
    pub scale: f64,
    /// See `scale`.
    pub offset: f64,
}

impl Default for Transform {
    fn default() -> Self {
        Transform {
            nodata: None,
            scale: 1.0,
            offset: 0.0,
        }
    }
}

impl Transform {
    /// The value of raw sample `v`, `NaN` for nodata.
    fn apply(&self, v: f32) -> f32 {
        if Some(f64::from(v)) == self.nodata {
            return f32::NAN;
        }
        if self.scale == 1.0 && self.offset == 0.0 {
            return v;
        }
        (f64::from(v) * self.scale + self.offset) as f32
    }
}

/// One source file of a mosaic.
pub(crate) struct Lane {
    /// The file.
    pub path: PathBuf,
    /// Its samples per row and rows, as planned (checked again when it is opened).
    pub size: (usize, usize),
    /// Mosaic columns to source columns.
    pub x: Axis,
    /// Mosaic rows to source rows.
    pub y: Axis,
    /// Its raw values to the mosaic's, in order (a VRT source's, then its band's).
    pub transform: [Transform; 2],
}

/// An open lane: its reader and the last two rows read.
struct Open {
    reader: Box<dyn DemReader>,
    /// Rows read, `(index, samples)`, at most two.
    rows: VecDeque<(usize, Vec<f32>)>,
    next_row: usize,
}

impl Open {
    /// Reads on until source row `k` is held (and the one before it still is).
    fn reach(&mut self, k: usize, width: usize) -> Result<()> {
        while self.next_row <= k {
            let mut row = if self.rows.len() == 2 {
                self.rows.pop_front().expect("two rows").1
            } else {
                vec![0.0; width]
            };
            self.reader.read_row(&mut row)?;
            self.rows.push_back((self.next_row, row));
            self.next_row += 1;
        }
        Ok(())
    }

    /// Source row `k`, which [`Open::reach`] read.
    fn row(&self, k: usize) -> &[f32] {
        &self
            .rows
            .iter()
            .find(|(i, _)| *i == k)
            .expect("row reached")
            .1
    }
}

/// A lane with the mosaic samples it covers and, once reached, its open reader.
struct Active {
    lane: Lane,
    rows: (usize, usize),
    /// Per covered mosaic column: the column, the source column at or before it, the weight
    /// of the one after.
    columns: Vec<(usize, usize, f32)>,
    open: Option<Open>,
}

/// Reads many files as one grid, row by row.
pub struct Mosaic {
    info: DemInfo,
    options: OpenOptions,
    /// How deep in VRTs the sources lie (a VRT may list VRTs, a few deep).
    depth: usize,
    lanes: Vec<Active>,
    /// The lanes by their first row, and how many of them the rows have reached.
    by_start: Vec<usize>,
    started: usize,
    /// The lanes under the current row, in listed order: a row visits these only, however
    /// many files the mosaic has.
    under: Vec<usize>,
    next_row: usize,
}

impl Mosaic {
    /// A mosaic described by `info` of the `lanes` (listed in order: the last wins where they
    /// overlap), opened with `options` at VRT depth `depth`.
    pub(crate) fn new(
        info: DemInfo,
        lanes: Vec<Lane>,
        options: OpenOptions,
        depth: usize,
    ) -> Mosaic {
        let (width, height) = (info.width, info.height);
        let lanes: Vec<Active> = lanes
            .into_iter()
            .filter_map(|lane| {
                let rows = lane.y.covered(height)?;
                let (c0, c1) = lane.x.covered(width)?;
                let columns = (c0..=c1)
                    .map(|i| {
                        let (k, t) = lane.x.weights(i);
                        (i, k, t)
                    })
                    .collect();
                Some(Active {
                    lane,
                    rows,
                    columns,
                    open: None,
                })
            })
            .collect();
        let mut by_start: Vec<usize> = (0..lanes.len()).collect();
        by_start.sort_by_key(|&k| lanes[k].rows.0);
        Mosaic {
            info,
            options,
            depth,
            lanes,
            by_start,
            started: 0,
            under: Vec::new(),
            next_row: 0,
        }
    }

    /// The files `paths` placed by their georeferencing on the grid of the finest cells among
    /// them, at VRT depth `depth`. They must all be placed and share one CRS.
    pub fn placed(paths: &[PathBuf], options: &OpenOptions, depth: usize) -> Result<Self> {
        if paths.is_empty() {
            return Err(Error::invalid("a mosaic", "no files to place"));
        }
        let mut placed: Vec<(PathBuf, DemInfo, Placement)> = Vec::with_capacity(paths.len());
        for path in paths {
            // Opened for its header only, and closed again until the rows reach it.
            let info = open_reader(path, options, depth)?.info().clone();
            let Some(p) = info.placement.clone() else {
                let why = info
                    .spacing_problem
                    .clone()
                    .unwrap_or_else(|| "it says nothing of where it lies".into());
                return Err(Error::invalid(
                    &info.name,
                    format!("cannot be placed in a mosaic: {why}"),
                ));
            };
            if let Some((_, first, fp)) = placed.first()
                && (fp.crs != p.crs || fp.units != p.units)
            {
                return Err(Error::invalid(
                    &info.name,
                    format!(
                        "is in {} ({}) and {} in {} ({}): the files of a mosaic must share one \
                         CRS (reproject them first, e.g. with gdalwarp -t_srs)",
                        p.crs,
                        p.unit_name(),
                        first.name,
                        fp.crs,
                        fp.unit_name()
                    ),
                ));
            }
            placed.push((path.clone(), info, p));
        }
        let name = mosaic_name(paths);
        let base = &placed[0].2;
        let cell = placed.iter().fold((f64::INFINITY, f64::INFINITY), |c, p| {
            (c.0.min(p.2.cell.0), c.1.min(p.2.cell.1))
        });
        let (mut west, mut north) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut east, mut south) = (f64::NEG_INFINITY, f64::INFINITY);
        for (_, info, p) in &placed {
            let (w, n) = p.at(0.0, 0.0);
            let (e, s) = p.at((info.width - 1) as f64, (info.height - 1) as f64);
            (west, north) = (west.min(w), north.max(n));
            (east, south) = (east.max(e), south.min(s));
        }
        let across = |extent: f64, cell: f64| (extent / cell + SNAP).floor() + 1.0;
        let (w, h) = (across(east - west, cell.0), across(north - south, cell.1));
        if !(w.is_finite() && h.is_finite()) || w > usize::MAX as f64 || h > usize::MAX as f64 {
            return Err(Error::invalid(&name, "the files' extent is not finite"));
        }
        let (width, height) = (w as usize, h as usize);
        check_dimensions(&name, width, height)?;
        let mut info = DemInfo::new(&name, width, height);
        Placement {
            crs: base.crs.clone(),
            named: base.named,
            units: base.units,
            cell,
            first: (west, north),
        }
        .apply(&mut info);
        let mut notes = vec![format!(
            "a mosaic of {} files in {} on a grid of {width} x {height} samples of {} x {} {}: \
             where files overlap, the last listed with data wins; where none lies, the \
             samples are nodata",
            placed.len(),
            base.crs,
            cell.0,
            cell.1,
            base.unit_name()
        )];
        let mut lanes = Vec::with_capacity(placed.len());
        for (path, file, p) in placed {
            let x = Axis {
                offset: (west - p.first.0) / p.cell.0,
                step: cell.0 / p.cell.0,
                cover: (-SNAP, (file.width - 1) as f64 + SNAP),
                samples: (0, file.width - 1),
            };
            let y = Axis {
                offset: (p.first.1 - north) / p.cell.1,
                step: cell.1 / p.cell.1,
                cover: (-SNAP, (file.height - 1) as f64 + SNAP),
                samples: (0, file.height - 1),
            };
            let whole = |a: &Axis| a.step == 1.0 && (a.offset - a.offset.round()).abs() < SNAP;
            if !whole(&x) || !whole(&y) {
                notes.push(format!(
                    "{}: cells of {} x {} {} resampled (bilinear) onto the mosaic's grid",
                    file.name,
                    p.cell.0,
                    p.cell.1,
                    p.unit_name()
                ));
            }
            let mut own = DemInfo::new(&file.name, file.width, file.height);
            p.apply(&mut own);
            for note in file.notes.iter().filter(|n| !own.notes.contains(n)) {
                let note = format!("{}: {note}", file.name);
                if !notes.contains(&note) {
                    notes.push(note);
                }
            }
            lanes.push(Lane {
                path,
                size: (file.width, file.height),
                x,
                y,
                transform: [Transform::default(); 2],
            });
        }
        notes.append(&mut info.notes);
        info.notes = notes;
        Ok(Mosaic::new(info, lanes, *options, depth))
    }
}

/// What a mosaic of `paths` is called in messages.
fn mosaic_name(paths: &[PathBuf]) -> String {
    match paths {
        [] => "an empty mosaic".into(),
        [one] => one.display().to_string(),
        [first, rest @ ..] => format!(
            "the mosaic of {} and {} more file{}",
            first.display(),
            rest.len(),
            if rest.len() == 1 { "" } else { "s" }
        ),
    }
}

/// Linear interpolation that leaves `a` exact (and a `NaN` `b` unread) when `t` is 0.
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    if t == 0.0 { a } else { a + (b - a) * t }
}

impl Active {
    /// Writes this lane's samples of mosaic row `j` into the `NaN`s of `out`, opening its
    /// file when the row is its first.
    fn paint(
        &mut self,
        j: usize,
        out: &mut [f32],
        options: &OpenOptions,
        depth: usize,
    ) -> Result<()> {
        let lane = &self.lane;
        if self.open.is_none() {
            let reader = open_reader(&lane.path, options, depth)?;
            let i = reader.info();
            if (i.width, i.height) != lane.size {
                return Err(Error::invalid(
                    &i.name,
                    format!(
                        "is {} x {} samples now, {} x {} when the mosaic was planned",
                        i.width, i.height, lane.size.0, lane.size.1
                    ),
                ));
            }
            self.open = Some(Open {
                reader,
                rows: VecDeque::with_capacity(2),
                next_row: 0,
            });
        }
        let open = self.open.as_mut().expect("opened");
        let (k, ty) = lane.y.weights(j);
        let k1 = if ty == 0.0 { k } else { k + 1 };
        open.reach(k1, lane.size.0)?;
        let (north, south) = (open.row(k), open.row(k1));
        for &(i, c, tx) in &self.columns {
            if !out[i].is_nan() {
                continue;
            }
            let c1 = if tx == 0.0 { c } else { c + 1 };
            let [a, b] = &lane.transform;
            let t = |v: f32| b.apply(a.apply(v));
            let top = lerp(t(north[c]), t(north[c1]), tx);
            let v = if ty == 0.0 {
                top
            } else {
                lerp(top, lerp(t(south[c]), t(south[c1]), tx), ty)
            };
            out[i] = v;
        }
        Ok(())
    }
}

impl DemReader for Mosaic {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        let j = self.next_row;
        if j >= self.info.height {
            return Err(Error::invalid(&self.info.name, "read past the last row"));
        }
        row.fill(f32::NAN);
        while let Some(&k) = self.by_start.get(self.started)
            && self.lanes[k].rows.0 <= j
        {
            let at = self.under.partition_point(|&u| u < k);
            self.under.insert(at, k);
            self.started += 1;
        }
        for &k in self.under.iter().rev() {
            self.lanes[k].paint(j, row, &self.options, self.depth)?;
        }
        let lanes = &mut self.lanes;
        self.under.retain(|&k| {
            let ended = lanes[k].rows.1 == j;
            if ended {
                lanes[k].open = None;
            }
            !ended
        });
        self.next_row += 1;
        Ok(())
    }
}

/// The DEM files `inputs` name: files as given, the DEM files in a folder (and its folders,
/// sorted by path), the files a glob pattern matches (sorted).
pub fn expand(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for input in inputs {
        let name = input.display().to_string();
        if input.is_dir() {
            let before = files.len();
            walk(input, &mut files)?;
            if files.len() == before {
                return Err(Error::invalid(
                    &name,
                    "this folder holds no DEM file whose extension says its format",
                ));
            }
        } else if !input.exists() && name.contains(['*', '?', '[']) {
            let matches = glob::glob(&name)
                .map_err(|e| Error::invalid(&name, format!("not a glob pattern: {e}")))?;
            let mut found: Vec<PathBuf> = matches
                .filter_map(|m| m.ok())
                .filter(|p| p.is_file())
                .collect();
            if found.is_empty() {
                return Err(Error::invalid(&name, "this pattern matches no file"));
            }
            found.sort();
            files.append(&mut found);
        } else {
            files.push(input.clone());
        }
    }
    let mut seen = std::collections::HashSet::new();
    files.retain(|f| seen.insert(f.clone()));
    Ok(files)
}

/// Adds the DEM files under `dir` to `files`, sorted by path.
fn walk(dir: &Path, files: &mut Vec<PathBuf>) -> Result<()> {
    let name = dir.display().to_string();
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(&name, e))?
        .map(|e| e.map(|e| e.path()).map_err(|e| Error::io(&name, e)))
        .collect::<Result<_>>()?;
    entries.sort();
    for path in entries {
        if path.is_dir() {
            walk(&path, files)?;
        } else if super::DemFormat::from_path(&path).is_some_and(|f| f.found_in_folders()) {
            files.push(path);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axis(offset: f64, step: f64, n: usize) -> Axis {
        Axis {
            offset,
            step,
            cover: (-SNAP, (n - 1) as f64 + SNAP),
            samples: (0, n - 1),
        }
    }

    #[test]
    fn a_source_on_the_grid_covers_its_own_samples_exactly() {
        // A 5-sample source whose first sample is the mosaic's sample 3.
        let a = axis(-3.0, 1.0, 5);
        assert_eq!(a.covered(20), Some((3, 7)));
        assert_eq!(a.covered(6), Some((3, 5)));
        assert_eq!(a.weights(4), (1, 0.0));
        assert_eq!(axis(-30.0, 1.0, 5).covered(20), None);
    }

    #[test]
    fn a_coarser_source_is_sampled_between_its_samples() {
        // Source cells twice the mosaic's: mosaic sample 3 is halfway between source 1 and 2.
        let a = axis(0.0, 0.5, 5);
        assert_eq!(a.covered(20), Some((0, 8)));
        assert_eq!(a.weights(3), (1, 0.5));
        assert_eq!(a.weights(8), (4, 0.0));
    }

    #[test]
    fn degree_arithmetic_snaps_to_whole_samples() {
        let cell = 1.0 / 3600.0;
        let a = axis((47.0 - (47.0 + 1200.0 * cell)) / -cell, 1.0, 3601);
        assert_eq!(a.weights(0), (1200, 0.0));
    }

    #[test]
    fn nodata_and_scaling_apply_to_raw_values() {
        let t = Transform {
            nodata: Some(-9999.0),
            scale: 0.1,
            offset: -200.0,
        };
        assert!(t.apply(-9999.0).is_nan());
        assert_eq!(t.apply(2000.0), 0.0);
        assert_eq!(lerp(1.0, f32::NAN, 0.0), 1.0);
    }
}
