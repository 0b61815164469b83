//! GDAL virtual mosaics (`.vrt`, as `gdalbuildvrt` writes them): a grid, its georeferencing,
//! and its first band's `SimpleSource` and `ComplexSource` files, each read from its `SrcRect`
//! into its `DstRect` ([`Mosaic`]).

use std::path::{Path, PathBuf};

use roxmltree::Node;

use super::mosaic::{Axis, Lane, Mosaic, Transform};
use super::placement::{Placement, Units};
use super::{DemInfo, OpenOptions, check_dimensions, open_reader, wkt};
use crate::error::{Error, Result};

/// The largest VRT file read (a mosaic of tens of thousands of sources is a few MiB).
const MAX_VRT_BYTES: u64 = 64 << 20;

/// Opens the VRT `path`, `depth` VRTs deep; its sources are opened with `options` when the
/// rows reach them.
pub fn open(path: &Path, options: &OpenOptions, depth: usize) -> Result<Mosaic> {
    let name = path.display().to_string();
    let len = std::fs::metadata(path)
        .map_err(|e| Error::io(&name, e))?
        .len();
    if len > MAX_VRT_BYTES {
        return Err(Error::invalid(
            &name,
            format!("a VRT of {len} bytes, more than the {MAX_VRT_BYTES} read"),
        ));
    }
    let xml = std::fs::read_to_string(path).map_err(|e| Error::io(&name, e))?;
    let plan = Plan::parse(&xml).map_err(|e| Error::invalid(&name, e))?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut info = DemInfo::new(&name, plan.width, plan.height);
    check_dimensions(&name, plan.width, plan.height)?;
    if let Some(p) = &plan.placement {
        p.apply(&mut info);
    }
    info.notes.insert(
        0,
        format!(
            "a GDAL VRT of {} source{}{}: where sources overlap, the last listed with data wins",
            plan.sources.len(),
            if plan.sources.len() == 1 { "" } else { "s" },
            plan.placement
                .as_ref()
                .map_or(String::new(), |p| format!(" in {}", p.crs)),
        ),
    );
    let mut lanes = Vec::with_capacity(plan.sources.len());
    for source in plan.sources {
        let file = if source.relative {
            dir.join(&source.file)
        } else {
            PathBuf::from(&source.file)
        };
        // Opened for its size only, and closed again until the rows reach it.
        let size = {
            let reader = open_reader(&file, options, depth + 1)?;
            (reader.info().width, reader.info().height)
        };
        let src = source.src.unwrap_or(Rect {
            x: 0.0,
            y: 0.0,
            w: size.0 as f64,
            h: size.1 as f64,
        });
        let dst = source.dst.unwrap_or(src);
        lanes.push(Lane {
            path: file,
            size,
            x: axis(src.x, src.w, dst.x, dst.w, size.0),
            y: axis(src.y, src.h, dst.y, dst.h, size.1),
            transform: [source.transform, plan.band],
        });
    }
    Ok(Mosaic::new(info, lanes, *options, depth + 1))
}

/// A window in pixels, as GDAL writes `SrcRect` and `DstRect` (pixel edges, not centres).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Rect {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
}

/// The map along one axis from the VRT's pixels to a source's: GDAL scales the window
/// `dst_off .. dst_off + dst_len` onto `src_off .. src_off + src_len` and takes each VRT
/// pixel whose centre lies in the window, from the source where its centre falls.
fn axis(src_off: f64, src_len: f64, dst_off: f64, dst_len: f64, samples: usize) -> Axis {
    let step = src_len / dst_len;
    let last = samples - 1;
    Axis {
        offset: src_off + (0.5 - dst_off) * step - 0.5,
        step,
        cover: (
            (src_off - 0.5).max(-0.5),
            (src_off + src_len - 0.5).min(samples as f64 - 0.5),
        ),
        samples: (
            (src_off.max(0.0).floor() as usize).min(last),
            (((src_off + src_len).ceil() - 1.0).max(0.0) as usize).min(last),
        ),
    }
}

/// One source of the VRT's band, as written.
#[derive(Clone, Debug, PartialEq)]
struct Source {
    file: String,
    relative: bool,
    src: Option<Rect>,
    dst: Option<Rect>,
    transform: Transform,
}

/// What a VRT says: the grid, its place, its first band's sources.
#[derive(Clone, Debug, PartialEq)]
struct Plan {
    width: usize,
    height: usize,
    placement: Option<Placement>,
    /// The band's nodata value and scale and offset.
    band: Transform,
    sources: Vec<Source>,
}

