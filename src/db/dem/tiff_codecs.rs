//! The TIFF codecs the `tiff` crate lacks, one stored chunk (strip or tile) at a time: ZSTD
//! (compression 50000) with TIFF's predictors, and LERC (34887), its blob stored as is or inside
//! DEFLATE or ZSTD. A chunk decodes into at most its own size, whatever its bytes claim.

use std::io::{Read, Seek, SeekFrom};

use lerc::DataType;
use lerc::bitmask::BitMask;
use ruzstd::decoding::{BlockDecodingStrategy, FrameDecoder};
use tiff::decoder::DecodingResult;

/// The TIFF tag of LERC's parameters: its version, then its additional compression.
pub(super) const LERC_PARAMETERS: u16 = 50674;

/// The largest stored chunk read: the limit the `tiff` crate applies to the chunks it decodes
/// itself (`tiff::decoder::Limits::default()`).
const MAX_STORED_BYTES: u64 = 128 << 20;
/// The largest decoded chunk, the `tiff` crate's limit too.
const MAX_DECODED_BYTES: u64 = 256 << 20;

/// How a file's chunks are compressed, for the codecs read here.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Codec {
    /// ZSTD over samples the predictor differenced.
    Zstd(Predictor),
    /// A LERC blob, stored as is or compressed again.
    Lerc(LercWrap),
}

/// TIFF's predictors: what was done to the samples before compression.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Predictor {
    /// Nothing (1).
    None,
    /// Each sample less the one before it in the row (2).
    Horizontal,
    /// The row's bytes regrouped into planes, most significant first, then each byte less the
    /// one before it (3, for floating point).
    FloatingPoint,
}

/// The compression around a LERC blob (LercParameters' second value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum LercWrap {
    /// None (0).
    None,
    /// DEFLATE in a zlib stream (1).
    Deflate,
    /// ZSTD (2).
    Zstd,
}

impl Codec {
    /// The codec of TIFF compression `compression` with its Predictor tag and LercParameters
    /// values, or `None` when the `tiff` crate reads the compression itself.
    pub(super) fn from_tags(
        compression: u16,
        predictor: u16,
        lerc_parameters: &[u32],
    ) -> Result<Option<Codec>, String> {
        match compression {
            50000 => {
                let predictor = match predictor {
                    1 => Predictor::None,
                    2 => Predictor::Horizontal,
                    3 => Predictor::FloatingPoint,
                    p => return Err(format!("unknown TIFF predictor {p}")),
                };
                Ok(Some(Codec::Zstd(predictor)))
            }
            // libtiff applies no predictor to LERC, whose blobs hold samples, not bytes.
            34887 => match lerc_parameters.get(1).copied().unwrap_or(0) {
                0 => Ok(Some(Codec::Lerc(LercWrap::None))),
                1 => Ok(Some(Codec::Lerc(LercWrap::Deflate))),
                2 => Ok(Some(Codec::Lerc(LercWrap::Zstd))),
                c => Err(format!(
                    "unknown compression {c} around LERC (LercParameters)"
                )),
            },
            _ => Ok(None),
        }
    }

    /// The most a chunk's samples may outweigh its stored bytes. ZSTD's densest block, one byte
    /// repeated, stores 128 KiB in 4 bytes; a constant LERC chunk is its header alone, under
    /// 100 bytes for any size, so 1024 x 1024 doubles (8 MiB) expand some 90,000 to 1.
    pub(super) fn max_expansion(self) -> u64 {
        match self {
            Codec::Zstd(_) => 1 << 15,
            Codec::Lerc(_) => 1 << 17,
        }
    }
}

/// What a sample is: unsigned, signed or floating point.
#[derive(Clone, Copy, Debug, PartialEq)]
enum SampleKind {
    Unsigned,
    Signed,
    Float,
}

/// One stored sample: its kind, size and byte order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SampleLayout {
    kind: SampleKind,
    bytes: usize,
    big_endian: bool,
}

impl SampleLayout {
    /// A sample of TIFF SampleFormat `format` (1 unsigned, 2 signed, 3 floating point) and
    /// `bits` (8, 16, 32 or 64) in a file of the given byte order.
    pub(super) fn new(format: u16, bits: u8, big_endian: bool) -> Result<SampleLayout, String> {
        let kind = match format {
            1 => SampleKind::Unsigned,
            2 => SampleKind::Signed,
            3 => SampleKind::Float,
            f => return Err(format!("unknown TIFF SampleFormat {f}")),
        };
        match (kind, bits) {
            (SampleKind::Float, 32 | 64)
            | (SampleKind::Unsigned | SampleKind::Signed, 8 | 16 | 32 | 64) => Ok(SampleLayout {
                kind,
                bytes: usize::from(bits / 8),
                big_endian,
            }),
            _ => Err(format!(
                "{bits}-bit {kind:?} samples compressed with ZSTD or LERC"
            )),
        }
    }

