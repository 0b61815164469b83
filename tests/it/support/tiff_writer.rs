//! A TIFF writer for the DEM readers' tests: one band of samples in strips or tiles, in either
//! byte order, each chunk's stored bytes made by the test (its compression, its predictor).

/// A sample type of a test TIFF.
pub trait Sample: Copy + Default {
    /// Its BitsPerSample.
    const BITS: u16;
    /// Its SampleFormat: 1 unsigned, 2 signed, 3 floating point.
    const FORMAT: u16;
    /// Its bytes, big-endian or little-endian.
    fn bytes(self, big_endian: bool) -> Vec<u8>;
}

macro_rules! sample {
    ($t:ty, $format:expr) => {
        impl Sample for $t {
            const BITS: u16 = 8 * size_of::<$t>() as u16;
            const FORMAT: u16 = $format;
            fn bytes(self, big_endian: bool) -> Vec<u8> {
                if big_endian {
                    self.to_be_bytes().to_vec()
                } else {
                    self.to_le_bytes().to_vec()
                }
            }
        }
    };
}
sample!(u16, 1);
sample!(i16, 2);
sample!(f32, 3);

/// The bytes of `samples` in a file of the given byte order, as an uncompressed chunk stores them.
pub fn raw<T: Sample>(samples: &[T], big_endian: bool) -> Vec<u8> {
    samples.iter().flat_map(|s| s.bytes(big_endian)).collect()
}

/// How a test TIFF cuts its grid into chunks.
#[derive(Clone, Copy, Debug)]
pub enum Chunking {
    /// Strips of this many rows (the last one shorter).
    Strips(u32),
    /// Tiles of this width and height (the ones past the grid's edge padded with zeros).
    Tiles(u32, u32),
}

/// A TIFF tag's value.
#[derive(Clone, Debug)]
pub enum Value {
    /// 16-bit unsigned integers.
    Short(Vec<u16>),
    /// 32-bit unsigned integers.
    Long(Vec<u32>),
    /// Text (written NUL-terminated).
    Ascii(String),
}

impl Value {
    /// The TIFF field type, the count and the bytes of the value.
    fn encode(&self, big_endian: bool) -> (u16, u32, Vec<u8>) {
        match self {
            Value::Short(v) => (3, v.len() as u32, raw(v, big_endian)),
            Value::Long(v) => (
                4,
                v.len() as u32,
                v.iter()
                    .flat_map(|x| {
                        if big_endian {
                            x.to_be_bytes()
                        } else {
                            x.to_le_bytes()
                        }
                    })
                    .collect(),
            ),
            Value::Ascii(s) => {
                let mut b = s.as_bytes().to_vec();
                b.push(0);
                (2, b.len() as u32, b)
            }
        }
    }
}

/// How a test TIFF stores its grid.
#[derive(Clone, Debug)]
pub struct Layout {
    pub chunking: Chunking,
    pub big_endian: bool,
    /// The Compression tag: 1 none, 8 DEFLATE, 34887 LERC, 50000 ZSTD.
    pub compression: u16,
    /// The Predictor tag: 1 none, 2 horizontal, 3 floating point.
    pub predictor: u16,
    /// More tags, `(tag, value)`.
    pub tags: Vec<(u16, Value)>,
}

impl Layout {
    /// Uncompressed little-endian chunks.
    pub fn new(chunking: Chunking) -> Layout {
        Layout {
            chunking,
            big_endian: false,
            compression: 1,
            predictor: 1,
            tags: Vec::new(),
        }
    }
}

/// The bytes of a TIFF of the `width x height` grid `samples` (row-major) stored as `layout`
/// says: `store` makes each chunk's bytes from its samples (a tile whole, a strip at its rows)
/// and their width and rows.
pub fn tiff<T: Sample>(
    (width, height): (u32, u32),
    samples: &[T],
    layout: &Layout,
    store: impl FnMut(&[T], (usize, usize)) -> Vec<u8>,
) -> Vec<u8> {
    tiff_of(
        (width, height),
        |i, j| samples[(j * width + i) as usize],
        layout,
        store,
    )
}