impl Plan {
    fn parse(xml: &str) -> std::result::Result<Plan, String> {
        let doc =
            roxmltree::Document::parse(xml).map_err(|e| format!("not a readable VRT: {e}"))?;
        let root = doc.root_element();
        if !root.has_tag_name("VRTDataset") {
            return Err(format!(
                "not a GDAL VRT: its root is <{}>, not <VRTDataset>",
                root.tag_name().name()
            ));
        }
        let size = |key: &str| -> std::result::Result<usize, String> {
            root.attribute(key)
                .and_then(|v| v.trim().parse().ok())
                .ok_or_else(|| format!("<VRTDataset> has no whole-number {key}"))
        };
        let (width, height) = (size("rasterXSize")?, size("rasterYSize")?);
        let crs = match text(child(root, "SRS")).filter(|t| !t.is_empty()) {
            Some(wkt) => Some(wkt::crs(wkt).map_err(|e| format!("unreadable <SRS>: {e}"))?),
            None => None,
        };
        let placement = match text(child(root, "GeoTransform")) {
            Some(t) => {
                let g: Vec<f64> = t
                    .split(',')
                    .map(|v| v.trim().parse::<f64>())
                    .collect::<std::result::Result<_, _>>()
                    .map_err(|_| format!("<GeoTransform> is not six numbers: {t:?}"))?;
                let [x0, dx, rx, y0, ry, dy] = g[..] else {
                    return Err(format!("<GeoTransform> is not six numbers: {t:?}"));
                };
                if rx != 0.0 || ry != 0.0 {
                    return Err("a rotated or sheared grid (<GeoTransform> terms 3 and 5 are not 0) is not read".into());
                }
                if !(dx > 0.0 && dy < 0.0 && dx.is_finite() && dy.is_finite()) {
                    return Err(format!(
                        "<GeoTransform> cells of {dx} x {dy}: a grid read north-up has cells \
                         positive east and negative north"
                    ));
                }
                let named = crs.is_some();
                let (crs, units) = crs
                    .unwrap_or_else(|| ("no CRS (the VRT names none)".into(), Units::Linear(1.0)));
                Some(Placement {
                    crs,
                    named,
                    units,
                    cell: (dx, -dy),
                    first: (x0 + dx / 2.0, y0 + dy / 2.0),
                })
            }
            None => None,
        };
        let band = root
            .children()
            .filter(|c| c.has_tag_name("VRTRasterBand"))
            .min_by_key(|b| {
                b.attribute("band")
                    .and_then(|v| v.parse::<u32>().ok())
                    .unwrap_or(1)
            })
            .ok_or("the VRT has no <VRTRasterBand>")?;
        if let Some(kind) = band.attribute("subClass") {
            return Err(format!(
                "a band of subClass {kind} (pixel functions, warps) is not read; only sources \
                 copied as they are"
            ));
        }
        let band_transform = Transform {
            nodata: number(band, "NoDataValue")?,
            scale: number(band, "Scale")?.unwrap_or(1.0),
            offset: number(band, "Offset")?.unwrap_or(0.0),
        };
        let mut sources = Vec::new();
        for s in band.children().filter(|c| c.is_element()) {
            let kind = s.tag_name().name();
            match kind {
                "SimpleSource" | "ComplexSource" => {}
                k if k.ends_with("Source") => {
                    return Err(format!(
                        "<{k}> is not read; a VRT for a DEM lists SimpleSource and \
                         ComplexSource files"
                    ));
                }
                _ => continue,
            }
            let file =
                child(s, "SourceFilename").ok_or(format!("a <{kind}> without <SourceFilename>"))?;
            let relative = file.attribute("relativeToVRT") == Some("1");
            let file = file.text().unwrap_or("").trim().to_string();
            if file.is_empty() {
                return Err(format!("a <{kind}> with an empty <SourceFilename>"));
            }
            if let Some(b) = text(child(s, "SourceBand"))
                && b != "1"
            {
                return Err(format!(
                    "{file}: band {b} of a source is not read (each source's first band is)"
                ));
            }
            if child(s, "LUT").is_some() {
                return Err(format!("{file}: a source's <LUT> is not read"));
            }
            let rect = |name: &str| -> std::result::Result<Option<Rect>, String> {
                let Some(r) = child(s, name) else {
                    return Ok(None);
                };
                let v = |k: &str| {
                    r.attribute(k)
                        .and_then(|v| v.trim().parse::<f64>().ok())
                        .filter(|v| v.is_finite() && v.abs() < 1e9)
                        .ok_or_else(|| format!("{file}: <{name}> has no number {k}"))
                };
                let rect = Rect {
                    x: v("xOff")?,
                    y: v("yOff")?,
                    w: v("xSize")?,
                    h: v("ySize")?,
                };
                if rect.w <= 0.0 || rect.h <= 0.0 {
                    return Err(format!("{file}: <{name}> is empty"));
                }
                Ok(Some(rect))
            };
            let transform = Transform {
                nodata: number(s, "NODATA")?,
                scale: number(s, "ScaleRatio")?.unwrap_or(1.0),
                offset: number(s, "ScaleOffset")?.unwrap_or(0.0),
            };
            sources.push(Source {
                src: rect("SrcRect")?,
                dst: rect("DstRect")?,
                file,
                relative,
                transform,
            });
        }
        if sources.is_empty() {
            return Err("the VRT's band lists no SimpleSource or ComplexSource".into());
        }
        Ok(Plan {
            width,
            height,
            placement,
            band: band_transform,
            sources,
        })
    }
}