    /// The LERC data type of these samples; LERC has no 64-bit integers.
    fn lerc_type(self) -> Option<DataType> {
        Some(match (self.kind, self.bytes) {
            (SampleKind::Signed, 1) => DataType::Char,
            (SampleKind::Unsigned, 1) => DataType::Byte,
            (SampleKind::Signed, 2) => DataType::Short,
            (SampleKind::Unsigned, 2) => DataType::UShort,
            (SampleKind::Signed, 4) => DataType::Int,
            (SampleKind::Unsigned, 4) => DataType::UInt,
            (SampleKind::Float, 4) => DataType::Float,
            (SampleKind::Float, 8) => DataType::Double,
            _ => return None,
        })
    }

    /// The samples of `bytes`, big-endian or little-endian as `big_endian` says.
    fn samples(self, bytes: Vec<u8>, big_endian: bool) -> DecodingResult {
        use DecodingResult as D;
        let be = big_endian;
        match (self.kind, self.bytes) {
            (SampleKind::Unsigned, 1) => D::U8(bytes),
            (SampleKind::Signed, 1) => {
                D::I8(words(&bytes, be, i8::from_be_bytes, i8::from_le_bytes))
            }
            (SampleKind::Unsigned, 2) => {
                D::U16(words(&bytes, be, u16::from_be_bytes, u16::from_le_bytes))
            }
            (SampleKind::Signed, 2) => {
                D::I16(words(&bytes, be, i16::from_be_bytes, i16::from_le_bytes))
            }
            (SampleKind::Unsigned, 4) => {
                D::U32(words(&bytes, be, u32::from_be_bytes, u32::from_le_bytes))
            }
            (SampleKind::Signed, 4) => {
                D::I32(words(&bytes, be, i32::from_be_bytes, i32::from_le_bytes))
            }
            (SampleKind::Unsigned, _) => {
                D::U64(words(&bytes, be, u64::from_be_bytes, u64::from_le_bytes))
            }
            (SampleKind::Signed, _) => {
                D::I64(words(&bytes, be, i64::from_be_bytes, i64::from_le_bytes))
            }
            (SampleKind::Float, 4) => {
                D::F32(words(&bytes, be, f32::from_be_bytes, f32::from_le_bytes))
            }
            (SampleKind::Float, _) => {
                D::F64(words(&bytes, be, f64::from_be_bytes, f64::from_le_bytes))
            }
        }
    }
}

/// The values of `bytes` read `N` at a time.
fn words<const N: usize, T>(
    bytes: &[u8],
    big_endian: bool,
    from_be: fn([u8; N]) -> T,
    from_le: fn([u8; N]) -> T,
) -> Vec<T> {
    let read = if big_endian { from_be } else { from_le };
    let mut word = [0; N];
    bytes
        .chunks_exact(N)
        .map(|w| {
            word.copy_from_slice(w);
            read(word)
        })
        .collect()
}

/// Decodes the chunks of one image whose compression the `tiff` crate lacks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ChunkCodec {
    codec: Codec,
    layout: SampleLayout,
}

impl ChunkCodec {
    /// The decoder of chunks compressed with `codec` holding samples laid out as `layout`.
    pub(super) fn new(codec: Codec, layout: SampleLayout) -> Result<ChunkCodec, String> {
        match codec {
            Codec::Zstd(Predictor::FloatingPoint) if layout.kind != SampleKind::Float => {
                Err(format!(
                    "the floating-point predictor over {:?} samples",
                    layout.kind
                ))
            }
            Codec::Lerc(_) if layout.lerc_type().is_none() => {
                Err(format!("LERC of {}-bit integers", layout.bytes * 8))
            }
            _ => Ok(ChunkCodec { codec, layout }),
        }
    }

    /// The codec's [`Codec::max_expansion`].
    pub(super) fn max_expansion(self) -> u64 {
        self.codec.max_expansion()
    }