/// [`tiff`] of the grid whose sample `(i, j)` is `sample(i, j)`, never held whole: a grid
/// larger than memory, most of whose chunks `store` leaves empty (a sparse file).
pub fn tiff_of<T: Sample>(
    (width, height): (u32, u32),
    sample: impl Fn(u32, u32) -> T,
    layout: &Layout,
    mut store: impl FnMut(&[T], (usize, usize)) -> Vec<u8>,
) -> Vec<u8> {
    let be = layout.big_endian;
    let (cw, ch) = match layout.chunking {
        Chunking::Strips(rows) => (width, rows),
        Chunking::Tiles(w, h) => (w, h),
    };
    let mut out = if be { b"MM\0*" } else { b"II*\0" }.to_vec();
    out.extend_from_slice(&[0; 4]);
    let (mut offsets, mut counts) = (Vec::new(), Vec::new());
    for y0 in (0..height).step_by(ch as usize) {
        for x0 in (0..width).step_by(cw as usize) {
            let rows = match layout.chunking {
                Chunking::Strips(_) => ch.min(height - y0),
                Chunking::Tiles(..) => ch,
            };
            let mut chunk = Vec::new();
            for j in y0..y0 + rows {
                for i in x0..x0 + cw {
                    chunk.push(if i < width && j < height {
                        sample(i, j)
                    } else {
                        T::default()
                    });
                }
            }
            let bytes = store(&chunk, (cw as usize, rows as usize));
            offsets.push(out.len() as u32);
            counts.push(bytes.len() as u32);
            out.extend(bytes);
        }
    }
    let mut entries = vec![
        (256, Value::Long(vec![width])),
        (257, Value::Long(vec![height])),
        (258, Value::Short(vec![T::BITS])),
        (259, Value::Short(vec![layout.compression])),
        (262, Value::Short(vec![1])),
        (277, Value::Short(vec![1])),
        (339, Value::Short(vec![T::FORMAT])),
    ];
    match layout.chunking {
        Chunking::Strips(rows) => entries.extend([
            (273, Value::Long(offsets)),
            (278, Value::Long(vec![rows])),
            (279, Value::Long(counts)),
        ]),
        Chunking::Tiles(w, h) => entries.extend([
            (322, Value::Long(vec![w])),
            (323, Value::Long(vec![h])),
            (324, Value::Long(offsets)),
            (325, Value::Long(counts)),
        ]),
    }
    if layout.predictor != 1 {
        entries.push((317, Value::Short(vec![layout.predictor])));
    }
    entries.extend(layout.tags.iter().cloned());
    entries.sort_by_key(|e| e.0);
    let word = |x: u32| if be { x.to_be_bytes() } else { x.to_le_bytes() };
    let short = |x: u16| if be { x.to_be_bytes() } else { x.to_le_bytes() };
    let mut ifd = short(entries.len() as u16).to_vec();
    for (tag, value) in &entries {
        let (kind, count, mut bytes) = value.encode(be);
        ifd.extend(short(*tag));
        ifd.extend(short(kind));
        ifd.extend(word(count));
        if bytes.len() <= 4 {
            bytes.resize(4, 0);
            ifd.extend(bytes);
        } else {
            out.resize(out.len().next_multiple_of(2), 0);
            ifd.extend(word(out.len() as u32));
            out.extend(bytes);
        }
    }
    ifd.extend(word(0));
    out.resize(out.len().next_multiple_of(2), 0);
    let at = word(out.len() as u32);
    out[4..8].copy_from_slice(&at);
    out.extend(ifd);
    out
}

/// The tags a test GeoTIFF carries besides its samples.
#[derive(Default)]
pub struct Tags<'a> {
    /// GDAL's metadata XML.
    pub metadata: Option<&'a str>,
    /// GDAL's nodata text.
    pub nodata: Option<&'a str>,
    /// Pixel scale (x, y) and the world position of the first pixel's corner.
    pub georeference: Option<([f64; 2], [f64; 2])>,
    /// GeoKeys `(id, value)`, short values.
    pub keys: &'a [(u16, u16)],
}

/// Writes a TIFF of `w x h` samples `sample(i, j)` of the `tiff` encoder's colour type `C`
/// with `tags`.
pub fn write_geotiff<C>(
    path: &std::path::Path,
    (w, h): (u32, u32),
    sample: impl Fn(u32, u32) -> C::Inner,
    tags: &Tags,
) where
    C: tiff::encoder::colortype::ColorType,
    [C::Inner]: tiff::encoder::TiffValue,
{
    use tiff::encoder::TiffEncoder;
    use tiff::tags::Tag;
    let data: Vec<C::Inner> = (0..w * h).map(|k| sample(k % w, k / w)).collect();
    let mut encoder = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut image = encoder.new_image::<C>(w, h).unwrap();
    let dir = image.encoder();
    if let Some(metadata) = tags.metadata {
        dir.write_tag(Tag::Unknown(42112), metadata).unwrap();
    }
    if let Some(nodata) = tags.nodata {
        dir.write_tag(Tag::GdalNodata, nodata).unwrap();
    }
    if let Some((scale, corner)) = tags.georeference {
        dir.write_tag(Tag::ModelPixelScaleTag, &[scale[0], scale[1], 0.0][..])
            .unwrap();
        dir.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, corner[0], corner[1], 0.0][..],
        )
        .unwrap();
    }
    if !tags.keys.is_empty() {
        let mut directory = vec![1, 1, 0, tags.keys.len() as u16];
        for &(id, value) in tags.keys {
            directory.extend([id, 0, 1, value]);
        }
        dir.write_tag(Tag::GeoKeyDirectoryTag, &directory[..])
            .unwrap();
    }
    image.write_data(&data).unwrap();
}