/// The first child element of `node` named `name`.
fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|c| c.has_tag_name(name))
}

/// The trimmed text of `node`.
fn text<'a>(node: Option<Node<'a, '_>>) -> Option<&'a str> {
    node.and_then(|n| n.text()).map(str::trim)
}

/// The number in child `name` of `node`, if it has one.
fn number(node: Node<'_, '_>, name: &str) -> std::result::Result<Option<f64>, String> {
    text(child(node, name))
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| format!("<{name}> is not a number: {t:?}"))
        })
        .transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    const VRT: &str = r#"<VRTDataset rasterXSize="4" rasterYSize="2">
  <SRS dataAxisToSRSAxisMapping="1,2">PROJCS["WGS 84 / UTM zone 10N",UNIT["metre",1],AUTHORITY["EPSG","32610"]]</SRS>
  <GeoTransform> 5.0e+05, 1.0e+01, 0.0, 5.2e+06, 0.0, -1.0e+01</GeoTransform>
  <VRTRasterBand dataType="Int16" band="1">
    <NoDataValue>-32768</NoDataValue>
    <ComplexSource>
      <SourceFilename relativeToVRT="1">a.tif</SourceFilename>
      <SourceBand>1</SourceBand>
      <SrcRect xOff="0" yOff="0" xSize="2" ySize="2" />
      <DstRect xOff="2" yOff="0" xSize="2" ySize="2" />
      <NODATA>-9999</NODATA>
      <ScaleRatio>0.1</ScaleRatio>
    </ComplexSource>
  </VRTRasterBand>
</VRTDataset>"#;

    #[test]
    fn gdalbuildvrt_output_is_read() {
        let plan = Plan::parse(VRT).unwrap();
        assert_eq!((plan.width, plan.height), (4, 2));
        let p = plan.placement.unwrap();
        assert_eq!(p.crs, "EPSG:32610");
        assert_eq!(p.first, (500_005.0, 5_199_995.0));
        assert_eq!(plan.band.nodata, Some(-32768.0));
        let s = &plan.sources[0];
        assert!(s.relative);
        assert_eq!(s.transform.nodata, Some(-9999.0));
        assert_eq!(s.transform.scale, 0.1);
        assert_eq!(s.dst.unwrap().x, 2.0);
    }

    #[test]
    fn a_source_window_maps_pixel_centres() {
        // A 2-wide source drawn at VRT pixels 2 and 3.
        let a = axis(0.0, 2.0, 2.0, 2.0, 2);
        assert_eq!(a.offset + a.step * 2.0, 0.0);
        assert_eq!(a.offset + a.step * 3.0, 1.0);
        assert!(a.cover.0 <= 0.0 && a.cover.1 > 1.0 && a.cover.1 < 2.0);
        // Half the resolution: VRT pixel 1's centre falls at source 0.25.
        let half = axis(0.0, 2.0, 0.0, 4.0, 2);
        assert_eq!(half.offset + half.step, 0.25);
    }

    #[test]
    fn what_is_not_read_is_said() {
        let derived = VRT.replace(
            r#"band="1">"#,
            r#"band="1" subClass="VRTDerivedRasterBand">"#,
        );
        assert!(Plan::parse(&derived).unwrap_err().contains("subClass"));
        let band2 = VRT.replace("<SourceBand>1<", "<SourceBand>2<");
        assert!(Plan::parse(&band2).unwrap_err().contains("band 2"));
        let rotated = VRT.replace("0.0, 5.2e+06", "0.5, 5.2e+06");
        assert!(Plan::parse(&rotated).unwrap_err().contains("rotated"));
        assert!(Plan::parse("<VRTDataset>").is_err());
        assert!(Plan::parse("<x/>").unwrap_err().contains("root"));
    }
}