    /// Reads the chunk stored in the `count` bytes at `offset` of `file` and decodes it into its
    /// `width x rows` samples (a tile is stored whole, a strip at its rows).
    pub(super) fn read(
        self,
        file: &mut (impl Read + Seek),
        (offset, count): (u64, u64),
        (width, rows): (usize, usize),
    ) -> Result<DecodingResult, String> {
        let decoded = (width as u64)
            .saturating_mul(rows as u64)
            .saturating_mul(self.layout.bytes as u64);
        if count > MAX_STORED_BYTES || decoded > MAX_DECODED_BYTES {
            return Err(format!(
                "{count} bytes stored for {width} x {rows} samples, more than the {} MiB stored \
                 or {} MiB decoded read in one chunk",
                MAX_STORED_BYTES >> 20,
                MAX_DECODED_BYTES >> 20
            ));
        }
        if decoded > count.saturating_mul(self.max_expansion()) {
            return Err(format!(
                "{count} bytes stored for {decoded} bytes of samples, more than {} to 1",
                self.max_expansion()
            ));
        }
        let mut stored = vec![0; count as usize];
        file.seek(SeekFrom::Start(offset))
            .and_then(|_| file.read_exact(&mut stored))
            .map_err(|e| format!("reading its {count} bytes: {e}"))?;
        self.decode(&stored, (width, rows))
    }

    /// Decodes the `stored` bytes of a chunk of `width x rows` samples.
    fn decode(
        self,
        stored: &[u8],
        (width, rows): (usize, usize),
    ) -> Result<DecodingResult, String> {
        let bytes = width * rows * self.layout.bytes;
        match self.codec {
            Codec::Zstd(predictor) => {
                let mut data = unzstd(stored, bytes)?;
                if data.len() != bytes {
                    return Err(format!(
                        "ZSTD data of {} bytes, {width} x {rows} samples of {} bytes expected",
                        data.len(),
                        self.layout.bytes
                    ));
                }
                let row = width * self.layout.bytes;
                let big_endian = match predictor {
                    Predictor::None => self.layout.big_endian,
                    Predictor::Horizontal => {
                        undo_horizontal(&mut data, row, self.layout);
                        self.layout.big_endian
                    }
                    Predictor::FloatingPoint => {
                        undo_floating_point(&mut data, row, self.layout.bytes);
                        true
                    }
                };
                Ok(self.layout.samples(data, big_endian))
            }
            Codec::Lerc(wrap) => {
                // libtiff's buffer for the blob inside another compression.
                let max_blob = 256 + bytes + bytes / 3;
                let unwrapped;
                let blob = match wrap {
                    LercWrap::None => stored,
                    LercWrap::Deflate => {
                        unwrapped = miniz_oxide::inflate::decompress_to_vec_zlib_with_limit(
                            stored, max_blob,
                        )
                        .map_err(|e| format!("DEFLATE around LERC: {e}"))?;
                        &unwrapped
                    }
                    LercWrap::Zstd => {
                        unwrapped = unzstd(stored, max_blob)?;
                        &unwrapped
                    }
                };
                self.unlerc(blob, (width, rows))
            }
        }
    }

    /// Decodes the LERC blob of a chunk of `width x rows` samples, its masked samples `NaN`.
    fn unlerc(self, blob: &[u8], (width, rows): (usize, usize)) -> Result<DecodingResult, String> {
        use DecodingResult as D;
        use lerc::SampleData as S;
        let info = lerc::decode_info(blob).map_err(|e| format!("LERC: {e}"))?;
        let shape = (
            info.width as usize,
            info.height as usize,
            info.depth,
            info.bands,
        );
        if shape != (width, rows, 1, 1) {
            return Err(format!(
                "a LERC blob of {} x {} samples ({} deep, {} bands), {width} x {rows} expected",
                shape.0, shape.1, shape.2, shape.3
            ));
        }
        if Some(info.data_type) != self.layout.lerc_type() {
            return Err(format!(
                "LERC samples of type {:?} in a TIFF of {:?} samples of {} bits",
                info.data_type,
                self.layout.kind,
                self.layout.bytes * 8
            ));
        }
        let image = lerc::decode(blob).map_err(|e| format!("LERC: {e}"))?;
        let n = width * rows;
        let mask = match image.valid_masks.first() {
            Some(m) if m.is_all_valid() => None,
            Some(m) if m.num_pixels() == n => Some(m),
            Some(m) => {
                return Err(format!(
                    "a LERC mask of {} pixels, {n} expected",
                    m.num_pixels()
                ));
            }
            None => None,
        };
        Ok(match image.data {
            S::F32(mut v) => {
                mask_with(&mut v, mask, f32::NAN);
                D::F32(v)
            }
            S::F64(mut v) => {
                mask_with(&mut v, mask, f64::NAN);
                D::F64(v)
            }
            S::I8(v) => masked(v, mask, D::I8),
            S::U8(v) => masked(v, mask, D::U8),
            S::I16(v) => masked(v, mask, D::I16),
            S::U16(v) => masked(v, mask, D::U16),
            S::I32(v) => masked(v, mask, D::I32),
            S::U32(v) => masked(v, mask, D::U32),
        })
    }
}

