//! Decompression bombs in DEMs are refused when the file is opened, before anything is
//! allocated for their claimed size: TIFF strips that share their bytes, and PNG headers
//! claiming far more samples than the file can hold.

use std::path::Path;

use stripmask::db::dem::{self, OpenOptions};

fn options() -> OpenOptions {
    OpenOptions::default()
}

/// A 64 x 64 16-bit uncompressed TIFF in 64 one-row strips; `shared` points every strip at
/// the same 128 bytes, otherwise each has its own.
fn tiff(path: &Path, shared: bool) {
    const N: u32 = 64;
    let entries: u32 = 9;
    let ifd_end = 8 + 2 + entries * 12 + 4;
    let (offsets_at, counts_at) = (ifd_end, ifd_end + 4 * N);
    let data_at = counts_at + 4 * N;
    let mut b: Vec<u8> = b"II*\0".to_vec();
    b.extend_from_slice(&8u32.to_le_bytes());
    b.extend_from_slice(&(entries as u16).to_le_bytes());
    let mut entry = |tag: u16, kind: u16, count: u32, value: u32| {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&kind.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&value.to_le_bytes());
    };
    let (short, long) = (3, 4);
    entry(256, short, 1, N); // ImageWidth
    entry(257, short, 1, N); // ImageLength
    entry(258, short, 1, 16); // BitsPerSample
    entry(259, short, 1, 1); // Compression: none
    entry(262, short, 1, 1); // PhotometricInterpretation: black is zero
    entry(273, long, N, offsets_at); // StripOffsets
    entry(277, short, 1, 1); // SamplesPerPixel
    entry(278, short, 1, 1); // RowsPerStrip
    entry(279, long, N, counts_at); // StripByteCounts
    b.extend_from_slice(&0u32.to_le_bytes());
    for k in 0..N {
        let at = if shared { data_at } else { data_at + k * 2 * N };
        b.extend_from_slice(&at.to_le_bytes());
    }
    for _ in 0..N {
        b.extend_from_slice(&(2 * N).to_le_bytes());
    }
    let strips = if shared { 1 } else { N };
    for k in 0..strips * N {
        b.extend_from_slice(&(k as u16).to_le_bytes());
    }
    std::fs::write(path, b).unwrap();
}

/// A grayscale 8-bit PNG whose header says `side x side` but whose data is a few bytes.
fn png_claiming(path: &Path, side: u32) {
    let mut b = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        b.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut typed = kind.to_vec();
        typed.extend_from_slice(data);
        b.extend_from_slice(&typed);
        b.extend_from_slice(&crc32fast::hash(&typed).to_be_bytes());
    };
    let mut ihdr = side.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&side.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(
        b"IDAT",
        &miniz_oxide::deflate::compress_to_vec_zlib(&[0; 64], 6),
    );
    chunk(b"IEND", &[]);
    std::fs::write(path, b).unwrap();
}

#[test]
fn tiff_strips_sharing_their_bytes_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let own = dir.path().join("own.tif");
    tiff(&own, false);
    let mut read = dem::open(&own, &options()).unwrap();
    let mut row = vec![0.0; 64];
    read.read_row(&mut row).unwrap();
    assert_eq!(row[5], 5.0);

    let shared = dir.path().join("shared.tif");
    tiff(&shared, true);
    let e = match dem::open(&shared, &options()) {
        Ok(_) => panic!("opened a TIFF whose strips share one offset"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("shared.tif") && e.contains("share"), "{e}");
}

#[test]
fn png_headers_claiming_more_than_the_file_holds_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for side in [65_537, 1 << 20] {
        let path = dir.path().join(format!("claim{side}.png"));
        png_claiming(&path, side);
        let e = match dem::open(&path, &options()) {
            Ok(_) => panic!("opened a {side}-pixel PNG of a few bytes"),
            Err(e) => e.to_string(),
        };
        assert!(e.contains("claims"), "{e}");
    }
    let small = dir.path().join("small.png");
    png_claiming(&small, 8);
    assert!(dem::open(&small, &options()).is_ok());
}