/// Sets the samples `mask` marks invalid to `nan`.
fn mask_with<T: Copy>(samples: &mut [T], mask: Option<&BitMask>, nan: T) {
    if let Some(mask) = mask {
        for (k, x) in samples.iter_mut().enumerate() {
            if !mask.is_valid(k) {
                *x = nan;
            }
        }
    }
}

/// Integer samples as they are when `mask` marks none invalid; otherwise as `f64`, the invalid
/// ones `NaN`, which converts to heights as the integers would.
fn masked<T: Into<f64>>(
    samples: Vec<T>,
    mask: Option<&BitMask>,
    whole: fn(Vec<T>) -> DecodingResult,
) -> DecodingResult {
    match mask {
        None => whole(samples),
        Some(mask) => DecodingResult::F64(
            samples
                .into_iter()
                .enumerate()
                .map(|(k, x)| if mask.is_valid(k) { x.into() } else { f64::NAN })
                .collect(),
        ),
    }
}

/// Undoes the horizontal predictor on rows of `row` bytes: each sample, read in the file's byte
/// order, is the sum (wrapping) of the stored differences up to it.
fn undo_horizontal(data: &mut [u8], row: usize, layout: SampleLayout) {
    fn sum<const N: usize>(row: &mut [u8], big_endian: bool) {
        let mask = u64::MAX >> (64 - 8 * N);
        let mut previous = 0u64;
        for word in row.chunks_exact_mut(N) {
            let mut wide = [0; 8];
            let value = if big_endian {
                wide[8 - N..].copy_from_slice(word);
                u64::from_be_bytes(wide)
            } else {
                wide[..N].copy_from_slice(word);
                u64::from_le_bytes(wide)
            };
            previous = previous.wrapping_add(value) & mask;
            if big_endian {
                word.copy_from_slice(&previous.to_be_bytes()[8 - N..]);
            } else {
                word.copy_from_slice(&previous.to_le_bytes()[..N]);
            }
        }
    }
    for r in data.chunks_exact_mut(row) {
        match layout.bytes {
            1 => sum::<1>(r, layout.big_endian),
            2 => sum::<2>(r, layout.big_endian),
            4 => sum::<4>(r, layout.big_endian),
            _ => sum::<8>(r, layout.big_endian),
        }
    }
}

/// Undoes the floating-point predictor on rows of `row` bytes holding samples of `bytes` bytes
/// (libtiff's `fpAcc`): sums the row's bytes, then gathers each sample's bytes from the planes,
/// big-endian.
fn undo_floating_point(data: &mut [u8], row: usize, bytes: usize) {
    let mut planes = vec![0; row];
    let count = row / bytes;
    for r in data.chunks_exact_mut(row) {
        for i in 1..r.len() {
            r[i] = r[i].wrapping_add(r[i - 1]);
        }
        planes.copy_from_slice(r);
        for (k, sample) in r.chunks_exact_mut(bytes).enumerate() {
            for (b, byte) in sample.iter_mut().enumerate() {
                *byte = planes[b * count + k];
            }
        }
    }
}

/// ZSTD's frame magic number, little-endian.
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];

/// Decompresses the ZSTD frame `stored`, refusing it as soon as it holds more than `max` bytes.
///
/// The decoder hands out nothing before it holds a window of output, and frames declare windows
/// of megabytes whatever their size (libzstd picks one by level when it is not told the size,
/// as in libtiff). A frame of at most `max` bytes refers back at most `max` bytes, so its
/// window is lowered to [`window_for`]`(max)`: the decoder then holds at most that window and
/// one block (128 KiB) before more output shows.
fn unzstd(stored: &[u8], max: usize) -> Result<Vec<u8>, String> {
    let window = window_for(max);
    let mut head = [0; 6];
    let n = stored.len().min(head.len());
    head[..n].copy_from_slice(&stored[..n]);
    lower_window(&mut head[..n], window);
    let mut source = (&head[..n]).chain(&stored[n..]);
    let zstd = |e: &dyn std::fmt::Display| format!("ZSTD: {e}");
    let mut frame = FrameDecoder::new();
    frame.set_max_window_size(window);
    frame.init(&mut source).map_err(|e| zstd(&e))?;
    let too_long = || format!("ZSTD data of more than {max} bytes");
    while !frame.is_finished() {
        frame
            .decode_blocks(&mut source, BlockDecodingStrategy::UptoBlocks(1))
            .map_err(|e| zstd(&e))?;
        // Only output beyond the window, hence beyond `max`, can be collected before the end.
        if !frame.is_finished() && frame.can_collect() > 0 {
            return Err(too_long());
        }
    }
    if frame.can_collect() > max {
        return Err(too_long());
    }
    Ok(frame.collect().unwrap_or_default())
}

/// The window of a frame of at most `max` bytes: the smallest power of two holding them, at
/// least ZSTD's smallest window (1 KiB).
fn window_for(max: usize) -> u64 {
    (max as u64).max(1 << 10).next_power_of_two()
}

/// Lowers the window the frame header `head` declares to `window` (a power of two) when it is
/// larger. A header is the magic number, a descriptor, then the window's exponent and mantissa
/// unless the frame is a single segment (whose window is its size, checked by the decoder).
fn lower_window(head: &mut [u8], window: u64) {
    let [m0, m1, m2, m3, descriptor, declared, ..] = head else {
        return;
    };
    if [*m0, *m1, *m2, *m3] != ZSTD_MAGIC || *descriptor & 0x20 != 0 {
        return;
    }
    let exponent = u64::from(*declared >> 3);
    let size = (1u64 << (10 + exponent)) / 8 * (8 + u64::from(*declared & 7));
    if size > window {
        *declared = ((window.trailing_zeros() - 10) << 3) as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_declaring_a_window_larger_than_its_chunk_gets_the_chunk_window() {
        // No single-segment flag, a window of 2^27 bytes (exponent 17).
        let mut head = [0x28, 0xb5, 0x2f, 0xfd, 0x00, 17 << 3];
        lower_window(&mut head, window_for(40_000));
        assert_eq!(head[5], 6 << 3, "64 KiB");
        let mut small = [0x28, 0xb5, 0x2f, 0xfd, 0x00, 1 << 3];
        lower_window(&mut small, window_for(40_000));
        assert_eq!(small[5], 1 << 3, "a smaller window stays");
        let mut single = [0x28, 0xb5, 0x2f, 0xfd, 0x20, 0xff];
        lower_window(&mut single, window_for(40_000));
        assert_eq!(single[5], 0xff, "a single segment has no window byte");
    }

    #[test]
    fn zstd_output_beyond_the_chunk_is_refused_before_it_is_held() {
        // A frame declaring a 128 MiB window, then 8192 RLE blocks of 16 KiB of zeros.
        let mut frame = vec![0x28, 0xb5, 0x2f, 0xfd, 0x00, 17 << 3];
        for k in 0..8192u32 {
            let header = (16 << 10) << 3 | 1 << 1 | u32::from(k == 8191);
            frame.extend_from_slice(&header.to_le_bytes()[..3]);
            frame.push(0);
        }
        let e = unzstd(&frame, 64 << 10).unwrap_err();
        assert!(e.contains("more than 65536 bytes"), "{e}");
        let exact = ruzstd::encoding::compress_to_vec(
            &[7u8; 5000][..],
            ruzstd::encoding::CompressionLevel::Fastest,
        );
        assert_eq!(unzstd(&exact, 5000).unwrap(), vec![7; 5000]);
        assert!(unzstd(&exact, 4999).is_err());
    }

    #[test]
    fn predictors_are_undone_per_row_in_the_file_byte_order() {
        // Two rows of two big-endian u16: [1, 2], [300, 65535] differenced as [1, 1], [300, 65235].
        let mut data = vec![0, 1, 0, 1, 1, 44, 254, 211];
        let layout = SampleLayout::new(1, 16, true).unwrap();
        undo_horizontal(&mut data, 4, layout);
        assert_eq!(data, [0, 1, 0, 2, 1, 44, 255, 255]);
        // One row of two f32, 1.0 (3f800000) and -2.5 (c0200000): planes [3f c0] [80 20] [00 00]
        // [00 00], each byte less the one before.
        let planes: [u8; 8] = [0x3f, 0xc0, 0x80, 0x20, 0, 0, 0, 0];
        let mut diff = planes;
        for i in (1..diff.len()).rev() {
            diff[i] = diff[i].wrapping_sub(diff[i - 1]);
        }
        let mut data = diff.to_vec();
        undo_floating_point(&mut data, 8, 4);
        assert_eq!(data, [0x3f, 0x80, 0, 0, 0xc0, 0x20, 0, 0]);
    }
}
